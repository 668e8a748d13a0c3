//! What accelerates the particles: their masses, gravity, drag and springs.
//!
//! [`Dynamics`] is everything a force evaluation needs besides the state, so that every
//! integrator can evaluate `a(x, v, t)` on any trial state (RK4 evaluates four per step).
//! A force that a scene does not have is `None` and costs nothing.

use super::model::{Model, Spring};
use super::{Real, Vec3, springs};

/// Particle masses and the forces acting on them.
#[derive(Clone, Debug)]
pub struct Dynamics<T> {
    /// Masses, in kg.
    pub masses: Vec<T>,
    /// Inverse masses, in 1/kg; zero for a pinned particle, which no force moves.
    pub inverse_masses: Vec<T>,
    /// Gravitational acceleration, when not zero.
    pub gravity: Option<Vec3<T>>,
    /// Drag rate in 1/s (force `-drag · m · v`), when positive.
    pub drag: Option<T>,
    /// Every spring.
    pub springs: Vec<Spring<T>>,
}

impl<T: Real> Dynamics<T> {
    /// Converts a model's particles and springs, with the given gravity and drag.
    pub fn new(model: &Model, gravity: glam::DVec3, drag: f64) -> Self {
        let masses: Vec<T> = model.masses.iter().map(|&m| T::from_f64(m)).collect();
        let inverse_masses = model
            .masses
            .iter()
            .zip(&model.pinned)
            .map(|(&m, &pinned)| if pinned { T::ZERO } else { T::from_f64(1.0 / m) })
            .collect();
        let springs = model
            .springs
            .iter()
            .map(|s| Spring {
                i: s.i,
                j: s.j,
                rest_length: T::from_f64(s.rest_length),
                stiffness: T::from_f64(s.stiffness),
                damping: T::from_f64(s.damping),
                kind: s.kind,
            })
            .collect();
        Self {
            masses,
            inverse_masses,
            gravity: (gravity != glam::DVec3::ZERO).then(|| Vec3::from_dvec3(gravity)),
            drag: (drag > 0.0).then(|| T::from_f64(drag)),
            springs,
        }
    }

    /// The names of the force stages present, in the order they are applied.
    pub fn stages(&self) -> impl Iterator<Item = &'static str> {
        [
            self.gravity.map(|_| "gravity"),
            self.drag.map(|_| "drag"),
            (!self.springs.is_empty()).then_some("springs"),
        ]
        .into_iter()
        .flatten()
    }

    /// Total force on each particle at state `(x, v)`, written into `forces`.
    pub fn forces(&self, x: &[Vec3<T>], v: &[Vec3<T>], forces: &mut [Vec3<T>]) {
        let body = self.gravity.unwrap_or(Vec3::ZERO);
        match self.drag {
            Some(drag) => {
                for ((f, &m), &v) in forces.iter_mut().zip(&self.masses).zip(v) {
                    *f = (body - v * drag) * m;
                }
            }
            None => {
                for (f, &m) in forces.iter_mut().zip(&self.masses) {
                    *f = body * m;
                }
            }
        }
        springs::add_forces(&self.springs, x, v, forces);
    }

    /// Acceleration of each particle at state `(x, v)`, written into `accelerations`; zero for
    /// pinned particles.
    pub fn accelerations(&self, x: &[Vec3<T>], v: &[Vec3<T>], accelerations: &mut [Vec3<T>]) {
        self.forces(x, v, accelerations);
        for (a, &w) in accelerations.iter_mut().zip(&self.inverse_masses) {
            *a *= w;
        }
    }
}
