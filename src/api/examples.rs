//! `GET /examples`: the example scenes of the repository (`examples/*.json`), embedded in the
//! binary, for front ends to offer as starting points (the viewer lists them).

use axum::Json;
use serde_json::{Value, json};

/// Each example's name (its file name without `.json`) and its scene.
pub const EXAMPLES: &[(&str, &str)] = &[
    ("cantilever", include_str!("../../examples/cantilever.json")),
    ("chain", include_str!("../../examples/chain.json")),
    ("drape_mesh_sphere", include_str!("../../examples/drape_mesh_sphere.json")),
    ("drape_sphere", include_str!("../../examples/drape_sphere.json")),
    ("drape_sphere_explicit", include_str!("../../examples/drape_sphere_explicit.json")),
    ("drape_tester", include_str!("../../examples/drape_tester.json")),
    ("drape_torus", include_str!("../../examples/drape_torus.json")),
    ("fast_particle_sheet", include_str!("../../examples/fast_particle_sheet.json")),
    ("flag", include_str!("../../examples/flag.json")),
    ("hanging_cloth", include_str!("../../examples/hanging_cloth.json")),
    ("jelly_cube", include_str!("../../examples/jelly_cube.json")),
    ("self_collision", include_str!("../../examples/self_collision.json")),
    ("single_spring", include_str!("../../examples/single_spring.json")),
    ("strain_limited", include_str!("../../examples/strain_limited.json")),
    ("swept_ball", include_str!("../../examples/swept_ball.json")),
    ("tablecloth", include_str!("../../examples/tablecloth.json")),
    ("tablecloth_pull", include_str!("../../examples/tablecloth_pull.json")),
];

/// `GET /examples`: `{"examples": [{"name", "scene"}, ...]}`, by name.
pub(super) async fn list() -> Json<Value> {
    let examples: Vec<Value> = EXAMPLES
        .iter()
        .map(|(name, text)| {
            let scene: Value = serde_json::from_str(text).expect("the examples are JSON (tests/examples.rs)");
            json!({"name": name, "scene": scene})
        })
        .collect();
    Json(json!({ "examples": examples }))
}
