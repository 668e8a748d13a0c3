//! Colliders in results: the JSON entries (read back exactly) and the GLB's collider nodes, read
//! back by the `gltf` crate, the Khronos glTF-Validator and three.js. The moving and mesh
//! colliders are added to a run's recording by hand, as a scene that has them would record them.

use std::process::Command;

use drape::output::{Format, read_json};
use drape::run::{ColliderShape, RecordedCollider, RigidTransform};
use gltf::animation::Property;
use gltf::animation::util::ReadOutputs;
use serde_json::json;

use crate::common::{INSTALL_NODE_READERS, Run, mixed_scene, repo, require_node, scratch_dir};

/// A cloth over one collider of each analytic shape, every frame recorded.
fn scene(precision: &str) -> String {
    format!(
        r#"{{"duration": 0.25, "precision": "{precision}",
            "bodies": [{{"type": "cloth", "name": "sheet", "resolution": [6, 6], "center": [0, 1, 0]}}],
            "colliders": [{{"type": "plane"}},
                          {{"type": "sphere", "center": [0.1, 0.5, -0.2], "radius": 0.3, "friction": 0.5}},
                          {{"type": "box", "center": [1, 0.25, 0], "half_extents": [0.2, 0.25, 0.4]}},
                          {{"type": "cylinder", "center": [-1, 0.4, 0.5], "radius": 0.35, "height": 0.8}}],
            "output": {{"fps": 20}}}}"#
    )
}

/// The sphere's transform at frame `k`: risen by 0.1 m per frame and turned about y by 0.2 rad
/// per frame.
fn sphere_transform(k: usize) -> RigidTransform {
    let half = 0.1 * k as f64;
    RigidTransform { translation: [0.0, 0.1 * k as f64, 0.0], rotation: [0.0, half.sin(), 0.0, half.cos()] }
}

/// A tetrahedron.
fn mesh_collider() -> RecordedCollider {
    RecordedCollider {
        name: "collider:4".into(),
        shape: ColliderShape::Mesh {
            vertices: vec![2.0, 0.0, 0.0, 3.0, 0.0, 0.0, 2.0, 1.0, 0.0, 2.0, 0.0, 1.0],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        },
        frames: None,
    }
}

/// The scene's run with its sphere moving and a mesh collider added.
fn moving_run(precision: &str) -> Run {
    let mut recording = Run::new(&scene(precision)).recording;
    let frames = recording.frames.len();
    recording.colliders[1].frames = Some((0..frames).map(sphere_transform).collect());
    recording.colliders.push(mesh_collider());
    Run::of(recording)
}

#[test]
fn json_result_lists_colliders_in_scene_order_after_defaults() {
    let run = Run::new(&scene("f64"));
    assert_eq!(
        run.json["colliders"],
        json!([
            {"name": "collider:0", "type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0]},
            {"name": "collider:1", "type": "sphere", "center": [0.1, 0.5, -0.2], "radius": 0.3},
            {"name": "collider:2", "type": "box", "center": [1.0, 0.25, 0.0], "half_extents": [0.2, 0.25, 0.4]},
            {"name": "collider:3", "type": "cylinder", "center": [-1.0, 0.4, 0.5], "radius": 0.35, "height": 0.8},
        ])
    );
    let without = Run::new(&mixed_scene("f64", "all", &["positions"]));
    assert!(without.json.get("colliders").is_none());
}

#[test]
fn json_read_is_the_exact_inverse_with_moving_and_mesh_colliders() {
    for precision in ["f32", "f64"] {
        let run = moving_run(precision);
        let bytes = run.encode(Format::Json);
        let read = read_json(&bytes).expect("reads back");
        assert_eq!(read, run.recording);
        let mut again = Vec::new();
        drape::output::write_json(&read, &mut again).unwrap();
        assert_eq!(again, bytes);
        let entry = &run.json["colliders"][1];
        assert_eq!(entry["frames"].as_array().unwrap().len(), run.frames().len());
        assert_eq!(
            entry["frames"][2],
            json!({"translation": [0.0, 0.2, 0.0], "rotation": [0.0, 0.2f64.sin(), 0.0, 0.2f64.cos()]})
        );
        assert_eq!(run.json["colliders"][4]["triangles"], json!([0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]));
    }
}

#[test]
fn json_read_refuses_collider_frames_of_another_count() {
    let run = moving_run("f64");
    let mut json = run.json.clone();
    json["colliders"][1]["frames"].as_array_mut().unwrap().pop();
    let error = read_json(json.to_string().as_bytes()).unwrap_err();
    assert!(error.to_string().contains("colliders.frames"), "{error}");
}

fn distance(p: [f32; 3], c: [f64; 3]) -> f64 {
    (0..3).map(|a| (f64::from(p[a]) - c[a]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn gltf_crate_reads_a_node_per_collider_with_its_shape_and_motion() {
    let run = moving_run("f32");
    let bytes = run.encode(Format::Glb);
    let gltf = gltf::Gltf::from_slice(&bytes).expect("the gltf crate loads the GLB");
    let blob = gltf.blob.as_deref().unwrap();
    let nodes: Vec<_> = gltf.nodes().collect();
    let names: Vec<_> = nodes.iter().map(|n| n.name().unwrap()).collect();
    assert_eq!(names, ["sheet", "collider:0", "collider:1", "collider:2", "collider:3", "collider:4"]);
    let positions = |node: &gltf::Node| -> Vec<[f32; 3]> {
        let primitive = node.mesh().unwrap().primitives().next().unwrap();
        primitive.reader(|_| Some(blob)).read_positions().unwrap().collect()
    };
    let bounds = |node: &gltf::Node| {
        let b = node.mesh().unwrap().primitives().next().unwrap().bounding_box();
        (b.min, b.max)
    };

    // The plane y = 0, as a square of at least 5 m each way from its point.
    let plane = positions(&nodes[1]);
    assert!(plane.iter().all(|p| p[1] == 0.0));
    assert!(plane.iter().all(|p| p[0].abs().max(p[2].abs()) >= 5.0));
    // The sphere: every vertex at its radius from its centre, reaching its poles.
    let sphere = positions(&nodes[2]);
    assert!(sphere.iter().all(|&p| (distance(p, [0.1, 0.5, -0.2]) - 0.3).abs() < 1e-6), "sphere");
    assert_eq!(bounds(&nodes[2]).0[1], 0.2f32);
    assert_eq!(bounds(&nodes[2]).1[1], 0.8f32);
    // The box: its corners exactly.
    assert_eq!(bounds(&nodes[3]), ([0.8f32, 0.0, -0.4], [1.2f32, 0.5, 0.4]));
    // The cylinder: its caps at centre ± height/2, its side at its radius from the axis.
    assert_eq!((bounds(&nodes[4]).0[1], bounds(&nodes[4]).1[1]), (0.0, 0.8));
    for p in positions(&nodes[4]) {
        let r = distance([p[0], 0.0, p[2]], [-1.0, 0.0, 0.5]);
        assert!(r < 0.35 + 1e-6 && (r > 0.35 - 1e-6 || (p[0], p[2]) == (-1.0, 0.5)), "cylinder {p:?}");
    }
    // The mesh: its vertices and triangles as they are.
    assert_eq!(positions(&nodes[5]), [[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [2.0, 1.0, 0.0], [2.0, 0.0, 1.0]]);
    let primitive = nodes[5].mesh().unwrap().primitives().next().unwrap();
    let indices: Vec<u32> = primitive.reader(|_| Some(blob)).read_indices().unwrap().into_u32().collect();
    assert_eq!(indices, [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]);

    // Static colliders stand where they are defined; the moving sphere's node holds its last
    // frame's transform, and the animation its transform at each frame.
    let frames = run.frames();
    let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    for (k, node) in nodes.iter().enumerate().skip(1) {
        let (t, r, s) = node.transform().decomposed();
        let expected = if k == 2 {
            sphere_transform(frames.len() - 1)
        } else {
            RigidTransform { translation: [0.0; 3], rotation: [0.0, 0.0, 0.0, 1.0] }
        };
        assert_eq!(
            (t.to_vec(), r.to_vec(), s),
            (f32s(&expected.translation), f32s(&expected.rotation), [1.0; 3]),
            "{}",
            names[k]
        );
    }
    let animation = gltf.animations().next().unwrap();
    let times: Vec<f32> = frames.iter().map(|f| f["t"].as_f64().unwrap() as f32).collect();
    let moving: Vec<_> = animation.channels().filter(|c| c.target().node().index() == 2).collect();
    assert_eq!(moving.len(), 2);
    for channel in moving {
        let reader = channel.reader(|_| Some(blob));
        assert_eq!(reader.read_inputs().unwrap().collect::<Vec<f32>>(), times);
        match (channel.target().property(), reader.read_outputs().unwrap()) {
            (Property::Translation, ReadOutputs::Translations(values)) => {
                let expected: Vec<Vec<f32>> =
                    (0..frames.len()).map(|k| f32s(&sphere_transform(k).translation)).collect();
                assert_eq!(values.map(|v| v.to_vec()).collect::<Vec<_>>(), expected);
            }
            (Property::Rotation, ReadOutputs::Rotations(values)) => {
                let expected: Vec<Vec<f32>> =
                    (0..frames.len()).map(|k| f32s(&sphere_transform(k).rotation)).collect();
                assert_eq!(values.into_f32().map(|v| v.to_vec()).collect::<Vec<_>>(), expected);
            }
            (property, _) => panic!("unexpected channel on {property:?}"),
        }
    }
    assert!(animation.channels().all(|c| matches!(c.target().node().index(), 0 | 2)));
}

#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn khronos_validator_finds_no_error_in_files_with_colliders() {
    require_node();
    let dir = scratch_dir("validator-colliders");
    let mut paths = Vec::new();
    for (file, run) in [
        ("animated.glb", moving_run("f64")),
        ("static.glb", Run::new(&scene("f32").replace(r#""fps": 20"#, r#""fps": 20, "frames": "final""#))),
    ] {
        let path = dir.join(file);
        std::fs::write(&path, run.encode(Format::Glb)).unwrap();
        paths.push(path);
    }
    let output = Command::new("node")
        .arg(repo().join("tests/support/validate_gltf.cjs"))
        .args(&paths)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&output.stdout);
    println!("{report}{}", String::from_utf8_lossy(&output.stderr));
    match output.status.code() {
        Some(0) => assert_eq!(report.matches(": 0 errors").count(), paths.len(), "{report}"),
        Some(2) => panic!("gltf-validator is not installed: {INSTALL_NODE_READERS}"),
        _ => panic!("the validator found errors:\n{report}"),
    }
}

#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn three_js_plays_the_colliders_where_the_result_puts_them() {
    require_node();
    let dir = scratch_dir("threejs-colliders");
    let run = moving_run("f32");
    let (glb, json) = (dir.join("colliders.glb"), dir.join("colliders.json"));
    std::fs::write(&glb, run.encode(Format::Glb)).unwrap();
    std::fs::write(&json, run.encode(Format::Json)).unwrap();
    let output = Command::new("node")
        .arg(repo().join("tests/support/play_threejs.mjs"))
        .args([&glb, &json])
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    println!("{stdout}{stderr}");
    match output.status.code() {
        Some(0) => {
            assert!(stdout.contains(&format!("and 5 colliders at {} frames", run.frames().len())), "{stdout}")
        }
        Some(2) => panic!("three.js is not installed: {INSTALL_NODE_READERS}"),
        _ => panic!("three.js does not play the GLB as recorded:\n{stdout}{stderr}"),
    }
}
