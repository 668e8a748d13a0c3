//! SIGTERM on the real `drape serve`: it stops accepting, lets running jobs finish within the
//! grace period, cancels the rest, and exits 0. And `Jobs::shutdown` itself returns soon after
//! the grace period even when a job's thread never returns, handing its job back.

#![cfg(unix)]

mod deadline;
mod serve;

use std::time::Duration;

use deadline::{PATIENCE, within};
use serde_json::Value;
use serve::{Server, wait_for};

const LONG: &str = r#"{"duration": 1000, "dt": 0.001, "gravity": [0, 0, 0],
                      "bodies": [{"type": "chain", "count": 10000}],
                      "output": {"frames": "none"}}"#;
const SHORT: &str = r#"{"duration": 20, "dt": 0.001, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 1000}],
                       "output": {"frames": "final"}}"#;

/// Starts `drape serve` on the memory store with one worker and the given shutdown grace (s).
fn serve(dir: &tempfile::TempDir, grace: &str) -> Server {
    Server::start(dir.path(), "memory", &["--workers", "1", "--shutdown-grace", grace])
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
    wait_for(client, base, &id, |job| job["status"] == "running").await;
    id
}

/// The `end` event of a job's stream.
async fn end_event(response: reqwest::Response) -> Value {
    let text = within("the end of the event stream", response.text()).await.unwrap();
    let data = text
        .split("\n\n")
        .find_map(|block| block.strip_prefix("event: end\ndata: "))
        .unwrap_or_else(|| panic!("no end event in {text:?}"));
    serde_json::from_str(data).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_cancels_a_job_still_running_after_the_grace_period_and_exits_0() {
    let dir = tempfile::tempdir().unwrap();
    let server = serve(&dir, "0.1");
    let base = server.base.clone();
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

    server.sigterm();
    let end = end_event(stream).await;
    assert_eq!(end["status"], "cancelled");
    assert_eq!(end["message"], "the server shut down before the job finished");
    let queued_end = end_event(queued_stream).await;
    assert_eq!(queued_end["status"], "cancelled");
    assert_eq!(queued_end["progress"]["step"], 0, "a queued job is dropped, not run");

    assert!(server.exit_within(PATIENCE).0.success(), "drape serve exits 0 on SIGTERM");
    assert!(client.get(format!("{base}/healthz")).send().await.is_err(), "no longer accepting");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_lets_a_running_job_finish_within_the_grace_period() {
    let dir = tempfile::tempdir().unwrap();
    let server = serve(&dir, "600");
    let base = server.base.clone();
    let client = reqwest::Client::new();
    let id = submit_and_wait_running(&client, &base, SHORT).await;
    let stream = client.get(format!("{base}/jobs/{id}/events")).send().await.unwrap();
    server.sigterm();
    let end = end_event(stream).await;
    assert_eq!(end["status"], "succeeded");
    assert_eq!(end["progress"]["step"], 20_000); // 20 s / 0.001 s
    assert!(server.exit_within(PATIENCE).0.success(), "drape serve exits 0 on SIGTERM");
}

/// A job system whose one job blocks its worker thread for an hour, far past any test.
async fn stuck(store: std::sync::Arc<dyn drape::jobs::JobStore>) -> (drape::jobs::Jobs, drape::jobs::JobId) {
    use drape::jobs::{Jobs, JobsConfig, Submission};
    let config = JobsConfig {
        workers: 1,
        before_run: Some(std::sync::Arc::new(|_: &drape::scene::Compiled| {
            std::thread::sleep(Duration::from_secs(3600));
        })),
        ..JobsConfig::default()
    };
    let jobs = Jobs::start(store, config);
    let document: Value = serde_json::from_str(SHORT).unwrap();
    let scene = drape::scene::Scene::from_value(document.clone()).unwrap();
    let submission = Submission { scene, document, fingerprint: 0, idempotency_key: None, max_work: None };
    let id = jobs.submit(submission).await.unwrap().job.id;
    deadline::poll_until_some("the stuck job to be running", || async { (jobs.running() > 0).then_some(()) })
        .await;
    (jobs, id)
}

/// Shuts down with a grace of 0.2 s; returns how long it took, checked against a deadline far
/// above the grace plus the second a stopped job is given.
async fn shut_down(jobs: &drape::jobs::Jobs) -> Duration {
    let started = std::time::Instant::now();
    tokio::time::timeout(Duration::from_secs(20), jobs.shutdown(Duration::from_millis(200)))
        .await
        .expect("shutdown returned although a worker thread never did");
    started.elapsed()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_hands_back_the_job_of_a_thread_that_never_returns_on_a_durable_store() {
    let dir = tempfile::tempdir().unwrap();
    let store =
        std::sync::Arc::new(drape::jobs::SqliteStore::open(&dir.path().join("jobs.db")).await.unwrap());
    let (jobs, id) = stuck(store.clone()).await;
    let took = shut_down(&jobs).await;
    eprintln!("shutdown returned after {took:?} with a grace of 0.2 s");
    let job = drape::jobs::JobStore::get(&*store, &id).await.unwrap().unwrap();
    assert_eq!((job.status, job.attempts), (drape::jobs::JobStatus::Queued, 0), "back in the queue");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_cancels_the_job_of_a_thread_that_never_returns_on_the_memory_store() {
    let store = std::sync::Arc::new(drape::jobs::MemoryStore::new());
    let (jobs, id) = stuck(store.clone()).await;
    shut_down(&jobs).await;
    let job = drape::jobs::JobStore::get(&*store, &id).await.unwrap().unwrap();
    assert_eq!(
        (job.status, job.message.as_deref()),
        (drape::jobs::JobStatus::Cancelled, Some("the server shut down before the job finished"))
    );
}
