//! SIGTERM on the real `drape serve`: it stops accepting, lets running jobs finish within the
//! grace period, cancels the rest, and exits 0.

#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use serde_json::Value;

const LONG: &str = r#"{"duration": 1000, "dt": 0.001, "gravity": [0, 0, 0],
                      "bodies": [{"type": "chain", "count": 10000}],
                      "output": {"frames": "none"}}"#;
const SHORT: &str = r#"{"duration": 20, "dt": 0.001, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 1000}],
                       "output": {"frames": "final"}}"#;

/// Starts `drape serve` on a free port and returns it with its base URL.
fn serve(grace: &str) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_drape"))
        .args([
            "serve",
            "--store",
            "memory",
            "--addr",
            "127.0.0.1:0",
            "--workers",
            "1",
            "--shutdown-grace",
            grace,
        ])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let base = line.trim().strip_prefix("drape listening on ").expect("the address line").to_string();
    (child, base)
}

fn sigterm(child: &Child) {
    let status = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
}

/// Waits for the process to exit; a hang shows as the test never ending, not as a time limit.
fn wait(mut child: Child) -> std::process::ExitStatus {
    child.wait().unwrap()
}

async fn submit_and_wait_running(client: &reqwest::Client, base: &str, scene: &str) -> String {
    let job: Value = client
        .post(format!("{base}/jobs"))
        .header("content-type", "application/json")
        .body(scene.to_string())
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let id = job["id"].as_str().unwrap().to_string();
    loop {
        let job: Value = client.get(format!("{base}/jobs/{id}")).send().await.unwrap().json().await.unwrap();
        if job["status"] == "running" {
            return id;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// The `end` event of a job's stream.
async fn end_event(response: reqwest::Response) -> Value {
    let text = response.text().await.unwrap();
    let data = text
        .split("\n\n")
        .find_map(|block| block.strip_prefix("event: end\ndata: "))
        .unwrap_or_else(|| panic!("no end event in {text:?}"));
    serde_json::from_str(data).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_cancels_a_job_still_running_after_the_grace_period_and_exits_0() {
    let (child, base) = serve("0.1");
    let client = reqwest::Client::new();
    let id = submit_and_wait_running(&client, &base, LONG).await;
    let queued: Value = client
        .post(format!("{base}/jobs"))
        .header("content-type", "application/json")
        .body(SHORT)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(queued["status"], "queued");
    let stream = client.get(format!("{base}/jobs/{id}/events")).send().await.unwrap();
    let queued_stream =
        client.get(format!("{base}/jobs/{}/events", queued["id"].as_str().unwrap())).send().await.unwrap();

    sigterm(&child);
    let end = end_event(stream).await;
    assert_eq!(end["status"], "cancelled");
    assert_eq!(end["message"], "the server shut down before the job finished");
    let queued_end = end_event(queued_stream).await;
    assert_eq!(queued_end["status"], "cancelled");
    assert_eq!(queued_end["progress"]["step"], 0, "a queued job is dropped, not run");

    assert!(wait(child).success());
    assert!(client.get(format!("{base}/healthz")).send().await.is_err(), "no longer accepting");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_lets_a_running_job_finish_within_the_grace_period() {
    let (child, base) = serve("600");
    let client = reqwest::Client::new();
    let id = submit_and_wait_running(&client, &base, SHORT).await;
    let stream = client.get(format!("{base}/jobs/{id}/events")).send().await.unwrap();
    sigterm(&child);
    let end = end_event(stream).await;
    assert_eq!(end["status"], "succeeded");
    assert_eq!(end["progress"]["step"], 20_000);
    assert!(wait(child).success());
}
