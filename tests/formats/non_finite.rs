//! Results holding numbers that are not finite, served over HTTP in every format and read back
//! by readers that are not ours: `null` in JSON, the IEEE value in NPY, NPZ and PC2, `NaN` and
//! `Infinity` in OBJ, and in glTF only the frames it can show.

use std::path::Path;
use std::process::Command;

use axum::Router;
use drape::api::ApiConfig;
use drape::output::{Format, check_recording, encode, read_json};
use serde_json::{Value, json};

use crate::api::{get, is_final, jobs_config, poll_until, post_json, test_app};
use crate::common::{reader_available, repo, scratch_dir};

/// The chain of the report: so heavy that RK4's first step leaves the state non-finite, and its
/// gravitational energy is infinite from the first frame.
fn heavy_chain(fields: &str) -> String {
    format!(
        r#"{{"duration": 1, "integrator": "rk4", "bodies": [{{"type": "chain", "mass": 1e308}}],
            "output": {{"fields": {fields}}}}}"#
    )
}

/// A chain flying up at 1e39 m/s, in f64: from 0.4 s on its positions are beyond `f32`'s range
/// (3.4e38), so the `f32` formats hold infinities there.
const FLYING: &str = r#"{"duration": 1, "gravity": [0, 0, 0], "error_estimate": "none",
    "bodies": [{"type": "chain", "count": 3, "velocity": [0, 1e39, 0]}],
    "output": {"fps": 10, "fields": ["positions"]}}"#;

/// Submits `scene` as a job, waits for its end, and gives its result path and status.
async fn run_job(app: &Router, scene: &str) -> (String, String) {
    let answer = post_json(app, "/jobs", scene).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let id = answer.json()["id"].as_str().unwrap().to_string();
    let job = poll_until(app, &id, is_final).await;
    (format!("/jobs/{id}/result"), job["status"].as_str().unwrap().to_string())
}

/// Fetches `path` in `format`: it must answer 200 with the format's media type.
async fn fetch(app: &Router, path: &str, format: &str, media_type: &str) -> Vec<u8> {
    let answer = get(app, &format!("{path}?format={format}")).await;
    assert_eq!(answer.status, 200, "{format}: {}", answer.text());
    assert_eq!(answer.header("content-type"), Some(media_type), "{format}");
    answer.body
}

/// Runs a Python snippet over files with NumPy; false when NumPy is missing (outside CI).
fn numpy(script: &str, files: &[&Path]) -> bool {
    if !reader_available("NumPy", "python3", &["-c", "import numpy"]) {
        return false;
    }
    let output = Command::new("python3").arg("-c").arg(script).args(files).output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "NumPy disagrees:\n{stdout}\n{stderr}");
    assert!(stdout.contains("numpy agrees"), "{stdout}");
    true
}

/// Checks GLB files with the Khronos glTF-Validator: every file without an error.
fn validate_gltf(paths: &[&Path]) {
    let output =
        Command::new("node").arg(repo().join("tests/support/validate_gltf.cjs")).args(paths).output();
    let Ok(output) = output else {
        assert!(!std::env::var("CI").is_ok_and(|v| v == "true"), "node is needed under CI");
        return eprintln!("skipping: node is not installed");
    };
    let report = String::from_utf8_lossy(&output.stdout);
    println!("{report}{}", String::from_utf8_lossy(&output.stderr));
    match output.status.code() {
        Some(0) => assert_eq!(report.matches(": 0 errors").count(), paths.len(), "{report}"),
        Some(2) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("gltf-validator is needed under CI: npm ci --prefix .ci/node")
        }
        Some(2) => eprintln!("skipping: gltf-validator is not installed"),
        _ => panic!("the validator found errors:\n{report}"),
    }
}

fn tobj_load(text: &[u8]) -> Vec<tobj::Model> {
    let options = tobj::LoadOptions { ignore_points: true, ..tobj::LoadOptions::default() };
    let (models, _) = tobj::load_obj_buf(&mut &text[..], &options, |_| Err(tobj::LoadError::OpenFileFailed))
        .expect("tobj reads the OBJ");
    models
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_diverged_heavy_chain_is_served_in_every_format() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let dir = scratch_dir("non-finite-heavy");

    // Positions and energy, as reported: JSON, NPY (sent as NPZ) and NPZ carry both.
    let (path, status) = run_job(&app, &heavy_chain(r#"["positions", "energy"]"#)).await;
    assert_eq!(status, "diverged");
    let result: Value =
        serde_json::from_slice(&fetch(&app, &path, "json", "application/json").await).unwrap();
    assert_eq!(result["stats"]["status"], "diverged");
    assert_eq!(result["frames"].as_array().unwrap().len(), 1);
    assert_eq!(result["frames"][0]["energy"], json!({"kinetic": 0.0, "gravitational": null, "spring": 0.0}));
    let npz = fetch(&app, &path, "npy", "application/x-npz").await;
    assert_eq!(fetch(&app, &path, "npz", "application/x-npz").await, npz);
    std::fs::write(dir.join("heavy.npz"), &npz).unwrap();
    std::fs::write(dir.join("heavy.json"), result.to_string()).unwrap();
    numpy(
        "import json, sys, numpy as np\n\
         a = np.load(sys.argv[1]); r = json.load(open(sys.argv[2]))\n\
         e = a['energy']\n\
         assert e.shape == (1, 3) and e.dtype == np.dtype('<f8'), (e.shape, e.dtype)\n\
         assert e[0, 0] == 0.0 and np.isnan(e[0, 1]) and e[0, 2] == 0.0, e\n\
         p = a['positions']\n\
         assert p.shape == (1, 10, 3) and np.array_equal(p.reshape(-1), np.array(r['frames'][0]['positions'])), p\n\
         assert list(a['times']) == [0.0]\n\
         print('numpy agrees')",
        &[&dir.join("heavy.npz"), &dir.join("heavy.json")],
    );
    // Energy is no field of the mesh formats: a 422 naming it, as for any run, not a 5xx.
    for format in ["glb", "obj", "pc2"] {
        let answer = get(&app, &format!("{path}?format={format}")).await;
        assert_eq!(answer.status, 422, "{format}: {}", answer.text());
        let problem = answer.problem();
        assert_eq!(problem["type"], "/problems/format-cannot-carry");
        assert_eq!(problem["errors"][0]["pointer"], "/output/fields/1");
    }

    // The same chain with positions alone: every format answers 200 and reads back.
    let (path, status) = run_job(&app, &heavy_chain(r#"["positions"]"#)).await;
    assert_eq!(status, "diverged");
    let result: Value =
        serde_json::from_slice(&fetch(&app, &path, "json", "application/json").await).unwrap();
    let positions: Vec<f64> =
        result["frames"][0]["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert_eq!(positions.len(), 30);

    let glb = fetch(&app, &path, "glb", "model/gltf-binary").await;
    let gltf = gltf::Gltf::from_slice(&glb).expect("the gltf crate loads the GLB");
    let mesh = gltf.meshes().next().unwrap();
    let primitive = mesh.primitives().next().unwrap();
    let reader = primitive.reader(|_| gltf.blob.as_deref());
    let read: Vec<f32> = reader.read_positions().unwrap().flatten().collect();
    assert_eq!(read, positions.iter().map(|&x| x as f32).collect::<Vec<_>>());
    std::fs::write(dir.join("heavy.glb"), &glb).unwrap();
    validate_gltf(&[&dir.join("heavy.glb")]);

    let models = tobj_load(&fetch(&app, &path, "obj", "model/obj").await);
    assert_eq!(models.len(), 1);
    assert_eq!(models[0].mesh.positions, positions);

    let pc2 = fetch(&app, &path, "pc2", "application/x-pc2").await;
    assert_eq!(&pc2[..12], b"POINTCACHE2\0");
    assert_eq!(f32s(&pc2[32..]), positions.iter().map(|&x| x as f32).collect::<Vec<_>>());

    let npy = fetch(&app, &path, "npy", "application/x-npy").await;
    std::fs::write(dir.join("heavy.npy"), &npy).unwrap();
    std::fs::write(dir.join("heavy_positions.json"), result.to_string()).unwrap();
    numpy(
        "import json, sys, numpy as np\n\
         p = np.load(sys.argv[1]); r = json.load(open(sys.argv[2]))\n\
         assert p.shape == (1, 10, 3) and np.array_equal(p.reshape(-1), np.array(r['frames'][0]['positions']))\n\
         print('numpy agrees')",
        &[&dir.join("heavy.npy"), &dir.join("heavy_positions.json")],
    );
    let npz = fetch(&app, &path, "npz", "application/x-npz").await;
    assert_eq!(&npz[..2], b"PK");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn positions_beyond_f32_range_are_infinite_in_pc2_and_left_out_of_glb() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let dir = scratch_dir("non-finite-flying");
    let (path, status) = run_job(&app, FLYING).await;
    assert_eq!(status, "succeeded");
    let result: Value =
        serde_json::from_slice(&fetch(&app, &path, "json", "application/json").await).unwrap();
    let frames = result["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 11);
    let heights: Vec<f64> = frames.iter().map(|f| f["positions"][1].as_f64().unwrap()).collect();
    // Finite in f64 everywhere; beyond f32::MAX from the fifth frame (0.4 s) on.
    let beyond: Vec<usize> = (0..11).filter(|&k| !(heights[k] as f32).is_finite()).collect();
    assert_eq!(beyond, [4, 5, 6, 7, 8, 9, 10]);

    // PC2 holds the f32 values as they are: infinity where f32 has no finite value.
    let pc2 = f32s(&fetch(&app, &path, "pc2", "application/x-pc2").await[32..]);
    assert_eq!(pc2.len(), 11 * 9);
    for (k, &height) in heights.iter().enumerate() {
        assert_eq!(pc2[9 * k + 1], height as f32, "frame {k}");
    }
    assert_eq!(pc2[9 * 10 + 1], f32::INFINITY);

    // glTF shows frames 0 to 3, the last of them as the base, and names those it left out.
    let glb = fetch(&app, &path, "glb", "model/gltf-binary").await;
    let gltf = gltf::Gltf::from_slice(&glb).expect("the gltf crate loads the GLB");
    let document: Value = serde_json::to_value(gltf.document.as_json()).unwrap();
    assert_eq!(document["asset"]["extras"], json!({"omitted_frames": [4, 5, 6, 7, 8, 9, 10]}));
    let animation = gltf.animations().next().unwrap();
    let channel = animation.channels().next().unwrap();
    let times: Vec<f32> = channel.reader(|_| gltf.blob.as_deref()).read_inputs().unwrap().collect();
    let expected: Vec<f32> = frames[..4].iter().map(|f| f["t"].as_f64().unwrap() as f32).collect();
    assert_eq!(times, expected);
    let mesh = gltf.meshes().next().unwrap();
    let primitive = mesh.primitives().next().unwrap();
    assert_eq!(primitive.morph_targets().count(), 4);
    let base: Vec<[f32; 3]> = primitive.reader(|_| gltf.blob.as_deref()).read_positions().unwrap().collect();
    assert_eq!(base[0][1], heights[3] as f32);
    let bounds = primitive.get(&gltf::Semantic::Positions).unwrap();
    assert!(bounds.min().unwrap().as_array().unwrap().iter().all(|x| x.as_f64().is_some_and(f64::is_finite)));
    std::fs::write(dir.join("flying.glb"), &glb).unwrap();
    validate_gltf(&[&dir.join("flying.glb")]);

    // OBJ holds the f64 values as decimals: tobj (f64) reads back the last frame exactly.
    let models = tobj_load(&fetch(&app, &path, "obj", "model/obj").await);
    let last: Vec<f64> =
        frames[10]["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert_eq!(models[0].mesh.positions, last);

    let npy = fetch(&app, &path, "npy", "application/x-npy").await;
    std::fs::write(dir.join("flying.npy"), &npy).unwrap();
    std::fs::write(dir.join("flying.json"), result.to_string()).unwrap();
    numpy(
        "import json, sys, numpy as np\n\
         p = np.load(sys.argv[1]); r = json.load(open(sys.argv[2]))\n\
         want = np.array([f['positions'] for f in r['frames']]).reshape(11, 3, 3)\n\
         assert p.dtype == np.dtype('<f8') and np.array_equal(p, want)\n\
         print('numpy agrees')",
        &[&dir.join("flying.npy"), &dir.join("flying.json")],
    );
}

#[test]
fn obj_spells_values_that_are_not_finite_as_its_readers_read_them() {
    let result = crate::common::Run::new(FLYING);
    let mut recording = read_json(&result.encode(Format::Json)).unwrap();
    let drape::run::Samples::F64(positions) = recording.frames.positions.as_mut().unwrap() else { panic!() };
    let last = positions.len() - 9;
    positions[last..last + 3].copy_from_slice(&[f64::NAN, f64::INFINITY, f64::NEG_INFINITY]);
    let mut obj = Vec::new();
    encode(&recording, Format::Obj, &mut obj).unwrap();
    let text = String::from_utf8(obj.clone()).unwrap();
    assert!(text.contains("\nv NaN Infinity -Infinity\n"), "{text}");
    let read = &tobj_load(&obj)[0].mesh.positions;
    assert!(read[0].is_nan());
    assert_eq!(read[1..3], [f64::INFINITY, f64::NEG_INFINITY]);

    // With no frame glTF can show, GLB is refused as a format that cannot carry the run.
    let drape::run::Samples::F64(positions) = recording.frames.positions.as_mut().unwrap() else { panic!() };
    for value in positions.iter_mut().skip(1).step_by(3) {
        *value = f64::NAN;
    }
    let problems = check_recording(Format::Glb, &recording).unwrap_err();
    assert_eq!(problems[0].pointer, "/output/frames");
    assert!(problems[0].detail.contains("finite"), "{}", problems[0].detail);
    assert!(encode(&recording, Format::Glb, &mut Vec::new()).is_err());
    assert_eq!(check_recording(Format::Pc2, &recording), Ok(()));
}
