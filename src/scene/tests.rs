//! The scene contract: defaults, the errors each bad input gets, and the time plan.

use serde_json::{Value, json};

use super::*;

fn scene(value: Value) -> Result<Scene, SceneError> {
    Scene::from_json(value.to_string().as_bytes())
}

fn cloth() -> Value {
    json!({"type": "cloth", "resolution": [4, 3]})
}

/// A valid scene with `change` applied at a JSON Pointer (a null value removes the field).
fn with(pointer: &str, change: Value) -> Value {
    let mut doc = json!({"duration": 1.0, "bodies": [cloth()]});
    let (parent, key) = pointer.rsplit_once('/').unwrap();
    let target = doc.pointer_mut(parent).unwrap();
    match (target, change) {
        (Value::Object(map), Value::Null) => {
            map.remove(key);
        }
        (Value::Object(map), value) => {
            map.insert(key.to_string(), value);
        }
        (Value::Array(items), value) => items[key.parse::<usize>().unwrap()] = value,
        _ => unreachable!(),
    }
    doc
}

#[test]
fn a_minimal_scene_takes_every_default() {
    let s = scene(json!({"duration": 2.0, "bodies": [{"type": "cloth"}]})).unwrap();
    assert_eq!(s.integrator, IntegratorName::SymplecticEuler);
    assert_eq!(s.precision, Precision::F64);
    assert_eq!(s.gravity, [0.0, -9.81, 0.0]);
    assert_eq!((s.dt, s.drag, s.stop_at_rest), (None, 0.0, None));
    assert_eq!(s.output, Output::default());
    let Body::Cloth(c) = &s.bodies[0] else { panic!("not a cloth") };
    assert_eq!(c, &ClothSpec::default());
    assert_eq!(s.bodies[0].particle_count(), 32 * 32);
}

#[test]
fn each_bad_field_is_named_by_its_pointer() {
    let cases: Vec<(Value, &[&str])> = vec![
        (with("/duration", json!(0)), &["/duration"]),
        (with("/duration", json!(-1.5)), &["/duration"]),
        (with("/duration", Value::Null), &["/duration"]),
        (with("/duration", json!("long")), &["/duration"]),
        (with("/dt", json!(0.0)), &["/dt"]),
        (with("/integrator", json!("rk5")), &["/integrator"]),
        (with("/precision", json!("f16")), &["/precision"]),
        (with("/gravity", json!([0, -9.81])), &["/gravity"]),
        (with("/drag", json!(-0.1)), &["/drag"]),
        (with("/verlet_damping", json!(1.0)), &["/verlet_damping"]),
        (with("/solver", json!({"tolerance": 0})), &["/solver/tolerance"]),
        (with("/solver", json!({"max_iterations": 0})), &["/solver/max_iterations"]),
        (with("/solver", json!({"tolerance": 1e-13})), &["/solver/tolerance"]),
        (with("/solver", json!({"tolerance": 0.2})), &["/solver/tolerance"]),
        (with("/solver", json!({"max_iterations": 10_001})), &["/solver/max_iterations"]),
        (with("/solver", json!({"reduction": -0.01})), &["/solver/reduction"]),
        (with("/solver", json!({"reduction": 0.2})), &["/solver/reduction"]),
        (with("/solver", json!({"tol": 1e-3})), &["/solver/tol"]),
        (with("/stop_at_rest", json!(0)), &["/stop_at_rest"]),
        (with("/colour", json!("red")), &["/colour"]),
        (with("/bodies", json!([])), &["/bodies"]),
        (with("/bodies/0", json!(3)), &["/bodies/0"]),
        (with("/bodies/0", json!({"resolution": [4, 4]})), &["/bodies/0/type"]),
        (with("/bodies/0", json!({"type": "blob"})), &["/bodies/0/type"]),
        (with("/bodies/0", json!({"type": "cloth", "resolution": [1, 4]})), &["/bodies/0/resolution/0"]),
        (with("/bodies/0", json!({"type": "cloth", "resolution": [4, -4]})), &["/bodies/0/resolution/1"]),
        (with("/bodies/0", json!({"type": "cloth", "size": [1, 0]})), &["/bodies/0/size/1"]),
        (with("/bodies/0", json!({"type": "cloth", "mass": 0})), &["/bodies/0/mass"]),
        (with("/bodies/0", json!({"type": "cloth", "mas": 1})), &["/bodies/0/mas"]),
        (with("/bodies/0", json!({"type": "cloth", "orientation": "diagonal"})), &["/bodies/0/orientation"]),
        (with("/bodies/0", json!({"type": "cloth", "pin": [[0, 0], [32, 5]]})), &["/bodies/0/pin/1/0"]),
        (with("/bodies/0", json!({"type": "cloth", "pin": [[1.5, 0]]})), &["/bodies/0/pin/0/0"]),
        (
            with("/bodies/0", json!({"type": "cloth", "springs": {"shear": {"k": -5}}})),
            &["/bodies/0/springs/shear/k"],
        ),
        (
            with("/bodies/0", json!({"type": "cloth", "springs": {"bending": {"k": 5, "damping": -1}}})),
            &["/bodies/0/springs/bending/damping"],
        ),
        (with("/bodies/0", json!({"type": "chain", "count": 1})), &["/bodies/0/count"]),
        (with("/bodies/0", json!({"type": "chain", "pin": [10]})), &["/bodies/0/pin/0"]),
        (
            with("/bodies/0", json!({"type": "chain", "spring": {"k": 1, "rest_length": -1}})),
            &["/bodies/0/spring/rest_length"],
        ),
        (with("/bodies/0", json!({"type": "lattice", "resolution": [2, 2, 1]})), &["/bodies/0/resolution/2"]),
        (with("/bodies/0", json!({"type": "lattice", "pin": [[0, 0, 6]]})), &["/bodies/0/pin/0/2"]),
        (with("/bodies/0", json!({"type": "mesh", "vertices": [0, 0, 0]})), &["/bodies/0/triangles"]),
        (
            with(
                "/bodies/0",
                json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1], "triangles": [0, 1, 2]}),
            ),
            &["/bodies/0/vertices", "/bodies/0/triangles/2"],
        ),
        (
            with(
                "/bodies/0",
                json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0, 1, 3]}),
            ),
            &["/bodies/0/triangles/2"],
        ),
        (
            with(
                "/bodies/0",
                json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 2, 0, 0], "triangles": [0, 1, 2]}),
            ),
            &["/bodies/0/vertices"],
        ),
        (
            with(
                "/bodies/0",
                json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0, 1, 1]}),
            ),
            &["/bodies/0/triangles/0", "/bodies/0/vertices"],
        ),
        (
            with(
                "/bodies/0",
                json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0, 1, 2], "springs": {"shear": {"k": 1}}}),
            ),
            &["/bodies/0/springs/shear"],
        ),
        (with("/gravity", json!([0, -1e7, 0])), &["/gravity"]),
        (with("/drag", json!(1e31)), &["/drag"]),
        (with("/bodies/0", json!({"type": "cloth", "center": [0, 6.35e136, 0]})), &["/bodies/0/center"]),
        (with("/bodies/0", json!({"type": "cloth", "velocity": [2e6, 0, 0]})), &["/bodies/0/velocity"]),
        (with("/bodies/0", json!({"type": "cloth", "size": [1, 2e6]})), &["/bodies/0/size/1"]),
        (with("/bodies/0", json!({"type": "cloth", "mass": 5e-324})), &["/bodies/0/mass"]),
        (
            with("/bodies/0", json!({"type": "cloth", "springs": {"bending": {"k": 1e31}}})),
            &["/bodies/0/springs/bending/k"],
        ),
        (
            with(
                "/bodies/0",
                json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1e7, 0], "triangles": [0, 1, 2]}),
            ),
            &["/bodies/0/vertices"],
        ),
        (with("/colliders", json!([{"type": "plane", "normal": [1e-300, 0, 0]}])), &["/colliders/0/normal"]),
        (
            with("/colliders", json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1e7}])),
            &["/colliders/0/radius"],
        ),
        (with("/output", json!({"fps": 0})), &["/output/fps"]),
        (with("/output", json!({"frames": "some"})), &["/output/frames"]),
        (with("/output", json!({"fields": ["positions", "colour"]})), &["/output/fields/1"]),
        (with("/output", json!({"fields": ["energy", "energy"]})), &["/output/fields/1"]),
        (
            json!({"duration": -1, "dt": -1, "bodies": [{"type": "cloth", "mass": -1}, {"type": "chain", "count": 0}]}),
            &["/duration", "/dt", "/bodies/0/mass", "/bodies/1/count"],
        ),
    ];
    for (document, expected) in cases {
        let error = scene(document.clone()).expect_err(&format!("accepted {document}"));
        let pointers: Vec<&str> = error.field_errors().iter().map(|e| e.pointer.as_str()).collect();
        assert_eq!(pointers, expected, "{document}: {error}");
        assert!(error.field_errors().iter().all(|e| !e.detail.is_empty()));
    }
}

#[test]
fn malformed_json_reports_where() {
    let error = Scene::from_json(b"{\"duration\": 1,\n \"bodies\": [").unwrap_err();
    let SceneError::Syntax { line, .. } = error else { panic!("{error:?}") };
    assert_eq!(line, 2);
}

#[test]
fn the_step_divides_the_duration_and_never_grows() {
    for (duration, dt, steps) in
        [(1.0, 1e-3, 1000), (1.0, 0.3, 4), (2.0, 0.0005, 4000), (0.1, 1.0, 1), (1.0, 0.1, 10)]
    {
        let s = scene(json!({"duration": duration, "dt": dt, "bodies": [cloth()]})).unwrap();
        let compiled = s.compile();
        assert_eq!(compiled.steps, steps, "duration {duration}, dt {dt}");
        assert!(compiled.config.dt <= dt);
        assert!((compiled.config.dt * steps as f64 - duration).abs() <= 1e-12 * duration);
        assert_eq!(compiled.dt_source, DtSource::Scene);
    }
}

#[test]
fn without_dt_the_step_is_half_the_stability_bound() {
    let s = scene(json!({"duration": 1.0, "bodies": [cloth()]})).unwrap();
    let compiled = s.compile();
    let bound = crate::solver::stable_step(&compiled.model, 0.0).unwrap();
    assert_eq!(compiled.dt_source, DtSource::Stability);
    assert!(compiled.config.dt <= 0.5 * bound && compiled.config.dt > 0.49 * bound);
}

#[test]
fn without_dt_implicit_euler_takes_half_the_frame_interval_in_contact_and_a_quarter_without() {
    let implicit = |colliders: Value, fps: f64| {
        let s = scene(json!({"duration": 1.0, "integrator": "implicit_euler", "bodies": [cloth()],
                             "colliders": colliders, "output": {"fps": fps}}))
        .unwrap();
        let compiled = s.compile();
        assert_eq!(compiled.dt_source, DtSource::Stability);
        compiled.config.dt
    };
    let floor = json!([{"type": "plane"}]);
    assert_eq!(implicit(json!([]), 30.0), 1.0 / 120.0);
    assert_eq!(implicit(floor.clone(), 30.0), 1.0 / 60.0);
    assert_eq!(implicit(floor, 24.0), 1.0 / 48.0);
}

#[test]
fn bodies_take_consecutive_particle_ranges_and_default_names() {
    let s = scene(json!({"duration": 1.0, "bodies": [
        cloth(),
        {"type": "chain", "name": "rope", "count": 5},
        {"type": "lattice", "resolution": [2, 3, 4]},
        {"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0], "triangles": [0, 1, 2, 2, 1, 3], "mass": 2.0}
    ]}))
    .unwrap();
    let compiled = s.compile();
    let summary: Vec<(&str, &str, usize, usize)> =
        compiled.bodies.iter().map(|b| (b.name.as_str(), b.kind, b.offset, b.count)).collect();
    assert_eq!(
        summary,
        [
            ("cloth0", "cloth", 0, 12),
            ("rope", "chain", 12, 5),
            ("lattice2", "lattice", 17, 24),
            ("mesh3", "mesh", 41, 4)
        ]
    );
    // Mesh mass is spread by area: the two corners on both triangles carry twice the others.
    let masses = &compiled.model.masses[41..];
    for (mass, expected) in masses.iter().zip([2.0 / 6.0, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 6.0]) {
        assert!((mass - expected).abs() < 1e-15, "{masses:?}");
    }
    // Structural edges (5) and one bending spring across the shared edge.
    let mesh_springs = compiled.model.springs.iter().filter(|s| s.i >= 41).count();
    assert_eq!(mesh_springs, 6);
    for body in &s.bodies {
        let built = compiled.bodies.iter().find(|b| b.kind == body.type_name()).unwrap();
        assert_eq!(body.particle_count(), built.count as u64);
    }
}

#[test]
fn spring_counts_are_known_before_building() {
    for body in [json!({"type": "cloth", "resolution": [7, 5]}), json!({"type": "chain", "count": 9})] {
        let s = scene(json!({"duration": 1.0, "bodies": [body]})).unwrap();
        assert_eq!(s.bodies[0].spring_count(), s.compile().model.springs.len() as u64);
    }
}

#[test]
fn integer_fields_take_integral_floats_and_refuse_fractions_at_their_pointer() {
    let floats = json!({"duration": 1.0, "solver": {"max_iterations": 39.0}, "bodies": [
        {"type": "cloth", "resolution": [4.0, 3.0], "pin": [[0.0, 0], [3, 2.0]]},
        {"type": "chain", "count": 5.0, "pin": [4.0]},
        {"type": "lattice", "resolution": [2.0, 2, 2e0], "pin": [[1.0, 1.0, 1.0]]},
        {"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0.0, 1.0, 2.0], "pin": [2.0]}
    ]});
    let integers = json!({"duration": 1.0, "solver": {"max_iterations": 39}, "bodies": [
        {"type": "cloth", "resolution": [4, 3], "pin": [[0, 0], [3, 2]]},
        {"type": "chain", "count": 5, "pin": [4]},
        {"type": "lattice", "resolution": [2, 2, 2], "pin": [[1, 1, 1]]},
        {"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0, 1, 2], "pin": [2]}
    ]});
    let read = scene(floats).unwrap();
    assert_eq!(read, scene(integers).unwrap());
    assert_eq!(read.solver.max_iterations, 39);

    let range = format!("expected a whole number from 0 to {}", usize::MAX);
    let cases = [
        (with("/solver", json!({"max_iterations": 39.5})), "/solver/max_iterations", "floating point `39.5`"),
        (
            with("/bodies/0", json!({"type": "cloth", "resolution": [4, 3.25]})),
            "/bodies/0/resolution/1",
            "floating point `3.25`",
        ),
        (
            with("/bodies/0", json!({"type": "chain", "count": 1e300})),
            "/bodies/0/count",
            "floating point `1e+300`",
        ),
        (
            with("/bodies/0", json!({"type": "chain", "pin": [0, -1.0]})),
            "/bodies/0/pin/1",
            "floating point `-1.0`",
        ),
        (
            with("/bodies/0", json!({"type": "lattice", "pin": [[0, 0, 0.5]]})),
            "/bodies/0/pin/0/2",
            "floating point `0.5`",
        ),
        (
            with("/bodies/0", json!({"type": "mesh", "vertices": [0, 0, 0], "triangles": [0, 0.1, 0]})),
            "/bodies/0/triangles/1",
            "floating point `0.1`",
        ),
    ];
    for (document, pointer, value) in cases {
        let error = scene(document.clone()).expect_err(&format!("accepted {document}"));
        let errors = error.field_errors();
        assert_eq!(errors.len(), 1, "{error}");
        assert_eq!(errors[0].pointer, pointer, "{document}");
        assert_eq!(errors[0].detail, format!("invalid value: {value}, {range}"), "{document}");
    }
}

/// The edges of every range a scene may use still compile to a model whose first frame is
/// finite in single precision, so that no number out of range reaches a result as `null`.
#[test]
fn the_widest_valid_scene_starts_finite_in_single_precision() {
    let extreme = json!({
        "duration": 1e-30, "precision": "f32", "gravity": [1e6, -1e6, 1e6], "drag": 1e30,
        "bodies": [
            {"type": "cloth", "resolution": [3, 3], "size": [1e6, 1e-30], "center": [1e6, -1e6, 1e6],
             "mass": 1e-30, "velocity": [-1e6, 1e6, -1e6],
             "springs": {"structural": {"k": 1e30, "damping": 1e30}, "shear": {"k": 1e-30}}},
            {"type": "lattice", "resolution": [2, 2, 2], "size": [1e-30, 1e6, 1e-30], "center": [-1e6, 1e6, -1e6],
             "mass": 1e30}
        ]
    });
    let compiled = scene(extreme).unwrap().compile();
    let positions = compiled.model.positions.iter().flat_map(|p| p.to_array());
    assert!(positions.clone().count() > 0);
    assert!(positions.map(|x| x as f32).all(f32::is_finite));
    assert!(compiled.model.masses.iter().all(|&m| (m as f32).is_normal()));
}

/// The one problem a scene with `error_estimate: "resolution"` gets, at `/error_estimate`.
fn resolution_refusal(bodies: Value) -> String {
    let error =
        scene(json!({"duration": 1.0, "error_estimate": "resolution", "bodies": bodies})).unwrap_err();
    let errors = error.field_errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(errors[0].pointer, "/error_estimate");
    errors[0].detail.clone()
}

#[test]
fn the_spatial_estimate_is_refused_with_the_reason_for_bodies_that_do_not_keep_their_material() {
    let material =
        |resolution: usize| json!({"type": "cloth", "resolution": [resolution, 12], "material": "cotton"});
    let chain = resolution_refusal(json!([material(9), {"type": "chain"}]));
    assert!(chain.contains("/bodies/1 is a chain"), "{chain}");
    let springs = resolution_refusal(json!([{"type": "cloth", "resolution": [17, 17]}]));
    assert!(springs.contains("/bodies/0 has spring constants"), "{springs}");
    let small = resolution_refusal(json!([material(8)]));
    assert!(small.contains("at least 9 particles") && small.contains("[8, 12]"), "{small}");
    let disk = resolution_refusal(
        json!([{"type": "cloth", "shape": "disk", "resolution": [7, 7], "material": "cotton"}]),
    );
    assert!(disk.contains("at least 4 rings") && disk.contains("has 3"), "{disk}");
    // A material whose particles would be too heavy at a quarter of the resolution is refused
    // for its companion, not for itself.
    let heavy = json!({"type": "cloth", "size": [1e6, 1e6], "resolution": [9, 9],
        "material": {"density": 1e19, "stretch": 100, "shear": 1, "bending": 1}});
    assert!(scene(json!({"duration": 1.0, "error_estimate": "none", "bodies": [heavy]})).is_ok());
    let companion = resolution_refusal(json!([heavy]));
    assert!(
        companion.contains("the companion at resolution [3, 3]") && companion.contains("particle mass"),
        "{companion}"
    );
    // Cloths of a material, rectangles and disks, are accepted, and compile with their companions.
    let accepted = scene(json!({"duration": 1.0, "error_estimate": "resolution",
        "bodies": [material(10), {"type": "cloth", "shape": "disk", "resolution": [9, 9], "material": "denim"}]}))
    .unwrap();
    let compiled = accepted.compile();
    let particles: Vec<usize> = compiled.coarser.iter().map(|c| c.compiled.model.particle_count()).collect();
    // [10, 12] → [5, 6] → [3, 3]; 4 rings → 2 → 1: 61 → 19 → 7 particles.
    assert_eq!(particles, [5 * 6 + 19, 3 * 3 + 7]);
    assert_eq!(compiled.coarser[1].on_main.len(), 3 * 3 + 7);
    assert!(
        compiled
            .coarser
            .iter()
            .all(|c| c.compiled.config.dt == compiled.config.dt && c.compiled.steps == compiled.steps)
    );
}
