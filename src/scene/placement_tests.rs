//! Placements: what a translation, rotation and scale do to each shape, and the bad ones named
//! by their pointers.

use glam::DVec3;
use serde_json::{Value, json};

use super::*;
use crate::solver::Shape;

fn scene(colliders: Value) -> Result<Scene, SceneError> {
    let doc = json!({"duration": 1.0, "bodies": [{"type": "chain", "count": 2}], "colliders": colliders});
    Scene::from_json(doc.to_string().as_bytes())
}

fn shapes(colliders: Value) -> Vec<Shape> {
    scene(colliders).unwrap().compile().config.colliders.into_iter().map(|c| c.shape).collect()
}

/// A quarter turn about y: x goes to -z.
const QUARTER_ABOUT_Y: [f64; 4] =
    [0.0, std::f64::consts::FRAC_1_SQRT_2, 0.0, std::f64::consts::FRAC_1_SQRT_2];

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-12
}

#[test]
fn a_placement_scales_then_rotates_then_translates_each_shape() {
    let placed = shapes(json!([
        {"type": "sphere", "center": [1, 0, 0], "radius": 0.5, "scale": 2, "rotation": QUARTER_ABOUT_Y, "translation": [0, 1, 0]},
        {"type": "plane", "point": [0, 0, 1], "normal": [1, 0, 0], "rotation": QUARTER_ABOUT_Y},
        {"type": "box", "center": [1, 2, 3], "half_extents": [1, 1, 2], "scale": 0.5, "translation": [1, 0, 0]},
        {"type": "cylinder", "center": [0, 1, 0], "radius": 1, "height": 2, "scale": 3},
        {"type": "mesh", "vertices": [1, 0, 0, 0, 0, 1, 0, 1, 0], "triangles": [0, 1, 2], "rotation": QUARTER_ABOUT_Y, "scale": 2, "translation": [0, 0, 5]},
    ]));
    let Shape::Sphere { center, radius } = placed[0] else { panic!() };
    assert!(close(center, DVec3::new(0.0, 1.0, -2.0)), "{center}");
    assert_eq!(radius, 1.0);
    let Shape::Plane { point, normal } = placed[1] else { panic!() };
    assert!(
        close(point, DVec3::new(1.0, 0.0, 0.0)) && close(normal, DVec3::new(0.0, 0.0, -1.0)),
        "{point} {normal}"
    );
    assert_eq!(
        placed[2],
        Shape::Box { center: DVec3::new(1.5, 1.0, 1.5), half_extents: DVec3::new(0.5, 0.5, 1.0) }
    );
    assert_eq!(placed[3], Shape::Cylinder { center: DVec3::new(0.0, 3.0, 0.0), radius: 3.0, height: 6.0 });
    let Shape::Mesh { surface, thickness } = &placed[4] else { panic!() };
    assert_eq!(*thickness, 0.005, "the thickness is not scaled");
    let expected = [DVec3::new(0.0, 0.0, 3.0), DVec3::new(2.0, 0.0, 5.0), DVec3::new(0.0, 2.0, 5.0)];
    for (v, e) in surface.vertices.iter().zip(expected) {
        assert!(close(*v, e), "{v} against {e}");
    }
}

#[test]
fn a_mesh_body_is_placed_too() {
    let doc = json!({"duration": 1.0, "bodies": [{"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0, 1, 2], "translation": [0, 2, 0], "scale": 3}]});
    let compiled = Scene::from_json(doc.to_string().as_bytes()).unwrap().compile();
    assert_eq!(
        compiled.model.positions,
        [DVec3::new(0.0, 2.0, 0.0), DVec3::new(3.0, 2.0, 0.0), DVec3::new(0.0, 5.0, 0.0)]
    );
}

#[test]
fn each_bad_placement_is_named_by_its_pointer() {
    let cases: Vec<(Value, &[&str])> = vec![
        (
            json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rotation": [0, 0, 0, 1.1]}]),
            &["/colliders/0/rotation"],
        ),
        (
            json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rotation": [0, 0, 0, 0]}]),
            &["/colliders/0/rotation"],
        ),
        (
            json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rotation": [0, 0, 1]}]),
            &["/colliders/0/rotation"],
        ),
        (json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "scale": 0}]), &["/colliders/0/scale"]),
        (
            json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "scale": [1, 2, 3]}]),
            &["/colliders/0/scale"],
        ),
        (
            json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "scale": 2e6}]),
            &["/colliders/0/scale"],
        ),
        (
            json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "translation": [0, 2e6, 0]}]),
            &["/colliders/0/translation"],
        ),
        (
            json!([{"type": "plane", "point": [9e5, 0, 0], "translation": [2e5, 0, 0]}]),
            &["/colliders/0/translation"],
        ),
        (
            json!([{"type": "box", "center": [0, 0, 0], "half_extents": [1, 1, 1], "rotation": QUARTER_ABOUT_Y}]),
            &["/colliders/0/rotation"],
        ),
        (
            json!([{"type": "cylinder", "center": [0, 0, 0], "radius": 1, "height": 1, "rotation": QUARTER_ABOUT_Y}]),
            &["/colliders/0/rotation"],
        ),
        (
            json!([{"type": "mesh", "vertices": [0, 0, 0, 9e5, 0, 0, 0, 0, 1], "triangles": [0, 1, 2], "scale": 2}]),
            &["/colliders/0/scale"],
        ),
    ];
    for (colliders, expected) in cases {
        let error = scene(colliders.clone()).expect_err(&format!("accepted {colliders}"));
        let pointers: Vec<&str> = error.field_errors().iter().map(|e| e.pointer.as_str()).collect();
        assert_eq!(pointers, expected, "{colliders}: {error}");
    }
    // A rotation written with six digits (30° about y) is a unit quaternion.
    assert!(scene(json!([{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rotation": [0, 0.258819, 0, 0.965926]}])).is_ok());
    let body = json!({"duration": 1.0, "bodies": [{"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "triangles": [0, 1, 2], "translation": [1e6, 0, 0]}]});
    let error = Scene::from_json(body.to_string().as_bytes()).unwrap_err();
    assert_eq!(error.field_errors()[0].pointer, "/bodies/0/translation");
}

#[test]
fn a_moving_collider_is_defined_in_its_own_frame_and_its_motion_checked() {
    let colliders = shapes(json!([
        {"type": "sphere", "center": [1, 0, 0], "radius": 0.5, "scale": 2, "translation": [5, 0, 0],
         "motion": {"keyframes": [{"t": 0, "translation": [0, 1, 0]}, {"t": 1, "translation": [0, 2, 0]}]}},
    ]));
    // The keyframes replace the static translation; the scale stays.
    assert_eq!(colliders[0], Shape::Sphere { center: DVec3::new(2.0, 0.0, 0.0), radius: 1.0 });
    let cases: Vec<(Value, &[&str])> = vec![
        (json!({"keyframes": [{"t": 1}, {"t": 0.5}]}), &["/colliders/0/motion/keyframes/1/t"]),
        (json!({"keyframes": [{"t": -1}]}), &["/colliders/0/motion/keyframes/0/t"]),
        (json!({"keyframes": []}), &["/colliders/0/motion/keyframes"]),
        (
            json!({"keyframes": [{"t": 0, "rotation": [0, 0, 0, 2]}]}),
            &["/colliders/0/motion/keyframes/0/rotation"],
        ),
        (
            json!({"keyframes": [{"t": 0, "translation": [0, 2e6, 0]}]}),
            &["/colliders/0/motion/keyframes/0/translation"],
        ),
        (json!({"keyframes": [{"t": 0}], "velocity": [1, 0, 0]}), &["/colliders/0/motion"]),
        (json!({}), &["/colliders/0/motion"]),
        (json!({"velocity": [2e6, 0, 0]}), &["/colliders/0/motion/velocity"]),
        (json!({"angular_velocity": [0, 1e7, 0]}), &["/colliders/0/motion/angular_velocity"]),
        (json!({"speed": 1}), &["/colliders/0/motion/speed"]),
    ];
    for (motion, expected) in cases {
        let colliders = json!([{"type": "plane", "motion": motion}]);
        let error = scene(colliders.clone()).expect_err(&format!("accepted {colliders}"));
        let pointers: Vec<&str> = error.field_errors().iter().map(|e| e.pointer.as_str()).collect();
        assert_eq!(pointers, expected, "{colliders}: {error}");
    }
}

#[test]
fn a_pin_motion_carries_the_pinned_particles_about_the_rest_centroid() {
    let doc = |pin: Value| {
        json!({"duration": 1.0, "bodies": [{"type": "chain", "count": 3, "start": [0, 1, 0], "end": [2, 1, 0], "pin": pin,
               "pin_motion": {"keyframes": [{"t": 0}, {"t": 1, "translation": [0, 1, 0]}]}}]})
    };
    let compiled = Scene::from_json(doc(json!([0])).to_string().as_bytes()).unwrap().compile();
    let pins = &compiled.config.pin_motions[0];
    assert_eq!((pins.particles.as_slice(), pins.centre), ([0].as_slice(), DVec3::new(1.0, 1.0, 0.0)));
    let error = Scene::from_json(doc(json!([])).to_string().as_bytes()).unwrap_err();
    let pointers: Vec<&str> = error.field_errors().iter().map(|e| e.pointer.as_str()).collect();
    assert_eq!(pointers, ["/bodies/0/pin_motion"]);
}
