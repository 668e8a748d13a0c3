//! A table of malformed requests, each with the status and JSON Pointer it must get, then a
//! health check and a job that succeeds: bad input never harms the server.

mod common;
mod deadline;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::ApiConfig;
use drape::jobs::{JobsConfig, Limits};

struct Case {
    name: &'static str,
    method: &'static str,
    path: &'static str,
    content_type: Option<&'static str>,
    body: String,
    status: u16,
    /// The pointer of the first entry of `errors`, or `None` when the problem has no `errors`.
    pointer: Option<&'static str>,
}

fn scene(name: &'static str, body: &str, status: u16, pointer: &'static str) -> Case {
    Case {
        name,
        method: "POST",
        path: "/jobs",
        content_type: Some("application/json"),
        body: body.to_string(),
        status,
        pointer: Some(pointer),
    }
}

fn bare(
    name: &'static str,
    method: &'static str,
    path: &'static str,
    status: u16,
    pointer: Option<&'static str>,
) -> Case {
    Case { name, method, path, content_type: None, body: String::new(), status, pointer }
}

fn with_body(body: &str) -> String {
    format!(r#"{{"duration": 0.1, "dt": 0.01, "bodies": [{body}]}}"#)
}

fn cases() -> Vec<Case> {
    let chain = |extra: &str| with_body(&format!(r#"{{"type": "chain", "count": 3{extra}}}"#));
    let cloth = |extra: &str| with_body(&format!(r#"{{"type": "cloth", "resolution": [4, 4]{extra}}}"#));
    let top =
        |extra: &str| format!(r#"{{"duration": 0.1, "dt": 0.01, "bodies": [{{"type": "chain"}}]{extra}}}"#);
    let mesh =
        |extra: &str| with_body(&format!(r#"{{"type": "mesh", "vertices": [0,0,0, 1,0,0, 0,1,0]{extra}}}"#));
    vec![
        // The body is not JSON, or not declared as JSON.
        Case { content_type: None, ..scene("no content type", TINY, 415, "") }.without_pointer(),
        Case { content_type: Some("text/plain"), ..scene("text/plain", TINY, 415, "") }.without_pointer(),
        Case { content_type: Some("application/x-www-form-urlencoded"), ..scene("form", "a=1", 415, "") }
            .without_pointer(),
        scene("empty body", "", 400, ""),
        scene("truncated", r#"{"duration": 1, "bodies": ["#, 400, ""),
        scene("trailing comma", r#"{"duration": 1,}"#, 400, ""),
        scene("number out of range", r#"{"duration": 1e400, "bodies": []}"#, 400, ""),
        scene("array document", "[]", 422, ""),
        scene("string document", r#""a scene""#, 422, ""),
        // Scene fields: unknown, wrong types, out of range.
        scene("missing duration", r#"{"bodies": [{"type": "chain"}]}"#, 422, "/duration"),
        scene("unknown top-level field", &top(r#", "colour": "red""#), 422, "/colour"),
        scene(
            "duration as a string",
            r#"{"duration": "2", "bodies": [{"type": "chain"}]}"#,
            422,
            "/duration",
        ),
        scene("null duration", r#"{"duration": null, "bodies": [{"type": "chain"}]}"#, 422, "/duration"),
        scene("negative duration", r#"{"duration": -1, "bodies": [{"type": "chain"}]}"#, 422, "/duration"),
        scene("zero dt", &top(r#", "dt": 0"#).replace(r#""dt": 0.01, "#, ""), 422, "/dt"),
        scene("unknown integrator", &top(r#", "integrator": "leapfrog""#), 422, "/integrator"),
        scene("unknown precision", &top(r#", "precision": "f16""#), 422, "/precision"),
        scene("two-component gravity", &top(r#", "gravity": [0, -9.81]"#), 422, "/gravity"),
        scene("negative drag", &top(r#", "drag": -0.1"#), 422, "/drag"),
        scene("verlet damping of 1", &top(r#", "verlet_damping": 1.0"#), 422, "/verlet_damping"),
        scene("tolerance above 1", &top(r#", "solver": {"tolerance": 2}"#), 422, "/solver/tolerance"),
        scene("zero iterations", &top(r#", "solver": {"max_iterations": 0}"#), 422, "/solver/max_iterations"),
        scene("unknown error estimate", &top(r#", "error_estimate": "exact""#), 422, "/error_estimate"),
        scene(
            "spatial estimate of a chain",
            &top(r#", "error_estimate": "resolution""#),
            422,
            "/error_estimate",
        ),
        scene(
            "spatial estimate of a cloth without a material",
            &cloth("").replace(r#""bodies""#, r#""error_estimate": "resolution", "bodies""#),
            422,
            "/error_estimate",
        ),
        scene("zero rest speed", &top(r#", "stop_at_rest": 0"#), 422, "/stop_at_rest"),
        scene("no bodies", r#"{"duration": 1, "bodies": []}"#, 422, "/bodies"),
        scene("body not an object", &with_body("5"), 422, "/bodies/0"),
        scene("body without type", &with_body(r#"{"count": 3}"#), 422, "/bodies/0/type"),
        scene("unknown body type", &with_body(r#"{"type": "rope"}"#), 422, "/bodies/0/type"),
        scene("unknown body field", &chain(r#", "colour": "red""#), 422, "/bodies/0/colour"),
        scene("cloth resolution of 1", &cloth("").replace("[4, 4]", "[1, 4]"), 422, "/bodies/0/resolution/0"),
        scene("negative resolution", &cloth("").replace("[4, 4]", "[4, -1]"), 422, "/bodies/0/resolution/1"),
        scene("zero cloth mass", &cloth(r#", "mass": 0"#), 422, "/bodies/0/mass"),
        scene("pin outside the cloth", &cloth(r#", "pin": [[0, 0], [4, 0]]"#), 422, "/bodies/0/pin/1/0"),
        scene(
            "zero shear stiffness",
            &cloth(r#", "springs": {"shear": {"k": 0}}"#),
            422,
            "/bodies/0/springs/shear/k",
        ),
        scene("chain of one", &chain("").replace(r#""count": 3"#, r#""count": 1"#), 422, "/bodies/0/count"),
        scene("pin outside the chain", &chain(r#", "pin": [3]"#), 422, "/bodies/0/pin/0"),
        scene(
            "infinite-looking velocity",
            &chain(r#", "velocity": [1e308, 1e308, "x"]"#),
            422,
            "/bodies/0/velocity/2",
        ),
        scene("mesh without triangles", &mesh(""), 422, "/bodies/0/triangles"),
        scene("mesh index out of range", &mesh(r#", "triangles": [0, 1, 3]"#), 422, "/bodies/0/triangles/2"),
        scene("zero fps", &top(r#", "output": {"fps": 0}"#), 422, "/output/fps"),
        scene("unknown field name", &top(r#", "output": {"fields": ["colour"]}"#), 422, "/output/fields/0"),
        scene(
            "field listed twice",
            &top(r#", "output": {"fields": ["positions", "positions"]}"#),
            422,
            "/output/fields/1",
        ),
        scene("unknown frame selection", &top(r#", "output": {"frames": "some"}"#), 422, "/output/frames"),
        scene("unknown format", &top(r#", "output": {"format": "gif"}"#), 422, "/output/format"),
        // Scenes over this server's limits (the test server accepts 1000 particles, 10000 steps).
        scene("too many particles", &cloth("").replace("[4, 4]", "[40, 40]"), 422, "/bodies/0/resolution"),
        scene("too many steps", &top("").replace("0.01", "0.000001"), 422, "/dt"),
        scene(
            "too much output",
            &top(r#", "output": {"fps": 100000000}"#).replace("0.01", "0.001"),
            422,
            "/output/fps",
        ),
        Case {
            path: "/simulate",
            // The chain's step is within its stability bound and twice it is not: the error
            // estimate's companion at half the step is the largest share of the work.
            ..scene("over the simulate budget", &chain("").replace("0.1", "5"), 413, "/error_estimate")
        },
        scene("body over the size limit", &format!(r#"{{"pad": "{}"}}"#, "x".repeat(70_000)), 413, "")
            .without_pointer(),
        // Result formats.
        Case { path: "/simulate?format=gif", ..scene("unknown format in the query", TINY, 400, "/format") },
        Case {
            path: "/jobs?format=pc2",
            ..scene(
                "format that cannot carry a field",
                &top(r#", "output": {"fields": ["energy"]}"#),
                422,
                "/output/fields/0",
            )
        },
        Case { method: "POST-TEXT-ONLY", path: "/simulate", ..scene("nothing acceptable", TINY, 406, "") }
            .without_pointer(),
        // Headers and query parameters.
        Case {
            name: "idempotency key too long",
            method: "POST-KEYED",
            ..scene("", TINY, 400, "/headers/idempotency-key")
        },
        bare("limit of zero", "GET", "/jobs?limit=0", 400, Some("/limit")),
        bare("limit too large", "GET", "/jobs?limit=101", 400, Some("/limit")),
        bare("limit not a number", "GET", "/jobs?limit=ten", 400, Some("/limit")),
        bare("negative offset", "GET", "/jobs?offset=-1", 400, Some("/offset")),
        bare("unknown query parameter", "GET", "/jobs?status=running", 400, Some("/status")),
        // Unknown ids, routes and methods.
        bare("malformed job id", "GET", "/jobs/not-a-job", 404, None),
        bare("unknown job", "GET", "/jobs/0123456789abcdef", 404, None),
        bare("unknown job result", "GET", "/jobs/0123456789abcdef/result", 404, None),
        bare("unknown job events", "GET", "/jobs/0123456789abcdef/events", 404, None),
        bare("cancel an unknown job", "DELETE", "/jobs/0123456789abcdef", 404, None),
        bare("unknown route", "GET", "/nowhere", 404, None),
        bare("PUT /jobs", "PUT", "/jobs", 405, None),
        bare("GET /simulate", "GET", "/simulate", 405, None),
        bare("POST /healthz", "POST", "/healthz", 405, None),
        bare("PATCH a job", "PATCH", "/jobs/0123456789abcdef", 405, None),
    ]
}

impl Case {
    fn without_pointer(self) -> Self {
        Self { pointer: None, ..self }
    }

    fn request(&self) -> Request<Body> {
        let method = if self.method.starts_with("POST-") { "POST" } else { self.method };
        let mut builder = Request::builder().method(method).uri(self.path);
        if let Some(content_type) = self.content_type {
            builder = builder.header("content-type", content_type);
        }
        if self.method == "POST-KEYED" {
            builder = builder.header("idempotency-key", "k".repeat(256));
        }
        if self.method == "POST-TEXT-ONLY" {
            builder = builder.header("accept", "text/html");
        }
        builder.body(Body::from(self.body.clone())).unwrap()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_requests_get_their_status_and_pointer_and_harm_nothing() {
    let jobs = JobsConfig {
        limits: Limits {
            max_particles: 1000,
            max_springs: 10_000,
            max_steps: 10_000,
            max_output_values: 1_000_000,
            ..Limits::default()
        },
        ..jobs_config()
    };
    let api = ApiConfig { body_limit: 64 << 10, simulate_work_budget: 100, ..ApiConfig::default() };
    let (_, app) = test_app(jobs, api);
    let cases = cases();
    assert!(cases.len() >= 30);
    let mut failures = Vec::new();
    for case in &cases {
        let answer = send(&app, case.request()).await;
        let problem = answer.problem();
        let pointer = problem["errors"][0]["pointer"].as_str();
        if answer.status != case.status || pointer != case.pointer {
            failures.push(format!(
                "{}: expected {} {:?}, got {} {:?}: {problem}",
                case.name, case.status, case.pointer, answer.status, pointer
            ));
        }
        if let Some(errors) = problem["errors"].as_array() {
            assert!(errors.iter().all(|e| e["detail"].as_str().is_some_and(|d| !d.is_empty())), "{problem}");
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );

    assert_eq!(get(&app, "/healthz").await.status, 200);
    let job = post_json(&app, "/jobs", TINY).await.json();
    assert_eq!(poll_until(&app, job["id"].as_str().unwrap(), is_final).await["status"], "succeeded");
    assert_eq!(
        get(&app, "/jobs").await.json()["jobs"].as_array().unwrap().len(),
        1,
        "no malformed request made a job"
    );
}
