//! The classic fourth-order Runge-Kutta method, with forces re-evaluated at each of the four
//! stages on the whole state.

use super::super::dynamics::Dynamics;
use super::super::{Real, State, Vectors};

#[derive(Debug)]
pub(crate) struct Rk4<T> {
    /// Trial state of the current stage.
    trial: State<T>,
    /// Acceleration at the trial state.
    accelerations: Vectors<T>,
    /// Weighted sums `k1 + 2k2 + 2k3 + k4` for x and v.
    sum_x: Vectors<T>,
    sum_v: Vectors<T>,
}

impl<T: Real> Rk4<T> {
    pub fn new(particles: usize) -> Self {
        let zeros = || Vectors::zeros(particles);
        Self {
            trial: State { positions: zeros(), velocities: zeros() },
            accelerations: zeros(),
            sum_x: zeros(),
            sum_v: zeros(),
        }
    }

    pub fn step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        let half = h * T::from_f64(0.5);
        let two = T::from_f64(2.0);
        let Self { trial, accelerations, sum_x, sum_v } = self;

        // Stage 1 at the start of the step.
        dynamics.accelerations(&state.positions, &state.velocities, t, accelerations);
        for axis in 0..3 {
            let (x0, v0, a) =
                (state.positions.axis(axis), state.velocities.axis(axis), accelerations.axis(axis));
            let sums = sum_x.axis_mut(axis).iter_mut().zip(sum_v.axis_mut(axis));
            let trials = trial.positions.axis_mut(axis).iter_mut().zip(trial.velocities.axis_mut(axis));
            for (((sum_x, sum_v), (trial_x, trial_v)), ((&x0, &v0), &a)) in
                sums.zip(trials).zip(x0.iter().zip(v0).zip(a))
            {
                *sum_x = v0;
                *sum_v = a;
                *trial_x = x0 + v0 * half;
                *trial_v = v0 + a * half;
            }
        }
        // Stages 2 and 3 at the midpoint; the trial state moves on to the next stage's.
        let midpoint = t + half.to_f64();
        for advance in [half, h] {
            dynamics.accelerations(&trial.positions, &trial.velocities, midpoint, accelerations);
            for axis in 0..3 {
                let (x0, v0, a) =
                    (state.positions.axis(axis), state.velocities.axis(axis), accelerations.axis(axis));
                let sums = sum_x.axis_mut(axis).iter_mut().zip(sum_v.axis_mut(axis));
                let trials = trial.positions.axis_mut(axis).iter_mut().zip(trial.velocities.axis_mut(axis));
                for (((sum_x, sum_v), (trial_x, trial_v)), ((&x0, &v0), &a)) in
                    sums.zip(trials).zip(x0.iter().zip(v0).zip(a))
                {
                    let v = *trial_v;
                    *sum_x += v * two;
                    *sum_v += a * two;
                    *trial_x = x0 + v * advance;
                    *trial_v = v0 + a * advance;
                }
            }
        }
        // Stage 4 at the end of the step.
        let end = t + h.to_f64();
        dynamics.accelerations(&trial.positions, &trial.velocities, end, accelerations);
        let sixth = h / T::from_f64(6.0);
        for axis in 0..3 {
            let (sum_x, sum_v, a) = (sum_x.axis(axis), sum_v.axis(axis), accelerations.axis(axis));
            for ((x, &s), &v) in
                state.positions.axis_mut(axis).iter_mut().zip(sum_x).zip(trial.velocities.axis(axis))
            {
                *x += (s + v) * sixth;
            }
            for ((v, &s), &a) in state.velocities.axis_mut(axis).iter_mut().zip(sum_v).zip(a) {
                *v += (s + a) * sixth;
            }
        }
    }
}
