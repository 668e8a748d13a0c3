//! `drape run` from the shell: results on stdout, a diverged run is still a result (and exits
//! 1), and a bad scene exits non-zero naming its fields.

mod terminal;

use std::io::Write;
use std::process::{Command, Output, Stdio};

use terminal::drape_in_terminal;

fn drape_run(scene: &str) -> Output {
    drape(&["run", "-"], scene)
}

/// `drape` with `args`, `input` on its standard input.
fn drape(args: &[&str], input: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(args)
        .env_remove("DRAPE_MEMORY_BUDGET")
        .env_remove("DRAPE_MAX_STEPS")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input.as_bytes()).unwrap();
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
    // From examples/hanging_cloth.json: 2 s at 10 fps is 21 frames (t = 0 included).
    assert_eq!(result["final"]["t"], 2.0);
    assert_eq!(result["frames"].as_array().unwrap().len(), 21);
    // Two pinned corners hold the sheet: it hangs, so its centre is below the pins. The 20 × 20,
    // 1 m sheet is centred at y = 1, upright, so its top row (particles 0 to 19, the pinned
    // corners at both ends) is at y = 1.5; particle 210 (row 10, column 10) is near its middle.
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
fn a_diverged_run_is_a_result_and_exits_1() {
    let out = drape_run(
        r#"{"duration": 1, "dt": 0.05, "bodies": [{"type": "chain", "count": 3, "mass": 0.001, "pin": [0],
            "spring": {"k": 100000}}]}"#,
    );
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("diverged"));
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

/// The 629-byte scene of the issue: every pair of a 300² cloth's particles a self-collision
/// candidate, 30 GiB of pairs.
const THICK_CLOTH: &str = r#"{"duration":0.01,"dt":0.005,"integrator":"symplectic_euler","error_estimate":"none","self_collision":{"thickness":10},"bodies":[{"type":"cloth","resolution":[300,300],"size":[1,1]}],"output":{"frames":"final"}}"#;

#[test]
fn drape_run_refuses_what_the_server_refuses_naming_the_field() {
    let chain = r#""bodies": [{"type": "chain"}]"#;
    for (scene, pointer) in [
        (THICK_CLOTH.to_string(), "/self_collision/thickness: "),
        (format!(r#"{{"duration": 1e9, {chain}}}"#), "/duration: "),
        (format!(r#"{{"duration": 1, "dt": 1e-12, {chain}}}"#), "/dt: "),
        (format!(r#"{{"duration": 1, "output": {{"fps": 1e9}}, {chain}}}"#), "/output/fps: "),
        (
            r#"{"duration": 1, "bodies": [{"type": "cloth", "resolution": [100000, 100000]}]}"#.into(),
            "/bodies/0/resolution: ",
        ),
    ] {
        let out = drape_run(&scene);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{scene}: {stderr}");
        assert!(out.stdout.is_empty());
        assert!(stderr.lines().any(|l| l.trim_start().starts_with(pointer)), "{scene}: {stderr}");
    }
}

#[test]
fn a_flag_or_a_variable_lifts_a_limit() {
    let scene = r#"{"duration": 1, "dt": 1e-4, "error_estimate": "none", "bodies": [{"type": "chain", "count": 2}],
                    "output": {"frames": "final"}}"#;
    let tight = drape(&["run", "--max-steps", "9999", "-"], scene);
    assert_eq!(tight.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&tight.stderr).contains("/dt: the run needs 10000 steps"));
    assert!(drape(&["run", "--max-steps", "10000", "-"], scene).status.success());

    // 2 particles, 1 spring, 10,000 steps: 30,000 element-steps.
    let out = drape(&["run", "--max-work", "29999", "-"], scene);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-work"));
    // The variable sets the limit when no flag is given; a flag given wins over it.
    let with_variable = |args: &[&str], work: &str| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drape"))
            .args(args)
            .env("DRAPE_MAX_WORK", work)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        child.stdin.take().unwrap().write_all(scene.as_bytes()).unwrap();
        child.wait_with_output().unwrap().status.code()
    };
    assert_eq!(with_variable(&["run", "-"], "29999"), Some(2));
    assert_eq!(with_variable(&["run", "-"], "30000"), Some(0));
    assert_eq!(with_variable(&["run", "--max-work", "30000", "-"], "1"), Some(0));

    // The memory budget: the thin cloth's pairs take about half a gigabyte.
    let thin = THICK_CLOTH.replace(r#""thickness":10"#, r#""thickness":0.02"#).replace("0.01", "0.005");
    let out = drape(&["run", "--memory-budget", "256M", "-"], &thin);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("/self_collision/thickness: the run needs about"), "{stderr}");
    assert!(drape(&["run", "--memory-budget", "2G", "-"], &thin).status.success());
}

#[test]
fn drape_sweep_refuses_a_variant_over_the_limits_at_its_vary_entry() {
    let sweep =
        r#"{"scene": {"duration": 1, "bodies": [{"type": "chain"}]}, "vary": {"/dt": [0.01, 1e-12]}}"#;
    let out = drape(&["sweep", "-"], sweep);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("/vary/~1dt/1: variant 1: the run needs"), "{stderr}");
    assert!(out.stdout.is_empty());
    // Within the limits, the sweep runs.
    let out = drape(
        &["sweep", "--max-steps", "100", "-"],
        r#"{"scene": {"duration": 1, "bodies": [{"type": "chain"}]}, "vary": {"/dt": [0.01, 0.02]}}"#,
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_run_that_meets_more_self_collision_pairs_than_it_may_hold_exits_1_with_the_reason() {
    // Two cloths, one falling onto the other; a budget that leaves little beyond the pairs at
    // rest (the 64 MiB kept for the process is all but the run's share).
    let scene = r#"{"duration": 0.2, "dt": 2e-4, "gravity": [0, 0, 0], "error_estimate": "none",
        "bodies": [{"type": "cloth", "resolution": [10, 10], "center": [0, 0.5, 0], "velocity": [0, -5, 0]},
                   {"type": "cloth", "resolution": [10, 10], "center": [0, 0, 0]}],
        "self_collision": {"thickness": 0.06}, "output": {"frames": "final"}}"#;
    let parsed = drape::scene::Scene::from_json(scene.as_bytes()).unwrap();
    let memory = drape::jobs::Limits::default().admit(&parsed).unwrap().cost.memory();
    let budget = (memory + drape::config::MEMORY_RESERVE).to_string();
    let out = drape(&["run", "--memory-budget", &budget, "-"], scene);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("failed: self-collision met") && stderr.contains("candidate pairs"), "{stderr}");
    assert!(out.stdout.is_empty());
}

#[test]
fn a_run_and_a_sweep_show_progress_on_a_terminal_and_nowhere_else() {
    let dir = tempfile::tempdir().unwrap();
    // 20,000 steps: long enough that the first redraw comes before the end.
    let scene = dir.path().join("chain.json");
    std::fs::write(
        &scene,
        r#"{"duration": 2, "dt": 0.0001, "bodies": [{"type": "chain", "count": 50}], "output": {"frames": "final"}}"#,
    )
    .unwrap();
    let result = dir.path().join("result.json");
    let args = format!("run {} -o {}", scene.display(), result.display());
    let shown = drape_in_terminal(&args);
    assert!(shown.contains("/20000 steps") && shown.contains(" left"), "{shown:?}");
    assert!(std::fs::read(&result).unwrap().starts_with(b"{"));
    let quiet = drape_in_terminal(&format!("{args} --quiet"));
    assert!(!quiet.contains("steps"), "{quiet:?}");

    let sweep = dir.path().join("sweep.json");
    std::fs::write(
        &sweep,
        format!(
            r#"{{"scene": {}, "vary": {{"/dt": [0.0001, 0.0002, 0.0004]}}}}"#,
            std::fs::read_to_string(&scene).unwrap()
        ),
    )
    .unwrap();
    let shown = drape_in_terminal(&format!("sweep {} --csv", sweep.display()));
    assert!(shown.contains("/3 runs"), "{shown:?}");

    // Not a terminal: standard error carries nothing for a run that succeeds.
    let piped =
        Command::new(env!("CARGO_BIN_EXE_drape")).args(["run", scene.to_str().unwrap()]).output().unwrap();
    assert!(piped.status.success());
    assert_eq!(String::from_utf8_lossy(&piped.stderr), "");
}

#[test]
fn drape_sweep_fails_a_ci_step_whose_orders_or_errors_cross_the_thresholds() {
    let sweep = "examples/sweeps/single_spring_orders.json";
    let gated = |flags: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_drape"))
            .args(["sweep", sweep, "--csv", "--quiet"])
            .args(flags)
            .env_remove("DRAPE_MEMORY_BUDGET")
            .output()
            .unwrap();
        (out.status.code(), String::from_utf8(out.stderr).unwrap())
    };
    // The sweep's orders are about 1, 1, 2, 4 and 1 (src/sweep/tests.rs checks them).
    assert_eq!(gated(&["--min-order", "0.8"]), (Some(0), String::new()));
    let (code, stderr) = gated(&["--min-order", "1.5"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(stderr.lines().filter(|l| l.contains("is below --min-order 1.5")).count(), 3, "{stderr}");
    assert!(!stderr.contains("verlet") && !stderr.contains("rk4"), "{stderr}");
    // RK4's largest error is about 1e-8 m, explicit Euler's about 2e-2 m.
    let (code, stderr) = gated(&["--max-error", "1e-3"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("/integrator = explicit_euler, /dt = 0.004: error "), "{stderr}");
    assert!(!stderr.contains("rk4"), "{stderr}");
    assert_eq!(gated(&["--max-error", "1"]).0, Some(0));
    // A threshold that cannot apply is a usage error, before anything runs.
    let out = Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(["sweep", "-", "--min-order", "1"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .and_then(|mut child| {
            child.stdin.take().unwrap().write_all(
                br#"{"scene": {"duration": 0.1, "bodies": [{"type": "chain", "count": 3}]}, "vary": {"/dt": [0.01, 0.02]}}"#,
            )?;
            child.wait_with_output()
        })
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr)
            .contains("--min-order needs a sweep that varies /dt and has a reference")
    );
}
