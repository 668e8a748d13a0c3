//! Mesh colliders in the scene contract: defaults, each bad input named by its pointer, and what
//! they compile to.

use serde_json::{Value, json};

use super::*;
use crate::solver::Shape;

fn scene(colliders: Value) -> Result<Scene, SceneError> {
    let doc =
        json!({"duration": 1.0, "bodies": [{"type": "cloth", "resolution": [4, 3]}], "colliders": colliders});
    Scene::from_json(doc.to_string().as_bytes())
}

fn square() -> Value {
    json!({"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1], "triangles": [0, 2, 1, 0, 3, 2]})
}

/// The square with `key` set to `value`, alone in a list of colliders.
fn square_with(key: &str, value: Value) -> Value {
    let mut collider = square();
    collider.as_object_mut().unwrap().insert(key.to_string(), value);
    json!([collider])
}

#[test]
fn a_mesh_collider_takes_its_defaults_and_compiles_to_its_triangles() {
    let s = scene(json!([square()])).unwrap();
    let ColliderSpec::Mesh(m) = &s.colliders[0] else { panic!("not a mesh") };
    assert_eq!((m.thickness, m.friction, m.restitution), (0.005, 0.3, 0.0));
    let compiled = s.compile();
    let Shape::Mesh { surface, thickness } = &compiled.config.colliders[0].shape else {
        panic!("not a mesh")
    };
    assert_eq!(*thickness, 0.005);
    assert_eq!(surface.triangles, [[0, 2, 1], [0, 3, 2]]);
    assert_eq!(surface.vertices[2], glam::DVec3::new(1.0, 0.0, 1.0));
    assert!(!surface.is_closed());
}

#[test]
fn each_bad_mesh_collider_field_is_named_by_its_pointer() {
    let cases: Vec<(Value, &[&str])> = vec![
        (square_with("triangles", json!([0, 1, 4])), &["/colliders/0/triangles/2"]),
        (square_with("triangles", json!([0, 1])), &["/colliders/0/triangles"]),
        (square_with("triangles", json!([])), &["/colliders/0/triangles"]),
        (square_with("triangles", json!([0, 1, 1.5])), &["/colliders/0/triangles/2"]),
        (
            square_with("vertices", json!([0, 0, 0, 1, 0, 0, 1, 0])),
            &[
                "/colliders/0/vertices",
                "/colliders/0/triangles/1",
                "/colliders/0/triangles/4",
                "/colliders/0/triangles/5",
            ],
        ),
        (square_with("vertices", json!([0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1e7])), &["/colliders/0/vertices"]),
        // Every triangle of zero area: no surface.
        (square_with("vertices", json!([0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0])), &["/colliders/0/triangles"]),
        (square_with("thickness", json!(0)), &["/colliders/0/thickness"]),
        (square_with("thickness", json!(2e6)), &["/colliders/0/thickness"]),
        (square_with("friction", json!(-1)), &["/colliders/0/friction"]),
        (square_with("restitution", json!(1.5)), &["/colliders/0/restitution"]),
        (square_with("normal", json!([0, 1, 0])), &["/colliders/0/normal"]),
        (json!([{"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0]}]), &["/colliders/0/triangles"]),
    ];
    for (colliders, expected) in cases {
        let error = scene(colliders.clone()).expect_err(&format!("accepted {colliders}"));
        let pointers: Vec<&str> = error.field_errors().iter().map(|e| e.pointer.as_str()).collect();
        assert_eq!(pointers, expected, "{colliders}: {error}");
    }
}

#[test]
fn a_mesh_collider_with_some_degenerate_triangles_is_valid() {
    // The second triangle repeats a corner: it has no surface and is left out.
    let s = scene(square_with("triangles", json!([0, 2, 1, 0, 0, 2]))).unwrap();
    let compiled = s.compile();
    assert_eq!(compiled.config.colliders.len(), 1);
}
