//! The classic fourth-order Runge-Kutta method, with forces re-evaluated at each of the four
//! stages on the whole state.
//!
//! For a scene whose passes fuse ([`Dynamics::has_fused_passes`]), each stage's update is done
//! row by row inside the pass that computes the stage's accelerations, which are never stored:
//! one pass per stage instead of two. The trial states then alternate between two buffers, since
//! a pass still reads rows of its input after it has written the rows before them. Both ways
//! perform the same operations on the same values, so they give the same bits.

use std::ops::Range;

use super::super::dynamics::Dynamics;
use super::super::grid_springs::AccelerationRows;
use super::super::{Real, State, Vectors, parallel};

#[derive(Debug)]
pub(crate) struct Rk4<T> {
    /// Trial state of the current stage.
    trial: State<T>,
    /// For a scene whose passes fuse, the other trial state.
    other_trial: Option<State<T>>,
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
    pub fn new(dynamics: &Dynamics<T>) -> Self {
        let particles = dynamics.masses.len();
        let zeros = || Vectors::zeros(particles);
        let fused = dynamics.has_fused_passes();
        Self {
            trial: State { positions: zeros(), velocities: zeros() },
            other_trial: fused.then(|| State { positions: zeros(), velocities: zeros() }),
            accelerations: if fused { Vectors::zeros(0) } else { zeros() },
            sum_x: zeros(),
            sum_v: zeros(),
            chunk: particles.div_ceil(parallel::band_count(particles, particles, 1)).max(1),
        }
    }

    pub fn step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        if self.other_trial.is_some() {
            self.fused_step(state, dynamics, h);
            return;
        }
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

    /// The step with each stage's update fused into its accelerations pass.
    fn fused_step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, h: T) {
        let half = h * T::from_f64(0.5);
        let Self { trial, other_trial, sum_x, sum_v, .. } = self;
        let other = other_trial.as_mut().expect("a fused step has two trial states");
        let [x0, v0] = [state.positions.axes(), state.velocities.axes()];
        let first = Stage { number: StageNumber::First, x0, v0, v: v0, advance: half };
        fused_stage(dynamics, &first, &state.positions, &state.velocities, sum_x, sum_v, trial);
        // Stages 2 and 3 at the midpoint, from one trial state into the other and back.
        let second = Stage { number: StageNumber::Second, x0, v0, v: trial.velocities.axes(), advance: half };
        fused_stage(dynamics, &second, &trial.positions, &trial.velocities, sum_x, sum_v, other);
        let third = Stage { number: StageNumber::Third, x0, v0, v: other.velocities.axes(), advance: h };
        fused_stage(dynamics, &third, &other.positions, &other.velocities, sum_x, sum_v, trial);
        let last = Last {
            sum_x: sum_x.axes(),
            sum_v: sum_v.axes(),
            v3: other.velocities.axes(),
            v: trial.velocities.axes(),
            sixth: h / T::from_f64(6.0),
        };
        let [x, y, z] = state.positions.axes_mut();
        let [u, v, w] = state.velocities.axes_mut();
        dynamics.accelerations_by_rows(&trial.positions, &trial.velocities, [x, y, z, u, v, w], &last);
    }
}

/// Stages 1 to 3 fused into their accelerations pass: with `v` the stage's trial velocity and
/// `a` its acceleration, adds `v` and `a` to the weighted sums (once in the first stage, twice
/// after) and writes the next trial state `x0 + v advance`, `v0 + a advance`. The outputs are the
/// sums of `x` and `v`, then the next trial's positions and velocities, per axis. The first
/// stage's `v` is `v0`, so its term of the sum of `x` is added by the second stage rather than
/// stored by the first: the same operations on the same values, one stream fewer.
struct Stage<'a, T> {
    number: StageNumber,
    x0: [&'a [T]; 3],
    v0: [&'a [T]; 3],
    v: [&'a [T]; 3],
    advance: T,
}

/// Which of stages 1 to 3 a [`Stage`] is.
#[derive(Clone, Copy, PartialEq, Eq)]
enum StageNumber {
    First,
    Second,
    Third,
}

impl<T: Real> AccelerationRows<T, 12> for Stage<'_, T> {
    fn take(&self, particles: Range<usize>, force: [&[T]; 3], inverse_masses: &[T], outputs: [&mut [T]; 12]) {
        let [sx, sy, sz, su, sv, sw, tx, ty, tz, tu, tv, tw] = outputs;
        let axes = [[sx, su, tx, tu], [sy, sv, ty, tv], [sz, sw, tz, tw]];
        for (axis, [sum_x, sum_v, trial_x, trial_v]) in axes.into_iter().enumerate() {
            let inputs = [
                &self.x0[axis][particles.clone()],
                &self.v0[axis][particles.clone()],
                &self.v[axis][particles.clone()],
                force[axis],
                inverse_masses,
            ];
            let outputs = [sum_x, sum_v, trial_x, trial_v];
            match self.number {
                StageNumber::First => stage_row::<T, 1>(inputs, outputs, self.advance),
                StageNumber::Second => stage_row::<T, 2>(inputs, outputs, self.advance),
                StageNumber::Third => stage_row::<T, 3>(inputs, outputs, self.advance),
            }
        }
    }
}

/// Stage `STAGE`'s update of one axis of a row (see [`Stage`]), from the row's force `f` and
/// inverse masses `w`.
#[inline(always)]
fn stage_row<T: Real, const STAGE: u8>(
    [x0, v0, v, f, w]: [&[T]; 5],
    [sum_x, sum_v, trial_x, trial_v]: [&mut [T]; 4],
    advance: T,
) {
    let n = x0.len();
    let (v0, v, f, w) = (&v0[..n], &v[..n], &f[..n], &w[..n]);
    let (sum_x, sum_v, trial_x, trial_v) =
        (&mut sum_x[..n], &mut sum_v[..n], &mut trial_x[..n], &mut trial_v[..n]);
    let two = T::from_f64(2.0);
    for i in 0..n {
        let a = f[i] * w[i];
        match STAGE {
            1 => sum_v[i] = a,
            2 => {
                sum_x[i] = v0[i] + v[i] * two;
                sum_v[i] += a * two;
            }
            _ => sum_v[i] += a * two,
        }
        trial_x[i] = x0[i] + v[i] * advance;
        trial_v[i] = v0[i] + a * advance;
    }
}

/// One of stages 1 to 3 from the trial state `(x, v)` into `next`.
fn fused_stage<T: Real>(
    dynamics: &mut Dynamics<T>,
    stage: &Stage<T>,
    x: &Vectors<T>,
    v: &Vectors<T>,
    sum_x: &mut Vectors<T>,
    sum_v: &mut Vectors<T>,
    next: &mut State<T>,
) {
    let [sx, sy, sz] = sum_x.axes_mut();
    let [su, sv, sw] = sum_v.axes_mut();
    let [tx, ty, tz] = next.positions.axes_mut();
    let [tu, tv, tw] = next.velocities.axes_mut();
    let outputs = [sx, sy, sz, su, sv, sw, tx, ty, tz, tu, tv, tw];
    dynamics.accelerations_by_rows(x, v, outputs, stage);
}

/// Stage 4 fused into its accelerations pass: `x += (Σx + v) h / 6`, `v += (Σv + a) h / 6` with
/// `v` the last trial velocity and `a` its acceleration. The third stage's term of `Σx`, twice its
/// trial velocity `v3`, is added here (one stream fewer than storing it there, the same
/// operations). The outputs are the state's positions and velocities, per axis.
struct Last<'a, T> {
    sum_x: [&'a [T]; 3],
    sum_v: [&'a [T]; 3],
    v3: [&'a [T]; 3],
    v: [&'a [T]; 3],
    sixth: T,
}

impl<T: Real> AccelerationRows<T, 6> for Last<'_, T> {
    fn take(&self, particles: Range<usize>, force: [&[T]; 3], inverse_masses: &[T], outputs: [&mut [T]; 6]) {
        let [x, y, z, u, v, w] = outputs;
        let two = T::from_f64(2.0);
        for (axis, (x, v)) in [(x, u), (y, v), (z, w)].into_iter().enumerate() {
            let p = particles.clone();
            let (sum_x, v3, v4) =
                (&self.sum_x[axis][p.clone()], &self.v3[axis][p.clone()], &self.v[axis][p.clone()]);
            for ((x, &s), (&v3, &v4)) in x.iter_mut().zip(sum_x).zip(v3.iter().zip(v4)) {
                *x += (s + v3 * two + v4) * self.sixth;
            }
            let sum_v = &self.sum_v[axis][p];
            for ((v, &s), (&f, &w)) in v.iter_mut().zip(sum_v).zip(force[axis].iter().zip(inverse_masses)) {
                *v += (s + f * w) * self.sixth;
            }
        }
    }
}

/// Runs `update` on the particles' outputs and inputs (one axis each, all of one length), cut in
/// halves run side by side on the solver's threads ([`parallel::join`], which allocates nothing) until
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
    parallel::join(
        || in_pieces(chunk, low, low_inputs, update),
        || in_pieces(chunk, high, high_inputs, update),
    );
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::super::super::{Cloth, Model, Orientation, SpringParams, Vec3};
    use super::*;

    #[test]
    fn fused_stages_give_the_bits_of_the_stored_accelerations() {
        // 19 × 23: rows that are not whole vectors, and enough rows for several bands.
        let mut model = Model::default();
        model.add_cloth(&Cloth {
            size: [0.9, 1.1],
            resolution: [19, 23],
            center: DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Vertical,
            mass: 0.4,
            velocity: DVec3::new(0.1, 0.0, -0.2),
            structural: SpringParams { stiffness: 800.0, damping: 0.2 },
            shear: SpringParams { stiffness: 300.0, damping: 0.1 },
            bending: SpringParams { stiffness: 40.0, damping: 0.05 },
            pins: vec![[0, 0], [18, 0]],
        });
        let mut dynamics = Dynamics::<f64>::new(&model, DVec3::new(0.0, -9.81, 0.0), 0.3);
        assert!(dynamics.has_fused_passes());
        let wave = |p: usize| Vec3::new((0.37 * p as f64).sin(), (0.5 * p as f64).cos(), 0.0) * 0.01;
        let start = State {
            positions: model
                .positions
                .iter()
                .enumerate()
                .map(|(p, &x)| Vec3::from_dvec3(x) + wave(p))
                .collect(),
            velocities: (0..model.particle_count()).map(|p| wave(p + 7) * 30.0).collect(),
        };
        let mut fused = Rk4::new(&dynamics);
        let mut stored = Rk4::new(&dynamics);
        stored.other_trial = None;
        stored.accelerations = Vectors::zeros(model.particle_count());
        let (mut a, mut b) = (start.clone(), start.clone());
        for _ in 0..20 {
            fused.step(&mut a, &mut dynamics, 0.0, 1e-3);
            stored.step(&mut b, &mut dynamics, 0.0, 1e-3);
        }
        let moved = (a.positions.get(200) - start.positions.get(200)).length();
        assert!(moved > 1e-3, "the cloth moved {moved} m");
        assert_eq!((a.positions, a.velocities), (b.positions, b.velocities));
    }

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
