//! One step of a 128×128 cloth with structural, shear and bending springs, for symplectic and
//! implicit Euler in f32 and f64.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;

use drape::solver::{
    Cloth, Config, IntegratorKind, IntegratorSettings, Model, Orientation, Real, Simulation, SpringParams,
};

/// The hanging cloth of the performance peers: 1 m², 1 kg, every spring at k = 5000 N/m and
/// damping 0.5 N·s/m, two corners pinned.
fn cloth(n: usize) -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth {
        size: [1.0, 1.0],
        resolution: [n, n],
        center: DVec3::new(0.5, 1.0, 0.5),
        orientation: Orientation::Horizontal,
        mass: 1.0,
        velocity: DVec3::ZERO,
        structural: springs,
        shear: springs,
        bending: springs,
        pins: vec![[0, 0], [n - 1, 0]],
    });
    model
}

fn bench_step<T: Real>(c: &mut Criterion, integrator: IntegratorKind, dt: f64) {
    let n = 128;
    let model = cloth(n);
    let config = Config {
        integrator,
        settings: IntegratorSettings::default(),
        dt,
        gravity: DVec3::new(0.0, -9.81, 0.0),
        drag: 0.01 * (n * n) as f64,
        ..Config::default()
    };
    let mut sim = Simulation::<T>::new(&model, &config);
    c.bench_function(&format!("step/cloth{n}/{}/{}", integrator.name(), T::NAME), |b| {
        b.iter(|| sim.step().expect("the benchmark cloth stays stable"))
    });
}

fn steps(c: &mut Criterion) {
    bench_step::<f32>(c, IntegratorKind::SymplecticEuler, 1.25e-5);
    bench_step::<f64>(c, IntegratorKind::SymplecticEuler, 1.25e-5);
    bench_step::<f32>(c, IntegratorKind::ImplicitEuler, 1.0 / 600.0);
    bench_step::<f64>(c, IntegratorKind::ImplicitEuler, 1.0 / 600.0);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(std::time::Duration::from_secs(4));
    targets = steps
}
criterion_main!(benches);
