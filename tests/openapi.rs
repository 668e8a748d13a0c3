//! The served description is `openapi/openapi.yaml`, and it and the router list the same routes.

mod common;
mod deadline;

use std::collections::BTreeSet;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::{ApiConfig, routes};
use serde_json::Value;

fn yaml() -> Value {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.yaml")).unwrap();
    serde_yaml_ng::from_str(&text).unwrap()
}

fn spec_operations(spec: &Value) -> BTreeSet<(String, String)> {
    let methods = ["get", "post", "put", "patch", "delete", "head", "options"];
    spec["paths"]
        .as_object()
        .unwrap()
        .iter()
        .flat_map(|(path, item)| {
            methods.iter().filter(|m| item.get(**m).is_some()).map(move |m| (m.to_uppercase(), path.clone()))
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_served_description_is_the_yaml_file() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let served = get(&app, "/openapi.json").await;
    assert_eq!(served.status, 200);
    assert_eq!(served.json(), yaml());
}

#[test]
fn the_router_and_the_description_list_the_same_operations() {
    let router: BTreeSet<(String, String)> =
        routes().iter().map(|r| (r.method.to_string(), r.path.to_string())).collect();
    assert_eq!(router, spec_operations(&yaml()));
}

/// Every operation in the description is served: the router answers it with neither "no such
/// route" nor "method not allowed". This reads the router itself, not the route list.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_described_operation_is_routed() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let id = post_json(&app, "/jobs", TINY).await.json()["id"].as_str().unwrap().to_string();
    poll_until(&app, &id, is_final).await;
    for (method, path) in spec_operations(&yaml()) {
        let uri = path.replace("{id}", &id).replace("{file}", "main.js");
        let request = Request::builder()
            .method(method.as_str())
            .uri(&uri)
            .header("content-type", "application/json")
            .body(Body::from(TINY))
            .unwrap();
        let answer = send(&app, request).await;
        let kind = if answer.status >= 400 { answer.problem()["type"].clone() } else { Value::Null };
        assert!(
            kind != "/problems/not-found" && kind != "/problems/method-not-allowed",
            "{method} {uri}: {}",
            answer.text()
        );
    }
}

/// The description's scene schema names every field the scene module accepts.
#[test]
fn the_scene_schema_lists_every_top_level_field() {
    let spec = yaml();
    let described: BTreeSet<&str> = spec["components"]["schemas"]["Scene"]["properties"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    // An unknown field is refused with the list of the accepted ones; read that list back.
    let error = drape::scene::Scene::from_json(br#"{"duration": 1, "bodies": [], "zzz": 1}"#).unwrap_err();
    let detail = &error.field_errors()[0].detail;
    let accepted: BTreeSet<&str> = detail.split('`').skip(3).step_by(2).collect();
    assert_eq!(described, accepted, "{detail}");
}

/// The operations open without a token: liveness and the viewer's page and files.
const OPEN_PATHS: [&str; 3] = ["/healthz", "/", "/viewer/{file}"];

/// Every operation but the open ones is under the bearer scheme and lists its 401; every operation
/// lists the 421 of a refused `Host` and the 414 and 431 of an oversized head, and every POST the
/// 415 of a body that is not JSON or not in gzip.
#[test]
fn every_operation_but_the_open_ones_declares_the_bearer_scheme() {
    let spec = yaml();
    assert_eq!(spec["components"]["securitySchemes"]["bearer"]["scheme"], "bearer");
    assert_eq!(spec["security"], serde_json::json!([{"bearer": []}, {}]));
    let mut checked = 0;
    for (method, path) in spec_operations(&spec) {
        let operation = &spec["paths"][&path][method.to_lowercase()];
        let responses = &operation["responses"];
        assert!(responses.get("421").is_some(), "{method} {path} lacks 421");
        assert_eq!(responses["414"]["$ref"], "#/components/responses/UriTooLong", "{method} {path}");
        assert_eq!(
            responses["431"]["$ref"], "#/components/responses/HeaderFieldsTooLarge",
            "{method} {path}"
        );
        if method == "POST" {
            assert_eq!(
                responses["415"]["$ref"], "#/components/responses/UnsupportedMediaType",
                "{method} {path}"
            );
        }
        if OPEN_PATHS.contains(&path.as_str()) {
            assert_eq!(operation["security"], serde_json::json!([]), "{method} {path}");
            assert!(responses.get("401").is_none(), "{method} {path}");
        } else {
            assert!(operation.get("security").is_none(), "{method} {path} overrides the security");
            assert_eq!(responses["401"]["$ref"], "#/components/responses/Unauthorized", "{method} {path}");
        }
        checked += 1;
    }
    assert_eq!(checked, routes().len());
}

/// What Schemathesis (`.ci/schemathesis`) found the description and the server disagreeing on,
/// each checked on both sides: the description now says what the server does.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_description_states_what_the_server_accepts_and_answers() {
    let spec = yaml();
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let job = post_json(&app, "/jobs", TINY).await.json();
    let id = job["id"].as_str().unwrap().to_string();
    poll_until(&app, &id, is_final).await;

    // An unknown ?format= is a 400, a response the result operation lists.
    let result = &spec["paths"]["/jobs/{id}/result"]["get"]["responses"];
    assert!(result.get("400").is_some(), "{result}");
    let unknown = get(&app, &format!("/jobs/{id}/result?format=AAA")).await;
    assert_eq!(unknown.status, 400);
    assert_eq!(unknown.problem()["errors"][0]["pointer"], "/format");

    // `offset` is at most u32::MAX.
    let offset = &spec["paths"]["/jobs"]["get"]["parameters"][0];
    assert_eq!(
        (offset["name"].as_str(), offset["schema"]["maximum"].as_u64()),
        (Some("offset"), Some(4294967295))
    );
    assert_eq!(get(&app, "/jobs?offset=4294967295").await.status, 200);
    assert_eq!(get(&app, "/jobs?offset=4294967296").await.status, 400);

    // Idempotency-Key: 1 to 255 visible ASCII characters, as the pattern says.
    let key = &spec["paths"]["/jobs"]["post"]["parameters"][1];
    assert_eq!(key["name"], "Idempotency-Key");
    assert_eq!(key["schema"]["pattern"], "^[!-~]{1,255}$");
    let keyed = |key: &str| {
        Request::post("/jobs")
            .header("content-type", "application/json")
            .header("idempotency-key", key)
            .body(Body::from(TINY))
            .unwrap()
    };
    assert_eq!(send(&app, keyed("a b")).await.status, 400);
    assert_eq!(send(&app, keyed(&"~".repeat(256))).await.status, 400);
    assert_eq!(send(&app, keyed(&"~".repeat(255))).await.status, 202);

    // An optional scene field without a default may be null, meaning left out.
    let scene = &spec["components"]["schemas"]["Scene"]["properties"];
    for field in ["dt", "stop_at_rest", "strain_limit", "self_collision"] {
        assert!(scene[field]["type"].as_array().is_some_and(|t| t.contains(&"null".into())), "{field}");
    }
    for field in ["wind", "output"] {
        assert_eq!(scene[field]["anyOf"][1], serde_json::json!({"type": "null"}), "{field}");
    }
    let nulls = TINY.replacen(
        '{',
        r#"{"dt": null, "stop_at_rest": null, "strain_limit": null, "self_collision": null, "wind": null, "#,
        1,
    );
    assert_eq!(post_json(&app, "/simulate", &nulls).await.status, 200);
    // A field with a default is not nullable, and null there is refused at the field.
    assert_eq!(scene["drag"]["type"], "number");
    let answer = post_json(&app, "/simulate", &TINY.replacen('{', r#"{"drag": null, "#, 1)).await;
    assert_eq!(answer.status, 422);
    assert_eq!(answer.problem()["errors"][0]["pointer"], "/drag");

    // Each server-sent event is an object with `event` and JSON `data`.
    let events = &spec["paths"]["/jobs/{id}/events"]["get"]["responses"]["200"]["content"]["text/event-stream"]
        ["schema"];
    assert_eq!(events["required"], serde_json::json!(["event", "data"]));
    let stream = get(&app, &format!("/jobs/{id}/events")).await.text();
    assert!(stream.starts_with("event: end\ndata: {"), "{stream}");
}

/// No key of the description is null where a value is due: in a YAML flow map an unquoted comma
/// ends a value, so `{description: Total mass, in kg.}` reads as a description `Total mass` and a
/// key `in kg.` with no value.
#[test]
fn no_description_is_cut_short_by_a_comma() {
    fn walk(value: &Value, at: &str, cut: &mut Vec<String>) {
        match value {
            Value::Object(map) => {
                for (key, child) in map {
                    let here = format!("{at}/{key}");
                    if child.is_null() && !matches!(key.as_str(), "default" | "example" | "const") {
                        cut.push(here.clone());
                    }
                    walk(child, &here, cut);
                }
            }
            Value::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    walk(item, &format!("{at}/{i}"), cut);
                }
            }
            _ => {}
        }
    }
    let mut cut = Vec::new();
    walk(&yaml(), "", &mut cut);
    assert!(cut.is_empty(), "keys with no value, each a description cut at a comma: {cut:?}");
}

/// An independent reader finds nothing wrong in the description: Redocly CLI, pinned in
/// `.ci/node`, lints it with the `recommended` ruleset (`.ci/redocly.yaml`), and finds neither an
/// error nor a warning.
#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn redocly_finds_no_problem_in_the_description() {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let cli = repo.join(".ci/node/node_modules/@redocly/cli/bin/cli.js");
    assert!(cli.is_file(), "Redocly CLI is not installed: node, then `npm ci --prefix .ci/node`");
    let output = std::process::Command::new("node")
        .arg(&cli)
        .args([
            "lint",
            "--config",
            ".ci/redocly.yaml",
            "--format",
            "json",
            "--max-problems",
            "1000",
            "openapi/openapi.yaml",
        ])
        .current_dir(repo)
        // No usage report or update check over the network.
        .env("REDOCLY_TELEMETRY", "off")
        .env("REDOCLY_SUPPRESS_UPDATE_NOTICE", "true")
        .output()
        .unwrap_or_else(|e| panic!("cannot run node ({e}): install node, then `npm ci --prefix .ci/node`"));
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    let report: Value = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("no JSON report from redocly ({e}):\n{stdout}\n{stderr}"));
    let totals = &report["totals"];
    assert!(
        output.status.success() && totals["errors"] == 0 && totals["warnings"] == 0,
        "redocly {} (exit {:?}) finds {} errors and {} warnings:\n{:#}\n{stderr}",
        report["version"],
        output.status.code(),
        totals["errors"],
        totals["warnings"],
        report["problems"],
    );
}

/// The viewer's TypeScript types (`src/api/viewer/drape-api.d.ts`) are what openapi-typescript
/// (pinned in `.ci/node`) generates from the description today, and the viewer's scripts,
/// typed by JSDoc against them, compile under `tsc --noEmit --checkJs --strict`: a field the
/// description does not have, or a wrong type, fails here.
#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn the_viewer_compiles_against_types_generated_from_the_description() {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let node_modules = repo.join(".ci/node/node_modules");
    let generator = node_modules.join("openapi-typescript/bin/cli.js");
    let tsc = node_modules.join("typescript/bin/tsc");
    assert!(
        generator.is_file() && tsc.is_file(),
        "openapi-typescript or typescript is not installed: node, then `npm ci --prefix .ci/node`"
    );
    let dir = tempfile::tempdir().unwrap();
    let generated = dir.path().join("drape-api.d.ts");
    let output = std::process::Command::new("node")
        .arg(&generator)
        .arg(repo.join("openapi/openapi.yaml"))
        .arg("-o")
        .arg(&generated)
        .output()
        .unwrap_or_else(|e| panic!("cannot run node ({e}): install node, then `npm ci --prefix .ci/node`"));
    assert!(output.status.success(), "openapi-typescript: {}", String::from_utf8_lossy(&output.stderr));
    let checked_in = std::fs::read_to_string(repo.join("src/api/viewer/drape-api.d.ts")).unwrap();
    assert!(
        std::fs::read_to_string(&generated).unwrap() == checked_in,
        "src/api/viewer/drape-api.d.ts is not what openapi/openapi.yaml gives; regenerate it with \
         `node .ci/node/node_modules/openapi-typescript/bin/cli.js openapi/openapi.yaml -o src/api/viewer/drape-api.d.ts`"
    );
    let output = std::process::Command::new("node")
        .arg(&tsc)
        .args(["--project", "src/api/viewer/tsconfig.json", "--pretty", "false"])
        .current_dir(repo)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "tsc finds the viewer's calls at odds with the description:\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}
