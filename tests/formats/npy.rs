//! NPY and NPZ, loaded by NumPy (a Python script run from here) and compared bit for bit with
//! the JSON result; the NPY header also checked byte for byte here.

use std::process::Command;

use drape::output::{Format, write_json};

use crate::common::{Run, mixed_scene, repo, require_numpy, scratch_dir};

fn check_with_numpy(test: &str, scene: &str) {
    require_numpy();
    let run = Run::new(scene);
    let dir = scratch_dir(test);
    let mut json = Vec::new();
    write_json(&run.recording, &mut json).unwrap();
    std::fs::write(dir.join("result.json"), json).unwrap();
    // NPY carries positions only: encode it from the same recording without the other fields.
    let mut positions_only = run.recording.clone();
    let f = &mut positions_only.frames;
    (f.velocities, f.normals, f.energy, f.strain) = (None, None, None, None);
    let mut npy = Vec::new();
    drape::output::encode(&positions_only, Format::Npy, &mut npy).unwrap();
    std::fs::write(dir.join("result.npy"), npy).unwrap();
    std::fs::write(dir.join("result.npz"), run.encode(Format::Npz)).unwrap();
    let output = Command::new("python3")
        .arg(repo().join("tests/support/check_numpy.py"))
        .args(["result.json", "result.npy", "result.npz"].map(|f| dir.join(f)))
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    println!("{stdout}");
    assert!(output.status.success(), "NumPy disagrees:\n{stdout}\n{stderr}");
    assert!(stdout.contains("npy positions"), "{stdout}");
}

#[test]
#[ignore = "needs NumPy (python3 -m pip install numpy)"]
fn numpy_loads_every_field_of_an_f64_run_bit_for_bit() {
    check_with_numpy(
        "f64",
        &mixed_scene("f64", "all", &["positions", "velocities", "normals", "energy", "strain"]),
    );
}

#[test]
#[ignore = "needs NumPy (python3 -m pip install numpy)"]
fn numpy_loads_an_f32_run_bit_for_bit() {
    check_with_numpy("f32", &mixed_scene("f32", "all", &["positions", "velocities", "energy"]));
}

#[test]
#[ignore = "needs NumPy (python3 -m pip install numpy)"]
fn numpy_loads_a_final_frame() {
    check_with_numpy("final", &mixed_scene("f32", "final", &["positions", "strain"]));
}

#[test]
fn npy_is_header_then_little_endian_positions() {
    let run = Run::new(&mixed_scene("f64", "all", &["positions"]));
    let bytes = run.encode(Format::Npy);
    let (frames, particles) = (run.frames().len(), run.recording.particles);
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    assert_eq!((10 + header_len) % 64, 0);
    let header = std::str::from_utf8(&bytes[10..10 + header_len]).unwrap();
    assert_eq!(
        header.trim_end(),
        format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({frames}, {particles}, 3), }}")
    );
    assert!(header.ends_with('\n'));
    let data: Vec<u64> =
        bytes[10 + header_len..].chunks_exact(8).map(|b| u64::from_le_bytes(b.try_into().unwrap())).collect();
    let json: Vec<u64> =
        run.frames().iter().flat_map(|f| crate::common::numbers(&f["positions"])).map(f64::to_bits).collect();
    assert_eq!(data, json);
}
