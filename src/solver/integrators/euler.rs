//! Explicit (forward) and symplectic (semi-implicit) Euler.

use super::super::dynamics::Dynamics;
use super::super::{Real, State, Vec3};

/// Scratch for the Euler methods: one acceleration per particle.
#[derive(Debug)]
pub(crate) struct Euler<T> {
    accelerations: Vec<Vec3<T>>,
}

impl<T: Real> Euler<T> {
    pub fn new(particles: usize) -> Self {
        Self { accelerations: vec![Vec3::ZERO; particles] }
    }

    /// `x += h v`, then `v += h a`, both from the state at the start of the step.
    pub fn explicit_step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        dynamics.accelerations(&state.positions, &state.velocities, t, &mut self.accelerations);
        for ((x, v), &a) in state.positions.iter_mut().zip(&mut state.velocities).zip(&self.accelerations) {
            *x += *v * h;
            *v += a * h;
        }
    }

    /// `v += h a`, then `x += h v` with the new velocity.
    pub fn symplectic_step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        dynamics.accelerations(&state.positions, &state.velocities, t, &mut self.accelerations);
        for ((x, v), &a) in state.positions.iter_mut().zip(&mut state.velocities).zip(&self.accelerations) {
            *v += a * h;
            *x += *v * h;
        }
    }
}
