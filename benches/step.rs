//! One step of the performance peers' hanging cloth at N = 32, 64, 128 and 256, for symplectic
//! Euler, RK4 and implicit Euler in f32 and f64; and the same cloth given as a triangle mesh, whose
//! springs go through the general spring pass, for symplectic Euler; and the cloth as a fabric
//! bending by its bending elements, for symplectic Euler, RK4 and implicit Euler.
//!
//! Explicit integrators use the peers' step for each size (the largest power-of-two fraction of
//! 1e-4 s that is stable); implicit Euler uses 1/600 s. `docs/performance.md` has the figures.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;

use drape::solver::{
    Cloth, Config, Fabric, IntegratorKind, IntegratorSettings, Mesh, Model, Real, Simulation, SpringParams,
    parallel,
};

/// The hanging cloth of the performance peers: 1 m², 1 kg, every spring at k = 5000 N/m and
/// damping 0.5 N·s/m, two corners pinned.
fn cloth(n: usize) -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth { pins: vec![[0, 0], [n - 1, 0]], ..Cloth::square_metre(n, springs) });
    model
}

/// The peers' cloth as a `mesh` body: the cloth's vertices in row-major order and its triangles,
/// k = 5000 N/m and damping 0.5 N·s/m on edges and across shared edges, 1 kg, the same two
/// corners pinned. Its springs are not a grid, so they take the general spring pass.
fn mesh(n: usize) -> Model {
    let grid = cloth(n);
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_mesh(&Mesh {
        vertices: grid.positions,
        triangles: grid.triangles.iter().map(|t| t.map(|v| v as usize)).collect(),
        mass: 1.0,
        velocity: DVec3::ZERO,
        structural: springs,
        bending: springs,
        pins: vec![0, n - 1],
    });
    model
}

/// The peers' cloth as a fabric that bends by its bending elements instead of springs two apart:
/// 1 kg/m², the same structural and shear springs (k = 5000 N/m, damping 0.5 N·s/m: stretch
/// 10,000 N/m, shear 5,000 N/m, damping time 1e-4 s), bending rigidity 0.01 N·m.
fn fabric(n: usize) -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let fabric = Fabric { density: 1.0, stretch: 10_000.0, shear: 5000.0, bending: 0.01, damping_time: 1e-4 };
    let mut model = Model::default();
    model.add_fabric_cloth(
        &Cloth { pins: vec![[0, 0], [n - 1, 0]], ..Cloth::square_metre(n, springs) },
        &fabric,
    );
    model
}

/// The peers' explicit step for an `n × n` cloth.
fn explicit_dt(n: usize) -> f64 {
    match n {
        32 => 1e-4,
        64 => 5e-5,
        128 => 1.25e-5,
        _ => 3.125e-6,
    }
}

/// Benchmarks one step of `body(n)` (named `name` in the bench id) with `integrator`.
fn bench_body<T: Real>(
    c: &mut Criterion,
    name: &str,
    body: fn(usize) -> Model,
    n: usize,
    integrator: IntegratorKind,
) {
    let dt = match integrator {
        IntegratorKind::ImplicitEuler => 1.0 / 600.0,
        _ => explicit_dt(n),
    };
    let config = Config {
        integrator,
        settings: IntegratorSettings::default(),
        dt,
        gravity: DVec3::new(0.0, -9.81, 0.0),
        drag: 0.01 * (n * n) as f64,
        ..Config::default()
    };
    let mut sim = Simulation::<T>::new(&body(n), &config);
    // Steps run inside the solver's pool, as a run does, so that a large cloth's bands are shared
    // out to the pool's threads.
    c.bench_function(&format!("step/{name}{n}/{}/{}", integrator.name(), T::NAME), |b| {
        b.iter_custom(|iterations| {
            parallel::install(|| {
                let start = Instant::now();
                for _ in 0..iterations {
                    sim.step().expect("the benchmark body stays stable");
                }
                start.elapsed()
            })
        })
    });
}

fn steps(c: &mut Criterion) {
    for n in [32, 64, 128, 256] {
        for integrator in
            [IntegratorKind::SymplecticEuler, IntegratorKind::Rk4, IntegratorKind::ImplicitEuler]
        {
            bench_body::<f32>(c, "cloth", cloth, n, integrator);
            bench_body::<f64>(c, "cloth", cloth, n, integrator);
        }
        for integrator in
            [IntegratorKind::SymplecticEuler, IntegratorKind::Rk4, IntegratorKind::ImplicitEuler]
        {
            bench_body::<f32>(c, "fabric", fabric, n, integrator);
            bench_body::<f64>(c, "fabric", fabric, n, integrator);
        }
        bench_body::<f32>(c, "mesh", mesh, n, IntegratorKind::SymplecticEuler);
        bench_body::<f64>(c, "mesh", mesh, n, IntegratorKind::SymplecticEuler);
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = steps
}
criterion_main!(benches);
