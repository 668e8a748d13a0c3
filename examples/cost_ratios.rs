//! Measures two cost ratios of the performance peers' hanging cloth at N = 32, 64, 128 and 256:
//! an RK4 step against a symplectic Euler step (in `f32`), and an `f64` symplectic step against
//! an `f32` one.
//!
//! ```sh
//! cargo run --release --example cost_ratios [-- BURSTS]
//! ```
//!
//! On a shared machine whose speed drifts by tens of percent over minutes, two benchmarks run one
//! after the other can disagree on a ratio by more than the ratio's own margin. Here both
//! simulations live in one process and take turns in short bursts of about the same wall time
//! (by default 41 pairs of bursts per size), and each pair gives a ratio; the median of those
//! ratios is reported with its quartiles. A drift slower than a pair of bursts cancels out.
//! Both run inside the solver's pool, as a run does.

use std::time::Instant;

use drape::solver::{
    Cloth, Config, IntegratorKind, IntegratorSettings, Model, Real, Simulation, SpringParams, parallel,
};
use glam::DVec3;

/// The peers' cloth at `n × n` with the peers' explicit step, compiled for `integrator`.
fn cloth<T: Real>(n: usize, integrator: IntegratorKind) -> Simulation<T> {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth { pins: vec![[0, 0], [n - 1, 0]], ..Cloth::square_metre(n, springs) });
    let dt = match n {
        32 => 1e-4,
        64 => 5e-5,
        128 => 1.25e-5,
        _ => 3.125e-6,
    };
    let config = Config {
        integrator,
        settings: IntegratorSettings::default(),
        dt,
        gravity: DVec3::new(0.0, -9.81, 0.0),
        drag: 0.01 * (n * n) as f64,
        ..Config::default()
    };
    Simulation::new(&model, &config)
}

/// Seconds per step of `steps` steps.
fn time_steps<T: Real>(simulation: &mut Simulation<T>, steps: usize) -> f64 {
    let start = Instant::now();
    for _ in 0..steps {
        simulation.step().expect("the peers' cloth is stable at the peers' step");
    }
    start.elapsed().as_secs_f64() / steps as f64
}

/// The median and quartiles of the cost of a step of `b` over one of `a`, in `bursts` pairs of
/// bursts; `a` takes `steps` steps a burst and `b` `steps / b_per_a` (one burst of each about the
/// same wall time).
fn ratio<A: Real, B: Real>(
    a: &mut Simulation<A>,
    b: &mut Simulation<B>,
    steps: usize,
    b_per_a: usize,
    bursts: usize,
) -> [f64; 3] {
    let mut ratios: Vec<f64> = parallel::install(|| {
        (0..bursts).map(|_| time_steps(b, (steps / b_per_a).max(1)) / time_steps(a, steps)).collect()
    });
    ratios.sort_by(f64::total_cmp);
    [ratios[bursts / 4], ratios[bursts / 2], ratios[3 * bursts / 4]]
}

fn main() {
    let bursts: usize = std::env::args().nth(1).map_or(41, |b| b.parse().expect("BURSTS is a count"));
    println!("| N | RK4 / symplectic Euler (f32) | f64 / f32 (symplectic Euler), cost | f64 / f32, speed |");
    println!("| --- | --- | --- | --- |");
    for n in [32, 64, 128, 256] {
        // 2.4 million particle-steps of symplectic Euler per burst at every size: short against
        // the machine's drift, long against the clock's resolution.
        let steps = 2_400_000 / (n * n);
        let mut symplectic = cloth::<f32>(n, IntegratorKind::SymplecticEuler);
        let mut rk4 = cloth::<f32>(n, IntegratorKind::Rk4);
        let mut symplectic_f64 = cloth::<f64>(n, IntegratorKind::SymplecticEuler);
        let [rk4_low, rk4_median, rk4_high] = ratio(&mut symplectic, &mut rk4, steps, 4, bursts);
        let [f64_low, f64_median, f64_high] = ratio(&mut symplectic, &mut symplectic_f64, steps, 2, bursts);
        println!(
            "| {n} | {rk4_median:.2} ({rk4_low:.2}-{rk4_high:.2}) | {f64_median:.2} ({f64_low:.2}-{f64_high:.2}) | {:.2} |",
            1.0 / f64_median
        );
    }
}
