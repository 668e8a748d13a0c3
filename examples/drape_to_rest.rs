//! Drapes a 64×64 cloth to rest with implicit Euler at a large step and with symplectic Euler at
//! its largest stable step, and compares wall times and final shapes.
//!
//! ```sh
//! cargo run --release --example drape_to_rest [-- IMPLICIT_DT]
//! ```
//!
//! The scene is the performance peers' hanging cloth at 64² (1 m², 1 kg, every spring at
//! k = 5000 N/m and 0.5 N·s/m, drag 0.01·64² 1/s), released flat with two corners pinned. It
//! has no contacts and no friction, so its rest shape is the static equilibrium of gravity and
//! springs, which does not depend on the integrator or the path: two runs that both come to rest
//! must agree on it, and a difference in shape is an error of one of them, not a different but
//! equally valid fold. (A cloth draped over a sphere settles into folds that friction and
//! the path decide, so there the comparison would measure chance as much as accuracy.)
//!
//! A run is at rest when every particle moves slower than 1 mm/s; the check runs once per
//! simulated millisecond (every step at steps of a millisecond and more) and is timed with it.

use std::time::{Duration, Instant};

use drape::solver::{
    Cloth, Config, IntegratorKind, IntegratorSettings, Model, Orientation, Real, Simulation, SpringParams, State,
};
use glam::DVec3;

/// Every particle slower than this is at rest, in m/s.
const REST_SPEED: f64 = 1e-3;
/// A run that has not come to rest after this much simulated time is reported as such.
const MAX_SIMULATED: f64 = 60.0;
const N: usize = 64;

fn cloth() -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth {
        size: [1.0, 1.0],
        resolution: [N, N],
        center: DVec3::new(0.5, 1.0, 0.5),
        orientation: Orientation::Horizontal,
        mass: 1.0,
        velocity: DVec3::ZERO,
        structural: springs,
        shear: springs,
        bending: springs,
        pins: vec![[0, 0], [N - 1, 0]],
    });
    model
}

fn config(integrator: IntegratorKind, dt: f64) -> Config {
    Config {
        integrator,
        settings: IntegratorSettings::default(),
        dt,
        gravity: DVec3::new(0.0, -9.81, 0.0),
        drag: 0.01 * (N * N) as f64,
        ..Config::default()
    }
}

fn max_speed<T: Real>(state: &State<T>) -> f64 {
    state.velocities.iter().map(|v| v.to_dvec3().length()).fold(0.0, f64::max)
}

fn positions<T: Real>(state: &State<T>) -> Vec<DVec3> {
    state.positions.iter().map(|p| p.to_dvec3()).collect()
}

/// One run to rest.
struct Run {
    name: String,
    dt: f64,
    steps: u64,
    simulated: f64,
    wall: Duration,
    at_rest: bool,
    final_speed: f64,
    positions: Vec<DVec3>,
    iterations: Option<(f64, usize)>,
}

fn run_to_rest(name: &str, integrator: IntegratorKind, dt: f64) -> Run {
    let model = cloth();
    let mut sim = Simulation::<f64>::new(&model, &config(integrator, dt));
    let check_every = ((1e-3 / dt).round() as u64).max(1);
    let start = Instant::now();
    let mut at_rest = false;
    while sim.time() < MAX_SIMULATED {
        if let Err(divergence) = sim.step() {
            panic!("{name} at dt = {dt:e} s diverged: {divergence:?}");
        }
        if sim.steps_taken() % check_every == 0 && max_speed(sim.state()) < REST_SPEED {
            at_rest = true;
            break;
        }
    }
    let wall = start.elapsed();
    let iterations = sim
        .linear_solve_stats()
        .map(|s| (s.total_iterations as f64 / sim.steps_taken() as f64, s.most_iterations));
    Run {
        name: name.to_string(),
        dt,
        steps: sim.steps_taken(),
        simulated: sim.time(),
        wall,
        at_rest,
        final_speed: max_speed(sim.state()),
        positions: positions(sim.state()),
        iterations,
    }
}

fn main() {
    let implicit_dt = std::env::args().nth(1).map_or(Ok(1.0 / 60.0), |a| a.parse::<f64>());
    let Ok(implicit_dt) = implicit_dt else {
        eprintln!("usage: drape_to_rest [IMPLICIT_DT]");
        std::process::exit(2);
    };
    let explicit_dt = Simulation::<f64>::new(&cloth(), &config(IntegratorKind::SymplecticEuler, 1e-5))
        .stable_dt()
        .expect("a cloth with springs has a stability bound");

    let implicit = run_to_rest("implicit Euler", IntegratorKind::ImplicitEuler, implicit_dt);
    let explicit = run_to_rest("symplectic Euler", IntegratorKind::SymplecticEuler, explicit_dt);
    let distance = implicit
        .positions
        .iter()
        .zip(&explicit.positions)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);

    println!("64×64 peers' cloth (k = 5000 N/m, c = 0.5 N·s/m, drag 40.96 1/s), f64, to rest (every particle < 1 mm/s):\n");
    println!("| integrator | dt (s) | steps | simulated (s) | at rest | final max speed (m/s) | CG iterations per step (max) | wall time (s) |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for run in [&implicit, &explicit] {
        let iterations = run.iterations.map_or("–".to_string(), |(mean, most)| format!("{mean:.1} ({most})"));
        println!(
            "| {} | {:.3e} | {} | {:.3} | {} | {:.2e} | {} | {:.3} |",
            run.name,
            run.dt,
            run.steps,
            run.simulated,
            if run.at_rest { "yes" } else { "no" },
            run.final_speed,
            iterations,
            run.wall.as_secs_f64()
        );
    }
    println!("\nLargest distance between the two final shapes: {:.3} mm", distance * 1e3);
    println!(
        "Wall time, implicit / explicit: {:.3}",
        implicit.wall.as_secs_f64() / explicit.wall.as_secs_f64()
    );
}
