//! A disk cloth in the scene contract: its defaults, its counts before building, its errors, and
//! when a scene is a drape tester.

use serde_json::{Value, json};

use crate::scene::{Body, ClothShape, DrapeTester, Scene, SceneError};

fn scene(value: Value) -> Result<Scene, SceneError> {
    Scene::from_json(value.to_string().as_bytes())
}

fn with_body(body: Value) -> Value {
    json!({"duration": 1.0, "bodies": [body]})
}

fn pointers(value: Value) -> Vec<String> {
    match scene(value) {
        Err(SceneError::Invalid(errors)) => errors.into_iter().map(|e| e.pointer).collect(),
        other => panic!("expected field errors, got {other:?}"),
    }
}

#[test]
fn a_disk_takes_the_cloth_defaults_and_a_metre_diameter() {
    let s = scene(with_body(json!({"type": "cloth", "shape": "disk"}))).unwrap();
    let Body::Cloth(c) = &s.bodies[0] else { panic!("not a cloth") };
    assert_eq!((c.shape, c.disk_diameter(), c.disk_rings()), (ClothShape::Disk, 1.0, 16));
    let compiled = s.compile();
    let p = &compiled.model.positions;
    let radius = p.iter().map(|q| (q.x.powi(2) + (q.z).powi(2)).sqrt()).fold(0.0, f64::max);
    assert!((radius - 0.5).abs() < 1e-15);
    assert!(p.iter().all(|q| q.y == 1.0));
    assert!(compiled.model.grids.is_empty(), "a disk runs through the spring list");
}

/// `particle_count` and `spring_count` are exact for a disk, odd and even `n` alike.
#[test]
fn counts_are_exact_before_building() {
    for n in [2, 3, 4, 9, 30, 31] {
        let s = scene(with_body(json!({"type": "cloth", "shape": "disk", "resolution": [n, n]}))).unwrap();
        let compiled = s.compile();
        assert_eq!(s.bodies[0].particle_count(), compiled.model.particle_count() as u64, "n = {n}");
        assert_eq!(s.bodies[0].spring_count(), compiled.model.springs.len() as u64, "n = {n}");
        // A diameter carries n particles, or n + 1 for even n: the centre and two per ring.
        let mut radii: Vec<f64> = compiled.model.positions.iter().map(|q| q.x.hypot(q.z)).collect();
        radii.sort_by(f64::total_cmp);
        radii.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        assert_eq!(2 * radii.len() - 1, if n % 2 == 1 { n } else { n + 1 }, "n = {n}");
    }
}

#[test]
fn each_bad_disk_field_is_named_by_its_pointer() {
    let disk = |extra: Value| {
        let mut body = json!({"type": "cloth", "shape": "disk", "resolution": [7, 7]});
        body.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
        with_body(body)
    };
    let cases: Vec<(Value, &[&str])> = vec![
        (disk(json!({"shape": "hexagon"})), &["/bodies/0/shape"]),
        (disk(json!({"diameter": 0})), &["/bodies/0/diameter"]),
        (disk(json!({"diameter": 2e6})), &["/bodies/0/diameter"]),
        (disk(json!({"diameter": "wide"})), &["/bodies/0/diameter"]),
        (disk(json!({"resolution": [7, 9]})), &["/bodies/0/resolution/1"]),
        (disk(json!({"resolution": [1, 1]})), &["/bodies/0/resolution/0", "/bodies/0/resolution/1"]),
        (disk(json!({"pin": [[0, 0], [4, 0]]})), &["/bodies/0/pin/1/0"]),
        (disk(json!({"pin": [[0, 1]]})), &["/bodies/0/pin/0/1"]),
        (disk(json!({"pin": [[3, 18]]})), &["/bodies/0/pin/0/1"]),
        (with_body(json!({"type": "cloth", "diameter": 0.3})), &["/bodies/0/diameter"]),
    ];
    for (doc, expected) in cases {
        assert_eq!(pointers(doc.clone()), *expected, "{doc}");
    }
    let pinned = scene(disk(json!({"pin": [[0, 0], [3, 17]]}))).unwrap().compile();
    let pinned: Vec<usize> = (0..pinned.model.particle_count()).filter(|&i| pinned.model.pinned[i]).collect();
    assert_eq!(pinned, [0, 36]);
}

fn tester_scene(bodies: Value, colliders: Value) -> Option<DrapeTester> {
    scene(json!({"duration": 1.0, "bodies": bodies, "colliders": colliders})).unwrap().compile().drape_tester
}

#[test]
fn a_drape_tester_is_one_disk_cloth_on_one_smaller_cylinder() {
    let specimen = json!({"type": "cloth", "shape": "disk", "diameter": 0.3, "resolution": [9, 9]});
    let support = json!({"type": "cylinder", "center": [0.02, 0.4, 0.01], "radius": 0.09, "height": 0.2});
    let chain = json!({"type": "chain"});
    let tester = tester_scene(json!([chain, specimen]), json!([support])).expect("a tester");
    // The chain has no triangles; the specimen's are all the model's.
    assert_eq!(tester.triangles, 0..6 * 16);
    assert_eq!((tester.support_center, tester.support_radius), ([0.02, 0.01], 0.09));
    let polygon = 0.5 * 24.0 * 0.15f64.powi(2) * (std::f64::consts::TAU / 24.0).sin();
    assert!((tester.specimen_area - polygon).abs() < 1e-15);

    let floor = json!({"type": "plane"});
    let rectangle = json!({"type": "cloth"});
    let wide = json!({"type": "cylinder", "center": [0, 0.4, 0], "radius": 0.15, "height": 0.2});
    assert_eq!(tester_scene(json!([specimen]), json!([support, floor])), None);
    assert_eq!(tester_scene(json!([specimen]), json!([])), None);
    assert_eq!(tester_scene(json!([specimen, specimen]), json!([support])), None);
    assert_eq!(tester_scene(json!([rectangle]), json!([support])), None);
    assert_eq!(tester_scene(json!([specimen]), json!([wide])), None);
    assert!(tester_scene(json!([rectangle, specimen]), json!([support])).is_some());
}
