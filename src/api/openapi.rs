//! `GET /openapi.json`: the API description, read from `openapi/openapi.yaml` at build time.

use std::sync::LazyLock;

use axum::Json;
use serde_json::Value;

/// The YAML source of the description.
pub const OPENAPI_YAML: &str = include_str!("../../openapi/openapi.yaml");

/// The description as JSON, parsed once.
pub fn spec() -> &'static Value {
    static SPEC: LazyLock<Value> =
        LazyLock::new(|| serde_yaml_ng::from_str(OPENAPI_YAML).expect("openapi/openapi.yaml is valid YAML"));
    &SPEC
}

/// Serves the description.
pub async fn openapi() -> Json<&'static Value> {
    Json(spec())
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_description_parses_and_is_openapi_3_1() {
        assert_eq!(super::spec()["openapi"].as_str().map(|v| &v[..4]), Some("3.1."));
    }
}
