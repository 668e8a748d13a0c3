//! Helpers shared by the HTTP tests: an app over a fresh job system, requests, and tiny scenes.
//! Its polls have the deadlines of `tests/deadline/mod.rs`, which a crate using this module
//! declares as `mod deadline` beside it.

#![allow(dead_code)]

use crate::deadline;

use std::sync::Arc;

use axum::Router;
use axum::body::Body;
use axum::http::{Request, Response};
use http_body_util::BodyExt;
use serde_json::Value;
use tower::ServiceExt;

use drape::api::{ApiConfig, AppState, app};
use drape::jobs::{Jobs, JobsConfig, MemoryStore};

/// A small scene: a 3-particle chain for 10 steps, the final frame only.
pub const TINY: &str = r#"{"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3}],
                          "output": {"frames": "final"}}"#;

/// A scene that runs for a long time (many seconds) unless cancelled.
pub const LONG: &str = r#"{"duration": 1000, "dt": 0.001, "gravity": [0, 0, 0],
                          "bodies": [{"type": "chain", "count": 10000}],
                          "output": {"frames": "none"}}"#;

/// Job settings for tests: one worker, a short queue.
pub fn jobs_config() -> JobsConfig {
    JobsConfig { workers: 1, queue_capacity: 4, ..JobsConfig::default() }
}

/// A job system and the app over it.
pub fn test_app(jobs: JobsConfig, api: ApiConfig) -> (Jobs, Router) {
    let jobs = Jobs::start(Arc::new(MemoryStore::new()), jobs);
    let router = app(AppState::new(jobs.clone(), api));
    (jobs, router)
}

/// A parsed response.
pub struct Answer {
    pub status: u16,
    pub headers: axum::http::HeaderMap,
    pub body: Vec<u8>,
}

impl Answer {
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&self.body)))
    }

    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.get(name).and_then(|v| v.to_str().ok())
    }

    /// The body as a problem, checking its media type and required members.
    pub fn problem(&self) -> Value {
        assert_eq!(self.header("content-type"), Some("application/problem+json"), "{}", self.text());
        let problem = self.json();
        assert_eq!(problem["status"], self.status, "{problem}");
        for member in ["type", "title", "detail"] {
            assert!(problem[member].is_string(), "{member} missing in {problem}");
        }
        problem
    }

    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// Sends one request through the router.
pub async fn send(app: &Router, request: Request<Body>) -> Answer {
    let response: Response<Body> = app.clone().oneshot(request).await.unwrap();
    let status = response.status().as_u16();
    let headers = response.headers().clone();
    let body = response.into_body().collect().await.unwrap().to_bytes().to_vec();
    Answer { status, headers, body }
}

pub async fn get(app: &Router, path: &str) -> Answer {
    send(app, Request::get(path).body(Body::empty()).unwrap()).await
}

pub async fn delete(app: &Router, path: &str) -> Answer {
    send(app, Request::delete(path).body(Body::empty()).unwrap()).await
}

pub async fn post_json(app: &Router, path: &str, body: &str) -> Answer {
    let request = Request::post(path)
        .header("content-type", "application/json")
        .body(Body::from(body.to_string()))
        .unwrap();
    send(app, request).await
}

/// Polls `GET /jobs/{id}` until `done` holds for the job, within [`deadline::PATIENCE`].
pub async fn poll_until(app: &Router, id: &str, done: impl Fn(&Value) -> bool) -> Value {
    deadline::poll_until_some(&format!("job {id} to get there"), || async {
        let job = get(app, &format!("/jobs/{id}")).await.json();
        done(&job).then_some(job)
    })
    .await
}

/// Waits, within [`deadline::PATIENCE`], until the job system runs a job.
pub async fn until_running(jobs: &Jobs) {
    deadline::poll_until_some("a job to be running", || async { (jobs.running() > 0).then_some(()) }).await;
}

pub fn is_final(job: &Value) -> bool {
    matches!(job["status"].as_str(), Some("succeeded" | "failed" | "diverged" | "cancelled"))
}
