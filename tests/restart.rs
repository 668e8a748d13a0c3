//! Jobs survive a crash: `drape serve` on SQLite is killed with SIGKILL while a job runs and
//! others wait; started again on the same file, it serves the results it had, reruns the job
//! that was running from the start, and runs the queued ones.

#![cfg(unix)]

mod deadline;
mod serve;

use serde::de::IgnoredAny;
use serve::{Server, ended, job, result, submit, under_way, wait_for};

const TINY: &str = r#"{"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3}],
                      "output": {"frames": "final"}}"#;
/// Long enough to be killed in the middle (a few seconds), short enough to run again.
const MEDIUM: &str = r#"{"duration": 15, "dt": 0.001, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 20000}],
                        "output": {"frames": "final"}}"#;

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
