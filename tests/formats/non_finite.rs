//! Results holding numbers that are not finite, encoded in every format and read back by
//! readers that are not ours: `null` in JSON, the IEEE value in NPY, NPZ and PC2, `NaN` and
//! `Infinity` in OBJ, and in glTF only the frames it can show.
//!
//! A scene cannot ask for such numbers: magnitudes beyond the scene's ranges are refused at their
//! field, and a run whose state stops being finite ends as diverged before the frame is recorded.
//! The encoders still carry them as their readers expect, so these tests put them into a real
//! run's recording and encode that.
//!
//! The scenarios read back by external readers run twice: by the Rust crates alone (always), and
//! also by NumPy and the Khronos glTF-Validator (ignored unless asked for, since those need
//! Python and node).

use std::path::Path;
use std::process::Command;

use drape::api::ApiConfig;
use drape::output::{Format, check_recording, encode, read_json};
use drape::run::{Recording, Samples};
use serde_json::{Value, json};

use crate::api::{jobs_config, post_json, test_app};
use crate::common::{INSTALL_NODE_READERS, Run, repo, require_node, require_numpy, scratch_dir};

/// Which readers a scenario's results are read back by.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Readers {
    /// The Rust crates (gltf, tobj) and this file's own decoding.
    Crates,
    /// Those, and NumPy and the Khronos glTF-Validator where the scenario uses them, which must
    /// be installed.
    CratesNumpyAndValidator,
}

/// The heavy chain of the reliability report (1e308 kg) and a chain flying at 1e39 m/s: both
/// overflowed once; both are now refused where they are written.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn magnitudes_that_would_overflow_are_refused_at_their_field() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    for (scene, pointer) in [
        (
            r#"{"duration": 1, "integrator": "rk4", "bodies": [{"type": "chain", "mass": 1e308}]}"#,
            "/bodies/0/mass",
        ),
        (r#"{"duration": 1, "bodies": [{"type": "chain", "velocity": [0, 1e39, 0]}]}"#, "/bodies/0/velocity"),
    ] {
        for path in ["/jobs", "/simulate"] {
            let answer = post_json(&app, path, scene).await;
            assert_eq!(answer.status, 422, "{path} {scene}: {}", answer.text());
            assert_eq!(answer.problem()["errors"][0]["pointer"], pointer, "{path} {scene}");
        }
    }
}

/// A chain of ten particles falling for 0.3 s, recorded at 10 fps in double precision.
const CHAIN: &str = r#"{"duration": 0.3, "error_estimate": "none", "bodies": [{"type": "chain"}],
    "output": {"fps": 10, "fields": ["positions", "energy"]}}"#;

/// A chain of three particles flying up, recorded at 10 fps for 1 s: eleven frames.
const FLYING: &str = r#"{"duration": 1, "gravity": [0, 0, 0], "error_estimate": "none",
    "bodies": [{"type": "chain", "count": 3, "velocity": [0, 100, 0]}],
    "output": {"fps": 10, "fields": ["positions"]}}"#;

/// The recording of `scene`, as a stored JSON result reads back.
fn recording(scene: &str) -> Recording {
    read_json(&Run::new(scene).encode(Format::Json)).unwrap()
}

fn encoded(recording: &Recording, format: Format) -> Vec<u8> {
    let mut bytes = Vec::new();
    encode(recording, format, &mut bytes).unwrap();
    bytes
}

fn positions_mut(recording: &mut Recording) -> &mut Vec<f64> {
    let Some(Samples::F64(positions)) = recording.frames.positions.as_mut() else { panic!("f64 positions") };
    positions
}

/// Runs a Python snippet over files with NumPy, if `readers` include it.
fn numpy(readers: Readers, script: &str, files: &[&Path]) {
    if readers == Readers::Crates {
        return;
    }
    require_numpy();
    let output = Command::new("python3").arg("-c").arg(script).args(files).output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "NumPy disagrees:\n{stdout}\n{stderr}");
    assert!(stdout.contains("numpy agrees"), "{stdout}");
}

/// Checks GLB files with the Khronos glTF-Validator, if `readers` include it: every file without
/// an error.
fn validate_gltf(readers: Readers, paths: &[&Path]) {
    if readers == Readers::Crates {
        return;
    }
    require_node();
    let output = Command::new("node")
        .arg(repo().join("tests/support/validate_gltf.cjs"))
        .args(paths)
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

fn tobj_load(text: &[u8]) -> Vec<tobj::Model> {
    let options = tobj::LoadOptions { ignore_points: true, ..tobj::LoadOptions::default() };
    let (models, _) = tobj::load_obj_buf(&mut &text[..], &options, |_| Err(tobj::LoadError::OpenFileFailed))
        .expect("tobj reads the OBJ");
    models
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect()
}

#[test]
fn an_infinite_energy_is_null_in_json_and_nan_in_npz_and_no_mesh_format_takes_energy() {
    infinite_energy(Readers::Crates);
}

#[test]
#[ignore = "needs NumPy (python3 -m pip install numpy)"]
fn an_infinite_energy_reads_back_in_numpy() {
    infinite_energy(Readers::CratesNumpyAndValidator);
}

fn infinite_energy(readers: Readers) {
    let dir = scratch_dir(&format!("non-finite-energy-{readers:?}"));
    let mut heavy = recording(CHAIN);
    heavy.frames.energy.as_mut().unwrap()[0].gravitational = f64::INFINITY;
    let result: Value = serde_json::from_slice(&encoded(&heavy, Format::Json)).unwrap();
    assert_eq!(result["frames"].as_array().unwrap().len(), 4);
    assert_eq!(result["frames"][0]["energy"]["gravitational"], Value::Null);
    assert!(result["frames"][1]["energy"]["gravitational"].is_f64());
    // JSON reads back as NaN: the one value JSON's `null` stands for.
    let read = read_json(&encoded(&heavy, Format::Json)).unwrap();
    assert!(read.frames.energy.as_ref().unwrap()[0].gravitational.is_nan());

    let npz = encoded(&heavy, Format::Npz);
    std::fs::write(dir.join("heavy.npz"), &npz).unwrap();
    std::fs::write(dir.join("heavy.json"), result.to_string()).unwrap();
    numpy(
        readers,
        "import json, sys, numpy as np\n\
         a = np.load(sys.argv[1]); r = json.load(open(sys.argv[2]))\n\
         e = a['energy']\n\
         assert e.shape == (4, 3) and e.dtype == np.dtype('<f8'), (e.shape, e.dtype)\n\
         assert np.isinf(e[0, 1]) and np.isfinite(e[1:]).all(), e\n\
         p = a['positions']\n\
         assert p.shape == (4, 10, 3) and np.array_equal(p[0].reshape(-1), np.array(r['frames'][0]['positions'])), p\n\
         print('numpy agrees')",
        &[&dir.join("heavy.npz"), &dir.join("heavy.json")],
    );
    // Energy is no field of the mesh formats: refused at the field, as for any run.
    for format in [Format::Glb, Format::Obj, Format::Pc2] {
        let problems = check_recording(format, &heavy).unwrap_err();
        assert_eq!(problems[0].pointer, "/output/fields/1", "{}", format.name());
    }
}

#[test]
fn positions_beyond_f32_range_are_infinite_in_pc2_and_left_out_of_glb() {
    positions_beyond_f32_range(Readers::Crates);
}

#[test]
#[ignore = "needs NumPy (python3 -m pip install numpy), node and .ci/node (npm ci --prefix .ci/node)"]
fn positions_beyond_f32_range_read_back_in_numpy_and_the_khronos_validator() {
    positions_beyond_f32_range(Readers::CratesNumpyAndValidator);
}

fn positions_beyond_f32_range(readers: Readers) {
    let dir = scratch_dir(&format!("non-finite-flying-{readers:?}"));
    let mut flying = recording(FLYING);
    // Frames 4 to 10 thrown beyond f32::MAX (3.4e38), still finite in f64.
    for value in positions_mut(&mut flying)[4 * 9..].iter_mut().skip(1).step_by(3) {
        *value *= 1e37;
    }
    let result: Value = serde_json::from_slice(&encoded(&flying, Format::Json)).unwrap();
    let frames = result["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 11);
    let heights: Vec<f64> = frames.iter().map(|f| f["positions"][1].as_f64().unwrap()).collect();
    let beyond: Vec<usize> = (0..11).filter(|&k| !(heights[k] as f32).is_finite()).collect();
    assert_eq!(beyond, [4, 5, 6, 7, 8, 9, 10]);

    // PC2 holds the f32 values as they are: infinity where f32 has no finite value.
    let pc2 = f32s(&encoded(&flying, Format::Pc2)[32..]);
    assert_eq!(pc2.len(), 11 * 9);
    for (k, &height) in heights.iter().enumerate() {
        assert_eq!(pc2[9 * k + 1], height as f32, "frame {k}");
    }
    assert_eq!(pc2[9 * 10 + 1], f32::INFINITY);

    // glTF shows frames 0 to 3, the last of them as the base, and names those it left out.
    let glb = encoded(&flying, Format::Glb);
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
    validate_gltf(readers, &[&dir.join("flying.glb")]);

    // OBJ holds the f64 values as decimals: tobj (f64) reads back the last frame exactly.
    let models = tobj_load(&encoded(&flying, Format::Obj));
    let last: Vec<f64> =
        frames[10]["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert_eq!(models[0].mesh.positions, last);

    let npy = encoded(&flying, Format::Npy);
    std::fs::write(dir.join("flying.npy"), &npy).unwrap();
    std::fs::write(dir.join("flying.json"), result.to_string()).unwrap();
    numpy(
        readers,
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
    let mut recording = recording(FLYING);
    let positions = positions_mut(&mut recording);
    let last = positions.len() - 9;
    positions[last..last + 3].copy_from_slice(&[f64::NAN, f64::INFINITY, f64::NEG_INFINITY]);
    let obj = encoded(&recording, Format::Obj);
    let text = String::from_utf8(obj.clone()).unwrap();
    assert!(text.contains("\nv NaN Infinity -Infinity\n"), "{text}");
    let read = &tobj_load(&obj)[0].mesh.positions;
    assert!(read[0].is_nan());
    assert_eq!(read[1..3], [f64::INFINITY, f64::NEG_INFINITY]);

    // With no frame glTF can show, GLB is refused as a format that cannot carry the run.
    for value in positions_mut(&mut recording).iter_mut().skip(1).step_by(3) {
        *value = f64::NAN;
    }
    let problems = check_recording(Format::Glb, &recording).unwrap_err();
    assert_eq!(problems[0].pointer, "/output/frames");
    assert!(problems[0].detail.contains("finite"), "{}", problems[0].detail);
    assert!(encode(&recording, Format::Glb, &mut Vec::new()).is_err());
    assert_eq!(check_recording(Format::Pc2, &recording), Ok(()));
}
