//! `drape run` from the shell: results on stdout, a diverged run is still a result, and a bad
//! scene exits non-zero naming its fields.

use std::io::Write;
use std::process::{Command, Output, Stdio};

fn drape_run(scene: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(["run", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(scene.as_bytes()).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn the_example_scene_runs_and_prints_its_result() {
    let out = Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(["run", "examples/hanging_cloth.json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let result: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(result["stats"]["status"], "succeeded");
    assert_eq!(result["final"]["t"], 2.0);
    assert_eq!(result["frames"].as_array().unwrap().len(), 21);
    // Two pinned corners hold the sheet: it hangs, so its centre is below the pins.
    let final_y: Vec<f64> = result["final"]["positions"]
        .as_array()
        .unwrap()
        .iter()
        .skip(1)
        .step_by(3)
        .map(|y| y.as_f64().unwrap())
        .collect();
    assert_eq!((final_y[0], final_y[19]), (1.5, 1.5));
    assert!(final_y[210] < 1.5);
}

#[test]
fn a_diverged_run_is_a_result() {
    let out = drape_run(
        r#"{"duration": 1, "dt": 0.05, "bodies": [{"type": "chain", "count": 3, "mass": 0.001, "pin": [0],
            "spring": {"k": 100000}}]}"#,
    );
    assert!(out.status.success());
    let result: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(result["stats"]["status"], "diverged");
    assert!(result["stats"]["diverged"]["suggested_dt"].as_f64().unwrap() < 0.05);
    assert!(result.get("final").is_none());
}

#[test]
fn a_bad_scene_exits_with_every_field_and_reason() {
    let out = drape_run(r#"{"duration": 1, "dt": -1, "bodies": [{"type": "cloth", "resolution": [1, 8]}]}"#);
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("/dt: must be positive, got -1"), "{stderr}");
    assert!(stderr.contains("/bodies/0/resolution/0: must be at least 2, got 1"), "{stderr}");
}

#[test]
fn malformed_json_exits_with_its_position() {
    let out = drape_run("{\"duration\": ");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8(out.stderr).unwrap().contains("line 1"));
}
