//! Sweeps: expansion, the errors a bad sweep gets before anything runs, the orders a dt sweep
//! shows, and the CSV and SVG encodings read back by standard readers.

use serde_json::{Value, json};

use super::*;

/// The single spring of the solver's known-answer tests: 1 kg on k = 100 N/m, released 0.1 m
/// beyond its rest length of 1 m, no gravity.
fn single_spring() -> Value {
    json!({"duration": 1.0, "gravity": [0, 0, 0], "error_estimate": "none",
        "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [1.1, 0, 0], "count": 2, "mass": 2.0,
                    "spring": {"k": 100, "rest_length": 1.0}, "pin": [0]}],
        "output": {"frames": "none"}})
}

fn sweep(document: Value) -> Result<Sweep, SweepError> {
    Sweep::from_value(document, 100)
}

#[test]
fn every_combination_is_a_variant_the_first_key_slowest() {
    let s = sweep(json!({"scene": single_spring(), "vary": {"/integrator": ["rk4", "verlet"], "/dt": [0.01, 0.02, 0.04]}}))
        .unwrap();
    assert_eq!(s.pointers, ["/integrator", "/dt"]);
    let values: Vec<(String, f64)> = s
        .variants
        .iter()
        .map(|v| (v.values[0].as_str().unwrap().to_string(), v.values[1].as_f64().unwrap()))
        .collect();
    assert_eq!(values[0], ("rk4".into(), 0.01));
    assert_eq!(values[2], ("rk4".into(), 0.04));
    assert_eq!(values[3], ("verlet".into(), 0.01));
    assert_eq!(values.len(), 6);
    for v in &s.variants {
        assert_eq!(v.scene.dt, v.values[1].as_f64());
        assert_eq!(v.scene.integrator.kind().name(), v.values[0].as_str().unwrap());
    }
}

#[test]
fn bad_sweeps_are_refused_before_any_run_naming_the_entry() {
    let cases: Vec<(Value, &[&str])> = vec![
        (json!({"vary": {}}), &["/scene"]),
        (json!({"scene": single_spring(), "vary": {"dt": [0.1]}}), &["/vary/dt"]),
        (json!({"scene": single_spring(), "vary": {"/nothing/here": [1]}}), &["/vary/~1nothing~1here"]),
        (json!({"scene": single_spring(), "vary": {"/bodies/3/mass": [1]}}), &["/vary/~1bodies~13~1mass"]),
        (json!({"scene": single_spring(), "vary": {"/dt": []}}), &["/vary/~1dt"]),
        (json!({"scene": single_spring(), "vary": {"/dt": [0.01, -1.0]}}), &["/vary/~1dt/1"]),
        (
            json!({"scene": single_spring(), "vary": {"/integrator": ["rk4", "rk5"]}}),
            &["/vary/~1integrator/1"],
        ),
        (json!({"scene": single_spring(), "vary": {"/colour": ["red"]}}), &["/vary/~1colour/0"]),
        (
            json!({"scene": single_spring(), "vary": {"/bodies/0/spring/k": [100, 0]}}),
            &["/vary/~1bodies~10~1spring~1k/1"],
        ),
        (json!({"scene": single_spring(), "reference": {"dt": 0}}), &["/reference"]),
        (json!({"scene": single_spring(), "vary": {"/dt": [0.1]}, "extra": 1}), &["/extra"]),
    ];
    for (document, expected) in cases {
        let error = sweep(document.clone()).expect_err(&document.to_string());
        let pointers: Vec<&str> = error.field_errors().iter().map(|e| e.pointer.as_str()).collect();
        assert_eq!(pointers, expected, "{document}: {error}");
    }
}

#[test]
fn a_sweep_over_the_limit_is_refused() {
    let doc = json!({"scene": single_spring(), "vary": {"/dt": [0.1, 0.2, 0.3], "/drag": [0, 1, 2, 3]}});
    assert_eq!(
        Sweep::from_value(doc, 10).unwrap_err(),
        SweepError::TooManyVariants { variants: 12, limit: 10 }
    );
}

fn order_sweep() -> Table {
    let s = sweep(json!({
        "scene": single_spring(),
        "vary": {"/integrator": ["explicit_euler", "symplectic_euler", "verlet", "rk4", "implicit_euler"],
                 "/dt": [0.004, 0.002, 0.001]},
        "reference": {"integrator": "rk4", "dt": 1e-5}
    }))
    .unwrap();
    run_locally(&s, 2)
}

#[test]
fn a_dt_sweep_shows_each_integrators_order() {
    let table = order_sweep();
    assert!(table.rows.iter().all(|r| r.status == "succeeded"));
    let orders = table.convergence();
    assert_eq!(orders.len(), 5);
    for (convergence, expected) in orders.iter().zip([1.0, 1.0, 2.0, 4.0, 1.0]) {
        assert_eq!(convergence.points, 3);
        assert!(
            (convergence.order - expected).abs() <= 0.15,
            "{:?}: order {} expected {expected}",
            convergence.group,
            convergence.order
        );
    }
    let json = table.to_json();
    assert_eq!(json["convergence"].as_array().unwrap().len(), 5);
    assert_eq!(json["rows"][0]["values"], json!({"/integrator": "explicit_euler", "/dt": 0.004}));
    assert!(json["reference"]["status"] == "succeeded");
}

#[test]
fn the_csv_reads_back_with_a_standard_reader_and_the_svg_is_xml() {
    let table = order_sweep();
    let mut csv_bytes = Vec::new();
    write_csv(&table, &mut csv_bytes).unwrap();
    let mut reader = csv::Reader::from_reader(csv_bytes.as_slice());
    let headers = reader.headers().unwrap().clone();
    assert_eq!(&headers[0], "/integrator");
    assert_eq!(&headers[1], "/dt");
    let column = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let records: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(records.len(), 15);
    for (record, row) in records.iter().zip(&table.rows) {
        assert_eq!(record.len(), headers.len());
        assert_eq!(&record[column("status")], "succeeded");
        let error: f64 = record[column("error_vs_reference_max")].parse().unwrap();
        assert_eq!(error, row.reference_error.unwrap().0);
        assert_eq!(record[column("dt")].parse::<f64>().unwrap(), row.dt);
    }

    let mut svg = Vec::new();
    write_svg(&table, "orders", &mut svg).unwrap();
    let text = String::from_utf8(svg).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    let series: Vec<&str> = doc.descendants().filter_map(|n| n.attribute("data-integrator")).collect();
    assert_eq!(series, ["explicit_euler", "symplectic_euler", "verlet", "rk4", "implicit_euler"]);
    let labels: Vec<&str> =
        doc.descendants().filter(|n| n.has_tag_name("text")).filter_map(|n| n.text()).collect();
    assert!(labels.contains(&"wall time (s, log scale)") && labels.contains(&"error (m, log scale)"));
    assert!(labels.iter().any(|l| l.starts_with("1e-")));
    for polyline in doc.descendants().filter(|n| n.has_tag_name("polyline")) {
        assert_eq!(polyline.attribute("points").unwrap().split(' ').count(), 3);
    }
}

#[test]
fn thresholds_name_exactly_the_rows_and_groups_that_cross_them() {
    let table = order_sweep();
    let orders = |min_order| Thresholds { max_error: None, min_order: Some(min_order) }.crossings(&table);
    assert_eq!(orders(0.8), Vec::<String>::new());
    // First-order methods fall below 1.5; Verlet (2) and RK4 (4) keep it.
    let low = orders(1.5);
    assert_eq!(low.len(), 3, "{low:?}");
    for (line, integrator) in low.iter().zip(["explicit_euler", "symplectic_euler", "implicit_euler"]) {
        assert!(line.starts_with(&format!("/integrator = {integrator}: order ")), "{line}");
    }
    // The worst row against the reference: a bound just above it passes, just below names it alone.
    let (worst, worst_error) = table
        .rows
        .iter()
        .map(|r| (r, r.reference_error.unwrap().0))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    let errors = |max_error| Thresholds { max_error: Some(max_error), min_order: None }.crossings(&table);
    assert_eq!(errors(worst_error * 1.001), Vec::<String>::new());
    let crossed = errors(worst_error * 0.999);
    assert_eq!(crossed.len(), 1, "{crossed:?}");
    let dt = worst.values[1].as_f64().unwrap();
    assert!(
        crossed[0].starts_with(&format!("/integrator = {}, /dt = {dt}: error ", worst.integrator)),
        "{crossed:?}"
    );
}

#[test]
fn thresholds_that_cannot_apply_are_refused_before_the_sweep_runs() {
    let no_reference = sweep(json!({"scene": single_spring(), "vary": {"/dt": [0.01, 0.02]}})).unwrap();
    let min_order = Thresholds { max_error: None, min_order: Some(1.0) };
    assert_eq!(
        min_order.check(&no_reference),
        Err("--min-order needs a sweep that varies /dt and has a reference".into())
    );
    assert_eq!(Thresholds { max_error: Some(1e-3), min_order: None }.check(&no_reference), Ok(()));
    let negative = Thresholds { max_error: Some(-1.0), min_order: None };
    assert_eq!(negative.check(&no_reference), Err("--max-error must be a positive number, got -1".into()));
}

#[test]
fn a_table_reads_back_from_its_json_exactly() {
    let table = order_sweep();
    assert!(table.rows.iter().all(|r| r.energy.is_some() && r.reference_error.is_some()));
    assert_eq!(Table::from_json(&table.to_json()).unwrap(), table);
    // A row still queued has no step (NaN, left out of the JSON), which reads back as NaN.
    let mut pending = table.clone();
    pending.rows[0] = Row::without_result(pending.rows[0].values.clone(), "rk4", "queued", None);
    let read = Table::from_json(&pending.to_json()).unwrap();
    assert!(read.rows[0].dt.is_nan());
    assert_eq!(read.to_json(), pending.to_json());
    assert_eq!(read.rows[1..], pending.rows[1..]);
    let mut broken = table.to_json();
    broken["rows"][2]["steps"] = json!("many");
    assert_eq!(Table::from_json(&broken).unwrap_err(), "/rows/2/steps is not a whole number");
}

#[test]
fn a_table_is_written_as_json_member_by_member() {
    let finished = Row {
        values: vec![json!("rk4"), json!(0.5)],
        status: "succeeded".into(),
        detail: None,
        integrator: "rk4".into(),
        dt: 0.5,
        steps: 2,
        wall_time_s: 0.25,
        estimate: Some((1e-3, 5e-4)),
        reference_error: Some((0.125, f64::NAN)),
        max_strain: Some(0.0625),
        energy: Some(crate::solver::Energy { kinetic: 1.0, gravitational: -2.0, spring: 0.5 }),
    };
    let queued =
        Row::without_result(vec![json!("verlet"), json!(1)], "verlet", "queued", Some("waits".into()));
    let reference = Row { values: Vec::new(), reference_error: None, ..finished.clone() };
    let table = Table {
        pointers: vec!["/integrator".into(), "/dt".into()],
        rows: vec![finished, queued],
        reference: Some(reference),
    };
    let expected = concat!(
        r#"{"pointers":["/integrator","/dt"],"rows":["#,
        r#"{"values":{"/integrator":"rk4","/dt":0.5},"status":"succeeded","integrator":"rk4","steps":2,"#,
        r#""wall_time_s":0.25,"dt":0.5,"error_estimate":{"max":0.001,"rms":0.0005},"#,
        r#""error_vs_reference":{"max":0.125,"rms":null},"max_strain":0.0625,"#,
        r#""energy":{"kinetic":1.0,"gravitational":-2.0,"spring":0.5}},"#,
        r#"{"values":{"/integrator":"verlet","/dt":1},"status":"queued","integrator":"verlet","steps":0,"#,
        r#""wall_time_s":0.0,"detail":"waits"}],"#,
        r#""reference":{"values":{},"status":"succeeded","integrator":"rk4","steps":2,"wall_time_s":0.25,"#,
        r#""dt":0.5,"error_estimate":{"max":0.001,"rms":0.0005},"max_strain":0.0625,"#,
        r#""energy":{"kinetic":1.0,"gravitational":-2.0,"spring":0.5}}}"#,
    );
    assert_eq!(serde_json::to_string(&table).unwrap(), expected);
    assert_eq!(table.to_json().to_string(), expected);
}
