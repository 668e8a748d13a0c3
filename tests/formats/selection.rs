//! Choosing a format: in the scene, on the command line, and what happens when the format
//! cannot carry what was asked.

use std::process::Command;

use drape::output::Format;
use drape::scene::{Field, Scene};

use crate::common::{Run, mixed_scene, scratch_dir};

#[test]
fn a_scene_asking_a_format_for_a_field_it_cannot_carry_is_invalid_at_that_field() {
    let scene = r#"{"duration": 1, "bodies": [{"type": "chain"}],
                    "output": {"format": "obj", "fields": ["positions", "normals", "velocities"]}}"#;
    let error = Scene::from_json(scene.as_bytes()).unwrap_err();
    let problems = error.field_errors();
    assert_eq!(problems.len(), 1, "{error}");
    assert_eq!(problems[0].pointer, "/output/fields/2");
    assert!(problems[0].detail.contains("velocities"), "{}", problems[0].detail);

    let pc2_without_frames = r#"{"duration": 1, "bodies": [{"type": "chain"}],
                                 "output": {"format": "pc2", "frames": "none"}}"#;
    let error = Scene::from_json(pc2_without_frames.as_bytes()).unwrap_err();
    assert_eq!(error.field_errors()[0].pointer, "/output/frames");

    let npy_with_energy = r#"{"duration": 0.1, "bodies": [{"type": "chain"}],
                              "output": {"format": "npy", "fields": ["positions", "energy"]}}"#;
    let scene = Scene::from_json(npy_with_energy.as_bytes()).expect("npy with more fields is sent as npz");
    assert_eq!(scene.output.format.for_fields(&scene.output.fields), Format::Npz);
}

#[test]
fn only_what_was_asked_is_computed_even_where_the_format_shows_normals() {
    let run = Run::new(&mixed_scene("f32", "all", &["positions"]));
    let stages = run.json["stats"]["stages"].as_array().unwrap();
    assert!(!stages.iter().any(|s| s == "normals"), "{stages:?}");
    assert!(run.recording.frames.normals.is_none());
    // The glTF still has normals for display, computed by the encoder from the last frame.
    let gltf = gltf::Gltf::from_slice(&run.encode(Format::Glb)).unwrap();
    assert!(
        gltf.meshes().next().unwrap().primitives().next().unwrap().get(&gltf::Semantic::Normals).is_some()
    );

    let with_normals = Run::new(&mixed_scene("f32", "all", &["positions", "normals"]));
    assert!(with_normals.json["stats"]["stages"].as_array().unwrap().iter().any(|s| s == "normals"));
}

#[test]
fn encode_refuses_rather_than_drops_a_field() {
    let run = Run::new(&mixed_scene("f64", "final", &["positions", "energy"]));
    for format in [Format::Glb, Format::Obj, Format::Npy, Format::Pc2] {
        let error = drape::output::encode(&run.recording, format, Vec::new()).unwrap_err();
        assert_eq!(error.kind(), std::io::ErrorKind::InvalidInput, "{format:?}");
        assert!(error.to_string().contains("energy"), "{error}");
    }
    assert!(drape::output::encode(&run.recording, Format::Npz, Vec::new()).is_ok());
}

#[test]
fn encode_fields_writes_what_a_run_recording_only_those_fields_would() {
    let every =
        Run::new(&mixed_scene("f64", "all", &["positions", "velocities", "normals", "energy", "strain"]));
    let mesh = Run::new(&mixed_scene("f64", "all", &["positions", "normals"]));
    let positions = Run::new(&mixed_scene("f64", "all", &["positions"]));
    let cases = [
        (Format::Glb, &mesh, &[Field::Normals, Field::Positions][..]),
        (Format::Obj, &mesh, &[Field::Positions, Field::Normals][..]),
        (Format::Npz, &mesh, &[Field::Positions, Field::Normals][..]),
        (Format::Npy, &positions, &[Field::Positions][..]),
        (Format::Pc2, &positions, &[Field::Positions][..]),
        // Display normals computed from the positions, as for a run that recorded none.
        (Format::Glb, &positions, &[Field::Positions][..]),
    ];
    for (format, expected, fields) in cases {
        let mut bytes = Vec::new();
        drape::output::encode_fields(&every.recording, fields, format, &mut bytes).unwrap();
        assert!(bytes == expected.encode(format), "{format:?} {fields:?}");
    }
    // JSON: the frames as the smaller run's (the statistics differ: it ran fewer stages).
    let mut bytes = Vec::new();
    drape::output::encode_fields(
        &every.recording,
        &[Field::Positions, Field::Normals],
        Format::Json,
        &mut bytes,
    )
    .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
    assert_eq!(json["frames"], mesh.json["frames"]);

    // Every field named must be recorded and carried.
    let mut bytes = Vec::new();
    let error = drape::output::encode_fields(&mesh.recording, &[Field::Energy], Format::Json, &mut bytes)
        .unwrap_err();
    assert!(error.to_string().contains("did not record energy"), "{error}");
    let error = drape::output::encode_fields(
        &every.recording,
        &[Field::Positions, Field::Strain],
        Format::Obj,
        &mut bytes,
    )
    .unwrap_err();
    assert!(error.to_string().contains("cannot carry strain"), "{error}");
    assert!(bytes.is_empty());
}

#[test]
fn drape_run_writes_the_format_asked_for() {
    let dir = scratch_dir("cli");
    let scene = dir.join("scene.json");
    std::fs::write(&scene, mixed_scene("f32", "all", &["positions"])).unwrap();
    let drape = env!("CARGO_BIN_EXE_drape");
    for (format, magic) in
        [("glb", b"glTF".as_slice()), ("pc2", b"POINTCACHE2\0"), ("npy", b"\x93NUMPY"), ("obj", b"# drape")]
    {
        let out = dir.join(format!("result.{format}"));
        let status = Command::new(drape)
            .arg("run")
            .arg(&scene)
            .args(["--format", format, "-o"])
            .arg(&out)
            .status()
            .unwrap();
        assert!(status.success(), "{format}");
        assert!(std::fs::read(&out).unwrap().starts_with(magic), "{format}");
    }

    // A format chosen over the scene's gets what it carries, and the rest is named on stderr.
    std::fs::write(&scene, mixed_scene("f32", "all", &["positions", "strain", "energy"])).unwrap();
    let out = dir.join("carried.pc2");
    let carried = Command::new(drape)
        .arg("run")
        .arg(&scene)
        .args(["--format", "pc2", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(carried.status.success(), "{}", String::from_utf8_lossy(&carried.stderr));
    let stderr = String::from_utf8_lossy(&carried.stderr);
    assert!(stderr.contains("pc2 cannot carry energy, strain;"), "{stderr}");
    let positions_only = Run::new(&mixed_scene("f32", "all", &["positions"]));
    assert_eq!(std::fs::read(&out).unwrap(), positions_only.encode(Format::Pc2));
    let all = Command::new(drape)
        .arg("run")
        .arg(&scene)
        .args(["--format", "npz", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(all.status.success() && all.stderr.is_empty(), "{}", String::from_utf8_lossy(&all.stderr));

    // What is left must still be enough: a mesh format needs positions.
    std::fs::write(&scene, mixed_scene("f32", "all", &["energy"])).unwrap();
    let refused = Command::new(drape).arg("run").arg(&scene).args(["--format", "glb"]).output().unwrap();
    assert_eq!(refused.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(stderr.contains("/output/fields: ") && stderr.contains("needs positions"), "{stderr}");

    let unknown = Command::new(drape).arg("run").arg(&scene).args(["--format", "fbx"]).output().unwrap();
    assert!(!unknown.status.success());
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("unknown format"));
}
