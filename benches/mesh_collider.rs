//! What a mesh collider costs: a step of the performance peers' 128 × 128 cloth (see `step.rs`)
//! resting on a 20,000-triangle sheet, against the same step with no collider and with the
//! analytic floor, for symplectic Euler and implicit Euler in `f32`; and the building of the
//! hierarchy over 100,000 triangles, alone and with the rest of the collider (the topology that
//! finds whether it is closed). `docs/performance.md` has the figures.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;

use drape::solver::{
    Chain, Cloth, Collider, Config, DEFAULT_FRICTION, IntegratorKind, Model, Shape, Simulation, SpringParams,
    TriangleBvh, TriangleSurface, Vec3, parallel,
};

const THICKNESS: f64 = 0.005;

/// A flat square sheet of `2 n²` triangles, 2 m wide, in the plane y = 0.
fn sheet(n: u32) -> TriangleSurface {
    let step = 2.0 / n as f64;
    let vertices = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| DVec3::new(i as f64 * step - 1.0, 0.0, j as f64 * step - 1.0)))
        .collect();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let triangles = (0..n)
        .flat_map(|j| {
            (0..n).flat_map(move |i| {
                [[at(i, j), at(i, j + 1), at(i + 1, j)], [at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]]
            })
        })
        .collect();
    TriangleSurface { vertices, triangles }
}

/// The peers' cloth, 1 m², 1 kg, lying on the sheet at the collider's thickness.
fn cloth() -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth { center: DVec3::new(0.0, THICKNESS, 0.0), ..Cloth::square_metre(128, springs) });
    model
}

fn config(integrator: IntegratorKind, floor: Option<Shape>) -> Config {
    Config {
        integrator,
        dt: if integrator == IntegratorKind::ImplicitEuler { 1.0 / 600.0 } else { 1.25e-5 },
        drag: 0.01 * (128 * 128) as f64,
        colliders: floor
            .into_iter()
            .map(|shape| Collider { shape, friction: DEFAULT_FRICTION, restitution: 0.0, motion: None })
            .collect(),
        ..Config::default()
    }
}

fn steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("mesh_collider");
    let mesh = Shape::Mesh { surface: Arc::new(sheet(100)), thickness: THICKNESS };
    let plane = Shape::Plane { point: DVec3::new(0.0, THICKNESS, 0.0), normal: DVec3::Y };
    for (integrator, name) in [
        (IntegratorKind::SymplecticEuler, "symplectic_euler"),
        (IntegratorKind::ImplicitEuler, "implicit_euler"),
    ] {
        for (floor, label) in
            [(None, "none"), (Some(plane.clone()), "plane"), (Some(mesh.clone()), "mesh20k")]
        {
            let mut sim = Simulation::<f32>::new(&cloth(), &config(integrator, floor));
            group.bench_function(format!("cloth128/{name}/{label}"), |b| {
                b.iter_custom(|iterations| {
                    parallel::install(|| {
                        let start = Instant::now();
                        for _ in 0..iterations {
                            sim.step().expect("the resting cloth stays stable");
                        }
                        start.elapsed()
                    })
                })
            });
        }
    }
    group.finish();
}

fn builds(c: &mut Criterion) {
    let mut group = c.benchmark_group("mesh_collider_build");
    // 224² quads: 100,352 triangles.
    let surface = sheet(224);
    let corners: Vec<[Vec3<f32>; 3]> =
        surface.triangles.iter().map(|t| t.map(|i| Vec3::from_dvec3(surface.vertices[i as usize]))).collect();
    group.bench_function("bvh100k/f32", |b| b.iter(|| TriangleBvh::new(&corners)));
    let mut two = Model::default();
    two.add_chain(&Chain {
        start: DVec3::new(0.0, 1.0, 0.0),
        end: DVec3::new(0.1, 1.0, 0.0),
        count: 2,
        mass: 0.1,
        velocity: DVec3::ZERO,
        spring: SpringParams { stiffness: 100.0, damping: 0.0 },
        rest_length: None,
        pins: Vec::new(),
    });
    let shape = Shape::Mesh { surface: Arc::new(surface), thickness: THICKNESS };
    let config = config(IntegratorKind::SymplecticEuler, Some(shape));
    group.bench_function("collider100k/f32", |b| b.iter(|| Simulation::<f32>::new(&two, &config)));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = steps, builds
}
criterion_main!(benches);
