//! The `/sweeps` endpoints through `app().oneshot(...)`: a sweep runs as jobs to a table, CSV
//! and plot; bad sweeps are refused before any job starts; a sweep can be cancelled.

mod common;
mod deadline;

use std::time::Duration;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::ApiConfig;
use drape::jobs::{JobsConfig, Limits};
use serde_json::{Value, json};

/// A single spring (one pinned end, 1 s) as a sweep base scene.
fn single_spring() -> Value {
    json!({
        "duration": 1.0, "gravity": [0, 0, 0],
        "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [1.1, 0, 0], "count": 2, "mass": 2.0,
                    "spring": {"k": 100, "rest_length": 1.0}, "pin": [0]}],
        "output": {"frames": "none"}
    })
}

/// Two integrators × three steps, against an rk4 reference at a much finer step.
fn orders_sweep() -> String {
    json!({
        "scene": single_spring(),
        "vary": {"/integrator": ["symplectic_euler", "rk4"], "/dt": [0.004, 0.002, 0.001]},
        "reference": {"integrator": "rk4", "dt": 0.00001}
    })
    .to_string()
}

fn config(workers: usize, queue_capacity: usize) -> JobsConfig {
    JobsConfig { workers, queue_capacity, ..JobsConfig::default() }
}

/// Polls `GET /sweeps/{id}` until it is complete, for at most two minutes.
async fn until_complete(app: &axum::Router, id: &str) -> Value {
    tokio::time::timeout(Duration::from_secs(120), async {
        loop {
            let sweep = get(app, &format!("/sweeps/{id}")).await.json();
            if sweep["complete"] == true {
                return sweep;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("the sweep completes within two minutes")
}

/// The pointers of a 422 problem.
fn pointers(answer: &Answer) -> Vec<String> {
    assert_eq!(answer.status, 422, "{}", answer.text());
    let problem = answer.problem();
    problem["errors"].as_array().unwrap().iter().map(|e| e["pointer"].as_str().unwrap().to_string()).collect()
}

/// Every job the service holds, with its status.
async fn job_statuses(app: &axum::Router) -> Vec<(String, String)> {
    let list = get(app, "/jobs?limit=100").await.json();
    list["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| (j["id"].as_str().unwrap().to_string(), j["status"].as_str().unwrap().to_string()))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sweep_runs_to_a_table_csv_and_plot() {
    let (_, app) = test_app(config(2, 16), ApiConfig::default());
    let answer = post_json(&app, "/sweeps", &orders_sweep()).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let submitted = answer.json();
    let id = submitted["id"].as_str().unwrap().to_string();
    assert_eq!(answer.header("location"), Some(format!("/sweeps/{id}").as_str()));
    assert_eq!(submitted["variants"], 6);
    assert_eq!(submitted["progress"]["runs"], 7);
    assert_eq!(submitted["rows"].as_array().unwrap().len(), 6);

    let sweep = until_complete(&app, &id).await;
    assert_eq!(sweep["progress"]["finished"], 7);
    assert_eq!(sweep["reference"]["status"], "succeeded");
    let rows = sweep["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for (row, (integrator, dt)) in rows.iter().zip([
        ("symplectic_euler", 0.004),
        ("symplectic_euler", 0.002),
        ("symplectic_euler", 0.001),
        ("rk4", 0.004),
        ("rk4", 0.002),
        ("rk4", 0.001),
    ]) {
        assert_eq!(row["status"], "succeeded", "{row}");
        assert_eq!((row["integrator"].as_str(), row["dt"].as_f64()), (Some(integrator), Some(dt)), "{row}");
        assert_eq!(row["steps"].as_f64(), Some((1.0 / dt).round()), "{row}");
        let error = row["error_vs_reference"]["max"].as_f64().unwrap();
        assert!(error > 0.0 && error < 0.1, "{row}");
    }
    // Symplectic Euler is first order, RK4 fourth (their textbook orders of accuracy): the
    // observed slopes say so, within ±0.15.
    let orders: Vec<(String, f64)> = sweep["convergence"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["group"]["/integrator"].as_str().unwrap().to_string(), c["order"].as_f64().unwrap()))
        .collect();
    assert_eq!(orders.len(), 2, "{orders:?}");
    assert_eq!(orders[0].0, "symplectic_euler");
    assert!((orders[0].1 - 1.0).abs() < 0.15, "{orders:?}");
    assert_eq!(orders[1].0, "rk4");
    assert!((orders[1].1 - 4.0).abs() < 0.15, "{orders:?}");

    // The CSV: one record per variant, the varied values first.
    let csv_answer = get(&app, &format!("/sweeps/{id}?format=csv")).await;
    assert_eq!(csv_answer.status, 200);
    assert!(csv_answer.header("content-type").unwrap().starts_with("text/csv"));
    let mut reader = csv::Reader::from_reader(csv_answer.body.as_slice());
    let header = reader.headers().unwrap().clone();
    assert_eq!(&header[0], "/integrator");
    assert_eq!(&header[1], "/dt");
    let status = header.iter().position(|h| h == "status").unwrap();
    let records: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(records.len(), 6);
    assert_eq!(&records[3][0], "rk4");
    assert!(records.iter().all(|r| &r[status] == "succeeded"));
    let by_accept = send(
        &app,
        Request::get(format!("/sweeps/{id}")).header("accept", "text/csv").body(Body::empty()).unwrap(),
    )
    .await;
    assert_eq!(by_accept.header("content-type"), csv_answer.header("content-type"));
    assert_eq!(by_accept.body.len(), csv_answer.body.len());

    // The plot: well-formed SVG with one series per integrator.
    let plot = get(&app, &format!("/sweeps/{id}/plot.svg")).await;
    assert_eq!(plot.status, 200);
    assert_eq!(plot.header("content-type"), Some("image/svg+xml"));
    let text = plot.text();
    let svg = roxmltree::Document::parse(&text).unwrap();
    let series: Vec<&str> = svg
        .descendants()
        .filter(|n| n.attribute("class") == Some("series"))
        .filter_map(|n| n.attribute("data-integrator"))
        .collect();
    assert_eq!(series, ["symplectic_euler", "rk4"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_sweeps_are_refused_naming_the_pointer_before_any_job() {
    let api = ApiConfig { max_sweep_variants: 4, ..ApiConfig::default() };
    let limits = Limits { max_steps: 500, ..Limits::default() };
    let (_, app) = test_app(JobsConfig { limits, ..config(1, 16) }, api);
    let sweep = |vary: Value| json!({"scene": single_spring(), "vary": vary}).to_string();

    let missing = post_json(&app, "/sweeps", &sweep(json!({"/nothing/here": [1]}))).await;
    assert_eq!(pointers(&missing), ["/vary/~1nothing~1here"]);
    let refused = post_json(&app, "/sweeps", &sweep(json!({"/dt": [0.01, -1.0]}))).await;
    assert_eq!(pointers(&refused), ["/vary/~1dt/1"]);
    let too_many = post_json(&app, "/sweeps", &sweep(json!({"/dt": [0.1, 0.05, 0.02, 0.01, 0.005]}))).await;
    assert_eq!(pointers(&too_many), ["/vary"]);
    assert!(too_many.problem()["detail"].as_str().unwrap().contains("5 variants"), "{}", too_many.text());
    // 1 s at dt = 0.001 is 1000 steps, over this server's 500: the value at /vary/~1dt/2 is at fault.
    let over_limit = post_json(&app, "/sweeps", &sweep(json!({"/dt": [0.01, 0.005, 0.001]}))).await;
    assert_eq!(pointers(&over_limit), ["/vary/~1dt/2"]);
    assert!(over_limit.problem()["detail"].as_str().unwrap().contains("variant 2"), "{}", over_limit.text());
    let malformed = post_json(&app, "/sweeps", "{\"scene\": ").await;
    assert_eq!(malformed.status, 400);

    assert!(job_statuses(&app).await.is_empty(), "no job was queued");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unknown_sweep_is_not_found() {
    let (_, app) = test_app(config(1, 4), ApiConfig::default());
    for path in ["/sweeps/0123456789abcdef", "/sweeps/nope", "/sweeps/0123456789abcdef/plot.svg"] {
        let answer = get(&app, path).await;
        assert_eq!(answer.status, 404, "{path}");
        assert_eq!(answer.problem()["type"], "/problems/sweep-not-found");
    }
    assert_eq!(delete(&app, "/sweeps/0123456789abcdef").await.status, 404);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deleting_a_sweep_cancels_every_run() {
    let (_, app) = test_app(config(1, 8), ApiConfig::default());
    // Long runs: one runs, the rest wait, until cancelled.
    let long = json!({
        "scene": {"duration": 500, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 10000}], "output": {"frames": "none"}},
        "vary": {"/dt": [0.001, 0.002, 0.004]},
    });
    let answer = post_json(&app, "/sweeps", &long.to_string()).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let id = answer.json()["id"].as_str().unwrap().to_string();

    let cancelled = delete(&app, &format!("/sweeps/{id}")).await;
    assert_eq!(cancelled.status, 202, "{}", cancelled.text());
    assert_eq!(cancelled.json()["id"], id.as_str());
    let sweep = until_complete(&app, &id).await;
    for row in sweep["rows"].as_array().unwrap() {
        assert_eq!(row["status"], "cancelled", "{row}");
    }
    assert_eq!(sweep["cancel_requested"], true);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idempotency_key_returns_the_same_sweep_or_refuses_a_different_document() {
    let (_, app) = test_app(config(1, 16), ApiConfig::default());
    let keyed = |body: &str| {
        Request::post("/sweeps")
            .header("content-type", "application/json")
            .header("idempotency-key", "ci-sweep-9")
            .body(Body::from(body.to_string()))
            .unwrap()
    };
    let first = send(&app, keyed(&orders_sweep())).await;
    assert_eq!(first.status, 202, "{}", first.text());
    assert_eq!(first.header("idempotent-replayed"), None);
    let id = first.json()["id"].as_str().unwrap().to_string();
    // The same document with its keys in another order and other spacing is the same sweep.
    let reordered = json!({
        "reference": {"dt": 0.00001, "integrator": "rk4"},
        "vary": {"/dt": [0.004, 0.002, 0.001], "/integrator": ["symplectic_euler", "rk4"]},
        "scene": single_spring()
    });
    let again = send(&app, keyed(&serde_json::to_string_pretty(&reordered).unwrap())).await;
    assert_eq!(again.status, 202, "{}", again.text());
    assert_eq!(again.json()["id"], id.as_str());
    assert_eq!(again.header("idempotent-replayed"), Some("true"));
    assert_eq!(again.header("location"), Some(format!("/sweeps/{id}").as_str()));
    let listed = get(&app, "/sweeps").await.json();
    assert_eq!(listed["sweeps"].as_array().unwrap().len(), 1, "{listed}");

    // Another document under the key is refused, and stores nothing.
    let other = send(&app, keyed(&orders_sweep().replace("0.004", "0.008"))).await;
    assert_eq!(other.status, 422, "{}", other.text());
    let problem = other.problem();
    assert_eq!(problem["type"], "/problems/idempotency-key-reused");
    let detail = problem["detail"].as_str().unwrap();
    assert!(detail.contains("ci-sweep-9") && detail.contains(&format!("sweep {id}")), "{detail}");
    assert_eq!(get(&app, "/sweeps").await.json()["sweeps"].as_array().unwrap().len(), 1);
    // A job's key space is its own: the same key on POST /jobs queues a job.
    let job = Request::post("/jobs")
        .header("content-type", "application/json")
        .header("idempotency-key", "ci-sweep-9")
        .body(Body::from(single_spring().to_string()))
        .unwrap();
    assert_eq!(send(&app, job).await.status, 202);

    // Once the sweep has ended, its key still finds it, with its table.
    until_complete(&app, &id).await;
    let ended = send(&app, keyed(&orders_sweep())).await;
    assert_eq!(ended.status, 202, "{}", ended.text());
    assert_eq!(ended.json()["id"], id.as_str());
    assert_eq!(ended.json()["complete"], true);
}

/// A sweep of `values` × 2 integrators of a 7-particle chain, tiny runs.
fn tiny_chains(values: usize) -> String {
    let dts: Vec<f64> = (0..values).map(|n| 0.001 + 0.000_001 * n as f64).collect();
    json!({
        "scene": {"duration": 0.1, "bodies": [{"type": "chain", "count": 7, "pin": [0]}], "error_estimate": "none"},
        "vary": {"/integrator": ["symplectic_euler", "verlet"], "/dt": dts},
    })
    .to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sweep_of_a_thousand_variants_is_one_entry_within_the_default_queue() {
    let (_, app) = test_app(JobsConfig { workers: 2, ..JobsConfig::default() }, ApiConfig::default());
    assert_eq!(JobsConfig::default().queue_capacity, 64);
    let answer = post_json(&app, "/sweeps", &tiny_chains(500)).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let id = answer.json()["id"].as_str().unwrap().to_string();
    assert_eq!(answer.json()["progress"]["runs"], 1000);
    assert!(job_statuses(&app).await.is_empty(), "the sweep's runs are not jobs");

    let listed = get(&app, "/sweeps").await.json();
    assert_eq!(listed["sweeps"][0]["id"], id.as_str());
    assert_eq!(listed["sweeps"][0]["variants"], 1000);

    let sweep = until_complete(&app, &id).await;
    assert_eq!(sweep["progress"]["finished"], 1000);
    let rows = sweep["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 1000);
    for row in rows {
        assert_eq!(row["status"], "succeeded", "{row}");
        assert_eq!(row["steps"].as_f64(), Some((0.1 / row["dt"].as_f64().unwrap()).round()), "{row}");
    }
    // The service's throughput counts the sweep's runs: 7 particles times each run's steps.
    let steps: f64 = rows.iter().map(|row| row["steps"].as_f64().unwrap()).sum();
    let metrics = get(&app, "/metrics").await.text();
    let counter = |name: &str| -> f64 {
        let line =
            metrics.lines().find(|l| l.starts_with(name)).unwrap_or_else(|| panic!("{name}: {metrics}"));
        line.rsplit(' ').next().unwrap().parse().unwrap()
    };
    assert_eq!(counter("drape_particle_steps_total"), 7.0 * steps);
    assert!(counter("drape_worker_busy_seconds_total") > 0.0, "{metrics}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn single_jobs_are_served_while_a_big_sweep_runs() {
    let (_, app) = test_app(config(1, 16), ApiConfig::default());
    // 80 runs of a 2,000-particle chain, each tens of milliseconds: seconds of work for one worker.
    let dts: Vec<f64> = (0..80).map(|n| 0.001 + 0.00001 * f64::from(n)).collect();
    let big = json!({
        "scene": {"duration": 0.5, "bodies": [{"type": "chain", "count": 2000, "mass": 200, "spring": {"k": 1000}}]},
        "vary": {"/dt": dts},
    });
    let answer = post_json(&app, "/sweeps", &big.to_string()).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let id = answer.json()["id"].as_str().unwrap().to_string();
    tokio::time::timeout(Duration::from_secs(60), async {
        while get(&app, &format!("/sweeps/{id}")).await.json()["progress"]["finished"] == 0 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("the sweep starts");

    // A job queued now is taken at the end of the worker's current batch, long before the sweep ends.
    let tiny = json!({"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3}]});
    let job = post_json(&app, "/jobs", &tiny.to_string()).await.json();
    let ended = poll_until(&app, job["id"].as_str().unwrap(), |j| j["status"] == "succeeded").await;
    assert_eq!(ended["status"], "succeeded");
    let sweep = get(&app, &format!("/sweeps/{id}")).await.json();
    let finished = sweep["progress"]["finished"].as_u64().unwrap();
    assert!(finished < 40, "the job waited for half the sweep: {finished} of 80 runs had ended");

    // Cancelled, the sweep ends; its events say so at once.
    assert_eq!(delete(&app, &format!("/sweeps/{id}")).await.status, 202);
    let cancelled = until_complete(&app, &id).await;
    let statuses: Vec<&str> =
        cancelled["rows"].as_array().unwrap().iter().map(|r| r["status"].as_str().unwrap()).collect();
    assert!(statuses.iter().all(|s| matches!(*s, "succeeded" | "cancelled")), "{statuses:?}");
    assert!(statuses.contains(&"cancelled"), "{statuses:?}");
    let events = get(&app, &format!("/sweeps/{id}/events")).await;
    assert_eq!(events.status, 200);
    let end = events.text().strip_prefix("event: end\ndata: ").expect("one end event").trim().to_string();
    assert_eq!(serde_json::from_str::<Value>(&end).unwrap()["complete"], true);
}
