//! The spatial error estimate (`error_estimate: "resolution"`): how far a cloth of a material is
//! from the continuum cloth, measured by running the scene again at coarser resolutions.
//!
//! Two companions run with the run's own step and to the same end (or each to its own rest, with
//! `stop_at_rest`): the scene at about half and at about a quarter of the resolution
//! ([`Coarser`](crate::scene::Coarser)). They are compared at the coarser scene's particles
//! ([`MaterialPoints`](crate::scene::MaterialPoints)): `a` the distance between the run and its
//! half, `b` between the half and the quarter, both at the quarter's particles. The order the
//! three show is `p = ln(rms b / rms a) / ln r`, `r` the spacing ratio between levels (2 for
//! grids of `2^k + 1` particles and disks of an even number of rings; the geometric mean of the
//! two ratios otherwise), and the run's error is about `|x_h − x_{2h}| / (r^p − 1)`, taken at
//! every particle of the half companion and reported as its maximum and root-mean-square, in
//! metres. The order used is the observed one held to [`ORDER_RANGE`], and the estimate is marked
//! `reliable: false` when the observed order lies outside it or the differences do not shrink
//! from the coarser pair to the finer (the resolutions are not yet in their asymptotic range, or
//! a non-smooth event such as a fold or a contact decides the shape).
//!
//! The companions have a quarter and a sixteenth of the run's particles; they run one after the
//! other beside the main run, as the time-step companions do, and cost about 5/16 of its work.

use std::ops::RangeInclusive;
use std::panic::{AssertUnwindSafe, catch_unwind};

use glam::DVec3;

use super::error_estimate::{Companion, ErrorEstimate, EstimateOutcome, root_mean_square, with_equilibrium};
use super::{Control, Outcome, Recording, simulate};
use crate::scene::{Coarser, Compiled, ErrorEstimateName};

/// The orders the spatial estimate uses, and outside of which it is not reliable: below 1/2
/// the differences barely shrink, and above 4 no cloth model converges.
pub const ORDER_RANGE: RangeInclusive<f64> = 0.5..=4.0;

/// Runs the scene and its coarser companions, and puts the spatial estimate into the main run's
/// statistics.
pub(super) fn execute_with_resolution_estimate(compiled: &Compiled, control: &Control) -> Recording {
    let (main, companions) = rayon::join(
        || simulate(compiled, control, true),
        || {
            // A companion that fails costs the estimate, never the run.
            catch_unwind(AssertUnwindSafe(|| {
                let at = ["at half the resolution", "at a quarter of the resolution"];
                compiled
                    .coarser
                    .iter()
                    .zip(at)
                    .map(|(c, at)| Companion::run(&c.compiled, control, at))
                    .collect::<Vec<_>>()
            }))
            .unwrap_or_else(|_| vec![Companion::failed()])
        },
    );
    let Outcome { mut recording, final_positions } = main;
    if let Some(fine) = final_positions {
        let unavailable = |reason: String| (*ORDER_RANGE.start(), EstimateOutcome::Unavailable { reason });
        let (order, outcome) =
            match companions.iter().map(|c| c.result.as_ref()).collect::<Result<Vec<_>, _>>() {
                Err(reason) => unavailable(reason.clone()),
                Ok(coarse) => match (&compiled.coarser[..], &coarse[..]) {
                    ([half, quarter], [(half_end, _), (quarter_end, _)]) => {
                        estimate(&fine, [half, quarter], [half_end, quarter_end])
                    }
                    _ => unavailable("the scene has no coarser companions".into()),
                },
            };
        let error = ErrorEstimate {
            method: ErrorEstimateName::Resolution,
            order,
            outcome,
            extra_wall_time_s: companions.iter().map(|c| c.wall_time_s).sum(),
            companion_step: None,
            equilibrium: None,
        };
        recording.stats.error = Some(with_equilibrium(error, compiled, control, &recording, &fine));
    }
    recording
}

/// The order used and the estimate, from the run's final positions and its companions'.
fn estimate(
    fine: &[DVec3],
    [half, quarter]: [&Coarser; 2],
    [half_end, quarter_end]: [&[DVec3]; 2],
) -> (f64, EstimateOutcome) {
    let to_half = distances(half.on_main.read(fine), half_end.iter().copied());
    let fine_to_half = distances(quarter.on_main.read(fine), quarter.on_finer.read(half_end));
    let half_to_quarter = distances(quarter.on_finer.read(half_end), quarter_end.iter().copied());
    let (finer, coarser) = (root_mean_square(&fine_to_half), root_mean_square(&half_to_quarter));
    let ratio = (half.on_finer.spacing_ratio * quarter.on_finer.spacing_ratio).sqrt();
    let observed = (finer > 0.0 && coarser > 0.0).then(|| (coarser / finer).ln() / ratio.ln());
    let order = observed.map_or(*ORDER_RANGE.start(), |p| p.clamp(*ORDER_RANGE.start(), *ORDER_RANGE.end()));
    let shrink = finer < coarser && largest(&fine_to_half) < largest(&half_to_quarter);
    let scale = 1.0 / (half.on_finer.spacing_ratio.powf(order) - 1.0);
    let outcome = EstimateOutcome::Estimate {
        max: largest(&to_half) * scale,
        rms: root_mean_square(&to_half) * scale,
        observed_order: observed,
        reliable: Some(shrink && observed.is_some_and(|p| ORDER_RANGE.contains(&p))),
    };
    (order, outcome)
}

/// The distance between each pair of points.
fn distances(a: impl Iterator<Item = DVec3>, b: impl Iterator<Item = DVec3>) -> Vec<f64> {
    a.zip(b).map(|(x, y)| x.distance(y)).collect()
}

fn largest(values: &[f64]) -> f64 {
    values.iter().copied().fold(0.0, f64::max)
}

/// The companions' work in steps of the run: their steps times their particles over the run's.
pub(super) fn planned_steps(compiled: &Compiled) -> u64 {
    let particles = compiled.model.particle_count().max(1) as u128;
    let coarser: u128 = compiled.coarser.iter().map(|c| c.compiled.model.particle_count() as u128).sum();
    let steps = (u128::from(compiled.steps) * coarser).div_ceil(particles);
    u64::try_from(steps).unwrap_or(u64::MAX)
}
