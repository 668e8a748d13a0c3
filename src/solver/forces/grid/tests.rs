//! The grid pass against the spring list, and its independence from the number of bands.

use glam::DVec3;

use super::bands::{MISSES, RETRY_PASSES};
use super::*;
use crate::solver::bodies::{Cloth, Orientation};
use crate::solver::forces::springs;
use crate::solver::model::SpringParams;
use crate::solver::state::State;

/// A 13 × 5 cloth (13 is not a multiple of the vector width, so the tail loops run too) with
/// springs of three different parameter sets, bent and moving so every spring is loaded.
fn moving_cloth() -> (Model, Vectors<f64>, Vectors<f64>) {
    let mut model = Model::default();
    model.add_cloth(&Cloth {
        size: [1.2, 0.4],
        resolution: [13, 5],
        center: DVec3::new(0.0, 1.0, 0.0),
        orientation: Orientation::Vertical,
        mass: 0.3,
        velocity: DVec3::ZERO,
        structural: SpringParams { stiffness: 900.0, damping: 0.3 },
        shear: SpringParams { stiffness: 400.0, damping: 0.1 },
        bending: SpringParams { stiffness: 50.0, damping: 0.05 },
        pins: vec![],
    });
    let wave = |p: usize, a: f64| {
        DVec3::new((a * p as f64).sin(), (1.3 * a * p as f64).cos(), (0.7 * p as f64).sin())
    };
    let x = model
        .positions
        .iter()
        .enumerate()
        .map(|(p, &x)| Vec3::from_dvec3(x + wave(p, 0.37) * 0.01))
        .collect();
    let v = (0..model.particle_count()).map(|p| Vec3::from_dvec3(wave(p, 0.91))).collect();
    (model, x, v)
}

#[test]
fn stencil_pass_gives_the_spring_list_force() {
    let (model, x, v) = moving_cloth();
    let springs: Vec<Spring<f64>> = model.springs.clone();
    let mut grid = GridSprings::new(&model.grids[0], &springs).expect("a builder's cloth is a grid");
    assert_eq!(grid.springs(), 0..springs.len());
    let mut by_stencil = Vectors::zeros(x.len());
    let mut by_list = Vectors::zeros(x.len());
    grid.add_forces(&x, &v, &mut by_stencil);
    springs::add_forces(&springs, &x, &v, &mut by_list);
    let largest = by_list.iter().map(|f| f.length()).fold(0.0, f64::max);
    assert!(largest > 1.0, "the springs are loaded: {largest}");
    for (a, b) in by_stencil.iter().zip(by_list.iter()) {
        assert!((a - b).length() <= 1e-12 * largest, "{a:?} against {b:?}");
    }
}

/// The same grid cut into `count` bands.
fn banded(model: &Model, count: usize) -> GridSprings<f64> {
    let grid = GridSprings::new(&model.grids[0], &model.springs).expect("a builder's cloth is a grid");
    GridSprings::with_bands(grid.first, grid.springs.clone(), grid.layout, count)
}

#[test]
fn forces_do_not_depend_on_the_number_of_bands() {
    let (model, x, v) = moving_cloth();
    let forces = |count: usize| {
        let mut grid = banded(&model, count);
        assert_eq!(grid.bands.len(), 5usize.div_ceil(5usize.div_ceil(count)), "rows are shared out evenly");
        let mut forces: Vectors<f64> = (0..x.len()).map(|p| Vec3::new(p as f64, -1.0, 0.5)).collect();
        grid.add_forces(&x, &v, &mut forces);
        forces
    };
    let one = forces(1);
    assert!(one.iter().any(|f| f.length() > 1.0));
    for count in 2..=5 {
        assert_eq!(forces(count), one, "{count} bands");
    }
}

/// Masses that differ from particle to particle, with particle 3 pinned: the masses and the
/// inverse masses.
fn masses(n: usize) -> (Vec<f64>, Vec<f64>) {
    let masses: Vec<f64> = (0..n).map(|p| 0.01 + 0.001 * p as f64).collect();
    let inverse = masses.iter().enumerate().map(|(p, m)| if p == 3 { 0.0 } else { 1.0 / m }).collect();
    (masses, inverse)
}

/// Gravity and a drag of 0.3 s⁻¹ on particles of `masses`.
fn body_terms<'a>(masses: &'a [f64], inverse_masses: &'a [f64]) -> BodyTerms<'a, f64> {
    BodyTerms { masses, inverse_masses, gravity: Vec3::new(0.0, -9.81, 0.0), drag: 0.3, extra: None }
}

#[test]
fn accelerations_do_not_depend_on_the_number_of_bands() {
    let (model, x, v) = moving_cloth();
    let n = x.len();
    let (masses, inverse_masses) = masses(n);
    let inputs = body_terms(&masses, &inverse_masses);
    let accelerations = |count: usize| {
        let mut out = Vectors::zeros(n);
        banded(&model, count).accelerations(&inputs, &x, &v, &mut out);
        out
    };
    let one = accelerations(1);
    assert_eq!(one.get(3), Vec3::ZERO, "a pinned particle does not accelerate");
    let mut forces = Vectors::zeros(n);
    springs::add_forces(&model.springs, &x, &v, &mut forces);
    let f = forces.get(40) + (inputs.gravity - v.get(40) * 0.3) * masses[40];
    assert!((one.get(40) - f * inverse_masses[40]).length() < 1e-9 * f.length() * inverse_masses[40]);
    for count in 2..=5 {
        assert_eq!(accelerations(count), one, "{count} bands");
    }
}

#[test]
fn symplectic_steps_do_not_depend_on_the_number_of_bands() {
    let (model, x, v) = moving_cloth();
    let n = x.len();
    let (masses, inverse_masses) = masses(n);
    let inputs = body_terms(&masses, &inverse_masses);
    let step = |count: usize| {
        let mut grid = banded(&model, count);
        let state = State { positions: x.clone(), velocities: v.clone() };
        let mut next = State { positions: Vectors::zeros(n), velocities: Vectors::zeros(n) };
        let sums = grid.symplectic_step(&inputs, 1e-4, &state, &mut next);
        (next.positions, next.velocities, sums)
    };
    let (x1, v1, sums) = step(1);
    assert_eq!(x1.get(3), x.get(3) + v.get(3) * 1e-4, "a pinned particle drifts with its own velocity only");
    let kinetic: f64 = masses.iter().zip(v1.iter()).map(|(m, v)| m * v.length_squared()).sum();
    assert!((sums.0 - kinetic).abs() < 1e-12 * kinetic, "{} against {kinetic}", sums.0);
    for count in 2..=5 {
        let (xs, vs, _) = step(count);
        assert_eq!((&xs, &vs), (&x1, &v1), "{count} bands");
    }
}

#[test]
fn a_grid_whose_bands_are_optional_steps_as_its_whole_band_does_in_either_mode() {
    let (model, x, v) = moving_cloth();
    let n = x.len();
    let (masses, inverse_masses) = masses(n);
    let inputs = body_terms(&masses, &inverse_masses);
    let grid = banded(&model, 1);
    let mut sharing = GridSprings::with_optional_bands(grid.first, grid.springs.clone(), grid.layout, 3);
    let mut whole = banded(&model, 1);
    assert_eq!(sharing.bands.len(), 3);
    let mut a = State { positions: x.clone(), velocities: v.clone() };
    let mut b = a.clone();
    let mut next = State { positions: Vectors::zeros(n), velocities: Vectors::zeros(n) };
    for step in 0..6 {
        // Even steps in the bands, odd steps whole.
        sharing.sharing = Some(Sharing { passes_until_retry: step % 2, misses: 0 });
        sharing.symplectic_step(&inputs, 1e-4, &a, &mut next);
        std::mem::swap(&mut a, &mut next);
        whole.symplectic_step(&inputs, 1e-4, &b, &mut next);
        std::mem::swap(&mut b, &mut next);
        assert_eq!((&a.positions, &a.velocities), (&b.positions, &b.velocities), "step {step}");
    }
    assert_ne!(a.positions, x, "the cloth moved");
}

#[test]
fn optional_bands_go_whole_after_offers_no_thread_takes_and_are_offered_again() {
    let mut sharing = Sharing::default();
    assert!(sharing.splits(), "a grid starts in its bands");
    for _ in 1..MISSES {
        sharing.after_pass(true, false);
        assert!(sharing.splits(), "a few misses may be a thread waking up");
    }
    sharing.after_pass(true, true);
    for _ in 1..MISSES {
        sharing.after_pass(true, false);
    }
    assert!(sharing.splits(), "a taken offer clears the misses before it");
    sharing.after_pass(true, false);
    for pass in 0..RETRY_PASSES {
        assert!(!sharing.splits(), "whole on pass {pass}");
        sharing.after_pass(false, false);
    }
    assert_eq!(sharing, Sharing::default(), "the bands are offered again, with no misses counted");
}

#[test]
fn springs_that_differ_from_the_stencil_stay_on_the_list() {
    let (model, _, _) = moving_cloth();
    let mut springs = model.springs.clone();
    springs[7].rest_length *= 1.01;
    assert!(GridSprings::new(&model.grids[0], &springs).is_none());
    let mut springs = model.springs.clone();
    springs.swap(3, 4);
    assert!(GridSprings::new(&model.grids[0], &springs).is_none());
    assert!(GridSprings::new(&model.grids[0], &model.springs[1..]).is_none());
}

#[test]
fn fused_symplectic_step_follows_the_spring_list_path() {
    use crate::solver::integrators::IntegratorKind;
    use crate::solver::simulation::{Config, Simulation};
    let (mut model, _, _) = moving_cloth();
    model.pin(0);
    let config =
        Config { integrator: IntegratorKind::SymplecticEuler, dt: 2e-4, drag: 0.5, ..Config::default() };
    let mut fused = Simulation::<f64>::new(&model, &config);
    model.grids.clear();
    let mut listed = Simulation::<f64>::new(&model, &config);
    for _ in 0..500 {
        fused.step().expect("stable");
        listed.step().expect("stable");
    }
    let (a, b) = (fused.state(), listed.state());
    assert_eq!(a.positions.get(0), b.positions.get(0), "the pin holds");
    let moved = (a.positions.get(40) - Vec3::from_dvec3(model.positions[40])).length();
    assert!(moved > 1e-3, "the cloth moved {moved} m");
    for (p, q) in a.positions.iter().zip(b.positions.iter()) {
        assert!((p - q).length() < 1e-9, "{p:?} against {q:?}");
    }
    assert!((fused.energy().kinetic - listed.energy().kinetic).abs() < 1e-9);
}

/// The performance peers' hanging cloth (`docs/performance.md`): N = 32, 1 s at 1e-4 s.
/// Their NumPy, Taichi, Warp, Newton and C++ versions all end with the centre particle at
/// y = 0.53204 and particle (0, 31) at y = 0.17014 (spread 4e-7 among them, in f32).
fn peers_cloth_after_one_second<T: Real>() -> (f64, f64) {
    use crate::solver::integrators::IntegratorKind;
    use crate::solver::simulation::{Config, Simulation};
    let n = 32;
    let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
    let mut model = Model::default();
    model.add_cloth(&Cloth { pins: vec![[0, 0], [n - 1, 0]], ..Cloth::square_metre(n, springs) });
    let config = Config {
        integrator: IntegratorKind::SymplecticEuler,
        dt: 1e-4,
        drag: 0.01 * (n * n) as f64,
        ..Config::default()
    };
    let mut simulation = Simulation::<T>::new(&model, &config);
    for _ in 0..10_000 {
        simulation.step().expect("stable at the peers' step");
    }
    let y = |i: usize, j: usize| simulation.state().positions.get(j * n + i).y.to_f64();
    (y(n / 2, n / 2), y(0, n - 1))
}

#[test]
fn the_peers_cloth_hangs_where_every_peer_puts_it() {
    for (centre, corner) in [peers_cloth_after_one_second::<f32>(), peers_cloth_after_one_second::<f64>()] {
        assert!((centre - 0.5320434).abs() < 3e-6, "centre at y = {centre}");
        assert!((corner - 0.1701399).abs() < 3e-6, "corner at y = {corner}");
    }
}
