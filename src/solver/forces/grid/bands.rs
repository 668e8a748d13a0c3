//! Bands: a grid cut into runs of rows for the solver's threads, and when a small grid is cut.
//!
//! Large grids are cut into bands of rows run by the solver's threads
//! ([`parallel`](crate::solver::parallel)). A band owns its rows' forces and outputs; it
//! recomputes the `reach` rows of springs above it that reach into it, and drops their
//! contributions to rows it does not own. Every particle's force is therefore summed in the same
//! order, by the same operations, whatever the number of bands: results do not depend on the
//! thread count.
//!
//! A grid too small to need its bands (a 32² cloth) still gains from them when the other
//! threads are idle, as for one job alone, but loses when they are busy, as in a sweep of small
//! jobs, where every thread runs a job of its own: its recomputed rows and the threads taking
//! each other's bands cost more than they give. Such a grid shares its bands out only while
//! another thread takes one ([`Sharing`]).

use std::ops::Range;

use super::GridSprings;
use super::layout::Layout;
use crate::solver::math::real::Real;
use crate::solver::parallel;

/// A band of rows with its scratch.
#[derive(Clone, Debug)]
pub(crate) struct Band<T> {
    pub(crate) rows: Range<usize>,
    /// Force accumulators of the `reach + 1` rows in flight, per axis: row `r` in slot
    /// `r % (reach + 1)`, and a last slot that takes, and drops, the forces on rows outside the
    /// band.
    pub(super) ring: [Vec<T>; 3],
    /// One family's spring forces along a row, per axis, on their way to the second ends.
    pub(super) staged: [Vec<T>; 3],
    /// Per column: `Σ m |v|²` and `Σ (x + y + z)` over the band's rows, for the stability watch.
    columns: [Vec<T>; 2],
    /// The totals of `columns` after the last symplectic step.
    pub(crate) sums: (T, T),
}

/// How a grid whose bands are optional runs a pass: in its bands while another thread takes one,
/// whole otherwise. [`MISSES`] passes in a row in bands whose other half no thread took send the
/// grid back to its whole band for [`RETRY_PASSES`] passes, after which it offers its bands
/// again: a grid beside busy threads pays for its bands on a few passes in every so many. More
/// than one miss is needed because a pool thread that had fallen asleep is only woken by the
/// first offer, too late to take it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Sharing {
    pub(super) passes_until_retry: u32,
    pub(super) misses: u32,
}

/// The passes in a row whose bands no other thread took before a grid whose bands are optional
/// runs whole, and the passes it then runs whole.
pub(super) const MISSES: u32 = 16;
pub(super) const RETRY_PASSES: u32 = 256;

/// The fewest particles and rows (in spans of a spring, `reach + 1` rows) of a band: a grid
/// with bands this large always runs in them.
const BAND_PARTICLES: usize = parallel::MIN_PARTICLES_PER_BAND;
const BAND_SPANS: usize = 8;

/// The same for a grid whose bands are optional: a band of 512 particles is several times the
/// work of handing it to an awake thread.
const OPTIONAL_BAND_PARTICLES: usize = 512;
const OPTIONAL_BAND_SPANS: usize = 4;

impl Sharing {
    /// Whether the next pass runs in bands.
    pub(super) fn splits(&self) -> bool {
        self.passes_until_retry == 0
    }

    /// Records a pass: whether it ran in bands, and if so whether another thread took one.
    pub(super) fn after_pass(&mut self, split: bool, side_by_side: bool) {
        if !split {
            self.passes_until_retry -= 1;
        } else if side_by_side {
            self.misses = 0;
        } else {
            self.misses += 1;
            if self.misses == MISSES {
                *self = Self { passes_until_retry: RETRY_PASSES, misses: 0 };
            }
        }
    }
}

/// How many bands a grid of `layout` is cut into when it always runs in them, and how many when
/// its bands are optional.
pub(super) fn band_counts<T>(layout: &Layout<T>) -> (usize, usize) {
    let (particles, span) = (layout.nx * layout.ny, layout.reach + 1);
    let needed = parallel::band_count_of_at_least(layout.ny, particles, BAND_SPANS * span, BAND_PARTICLES);
    let optional = parallel::band_count_of_at_least(
        layout.ny,
        particles,
        OPTIONAL_BAND_SPANS * span,
        OPTIONAL_BAND_PARTICLES,
    );
    (needed, optional)
}

impl<T: Real> GridSprings<T> {
    /// The evaluator cut into `count` bands of rows (at most one per row).
    pub(super) fn with_bands(first: usize, springs: Range<usize>, layout: Layout<T>, count: usize) -> Self {
        let bands = bands(&layout, count);
        Self { first, springs, layout, bands, whole: Vec::new(), sharing: None }
    }

    /// The evaluator cut into `count` bands of rows that it runs in only while another thread
    /// takes one.
    pub(super) fn with_optional_bands(
        first: usize,
        springs: Range<usize>,
        layout: Layout<T>,
        count: usize,
    ) -> Self {
        let whole = bands(&layout, 1);
        let sharing = Some(Sharing::default());
        Self { whole, sharing, ..Self::with_bands(first, springs, layout, count) }
    }

    /// Runs one pass, `run(layout, bands)`, over the bands the grid runs in now, which `run`
    /// reports whether another thread took one of; returns those bands.
    pub(crate) fn pass(&mut self, run: impl FnOnce(&Layout<T>, &mut [Band<T>]) -> bool) -> &[Band<T>] {
        let Some(sharing) = &mut self.sharing else {
            run(&self.layout, &mut self.bands);
            return &self.bands;
        };
        let split = sharing.splits();
        let bands = if split { &mut self.bands } else { &mut self.whole };
        let side_by_side = run(&self.layout, bands);
        sharing.after_pass(split, side_by_side);
        bands
    }
}

/// The bands of a grid's layout cut into `count` bands of rows (at most one per row).
fn bands<T: Real>(layout: &Layout<T>, count: usize) -> Vec<Band<T>> {
    let ny = layout.ny.max(1);
    let band_rows = ny.div_ceil(count.clamp(1, ny.min(MAX_BANDS)));
    (0..ny.div_ceil(band_rows))
        .map(|b| Band {
            rows: b * band_rows..((b + 1) * band_rows).min(layout.ny),
            ring: std::array::from_fn(|_| vec![T::ZERO; (layout.reach + 2) * layout.stride()]),
            staged: std::array::from_fn(|_| vec![T::ZERO; layout.stride()]),
            columns: std::array::from_fn(|_| vec![T::ZERO; layout.nx]),
            sums: (T::ZERO, T::ZERO),
        })
        .collect()
}

/// Runs `work` on every band with its rows' part of `outputs` (rows of `nx` particles from the
/// first band's), the bands side by side on the solver's threads: halves of the bands are joined
/// ([`parallel::join`]), which allocates nothing. Returns whether the first split's halves ran
/// side by side.
pub(crate) fn in_bands<T: Send, const O: usize>(
    bands: &mut [Band<T>],
    nx: usize,
    outputs: [&mut [T]; O],
    work: &(impl Fn(&mut Band<T>, [&mut [T]; O]) + Sync),
) -> bool {
    match bands {
        [] => return false,
        [band] => {
            work(band, outputs);
            return false;
        }
        _ => {}
    }
    let middle = bands.len() / 2;
    let split = (bands[middle].rows.start - bands[0].rows.start) * nx;
    let (low_bands, high_bands) = bands.split_at_mut(middle);
    let mut low: [&mut [T]; O] = [(); O].map(|_| Default::default());
    let mut high: [&mut [T]; O] = [(); O].map(|_| Default::default());
    for ((low, high), output) in low.iter_mut().zip(&mut high).zip(outputs) {
        (*low, *high) = output.split_at_mut(split);
    }
    let (_, side_by_side) = parallel::join_side_by_side(
        || in_bands(low_bands, nx, low, work),
        || in_bands(high_bands, nx, high, work),
    );
    side_by_side
}

/// The most bands a grid is cut into: more than the cores of any machine this runs on would
/// only add recomputed rows.
const MAX_BANDS: usize = 64;

impl<T: Real> Band<T> {
    /// The band's column sums, zeroed, for a sink to fill.
    pub(crate) fn take_columns(&mut self) -> [Vec<T>; 2] {
        let mut columns = std::mem::take(&mut self.columns);
        for column in &mut columns {
            column.fill(T::ZERO);
        }
        columns
    }

    /// Keeps the column sums for the next step and their totals, summed column by column, in
    /// `sums`.
    pub(crate) fn put_back_columns(&mut self, columns: [Vec<T>; 2]) {
        let total = |column: &Vec<T>| column.iter().fold(T::ZERO, |sum, &c| sum + c);
        self.sums = (total(&columns[0]), total(&columns[1]));
        self.columns = columns;
    }
}
