//! The scripts in `examples/curl/` work against `drape serve` as the README shows.

#![cfg(unix)]

mod deadline;
mod serve;

use std::path::Path;
use std::process::{Command, Output, Stdio};

use serde_json::Value;
use serve::Server;

const SCENE: &str = r#"{"duration": 0.5, "dt": 0.01, "bodies": [{"type": "chain", "count": 4}],
                       "output": {"frames": "final"}}"#;

fn run(base: &str, name: &str, args: &[&str]) -> Output {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/curl").join(name);
    Command::new(&path).args(args).env("DRAPE", base).output().unwrap()
}

fn script(base: &str, name: &str, args: &[&str]) -> Output {
    let output = run(base, name, args);
    assert!(output.status.success(), "{name} {args:?}: {}", String::from_utf8_lossy(&output.stderr));
    output
}

fn json(output: &Output) -> Value {
    serde_json::from_slice(&output.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&output.stdout)))
}

/// The JSON on the last line of a script's standard error (curl's own message comes first).
fn last_line_json(stderr: &[u8]) -> Value {
    let text = String::from_utf8_lossy(stderr);
    let last = text.lines().last().unwrap_or_default();
    serde_json::from_str(last).unwrap_or_else(|e| panic!("{e}: {text}"))
}

#[test]
fn every_curl_script_works_against_drape_serve() {
    if Command::new("curl").arg("--version").stdout(Stdio::null()).status().is_err() {
        panic!("curl is needed to check examples/curl/");
    }
    let dir = std::env::temp_dir().join(format!("drape-curl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let server = Server::start(&dir, "memory", &["--workers", "1"]);
    let base = server.base.clone();
    let scene = dir.join("scene.json");
    std::fs::write(&scene, SCENE).unwrap();
    let scene = scene.to_str().unwrap();

    assert_eq!(json(&script(&base, "healthz.sh", &[]))["status"], "ok");
    let result = json(&script(&base, "simulate.sh", &[scene]));
    assert_eq!(result["final"]["positions"].as_array().unwrap().len(), 12);

    let job = json(&script(&base, "submit_job.sh", &[scene, "curl-test"]));
    let id = job["id"].as_str().unwrap();
    let again = json(&script(&base, "submit_job.sh", &[scene, "curl-test"]));
    assert_eq!(again["id"], id, "same key, same job");
    let events = String::from_utf8(script(&base, "follow_events.sh", &[id]).stdout).unwrap();
    assert!(events.contains("event: end\ndata: "), "{events}");
    assert_eq!(json(&script(&base, "get_job.sh", &[id]))["status"], "succeeded");
    let saved = dir.join("result.json");
    script(&base, "get_result.sh", &[id, saved.to_str().unwrap()]);
    let saved: Value = serde_json::from_slice(&std::fs::read(&saved).unwrap()).unwrap();
    assert_eq!(saved["stats"]["steps"], 50);
    assert_eq!(json(&script(&base, "list_jobs.sh", &["0", "1"]))["jobs"][0]["id"], id);
    assert!(
        String::from_utf8(script(&base, "metrics.sh", &[]).stdout)
            .unwrap()
            .contains("drape_jobs{status=\"succeeded\"} 2")
    );
    assert_eq!(json(&script(&base, "openapi.sh", &[]))["openapi"], "3.1.0");

    let long = dir.join("long.json");
    std::fs::write(
        &long,
        SCENE.replace("0.5", "1000").replace("0.01", "0.001").replace("\"count\": 4", "\"count\": 1000"),
    )
    .unwrap();
    let running = json(&script(&base, "submit_job.sh", &[long.to_str().unwrap()]));
    let cancelled = json(&script(&base, "cancel_job.sh", &[running["id"].as_str().unwrap()]));
    assert_eq!(cancelled["id"], running["id"]);

    let ci = script(&base, "ci_job.sh", &[scene, dir.join("ci.json").to_str().unwrap()]);
    assert!(String::from_utf8(ci.stdout).unwrap().contains("status succeeded"));
    assert!(std::fs::read(dir.join("ci.json")).unwrap().starts_with(b"{\"mesh\""));

    // A refused scene or sweep: the CI scripts fail with 2 and print the problem body, which
    // names the field at fault, on standard error.
    let bad = dir.join("bad.json");
    std::fs::write(&bad, r#"{"duration": 1, "dt": -1, "bodies": [{"type": "chain", "count": 4}]}"#).unwrap();
    let refused = run(&base, "ci_job.sh", &[bad.to_str().unwrap(), dir.join("no.json").to_str().unwrap()]);
    assert_eq!(refused.status.code(), Some(2));
    let problem = last_line_json(&refused.stderr);
    assert_eq!(problem["status"], 422);
    assert_eq!(problem["errors"][0]["pointer"], "/dt", "{problem}");
    let refused = run(&base, "ci_sweep.sh", &[bad.to_str().unwrap(), dir.to_str().unwrap()]);
    assert_eq!(refused.status.code(), Some(2));
    let problem = last_line_json(&refused.stderr);
    assert_eq!(problem["status"], 422, "{problem}");

    let sweep = json(&script(&base, "submit_sweep.sh", &[]));
    let sweep_id = sweep["id"].as_str().unwrap();
    assert_eq!(sweep["variants"], 4);
    assert_eq!(json(&script(&base, "get_sweep.sh", &[sweep_id]))["id"], sweep_id);
    let plot = dir.join("plot.svg");
    script(&base, "sweep_plot.sh", &[sweep_id, plot.to_str().unwrap()]);
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
    let ci = script(&base, "ci_sweep.sh", &["", dir.to_str().unwrap()]);
    assert!(String::from_utf8(ci.stdout).unwrap().contains("runs not succeeded: 0"));
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    assert_eq!(csv.lines().count(), 5, "{csv}");
    let csv_again = String::from_utf8(script(&base, "get_sweep.sh", &[sweep_id, "csv"]).stdout).unwrap();
    assert!(csv_again.starts_with("/integrator,/dt,status,"), "{csv_again}");
    let cancelled = json(&script(&base, "cancel_sweep.sh", &[sweep_id]));
    assert_eq!(cancelled["complete"], true);

    server.terminate();
    std::fs::remove_dir_all(&dir).unwrap();
}
