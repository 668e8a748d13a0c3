//! Every job stops when asked, through the real `drape serve`: a long job is cancelled, failed
//! at its wall time, and handed back on SIGTERM within about a second, whichever of its steps
//! it is in; a job that kills the server each time it runs is failed after `--max-attempts`
//! starts, and the server stays up. That a stop reaches inside a single linear solve, however
//! long, is shown on the solver itself (`src/run/tests.rs`).

#![cfg(unix)]

mod deadline;
mod serve;

use std::time::{Duration, Instant};

use serde_json::Value;
use serve::{PATIENCE, Server, ended, job, submit, wait_for};

/// A stiff chain of 100,000 particles, the most a scene may have, whose every implicit solve
/// goes down to 10⁻¹², the finest tolerance a scene may ask for, with no stop on the reduction
/// of its starting guess's residual: each of its 200 steps sets up the preconditioner's
/// hierarchy of the whole chain and runs tens of V-cycles over it, so that the run outlasts any
/// test on any machine while no single step outlasts a stop's deadline.
const ENDLESS: &str = r#"{"duration": 1, "dt": 0.005, "integrator": "implicit_euler",
    "solver": {"tolerance": 1e-12, "reduction": 0, "max_iterations": 10000},
    "bodies": [{"type": "chain", "count": 100000, "start": [0, 0, 0], "end": [100, 0, 0], "pin": [0],
                "mass": 0.1, "spring": {"k": 100000, "damping": 0.1, "rest_length": 0.0005}}],
    "error_estimate": "none", "output": {"frames": "none"}}"#;

/// The same chain over 20 steps: long enough to be stopped in the middle on a fast machine, and
/// short enough to run to its end.
const SLOW: &str = r#"{"duration": 0.1, "dt": 0.005, "integrator": "implicit_euler",
    "solver": {"tolerance": 1e-12, "reduction": 0, "max_iterations": 10000},
    "bodies": [{"type": "chain", "count": 100000, "start": [0, 0, 0], "end": [100, 0, 0], "pin": [0],
                "mass": 0.1, "spring": {"k": 100000, "damping": 0.1, "rest_length": 0.0005}}],
    "error_estimate": "none", "output": {"frames": "final"}}"#;

const TINY: &str = r#"{"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3}],
                      "output": {"frames": "final"}}"#;

/// How long a stop may take here. The contract is one second; this leaves room for a loaded
/// two-core machine, whose time shows in the measured figure each test prints.
const STOP_DEADLINE: Duration = Duration::from_secs(5);

/// Whether the job is running (its first step may not have ended yet).
fn running(job: &Value) -> bool {
    job["status"] == "running"
}

/// Waits until the job has been running for a while.
async fn running_for_a_while(client: &reqwest::Client, base: &str, id: &str) {
    wait_for(client, base, id, running).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let job = job(client, base, id).await;
    assert_eq!(job["status"], "running", "{job}");
}

/// Polls until the job ends; returns it and how long that took from `since`.
async fn ended_after(client: &reqwest::Client, base: &str, id: &str, since: Instant) -> (Value, Duration) {
    let deadline = since + STOP_DEADLINE;
    loop {
        let job = job(client, base, id).await;
        if ended(&job) {
            return (job, since.elapsed());
        }
        assert!(Instant::now() < deadline, "job {id} did not end within {STOP_DEADLINE:?}: {job}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_stops_a_long_job_within_a_second() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &["--workers", "1"]);
    let client = reqwest::Client::new();
    let id = submit(&client, &server.base, ENDLESS).await;
    running_for_a_while(&client, &server.base, &id).await;
    let asked = Instant::now();
    let response = client.delete(format!("{}/jobs/{id}", server.base)).send().await.unwrap();
    assert_eq!(response.status(), 202);
    let (job, took) = ended_after(&client, &server.base, &id, asked).await;
    eprintln!("cancelled {took:?} after DELETE");
    assert_eq!(
        (job["status"].as_str(), job["message"].as_str()),
        (Some("cancelled"), Some("cancelled by request"))
    );
    // The worker is free again.
    let next = submit(&client, &server.base, TINY).await;
    assert_eq!(wait_for(&client, &server.base, &next, ended).await["status"], "succeeded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_wall_time_fails_a_long_job_where_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &["--workers", "1", "--job-wall-time", "1"]);
    let client = reqwest::Client::new();
    let id = submit(&client, &server.base, ENDLESS).await;
    wait_for(&client, &server.base, &id, running).await;
    let seen_running = Instant::now();
    let (job, took) = ended_after(&client, &server.base, &id, seen_running).await;
    eprintln!("ended {took:?} after it was seen running, with a wall time of 1 s");
    assert_eq!(
        (job["status"].as_str(), job["failure"].as_str()),
        (Some("failed"), Some("wall_time")),
        "{job}"
    );
    let steps = job["message"]
        .as_str()
        .and_then(|m| m.strip_prefix("the job exceeded the wall-time limit of 1 s after "))
        .and_then(|m| m.strip_suffix(" of 200 steps"))
        .and_then(|steps| steps.parse::<u64>().ok());
    assert!(steps.is_some_and(|steps| steps < 200), "stopped part way: {job}");
    let next = submit(&client, &server.base, TINY).await;
    assert_eq!(wait_for(&client, &server.base, &next, ended).await["status"], "succeeded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_hands_a_running_job_back_and_the_next_start_runs_it_to_its_end() {
    let dir = tempfile::tempdir().unwrap();
    let store = "sqlite://jobs.db";
    let client = reqwest::Client::new();
    let first = Server::start(dir.path(), store, &["--workers", "1", "--shutdown-grace", "1"]);
    let slow = submit(&client, &first.base, SLOW).await;
    running_for_a_while(&client, &first.base, &slow).await;
    let took = first.terminate_within(Duration::from_secs(1) + STOP_DEADLINE);
    eprintln!("exited {took:?} after SIGTERM with a grace of 1 s");

    let second = Server::start(dir.path(), store, &["--workers", "1"]);
    let job = wait_for(&client, &second.base, &slow, ended).await;
    assert_eq!(
        (job["status"].as_str(), job["progress"]["step"].as_u64(), job["attempts"].as_u64()),
        (Some("succeeded"), Some(20), Some(1)),
        "run again from the start; a shutdown's hand-back is not an attempt: {job}"
    );
    assert_eq!(second.starts(), [slow]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_that_kills_the_server_three_times_is_failed_on_the_fourth_start() {
    let dir = tempfile::tempdir().unwrap();
    let store = "sqlite://jobs.db";
    let client = reqwest::Client::new();
    let first = Server::start(dir.path(), store, &["--workers", "1"]);
    let poison = submit(&client, &first.base, SLOW).await;
    let mut server = first;
    for attempt in 1..=3u64 {
        running_for_a_while(&client, &server.base, &poison).await;
        assert_eq!(job(&client, &server.base, &poison).await["attempts"], attempt);
        server.kill();
        server = Server::start(dir.path(), store, &["--workers", "1"]);
    }
    let job = wait_for(&client, &server.base, &poison, ended).await;
    assert_eq!(
        (job["status"].as_str(), job["failure"].as_str(), job["attempts"].as_u64()),
        (Some("failed"), Some("attempts"), Some(3)),
        "{job}"
    );
    assert_eq!(
        job["message"],
        "the job was started 3 times without ending (--max-attempts 3): it may crash the server"
    );
    assert!(server.starts().is_empty(), "the fourth server never started it");
    let health = client.get(format!("{}/healthz", server.base)).send().await.unwrap();
    assert_eq!(health.status(), 200);
    let next = submit(&client, &server.base, TINY).await;
    let next = tokio::time::timeout(PATIENCE, wait_for(&client, &server.base, &next, ended)).await.unwrap();
    assert_eq!(next["status"], "succeeded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_calls_that_time_out_inside_long_runs_free_their_workers() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &["--workers", "2", "--request-timeout", "1"]);
    let client = reqwest::Client::new();
    let simulate = |scene: &'static str| {
        client
            .post(format!("{}/simulate", server.base))
            .header("content-type", "application/json")
            .body(scene)
            .send()
    };
    let (one, two) = tokio::join!(simulate(ENDLESS), simulate(ENDLESS));
    assert_eq!((one.unwrap().status().as_u16(), two.unwrap().status().as_u16()), (408, 408));
    let timed_out = Instant::now();
    // Both workers are free again within the stop deadline: two more runs go through at once.
    let (one, two) = tokio::join!(simulate(TINY), simulate(TINY));
    let took = timed_out.elapsed();
    eprintln!("two more /simulate answered {took:?} after the first two timed out");
    assert_eq!((one.unwrap().status().as_u16(), two.unwrap().status().as_u16()), (200, 200));
    assert!(took < STOP_DEADLINE, "{took:?}");
}
