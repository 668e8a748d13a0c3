//! Moving colliders: a surface sweeps up the particles in its way however fast it goes, and its
//! friction carries what rests on it.

use std::sync::Arc;

use glam::{DQuat, DVec3};

use super::mesh_tests::{sheet, unit_cube};
use super::*;
use crate::solver::integrators::IntegratorKind;
use crate::solver::model::Model;
use crate::solver::motion::{Keyframe, Motion, Rigid};
use crate::solver::simulation::{Config, Simulation};

fn particle(position: DVec3) -> Model {
    let mut m = Model::default();
    m.add_particles([position], |_| 1.0, DVec3::ZERO);
    m
}

fn config(dt: f64, gravity: DVec3, colliders: Vec<Collider>) -> Config {
    Config { integrator: IntegratorKind::SymplecticEuler, dt, gravity, colliders, ..Config::default() }
}

fn moving_sheet(motion: Motion, friction: f64) -> Collider {
    Collider {
        shape: Shape::Mesh { surface: Arc::new(sheet(0.0, 4.0, 8)), thickness: 0.01 },
        friction,
        restitution: 0.0,
        motion: Some(motion),
    }
}

#[test]
fn a_sheet_rising_at_100_m_s_sweeps_up_a_particle_instead_of_passing_it() {
    let dt = 1.0 / 60.0;
    let up = Motion::Velocity {
        start: Rigid::IDENTITY,
        velocity: DVec3::new(0.0, 100.0, 0.0),
        angular_velocity: DVec3::ZERO,
    };
    // 0.5 m above the sheet: the sheet passes it within the first step (1.67 m).
    let model = particle(DVec3::new(0.1, 0.5, 0.2));
    let mut sim = Simulation::<f64>::new(&model, &config(dt, DVec3::ZERO, vec![moving_sheet(up, 0.3)]));
    assert!(sim.stages().contains(&"moving_colliders"), "{:?}", sim.stages());
    for step in 1..=3 {
        sim.step().unwrap();
        let (x, v) = (sim.state().positions.get(0), sim.state().velocities.get(0));
        let sheet_y = 100.0 * dt * step as f64;
        assert!((x.y - (sheet_y + 0.01)).abs() < 1e-9, "step {step}: at {} with the sheet at {sheet_y}", x.y);
        // Carried with the sheet: restitution 0 leaves it the sheet's speed.
        assert!((v.y - 100.0).abs() < 1e-9, "step {step}: {v:?}");
    }
}

#[test]
fn a_sphere_swept_by_keyframes_pushes_a_particle_ahead_of_it() {
    let dt = 1.0 / 60.0;
    let key = |t: f64, x: f64| Keyframe {
        t,
        transform: Rigid { translation: DVec3::new(x, 0.0, 0.0), rotation: DQuat::IDENTITY },
    };
    // From x = -1 to x = 1 in 1/60 s: through the particle at the origin in one step.
    let ball = Collider {
        shape: Shape::Sphere { center: DVec3::ZERO, radius: 0.2 },
        friction: 0.0,
        restitution: 0.0,
        motion: Some(Motion::Keyframes(vec![key(0.0, -1.0), key(dt, 1.0)])),
    };
    let model = particle(DVec3::new(0.0, 0.05, 0.0));
    let mut sim = Simulation::<f64>::new(&model, &config(dt, DVec3::ZERO, vec![ball]));
    sim.step().unwrap();
    let x = sim.state().positions.get(0).to_dvec3();
    // Met on the ball's front, and left on its surface there, ahead of its centre at x = 1.
    assert!(x.x > 1.0, "passed through to {x:?}");
    assert!(((x - DVec3::new(1.0, 0.0, 0.0)).length() - 0.2).abs() < 1e-9, "{x:?}");
}

#[test]
fn friction_drags_a_resting_particle_along_with_a_sliding_floor() {
    let dt = 1e-3;
    let along = Motion::Velocity {
        start: Rigid::IDENTITY,
        velocity: DVec3::new(0.5, 0.0, 0.0),
        angular_velocity: DVec3::ZERO,
    };
    let model = particle(DVec3::new(0.0, 0.01, 0.0));
    let (mu, g) = (0.5, 9.81);
    let mut sim =
        Simulation::<f64>::new(&model, &config(dt, DVec3::new(0.0, -g, 0.0), vec![moving_sheet(along, mu)]));
    // Coulomb friction accelerates it at μg until it moves with the floor: 0.5 / 4.905 s ≈ 0.1 s.
    for _ in 0..90 {
        sim.step().unwrap();
    }
    let v = sim.state().velocities.get(0).x;
    assert!((v - mu * g * 0.09).abs() < 0.01, "at 90 ms: {v}");
    for _ in 0..200 {
        sim.step().unwrap();
    }
    let v = sim.state().velocities.get(0);
    assert!((v.x - 0.5).abs() < 1e-9 && v.y.abs() < 1e-9, "{v:?}");
}

#[test]
fn a_turning_closed_mesh_keeps_particles_out() {
    let dt = 1e-3;
    let spin = Motion::Velocity {
        start: Rigid::IDENTITY,
        velocity: DVec3::ZERO,
        angular_velocity: DVec3::new(0.0, 0.0, 20.0),
    };
    // A cube of side 1 turning about z at 20 rad/s through particles scattered around it.
    let cube = unit_cube();
    let collider = Collider {
        shape: Shape::Mesh { surface: Arc::new(cube), thickness: 0.005 },
        friction: 0.3,
        restitution: 0.0,
        motion: Some(spin.clone()),
    };
    let mut model = Model::default();
    model.add_particles(
        (0..200).map(|k| {
            let a = k as f64 * 0.1;
            DVec3::new(0.6 * a.cos(), 0.6 * a.sin(), (k % 7) as f64 * 0.1 - 0.3)
        }),
        |_| 1.0,
        DVec3::ZERO,
    );
    let mut sim = Simulation::<f64>::new(&model, &config(dt, DVec3::ZERO, vec![collider]));
    let box_shape = Shape::Box { center: DVec3::ZERO, half_extents: DVec3::splat(0.5) };
    for step in 1..=100 {
        sim.step().unwrap();
        let now = spin.at(step as f64 * dt);
        for x in sim.state().positions.iter() {
            let local = now.inverse_point(x.to_dvec3());
            let depth = box_shape.signed_distance(local);
            assert!(depth > 0.005 - 1e-9, "step {step}: a particle {depth} from the cube");
        }
    }
}
