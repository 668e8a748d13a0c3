//! The scene contract for colliders, wind, self-collision and the strain limit: defaults, every
//! error at its JSON Pointer, and what the scene compiles to.

use drape::scene::{ColliderSpec, Scene, WindModelName};
use drape::solver::{Shape, WindModel};
use glam::DVec3;

const CLOTH: &str = r#"[{"type": "cloth", "resolution": [4, 4]}]"#;

fn with(extra: &str) -> String {
    format!(r#"{{"duration": 0.1, "bodies": {CLOTH}, {extra}}}"#)
}

fn errors(extra: &str) -> Vec<(String, String)> {
    match Scene::from_json(with(extra).as_bytes()) {
        Ok(_) => panic!("accepted: {extra}"),
        Err(e) => e.field_errors().iter().map(|f| (f.pointer.clone(), f.detail.clone())).collect(),
    }
}

fn pointers(extra: &str) -> Vec<String> {
    errors(extra).into_iter().map(|(p, _)| p).collect()
}

#[test]
fn defaults_fill_in_friction_restitution_the_floor_and_the_gust() {
    let scene = Scene::from_json(
        with(
            r#""colliders": [{"type": "plane"}, {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.3, "restitution": 0.5}],
               "wind": {"velocity": [1, 0, 0], "gust": {}}, "self_collision": {}, "strain_limit": 0.1"#,
        )
        .as_bytes(),
    )
    .unwrap();
    let ColliderSpec::Plane(plane) = &scene.colliders[0] else { panic!("{:?}", scene.colliders[0]) };
    assert_eq!(
        (plane.point, plane.normal, plane.friction, plane.restitution),
        ([0.0; 3], [0.0, 1.0, 0.0], 0.3, 0.0)
    );
    assert_eq!(scene.colliders[1].surface(), (0.3, 0.5));
    let wind = scene.wind.unwrap();
    assert_eq!((wind.model, wind.coefficient), (WindModelName::Aerodynamic, 1.0));
    let gust = wind.gust.unwrap();
    assert_eq!((gust.amplitude, gust.frequency, gust.wavelength), (0.5, 1.0, 2.0));
    assert_eq!(scene.self_collision.unwrap().thickness, 0.005);

    let compiled = scene.compile();
    let config = &compiled.config;
    assert_eq!(config.colliders[0].shape, Shape::Plane { point: DVec3::ZERO, normal: DVec3::Y });
    assert_eq!(config.colliders[1].shape, Shape::Sphere { center: DVec3::new(0.0, 0.5, 0.0), radius: 0.3 });
    assert_eq!(config.colliders[1].restitution, 0.5);
    assert_eq!(config.wind.unwrap().model, WindModel::Aerodynamic);
    assert_eq!(config.strain_limit, Some(0.1));
    assert_eq!(config.self_collision, Some(0.005));
}

#[test]
fn a_scene_without_them_compiles_to_none_of_them() {
    let compiled =
        Scene::from_json(format!(r#"{{"duration": 0.1, "bodies": {CLOTH}}}"#).as_bytes()).unwrap().compile();
    let config = &compiled.config;
    assert!(config.colliders.is_empty() && config.wind.is_none());
    assert!(config.strain_limit.is_none() && config.self_collision.is_none());
}

#[test]
fn collider_type_errors_point_into_the_collider() {
    assert_eq!(
        errors(r#""colliders": [{"type": "plane"}, {"type": "cone"}]"#),
        [(
            "/colliders/1/type".to_string(),
            "unknown collider type `cone`: expected `plane`, `sphere`, `box`, `cylinder` or `mesh`"
                .to_string()
        )]
    );
    assert_eq!(pointers(r#""colliders": [{"center": [0, 0, 0]}]"#), ["/colliders/0/type"]);
    assert_eq!(pointers(r#""colliders": [7]"#), ["/colliders/0"]);
    assert_eq!(
        pointers(r#""colliders": [{"type": "sphere", "center": [0, 0, 0]}]"#),
        ["/colliders/0/radius"]
    );
    assert_eq!(
        pointers(r#""colliders": [{"type": "box", "center": [0, 0, 0], "half_extents": [1, "a", 1]}]"#),
        ["/colliders/0/half_extents/1"]
    );
    assert_eq!(pointers(r#""wind": {"velocity": [1, 0, 0], "model": "breeze"}"#), ["/wind/model"]);
}

#[test]
fn every_bad_number_is_named_by_its_pointer() {
    let found = pointers(
        r#""colliders": [
            {"type": "plane", "normal": [0, 0, 0]},
            {"type": "sphere", "center": [0, 0, 0], "radius": -1, "restitution": 1.5},
            {"type": "box", "center": [0, 0, 0], "half_extents": [1, 1, 0], "friction": -0.1},
            {"type": "cylinder", "center": [0, 0, 0], "radius": 0.5, "height": 0}
        ],
        "wind": {"velocity": [1, 0, 0], "coefficient": -1, "gust": {"amplitude": 2, "frequency": -1, "wavelength": 0}},
        "self_collision": {"thickness": 0},
        "strain_limit": -0.1"#,
    );
    assert_eq!(
        found,
        [
            "/colliders/0/normal",
            "/colliders/1/radius",
            "/colliders/1/restitution",
            "/colliders/2/half_extents/2",
            "/colliders/2/friction",
            "/colliders/3/height",
            "/wind/coefficient",
            "/wind/gust/amplitude",
            "/wind/gust/frequency",
            "/wind/gust/wavelength",
            "/self_collision/thickness",
            "/strain_limit",
        ]
    );
}
