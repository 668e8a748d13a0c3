//! Pinned particles carried along a rigid motion: a body's pins moved about its centre, so that a
//! cloth can be lifted, shaken or pulled.
//!
//! A pinned particle at rest position `x₀` of a body with centre `c` is at
//! `c + translation(t) + rotation(t) · (x₀ - c)` at time `t`. After each step of any integrator
//! the stage puts it there for the step's end and gives it the velocity that took it there from
//! where the motion had it at the step's start, so that every integrator and every spring sees
//! the pin move consistently with its velocity. Pinned particles have no inverse mass, so nothing
//! else moves them.

use glam::DVec3;

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::motion::Motion;
use crate::solver::state::State;

/// Some pinned particles and the motion that carries them.
#[derive(Clone, Debug, PartialEq)]
pub struct PinMotion {
    /// The pinned particles it moves.
    pub particles: Vec<usize>,
    /// The point the rotation turns them about, in metres (a body's rest centroid).
    pub centre: DVec3,
    /// Their motion.
    pub motion: Motion,
}

/// The stage: each group's particles with their rest offsets from its centre.
#[derive(Clone, Debug)]
pub(crate) struct MovingPins {
    groups: Vec<(PinMotion, Vec<DVec3>)>,
}

impl MovingPins {
    /// The stage for these motions over the model's rest `positions`, or `None` without any.
    pub fn new(pins: &[PinMotion], positions: &[DVec3]) -> Option<Self> {
        if pins.is_empty() {
            return None;
        }
        let groups = pins
            .iter()
            .map(|p| (p.clone(), p.particles.iter().map(|&i| positions[i] - p.centre).collect()))
            .collect();
        Some(Self { groups })
    }

    /// Puts the pins where the motion has them at `t + dt`, with the velocity that took them
    /// there from `t`.
    pub fn place<T: Real>(&self, state: &mut State<T>, t: f64, dt: f64) {
        for (pins, offsets) in &self.groups {
            let (before, after) = (pins.motion.at(t), pins.motion.at(t + dt));
            for (&p, &offset) in pins.particles.iter().zip(offsets) {
                let (from, to) = (pins.centre + before.point(offset), pins.centre + after.point(offset));
                state.positions.set(p, Vec3::from_dvec3(to));
                let velocity: Vec3<T> = Vec3::from_dvec3((to - from) / dt);
                let kept =
                    Vec3::new(velocity.x.kept_speed(), velocity.y.kept_speed(), velocity.z.kept_speed());
                state.velocities.set(p, kept);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DQuat;

    use super::*;
    use crate::solver::bodies::Chain;
    use crate::solver::integrators::IntegratorKind;
    use crate::solver::model::{Model, SpringParams};
    use crate::solver::motion::{Keyframe, Rigid};
    use crate::solver::simulation::{Config, Simulation};

    /// A chain of three from (0, 1, 0) to (2, 1, 0), its ends pinned: centre (1, 1, 0).
    fn chain() -> Model {
        let mut model = Model::default();
        model.add_chain(&Chain {
            start: DVec3::new(0.0, 1.0, 0.0),
            end: DVec3::new(2.0, 1.0, 0.0),
            count: 3,
            mass: 0.3,
            velocity: DVec3::ZERO,
            spring: SpringParams { stiffness: 100.0, damping: 0.1 },
            rest_length: None,
            pins: vec![0, 2],
        });
        model
    }

    #[test]
    fn pins_follow_their_keyframes_about_the_centre_with_consistent_velocities_in_every_integrator() {
        // Half a turn about y and 1 m along z over the first second.
        let motion = Motion::Keyframes(vec![
            Keyframe { t: 0.0, transform: Rigid::IDENTITY },
            Keyframe {
                t: 1.0,
                transform: Rigid {
                    translation: DVec3::new(0.0, 0.0, 1.0),
                    rotation: DQuat::from_rotation_y(std::f64::consts::PI),
                },
            },
        ]);
        let pins =
            PinMotion { particles: vec![0, 2], centre: DVec3::new(1.0, 1.0, 0.0), motion: motion.clone() };
        for integrator in [
            IntegratorKind::ExplicitEuler,
            IntegratorKind::SymplecticEuler,
            IntegratorKind::Verlet,
            IntegratorKind::Rk4,
            IntegratorKind::ImplicitEuler,
        ] {
            let config =
                Config { integrator, dt: 1e-3, pin_motions: vec![pins.clone()], ..Config::default() };
            let mut sim = Simulation::<f64>::new(&chain(), &config);
            assert!(sim.stages().contains(&"pin_motion"), "{:?}", sim.stages());
            for _ in 0..500 {
                sim.step().unwrap();
            }
            // At 0.5 s: a quarter turn, so the end at x = 0 (1 m left of the centre) is now 1 m
            // along +z from it, and everything 0.5 m along z.
            let first = sim.state().positions.get(0).to_dvec3();
            assert!((first - DVec3::new(1.0, 1.0, 1.5)).length() < 1e-9, "{integrator:?}: {first}");
            let last = sim.state().positions.get(2).to_dvec3();
            assert!((last - DVec3::new(1.0, 1.0, -0.5)).length() < 1e-9, "{integrator:?}: {last}");
            // Its velocity: 1 m/s along z, plus π rad/s about y at 1 m, along +x for the first end there.
            let v = sim.state().velocities.get(0).to_dvec3();
            let expected = DVec3::new(std::f64::consts::PI, 0.0, 1.0);
            assert!((v - expected).length() < 1e-2, "{integrator:?}: {v}");
            for _ in 0..700 {
                sim.step().unwrap();
            }
            // Held after the last key.
            let first = sim.state().positions.get(0).to_dvec3();
            assert!((first - DVec3::new(2.0, 1.0, 1.0)).length() < 1e-9, "{integrator:?}: {first}");
            assert_eq!(sim.state().velocities.get(0).to_dvec3(), DVec3::ZERO);
        }
    }
}
