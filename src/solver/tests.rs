//! Known-answer tests of the solver core: closed-form oscillators, convergence orders, energy
//! behaviour, stability limits, a hanging chain in equilibrium, stiff and degenerate springs, and
//! a pinned cloth. Each runs through one small harness so that the cases read as data.

use glam::DVec3;

use super::*;

const K: f64 = 100.0;
const MASS: f64 = 1.0;
const OMEGA: f64 = 10.0; // sqrt(K / MASS)
const AMPLITUDE: f64 = 0.1;
const REST: f64 = 1.0;

/// A pinned anchor at the origin and a moving mass of 1 kg on a spring of k = 100 N/m, rest
/// length 1 m, released from rest `AMPLITUDE` beyond rest along x. No gravity.
fn single_spring(damping: f64) -> Model {
    spring_of_rest_length(REST, damping)
}

/// The single spring with another rest length. A long one keeps the motion linear however far
/// an instability swings it, where a short one lets the mass pass through its anchor.
fn spring_of_rest_length(rest: f64, damping: f64) -> Model {
    let mut model = Model::default();
    model.add_chain(&Chain {
        start: DVec3::ZERO,
        end: DVec3::new(rest + AMPLITUDE, 0.0, 0.0),
        count: 2,
        mass: 2.0 * MASS,
        velocity: DVec3::ZERO,
        spring: SpringParams { stiffness: K, damping },
        rest_length: Some(rest),
        pins: vec![0],
    });
    model
}

fn config(integrator: IntegratorKind, dt: f64) -> Config {
    Config {
        integrator,
        settings: IntegratorSettings { tolerance: 1e-12, ..IntegratorSettings::default() },
        dt,
        gravity: DVec3::ZERO,
        drag: 0.0,
        ..Config::default()
    }
}

/// Displacement and velocity of the damped oscillator `x'' + (c/m) x' + (k/m) x = 0` from
/// `x(0) = AMPLITUDE`, `v(0) = 0`.
fn closed_form(damping: f64, t: f64) -> (f64, f64) {
    let zeta = damping / (2.0 * (K * MASS).sqrt());
    let decay = zeta * OMEGA;
    if zeta < 1.0 {
        let wd = OMEGA * (1.0 - zeta * zeta).sqrt();
        let e = (-decay * t).exp();
        let x = AMPLITUDE * e * ((wd * t).cos() + decay / wd * (wd * t).sin());
        let v = -AMPLITUDE * e * OMEGA * OMEGA / wd * (wd * t).sin();
        (x, v)
    } else if zeta == 1.0 {
        let e = (-OMEGA * t).exp();
        (AMPLITUDE * (1.0 + OMEGA * t) * e, -AMPLITUDE * OMEGA * OMEGA * t * e)
    } else {
        let root = OMEGA * (zeta * zeta - 1.0).sqrt();
        let (r1, r2) = (-decay + root, -decay - root);
        let (e1, e2) = ((r1 * t).exp(), (r2 * t).exp());
        let x = AMPLITUDE * (r2 * e1 - r1 * e2) / (r2 - r1);
        let v = AMPLITUDE * r1 * r2 * (e1 - e2) / (r2 - r1);
        (x, v)
    }
}

/// Runs the single spring for `duration` and returns the moving mass's displacement and velocity.
fn run_spring<T: Real>(integrator: IntegratorKind, damping: f64, dt: f64, duration: f64) -> (f64, f64) {
    let mut sim = Simulation::<T>::new(&single_spring(damping), &config(integrator, dt));
    let steps = (duration / dt).round() as u64;
    for _ in 0..steps {
        sim.step().expect("the single spring is stable at these steps");
    }
    let state = sim.state();
    (state.positions.get(1).x.to_f64() - REST, state.velocities.get(1).x.to_f64())
}

/// The phase-space error at `t = 1 s` relative to the amplitude:
/// `|(x - x*, (v - v*)/ω)| / A`.
fn spring_error(integrator: IntegratorKind, damping: f64, dt: f64) -> f64 {
    let (x, v) = run_spring::<f64>(integrator, damping, dt, 1.0);
    let (xe, ve) = closed_form(damping, 1.0);
    (x - xe).hypot((v - ve) / OMEGA) / AMPLITUDE
}

use IntegratorKind::{ExplicitEuler, ImplicitEuler, Rk4, SymplecticEuler, Verlet};

/// The expected values are the closed form evaluated independently: `0.1 cos 10` undamped,
/// `0.1 · 11 e⁻¹⁰` at critical damping (c = 20), and the textbook under- and overdamped
/// solutions at c = 2 and c = 50.
#[test]
fn closed_form_matches_the_published_values() {
    for (damping, expected) in [
        (0.0, -0.08390715290764525),
        (2.0, -0.03368516805904134),
        (20.0, 4.993992273873334e-5),
        (50.0, 0.01296932143448004),
    ] {
        let (x, _) = closed_form(damping, 1.0);
        assert!((x - expected).abs() < 1e-15, "c = {damping}: {x} != {expected}");
    }
}

#[test]
fn rk4_follows_the_closed_form_at_every_damping() {
    for damping in [0.0, 2.0, 20.0, 50.0] {
        let (x, _) = run_spring::<f64>(Rk4, damping, 1e-4, 1.0);
        let (expected, _) = closed_form(damping, 1.0);
        assert!((x - expected).abs() < 1e-12, "c = {damping}: x(1) = {x}, closed form {expected}");
    }
}

/// The expected errors are each method's own update applied to `x'' = -ω² x` (a linear map)
/// for 1000 steps of `hω = 0.01`, against the closed form: for RK4 the leading term
/// `n (hω)⁵/120`, for implicit Euler the amplitude lost, `1 - (1 + (hω)²)^(-n/2)`; for Verlet and
/// symplectic Euler the map iterated.
#[test]
fn each_integrator_has_its_known_error_at_one_millisecond() {
    for (integrator, expected) in
        [(Rk4, 8.33e-10), (Verlet, 3.6e-5), (SymplecticEuler, 2.74e-3), (ImplicitEuler, 4.88e-2)]
    {
        let error = spring_error(integrator, 0.0, 1e-3);
        let ratio = error / expected;
        assert!(
            (0.95..=1.05).contains(&ratio),
            "{}: error {error:.4e}, expected {expected:.3e}",
            integrator.name()
        );
    }
}

#[test]
fn halving_the_step_shows_each_integrators_order() {
    for damping in [0.0, 2.0] {
        for integrator in IntegratorKind::ALL {
            let (coarse, fine) =
                (spring_error(integrator, damping, 2e-3), spring_error(integrator, damping, 1e-3));
            let order = (coarse / fine).log2();
            let expected = integrator.order() as f64;
            assert!(
                (order - expected).abs() <= 0.1,
                "{} at c = {damping}: observed order {order:.3}, expected {expected}",
                integrator.name()
            );
        }
    }
}

#[test]
fn symplectic_euler_keeps_energy_bounded_without_drift() {
    let dt = 0.01 / OMEGA;
    let mut sim = Simulation::<f64>::new(&single_spring(0.0), &config(SymplecticEuler, dt));
    let initial = sim.energy().total();
    let steps = 1_000_000;
    // Averages over a window of many periods, so that a window not ending on a whole period
    // biases the mean by less than the drift tolerance.
    let window = (200.0 * std::f64::consts::PI / (OMEGA * dt)).round() as usize;
    let (mut worst, mut first_period, mut last_period) = (0.0f64, 0.0, 0.0);
    for n in 0..steps {
        sim.step().unwrap();
        let deviation = sim.energy().total() / initial - 1.0;
        worst = worst.max(deviation.abs());
        if n < window {
            first_period += deviation / window as f64;
        }
        if n >= steps - window {
            last_period += deviation / window as f64;
        }
    }
    // Symplectic Euler conserves a modified energy exactly; the true energy swings about it by at
    // most `(hω/2) / (1 - hω/2)` of itself, 5.03e-3 at `hω = 0.01`.
    assert!(worst <= 5.1e-3, "energy strayed by {worst:.3e}");
    assert!(
        (last_period - first_period).abs() < 1e-6,
        "energy drifted from {first_period:.3e} to {last_period:.3e}"
    );
}

#[test]
fn explicit_euler_energy_grows_geometrically() {
    let h_omega = 0.01;
    let mut sim = Simulation::<f64>::new(&single_spring(0.0), &config(ExplicitEuler, h_omega / OMEGA));
    let initial = sim.energy().total();
    for n in 1..=20_000u32 {
        sim.step().unwrap();
        if n % 5_000 == 0 {
            let expected = (1.0 + h_omega * h_omega).powi(n as i32);
            let ratio = sim.energy().total() / initial;
            assert!(
                (ratio / expected - 1.0).abs() < 1e-9,
                "after {n} steps: grew {ratio}, expected {expected}"
            );
        }
    }
}

/// Steps until divergence or `steps`; returns the divergence, if any, and checks the state never
/// showed a non-finite value before it.
fn run_until_divergence(integrator: IntegratorKind, h_omega: f64, steps: u64) -> Option<Divergence> {
    let model = spring_of_rest_length(100.0, 0.0);
    let mut sim = Simulation::<f64>::new(&model, &config(integrator, h_omega / OMEGA));
    for _ in 0..steps {
        if let Err(error) = sim.step() {
            return error.divergence();
        }
        assert!(sim.state().positions.iter().all(|p| p.is_finite()));
    }
    None
}

#[test]
fn explicit_methods_hold_below_their_stability_limit_and_diverge_above() {
    let rk4_limit = 2.0 * std::f64::consts::SQRT_2;
    for (integrator, limit) in [(SymplecticEuler, 2.0), (Verlet, 2.0), (Rk4, rk4_limit)] {
        let below = run_until_divergence(integrator, 0.99 * limit, 100_000);
        assert_eq!(below, None, "{} diverged just below h·ω = {limit}", integrator.name());
        let above = run_until_divergence(integrator, 1.01 * limit, 100_000)
            .unwrap_or_else(|| panic!("{} held just above h·ω = {limit}", integrator.name()));
        assert!(above.step > 1 && above.time > 0.0);
        assert!(matches!(above.reason, DivergenceReason::EnergyRunaway { .. }), "{:?}", above.reason);
    }
}

#[test]
fn the_stability_bound_is_two_over_omega_without_damping() {
    let model = single_spring(0.0);
    let bound = stable_step(&model, 0.0).unwrap();
    // Gershgorin doubles the diagonal: ω̂² = 2k/m, so the bound is 2/ω̂ = √2/ω.
    assert!((bound - 2.0 / (2.0 * K / MASS).sqrt()).abs() < 1e-15);
    let damped = stable_step(&single_spring(2.0), 1.0).unwrap();
    let (c, w2) = (1.0 + 2.0 * 2.0 / MASS, 2.0 * K / MASS);
    assert!((damped - 4.0 / (c + (c * c + 4.0 * w2).sqrt())).abs() < 1e-15);
}

/// Ten particles of 10 g hang below a pinned one on springs of k = 100 N/m and rest 0.1 m.
fn hanging_chain(damping: f64) -> Model {
    let mut model = Model::default();
    model.add_chain(&Chain {
        start: DVec3::ZERO,
        end: DVec3::new(0.0, -1.0, 0.0),
        count: 11,
        mass: 0.11,
        velocity: DVec3::ZERO,
        spring: SpringParams { stiffness: 100.0, damping },
        rest_length: Some(0.1),
        pins: vec![0],
    });
    model
}

#[test]
fn a_settled_chain_carries_the_weight_below_each_link() {
    let config = Config {
        integrator: ImplicitEuler,
        settings: IntegratorSettings { tolerance: 1e-12, ..IntegratorSettings::default() },
        dt: 0.01,
        gravity: DVec3::new(0.0, -9.81, 0.0),
        drag: 0.0,
        ..Config::default()
    };
    let mut sim = Simulation::<f64>::new(&hanging_chain(0.5), &config);
    for _ in 0..3000 {
        sim.step().unwrap();
    }
    let x = &sim.state().positions;
    for link in 0..10 {
        let tension = 100.0 * ((x.get(link + 1) - x.get(link)).length() - 0.1);
        let weight_below = (10 - link) as f64 * 0.01 * 9.81;
        assert!((tension / weight_below - 1.0).abs() < 1e-6, "link {link}: {tension} N vs {weight_below} N");
    }
    let length: f64 = (0..10).map(|l| (x.get(l + 1) - x.get(l)).length()).sum();
    // Closed form: ten rest lengths of 0.1 m, each stretched by the weight below it over k,
    // `Σ i · 0.01 · 9.81 / 100` for i = 1..=10.
    assert!((length / 1.053955 - 1.0).abs() < 1e-6, "total length {length}");
}

#[test]
fn a_stiff_spring_diverges_explicitly_and_settles_implicitly() {
    let stiff = |integrator| {
        let mut model = Model::default();
        model.add_chain(&Chain {
            start: DVec3::ZERO,
            end: DVec3::new(0.0, -0.01, 0.0),
            count: 2,
            mass: 2e-4,
            velocity: DVec3::ZERO,
            spring: SpringParams { stiffness: 1e6, damping: 0.0 },
            rest_length: None,
            pins: vec![0],
        });
        let config = Config { gravity: DVec3::new(0.0, -9.81, 0.0), ..config(integrator, 1.0 / 60.0) };
        Simulation::<f64>::new(&model, &config)
    };
    for integrator in [ExplicitEuler, SymplecticEuler, Verlet, Rk4] {
        let mut sim = stiff(integrator);
        let divergence = (0..600).find_map(|_| sim.step().err().and_then(StepError::divergence));
        assert!(divergence.is_some(), "{} survived a step 1000× past its limit", integrator.name());
        let suggested = sim.stable_dt().unwrap();
        assert!(suggested < (1e-4f64 / 1e6).sqrt() * 2.0, "suggested dt {suggested}");
    }
    let mut sim = stiff(ImplicitEuler);
    for _ in 0..600 {
        sim.step().expect("implicit Euler is stable at any step");
    }
    let (x, v) = (sim.state().positions.get(1), sim.state().velocities.get(1));
    let sag = 1e-4 * 9.81 / 1e6;
    assert!((x.y + 0.01 + sag).abs() < 1e-12, "rests at {} instead of {}", x.y, -0.01 - sag);
    assert!(v.length() < 1e-9, "still moving at {} m/s", v.length());
}

#[test]
fn coincident_particles_on_a_spring_stay_finite() {
    for integrator in IntegratorKind::ALL {
        let mut model = Model::default();
        model.add_chain(&Chain {
            start: DVec3::new(0.0, 1.0, 0.0),
            end: DVec3::new(0.0, 1.0, 0.0),
            count: 3,
            mass: 0.3,
            velocity: DVec3::ZERO,
            spring: SpringParams { stiffness: 50.0, damping: 1.0 },
            rest_length: Some(0.1),
            pins: vec![],
        });
        let config = Config { gravity: DVec3::new(0.0, -9.81, 0.0), ..config(integrator, 1e-3) };
        let mut sim = Simulation::<f64>::new(&model, &config);
        for _ in 0..1000 {
            sim.step().unwrap();
        }
        let state = sim.state();
        assert!(
            state.positions.iter().chain(state.velocities.iter()).all(|p| p.is_finite()),
            "{}",
            integrator.name()
        );
        // With no direction to push along, the springs stay silent and the particles fall together.
        let fallen = 1.0 - 0.5 * 9.81 * 1.0;
        assert!(
            (state.positions.get(0).y - fallen).abs() < 0.01,
            "{}: y = {}",
            integrator.name(),
            state.positions.get(0).y
        );
    }
}

fn pinned_cloth() -> Model {
    let mut model = Model::default();
    let springs = |stiffness, damping| SpringParams { stiffness, damping };
    model.add_cloth(&Cloth {
        size: [1.0, 1.0],
        resolution: [32, 32],
        center: DVec3::new(0.0, 1.0, 0.0),
        orientation: Orientation::Horizontal,
        mass: 0.5,
        velocity: DVec3::ZERO,
        structural: springs(5000.0, 0.5),
        shear: springs(500.0, 0.2),
        bending: springs(50.0, 0.1),
        pins: vec![[0, 0], [31, 0]],
    });
    model
}

fn cloth_run<T: Real>(integrator: IntegratorKind, dt: f64, steps: usize) -> (Vectors<T>, Vec<f64>) {
    let model = pinned_cloth();
    let config = Config { gravity: DVec3::new(0.0, -9.81, 0.0), drag: 0.05, ..config(integrator, dt) };
    let mut sim = Simulation::<T>::new(&model, &config);
    let mut energies = vec![sim.energy().total()];
    for n in 1..=steps {
        sim.step().unwrap();
        if n % 100 == 0 {
            energies.push(sim.energy().total());
        }
    }
    for &corner in &[0usize, 31] {
        assert_eq!(
            sim.state().positions.get(corner),
            Vec3::from_dvec3(model.positions[corner]),
            "corner moved"
        );
    }
    (sim.state().positions.clone(), energies)
}

#[test]
fn a_cloth_released_flat_never_stores_a_subnormal_velocity() {
    // On a 65 × 65 grid the particles sit at exact binary fractions, so the cloth starts at exact
    // rest and its motion spreads from the pins: without flushing, the velocities ahead of that
    // front run down through the subnormal numbers within 300 steps.
    let mut model = Model::default();
    let params = SpringParams { stiffness: 5000.0, damping: 0.5 };
    model.add_cloth(&Cloth { pins: vec![[0, 0], [64, 0]], ..Cloth::square_metre(65, params) });
    // Explicit Euler diverges on this cloth at any step that shows the effect.
    for integrator in [SymplecticEuler, Verlet, Rk4, ImplicitEuler] {
        let gravity = DVec3::new(0.0, -9.81, 0.0);
        let config = Config { gravity, drag: 0.01 * 65.0 * 65.0, ..config(integrator, 2.5e-5) };
        let mut sim = Simulation::<f32>::new(&model, &config);
        let mut at_rest = 0;
        for step in 1..=400 {
            sim.step().unwrap_or_else(|d| panic!("{}: {d:?}", integrator.name()));
            let state = sim.state();
            let values = state.velocities.axes().into_iter().chain(state.positions.axes()).flatten();
            let subnormal = values.filter(|v| v.is_subnormal()).count();
            assert_eq!(
                subnormal,
                0,
                "{}: {subnormal} subnormal values after {step} steps",
                integrator.name()
            );
            at_rest = state.velocities.axis(0).iter().filter(|&&u| u == 0.0).count();
        }
        assert!(at_rest < 65 * 65, "{}: the motion spreads sideways", integrator.name());
    }
}

fn check_pinned_cloth<T: Real>() {
    for (integrator, dt, steps) in [(SymplecticEuler, 1e-4, 10_000), (ImplicitEuler, 1e-3, 1_000)] {
        let (first, energies) = cloth_run::<T>(integrator, dt, steps);
        let (second, _) = cloth_run::<T>(integrator, dt, steps);
        assert!(
            first.iter().zip(second.iter()).all(|(a, b)| a.to_array().map(|c| c.to_f64().to_bits())
                == b.to_array().map(|c| c.to_f64().to_bits()))
        );
        // Springs and drag only dissipate: the total falls between any two samples, and by
        // percents over the run (3.6 % for symplectic Euler over 1 s, 7.5 % for implicit Euler, as
        // recorded from this solver; the test asks only for 2 %).
        let (start, end) = (energies[0], *energies.last().unwrap());
        assert!(end < 0.98 * start, "{} {}: energy {start} -> {end}", T::NAME, integrator.name());
        for pair in energies.windows(2) {
            assert!(
                pair[1] < pair[0],
                "{} {}: energy rose {} -> {}",
                T::NAME,
                integrator.name(),
                pair[0],
                pair[1]
            );
        }
    }
}

#[test]
fn a_cloth_pinned_at_two_corners_holds_them_loses_energy_and_repeats_exactly_in_f64() {
    check_pinned_cloth::<f64>();
}

#[test]
fn a_cloth_pinned_at_two_corners_holds_them_loses_energy_and_repeats_exactly_in_f32() {
    check_pinned_cloth::<f32>();
}

#[test]
fn f32_and_f64_agree_on_the_single_spring() {
    let (x64, _) = run_spring::<f64>(Verlet, 2.0, 1e-3, 1.0);
    let (x32, _) = run_spring::<f32>(Verlet, 2.0, 1e-3, 1.0);
    assert!((x64 - x32).abs() < 1e-5, "f64 {x64} vs f32 {x32}");
}

#[test]
fn stages_name_only_the_forces_present() {
    let sim = Simulation::<f64>::new(&single_spring(0.0), &config(SymplecticEuler, 1e-3));
    assert_eq!(sim.stages(), ["springs"]);
    let with_all =
        Config { gravity: DVec3::new(0.0, -9.81, 0.0), drag: 0.1, ..config(SymplecticEuler, 1e-3) };
    let sim = Simulation::<f64>::new(&single_spring(0.0), &with_all);
    assert_eq!(sim.stages(), ["gravity", "drag", "springs"]);
}
