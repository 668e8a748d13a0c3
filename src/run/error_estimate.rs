//! A run's estimate of its own error, by Richardson extrapolation.
//!
//! A companion run of the same scene at a step `H ≈ 2h` ends at the same time; for an integrator
//! of order `p` the error of the run at `h` is about `|x_h - x_H| / (r^p - 1)` with `r = H / h`,
//! taken per particle at the final time and reported as its maximum and root-mean-square, in
//! metres. `richardson3` adds a companion at `≈ 4h`: the ratio of the two differences measures
//! the order actually seen, and the estimate is flagged unreliable when that ratio is more than
//! 30 % off `2^p` (the run is not yet in its asymptotic regime, or something non-smooth such as
//! a contact dominates).
//!
//! Companions run beside the main run, one after another, as a second task of the solver's pool
//! (see [`parallel`](crate::solver::parallel)): on a machine with a core to spare they add little
//! wall time, and when the cores are all busy they wait their turn rather than oversubscribe
//! them. Their own wall time is reported as `extra_wall_time_s`.
//! With `stop_at_rest` the end time is known only when the main run stops, so the companions run
//! after it, to that time. A companion that diverges or cannot take a single step says so
//! instead of an estimate.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use glam::DVec3;

use super::{Control, Outcome, Recording, Status, simulate};
use crate::scene::{Compiled, ErrorEstimateName};

/// The error estimate of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorEstimate {
    /// How it was estimated.
    pub method: ErrorEstimateName,
    /// The integrator's order `p` the extrapolation assumes.
    pub order: u32,
    /// The estimate, or why there is none.
    pub outcome: EstimateOutcome,
    /// Wall time of the companion runs, in seconds.
    pub extra_wall_time_s: f64,
}

/// What the companions gave.
#[derive(Clone, Debug, PartialEq)]
pub enum EstimateOutcome {
    /// An estimate of the position error at the final time.
    Estimate {
        /// Largest per-particle error, in metres.
        max: f64,
        /// Root-mean-square per-particle error, in metres.
        rms: f64,
        /// With `richardson3`: the order the three runs show (`None` if the runs agree exactly).
        observed_order: Option<f64>,
        /// With `richardson3`: whether the observed order is within 30 % of the assumed one.
        reliable: Option<bool>,
    },
    /// No estimate: a companion diverged, was cancelled, or had too few steps.
    Unavailable {
        /// Why, in words.
        reason: String,
    },
}

/// Runs the scene and its companions, and puts the estimate into the main run's statistics.
pub(super) fn execute_with_estimate(
    compiled: &Compiled,
    control: &Control,
    method: ErrorEstimateName,
) -> Recording {
    let factors: &[u64] = match method {
        ErrorEstimateName::Richardson3 => &[2, 4],
        _ => &[2],
    };
    let (main, companions): (Outcome, Vec<Companion>) = if compiled.stop_at_rest.is_some() {
        let main = simulate(compiled, control, true);
        let (steps, duration) = (main.recording.stats.steps, main.recording.frames.times.last().copied());
        let end = duration.unwrap_or(steps as f64 * compiled.config.dt);
        let companions = factors.iter().map(|&f| run_companion(compiled, control, f, steps, end)).collect();
        (main, companions)
    } else {
        rayon::join(
            || simulate(compiled, control, true),
            || {
                let companion = |f| run_companion(compiled, control, f, compiled.steps, compiled.duration);
                // A companion that fails costs the estimate, never the run.
                let guarded = |f| {
                    catch_unwind(AssertUnwindSafe(|| companion(f))).unwrap_or_else(|_| Companion::failed())
                };
                factors.iter().map(|&f| guarded(f)).collect()
            },
        )
    };
    let Outcome { mut recording, final_positions } = main;
    if let Some(fine) = final_positions {
        let h = recording.stats.dt;
        recording.stats.error = Some(estimate(compiled, method, &fine, h, &companions));
    }
    recording
}

/// A companion's end state, or why it has none, and its wall time.
struct Companion {
    result: Result<(Vec<DVec3>, f64), String>,
    wall_time_s: f64,
}

impl Companion {
    fn failed() -> Self {
        Self { result: Err("the companion run failed".into()), wall_time_s: 0.0 }
    }
}

fn run_companion(
    compiled: &Compiled,
    control: &Control,
    factor: u64,
    steps: u64,
    duration: f64,
) -> Companion {
    let started = Instant::now();
    let Some(coarse) = compiled.companion(factor, steps, duration) else {
        return Companion {
            result: Err(format!("the run has too few steps ({steps}) for a companion at {factor}× the step")),
            wall_time_s: 0.0,
        };
    };
    let Outcome { recording, final_positions } = simulate(&coarse, control, false);
    let result = match (recording.stats.status, final_positions) {
        (Status::Succeeded, Some(positions)) => Ok((positions, coarse.config.dt)),
        (Status::Diverged, _) => Err(match &recording.stats.diverged {
            Some(d) => format!(
                "the companion at dt = {:.3e} s diverged at step {} (t = {} s)",
                coarse.config.dt, d.step, d.t
            ),
            None => format!("the companion at dt = {:.3e} s diverged", coarse.config.dt),
        }),
        (Status::Failed, _) => Err(format!(
            "the companion at dt = {:.3e} s failed: {}",
            coarse.config.dt,
            recording.stats.failure.as_deref().unwrap_or("a stage met more than it may hold")
        )),
        _ => Err("the companion run was cancelled".into()),
    };
    Companion { result, wall_time_s: started.elapsed().as_secs_f64() }
}

fn estimate(
    compiled: &Compiled,
    method: ErrorEstimateName,
    fine: &[DVec3],
    h: f64,
    companions: &[Companion],
) -> ErrorEstimate {
    let order = compiled.config.integrator.order();
    let extra_wall_time_s = companions.iter().map(|c| c.wall_time_s).sum();
    let outcome = match companions.iter().map(|c| c.result.as_ref()).collect::<Result<Vec<_>, _>>() {
        Err(reason) => EstimateOutcome::Unavailable { reason: reason.clone() },
        Ok(coarse) => {
            let (first, first_dt) = (&coarse[0].0, coarse[0].1);
            let scale = 1.0 / ((first_dt / h).powi(order as i32) - 1.0);
            let differences: Vec<f64> = fine.iter().zip(first).map(|(a, b)| a.distance(*b)).collect();
            let max = differences.iter().copied().fold(0.0, f64::max) * scale;
            let rms_difference = root_mean_square(&differences);
            let (observed_order, reliable) = match coarse.get(1) {
                None => (None, None),
                Some((second, second_dt)) => {
                    let further: Vec<f64> = first.iter().zip(second).map(|(a, b)| a.distance(*b)).collect();
                    let ratio = root_mean_square(&further) / rms_difference;
                    let step_ratio = second_dt / first_dt;
                    let observed = (ratio.is_finite() && ratio > 0.0).then(|| ratio.ln() / step_ratio.ln());
                    let expected = step_ratio.powi(order as i32);
                    (observed, Some(ratio.is_finite() && (ratio / expected - 1.0).abs() <= 0.3))
                }
            };
            EstimateOutcome::Estimate { max, rms: rms_difference * scale, observed_order, reliable }
        }
    };
    ErrorEstimate { method, order, outcome, extra_wall_time_s }
}

fn root_mean_square(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}
