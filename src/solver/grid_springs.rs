//! The springs of a cloth evaluated as row stencils: the fast force pass for grid bodies.
//!
//! A cloth's springs follow a fixed stencil, six families of the form `(i + ai, j + aj)` to
//! `(i + bi, j + bj)` with non-negative offsets, each with one rest length, stiffness and damping.
//! Along a grid row the first ends of a family are consecutive particles and so are the second
//! ends, so a family's springs on one row are two contiguous runs of each axis of the state: no
//! index lists. A family's springs along a row are evaluated a vector block at a time
//! ([`spring_blocks`](crate::solver::forces::spring_blocks)) and each block's forces go straight into the force
//! accumulators of both ends' rows.
//!
//! Rows are visited in order. A spring of row `j` reaches rows `j` to `j + reach` only, so once
//! row `j`'s springs are done, row `j` has its whole force: it is handed on (to the forces array,
//! or straight to the symplectic update, which then needs no force array at all) and its
//! accumulator is reused by row `j + reach + 1`. Only `reach + 1` rows of forces are ever live,
//! and they stay in the first-level cache.
//!
//! Large grids are cut into bands of rows run by the solver's threads
//! ([`parallel`](crate::solver::parallel)). A band owns its rows' forces and outputs; it recomputes the
//! `reach` rows of springs above it that reach into it, and drops their contributions to rows it
//! does not own. Every particle's force is therefore summed in the same order, by the same
//! operations, whatever the number of bands: results do not depend on the thread count.
//!
//! A grid too small to need its bands (a 32² cloth) still gains from them when the other
//! threads are idle, as for one job alone, but loses when they are busy, as in a sweep of small
//! jobs, where every thread runs a job of its own: its recomputed rows and the threads taking
//! each other's bands cost more than they give. Such a grid shares its bands out only while
//! another thread takes one ([`Sharing`]).
//!
//! The result is the same force as the general spring-list loop, summed in a different, fixed
//! order: deterministic, and equal to it up to rounding.

use std::ops::Range;

use crate::solver::forces::spring_blocks::{self as blocks, LANES};
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::{Model, Spring, SpringGrid};
use crate::solver::parallel;
use crate::solver::state::State;

/// One spring family of a grid: its stencil offsets and its parameters.
#[derive(Clone, Copy, Debug)]
struct Family<T> {
    /// `[ai, aj, bi, bj]`: the spring joins `(i + ai, j + aj)` to `(i + bi, j + bj)`.
    offsets: [usize; 4],
    rest_length: T,
    stiffness: T,
    damping: T,
}

/// The shape of a grid body's springs.
#[derive(Clone, Debug)]
struct Layout<T> {
    nx: usize,
    ny: usize,
    families: Vec<Family<T>>,
    /// The most rows a spring spans: row `j`'s springs reach rows `j..=j + reach`.
    reach: usize,
}

impl<T> Layout<T> {
    /// The length of a row's force accumulator: a row, rounded up to whole vectors, with room for
    /// a family's column offset.
    fn stride(&self) -> usize {
        self.nx.next_multiple_of(LANES) + LANES
    }
}

/// A band of rows with its scratch.
#[derive(Clone, Debug)]
struct Band<T> {
    rows: Range<usize>,
    /// Force accumulators of the `reach + 1` rows in flight, per axis: row `r` in slot
    /// `r % (reach + 1)`, and a last slot that takes, and drops, the forces on rows outside the
    /// band.
    ring: [Vec<T>; 3],
    /// One family's spring forces along a row, per axis, on their way to the second ends.
    staged: [Vec<T>; 3],
    /// Per column: `Σ m |v|²` and `Σ (x + y + z)` over the band's rows, for the stability watch.
    columns: [Vec<T>; 2],
    /// The totals of `columns` after the last symplectic step.
    sums: (T, T),
}

/// What a band does with its rows' forces. Rows are numbered from the band's first.
trait RowSink<T> {
    /// Sets the force a row starts from, before any spring adds to it.
    fn start(&mut self, row: usize, force: [&mut [T]; 3]);
    /// Takes a row's force once every spring has added to it (and may overwrite it).
    fn finish(&mut self, row: usize, force: [&mut [T]; 3]);
}

/// A cloth body whose springs are evaluated by stencil, with its per-band scratch.
#[derive(Clone, Debug)]
pub(crate) struct GridSprings<T> {
    first: usize,
    springs: Range<usize>,
    layout: Layout<T>,
    bands: Vec<Band<T>>,
    /// For a grid whose bands are optional, the one band it runs in while no other thread takes
    /// a band (empty otherwise).
    whole: Vec<Band<T>>,
    /// For such a grid, whether its next pass runs in bands.
    sharing: Option<Sharing>,
}

/// How a grid whose bands are optional runs a pass: in its bands while another thread takes one,
/// whole otherwise. [`MISSES`] passes in a row in bands whose other half no thread took send the
/// grid back to its whole band for [`RETRY_PASSES`] passes, after which it offers its bands
/// again: a grid beside busy threads pays for its bands on a few passes in every so many. More
/// than one miss is needed because a pool thread that had fallen asleep is only woken by the
/// first offer, too late to take it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sharing {
    passes_until_retry: u32,
    misses: u32,
}

/// The passes in a row whose bands no other thread took before a grid whose bands are optional
/// runs whole, and the passes it then runs whole.
const MISSES: u32 = 16;
const RETRY_PASSES: u32 = 256;

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
    fn splits(&self) -> bool {
        self.passes_until_retry == 0
    }

    /// Records a pass: whether it ran in bands, and if so whether another thread took one.
    fn after_pass(&mut self, split: bool, side_by_side: bool) {
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

/// What the body forces and the accelerations need from outside the grid: the particles'
/// masses, gravity and the drag rate.
pub(crate) struct BodyTerms<'a, T> {
    pub masses: &'a [T],
    pub inverse_masses: &'a [T],
    pub gravity: Vec3<T>,
    pub drag: T,
}

impl<T: Real> GridSprings<T> {
    /// The grid's stencil evaluator, if `springs[grid.springs]` are exactly the springs its stencil
    /// generates (in the builder's order) with one rest length, stiffness and damping per family
    /// in precision `T`; `None` otherwise, and the springs stay on the general path.
    pub fn new(grid: &SpringGrid, springs: &[Spring<T>]) -> Option<Self> {
        let [nx, ny] = grid.resolution;
        let springs = springs.get(grid.springs.clone())?;
        let at = |i: usize, j: usize| (grid.first_particle + j * nx + i) as u32;
        let mut families = Vec::with_capacity(grid.stencil.len());
        let mut next = springs.iter();
        for &offsets in &grid.stencil {
            let [ai, aj, bi, bj] = offsets;
            // A row's accumulator has room for column offsets below one vector.
            if ai.max(bi) >= LANES {
                return None;
            }
            let (reach_i, reach_j) = (ai.max(bi), aj.max(bj));
            let mut family: Option<Family<T>> = None;
            for j in 0..ny.saturating_sub(reach_j) {
                for i in 0..nx.saturating_sub(reach_i) {
                    let s = next.next()?;
                    if (s.i, s.j) != (at(i + ai, j + aj), at(i + bi, j + bj)) {
                        return None;
                    }
                    let this = Family {
                        offsets,
                        rest_length: s.rest_length,
                        stiffness: s.stiffness,
                        damping: s.damping,
                    };
                    match family {
                        None => family = Some(this),
                        Some(f)
                            if f.rest_length == this.rest_length
                                && f.stiffness == this.stiffness
                                && f.damping == this.damping => {}
                        Some(_) => return None,
                    }
                }
            }
            families.extend(family);
        }
        if next.next().is_some() {
            return None;
        }
        let reach = families.iter().map(|f| f.offsets[1].max(f.offsets[3])).max().unwrap_or(0);
        let layout = Layout { nx, ny, families, reach };
        let (particles, span) = (nx * ny, reach + 1);
        let needed = parallel::band_count_of_at_least(ny, particles, BAND_SPANS * span, BAND_PARTICLES);
        let optional = parallel::band_count_of_at_least(
            ny,
            particles,
            OPTIONAL_BAND_SPANS * span,
            OPTIONAL_BAND_PARTICLES,
        );
        let (first, springs) = (grid.first_particle, grid.springs.clone());
        Some(if needed == 1 && optional > 1 {
            Self::with_optional_bands(first, springs, layout, optional)
        } else {
            Self::with_bands(first, springs, layout, needed)
        })
    }

    /// The evaluator cut into `count` bands of rows (at most one per row).
    fn with_bands(first: usize, springs: Range<usize>, layout: Layout<T>, count: usize) -> Self {
        let bands = bands(&layout, count);
        Self { first, springs, layout, bands, whole: Vec::new(), sharing: None }
    }

    /// The evaluator cut into `count` bands of rows that it runs in only while another thread
    /// takes one.
    fn with_optional_bands(first: usize, springs: Range<usize>, layout: Layout<T>, count: usize) -> Self {
        let whole = bands(&layout, 1);
        let sharing = Some(Sharing::default());
        Self { whole, sharing, ..Self::with_bands(first, springs, layout, count) }
    }

    /// Runs one pass, `run(layout, bands)`, over the bands the grid runs in now, which `run`
    /// reports whether another thread took one of; returns those bands.
    fn pass(&mut self, run: impl FnOnce(&Layout<T>, &mut [Band<T>]) -> bool) -> &[Band<T>] {
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

    /// The particles of the body.
    pub fn particles(&self) -> Range<usize> {
        self.first..self.first + self.layout.nx * self.layout.ny
    }

    /// The springs of the model's list this body evaluates.
    pub fn springs(&self) -> Range<usize> {
        self.springs.clone()
    }

    /// Adds every spring force of the body to `forces`.
    pub fn add_forces(&mut self, x: &Vectors<T>, v: &Vectors<T>, forces: &mut Vectors<T>) {
        let range = self.particles();
        let (x, v) = (x.range(range.clone()), v.range(range.clone()));
        let nx = self.layout.nx;
        self.pass(|layout, bands| {
            in_bands(bands, nx, forces.range_mut(range), &|band, out| {
                band.sweep(layout, x, v, &mut AddTo { nx, out });
            })
        });
    }

    /// The acceleration of every particle of the body (gravity, drag and the springs, over the
    /// mass; zero for a pinned particle) into `out`, in one pass: the same values, by the same
    /// operations, as the forces pass followed by the division by the masses.
    pub fn accelerations(
        &mut self,
        inputs: &BodyTerms<T>,
        x: &Vectors<T>,
        v: &Vectors<T>,
        out: &mut Vectors<T>,
    ) {
        let range = self.particles();
        self.accelerations_by_rows(inputs, x, v, out.range_mut(range), &Store);
    }

    /// Computes the accelerations of the body's particles row by row, as
    /// [`accelerations`](Self::accelerations) does, and hands each row to `update` with the
    /// row's part of `outputs` (arrays over the body's particles), in the same pass: what an
    /// integrator does with the accelerations costs no pass of its own.
    pub fn accelerations_by_rows<const O: usize>(
        &mut self,
        inputs: &BodyTerms<T>,
        x: &Vectors<T>,
        v: &Vectors<T>,
        outputs: [&mut [T]; O],
        update: &impl AccelerationRows<T, O>,
    ) {
        let range = self.particles();
        let (x, v) = (x.range(range.clone()), v.range(range.clone()));
        let masses = &inputs.masses[range.clone()];
        let inverse_masses = &inputs.inverse_masses[range.clone()];
        let (nx, first) = (self.layout.nx, self.first);
        self.pass(|layout, bands| {
            in_bands(bands, nx, outputs, &|band, outputs| {
                let offset = band.rows.start * nx;
                let gravity = inputs.gravity.to_array();
                let body = BodyForce { offset, nx, v, masses, gravity, drag: inputs.drag };
                let sink = &mut Accelerations { body, first, inverse_masses, outputs, update };
                band.sweep(layout, x, v, sink);
            })
        });
    }

    /// One symplectic Euler step of the body from `state` into `next` (`v' = v + h f / m`, then
    /// `x' = x + h v'`), where `f` is gravity, drag and the springs. The forces never leave the
    /// row accumulators. Returns `Σ m |v'|²` and the sum of every component of `x'`, for the
    /// stability watch.
    pub fn symplectic_step(
        &mut self,
        inputs: &BodyTerms<T>,
        h: T,
        state: &State<T>,
        next: &mut State<T>,
    ) -> (T, T) {
        let range = self.particles();
        let (x, v) = (state.positions.range(range.clone()), state.velocities.range(range.clone()));
        let masses = &inputs.masses[range.clone()];
        let inverse_masses = &inputs.inverse_masses[range.clone()];
        let nx = self.layout.nx;
        let [px, py, pz] = next.positions.range_mut(range.clone());
        let [vx, vy, vz] = next.velocities.range_mut(range);
        let outputs = [px, py, pz, vx, vy, vz];
        let bands = self.pass(|layout, bands| {
            in_bands(bands, nx, outputs, &|band, [px, py, pz, vx, vy, vz]| {
                let mut sink = SymplecticUpdate {
                    offset: band.rows.start * nx,
                    nx,
                    x,
                    v,
                    masses,
                    inverse_masses,
                    gravity: inputs.gravity.to_array(),
                    drag: inputs.drag,
                    h,
                    positions: [px, py, pz],
                    velocities: [vx, vy, vz],
                    columns: band.take_columns(),
                };
                band.sweep(layout, x, v, &mut sink);
                band.put_back_columns(sink.columns);
            })
        });
        // Band by band, in order: the same sums whichever thread ran which band.
        bands.iter().fold((T::ZERO, T::ZERO), |(k, p), band| (k + band.sums.0, p + band.sums.1))
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
fn in_bands<T: Send, const O: usize>(
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

/// What a pass computing accelerations row by row does with each row of them, given the row's
/// part of its `O` output arrays.
pub(crate) trait AccelerationRows<T, const O: usize>: Sync {
    /// Takes the total force `force` on the particles `particles` (indices into the whole state)
    /// and their inverse masses, with the same particles of each output: their accelerations are
    /// `force * inverse_mass`, which the implementation computes where it uses them.
    fn take(&self, particles: Range<usize>, force: [&[T]; 3], inverse_masses: &[T], outputs: [&mut [T]; O]);
}

/// Writes the accelerations into the three outputs, one per axis.
struct Store;

impl<T: Real> AccelerationRows<T, 3> for Store {
    fn take(&self, _: Range<usize>, force: [&[T]; 3], inverse_masses: &[T], outputs: [&mut [T]; 3]) {
        for (out, f) in outputs.into_iter().zip(force) {
            for ((a, &f), &w) in out.iter_mut().zip(f).zip(inverse_masses) {
                *a = f * w;
            }
        }
    }
}

impl<T: Real> Band<T> {
    /// The band's column sums, zeroed, for a sink to fill.
    fn take_columns(&mut self) -> [Vec<T>; 2] {
        let mut columns = std::mem::take(&mut self.columns);
        for column in &mut columns {
            column.fill(T::ZERO);
        }
        columns
    }

    /// Keeps the column sums for the next step and their totals, summed column by column, in
    /// `sums`.
    fn put_back_columns(&mut self, columns: [Vec<T>; 2]) {
        let total = |column: &Vec<T>| column.iter().fold(T::ZERO, |sum, &c| sum + c);
        self.sums = (total(&columns[0]), total(&columns[1]));
        self.columns = columns;
    }

    /// Evaluates every spring that reaches the band's rows, row after row, handing each row's
    /// total force to `sink` as soon as it is complete.
    fn sweep(&mut self, layout: &Layout<T>, x: [&[T]; 3], v: [&[T]; 3], sink: &mut impl RowSink<T>) {
        let Layout { nx, ny, reach, .. } = *layout;
        let stride = layout.stride();
        let (first, end) = (self.rows.start, self.rows.end);
        let owned = |row: usize| (first..end).contains(&row);
        let dropped = reach + 1;
        let first_springs = first.saturating_sub(reach);
        for axis in &mut self.ring {
            axis[dropped * stride..].fill(T::ZERO);
        }
        for row in first..(first_springs + reach).min(end) {
            sink.start(row - first, ring_row(&mut self.ring, row, reach, stride).map(|axis| &mut axis[..nx]));
        }
        for j in first_springs..end {
            // Row `j + k`'s slot, for `k <= reach`, without a division per spring family.
            let slot_j = j % (reach + 1);
            let slot = |row: usize| {
                let slot = slot_j + (row - j);
                if !owned(row) {
                    dropped
                } else if slot > reach {
                    slot - (reach + 1)
                } else {
                    slot
                }
            };
            let entering = j + reach;
            if owned(entering) {
                sink.start(
                    entering - first,
                    ring_row(&mut self.ring, entering, reach, stride).map(|axis| &mut axis[..nx]),
                );
            }
            for family in &layout.families {
                let [ai, aj, bi, bj] = family.offsets;
                let (row_a, row_b) = (j + aj, j + bj);
                if row_a.max(row_b) >= ny || !(owned(row_a) || owned(row_b)) {
                    continue;
                }
                spring_row(
                    family,
                    x,
                    v,
                    [row_a * nx + ai, row_b * nx + bi],
                    nx - ai.max(bi),
                    &mut self.ring,
                    &mut self.staged,
                    [slot(row_a) * stride + ai, slot(row_b) * stride + bi],
                );
            }
            if j >= first {
                sink.finish(
                    j - first,
                    self.ring.each_mut().map(|axis| &mut axis[slot_j * stride..slot_j * stride + nx]),
                );
            }
        }
    }
}

/// The accumulator of `row`, per axis.
#[inline]
fn ring_row<T>(ring: &mut [Vec<T>; 3], row: usize, reach: usize, stride: usize) -> [&mut [T]; 3] {
    let slot = row % (reach + 1);
    ring.each_mut().map(|axis| &mut axis[slot * stride..(slot + 1) * stride])
}

/// The most bands a grid is cut into: more than the cores of any machine this runs on would
/// only add recomputed rows.
const MAX_BANDS: usize = 64;

/// Evaluates the `len` springs of one family along a row, from particles `p..` to `q..`, and adds
/// their forces to the accumulators in `ring` from `a` (first ends) and subtracts them from `b`
/// (second ends).
///
/// The springs in whole vectors go through [`row_blocks`]. When both ends lie on the same row,
/// the second ends' accumulators overlap the first ends', so their forces wait in `staged` and a
/// second loop subtracts them (one loop updating both would not vectorise). The last, partial vector is a block padded with springs of zero
/// force: the accumulators have room past the row, so no spring is left to a scalar remainder
/// loop, one spring per instruction where a block takes eight.
#[allow(clippy::too_many_arguments)]
#[inline]
fn spring_row<'a, T: Real>(
    family: &Family<T>,
    x: [&'a [T]; 3],
    v: [&'a [T]; 3],
    [p, q]: [usize; 2],
    len: usize,
    ring: &mut [Vec<T>; 3],
    staged: &mut [Vec<T>; 3],
    [a, b]: [usize; 2],
) {
    let whole = len - len % LANES;
    let blocks_of = |at: usize| {
        let [x0, x1, x2] = x.map(|axis| axis[at..at + whole].as_chunks::<LANES>().0);
        let [v0, v1, v2] = v.map(|axis| axis[at..at + whole].as_chunks::<LANES>().0);
        [x0, x1, x2, v0, v1, v2]
    };
    let (ends_a, ends_b) = (blocks_of(p), blocks_of(q));
    let overlapping = a.abs_diff(b) < whole;
    if overlapping {
        let first = ring.each_mut().map(|axis| axis[a..a + whole].as_chunks_mut::<LANES>().0);
        let second = staged.each_mut().map(|axis| axis[..whole].as_chunks_mut::<LANES>().0);
        row_blocks::<T, false>(family, ends_a, ends_b, first, second);
    } else {
        let [rx, ry, rz] = ring;
        let ((xa, xb), (ya, yb), (za, zb)) =
            (apart(rx, a, b, whole), apart(ry, a, b, whole), apart(rz, a, b, whole));
        row_blocks::<T, true>(family, ends_a, ends_b, [xa, ya, za], [xb, yb, zb]);
    }
    if whole < len {
        let (count, rest) = (len - whole, [family.rest_length; LANES]);
        let (k, c) = (family.stiffness, family.damping);
        let forces = if p.max(q) + whole + LANES <= x[0].len() {
            // Read on into the next row, and drop those springs' forces.
            let ends = |at| blocks::whole(x, v, at);
            let mut forces = blocks::forces(k, c, &rest, ends(p + whole), ends(q + whole));
            for axis in &mut forces {
                axis[count..].fill(T::ZERO);
            }
            forces
        } else {
            let ends_a = blocks::padded(x, v, p + whole, count);
            let ends_b = blocks::padded(x, v, q + whole, count);
            blocks::forces(k, c, &rest, ends_a.each_ref(), ends_b.each_ref())
        };
        blocks::subtract(ring.each_mut().map(Vec::as_mut_slice), b + whole, LANES, &forces);
        blocks::add(ring.each_mut().map(Vec::as_mut_slice), a + whole, LANES, &forces);
    }
    if overlapping {
        for (acc, staged) in ring.iter_mut().zip(staged.iter()) {
            for (f, &g) in acc[b..b + whole].iter_mut().zip(&staged[..whole]) {
                *f -= g;
            }
        }
    }
}

/// The blocks of `axis` from `a` and from `b`, `len` values each, `len` at most `|a - b|`.
#[inline(always)]
fn apart<T>(axis: &mut [T], a: usize, b: usize, len: usize) -> (&mut [[T; LANES]], &mut [[T; LANES]]) {
    let (low, high) = axis.split_at_mut(a.max(b));
    let (low, high) = (&mut low[a.min(b)..a.min(b) + len], &mut high[..len]);
    let (low, high) = (low.as_chunks_mut::<LANES>().0, high.as_chunks_mut::<LANES>().0);
    if a < b { (low, high) } else { (high, low) }
}

/// Evaluates a family's springs block by block, from the ends `ends_a` to `ends_b` (positions
/// then velocities, per component), adding each block's forces to `first` and either subtracting
/// them from `second` (`SUBTRACT`) or writing them there.
#[inline(always)]
fn row_blocks<T: Real, const SUBTRACT: bool>(
    family: &Family<T>,
    ends_a: [&[[T; LANES]]; 6],
    ends_b: [&[[T; LANES]]; 6],
    first: [&mut [[T; LANES]]; 3],
    second: [&mut [[T; LANES]]; 3],
) {
    let rest = [family.rest_length; LANES];
    let [xa, ya, za, ua, va, wa] = ends_a;
    let [xb, yb, zb, ub, vb, wb] = ends_b;
    let [fx, fy, fz] = first;
    let [gx, gy, gz] = second;
    for block in 0..xa.len() {
        let ends_a = [&xa[block], &ya[block], &za[block], &ua[block], &va[block], &wa[block]];
        let ends_b = [&xb[block], &yb[block], &zb[block], &ub[block], &vb[block], &wb[block]];
        let forces = blocks::forces(family.stiffness, family.damping, &rest, ends_a, ends_b);
        let first = [&mut fx[block], &mut fy[block], &mut fz[block]];
        let second = [&mut gx[block], &mut gy[block], &mut gz[block]];
        for ((first, second), lanes) in first.into_iter().zip(second).zip(&forces) {
            if SUBTRACT {
                for lane in 0..LANES {
                    second[lane] -= lanes[lane];
                }
            } else {
                *second = *lanes;
            }
            for lane in 0..LANES {
                first[lane] += lanes[lane];
            }
        }
    }
}

/// A sink that adds each row's spring forces to a band of a forces array: the row starts from
/// what the array holds (gravity and drag) and is written back complete.
struct AddTo<'a, T> {
    nx: usize,
    out: [&'a mut [T]; 3],
}

impl<T: Real> RowSink<T> for AddTo<'_, T> {
    fn start(&mut self, row: usize, force: [&mut [T]; 3]) {
        let cells = row * self.nx..(row + 1) * self.nx;
        for (f, out) in force.into_iter().zip(&self.out) {
            f.copy_from_slice(&out[cells.clone()]);
        }
    }

    fn finish(&mut self, row: usize, force: [&mut [T]; 3]) {
        let cells = row * self.nx..(row + 1) * self.nx;
        for (out, f) in self.out.iter_mut().zip(force) {
            out[cells.clone()].copy_from_slice(f);
        }
    }
}

/// A sink that turns each row's force straight into symplectic Euler's new state.
struct SymplecticUpdate<'a, T> {
    /// The band's first particle within the body.
    offset: usize,
    nx: usize,
    x: [&'a [T]; 3],
    v: [&'a [T]; 3],
    masses: &'a [T],
    inverse_masses: &'a [T],
    gravity: [T; 3],
    drag: T,
    h: T,
    /// The band's new positions and velocities.
    positions: [&'a mut [T]; 3],
    velocities: [&'a mut [T]; 3],
    /// Per column, summed over rows: `Σ m |v|²` and `Σ (x + y + z)`. Summing down the columns
    /// keeps the loop a plain element-wise one, which vectorises, where a sum along the row would
    /// not.
    columns: [Vec<T>; 2],
}

/// Gravity and drag on a band's rows: what their forces start from.
struct BodyForce<'a, T> {
    /// The band's first particle within the body.
    offset: usize,
    nx: usize,
    v: [&'a [T]; 3],
    masses: &'a [T],
    gravity: [T; 3],
    drag: T,
}

impl<T: Real> BodyForce<'_, T> {
    /// `(g - drag v) m` for each particle of `row` (numbered within the band).
    #[inline]
    fn start(&self, row: usize, force: [&mut [T]; 3]) {
        let cells = self.offset + row * self.nx..self.offset + (row + 1) * self.nx;
        let masses = &self.masses[cells.clone()];
        for ((f, v), g) in force.into_iter().zip(self.v).zip(self.gravity) {
            for ((f, &v), &m) in f.iter_mut().zip(&v[cells.clone()]).zip(masses) {
                *f = (g - v * self.drag) * m;
            }
        }
    }
}

/// A sink that hands each row's total force, whose accelerations are its force times the inverse
/// mass, to an [`AccelerationRows`].
struct Accelerations<'a, T, U, const O: usize> {
    body: BodyForce<'a, T>,
    /// The body's first particle in the whole state.
    first: usize,
    inverse_masses: &'a [T],
    /// The band's outputs.
    outputs: [&'a mut [T]; O],
    update: &'a U,
}

impl<T: Real, U: AccelerationRows<T, O>, const O: usize> RowSink<T> for Accelerations<'_, T, U, O> {
    fn start(&mut self, row: usize, force: [&mut [T]; 3]) {
        self.body.start(row, force);
    }

    fn finish(&mut self, row: usize, force: [&mut [T]; 3]) {
        let nx = self.body.nx;
        let local = row * nx..(row + 1) * nx;
        let cells = self.body.offset + local.start..self.body.offset + local.end;
        let inverse_masses = &self.inverse_masses[cells.clone()];
        let particles = self.first + cells.start..self.first + cells.end;
        let outputs = self.outputs.each_mut().map(|out| &mut out[local.clone()]);
        self.update.take(particles, force.map(|f| &*f), inverse_masses, outputs);
    }
}

impl<T: Real> RowSink<T> for SymplecticUpdate<'_, T> {
    fn start(&mut self, row: usize, force: [&mut [T]; 3]) {
        let body = BodyForce {
            offset: self.offset,
            nx: self.nx,
            v: self.v,
            masses: self.masses,
            gravity: self.gravity,
            drag: self.drag,
        };
        body.start(row, force);
    }

    fn finish(&mut self, row: usize, force: [&mut [T]; 3]) {
        let local = row * self.nx..(row + 1) * self.nx;
        let cells = self.offset + local.start..self.offset + local.end;
        let inverse_masses = &self.inverse_masses[cells.clone()];
        let h = self.h;
        let old = self.x.iter().zip(self.v).zip(force);
        for (((x, v), f), (new_x, new_v)) in
            old.zip(self.positions.iter_mut().zip(self.velocities.iter_mut()))
        {
            let (x, v) = (&x[cells.clone()], &v[cells.clone()]);
            let new = new_x[local.clone()].iter_mut().zip(&mut new_v[local.clone()]);
            for (((new_x, new_v), (&x, &v)), (&f, &w)) in
                new.zip(x.iter().zip(v)).zip(f.iter().zip(inverse_masses))
            {
                let velocity = (v + f * w * h).kept_speed();
                *new_v = velocity;
                *new_x = x + velocity * h;
            }
        }
        let [px, py, pz] = self.positions.each_ref().map(|axis| &axis[local.clone()]);
        let [vx, vy, vz] = self.velocities.each_ref().map(|axis| &axis[local.clone()]);
        let [kinetic, position] = &mut self.columns;
        let velocities = vx.iter().zip(vy).zip(vz);
        let positions = px.iter().zip(py).zip(pz);
        let sums = kinetic.iter_mut().zip(position.iter_mut()).zip(&self.masses[cells]);
        for (((kinetic, position), &m), (((&vx, &vy), &vz), ((&x, &y), &z))) in
            sums.zip(velocities.zip(positions))
        {
            *kinetic += m * (vx * vx + vy * vy + vz * vz);
            *position += x + y + z;
        }
    }
}

/// The grid records of a model whose springs this module can evaluate.
pub(crate) fn grids<T: Real>(model: &Model, springs: &[Spring<T>]) -> Vec<GridSprings<T>> {
    model.grids.iter().filter_map(|g| GridSprings::new(g, springs)).collect()
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::bodies::{Cloth, Orientation};
    use crate::solver::forces::springs;
    use crate::solver::model::SpringParams;

    /// A 13 × 5 cloth (13 is not a multiple of the vector width, so the tail loops run too) with
    /// springs of three different parameter sets, bent and moving so every spring is loaded.
    fn moving_cloth() -> (Model, Vectors<f64>, Vectors<f64>) {
        let mut model = Model::default();
        model.add_cloth(&Cloth {
            size: [1.2, 0.4],
            resolution: [13, 5],
            center: DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Vertical,
            mass: 0.3,
            velocity: DVec3::ZERO,
            structural: SpringParams { stiffness: 900.0, damping: 0.3 },
            shear: SpringParams { stiffness: 400.0, damping: 0.1 },
            bending: SpringParams { stiffness: 50.0, damping: 0.05 },
            pins: vec![],
        });
        let wave = |p: usize, a: f64| {
            DVec3::new((a * p as f64).sin(), (1.3 * a * p as f64).cos(), (0.7 * p as f64).sin())
        };
        let x = model
            .positions
            .iter()
            .enumerate()
            .map(|(p, &x)| Vec3::from_dvec3(x + wave(p, 0.37) * 0.01))
            .collect();
        let v = (0..model.particle_count()).map(|p| Vec3::from_dvec3(wave(p, 0.91))).collect();
        (model, x, v)
    }

    #[test]
    fn stencil_pass_gives_the_spring_list_force() {
        let (model, x, v) = moving_cloth();
        let springs: Vec<Spring<f64>> = model.springs.clone();
        let mut grid = GridSprings::new(&model.grids[0], &springs).expect("a builder's cloth is a grid");
        assert_eq!(grid.springs(), 0..springs.len());
        let mut by_stencil = Vectors::zeros(x.len());
        let mut by_list = Vectors::zeros(x.len());
        grid.add_forces(&x, &v, &mut by_stencil);
        springs::add_forces(&springs, &x, &v, &mut by_list);
        let largest = by_list.iter().map(|f| f.length()).fold(0.0, f64::max);
        assert!(largest > 1.0, "the springs are loaded: {largest}");
        for (a, b) in by_stencil.iter().zip(by_list.iter()) {
            assert!((a - b).length() <= 1e-12 * largest, "{a:?} against {b:?}");
        }
    }

    /// The same grid cut into `count` bands.
    fn banded(model: &Model, count: usize) -> GridSprings<f64> {
        let grid = GridSprings::new(&model.grids[0], &model.springs).expect("a builder's cloth is a grid");
        GridSprings::with_bands(grid.first, grid.springs.clone(), grid.layout, count)
    }

    #[test]
    fn forces_do_not_depend_on_the_number_of_bands() {
        let (model, x, v) = moving_cloth();
        let forces = |count: usize| {
            let mut grid = banded(&model, count);
            assert_eq!(
                grid.bands.len(),
                5usize.div_ceil(5usize.div_ceil(count)),
                "rows are shared out evenly"
            );
            let mut forces: Vectors<f64> = (0..x.len()).map(|p| Vec3::new(p as f64, -1.0, 0.5)).collect();
            grid.add_forces(&x, &v, &mut forces);
            forces
        };
        let one = forces(1);
        assert!(one.iter().any(|f| f.length() > 1.0));
        for count in 2..=5 {
            assert_eq!(forces(count), one, "{count} bands");
        }
    }

    /// Masses that differ from particle to particle, with particle 3 pinned: the masses and the
    /// inverse masses.
    fn masses(n: usize) -> (Vec<f64>, Vec<f64>) {
        let masses: Vec<f64> = (0..n).map(|p| 0.01 + 0.001 * p as f64).collect();
        let inverse = masses.iter().enumerate().map(|(p, m)| if p == 3 { 0.0 } else { 1.0 / m }).collect();
        (masses, inverse)
    }

    /// Gravity and a drag of 0.3 s⁻¹ on particles of `masses`.
    fn body_terms<'a>(masses: &'a [f64], inverse_masses: &'a [f64]) -> BodyTerms<'a, f64> {
        BodyTerms { masses, inverse_masses, gravity: Vec3::new(0.0, -9.81, 0.0), drag: 0.3 }
    }

    #[test]
    fn accelerations_do_not_depend_on_the_number_of_bands() {
        let (model, x, v) = moving_cloth();
        let n = x.len();
        let (masses, inverse_masses) = masses(n);
        let inputs = body_terms(&masses, &inverse_masses);
        let accelerations = |count: usize| {
            let mut out = Vectors::zeros(n);
            banded(&model, count).accelerations(&inputs, &x, &v, &mut out);
            out
        };
        let one = accelerations(1);
        assert_eq!(one.get(3), Vec3::ZERO, "a pinned particle does not accelerate");
        let mut forces = Vectors::zeros(n);
        springs::add_forces(&model.springs, &x, &v, &mut forces);
        let f = forces.get(40) + (inputs.gravity - v.get(40) * 0.3) * masses[40];
        assert!((one.get(40) - f * inverse_masses[40]).length() < 1e-9 * f.length() * inverse_masses[40]);
        for count in 2..=5 {
            assert_eq!(accelerations(count), one, "{count} bands");
        }
    }

    #[test]
    fn symplectic_steps_do_not_depend_on_the_number_of_bands() {
        let (model, x, v) = moving_cloth();
        let n = x.len();
        let (masses, inverse_masses) = masses(n);
        let inputs = body_terms(&masses, &inverse_masses);
        let step = |count: usize| {
            let mut grid = banded(&model, count);
            let state = State { positions: x.clone(), velocities: v.clone() };
            let mut next = State { positions: Vectors::zeros(n), velocities: Vectors::zeros(n) };
            let sums = grid.symplectic_step(&inputs, 1e-4, &state, &mut next);
            (next.positions, next.velocities, sums)
        };
        let (x1, v1, sums) = step(1);
        assert_eq!(
            x1.get(3),
            x.get(3) + v.get(3) * 1e-4,
            "a pinned particle drifts with its own velocity only"
        );
        let kinetic: f64 = masses.iter().zip(v1.iter()).map(|(m, v)| m * v.length_squared()).sum();
        assert!((sums.0 - kinetic).abs() < 1e-12 * kinetic, "{} against {kinetic}", sums.0);
        for count in 2..=5 {
            let (xs, vs, _) = step(count);
            assert_eq!((&xs, &vs), (&x1, &v1), "{count} bands");
        }
    }

    #[test]
    fn a_grid_whose_bands_are_optional_steps_as_its_whole_band_does_in_either_mode() {
        let (model, x, v) = moving_cloth();
        let n = x.len();
        let (masses, inverse_masses) = masses(n);
        let inputs = body_terms(&masses, &inverse_masses);
        let grid = banded(&model, 1);
        let mut sharing = GridSprings::with_optional_bands(grid.first, grid.springs.clone(), grid.layout, 3);
        let mut whole = banded(&model, 1);
        assert_eq!(sharing.bands.len(), 3);
        let mut a = State { positions: x.clone(), velocities: v.clone() };
        let mut b = a.clone();
        let mut next = State { positions: Vectors::zeros(n), velocities: Vectors::zeros(n) };
        for step in 0..6 {
            // Even steps in the bands, odd steps whole.
            sharing.sharing = Some(Sharing { passes_until_retry: step % 2, misses: 0 });
            sharing.symplectic_step(&inputs, 1e-4, &a, &mut next);
            std::mem::swap(&mut a, &mut next);
            whole.symplectic_step(&inputs, 1e-4, &b, &mut next);
            std::mem::swap(&mut b, &mut next);
            assert_eq!((&a.positions, &a.velocities), (&b.positions, &b.velocities), "step {step}");
        }
        assert_ne!(a.positions, x, "the cloth moved");
    }

    #[test]
    fn optional_bands_go_whole_after_offers_no_thread_takes_and_are_offered_again() {
        let mut sharing = Sharing::default();
        assert!(sharing.splits(), "a grid starts in its bands");
        for _ in 1..MISSES {
            sharing.after_pass(true, false);
            assert!(sharing.splits(), "a few misses may be a thread waking up");
        }
        sharing.after_pass(true, true);
        for _ in 1..MISSES {
            sharing.after_pass(true, false);
        }
        assert!(sharing.splits(), "a taken offer clears the misses before it");
        sharing.after_pass(true, false);
        for pass in 0..RETRY_PASSES {
            assert!(!sharing.splits(), "whole on pass {pass}");
            sharing.after_pass(false, false);
        }
        assert_eq!(sharing, Sharing::default(), "the bands are offered again, with no misses counted");
    }

    #[test]
    fn springs_that_differ_from_the_stencil_stay_on_the_list() {
        let (model, _, _) = moving_cloth();
        let mut springs = model.springs.clone();
        springs[7].rest_length *= 1.01;
        assert!(GridSprings::new(&model.grids[0], &springs).is_none());
        let mut springs = model.springs.clone();
        springs.swap(3, 4);
        assert!(GridSprings::new(&model.grids[0], &springs).is_none());
        assert!(GridSprings::new(&model.grids[0], &model.springs[1..]).is_none());
    }

    #[test]
    fn fused_symplectic_step_follows_the_spring_list_path() {
        use crate::solver::integrators::IntegratorKind;
        use crate::solver::simulation::{Config, Simulation};
        let (mut model, _, _) = moving_cloth();
        model.pin(0);
        let config =
            Config { integrator: IntegratorKind::SymplecticEuler, dt: 2e-4, drag: 0.5, ..Config::default() };
        let mut fused = Simulation::<f64>::new(&model, &config);
        model.grids.clear();
        let mut listed = Simulation::<f64>::new(&model, &config);
        for _ in 0..500 {
            fused.step().expect("stable");
            listed.step().expect("stable");
        }
        let (a, b) = (fused.state(), listed.state());
        assert_eq!(a.positions.get(0), b.positions.get(0), "the pin holds");
        let moved = (a.positions.get(40) - Vec3::from_dvec3(model.positions[40])).length();
        assert!(moved > 1e-3, "the cloth moved {moved} m");
        for (p, q) in a.positions.iter().zip(b.positions.iter()) {
            assert!((p - q).length() < 1e-9, "{p:?} against {q:?}");
        }
        assert!((fused.energy().kinetic - listed.energy().kinetic).abs() < 1e-9);
    }

    /// The performance peers' hanging cloth (`docs/performance.md`): N = 32, 1 s at 1e-4 s.
    /// Their NumPy, Taichi, Warp, Newton and C++ versions all end with the centre particle at
    /// y = 0.53204 and particle (0, 31) at y = 0.17014 (spread 4e-7 among them, in f32).
    fn peers_cloth_after_one_second<T: Real>() -> (f64, f64) {
        use crate::solver::integrators::IntegratorKind;
        use crate::solver::simulation::{Config, Simulation};
        let n = 32;
        let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
        let mut model = Model::default();
        model.add_cloth(&Cloth { pins: vec![[0, 0], [n - 1, 0]], ..Cloth::square_metre(n, springs) });
        let config = Config {
            integrator: IntegratorKind::SymplecticEuler,
            dt: 1e-4,
            drag: 0.01 * (n * n) as f64,
            ..Config::default()
        };
        let mut simulation = Simulation::<T>::new(&model, &config);
        for _ in 0..10_000 {
            simulation.step().expect("stable at the peers' step");
        }
        let y = |i: usize, j: usize| simulation.state().positions.get(j * n + i).y.to_f64();
        (y(n / 2, n / 2), y(0, n - 1))
    }

    #[test]
    fn the_peers_cloth_hangs_where_every_peer_puts_it() {
        for (centre, corner) in [peers_cloth_after_one_second::<f32>(), peers_cloth_after_one_second::<f64>()]
        {
            assert!((centre - 0.5320434).abs() < 3e-6, "centre at y = {centre}");
            assert!((corner - 0.1701399).abs() < 3e-6, "corner at y = {corner}");
        }
    }
}
