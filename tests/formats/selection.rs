//! Choosing a format: in the scene, on the command line, and what happens when the format
//! cannot carry what was asked.

use std::process::Command;

use drape::output::Format;
use drape::scene::Scene;

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

    std::fs::write(&scene, mixed_scene("f32", "all", &["positions", "strain"])).unwrap();
    let refused = Command::new(drape).arg("run").arg(&scene).args(["--format", "pc2"]).output().unwrap();
    assert_eq!(refused.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(stderr.contains("/output/fields/1"), "{stderr}");

    let unknown = Command::new(drape).arg("run").arg(&scene).args(["--format", "fbx"]).output().unwrap();
    assert!(!unknown.status.success());
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("unknown format"));
}
