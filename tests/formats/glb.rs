//! glTF binary, read back by the `gltf` crate and checked by the Khronos glTF-Validator.

use std::process::Command;

use drape::output::Format;
use gltf::animation::Interpolation;
use gltf::animation::util::ReadOutputs;
use gltf::mesh::Mode;

use crate::common::{INSTALL_NODE_READERS, Run, mixed_scene, numbers, repo, require_node, scratch_dir};

/// `x` rounded to `f32` as the glTF holds it: exact for an `f32` run.
fn as_f32(x: f64) -> f32 {
    x as f32
}

fn check_against_json(run: &Run) {
    let bytes = run.encode(Format::Glb);
    let gltf = gltf::Gltf::from_slice(&bytes).expect("the gltf crate loads the GLB");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    let frames = run.frames();
    let last = run.last();
    let triangles = run.triangles();
    let last_positions = numbers(&last["positions"]);
    let animated = frames.len() > 1;
    let f32_run = run.precision() == "f32";

    let bodies = run.bodies();
    let nodes: Vec<_> = gltf.nodes().collect();
    assert_eq!(nodes.len(), bodies.len());
    for (node, (name, offset, count)) in nodes.iter().zip(&bodies) {
        assert_eq!(node.name(), Some(name.as_str()));
        let mesh = node.mesh().expect("a mesh per body");
        assert_eq!(mesh.name(), Some(name.as_str()));
        let primitive = mesh.primitives().next().unwrap();
        let reader = primitive.reader(|_| Some(blob));

        // Positions of the last frame, exactly the JSON's (rounded to f32 for an f64 run).
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        let expected: Vec<[f32; 3]> = last_positions[3 * offset..3 * (offset + count)]
            .chunks_exact(3)
            .map(|c| [0, 1, 2].map(|a| as_f32(c[a])))
            .collect();
        assert_eq!(positions, expected, "{name}: positions");

        // Triangles, re-based to the body; a chain is a line strip.
        let body_triangles: Vec<u32> = triangles
            .iter()
            .filter(|t| (*offset..offset + count).contains(&t[0]))
            .flat_map(|t| t.map(|i| (i - offset) as u32))
            .collect();
        if body_triangles.is_empty() {
            assert_eq!(primitive.mode(), Mode::LineStrip, "{name}");
            assert!(reader.read_normals().is_none());
        } else {
            assert_eq!(primitive.mode(), Mode::Triangles, "{name}");
            let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            assert_eq!(indices, body_triangles, "{name}: indices");
            let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
            for n in &normals {
                let length = n.iter().map(|x| f64::from(*x).powi(2)).sum::<f64>().sqrt();
                assert!((length - 1.0).abs() < 1e-6, "{name}: normal {n:?} is not unit");
            }
            if let Some(json_normals) = last.get("normals") {
                let json_normals = numbers(json_normals);
                for (k, n) in normals.iter().enumerate() {
                    let j = &json_normals[3 * (offset + k)..3 * (offset + k + 1)];
                    if j != [0.0; 3] {
                        assert_eq!(*n, [0, 1, 2].map(|a| as_f32(j[a])), "{name}: normal {k}");
                    }
                }
            }
        }

        // Morph targets: one per frame, each reconstructing that frame within half an f32 step
        // of the delta's size.
        let targets: Vec<_> = reader.read_morph_targets().collect();
        assert_eq!(targets.len(), if animated { frames.len() } else { 0 }, "{name}: targets");
        for (k, (deltas, _, _)) in targets.into_iter().enumerate() {
            let deltas: Vec<[f32; 3]> = deltas.expect("POSITION deltas").collect();
            let frame = numbers(&frames[k]["positions"]);
            for (i, (base, delta)) in positions.iter().zip(&deltas).enumerate() {
                for a in 0..3 {
                    let x = frame[3 * (offset + i) + a];
                    let x = if f32_run { f64::from(as_f32(x)) } else { x };
                    let shown = f64::from(base[a]) + f64::from(delta[a]);
                    // Half an f32 step of the delta (the smallest step, for a subnormal delta),
                    // and for an f64 run the f64 rounding of the difference it was made from.
                    let rounding = if f32_run { 0.0 } else { x.abs() * f64::EPSILON } + 2f64.powi(-150);
                    let tolerance = f64::from(delta[a].abs()) * f64::from(f32::EPSILON) / 2.0 + rounding;
                    assert!(
                        (shown - x).abs() <= tolerance,
                        "{name}: frame {k}, particle {i}: {shown} vs {x}"
                    );
                }
            }
            if k == frames.len() - 1 && f32_run {
                assert!(deltas.iter().all(|d| *d == [0.0; 3]), "the last frame is the base");
            }
        }
    }

    // The animation: one channel per node on `weights`, one keyframe per frame, each showing
    // exactly its own target.
    let animations: Vec<_> = gltf.animations().collect();
    if !animated {
        assert!(animations.is_empty());
        return;
    }
    assert_eq!(animations.len(), 1);
    let channels: Vec<_> = animations[0].channels().collect();
    assert_eq!(channels.len(), bodies.len());
    for channel in &channels {
        assert_eq!(channel.target().property(), gltf::animation::Property::MorphTargetWeights);
        assert_eq!(channel.sampler().interpolation(), Interpolation::Step);
        let reader = channel.reader(|_| Some(blob));
        let times: Vec<f32> = reader.read_inputs().unwrap().collect();
        let expected: Vec<f32> = frames.iter().map(|f| f["t"].as_f64().unwrap() as f32).collect();
        assert_eq!(times, expected);
        let Some(ReadOutputs::MorphTargetWeights(weights)) = reader.read_outputs() else { panic!("weights") };
        let weights: Vec<f32> = weights.into_f32().collect();
        assert_eq!(weights.len(), frames.len() * frames.len());
        for (k, row) in weights.chunks_exact(frames.len()).enumerate() {
            for (target, &w) in row.iter().enumerate() {
                assert_eq!(w, if target == k { 1.0 } else { 0.0 });
            }
        }
    }
}

#[test]
fn gltf_crate_reads_back_every_frame_of_an_f32_run() {
    check_against_json(&Run::new(&mixed_scene("f32", "all", &["positions"])));
}

#[test]
fn gltf_crate_reads_back_an_f64_run_with_normals() {
    check_against_json(&Run::new(&mixed_scene("f64", "all", &["positions", "normals"])));
}

#[test]
fn gltf_crate_reads_back_a_final_frame_without_animation() {
    check_against_json(&Run::new(&mixed_scene("f32", "final", &["positions", "normals"])));
}

#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn khronos_validator_finds_no_error_in_static_and_animated_files() {
    require_node();
    let dir = scratch_dir("validator");
    let files = [
        ("static.glb", mixed_scene("f64", "final", &["positions"])),
        ("animated.glb", mixed_scene("f32", "all", &["positions"])),
        ("animated_normals.glb", mixed_scene("f64", "all", &["positions", "normals"])),
    ];
    let mut paths = Vec::new();
    for (file, scene) in &files {
        let path = dir.join(file);
        std::fs::write(&path, Run::new(scene).encode(Format::Glb)).unwrap();
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
        Some(0) => {
            assert_eq!(report.matches(": 0 errors").count(), files.len(), "{report}");
        }
        Some(2) => panic!("gltf-validator is not installed: {INSTALL_NODE_READERS}"),
        _ => panic!("the validator found errors:\n{report}"),
    }
}

#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn three_js_plays_each_frame_as_its_own_morph_target() {
    require_node();
    let dir = scratch_dir("threejs");
    for (name, scene) in [
        ("f32", mixed_scene("f32", "all", &["positions"])),
        ("f64", mixed_scene("f64", "all", &["positions", "normals"])),
    ] {
        let run = Run::new(&scene);
        let (glb, json) = (dir.join(format!("{name}.glb")), dir.join(format!("{name}.json")));
        std::fs::write(&glb, run.encode(Format::Glb)).unwrap();
        std::fs::write(&json, run.encode(Format::Json)).unwrap();
        let output = Command::new("node")
            .arg(repo().join("tests/support/play_threejs.mjs"))
            .args([&glb, &json])
            .output()
            .unwrap();
        let (stdout, stderr) =
            (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
        println!("{stdout}{stderr}");
        match output.status.code() {
            Some(0) => assert!(stdout.contains(&format!("played {} frames", run.frames().len())), "{stdout}"),
            Some(2) => panic!("three.js is not installed: {INSTALL_NODE_READERS}"),
            _ => panic!("three.js does not play the GLB as recorded ({name}):\n{stdout}{stderr}"),
        }
    }
}
