//! Mesh files read back: a GLB written by drape's own encoder is read by the asset reader into
//! the mesh it shows, and `drape run` puts the mesh of a scene's `"file"` in place.

use std::process::Command;

use drape::assets::{MeshLimits, read_glb};
use drape::jobs::Limits;
use drape::output::{Format, encode};
use drape::run::{Control, execute};
use drape::scene::Scene;
use serde_json::{Value, json};

const LIMITS: MeshLimits = MeshLimits { max_vertices: 100_000, max_triangles: 500_000 };

/// The hanging cloth of `examples/hanging_cloth.json`, run for 0.2 s recording positions, encoded
/// as JSON and as GLB.
fn hanging_cloth() -> (Value, Vec<u8>) {
    let mut scene: Value = serde_json::from_str(include_str!("../examples/hanging_cloth.json")).unwrap();
    scene["duration"] = json!(0.2);
    scene["output"]["fields"] = json!(["positions"]);
    let scene = Scene::from_value(scene).unwrap();
    let compiled = Limits::default().admit(&scene).unwrap().compiled;
    let recording = execute(&compiled, &Control::new());
    let (mut json_bytes, mut glb) = (Vec::new(), Vec::new());
    encode(&recording, Format::Json, &mut json_bytes).unwrap();
    encode(&recording, Format::Glb, &mut glb).unwrap();
    (serde_json::from_slice(&json_bytes).unwrap(), glb)
}

#[test]
fn a_glb_from_drapes_encoder_reads_back_as_its_last_frame() {
    let (result, glb) = hanging_cloth();
    let mesh = read_glb(&glb, LIMITS).unwrap();
    // The encoder's base mesh is the last frame (its morph targets, ignored here, are the
    // others), in f32, with the result's triangles.
    let expected: Vec<f64> = result["final"]["positions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32 as f64)
        .collect();
    assert_eq!(mesh.vertex_count(), 400);
    assert_eq!(mesh.vertices, expected);
    let triangles: Vec<u32> =
        result["mesh"]["triangles"].as_array().unwrap().iter().map(|i| i.as_u64().unwrap() as u32).collect();
    // A 20 × 20 grid: 19 × 19 squares, two triangles each.
    assert_eq!(mesh.triangle_count(), 2 * 19 * 19);
    assert_eq!(mesh.triangles, triangles);
}

#[test]
fn drape_run_reads_a_file_relative_to_the_scene() {
    let (first, glb) = hanging_cloth();
    let directory = tempfile::tempdir().unwrap();
    std::fs::create_dir(directory.path().join("meshes")).unwrap();
    std::fs::write(directory.path().join("meshes/cloth.glb"), &glb).unwrap();
    let scene = json!({
        "duration": 0.01, "dt": 0.01, "gravity": [0, 0, 0],
        "bodies": [{"type": "mesh", "file": "meshes/cloth.glb"}],
        "output": {"frames": "all"},
    });
    std::fs::write(directory.path().join("scene.json"), scene.to_string()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_drape"))
        .arg("run")
        .arg(directory.path().join("scene.json"))
        .env_remove("DRAPE_MEMORY_BUDGET")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let result: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(result["mesh"]["particles"], 400);
    // At t = 0 the body is where the file put it: the cloth's last frame, in f32.
    let start: Vec<f64> =
        result["frames"][0]["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let cloth: Vec<f64> = first["final"]["positions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32 as f64)
        .collect();
    assert_eq!(start, cloth);

    let bad = json!({"duration": 0.01, "bodies": [{"type": "mesh", "file": "missing.obj"}]});
    std::fs::write(directory.path().join("bad.json"), bad.to_string()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_drape"))
        .arg("run")
        .arg(directory.path().join("bad.json"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("/bodies/0/file: cannot read"), "{stderr}");
}

#[test]
fn drape_sweep_reads_a_file_of_its_base_scene() {
    let directory = tempfile::tempdir().unwrap();
    std::fs::write(directory.path().join("square.obj"), "v 0 1 0\nv 1 1 0\nv 1 1 1\nv 0 1 1\nf 1 2 3 4\n")
        .unwrap();
    let sweep = json!({
        "scene": {"duration": 0.1, "bodies": [{"type": "mesh", "file": "square.obj"}], "output": {"frames": "none"}},
        "vary": {"/dt": [0.01, 0.005]},
    });
    std::fs::write(directory.path().join("sweep.json"), sweep.to_string()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(["sweep", "--threads", "1"])
        .arg(directory.path().join("sweep.json"))
        .env_remove("DRAPE_MEMORY_BUDGET")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table: Value = serde_json::from_slice(&out.stdout).unwrap();
    let statuses: Vec<&str> =
        table["rows"].as_array().unwrap().iter().map(|r| r["status"].as_str().unwrap()).collect();
    assert_eq!(statuses, ["succeeded", "succeeded"]);

    let missing = json!({"scene": {"duration": 0.1, "bodies": [{"type": "mesh", "file": "no.glb"}]}, "vary": {"/dt": [0.01]}});
    std::fs::write(directory.path().join("missing.json"), missing.to_string()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_drape"))
        .arg("sweep")
        .arg(directory.path().join("missing.json"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/scene/bodies/0/file: cannot read"));
}
