//! Position Verlet with a damping factor, written in velocity form.
//!
//! Position Verlet advances `x' = x + (1 - d)(x - x_prev) + h² a`. Carrying the drift velocity
//! `u = (x' - x) / h` instead of `x_prev` gives the same positions, and lets the step report a
//! second-order velocity `v = u + (h/2) a(x')` (velocity Verlet's closing half kick), so that
//! velocities, energies and velocity-dependent forces stay second order too. The acceleration at
//! the end of one step is the one at the start of the next: one force evaluation per step. Damping
//! forces see the predicted velocity `u + (h/2) a(x)` at the end of the step.

use crate::solver::forces::dynamics::Dynamics;
use crate::solver::math::real::Real;
use crate::solver::math::vectors::Vectors;
use crate::solver::state::State;

#[derive(Debug)]
pub(crate) struct Verlet<T> {
    /// Acceleration at the current state, valid when `primed`.
    accelerations: Vectors<T>,
    /// Drift velocity of the step under way (scratch).
    drift: Vectors<T>,
    /// `1 - d`.
    keep: T,
    primed: bool,
}

impl<T: Real> Verlet<T> {
    pub fn new(particles: usize, damping: f64) -> Self {
        Self {
            accelerations: Vectors::zeros(particles),
            drift: Vectors::zeros(particles),
            keep: T::from_f64(1.0 - damping),
            primed: false,
        }
    }

    /// Forgets the cached acceleration: the state was changed from outside.
    pub fn invalidate(&mut self) {
        self.primed = false;
    }

    pub fn step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        if !self.primed {
            dynamics.accelerations(&state.positions, &state.velocities, t, &mut self.accelerations);
        }
        let half = h * T::from_f64(0.5);
        let keep = self.keep;
        // The previous drift velocity is v - (h/2) a; damp it and kick by a full step.
        let axes = state.positions.axes_mut().into_iter().zip(state.velocities.axes_mut());
        for (((x, v), u), a) in axes.zip(self.drift.axes_mut()).zip(self.accelerations.axes()) {
            for (((x, v), u), &a) in x.iter_mut().zip(v.iter_mut()).zip(u.iter_mut()).zip(a) {
                *u = ((*v - a * half) * keep + a * h).kept_speed();
                *x += *u * h;
                *v = (*u + a * half).kept_speed();
            }
        }
        let end = t + h.to_f64();
        dynamics.accelerations(&state.positions, &state.velocities, end, &mut self.accelerations);
        let axes = state.velocities.axes_mut().into_iter().zip(self.drift.axes());
        for ((v, u), a) in axes.zip(self.accelerations.axes()) {
            for ((v, &u), &a) in v.iter_mut().zip(u).zip(a) {
                *v = (u + a * half).kept_speed();
            }
        }
        self.primed = true;
    }
}
