//! The JSON result is drape's canonical form: reading it back gives a recording that writes the
//! same bytes and encodes every other format exactly as the original run does.

use drape::output::{Format, encode, read_json, write_json};
use drape::run::{Control, Recording, execute};
use drape::scene::Scene;

fn run(scene: &str) -> Recording {
    let scene = Scene::from_json(scene.as_bytes()).unwrap_or_else(|e| panic!("{e}"));
    execute(&scene.compile(), &Control::new())
}

fn json(recording: &Recording) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_json(recording, &mut bytes).unwrap();
    bytes
}

const CLOTH: &str = r#"{"type": "cloth", "resolution": [6, 5], "pin": [[0, 0], [5, 0]]}"#;

fn scenes() -> Vec<String> {
    let all_fields = r#"["positions", "velocities", "normals", "energy", "strain"]"#;
    vec![
        format!(r#"{{"duration": 0.1, "dt": 0.001, "bodies": [{CLOTH}], "output": {{"fps": 30, "fields": {all_fields}}}}}"#),
        format!(r#"{{"duration": 0.1, "dt": 0.001, "precision": "f32", "bodies": [{CLOTH}], "output": {{"fps": 30, "fields": {all_fields}}}}}"#),
        format!(r#"{{"duration": 0.05, "dt": 0.005, "integrator": "implicit_euler", "error_estimate": "richardson3", "bodies": [{CLOTH}], "output": {{"frames": "final"}}}}"#),
        format!(r#"{{"duration": 0.05, "dt": 0.001, "error_estimate": "none", "bodies": [{CLOTH}], "output": {{"frames": "none"}}}}"#),
        r#"{"duration": 0.05, "dt": 0.005, "integrator": "implicit_euler", "error_estimate": "resolution", "bodies": [{"type": "cloth", "size": [0.5, 0.5], "resolution": [9, 9], "material": "cotton", "pin": [[0, 0], [8, 0]]}], "output": {"frames": "final"}}"#.to_string(),
        r#"{"duration": 1, "dt": 0.05, "bodies": [{"type": "chain", "count": 3, "mass": 0.001, "pin": [0], "spring": {"k": 100000}}], "output": {"fps": 100}}"#.to_string(),
        r#"{"duration": 20, "dt": 0.01, "integrator": "implicit_euler", "stop_at_rest": 0.001, "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [0, -1, 0], "count": 5, "pin": [0], "spring": {"k": 100, "damping": 1}}], "output": {"fps": 2}}"#.to_string(),
        format!(
            r#"{{"duration": 0.05, "dt": 0.0005, "drag": 0.1, "bodies": [{CLOTH}, {{"type": "lattice", "resolution": [3, 3, 3]}}, {{"type": "mesh", "vertices": [0, 2, 0, 1, 2, 0, 0, 2, 1], "triangles": [0, 1, 2]}}],
                "colliders": [{{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]}}, {{"type": "sphere", "center": [0, 0.5, 0], "radius": 0.2}},
                              {{"type": "box", "center": [1, 0.5, 0], "half_extents": [0.1, 0.1, 0.1]}}, {{"type": "cylinder", "center": [-1, 0.5, 0], "radius": 0.1, "height": 0.2}}],
                "wind": {{"model": "viscous", "velocity": [1, 0, 0]}}, "strain_limit": 0.1, "self_collision": {{"thickness": 0.005}},
                "output": {{"fields": ["positions", "normals"]}}}}"#
        ),
    ]
}

#[test]
fn writing_what_was_read_gives_the_same_bytes() {
    for scene in scenes() {
        let recording = run(&scene);
        let written = json(&recording);
        let read = read_json(&written).unwrap_or_else(|e| panic!("{scene}: {e}"));
        assert_eq!(read, recording, "{scene}");
        assert_eq!(json(&read), written, "{scene}");
    }
}

#[test]
fn a_run_at_rest_reads_back_its_distance_from_equilibrium() {
    let scene = &scenes()[6];
    let recording = run(scene);
    let equilibrium = recording.stats.error.as_ref().and_then(|e| e.equilibrium);
    assert!(equilibrium.is_some_and(|q| q.residual_relative.is_some()), "{scene}");
    let read = read_json(&json(&recording)).unwrap();
    assert_eq!(read.stats.error.and_then(|e| e.equilibrium), equilibrium);
}

#[test]
fn a_spatial_estimate_reads_back_without_a_companion_step() {
    let scene = &scenes()[4];
    let recording = run(scene);
    let error = recording.stats.error.as_ref().expect("an estimate");
    assert_eq!((error.method.name(), error.companion_step), ("resolution", None), "{scene}");
    assert!(
        matches!(error.outcome, drape::run::EstimateOutcome::Estimate { observed_order: Some(_), .. }),
        "{error:?}"
    );
    let written = json(&recording);
    let value: serde_json::Value = serde_json::from_slice(&written).unwrap();
    assert!(value["stats"]["error"].get("companion_step").is_none(), "{}", value["stats"]["error"]);
    assert_eq!(read_json(&written).unwrap().stats.error.as_ref(), Some(error));
}

#[test]
fn every_format_encodes_the_same_from_the_json_as_from_the_run() {
    let scene = format!(
        r#"{{"duration": 0.1, "dt": 0.001, "precision": "f32", "bodies": [{CLOTH}], "output": {{"fps": 30}}}}"#
    );
    let recording = run(&scene);
    let read = read_json(&json(&recording)).unwrap();
    for format in [Format::Glb, Format::Obj, Format::Npy, Format::Pc2] {
        let (mut direct, mut transcoded) = (Vec::new(), Vec::new());
        encode(&recording, format, &mut direct).unwrap();
        encode(&read, format, &mut transcoded).unwrap();
        assert!(!direct.is_empty());
        assert_eq!(direct, transcoded, "{}", format.name());
    }
}

#[test]
fn other_bytes_are_refused_not_misread() {
    assert!(read_json(b"{\"mesh\": 1}").is_err());
    assert!(read_json(b"not json").is_err());
    let recording = run(&scenes()[3]);
    let text = String::from_utf8(json(&recording)).unwrap().replace("\"symplectic_euler\"", "\"leapfrog\"");
    assert!(read_json(text.as_bytes()).is_err());
}

/// A chain thrown up by a step of 1e16 s: it diverges at the first step, leaving its first frame.
const DIVERGING: &str = r#"{"duration": 1e17, "dt": 1e16, "gravity": [0, 1e6, 0], "error_estimate": "none",
    "bodies": [{"type": "chain", "count": 3}], "output": {"fps": 1e-16, "fields": ["positions", "energy"]}}"#;

#[test]
fn a_number_that_is_not_finite_is_null_and_reads_back_as_nan() {
    let mut recording = run(DIVERGING);
    assert_eq!(recording.stats.status.name(), "diverged");
    // No scene within its ranges records a number that is not finite (energies are summed in
    // f64 from bounded inputs, and the watch stops a run before a non-finite state is recorded),
    // so they are put in: an energy, velocities, a stored statistic and a strain.
    recording.frames.energy.as_mut().unwrap()[0].gravitational = f64::INFINITY;
    recording.frames.velocities = Some([f64::NAN, f64::INFINITY, 0.5].repeat(recording.particles).into());
    recording.frames.strain = Some(vec![f64::NEG_INFINITY; recording.springs]);
    recording.stats.max_strain = Some(f64::INFINITY);

    let written = json(&recording);
    let value: serde_json::Value = serde_json::from_slice(&written).unwrap();
    let frame = &value["frames"][0];
    assert_eq!(frame["energy"]["kinetic"], 0.0);
    assert_eq!(frame["energy"]["gravitational"], serde_json::Value::Null);
    assert_eq!(
        frame["velocities"].as_array().unwrap()[0..3],
        [serde_json::Value::Null, serde_json::Value::Null, 0.5.into()]
    );
    assert_eq!(frame["strain"].as_array().unwrap().iter().filter(|s| s.is_null()).count(), recording.springs);
    assert_eq!(value["stats"]["max_strain"], serde_json::Value::Null);
    assert!(value["stats"].get("energy").is_none(), "a statistic that does not apply is left out");

    let read = read_json(&written).unwrap();
    assert!(read.frames.energy.as_ref().unwrap()[0].gravitational.is_nan());
    let drape::run::Samples::F64(velocities) = read.frames.velocities.as_ref().unwrap() else { panic!() };
    assert_eq!(velocities.iter().filter(|v| v.is_nan()).count(), 2 * recording.particles);
    assert_eq!(velocities[2], 0.5);
    assert!(read.frames.strain.as_ref().unwrap().iter().all(|s| s.is_nan()));
    assert!(read.stats.max_strain.unwrap().is_nan());
    assert_eq!(read.stats.energy, None);
    assert_eq!(read.stats.diverged, recording.stats.diverged);
    assert_eq!(json(&read), written, "writing what was read gives the same bytes");
}
