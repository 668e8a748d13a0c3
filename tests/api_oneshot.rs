//! Every endpoint through `app().oneshot(...)`, without a socket.

mod common;
mod deadline;

use std::sync::Arc;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::ApiConfig;
use drape::jobs::JobsConfig;
use drape::output::Format;
use drape::scene::Field;
use serde_json::Value;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_returns_the_same_result_as_a_direct_run() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let answer = post_json(&app, "/simulate", TINY).await;
    assert_eq!(answer.status, 200, "{}", answer.text());
    assert_eq!(answer.header("content-type"), Some("application/json"));
    let id = answer.header("drape-job-id").unwrap().to_string();
    assert_eq!(answer.header("content-location"), Some(format!("/jobs/{id}").as_str()));

    let scene = drape::scene::Scene::from_json(TINY.as_bytes()).unwrap();
    let direct = drape::run::execute(&scene.compile(), &drape::run::Control::new());
    let mut expected = Vec::new();
    drape::output::write_json(&direct, &mut expected).unwrap();
    let (mut got, mut want): (Value, Value) = (answer.json(), serde_json::from_slice(&expected).unwrap());
    // Everything but the measured wall times is identical: runs are deterministic.
    for v in [&mut got, &mut want] {
        v["stats"]["wall_time_s"] = Value::Null;
        v["stats"]["error"]["extra_wall_time_s"] = Value::Null;
    }
    assert_eq!(got, want);
    assert_eq!(got["final"]["positions"].as_array().unwrap().len(), 9);

    let job = get(&app, &format!("/jobs/{id}")).await.json();
    assert_eq!(job["status"], "succeeded");
    assert_eq!(job["progress"]["step"], 10);
    assert_eq!(job["progress"]["fraction"], 1.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_diverged_run_is_a_successful_answer_about_the_scene() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    // Explicit Euler at 100 times the stable step of a stiff, moving chain blows up.
    let scene = r#"{"duration": 2, "dt": 0.05, "integrator": "explicit_euler", "gravity": [0, 0, 0],
                    "bodies": [{"type": "chain", "count": 4, "spring": {"k": 100000},
                                "velocity": [0, 1, 0], "pin": [0]}],
                    "output": {"frames": "none"}}"#;
    let answer = post_json(&app, "/simulate", scene).await;
    assert_eq!(answer.status, 200, "{}", answer.text());
    assert_eq!(answer.header("drape-job-status"), Some("diverged"));
    let result = answer.json();
    assert_eq!(result["stats"]["status"], "diverged");
    assert!(result["stats"]["diverged"]["step"].as_u64().is_some());
    let id = answer.header("drape-job-id").unwrap();
    let job = get(&app, &format!("/jobs/{id}")).await.json();
    assert_eq!(job["status"], "diverged");
    assert_eq!(job["message"], result["stats"]["diverged"]["reason"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_refuses_runs_over_its_budget_and_points_to_jobs() {
    let api = ApiConfig { simulate_work_budget: 149, ..ApiConfig::default() };
    let (_, app) = test_app(jobs_config(), api);
    // TINY is 3 particles and 2 springs × (10 steps + 20 of its error estimate's companion, at
    // half the step because twice the step would pass the stability bound) = 150 element-steps,
    // 50 of them the bodies' own.
    let answer = post_json(&app, "/simulate", TINY).await;
    assert_eq!(answer.status, 413);
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/over-simulate-budget");
    let detail = problem["detail"].as_str().unwrap();
    assert!(detail.contains("150 element-steps") && detail.contains("POST /jobs"), "{detail}");
    assert_eq!(problem["errors"][0]["pointer"], "/error_estimate");
    assert_eq!(problem["errors"][0]["detail"], "error_estimate costs 100 of the run's 150 element-steps");
    // The same scene is welcome as a job.
    assert_eq!(post_json(&app, "/jobs", TINY).await.status, 202);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_are_queued_listed_looked_up_and_their_results_served() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let answer = post_json(&app, "/jobs", TINY).await;
    assert_eq!(answer.status, 202);
    let job = answer.json();
    let id = job["id"].as_str().unwrap().to_string();
    assert_eq!(answer.header("location"), Some(format!("/jobs/{id}").as_str()));
    assert_eq!(job["links"]["result"], format!("/jobs/{id}/result"));
    assert_eq!((job["particles"].as_u64(), job["springs"].as_u64()), (Some(3), Some(2)));
    assert_eq!(job["progress"]["steps"], 10);
    assert_eq!(job["attempts"], 0, "not started yet");

    let ended = poll_until(&app, &id, is_final).await;
    assert_eq!(ended["status"], "succeeded");
    assert_eq!(ended["attempts"], 1);
    assert_eq!(ended["stats"]["steps"], 10);
    assert!(ended["finished_at"].as_str().unwrap().ends_with('Z'));

    let result = get(&app, &format!("/jobs/{id}/result")).await;
    assert_eq!(result.status, 200);
    assert_eq!(result.json()["stats"], ended["stats"]);

    let second = post_json(&app, "/jobs", TINY).await.json();
    poll_until(&app, second["id"].as_str().unwrap(), is_final).await;
    let list = get(&app, "/jobs?limit=1").await.json();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 1);
    assert_eq!(list["jobs"][0]["id"], second["id"], "newest first");
    assert_eq!(list["next"], "/jobs?offset=1&limit=1");
    let page2 = get(&app, "/jobs?offset=1&limit=1").await.json();
    assert_eq!(page2["jobs"][0]["id"], id);
    let all = get(&app, "/jobs").await.json();
    assert_eq!(all["jobs"].as_array().unwrap().len(), 2);
    assert_eq!(all["next"], Value::Null);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idempotency_keys_return_the_same_job_or_refuse_a_different_body() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let keyed = |body: &str| {
        Request::post("/jobs")
            .header("content-type", "application/json")
            .header("idempotency-key", "order-42")
            .body(Body::from(body.to_string()))
            .unwrap()
    };
    let first = send(&app, keyed(TINY)).await;
    assert_eq!(first.status, 202);
    // The same scene with other spacing is the same body.
    let again = send(&app, keyed(&TINY.replace(' ', ""))).await;
    assert_eq!(again.status, 202);
    assert_eq!(again.json()["id"], first.json()["id"]);
    assert_eq!(again.header("idempotent-replayed"), Some("true"));
    assert_eq!(get(&app, "/jobs").await.json()["jobs"].as_array().unwrap().len(), 1);

    let other = send(&app, keyed(&TINY.replace("0.1", "0.2"))).await;
    assert_eq!(other.status, 422);
    let problem = other.problem();
    assert_eq!(problem["type"], "/problems/idempotency-key-reused");
    assert!(problem["detail"].as_str().unwrap().contains("order-42"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancelling_drops_a_queued_job_stops_a_running_one_and_refuses_an_ended_one() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let running = post_json(&app, "/jobs", LONG).await.json()["id"].as_str().unwrap().to_string();
    poll_until(&app, &running, |j| j["status"] == "running").await;
    let queued = post_json(&app, "/jobs", TINY).await.json()["id"].as_str().unwrap().to_string();

    let dropped = delete(&app, &format!("/jobs/{queued}")).await;
    assert_eq!(dropped.status, 200);
    assert_eq!(dropped.json()["status"], "cancelled");
    let no_result = get(&app, &format!("/jobs/{queued}/result")).await;
    assert_eq!(no_result.status, 409);
    assert_eq!(no_result.problem()["type"], "/problems/no-result");

    let running_result = get(&app, &format!("/jobs/{running}/result")).await;
    assert_eq!(running_result.status, 409, "no result while running");

    let stopping = delete(&app, &format!("/jobs/{running}")).await;
    assert_eq!(stopping.status, 202);
    let ended = poll_until(&app, &running, is_final).await;
    assert_eq!(ended["status"], "cancelled");
    assert_eq!(ended["message"], "cancelled by request");
    let steps = ended["progress"]["step"].as_u64().unwrap();
    assert!(steps < 1_000_000, "stopped early, at step {steps}");
    // The partial result is kept and ends where the run stopped.
    let partial = get(&app, &format!("/jobs/{running}/result")).await;
    assert_eq!(partial.status, 200);
    assert_eq!(partial.json()["stats"]["status"], "cancelled");
    assert_eq!(partial.json()["stats"]["steps"], steps);

    let again = delete(&app, &format!("/jobs/{running}")).await;
    assert_eq!(again.status, 409);
    assert_eq!(again.problem()["type"], "/problems/already-ended");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_over_its_wall_time_fails_with_a_message() {
    let jobs = JobsConfig { wall_time: std::time::Duration::from_millis(50), ..jobs_config() };
    let (_, app) = test_app(jobs, ApiConfig::default());
    let id = post_json(&app, "/jobs", LONG).await.json()["id"].as_str().unwrap().to_string();
    let ended = poll_until(&app, &id, is_final).await;
    assert_eq!(ended["status"], "failed");
    assert_eq!(ended["failure"], "wall_time");
    let message = ended["message"].as_str().unwrap();
    assert!(message.contains("wall-time limit of 0.05 s"), "{message}");
    assert_eq!(get(&app, &format!("/jobs/{id}/result")).await.status, 409);
    // Through /simulate, the answer is about the scene: a 422 that says why.
    let api = ApiConfig { simulate_work_budget: u64::MAX, ..ApiConfig::default() };
    let jobs = JobsConfig { wall_time: std::time::Duration::from_millis(50), ..jobs_config() };
    let (_, app) = test_app(jobs, api);
    let answer = post_json(&app, "/simulate", LONG).await;
    assert_eq!(answer.status, 422);
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/wall-time-exceeded");
    assert!(problem["detail"].as_str().unwrap().contains("wall-time limit of 0.05 s"), "{problem}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_job_fails_alone() {
    let jobs = JobsConfig {
        before_run: Some(Arc::new(|c: &drape::scene::Compiled| {
            if c.duration == 0.25 {
                panic!("injected failure");
            }
        })),
        ..jobs_config()
    };
    let (_, app) = test_app(jobs, ApiConfig::default());
    let doomed = post_json(&app, "/jobs", &TINY.replace("0.1", "0.25")).await.json();
    let fine = post_json(&app, "/jobs", TINY).await.json();
    let doomed = poll_until(&app, doomed["id"].as_str().unwrap(), is_final).await;
    let fine = poll_until(&app, fine["id"].as_str().unwrap(), is_final).await;
    assert_eq!(doomed["status"], "failed");
    assert_eq!(doomed["message"], "the simulation panicked: injected failure");
    assert_eq!(doomed["failure"], "panicked");
    assert_eq!(fine["status"], "succeeded");
    assert_eq!(get(&app, "/healthz").await.status, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_queue_answers_429_with_retry_after() {
    let jobs = JobsConfig { queue_capacity: 1, ..jobs_config() };
    let (_, app) = test_app(jobs, ApiConfig::default());
    let running = post_json(&app, "/jobs", LONG).await.json()["id"].as_str().unwrap().to_string();
    poll_until(&app, &running, |j| j["status"] == "running").await;
    let waiting = post_json(&app, "/jobs", TINY).await;
    assert_eq!(waiting.status, 202);
    for path in ["/jobs", "/simulate"] {
        let refused = post_json(&app, path, TINY).await;
        assert_eq!(refused.status, 429, "{path}");
        assert_eq!(refused.header("retry-after"), Some("1"));
        assert_eq!(refused.problem()["type"], "/problems/queue-full");
    }
    delete(&app, &format!("/jobs/{running}")).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn events_of_an_ended_job_are_one_end_event() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let id = post_json(&app, "/jobs", TINY).await.json()["id"].as_str().unwrap().to_string();
    poll_until(&app, &id, is_final).await;
    let answer = get(&app, &format!("/jobs/{id}/events")).await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.header("content-type"), Some("text/event-stream"));
    let text = answer.text();
    let events: Vec<&str> = text.split("\n\n").filter(|e| !e.trim().is_empty()).collect();
    assert_eq!(events.len(), 1, "{text}");
    assert!(events[0].starts_with("event: end\ndata: "), "{text}");
    let job: Value = serde_json::from_str(events[0].trim_start_matches("event: end\ndata: ")).unwrap();
    assert_eq!(job["status"], "succeeded");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_metrics_and_openapi_answer() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    assert_eq!(get(&app, "/healthz").await.json(), serde_json::json!({"status": "ok"}));
    let id = post_json(&app, "/jobs", TINY).await.json()["id"].as_str().unwrap().to_string();
    poll_until(&app, &id, is_final).await;
    let metrics = get(&app, "/metrics").await;
    assert_eq!(metrics.status, 200);
    assert!(metrics.header("content-type").unwrap().starts_with("text/plain; version=0.0.4"));
    let text = metrics.text();
    for line in [
        "drape_jobs{status=\"succeeded\"} 1",
        "drape_jobs{status=\"running\"} 0",
        "drape_queue_length 0",
        "drape_running_jobs 0",
        "drape_particle_steps_total 90",
        "drape_http_request_duration_seconds_bucket{le=\"+Inf\"}",
        "drape_http_requests_total{code=\"2xx\"}",
    ] {
        assert!(text.contains(line), "missing {line} in\n{text}");
    }
    assert!(text.lines().filter(|l| !l.starts_with('#')).all(|l| l.starts_with("drape_")));
    assert_eq!(get(&app, "/openapi.json").await.json()["openapi"], "3.1.0");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn large_responses_are_gzipped_when_asked_and_cors_answers_preflight() {
    let api = ApiConfig { cors_origins: vec!["https://app.example".into()], ..ApiConfig::default() };
    let (_, app) = test_app(jobs_config(), api);
    let request =
        Request::get("/openapi.json").header("accept-encoding", "gzip").body(Body::empty()).unwrap();
    let answer = send(&app, request).await;
    assert_eq!(answer.header("content-encoding"), Some("gzip"));
    assert_eq!(&answer.body[..2], [0x1f, 0x8b], "gzip magic");
    let small =
        send(&app, Request::get("/healthz").header("accept-encoding", "gzip").body(Body::empty()).unwrap())
            .await;
    assert_eq!(small.header("content-encoding"), None, "small bodies are sent as they are");

    let preflight = Request::options("/jobs")
        .header("origin", "https://app.example")
        .header("access-control-request-method", "POST")
        .header("access-control-request-headers", "content-type,idempotency-key")
        .body(Body::empty())
        .unwrap();
    let answer = send(&app, preflight).await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.header("access-control-allow-origin"), Some("https://app.example"));
    let stranger =
        Request::get("/healthz").header("origin", "https://evil.example").body(Body::empty()).unwrap();
    assert_eq!(send(&app, stranger).await.header("access-control-allow-origin"), None);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn timeouts_and_overload_are_problems() {
    let api = ApiConfig {
        request_timeout: std::time::Duration::from_millis(20),
        simulate_work_budget: u64::MAX,
        ..ApiConfig::default()
    };
    let (jobs, app) = test_app(jobs_config(), api);
    let answer = post_json(&app, "/simulate", LONG).await;
    assert_eq!(answer.status, 408);
    assert_eq!(answer.problem()["type"], "/problems/timeout");
    // The abandoned /simulate job is cancelled.
    let id = get(&app, "/jobs").await.json()["jobs"][0]["id"].as_str().unwrap().to_string();
    assert_eq!(poll_until(&app, &id, is_final).await["status"], "cancelled");
    jobs.shutdown(std::time::Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_over_the_concurrency_limit_are_shed_with_503() {
    let api =
        ApiConfig { max_concurrent_requests: 1, simulate_work_budget: u64::MAX, ..ApiConfig::default() };
    let (jobs, app) = test_app(jobs_config(), api);
    let waiting = tokio::spawn({
        let app = app.clone();
        async move { post_json(&app, "/simulate", LONG).await }
    });
    // The /simulate request holds the only permit while its job runs.
    common::until_running(&jobs).await;
    let shed = get(&app, "/healthz").await;
    assert_eq!(shed.status, 503);
    assert_eq!(shed.problem()["type"], "/problems/overloaded");

    let page = drape::jobs::Page { offset: 0, limit: 1 };
    let id = jobs.list(page).await.unwrap()[0].id.clone();
    jobs.cancel(&id).await.unwrap();
    let cancelled = waiting.await.unwrap();
    assert_eq!(cancelled.status, 409);
    assert_eq!(cancelled.problem()["type"], "/problems/job-cancelled");
    assert_eq!(get(&app, "/healthz").await.status, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn results_are_served_in_the_scenes_format() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let scene = TINY.replace(r#""frames": "final""#, r#""frames": "all", "format": "pc2""#);
    let id = post_json(&app, "/jobs", &scene).await.json()["id"].as_str().unwrap().to_string();
    assert_eq!(poll_until(&app, &id, is_final).await["status"], "succeeded");
    let result = get(&app, &format!("/jobs/{id}/result")).await;
    assert_eq!(result.status, 200);
    assert_eq!(result.header("content-type"), Some("application/x-pc2"));
    // PC2: a 32-byte header (magic, version, points, start, sample rate, samples), then
    // samples × points × 3 little-endian f32.
    assert_eq!(&result.body[..12], b"POINTCACHE2\0");
    let points = u32::from_le_bytes(result.body[16..20].try_into().unwrap()) as usize;
    let samples = u32::from_le_bytes(result.body[28..32].try_into().unwrap()) as usize;
    assert_eq!(points, 3);
    assert_eq!(result.body.len(), 32 + samples * points * 12);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_result_format_is_chosen_by_query_or_accept_and_stored_once() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let with_accept = |path: &str, accept: &str| {
        Request::post(path)
            .header("content-type", "application/json")
            .header("accept", accept)
            .body(Body::from(TINY.replace("final", "all")))
            .unwrap()
    };
    let pc2 = send(&app, with_accept("/simulate", "application/x-pc2")).await;
    assert_eq!(pc2.status, 200, "{}", pc2.text());
    assert_eq!(pc2.header("content-type"), Some("application/x-pc2"));
    assert_eq!(&pc2.body[..12], b"POINTCACHE2\0");
    let glb = post_json(&app, "/simulate?format=glb", &TINY.replace("final", "all")).await;
    assert_eq!(glb.header("content-type"), Some("model/gltf-binary"));
    assert_eq!(&glb.body[..4], b"glTF");
    let browser = send(&app, with_accept("/simulate", "text/html, */*;q=0.8")).await;
    assert_eq!(browser.header("content-type"), Some("application/json"), "*/* leaves the scene's format");

    let job = post_json(&app, "/jobs?format=pc2", &TINY.replace("final", "all")).await.json();
    let id = job["id"].as_str().unwrap().to_string();
    poll_until(&app, &id, is_final).await;
    let path = format!("/jobs/{id}/result");
    assert_eq!(get(&app, &path).await.header("content-type"), Some("application/x-pc2"));
    assert_eq!(get(&app, &format!("{path}?format=pc2")).await.status, 200);
    let refused =
        send(&app, Request::get(&path).header("accept", "application/json").body(Body::empty()).unwrap())
            .await;
    assert_eq!(refused.status, 406);
    let detail = refused.problem()["detail"].as_str().unwrap().to_string();
    assert!(detail.contains("stored as application/x-pc2") && detail.contains("?format=json"), "{detail}");

    // The format is part of the idempotent request.
    let keyed = |path: &str| {
        Request::post(path)
            .header("content-type", "application/json")
            .header("idempotency-key", "fmt")
            .body(Body::from(TINY))
            .unwrap()
    };
    assert_eq!(send(&app, keyed("/jobs?format=json")).await.status, 202);
    assert_eq!(send(&app, keyed("/jobs?format=npz")).await.status, 422);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_json_result_is_served_in_any_format_that_can_carry_it() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let submit = |fields: &'static str| {
        let app = app.clone();
        async move {
            let scene =
                TINY.replace(r#""frames": "final""#, &format!(r#""frames": "all", "fields": {fields}"#));
            let id = post_json(&app, "/jobs", &scene).await.json()["id"].as_str().unwrap().to_string();
            assert_eq!(poll_until(&app, &id, is_final).await["status"], "succeeded");
            format!("/jobs/{id}/result")
        }
    };
    let path = submit(r#"["positions"]"#).await;
    let json = get(&app, &path).await;
    assert_eq!(json.header("content-type"), Some("application/json"));
    let frames = json.json()["frames"].as_array().unwrap().clone();

    // PC2 carries the positions of every frame, as f32, in frame order.
    let pc2 = get(&app, &format!("{path}?format=pc2")).await;
    assert_eq!((pc2.status, pc2.header("content-type")), (200, Some("application/x-pc2")));
    let values: Vec<f32> =
        pc2.body[32..].chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
    let expected: Vec<f32> = frames
        .iter()
        .flat_map(|f| f["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32))
        .collect();
    assert_eq!(values, expected);
    let glb =
        send(&app, Request::get(&path).header("accept", "model/gltf-binary").body(Body::empty()).unwrap())
            .await;
    assert_eq!((glb.status, glb.header("content-type")), (200, Some("model/gltf-binary")));
    assert_eq!(&glb.body[..4], b"glTF");
    let npy = get(&app, &format!("{path}?format=npy")).await;
    assert_eq!((npy.status, npy.header("content-type")), (200, Some("application/x-npy")));
    assert_eq!(&npy.body[..6], b"\x93NUMPY");

    // With velocities too, NPY becomes NPZ (a zip of one array per field), and OBJ, which holds
    // positions and normals only, leaves the velocities out and says so.
    let path = submit(r#"["positions", "velocities"]"#).await;
    let npz = get(&app, &format!("{path}?format=npy")).await;
    assert_eq!((npz.status, npz.header("content-type")), (200, Some("application/x-npz")));
    assert_eq!(&npz.body[..2], b"PK");
    assert_eq!(npz.header("drape-omitted-fields"), None);
    let obj = get(&app, &format!("{path}?format=obj")).await;
    assert_eq!((obj.status, obj.header("content-type")), (200, Some("model/obj")), "{}", obj.text());
    assert_eq!(obj.header("drape-omitted-fields"), Some("velocities"));
    // Without positions, a mesh format has nothing to show: still a 422, at the scene's field.
    let path = submit(r#"["energy"]"#).await;
    let glb = get(&app, &format!("{path}?format=glb")).await;
    assert_eq!(glb.status, 422, "{}", glb.text());
    assert_eq!(glb.problem()["type"], "/problems/format-cannot-carry");
    assert_eq!(glb.problem()["errors"][0]["pointer"], "/output/fields");
}

/// Submits `scene` to `POST /jobs`, waits for it to succeed, and gives its result's path and
/// the recording read back from its JSON result.
async fn stored_result(app: &axum::Router, scene: &str) -> (String, drape::run::Recording) {
    let id = post_json(app, "/jobs", scene).await.json()["id"].as_str().unwrap().to_string();
    assert_eq!(poll_until(app, &id, is_final).await["status"], "succeeded");
    let path = format!("/jobs/{id}/result");
    let json = get(app, &path).await;
    assert_eq!(json.header("content-type"), Some("application/json"));
    (path, drape::output::read_json(&json.body).unwrap())
}

/// `fields` of `recording` encoded as `format`, as the library encodes them.
fn encoded(recording: &drape::run::Recording, fields: &[drape::scene::Field], format: Format) -> Vec<u8> {
    let mut bytes = Vec::new();
    drape::output::encode_fields(recording, fields, format, &mut bytes).unwrap();
    bytes
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_examples_result_is_served_in_any_format_naming_the_fields_it_leaves_out() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    // The README's example records energy, which no mesh format carries.
    let scene =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/hanging_cloth.json")).unwrap();
    let (path, recording) = stored_result(&app, &scene).await;
    assert!(recording.frames.energy.is_some());
    let positions = [Field::Positions];
    let cases = [
        ("glb", "model/gltf-binary", Some("energy"), Format::Glb, &positions[..]),
        ("obj", "model/obj", Some("energy"), Format::Obj, &positions[..]),
        ("pc2", "application/x-pc2", Some("energy"), Format::Pc2, &positions[..]),
        // NPY with more than positions is sent as NPZ, which carries them all.
        ("npy", "application/x-npz", None, Format::Npz, &[Field::Positions, Field::Energy][..]),
    ];
    for (name, media_type, omitted, format, fields) in cases {
        let answer = get(&app, &format!("{path}?format={name}")).await;
        assert_eq!(
            (answer.status, answer.header("content-type")),
            (200, Some(media_type)),
            "{name}: {}",
            answer.text()
        );
        assert_eq!(answer.header("drape-omitted-fields"), omitted, "{name}");
        assert!(answer.body == encoded(&recording, fields, format), "{name}: not the encoding of {fields:?}");
        // Content negotiation gets the same.
        let accept = Request::get(&path).header("accept", format.media_type()).body(Body::empty()).unwrap();
        let negotiated = send(&app, accept).await;
        assert_eq!((negotiated.status, negotiated.header("drape-omitted-fields")), (200, omitted), "{name}");
        assert_eq!(negotiated.body, answer.body, "{name}");
    }

    // Several fields left out are all named, in contract order.
    let every = TINY.replace(
        r#""frames": "final""#,
        r#""frames": "all", "fields": ["strain", "positions", "energy", "velocities"]"#,
    );
    let (path, recording) = stored_result(&app, &every).await;
    let pc2 = get(&app, &format!("{path}?format=pc2")).await;
    assert_eq!(pc2.status, 200, "{}", pc2.text());
    assert_eq!(pc2.header("drape-omitted-fields"), Some("velocities, energy, strain"));
    assert!(pc2.body == encoded(&recording, &positions, Format::Pc2));
    // Formats that carry everything leave nothing out.
    for name in ["json", "npz"] {
        let answer = get(&app, &format!("{path}?format={name}")).await;
        assert_eq!((answer.status, answer.header("drape-omitted-fields")), (200, None), "{name}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fields_select_what_a_result_holds_and_each_must_be_recorded_and_carried() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let scene = TINY.replace(
        r#""frames": "final""#,
        r#""frames": "all", "fields": ["positions", "velocities", "energy"]"#,
    );
    let (path, recording) = stored_result(&app, &scene).await;

    // In the stored format (JSON) and in another; the order named does not matter.
    let json = get(&app, &format!("{path}?fields=energy,positions")).await;
    assert_eq!(
        (json.status, json.header("content-type")),
        (200, Some("application/json")),
        "{}",
        json.text()
    );
    assert_eq!(json.header("drape-omitted-fields"), None);
    assert!(json.body == encoded(&recording, &[Field::Positions, Field::Energy], Format::Json));
    let frame = &json.json()["frames"][0];
    assert!(frame.get("velocities").is_none() && frame.get("energy").is_some(), "{frame}");
    let npy = get(&app, &format!("{path}?format=npy&fields=positions")).await;
    assert_eq!((npy.status, npy.header("content-type")), (200, Some("application/x-npy")), "{}", npy.text());
    assert!(npy.body == encoded(&recording, &[Field::Positions], Format::Npy));
    let npz = get(&app, &format!("{path}?format=npz&fields=velocities")).await;
    assert_eq!((npz.status, npz.header("content-type")), (200, Some("application/x-npz")), "{}", npz.text());
    assert!(npz.body == encoded(&recording, &[Field::Velocities], Format::Npz));

    // A field the run did not record.
    let unrecorded = get(&app, &format!("{path}?fields=positions,normals")).await;
    assert_eq!(unrecorded.status, 422, "{}", unrecorded.text());
    let problem = unrecorded.problem();
    assert_eq!(problem["type"], "/problems/field-not-recorded");
    assert_eq!(problem["errors"][0]["pointer"], "/fields");
    assert!(problem["detail"].as_str().unwrap().contains("normals"), "{problem}");
    // A field asked for by name that the format cannot carry is refused, not left out.
    let uncarried = get(&app, &format!("{path}?fields=positions,energy&format=glb")).await;
    assert_eq!(uncarried.status, 422, "{}", uncarried.text());
    let problem = uncarried.problem();
    assert_eq!(problem["type"], "/problems/format-cannot-carry");
    assert_eq!(problem["errors"][0]["pointer"], "/fields");
    assert!(problem["detail"].as_str().unwrap().contains("energy"), "{problem}");
    // A mesh format still needs positions among them.
    let no_positions = get(&app, &format!("{path}?fields=velocities&format=pc2")).await;
    assert_eq!(no_positions.status, 422, "{}", no_positions.text());
    assert_eq!(no_positions.problem()["errors"][0]["pointer"], "/fields");
    // Names that are not fields are a malformed request.
    for bad in ["positions,bogus", "", "positions,%20energy", "positions,"] {
        let answer = get(&app, &format!("{path}?fields={bad}")).await;
        assert_eq!(answer.status, 400, "{bad}: {}", answer.text());
        assert_eq!(answer.problem()["errors"][0]["pointer"], "/fields", "{bad}");
    }

    // A result stored in a binary format is served only as stored.
    let job = post_json(&app, "/jobs?format=pc2", &TINY.replace("final", "all")).await.json();
    let id = job["id"].as_str().unwrap().to_string();
    poll_until(&app, &id, is_final).await;
    let selected = get(&app, &format!("/jobs/{id}/result?fields=positions")).await;
    assert_eq!(selected.status, 406, "{}", selected.text());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_sends_what_the_format_carries_and_names_the_rest() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let scene = TINY
        .replace(r#""frames": "final""#, r#""frames": "all", "fields": ["positions", "energy", "strain"]"#);
    let direct = {
        let scene = drape::scene::Scene::from_json(scene.as_bytes()).unwrap();
        drape::run::execute(&scene.compile(), &drape::run::Control::new())
    };
    let pc2 = post_json(&app, "/simulate?format=pc2", &scene).await;
    assert_eq!((pc2.status, pc2.header("content-type")), (200, Some("application/x-pc2")), "{}", pc2.text());
    assert_eq!(pc2.header("drape-omitted-fields"), Some("energy, strain"));
    assert!(pc2.body == encoded(&direct, &[Field::Positions], Format::Pc2));
    let with_accept = |path: &str, accept: &str| {
        Request::post(path)
            .header("content-type", "application/json")
            .header("accept", accept)
            .body(Body::from(scene.clone()))
            .unwrap()
    };
    let glb = send(&app, with_accept("/simulate", "model/gltf-binary")).await;
    assert_eq!((glb.status, glb.header("content-type")), (200, Some("model/gltf-binary")), "{}", glb.text());
    assert_eq!(glb.header("drape-omitted-fields"), Some("energy, strain"));
    assert!(glb.body == encoded(&direct, &[Field::Positions], Format::Glb));
    // The job it ran recorded what was sent: its stored result is that.
    let id = glb.header("drape-job-id").unwrap().to_string();
    let stored = get(&app, &format!("/jobs/{id}/result")).await;
    assert_eq!(
        (stored.header("content-type"), stored.header("drape-omitted-fields")),
        (Some("model/gltf-binary"), None)
    );
    assert_eq!(stored.body, glb.body);

    let selected = post_json(&app, "/simulate?fields=strain", &scene).await;
    assert_eq!(selected.status, 200, "{}", selected.text());
    let frame = &selected.json()["frames"][0];
    assert!(frame.get("positions").is_none() && frame.get("strain").is_some(), "{frame}");
    for (query, status, kind) in [
        ("fields=normals", 422, "/problems/field-not-recorded"),
        ("fields=energy&format=glb", 422, "/problems/format-cannot-carry"),
        ("fields=strain&format=obj", 422, "/problems/format-cannot-carry"),
        ("fields=wind", 400, "/problems/bad-request"),
    ] {
        let answer = post_json(&app, &format!("/simulate?{query}"), &scene).await;
        assert_eq!(answer.status, status, "{query}: {}", answer.text());
        let problem = answer.problem();
        assert_eq!(
            (problem["type"].as_str(), problem["errors"][0]["pointer"].as_str()),
            (Some(kind), Some("/fields")),
            "{query}"
        );
    }
    // A scene whose own format cannot carry its fields contradicts itself: still invalid.
    let contradictory = scene.replace(r#""frames": "all""#, r#""frames": "all", "format": "glb""#);
    let answer = post_json(&app, "/simulate", &contradictory).await;
    assert_eq!(answer.status, 422, "{}", answer.text());
    assert_eq!(answer.problem()["errors"][0]["pointer"], "/output/fields/1");
}

/// The 629-byte scene of the issue: every pair of a 300² cloth's particles a self-collision
/// candidate.
const THICK_CLOTH: &str = r#"{"duration":0.01,"dt":0.005,"integrator":"symplectic_euler","error_estimate":"none","self_collision":{"thickness":10},"bodies":[{"type":"cloth","resolution":[300,300],"size":[1,1]}],"output":{"frames":"final"}}"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_cost_is_refused_before_work_starts_at_the_field_that_makes_it() {
    let (jobs, app) = test_app(jobs_config(), ApiConfig::default());
    let chain = r#""bodies": [{"type": "chain"}]"#;
    let cases = [
        (THICK_CLOTH.to_string(), "/self_collision/thickness"),
        (format!(r#"{{"duration": 1, "output": {{"fps": 1e9}}, {chain}}}"#), "/output/fps"),
        (format!(r#"{{"duration": 1e9, {chain}}}"#), "/duration"),
        (format!(r#"{{"duration": 1, "dt": 1e-12, {chain}}}"#), "/dt"),
        (
            r#"{"duration": 1, "bodies": [{"type": "cloth", "resolution": [100000, 100000]}]}"#.into(),
            "/bodies/0/resolution",
        ),
        (format!(r#"{{"duration": 1, "solver": {{"tolerance": 1}}, {chain}}}"#), "/solver/tolerance"),
        (
            format!(r#"{{"duration": 1, "solver": {{"max_iterations": 100000}}, {chain}}}"#),
            "/solver/max_iterations",
        ),
    ];
    for (scene, pointer) in &cases {
        for path in ["/jobs", "/simulate"] {
            let answer = post_json(&app, path, scene).await;
            assert_eq!(answer.status, 422, "{path} {scene}: {}", answer.text());
            let problem = answer.problem();
            assert_eq!(problem["errors"][0]["pointer"], *pointer, "{path} {scene}: {problem}");
        }
    }
    let page = drape::jobs::Page { offset: 0, limit: 100 };
    assert!(jobs.list(page).await.unwrap().is_empty(), "nothing was queued");

    // 10,000 spheres over a small cloth: 0.3 % of the old particle-step budget, but 10,000
    // collider tests per particle and step.
    let spheres: Vec<String> = (0..10_000)
        .map(|i| format!(r#"{{"type":"sphere","center":[{},-5,0],"radius":0.01}}"#, i as f64 * 1e-3))
        .collect();
    let scene = format!(
        r#"{{"duration":0.15,"dt":0.001,"error_estimate":"none","bodies":[{{"type":"cloth","resolution":[32,32]}}],"colliders":[{}]}}"#,
        spheres.join(",")
    );
    let answer = post_json(&app, "/simulate", &scene).await;
    assert_eq!(answer.status, 413, "{}", answer.text());
    let problem = answer.problem();
    assert_eq!(problem["errors"][0]["pointer"], "/colliders");
    // 1024 particles × 10,000 colliders × 150 steps.
    assert!(problem["detail"].as_str().unwrap().contains("POST /jobs"), "{problem}");
    assert_eq!(
        problem["errors"][0]["detail"].as_str().unwrap().split(' ').nth(2),
        Some((1024u64 * 10_000 * 150).to_string().as_str())
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_whose_self_collision_outgrows_its_memory_fails_at_the_thickness() {
    // Two cloths 0.5 m apart, one falling onto the other at 5 m/s: their particles, each in a
    // cell of its own layer, meet the other layer's when they touch.
    let scene = r#"{"duration": 0.2, "dt": 2e-4, "gravity": [0, 0, 0], "error_estimate": "none",
        "bodies": [{"type": "cloth", "resolution": [10, 10], "center": [0, 0.5, 0], "velocity": [0, -5, 0]},
                   {"type": "cloth", "resolution": [10, 10], "center": [0, 0, 0]}],
        "self_collision": {"thickness": 0.06}, "output": {"frames": "final"}}"#;
    // A job allowance of exactly the estimate leaves no room beyond the pairs at rest.
    let parsed = drape::scene::Scene::from_json(scene.as_bytes()).unwrap();
    let admitted = drape::jobs::Limits::default().admit(&parsed).unwrap();
    let (pairs, memory) = (admitted.cost.pairs, admitted.cost.memory());
    assert!(pairs > 200, "{pairs} pairs at rest");
    assert_eq!(
        admitted.compiled.config.max_self_collision_pairs as u64,
        pairs + (drape::jobs::Limits::default().max_memory - memory) / 8
    );
    let limits = drape::jobs::Limits { max_memory: memory, ..drape::jobs::Limits::default() };
    let (_, app) = test_app(JobsConfig { limits, ..jobs_config() }, ApiConfig::default());

    let answer = post_json(&app, "/simulate", scene).await;
    assert_eq!(answer.status, 422, "{}", answer.text());
    let problem = answer.problem();
    assert_eq!(problem["errors"][0]["pointer"], "/self_collision/thickness");
    let detail = problem["errors"][0]["detail"].as_str().unwrap();
    assert!(detail.contains(&format!("more than the {pairs} this run may hold")), "{detail}");
    let id = detail.strip_prefix("job ").and_then(|rest| rest.split(' ').next()).unwrap();
    let job = get(&app, &format!("/jobs/{id}")).await.json();
    assert_eq!((job["status"].as_str(), job["failure"].as_str()), (Some("failed"), Some("limit")), "{job}");
    assert_eq!(get(&app, &format!("/jobs/{id}/result")).await.status, 409);
}
