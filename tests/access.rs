//! Bearer tokens and allowed `Host` names, through the router.

mod common;
mod deadline;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::{AllowedHosts, ApiConfig, AuthToken};

const TOKEN: &str = "test-token-0123456789";

fn with_tokens() -> ApiConfig {
    ApiConfig {
        auth_tokens: vec![AuthToken::parse("another-token").unwrap(), AuthToken::parse(TOKEN).unwrap()],
        cors_origins: vec!["https://app.example".into()],
        ..ApiConfig::default()
    }
}

fn get_with(path: &str, headers: &[(&str, &str)]) -> Request<Body> {
    let mut request = Request::get(path);
    for (name, value) in headers {
        request = request.header(*name, *value);
    }
    request.body(Body::empty()).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_tokens_set_every_endpoint_but_healthz_needs_one() {
    let (_, app) = test_app(jobs_config(), with_tokens());
    let bearer = format!("Bearer {TOKEN}");

    let none = send(&app, get_with("/jobs", &[])).await;
    assert_eq!(none.status, 401);
    assert_eq!(none.header("www-authenticate"), Some("Bearer"));
    assert_eq!(none.problem()["type"], "/problems/unauthorized");

    let wrong = send(&app, get_with("/jobs", &[("authorization", "Bearer test-token-012345678")])).await;
    assert_eq!(wrong.status, 401);
    assert_eq!(wrong.header("www-authenticate"), Some("Bearer error=\"invalid_token\""));
    assert_eq!(wrong.problem()["detail"], "the bearer token is not one this server accepts");

    let basic = send(&app, get_with("/jobs", &[("authorization", "Basic dXNlcjpwYXNz")])).await;
    assert_eq!(basic.status, 401);
    assert_eq!(basic.header("www-authenticate"), Some("Bearer error=\"invalid_request\""));

    // Unknown paths and the description are closed too: nothing is learnt without a token.
    for path in ["/openapi.json", "/metrics", "/jobs/nope", "/no/such/path"] {
        let answer = send(&app, get_with(path, &[])).await;
        assert_eq!(answer.status, 401, "{path}");
        assert_eq!(answer.problem()["type"], "/problems/unauthorized", "{path}");
    }
    let post =
        Request::post("/jobs").header("content-type", "application/json").body(Body::from(TINY)).unwrap();
    assert_eq!(send(&app, post).await.status, 401);

    let right = send(&app, get_with("/jobs", &[("authorization", &bearer)])).await;
    assert_eq!(right.status, 200, "{}", right.text());
    assert_eq!(right.json()["jobs"], serde_json::json!([]));
    let lower = send(&app, get_with("/jobs", &[("authorization", &format!("bearer {TOKEN}"))])).await;
    assert_eq!(lower.status, 200);
    let other = send(&app, get_with("/jobs", &[("authorization", "Bearer another-token")])).await;
    assert_eq!(other.status, 200);
    let submit = Request::post("/jobs")
        .header("content-type", "application/json")
        .header("authorization", &bearer)
        .body(Body::from(TINY))
        .unwrap();
    assert_eq!(send(&app, submit).await.status, 202);

    // Uploads are held to the same tokens.
    let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let upload = |token: Option<&str>| {
        let mut request = Request::post("/assets").header("content-type", "model/obj");
        if let Some(token) = token {
            request = request.header("authorization", token);
        }
        request.body(Body::from(triangle)).unwrap()
    };
    assert_eq!(send(&app, upload(None)).await.status, 401);
    assert_eq!(send(&app, get_with("/assets", &[])).await.status, 401);
    assert_eq!(send(&app, upload(Some(&bearer))).await.status, 201);

    let health = send(&app, get_with("/healthz", &[])).await;
    assert_eq!(health.status, 200);
    assert_eq!(health.json(), serde_json::json!({"status": "ok"}));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cors_preflight_needs_no_token_and_a_refusal_carries_cors_headers() {
    let (_, app) = test_app(jobs_config(), with_tokens());
    let preflight = Request::options("/jobs")
        .header("origin", "https://app.example")
        .header("access-control-request-method", "POST")
        .header("access-control-request-headers", "authorization,content-type")
        .body(Body::empty())
        .unwrap();
    let answer = send(&app, preflight).await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.header("access-control-allow-origin"), Some("https://app.example"));
    let allowed = answer.header("access-control-allow-headers").unwrap().to_ascii_lowercase();
    assert!(allowed.split(',').any(|h| h.trim() == "authorization"), "{allowed}");

    let refused = send(&app, get_with("/jobs", &[("origin", "https://app.example")])).await;
    assert_eq!(refused.status, 401);
    assert_eq!(refused.header("access-control-allow-origin"), Some("https://app.example"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_tokens_no_authorization_is_asked_for() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    assert_eq!(send(&app, get_with("/jobs", &[])).await.status, 200);
    assert_eq!(send(&app, get_with("/jobs", &[("authorization", "Bearer anything")])).await.status, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_to_other_host_names_are_refused_with_421() {
    let api = ApiConfig { allowed_hosts: AllowedHosts::loopback(), ..ApiConfig::default() };
    let (_, app) = test_app(jobs_config(), api);
    for host in ["localhost:8080", "127.0.0.1:8080", "[::1]:8080", "LOCALHOST", "localhost."] {
        let answer = send(&app, get_with("/jobs", &[("host", host)])).await;
        assert_eq!(answer.status, 200, "{host}: {}", answer.text());
    }
    for host in ["evil.example", "evil.example:8080", "localhost.evil.example", "127.0.0.2:8080"] {
        let answer = send(&app, get_with("/healthz", &[("host", host)])).await;
        assert_eq!(answer.status, 421, "{host}");
        let problem = answer.problem();
        assert_eq!(problem["type"], "/problems/host-not-allowed");
        assert_eq!(
            problem["detail"],
            format!("this server does not answer to the Host `{host}` (--allowed-hosts)")
        );
    }
    // A rebound page's preflight is refused too.
    let preflight = Request::options("/jobs")
        .header("host", "evil.example")
        .header("origin", "http://evil.example")
        .header("access-control-request-method", "POST")
        .body(Body::empty())
        .unwrap();
    assert_eq!(send(&app, preflight).await.status, 421);
    let nameless = send(&app, get_with("/jobs", &[])).await;
    assert_eq!(nameless.status, 421);
    assert_eq!(nameless.problem()["type"], "/problems/host-not-allowed");

    let listed = ApiConfig {
        allowed_hosts: AllowedHosts::from_names(&["drape.example".into()]),
        ..ApiConfig::default()
    };
    let (_, app) = test_app(jobs_config(), listed);
    assert_eq!(send(&app, get_with("/jobs", &[("host", "drape.example:443")])).await.status, 200);
    assert_eq!(send(&app, get_with("/jobs", &[("host", "localhost")])).await.status, 421);
}

/// A page on another origin reads every response header the description declares: CORS
/// exposes each of them by name.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cors_exposes_every_response_header_the_description_declares() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.yaml")).unwrap();
    let spec: serde_json::Value = serde_yaml_ng::from_str(&text).unwrap();
    let mut declared = std::collections::BTreeSet::new();
    collect_response_headers(&spec, &mut declared);
    assert!(declared.contains("drape-job-id") && declared.contains("retry-after"), "{declared:?}");

    let (_, app) = test_app(jobs_config(), with_tokens());
    let answer = send(
        &app,
        get_with(
            "/jobs",
            &[("origin", "https://app.example"), ("authorization", &format!("Bearer {TOKEN}"))],
        ),
    )
    .await;
    assert_eq!(answer.status, 200);
    let exposed: std::collections::BTreeSet<String> = answer
        .header("access-control-expose-headers")
        .unwrap()
        .split(',')
        .map(|h| h.trim().to_ascii_lowercase())
        .collect();
    let hidden: Vec<&String> = declared.iter().filter(|h| !exposed.contains(*h)).collect();
    assert!(hidden.is_empty(), "declared but not exposed: {hidden:?}");
}

/// The names under every `headers` map of a response (in `responses` and `components`).
fn collect_response_headers(value: &serde_json::Value, names: &mut std::collections::BTreeSet<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (key, child) in map {
                if key == "headers"
                    && let Some(headers) = child.as_object()
                {
                    names.extend(headers.keys().map(|h| h.to_ascii_lowercase()));
                }
                collect_response_headers(child, names);
            }
        }
        serde_json::Value::Array(items) => {
            items.iter().for_each(|item| collect_response_headers(item, names))
        }
        _ => {}
    }
}
