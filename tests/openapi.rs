//! The served description is `openapi/openapi.yaml`, and it and the router list the same routes.

mod common;

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
        let uri = path.replace("{id}", &id);
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
