//! The classic fourth-order Runge-Kutta method, with forces re-evaluated at each of the four
//! stages on the whole state.

use super::super::dynamics::Dynamics;
use super::super::{Real, State, Vectors, parallel};

#[derive(Debug)]
pub(crate) struct Rk4<T> {
    /// Trial state of the current stage.
    trial: State<T>,
    /// Acceleration at the trial state.
    accelerations: Vectors<T>,
    /// Weighted sums `k1 + 2k2 + 2k3 + k4` for x and v.
    sum_x: Vectors<T>,
    sum_v: Vectors<T>,
    /// The most particles one thread updates in a stage: all of them, or a share per solver
    /// thread for a large state.
    chunk: usize,
}

impl<T: Real> Rk4<T> {
    pub fn new(particles: usize) -> Self {
        let zeros = || Vectors::zeros(particles);
        Self {
            trial: State { positions: zeros(), velocities: zeros() },
            accelerations: zeros(),
            sum_x: zeros(),
            sum_v: zeros(),
            chunk: particles.div_ceil(parallel::band_count(particles, particles, 1)).max(1),
        }
    }

    pub fn step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        let half = h * T::from_f64(0.5);
        let two = T::from_f64(2.0);
        let chunk = self.chunk;
        let Self { trial, accelerations, sum_x, sum_v, .. } = self;

        // Stage 1 at the start of the step.
        dynamics.accelerations(&state.positions, &state.velocities, t, accelerations);
        for axis in 0..3 {
            let outputs = [&mut *sum_x, &mut *sum_v, &mut trial.positions, &mut trial.velocities]
                .map(|o| o.axis_mut(axis));
            let inputs = [&state.positions, &state.velocities, &*accelerations].map(|i| i.axis(axis));
            in_pieces(chunk, outputs, inputs, &|[sum_x, sum_v, trial_x, trial_v], [x0, v0, a]| {
                let sums = sum_x.iter_mut().zip(sum_v);
                let trials = trial_x.iter_mut().zip(trial_v);
                for (((sum_x, sum_v), (trial_x, trial_v)), ((&x0, &v0), &a)) in
                    sums.zip(trials).zip(x0.iter().zip(v0).zip(a))
                {
                    *sum_x = v0;
                    *sum_v = a;
                    *trial_x = x0 + v0 * half;
                    *trial_v = v0 + a * half;
                }
            });
        }
        // Stages 2 and 3 at the midpoint; the trial state moves on to the next stage's.
        let midpoint = t + half.to_f64();
        for advance in [half, h] {
            dynamics.accelerations(&trial.positions, &trial.velocities, midpoint, accelerations);
            for axis in 0..3 {
                let outputs = [&mut *sum_x, &mut *sum_v, &mut trial.positions, &mut trial.velocities]
                    .map(|o| o.axis_mut(axis));
                let inputs = [&state.positions, &state.velocities, &*accelerations].map(|i| i.axis(axis));
                in_pieces(chunk, outputs, inputs, &|[sum_x, sum_v, trial_x, trial_v], [x0, v0, a]| {
                    let sums = sum_x.iter_mut().zip(sum_v);
                    let trials = trial_x.iter_mut().zip(trial_v);
                    for (((sum_x, sum_v), (trial_x, trial_v)), ((&x0, &v0), &a)) in
                        sums.zip(trials).zip(x0.iter().zip(v0).zip(a))
                    {
                        let v = *trial_v;
                        *sum_x += v * two;
                        *sum_v += a * two;
                        *trial_x = x0 + v * advance;
                        *trial_v = v0 + a * advance;
                    }
                });
            }
        }
        // Stage 4 at the end of the step.
        let end = t + h.to_f64();
        dynamics.accelerations(&trial.positions, &trial.velocities, end, accelerations);
        let sixth = h / T::from_f64(6.0);
        for axis in 0..3 {
            let outputs = [&mut state.positions, &mut state.velocities].map(|o| o.axis_mut(axis));
            let inputs = [&*sum_x, &*sum_v, &trial.velocities, &*accelerations].map(|i| i.axis(axis));
            in_pieces(chunk, outputs, inputs, &|[x, v], [sum_x, sum_v, trial_v, a]| {
                for ((x, &s), &u) in x.iter_mut().zip(sum_x).zip(trial_v) {
                    *x += (s + u) * sixth;
                }
                for ((v, &s), &a) in v.iter_mut().zip(sum_v).zip(a) {
                    *v += (s + a) * sixth;
                }
            });
        }
    }
}

/// Runs `update` on the particles' outputs and inputs (one axis each, all of one length), cut in
/// halves run side by side on the solver's threads (`rayon::join`, which allocates nothing) until
/// a piece has at most `chunk` particles. Each particle's update depends on that particle alone,
/// so the cut never changes a result.
fn in_pieces<T: Real, const O: usize, const I: usize>(
    chunk: usize,
    outputs: [&mut [T]; O],
    inputs: [&[T]; I],
    update: &(impl Fn([&mut [T]; O], [&[T]; I]) + Sync),
) {
    let n = inputs[0].len();
    if n <= chunk {
        update(outputs, inputs);
        return;
    }
    let middle = n.div_ceil(2);
    let mut low: [&mut [T]; O] = [(); O].map(|_| Default::default());
    let mut high: [&mut [T]; O] = [(); O].map(|_| Default::default());
    for ((low, high), output) in low.iter_mut().zip(&mut high).zip(outputs) {
        (*low, *high) = output.split_at_mut(middle);
    }
    let (low_inputs, high_inputs) = (inputs.map(|i| &i[..middle]), inputs.map(|i| &i[middle..]));
    rayon::join(|| in_pieces(chunk, low, low_inputs, update), || in_pieces(chunk, high, high_inputs, update));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_cover_every_particle_once_whatever_their_size() {
        let input: Vec<f64> = (0..37).map(|k| k as f64 * 0.5).collect();
        for chunk in [1, 3, 8, 36, 37, 100] {
            let mut output = vec![1.0; 37];
            in_pieces(chunk, [&mut output[..]], [&input[..]], &|[out], [input]| {
                for (o, &i) in out.iter_mut().zip(input) {
                    *o += 2.0 * i;
                }
            });
            let expected: Vec<f64> = input.iter().map(|i| 1.0 + 2.0 * i).collect();
            assert_eq!(output, expected, "pieces of {chunk}");
        }
    }
}
