//! A run's estimate of its own error, by Richardson extrapolation in the time step (the spatial
//! estimate, `resolution`, is [`resolution_estimate`](super::resolution_estimate)'s).
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
//! after it, to that time.
//!
//! A run near its stability limit, the usual choice for an explicit method, cannot have a
//! companion at twice its step. Its companions are then taken at half the step (and a quarter,
//! for `richardson3`): the same extrapolation holds with `r = 1/2`, the error of the run at `h`
//! being about `|x_h - x_{h/2}| / (1 - 2^-p)`. Halved companions are chosen from the start when an
//! explicit integrator's doubled step (or quadrupled, for `richardson3`) passes the stability
//! bound, and after the fact when a doubled companion diverges anyway; `companion_step` says
//! which was used, and `extra_wall_time_s` counts every companion run, the diverged ones
//! included. A companion that cannot take a single step, or a halved one that diverges too,
//! says so instead of an estimate.
//!
//! A scene with contacts (colliders or self-collision) has halved companions too. A contact is
//! an event inside a step that no integrator's order covers, so in contact the error does not
//! shrink as `h^p`: it stays on a plateau over a range of steps and then drops, and a step on the
//! far side of a change of contact history can be much further from the truth than the run. A
//! doubled companion can then be far worse than the run, and `1 / (2^p - 1)` scales the
//! difference down by 15 for RK4 where the error did not shrink at all. A halved companion is
//! about as accurate as the run or better, so `|x_h - x_{h/2}|` lies between `e(h) - e(h/2)` and
//! `e(h) + e(h/2)` whatever the order: near `e(h)` on a plateau, and `(1 - 2^-p) e(h)` where the
//! order holds. It costs twice the run's steps instead of half; docs/accuracy.md has the ratios
//! either way.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use glam::DVec3;

use super::{Control, Outcome, Recording, Status, resolution_estimate, simulate};
use crate::scene::{Compiled, ErrorEstimateName};
use crate::solver::{Equilibrium, IntegratorKind, equilibrium, stable_step};

/// The error estimate of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorEstimate {
    /// How it was estimated.
    pub method: ErrorEstimateName,
    /// The order `p` the extrapolation uses: the integrator's for `richardson` and
    /// `richardson3`, the observed one within [`ORDER_RANGE`](crate::run::ORDER_RANGE) for `resolution`.
    pub order: f64,
    /// The estimate, or why there is none.
    pub outcome: EstimateOutcome,
    /// Wall time of the companion runs, in seconds.
    pub extra_wall_time_s: f64,
    /// Whether the companions took larger or smaller steps than the run (`None` for
    /// `resolution`, whose companions take the run's step).
    pub companion_step: Option<CompanionStep>,
    /// For a run that stopped at rest: how far its final state is from static equilibrium.
    pub equilibrium: Option<Equilibrium>,
}

/// The companions' step against the run's own `h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompanionStep {
    /// `2h` (and `4h` for `richardson3`): cheap, and the default.
    Doubled,
    /// `h/2` (and `h/4`): when the doubled step would not be stable, or the scene has contacts.
    Halved,
}

impl CompanionStep {
    /// The name results use.
    pub fn name(self) -> &'static str {
        match self {
            Self::Doubled => "doubled",
            Self::Halved => "halved",
        }
    }

    /// The companions' step counts for a run of `steps` steps (`None` past `u64`).
    fn steps(self, method: ErrorEstimateName, steps: u64) -> Vec<Option<u64>> {
        let factors: &[u64] = match method {
            ErrorEstimateName::Richardson3 => &[2, 4],
            _ => &[2],
        };
        factors
            .iter()
            .map(|&f| match self {
                Self::Doubled => Some((steps / f).max(1)),
                Self::Halved => steps.checked_mul(f),
            })
            .collect()
    }
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
        /// With `richardson3` and `resolution`: the order the three runs show (`None` if the
        /// runs agree exactly).
        observed_order: Option<f64>,
        /// With `richardson3`: whether the observed order is within 30 % of the assumed one;
        /// with `resolution`, whether it is within [`ORDER_RANGE`](crate::run::ORDER_RANGE) and the differences shrink.
        reliable: Option<bool>,
    },
    /// No estimate: a halved companion diverged too, or the companions were cancelled.
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
    let choose = |steps: u64| companion_step(compiled, method, steps);
    let companions_to = |spacing: CompanionStep, steps: u64, end: f64| -> Vec<Companion> {
        spacing
            .steps(method, steps)
            .into_iter()
            .map(|n| run_companion(compiled, control, n, steps, end))
            .collect()
    };
    let (first_choice, main, mut companions) = if compiled.stop_at_rest.is_some() {
        let main = simulate(compiled, control, true);
        let (steps, end) = main_extent(compiled, &main);
        let spacing = choose(steps);
        (spacing, main, companions_to(spacing, steps, end))
    } else {
        let spacing = choose(compiled.steps);
        let (main, companions) = rayon::join(
            || simulate(compiled, control, true),
            || {
                // A companion that fails costs the estimate, never the run.
                catch_unwind(AssertUnwindSafe(|| companions_to(spacing, compiled.steps, compiled.duration)))
                    .unwrap_or_else(|_| vec![Companion::failed()])
            },
        );
        (spacing, main, companions)
    };
    let mut spacing = first_choice;
    if spacing == CompanionStep::Doubled && companions.iter().any(|c| c.diverged) && !control.is_cancelled() {
        let (steps, end) = main_extent(compiled, &main);
        let spent: f64 = companions.iter().map(|c| c.wall_time_s).sum();
        let halved = catch_unwind(AssertUnwindSafe(|| companions_to(CompanionStep::Halved, steps, end)))
            .unwrap_or_else(|_| vec![Companion::failed()]);
        companions = halved;
        if let Some(first) = companions.first_mut() {
            first.wall_time_s += spent;
        }
        spacing = CompanionStep::Halved;
    }
    let Outcome { mut recording, final_positions } = main;
    if let Some(fine) = final_positions {
        let h = recording.stats.dt;
        let error = estimate(compiled, method, &fine, h, &companions, spacing);
        recording.stats.error = Some(with_equilibrium(error, compiled, control, &recording, &fine));
    }
    recording
}

/// The estimate with, for a run that stopped at rest, its distance from static equilibrium.
pub(super) fn with_equilibrium(
    mut error: ErrorEstimate,
    compiled: &Compiled,
    control: &Control,
    recording: &Recording,
    fine: &[DVec3],
) -> ErrorEstimate {
    let interrupt = control.interrupt();
    error.equilibrium = recording
        .stats
        .stopped_at_rest
        .and_then(|t| equilibrium(&compiled.model, &compiled.config, fine, t, &interrupt));
    error
}

/// The companions' step for a run of `steps` steps, chosen before they run: halved when the
/// scene has contacts, or when the doubled step would pass the stability bound that an explicit
/// integrator's own step keeps, or would leave no step at all.
pub fn companion_step(compiled: &Compiled, method: ErrorEstimateName, steps: u64) -> CompanionStep {
    if has_contacts(compiled) || doubled_step_is_unstable(compiled, method) || steps < largest_factor(method)
    {
        CompanionStep::Halved
    } else {
        CompanionStep::Doubled
    }
}

/// The steps of the companions an estimate plans for a run of `compiled.steps` steps (0 without
/// an estimate; for `resolution`, counted in steps of the run by the companions' share of its
/// particles). A doubled companion that diverges all the same is followed by halved ones, at
/// twice (six times, for `richardson3`) the run's steps more, which only the job's wall time
/// bounds: it happens only where the stability bound did not foresee the divergence.
pub fn planned_companion_steps(compiled: &Compiled) -> u64 {
    let method = compiled.error_estimate;
    match method {
        ErrorEstimateName::None => return 0,
        ErrorEstimateName::Resolution => return resolution_estimate::planned_steps(compiled),
        _ => {}
    }
    companion_step(compiled, method, compiled.steps)
        .steps(method, compiled.steps)
        .into_iter()
        .map(|n| n.unwrap_or(u64::MAX))
        .fold(0, u64::saturating_add)
}

/// The steps the main run took and the time it reached: the companions' span.
fn main_extent(compiled: &Compiled, main: &Outcome) -> (u64, f64) {
    let steps = main.recording.stats.steps;
    let end = main.recording.frames.times.last().copied();
    (steps, end.unwrap_or(steps as f64 * compiled.config.dt))
}

/// The largest factor between the run's step and a companion's.
fn largest_factor(method: ErrorEstimateName) -> u64 {
    match method {
        ErrorEstimateName::Richardson3 => 4,
        _ => 2,
    }
}

/// Whether particles can meet a collider or each other: events inside a step that break the
/// smoothness a doubled companion's extrapolation assumes.
fn has_contacts(compiled: &Compiled) -> bool {
    !compiled.config.colliders.is_empty() || compiled.config.self_collision.is_some()
}

/// Whether an explicit integrator's step is within its stability bound and its largest
/// companion step is not. (A run already past the bound is left to its watch: it diverges, or
/// its doubled companion shows how far it is from its own asymptotic regime.)
fn doubled_step_is_unstable(compiled: &Compiled, method: ErrorEstimateName) -> bool {
    let integrator = compiled.config.integrator;
    if integrator == IntegratorKind::ImplicitEuler {
        return false;
    }
    let dt = compiled.config.dt;
    let largest = largest_factor(method) as f64 * dt;
    stable_step(&compiled.model, compiled.config.drag)
        .map(|bound| bound * integrator.stability_factor())
        .is_some_and(|bound| dt <= bound && largest > bound)
}

/// A companion's end state and step, or why it has none, and its wall time.
pub(super) struct Companion {
    pub(super) result: Result<(Vec<DVec3>, f64), String>,
    diverged: bool,
    pub(super) wall_time_s: f64,
}

impl Companion {
    pub(super) fn failed() -> Self {
        Self { result: Err("the companion run failed".into()), diverged: false, wall_time_s: 0.0 }
    }

    /// Runs `coarse`, the companion `at` (in words: "at dt = 4.000e-4 s").
    pub(super) fn run(coarse: &Compiled, control: &Control, at: &str) -> Self {
        let started = Instant::now();
        let Outcome { recording, final_positions } = simulate(coarse, control, false);
        let result = match (recording.stats.status, final_positions) {
            (Status::Succeeded, Some(positions)) => Ok((positions, coarse.config.dt)),
            (Status::Diverged, _) => Err(match &recording.stats.diverged {
                Some(d) => format!("the companion {at} diverged at step {} (t = {} s)", d.step, d.t),
                None => format!("the companion {at} diverged"),
            }),
            (Status::Failed, _) => Err(format!(
                "the companion {at} failed: {}",
                recording.stats.failure.as_deref().unwrap_or("a stage met more than it may hold")
            )),
            _ => Err("the companion run was cancelled".into()),
        };
        let diverged = recording.stats.status == Status::Diverged;
        Self { result, diverged, wall_time_s: started.elapsed().as_secs_f64() }
    }
}

/// A companion of `companion_steps` steps over the main run's first `steps` steps (`duration`).
fn run_companion(
    compiled: &Compiled,
    control: &Control,
    companion_steps: Option<u64>,
    steps: u64,
    duration: f64,
) -> Companion {
    let Some(coarse) = companion_steps.map(|n| compiled.companion(n, duration)) else {
        return Companion {
            result: Err(format!("the run has too many steps ({steps}) for a companion at half its step")),
            diverged: false,
            wall_time_s: 0.0,
        };
    };
    Companion::run(&coarse, control, &format!("at dt = {:.3e} s", coarse.config.dt))
}

fn estimate(
    compiled: &Compiled,
    method: ErrorEstimateName,
    fine: &[DVec3],
    h: f64,
    companions: &[Companion],
    companion_step: CompanionStep,
) -> ErrorEstimate {
    let order = compiled.config.integrator.order();
    let extra_wall_time_s = companions.iter().map(|c| c.wall_time_s).sum();
    let outcome = match companions.iter().map(|c| c.result.as_ref()).collect::<Result<Vec<_>, _>>() {
        Err(reason) => EstimateOutcome::Unavailable { reason: reason.clone() },
        Ok(coarse) => {
            let (first, first_dt) = (&coarse[0].0, coarse[0].1);
            // |r^p - 1| with r = H / h: 2^p - 1 for a doubled step, 1 - 2^-p for a halved one.
            let scale = 1.0 / ((first_dt / h).powi(order as i32) - 1.0).abs();
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
    ErrorEstimate {
        method,
        order: f64::from(order),
        outcome,
        extra_wall_time_s,
        companion_step: Some(companion_step),
        equilibrium: None,
    }
}

pub(super) fn root_mean_square(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}
