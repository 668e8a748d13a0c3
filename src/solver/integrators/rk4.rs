//! The classic fourth-order Runge-Kutta method, with forces re-evaluated at each of the four
//! stages on the whole state.

use super::super::dynamics::Dynamics;
use super::super::{Real, State, Vec3};

#[derive(Debug)]
pub(crate) struct Rk4<T> {
    /// Trial state of the current stage.
    trial_x: Vec<Vec3<T>>,
    trial_v: Vec<Vec3<T>>,
    /// Acceleration at the trial state.
    accelerations: Vec<Vec3<T>>,
    /// Weighted sums `k1 + 2k2 + 2k3 + k4` for x and v.
    sum_x: Vec<Vec3<T>>,
    sum_v: Vec<Vec3<T>>,
}

impl<T: Real> Rk4<T> {
    pub fn new(particles: usize) -> Self {
        let zeros = || vec![Vec3::ZERO; particles];
        Self { trial_x: zeros(), trial_v: zeros(), accelerations: zeros(), sum_x: zeros(), sum_v: zeros() }
    }

    pub fn step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        let half = h * T::from_f64(0.5);
        let two = T::from_f64(2.0);
        let (x0, v0) = (&state.positions, &state.velocities);

        // Stage 1 at the start of the step.
        dynamics.accelerations(x0, v0, t, &mut self.accelerations);
        for p in 0..x0.len() {
            let a = self.accelerations[p];
            self.sum_x[p] = v0[p];
            self.sum_v[p] = a;
            self.trial_x[p] = x0[p] + v0[p] * half;
            self.trial_v[p] = v0[p] + a * half;
        }
        // Stages 2 and 3 at the midpoint; the trial state moves on to the next stage's.
        let midpoint = t + half.to_f64();
        for advance in [half, h] {
            dynamics.accelerations(&self.trial_x, &self.trial_v, midpoint, &mut self.accelerations);
            for p in 0..x0.len() {
                let (v, a) = (self.trial_v[p], self.accelerations[p]);
                self.sum_x[p] += v * two;
                self.sum_v[p] += a * two;
                self.trial_x[p] = x0[p] + v * advance;
                self.trial_v[p] = v0[p] + a * advance;
            }
        }
        // Stage 4 at the end of the step.
        let end = t + h.to_f64();
        dynamics.accelerations(&self.trial_x, &self.trial_v, end, &mut self.accelerations);
        let sixth = h / T::from_f64(6.0);
        for p in 0..x0.len() {
            let kx = self.sum_x[p] + self.trial_v[p];
            let kv = self.sum_v[p] + self.accelerations[p];
            state.positions[p] += kx * sixth;
            state.velocities[p] += kv * sixth;
        }
    }
}
