//! Self-collision cost against particle count: one pass (hash build and pair resolution) over a
//! cloth of n × n particles folded onto itself, so that every particle of the top layer lies
//! within the collision distance of one below it. Linear cost shows as a constant time per
//! particle from 32² to 128². The passes run inside the solver's pool, as a run's steps do.

use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput};
use drape::solver::{Cloth, Model, Orientation, SelfCollision, SpringParams, State, Vec3, Vectors, parallel};
use glam::DVec3;

/// A 1 m cloth of n × n particles folded in half along x = 0, the two layers 1.6 thickness apart.
fn folded_cloth(n: usize) -> (Model, State<f64>, f64) {
    let mut model = Model::default();
    let springs = SpringParams { stiffness: 1000.0, damping: 0.1 };
    model.add_cloth(&Cloth {
        size: [1.0, 1.0],
        resolution: [n, n],
        center: DVec3::ZERO,
        orientation: Orientation::Horizontal,
        mass: 0.5,
        velocity: DVec3::ZERO,
        structural: springs,
        shear: springs,
        bending: springs,
        pins: Vec::new(),
    });
    let thickness = 0.25 / (n - 1) as f64;
    let positions = model
        .positions
        .iter()
        .map(|p| {
            let folded = if p.x > 0.0 { DVec3::new(-p.x, 1.6 * thickness, p.z) } else { *p };
            Vec3::from_dvec3(folded)
        })
        .collect();
    let state = State { positions, velocities: Vectors::zeros(model.particle_count()) };
    (model, state, thickness)
}

fn self_collision(c: &mut Criterion) {
    let mut group = c.benchmark_group("self_collision");
    for n in [32, 64, 128] {
        let (model, state, thickness) = folded_cloth(n);
        let inverse_masses = vec![1.0; model.particle_count()];
        let mut stage = SelfCollision::<f64>::new(&model, thickness, usize::MAX);
        group.throughput(Throughput::Elements((n * n) as u64));
        group.bench_with_input(BenchmarkId::from_parameter(format!("{n}x{n}")), &n, |b, _| {
            b.iter_custom(|iterations| {
                parallel::install(|| {
                    let mut elapsed = Duration::ZERO;
                    for _ in 0..iterations {
                        let mut folded = state.clone();
                        let start = Instant::now();
                        stage.resolve(&mut folded, &inverse_masses).expect("the stage has no cap");
                        elapsed += start.elapsed();
                    }
                    elapsed
                })
            })
        });
    }
    group.finish();
}

fn main() {
    let mut criterion = Criterion::default().configure_from_args();
    self_collision(&mut criterion);
    criterion.final_summary();
}
