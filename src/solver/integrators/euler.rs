//! Explicit (forward) and symplectic (semi-implicit) Euler.

use super::fused_symplectic;
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::math::real::Real;
use crate::solver::math::vectors::Vectors;
use crate::solver::state::State;

/// Scratch for the Euler methods: one acceleration per particle, and for a scene that symplectic
/// Euler advances in one fused pass, the state that pass writes.
#[derive(Debug)]
pub(crate) struct Euler<T> {
    accelerations: Vectors<T>,
    next: Option<State<T>>,
}

impl<T: Real> Euler<T> {
    pub fn new(particles: usize) -> Self {
        Self { accelerations: Vectors::zeros(particles), next: None }
    }

    /// Symplectic Euler's scratch: the fused pass's output state when the scene has one, the
    /// accelerations otherwise.
    pub fn symplectic(dynamics: &Dynamics<T>) -> Self {
        let n = dynamics.masses.len();
        if dynamics.has_fused_passes() {
            let next = State { positions: Vectors::zeros(n), velocities: Vectors::zeros(n) };
            Self { accelerations: Vectors::zeros(0), next: Some(next) }
        } else {
            Self::new(n)
        }
    }

    /// `x += h v`, then `v += h a`, both from the state at the start of the step.
    pub fn explicit_step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        dynamics.accelerations(&state.positions, &state.velocities, t, &mut self.accelerations);
        let axes = state.positions.axes_mut().into_iter().zip(state.velocities.axes_mut());
        for ((x, v), a) in axes.zip(self.accelerations.axes()) {
            for ((x, v), &a) in x.iter_mut().zip(v.iter_mut()).zip(a) {
                *x += *v * h;
                *v = (*v + a * h).kept_speed();
            }
        }
    }

    /// `v += h a`, then `x += h v` with the new velocity. Returns the stability watch's sums when
    /// the fused pass took the step.
    pub fn symplectic_step(
        &mut self,
        state: &mut State<T>,
        dynamics: &mut Dynamics<T>,
        t: f64,
        h: T,
    ) -> Option<(T, T)> {
        if let Some(next) = &mut self.next {
            let sums = fused_symplectic::step(dynamics, state, next, h);
            std::mem::swap(state, next);
            return sums;
        }
        dynamics.accelerations(&state.positions, &state.velocities, t, &mut self.accelerations);
        let axes = state.positions.axes_mut().into_iter().zip(state.velocities.axes_mut());
        for ((x, v), a) in axes.zip(self.accelerations.axes()) {
            for ((x, v), &a) in x.iter_mut().zip(v.iter_mut()).zip(a) {
                *v = (*v + a * h).kept_speed();
                *x += *v * h;
            }
        }
        None
    }
}
