//! Drapes a 64×64 cloth to rest with implicit Euler at a large step and with symplectic Euler at
//! its largest stable step, and compares wall times and final shapes.
//!
//! ```sh
//! cargo run --release --example drape_to_rest [-- IMPLICIT_DT [DRAG]]
//! ```
//!
//! The scene is the performance peers' cloth at 64² (1 m², 1 kg, every spring at k = 5000 N/m
//! and 0.5 N·s/m, drag 0.01·64² ≈ 41 1/s), released flat and pinned at its four corners, so
//! that it sags like a hammock. Pinned at four corners the cloth is in tension everywhere when it
//! rests, so it has one equilibrium, with no slack edge to fold one way or the other, and no
//! contact or friction makes the rest shape depend on the path: two runs that both come to rest
//! must agree on it, and a difference in shape is an error of one of them. A third run, implicit
//! Euler taken on until every particle is under 1e-7 m/s, gives that equilibrium, and the table
//! reports each run's largest distance from it. The drag overdamps the sag, so a run does not
//! pass under 1 mm/s at the turning point of a swing. (Pinned at two corners, as in the
//! benchmark, the slack top edge creeps for seconds, and two runs under 1 mm/s were 1.8 to
//! 3.2 mm apart; draped over a sphere, friction and the path decide the folds.)
//!
//! Implicit Euler's step is 1/240 s: at 1/60 and 1/120 s its numerical damping slows the last
//! creep so much that it is under 1 mm/s while still more than a millimetre from the
//! equilibrium; at 1/240 s it is 0.2 mm away when it comes to rest (`docs/performance.md`).
//!
//! A run is at rest when every particle moves slower than 1 mm/s; the check runs once per
//! simulated millisecond (every step at steps of a millisecond and more) and is timed with it.

use std::time::{Duration, Instant};

use drape::solver::{
    Cloth, Config, IntegratorKind, IntegratorSettings, Model, Real, Simulation, SpringParams, State,
};
use glam::DVec3;

/// Every particle slower than this is at rest, in m/s.
const REST_SPEED: f64 = 1e-3;
/// The equilibrium that both runs approach: a run taken on until every particle is slower than
/// this, in m/s.
const EQUILIBRIUM_SPEED: f64 = 1e-7;
/// A run that has not come to rest after this much simulated time is reported as such.
const MAX_SIMULATED: f64 = 60.0;
const N: usize = 64;

fn cloth() -> Model {
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    let pins = vec![[0, 0], [N - 1, 0], [0, N - 1], [N - 1, N - 1]];
    model.add_cloth(&Cloth { pins, ..Cloth::square_metre(N, springs) });
    model
}

fn config(integrator: IntegratorKind, dt: f64, drag: f64) -> Config {
    Config {
        integrator,
        settings: IntegratorSettings::default(),
        dt,
        gravity: DVec3::new(0.0, -9.81, 0.0),
        drag,
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

fn run_to_rest(name: &str, integrator: IntegratorKind, dt: f64, drag: f64) -> Run {
    run_until(name, integrator, dt, drag, REST_SPEED)
}

fn run_until(name: &str, integrator: IntegratorKind, dt: f64, drag: f64, rest_speed: f64) -> Run {
    let model = cloth();
    let mut sim = Simulation::<f64>::new(&model, &config(integrator, dt, drag));
    let check_every = ((1e-3 / dt).round() as u64).max(1);
    let start = Instant::now();
    let mut at_rest = false;
    while sim.time() < MAX_SIMULATED {
        if let Err(divergence) = sim.step() {
            panic!("{name} at dt = {dt:e} s diverged: {divergence:?}");
        }
        if sim.steps_taken().is_multiple_of(check_every) && max_speed(sim.state()) < rest_speed {
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
    let argument = |k: usize, default: f64| std::env::args().nth(k).map_or(Ok(default), |a| a.parse::<f64>());
    let (Ok(implicit_dt), Ok(drag)) = (argument(1, 1.0 / 240.0), argument(2, 0.01 * (N * N) as f64)) else {
        eprintln!("usage: drape_to_rest [IMPLICIT_DT [DRAG]]");
        std::process::exit(2);
    };
    let explicit_dt = Simulation::<f64>::new(&cloth(), &config(IntegratorKind::SymplecticEuler, 1e-5, drag))
        .stable_dt()
        .expect("a cloth with springs has a stability bound");

    let implicit = run_to_rest("implicit Euler", IntegratorKind::ImplicitEuler, implicit_dt, drag);
    let explicit = run_to_rest("symplectic Euler", IntegratorKind::SymplecticEuler, explicit_dt, drag);
    let equilibrium =
        run_until("equilibrium", IntegratorKind::ImplicitEuler, implicit_dt, drag, EQUILIBRIUM_SPEED);
    let distance = |a: &Run, b: &Run| {
        a.positions.iter().zip(&b.positions).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max)
    };

    println!(
        "64×64 cloth pinned at its four corners (k = 5000 N/m, c = 0.5 N·s/m, drag {drag} 1/s), f64, \
         to rest (every particle < 1 mm/s):\n"
    );
    println!(
        "| integrator | dt (s) | steps | simulated (s) | at rest | final max speed (m/s) | \
         CG iterations per step (max) | from the equilibrium (mm) | wall time (s) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for run in [&implicit, &explicit] {
        let iterations =
            run.iterations.map_or("–".to_string(), |(mean, most)| format!("{mean:.1} ({most})"));
        println!(
            "| {} | {:.3e} | {} | {:.3} | {} | {:.2e} | {} | {:.3} | {:.3} |",
            run.name,
            run.dt,
            run.steps,
            run.simulated,
            if run.at_rest { "yes" } else { "no" },
            run.final_speed,
            iterations,
            distance(run, &equilibrium) * 1e3,
            run.wall.as_secs_f64()
        );
    }
    println!(
        "\nLargest distance between the two final shapes: {:.3} mm. The equilibrium is implicit Euler \
         at the same step run on until every particle is under {EQUILIBRIUM_SPEED:e} m/s ({:.1} s simulated).",
        distance(&implicit, &explicit) * 1e3,
        equilibrium.simulated
    );
    println!(
        "Wall time, implicit / explicit: {:.3}",
        implicit.wall.as_secs_f64() / explicit.wall.as_secs_f64()
    );
}
