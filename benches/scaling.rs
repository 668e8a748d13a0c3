//! How a step's cost grows with the particle count when contacts and self-collision are on: the
//! performance peers' cloth (see `step.rs`) falling onto a sphere and the floor, with
//! self-collision, at N = 32, 64, 128 and 256, symplectic Euler in `f32`. Linear cost shows as
//! a constant time per particle; `docs/performance.md` has the table.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;

use drape::solver::{
    Cloth, Collider, Config, DEFAULT_FRICTION, IntegratorKind, Model, Shape, Simulation, SpringParams,
    parallel,
};

/// The peers' cloth, 1 m², 1 kg, every spring at k = 5000 N/m and damping 0.5 N·s/m, held flat
/// 0.3 m above a sphere (nothing pinned), so that it drapes over it.
fn cloth(n: usize) -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth {
        center: DVec3::new(0.0, 0.6, 0.0),
        velocity: DVec3::new(0.0, -1.0, 0.0),
        ..Cloth::square_metre(n, springs)
    });
    model
}

fn config(n: usize) -> Config {
    let collider = |shape| Collider { shape, friction: DEFAULT_FRICTION, restitution: 0.0, motion: None };
    Config {
        integrator: IntegratorKind::SymplecticEuler,
        dt: match n {
            32 => 1e-4,
            64 => 5e-5,
            128 => 1.25e-5,
            _ => 3.125e-6,
        },
        drag: 0.01 * (n * n) as f64,
        colliders: vec![
            collider(Shape::Sphere { center: DVec3::new(0.0, 0.0, 0.0), radius: 0.25 }),
            collider(Shape::Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        ],
        self_collision: Some(0.25 / (n - 1) as f64),
        ..Config::default()
    }
}

fn scaling(c: &mut Criterion) {
    let mut group = c.benchmark_group("contacts");
    for n in [32, 64, 128, 256] {
        let mut sim = Simulation::<f32>::new(&cloth(n), &config(n));
        // Into contact first: 0.35 s of fall at the smallest size's pace.
        let settle = (0.35 / sim.dt()).min(4_000.0) as usize;
        parallel::install(|| (0..settle).for_each(|_| sim.step().expect("the draping cloth stays stable")));
        group.throughput(Throughput::Elements((n * n) as u64));
        group.bench_function(format!("cloth{n}/symplectic_euler/f32"), |b| {
            b.iter_custom(|iterations| {
                parallel::install(|| {
                    let start = Instant::now();
                    for _ in 0..iterations {
                        sim.step().expect("the draping cloth stays stable");
                    }
                    start.elapsed()
                })
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = scaling
}
criterion_main!(benches);
