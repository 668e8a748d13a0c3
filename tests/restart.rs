//! Jobs survive a crash: `drape serve` on SQLite is killed with SIGKILL while a job runs and
//! others wait; started again on the same file, it serves the results it had, reruns the job
//! that was running from the start, and runs the queued ones.

#![cfg(unix)]

mod deadline;
mod serve;

use serde::de::IgnoredAny;
use serve::{Server, ended, job, result, submit, submit_sweep, under_way, wait_for, wait_for_sweep};

const TINY: &str = r#"{"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3}],
                      "output": {"frames": "final"}}"#;
/// Long enough to be killed in the middle (a few seconds), short enough to run again.
const MEDIUM: &str = r#"{"duration": 15, "dt": 0.001, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 20000}],
                        "output": {"frames": "final"}}"#;

/// 2 integrators × 12 steps of a 5,000-particle chain: a few seconds of runs, long enough to be
/// killed in the middle, each run tens of milliseconds.
fn sweep_of_chains() -> String {
    let dts: Vec<f64> = (0..12).map(|n| 0.001 + 0.0001 * f64::from(n)).collect();
    serde_json::json!({
        "scene": {"duration": 0.5, "gravity": [0, -9.81, 0],
                  "bodies": [{"type": "chain", "count": 5000, "mass": 500, "spring": {"k": 1000}, "pin": [0]}]},
        "vary": {"/integrator": ["symplectic_euler", "verlet"], "/dt": dts},
        "reference": {"integrator": "rk4", "dt": 0.0005},
    })
    .to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sweep_killed_in_the_middle_completes_after_a_restart() {
    let dir = tempfile::tempdir().unwrap();
    let store = "sqlite://jobs.db";
    let client = reqwest::Client::new();

    let first = Server::start(dir.path(), store, &["--workers", "1"]);
    let id = submit_sweep(&client, &first.base, &sweep_of_chains()).await;
    let part_way =
        wait_for_sweep(&client, &first.base, &id, |s| s["progress"]["finished"].as_u64() >= Some(2)).await;
    assert_eq!(part_way["complete"], false, "killed in the middle: {}", part_way["progress"]);
    first.kill();

    let second = Server::start(dir.path(), store, &["--workers", "1"]);
    let listed: serde_json::Value =
        client.get(format!("{}/sweeps", second.base)).send().await.unwrap().json().await.unwrap();
    assert_eq!(listed["sweeps"][0]["id"], id.as_str(), "the restarted server lists the sweep");
    let done = wait_for_sweep(&client, &second.base, &id, |s| s["complete"] == true).await;
    assert_eq!(done["progress"]["finished"], 25);
    assert_eq!(done["reference"]["status"], "succeeded", "{}", done["reference"]);
    let rows = done["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 24);
    for row in rows {
        assert_eq!(row["status"], "succeeded", "{row}");
        let steps = (0.5 / row["dt"].as_f64().unwrap()).round();
        assert_eq!(row["steps"].as_f64(), Some(steps), "{row}");
        assert!(row["error_vs_reference"]["max"].as_f64().unwrap() > 0.0, "{row}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_server_restarted_on_its_sqlite_file_finishes_every_job() {
    let dir = tempfile::tempdir().unwrap();
    let store = "sqlite://jobs.db";
    let client = reqwest::Client::new();

    let first = Server::start(dir.path(), store, &["--workers", "1"]);
    let done = submit(&client, &first.base, TINY).await;
    wait_for(&client, &first.base, &done, ended).await;
    let done_result = result(&client, &first.base, &done).await;
    let running = submit(&client, &first.base, MEDIUM).await;
    let mut waiting = Vec::new();
    for scene in [TINY, TINY] {
        waiting.push(submit(&client, &first.base, scene).await);
    }
    wait_for(&client, &first.base, &running, under_way).await;
    for id in &waiting {
        assert_eq!(job(&client, &first.base, id).await["status"], "queued");
    }
    first.kill();
    assert!(dir.path().join("jobs.db").exists(), "the store is the file named, in the working directory");

    let second = Server::start(dir.path(), store, &["--workers", "1"]);
    let base = &second.base;
    for id in waiting.iter().chain([&running]) {
        let ended = wait_for(&client, base, id, ended).await;
        assert_eq!(ended["status"], "succeeded", "{ended}");
    }
    assert_eq!(job(&client, base, &running).await["attempts"], 2, "run again from the start");
    assert_eq!(job(&client, base, &running).await["progress"]["step"], 15_000);
    for id in &waiting {
        assert_eq!(job(&client, base, id).await["attempts"], 1);
        let _: IgnoredAny = serde_json::from_value(result(&client, base, id).await).unwrap();
    }
    assert_eq!(result(&client, base, &done).await, done_result, "a finished result is served as it was");
    assert_eq!(job(&client, base, &done).await["attempts"], 1);
    let mut starts = second.starts();
    starts.sort();
    let mut expected: Vec<String> = waiting.iter().chain([&running]).cloned().collect();
    expected.sort();
    assert_eq!(starts, expected, "the restarted server ran the unfinished jobs, each once");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stopped_server_leaves_its_jobs_queued_for_the_next_start() {
    let dir = tempfile::tempdir().unwrap();
    let store = "sqlite://jobs.db";
    let client = reqwest::Client::new();
    let first = Server::start(dir.path(), store, &["--workers", "1", "--shutdown-grace", "0"]);
    let running = submit(&client, &first.base, MEDIUM).await;
    let waiting = submit(&client, &first.base, TINY).await;
    wait_for(&client, &first.base, &running, under_way).await;
    first.terminate();

    let second = Server::start(dir.path(), store, &["--workers", "1"]);
    // The job stopped by the shutdown was handed back, which does not count as an attempt.
    for (id, attempts) in [(&running, 1), (&waiting, 1)] {
        let job = wait_for(&client, &second.base, id, ended).await;
        assert_eq!(
            (job["status"].as_str(), job["attempts"].as_u64()),
            (Some("succeeded"), Some(attempts)),
            "{job}"
        );
    }
}
