//! `GET /metrics`: Prometheus text, every name prefixed `drape_`, and the middleware that times
//! requests for it.
//!
//! Job counts come from the store; queue length, running jobs and throughput from the job
//! system; request counts and latencies from [`HttpMetrics`], which the middleware fills with
//! atomics only.

use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::problem::AppError;

/// Upper bounds of the latency histogram's buckets, in seconds.
const BUCKETS: [f64; 12] = [0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 5.0, 30.0];

/// Request counts and latencies.
#[derive(Default)]
pub struct HttpMetrics {
    /// Requests per status class, `1xx` to `5xx`.
    by_class: [AtomicU64; 5],
    /// Requests no slower than each bucket's bound (not cumulative; summed when written).
    buckets: [AtomicU64; BUCKETS.len()],
    /// Requests slower than the last bound.
    overflow: AtomicU64,
    sum_micros: AtomicU64,
}

impl HttpMetrics {
    fn record(&self, status: u16, seconds: f64) {
        if let Some(class) = self.by_class.get(usize::from(status / 100).wrapping_sub(1)) {
            class.fetch_add(1, Ordering::Relaxed);
        }
        match BUCKETS.iter().position(|&bound| seconds <= bound) {
            Some(i) => self.buckets[i].fetch_add(1, Ordering::Relaxed),
            None => self.overflow.fetch_add(1, Ordering::Relaxed),
        };
        self.sum_micros.fetch_add((seconds * 1e6) as u64, Ordering::Relaxed);
    }
}

/// Times every request; the time is until the response head, not the end of a stream.
pub async fn track(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let started = Instant::now();
    let response = next.run(request).await;
    state.http_metrics.record(response.status().as_u16(), started.elapsed().as_secs_f64());
    response
}

/// Writes the metrics.
pub async fn metrics(State(state): State<AppState>) -> Result<Response, AppError> {
    let counts = state.jobs.count_by_status().await?;
    let jobs = &state.jobs;
    let mut text = String::new();
    let mut family = |name: &str, kind: &str, help: &str, samples: &[(String, f64)]| {
        let _ = writeln!(text, "# HELP drape_{name} {help}\n# TYPE drape_{name} {kind}");
        for (labels, value) in samples {
            let _ = writeln!(text, "drape_{name}{labels} {value}");
        }
    };
    let counts: Vec<_> =
        counts.iter().map(|(s, n)| (format!("{{status=\"{}\"}}", s.name()), *n as f64)).collect();
    family("jobs", "gauge", "Jobs in the store, by status.", &counts);
    family(
        "queue_length",
        "gauge",
        "Jobs waiting for a worker.",
        &[(String::new(), jobs.queue_len().await? as f64)],
    );
    let capacity = jobs.config().queue_capacity as f64;
    family("queue_capacity", "gauge", "Jobs that may wait for a worker.", &[(String::new(), capacity)]);
    family("running_jobs", "gauge", "Jobs being run.", &[(String::new(), jobs.running() as f64)]);
    family("workers", "gauge", "Worker threads.", &[(String::new(), jobs.config().workers as f64)]);
    let (particle_steps, busy) = jobs.throughput();
    family(
        "particle_steps_total",
        "counter",
        "Particle-steps taken by ended jobs and sweep runs.",
        &[(String::new(), particle_steps as f64)],
    );
    family(
        "worker_busy_seconds_total",
        "counter",
        "Worker time spent on ended jobs and sweep runs.",
        &[(String::new(), busy.as_secs_f64())],
    );
    let rate = if busy.is_zero() { 0.0 } else { particle_steps as f64 / busy.as_secs_f64() };
    family(
        "particle_steps_per_second",
        "gauge",
        "Particle-steps per second of worker time, over ended jobs and sweep runs.",
        &[(String::new(), rate)],
    );

    let http = &state.http_metrics;
    let classes: Vec<_> = (0..5)
        .map(|i| (format!("{{code=\"{}xx\"}}", i + 1), http.by_class[i].load(Ordering::Relaxed) as f64))
        .collect();
    family("http_requests_total", "counter", "HTTP requests, by status class.", &classes);
    let mut cumulative = 0;
    let mut histogram: Vec<_> = BUCKETS
        .iter()
        .zip(&http.buckets)
        .map(|(bound, count)| {
            cumulative += count.load(Ordering::Relaxed);
            (format!("_bucket{{le=\"{bound}\"}}"), cumulative as f64)
        })
        .collect();
    let total = cumulative + http.overflow.load(Ordering::Relaxed);
    histogram.push(("_bucket{le=\"+Inf\"}".into(), total as f64));
    histogram.push(("_sum".into(), http.sum_micros.load(Ordering::Relaxed) as f64 / 1e6));
    histogram.push(("_count".into(), total as f64));
    family(
        "http_request_duration_seconds",
        "histogram",
        "Time to the response head, in seconds.",
        &histogram,
    );
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8")], text).into_response())
}
