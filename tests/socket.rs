//! The service over a real socket with a real HTTP client.

mod common;
mod deadline;
mod serve;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use common::{LONG, TINY, jobs_config};
use deadline::{PATIENCE, within};
use drape::api::{ApiConfig, AppState};
use drape::jobs::{Jobs, JobsConfig, MemoryStore};
use futures_util::StreamExt;
use serde_json::Value;
use serve::submit;
use tokio::net::TcpListener;

/// A server on a free port, stopped when the returned sender is dropped.
async fn start(jobs: JobsConfig) -> (String, tokio::sync::oneshot::Sender<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr: SocketAddr = listener.local_addr().unwrap();
    let state = AppState::new(Jobs::start(Arc::new(MemoryStore::new()), jobs), ApiConfig::default());
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    tokio::spawn(drape::server::serve(
        listener,
        state,
        async {
            let _ = stopped.await;
        },
        Duration::ZERO,
    ));
    (format!("http://{addr}"), stop)
}

async fn wait_for_status(client: &reqwest::Client, base: &str, id: &str, status: &str) {
    serve::wait_for(client, base, id, |job| job["status"] == status).await;
}

/// Reads server-sent events as (name, data) pairs.
struct Events {
    stream: std::pin::Pin<Box<dyn futures_util::Stream<Item = reqwest::Result<bytes::Bytes>> + Send>>,
    buffer: String,
}

impl Events {
    async fn open(client: &reqwest::Client, url: String) -> Self {
        let response = client.get(url).send().await.unwrap();
        assert_eq!(response.status(), 200);
        assert_eq!(response.headers()["content-type"], "text/event-stream");
        Self { stream: Box::pin(response.bytes_stream()), buffer: String::new() }
    }

    /// The next event, or `None` when the stream ends; within [`PATIENCE`].
    async fn next(&mut self) -> Option<(String, Value)> {
        within("the next server-sent event", self.next_unbounded()).await
    }

    async fn next_unbounded(&mut self) -> Option<(String, Value)> {
        loop {
            if let Some(end) = self.buffer.find("\n\n") {
                let block: String = self.buffer.drain(..end + 2).collect();
                let field = |name: &str| {
                    block.lines().find_map(|l| l.strip_prefix(name).map(|v| v.trim_start().to_string()))
                };
                match (field("event:"), field("data:")) {
                    (Some(name), Some(data)) => return Some((name, serde_json::from_str(&data).unwrap())),
                    _ => continue, // a keep-alive comment
                }
            }
            let chunk = self.stream.next().await?.unwrap();
            self.buffer.push_str(std::str::from_utf8(&chunk).unwrap());
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn submit_follow_events_and_fetch_the_result() {
    let (base, _stop) = start(jobs_config()).await;
    let client = reqwest::Client::new();
    // A long job holds the only worker, so the followed job is still queued when its stream
    // opens and the stream must show it from step 0 to its end.
    let blocker = submit(&client, &base, LONG).await;
    wait_for_status(&client, &base, &blocker, "running").await;
    let scene = r#"{"duration": 20, "dt": 0.001, "bodies": [{"type": "chain", "count": 50}],
                    "output": {"frames": "final"}}"#;
    let id = submit(&client, &base, scene).await;
    let mut events = Events::open(&client, format!("{base}/jobs/{id}/events")).await;
    let (name, first) = events.next().await.unwrap();
    assert_eq!(
        (name.as_str(), first["step"].as_u64(), first["steps"].as_u64()),
        ("progress", Some(0), Some(20_000))
    );
    assert_eq!(client.delete(format!("{base}/jobs/{blocker}")).send().await.unwrap().status(), 202);

    let mut last_step = 0;
    let mut end = None;
    let started = std::time::Instant::now();
    while end.is_none() {
        assert!(started.elapsed() < PATIENCE, "no end event within {PATIENCE:?}");
        let (name, data) = events.next().await.expect("the stream ends with an end event");
        if name == "end" {
            end = Some(data);
            continue;
        }
        assert_eq!(name, "progress");
        let step = data["step"].as_u64().unwrap();
        assert!(step > last_step, "progress moves forward: {step} after {last_step}");
        let fraction = data["fraction"].as_f64().unwrap();
        assert!((fraction - step as f64 / 20_000.0).abs() < 1e-12 && fraction <= 1.0);
        assert!((data["t"].as_f64().unwrap() - step as f64 * 0.001).abs() < 1e-9);
        last_step = step;
    }
    let end = end.unwrap();
    assert!(events.next().await.is_none(), "nothing after the end event");
    assert_eq!(end["status"], "succeeded");
    assert_eq!(end["progress"]["step"], 20_000);

    let response = client.get(format!("{base}/jobs/{id}/result")).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let result: Value = response.json().await.unwrap();
    // Closed form: 20 s / 0.001 s = 20,000 steps; 50 particles × 3 coordinates.
    assert_eq!(result["stats"]["steps"], 20_000);
    assert_eq!(result["final"]["t"], 20.0);
    assert_eq!(result["final"]["positions"].as_array().unwrap().len(), 150);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_long_job_is_cancelled_and_its_stream_ends() {
    let (base, _stop) = start(jobs_config()).await;
    let client = reqwest::Client::new();
    let id = submit(&client, &base, LONG).await;
    let mut events = Events::open(&client, format!("{base}/jobs/{id}/events")).await;
    within("a progress event past step 0", async {
        loop {
            let (name, data) = events.next().await.unwrap();
            assert_eq!(name, "progress");
            if data["step"].as_u64().unwrap() > 0 {
                break;
            }
        }
    })
    .await;
    let response = client.delete(format!("{base}/jobs/{id}")).send().await.unwrap();
    assert_eq!(response.status(), 202);
    let end = within("the end event", async {
        loop {
            let (name, data) = events.next().await.unwrap();
            if name == "end" {
                break data;
            }
        }
    })
    .await;
    assert_eq!(end["status"], "cancelled");
    assert_eq!(end["message"], "cancelled by request");
    assert!(end["progress"]["step"].as_u64().unwrap() < 1_000_000);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_queue_is_refused_with_429() {
    let (base, _stop) = start(JobsConfig { queue_capacity: 2, ..jobs_config() }).await;
    let client = reqwest::Client::new();
    let running = submit(&client, &base, LONG).await;
    wait_for_status(&client, &base, &running, "running").await;
    submit(&client, &base, TINY).await;
    submit(&client, &base, TINY).await;
    let response = client
        .post(format!("{base}/jobs"))
        .header("content-type", "application/json")
        .body(TINY)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 429);
    assert_eq!(response.headers()["retry-after"], "1");
    assert_eq!(response.headers()["content-type"], "application/problem+json");
    let metrics = client.get(format!("{base}/metrics")).send().await.unwrap().text().await.unwrap();
    assert!(
        metrics.contains("drape_queue_length 2\n") && metrics.contains("drape_running_jobs 1\n"),
        "{metrics}"
    );
    client.delete(format!("{base}/jobs/{running}")).send().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_job_fails_alone_while_another_succeeds() {
    let jobs = JobsConfig {
        workers: 2,
        before_run: Some(Arc::new(|c: &drape::scene::Compiled| {
            if c.duration == 0.25 {
                panic!("injected failure");
            }
        })),
        ..jobs_config()
    };
    let (base, _stop) = start(jobs).await;
    let client = reqwest::Client::new();
    let simulate = |scene: String| {
        let client = client.clone();
        let url = format!("{base}/simulate");
        async move {
            client.post(url).header("content-type", "application/json").body(scene).send().await.unwrap()
        }
    };
    let (doomed, fine) = tokio::join!(simulate(TINY.replace("0.1", "0.25")), simulate(TINY.to_string()));
    assert_eq!(doomed.status(), 500);
    let problem: Value = doomed.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/job-failed");
    assert!(
        problem["detail"].as_str().unwrap().ends_with("failed: the simulation panicked: injected failure")
    );
    assert_eq!(fine.status(), 200);
    assert_eq!(fine.json::<Value>().await.unwrap()["stats"]["status"], "succeeded");
    assert_eq!(client.get(format!("{base}/healthz")).send().await.unwrap().status(), 200);
}
