//! A geometric multigrid V-cycle on a grid cloth, used as the conjugate-gradient preconditioner.
//!
//! Level 0 is the step's system on the cloth's grid, or its copy in the hierarchy's precision
//! (an `f64` step is preconditioned in `f32`), with a fabric's bending elements applied beside it
//! ([`level_bending`](super::level_bending)). Each coarser level keeps every other particle in
//! both directions (`⌈n/2⌉`; on an even grid the last fine column and row are extrapolated from
//! the last coarse one) and is the Galerkin product `Pᵀ A P` of the level above
//! ([`galerkin`](super::galerkin)), bending included. Level 0 is renewed every step; the caller
//! decides when the coarse levels are refilled from it ([`Multigrid::refill_coarse`]): a drape's
//! system changes little from one step to the next, and the coarse correction of a nearby system
//! still preconditions it well.
//!
//! Galerkin levels, not the cloth rediscretised on the coarse grid: a rediscretised level is the
//! springs between the coarse particles at their current positions, which stands for the fine
//! level while the cloth is smooth and stretched; once it is in contact and compressed (folds
//! finer than the coarse spacing, springs slack) it no longer does, and the drape onto a sphere at
//! the frame interval took 130 to 270 iterations a solve with it where the Galerkin levels take
//! 40 to 60. On a hanging cloth the two take about as many iterations (`docs/decisions.md`).
//!
//! Transfers are bilinear interpolation `P` and its transpose, and a coarse particle is held
//! fixed when a pinned fine particle takes its value alone. Each output row of a transfer is
//! computed alone from its input rows (a coarse row gathers its fine children), so on a grid
//! whose products run on the pool's threads the transfers are split over them too, with the same
//! bits. Smoothing is damped block Jacobi, one sweep before and one after the coarse correction
//! (level 0 damped by 0.9, each coarse level by its own damping from its largest eigenvalue), and
//! the coarsest level (at most [`COARSEST_PARTICLES`] particles) is solved exactly by a dense
//! Cholesky factorisation in `f64`. Pre- and post-smoothing match and the transfers are each
//! other's transposes, so the cycle is a symmetric positive definite operator, as conjugate
//! gradients needs.
//!
//! A step may give a filter: a symmetric projection `S_p` per particle (`I − n nᵀ` for a particle
//! held on a contact plane of normal `n`, the identity for a free one). The cycle then
//! preconditions the filtered system `S A S + (I − S)` of filtered conjugate gradients: level 0 is
//! `S A S` as blocks, its smoother inverts `S D S + (I − S)`, interpolation is followed by `S`
//! and restriction preceded by it, so every coarse level is `Pᵀ S A S P` and inherits the
//! constraints; on each held particle the cycle returns the held part of its input unchanged and
//! adds nothing to it.

use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use std::any::Any;

use super::dense_cholesky::DenseCholesky;
use super::galerkin::{BlockStencil, FORWARD, held_smoother, parent_weights, slot};
use super::grid_operator::{Family, Field, GridOperator, zero_field};
use super::level_bending::{BendingMatrices, LevelBending};
use crate::solver::parallel::in_bands;

/// The coarsest level has at most this many particles and is solved directly.
pub(crate) const COARSEST_PARTICLES: usize = 16;

/// A coarse level: its operator, the level above coarsened along y alone (the first half of
/// the Galerkin product), the cycle's right-hand side, correction and residual, and the power
/// iteration's vector for its smoother's damping, kept between steps.
#[derive(Debug)]
struct Level<T> {
    operator: BlockStencil<T>,
    across: BlockStencil<T>,
    /// The weights of the parents of each column of the level above.
    column_weights: [Vec<T>; 2],
    rhs: Field<T>,
    solution: Field<T>,
    residual: Field<T>,
    power: Field<T>,
}

/// The hierarchy, its transfers and the coarsest level's dense factor.
#[derive(Debug)]
pub(crate) struct Multigrid<T> {
    /// Level 0: the step's system, with its bending elements applied beside it.
    fine: GridOperator<T>,
    bending: Option<LevelBending<T>>,
    /// Level 0 as blocks, filtered by the step's filter and the pins: the first Galerkin
    /// product's input, and level 0 of the cycle when a filter holds particles.
    blocks: BlockStencil<T>,
    /// The particles the step's filter holds, and the filter `S_p` of each particle.
    held: Vec<usize>,
    filter: Vec<Sym3<T>>,
    /// Level 0's right-hand side, correction and residual.
    rhs: Field<T>,
    solution: Field<T>,
    residual: Field<T>,
    coarse: Vec<Level<T>>,
    coarsest: DenseCholesky,
}

impl<T: Real> Multigrid<T> {
    /// The hierarchy for an `nx × ny` grid, with `bending` (level 0's) when given, or `None`
    /// when the grid cannot be coarsened to a direct solve (a strip too narrow to halve) or a
    /// family or bending element reaches further than the levels' stencil.
    pub fn new(
        nx: usize,
        ny: usize,
        families: Vec<Family<T>>,
        pinned: Vec<usize>,
        bending: Option<BendingMatrices>,
    ) -> Option<Self> {
        let n = nx * ny;
        let fine = GridOperator::new(nx, ny, &families, pinned.clone());
        let bending = bending.map(LevelBending::new);
        let mut used = [false; FORWARD];
        let bending_offsets = bending.iter().flat_map(|b| b.couplings().map(|(offset, _)| offset));
        for offset in families.iter().map(|f| f.offset).chain(bending_offsets) {
            used[slot(offset)?] = true;
        }
        let blocks = BlockStencil::new(nx, ny, used, pinned);
        let mut coarse: Vec<Level<T>> = Vec::new();
        let (mut fx, mut fy, mut fine_pinned) = (nx, ny, blocks.pinned.clone());
        while fx * fy > COARSEST_PARTICLES {
            if fx < 5 || fy < 5 {
                return None;
            }
            let (cx, cy) = (fx.div_ceil(2), fy.div_ceil(2));
            let pinned = coarse_pins(&fine_pinned, fx, cx, cy);
            let operator = BlockStencil::new(cx, cy, BlockStencil::<T>::coarse_slots(cx, cy), pinned.clone());
            let across = BlockStencil::new(fx, cy, BlockStencil::<T>::coarse_slots(fx, cy), Vec::new());
            coarse.push(Level {
                operator,
                across,
                column_weights: parent_weights(fx, cx),
                rhs: zero_field(cx * cy),
                solution: zero_field(cx * cy),
                residual: zero_field(cx * cy),
                power: zero_field(cx * cy),
            });
            (fx, fy, fine_pinned) = (cx, cy, pinned);
        }
        let coarsest = DenseCholesky::new(fx * fy);
        let fine = if bending.is_some() { fine.with_smoother_shift() } else { fine };
        Some(Self {
            fine,
            bending,
            blocks,
            held: Vec::with_capacity(n),
            filter: vec![Sym3::identity(); n],
            rhs: zero_field(n),
            solution: zero_field(n),
            residual: zero_field(n),
            coarse,
            coarsest,
        })
    }

    /// Makes every level for a step of `h`. The fine level is a copy of the step's `system` in
    /// this hierarchy's precision, or, without `system`, the step's system itself, already
    /// assembled through [`fine_mut`](Self::fine_mut). With `filter` (a symmetric projection
    /// `S_p` per particle, the identity on a free particle), the cycle preconditions the
    /// filtered system `S A S + (I − S)` instead, and every coarse level is the Galerkin product
    /// of the filtered level 0, so the coarse levels keep the constraints too.
    #[cfg(test)]
    pub fn assemble<S: Real>(&mut self, system: Option<&GridOperator<S>>, h: T, filter: Option<&[Sym3<S>]>) {
        self.assemble_fine(system, h, filter);
        self.refill_coarse();
    }

    /// The first half of [`assemble`](Self::assemble): level 0 and its smoother, leaving the
    /// coarse levels as the last [`refill_coarse`](Self::refill_coarse) made them. The cycle is
    /// then still symmetric, its coarse correction that of a nearby system. Returns whether the
    /// coarse levels must be refilled before the next cycle: the step, and with it the bending
    /// elements' weight, changed, a filter holds particles (the coarse levels carry it), or
    /// there is no coarse level (the coarsest factor is level 0's).
    pub fn assemble_fine<S: Real>(
        &mut self,
        system: Option<&GridOperator<S>>,
        h: T,
        filter: Option<&[Sym3<S>]>,
    ) -> bool {
        let h64 = h.to_f64();
        let mut stale = false;
        if let Some(bending) = &mut self.bending
            && bending.set_step(h64 * h64, h64)
        {
            self.fine.smoother_shift_mut().copy_from_slice(bending.smoother_shift());
            stale = true;
        }
        match system {
            Some(system) => self.fine.copy_from(system),
            // The fine level was assembled in place, which leaves its smoother to the level.
            None => self.fine.update_smoother(),
        }
        self.held.clear();
        if let Some(filter) = filter {
            let identity = Sym3::<S>::identity();
            for (p, &s) in filter.iter().enumerate() {
                if s != identity && self.fine.pinned.binary_search(&p).is_err() {
                    self.held.push(p);
                    self.filter[p] = Sym3::from_entries(s.entries().map(|e| T::from_f64(e.to_f64())));
                }
            }
        }
        stale || !self.held.is_empty() || self.coarse.is_empty()
    }

    /// The second half of [`assemble`](Self::assemble): level 0 as blocks, every coarse level as
    /// the Galerkin product of the one above, and the coarsest level's factor.
    pub fn refill_coarse(&mut self) {
        self.blocks.fill_from_system(&self.fine, self.bending.as_ref(), &self.held, &self.filter);
        if !self.held.is_empty() {
            let (fine, held, filter) = (&self.fine, &self.held, &self.filter);
            self.blocks.set_smoother(|p| match held.binary_search(&p) {
                Ok(_) => held_smoother(fine, p, filter[p]),
                Err(_) => fine.smoother_block(p),
            });
        }
        for l in 0..self.coarse.len() {
            let (finer, rest) = self.coarse.split_at_mut(l);
            let above = finer.last().map_or(&self.blocks, |level| &level.operator);
            let Level { operator, across, column_weights, power, residual, .. } = &mut rest[0];
            operator.fill_galerkin(above, across, column_weights);
            operator.update_smoother(power, residual);
        }
        match self.coarse.last() {
            Some(last) => factor_coarsest(&mut self.coarsest, &last.operator, &[], &self.filter),
            None => factor_coarsest(&mut self.coarsest, &self.blocks, &self.held, &self.filter),
        }
    }

    /// The fine level's operator.
    pub fn fine(&self) -> &GridOperator<T> {
        &self.fine
    }

    /// The fine level's operator, to assemble the step's system in place when it has this
    /// hierarchy's precision.
    pub fn fine_mut(&mut self) -> &mut GridOperator<T> {
        &mut self.fine
    }

    /// `z = B r`, one V-cycle from a zero guess; `r` and `z` are fine-level fields, zero (and
    /// kept zero) on pinned particles. Fields of another precision are rounded on the way in and
    /// out.
    pub fn precondition<S: Real>(&mut self, r: &mut Field<S>, z: &mut Field<S>) {
        let same = (r as &mut dyn Any).downcast_mut::<Field<T>>();
        if let Some(r) = same {
            // Swapping the vectors in is free; the cycle works on the levels' own fields.
            std::mem::swap(r, &mut self.rhs);
            let z = (z as &mut dyn Any).downcast_mut::<Field<T>>().expect("r and z share a type");
            std::mem::swap(z, &mut self.solution);
            self.cycle();
            std::mem::swap(r, &mut self.rhs);
            std::mem::swap(z, &mut self.solution);
            return;
        }
        for (to, from) in self.rhs.iter_mut().zip(r.iter()) {
            for (t, &f) in to.iter_mut().zip(from) {
                *t = T::from_f64(f.to_f64());
            }
        }
        self.cycle();
        for (to, from) in z.iter_mut().zip(&self.solution) {
            for (t, &f) in to.iter_mut().zip(from) {
                *t = S::from_f64(f.to_f64());
            }
        }
    }

    fn cycle(&mut self) {
        if self.coarse.is_empty() {
            solve_coarsest(&mut self.coarsest, &self.rhs, &mut self.solution);
            zero_pinned(&mut self.solution, &self.fine.pinned);
            return;
        }
        // Level 0: smooth, and restrict the (filtered) residual.
        if self.held.is_empty() {
            self.fine.smooth_from_zero(&self.rhs, &mut self.solution);
        } else {
            self.blocks.smooth_from_zero(&self.rhs, &mut self.solution);
            hold(&mut self.solution, &self.rhs, &self.held, &self.filter);
        }
        self.update_residual();
        let parallel = self.fine.is_parallel();
        restrict(&self.residual, self.fine.nx, self.fine.ny, parallel, &mut self.coarse[0]);
        let last = self.coarse.len() - 1;
        for l in 0..last {
            let (finer, coarser) = self.coarse.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &mut coarser[0]);
            fine.operator.smooth_from_zero(&fine.rhs, &mut fine.solution);
            fine.operator.residual(&fine.rhs, &fine.solution, &mut fine.residual);
            let (nx, ny) = (fine.operator.nx, fine.operator.ny);
            restrict(&fine.residual, nx, ny, fine.operator.is_parallel(), coarse);
        }
        let coarsest = &mut self.coarse[last];
        solve_coarsest(&mut self.coarsest, &coarsest.rhs, &mut coarsest.solution);
        zero_pinned(&mut coarsest.solution, &coarsest.operator.pinned);
        for l in (0..last).rev() {
            let (finer, coarser) = self.coarse.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &coarser[0]);
            let nx = fine.operator.nx;
            prolong(coarse, &mut fine.solution, nx, fine.operator.is_parallel());
            zero_pinned(&mut fine.solution, &fine.operator.pinned);
            fine.operator.residual(&fine.rhs, &fine.solution, &mut fine.residual);
            fine.operator.smooth_from_residual(&fine.residual, &mut fine.solution);
        }
        prolong(&self.coarse[0], &mut self.solution, self.fine.nx, self.fine.is_parallel());
        zero_pinned(&mut self.solution, &self.fine.pinned);
        if self.held.is_empty() {
            self.update_residual();
            self.fine.smooth_from_residual(&self.residual, &mut self.solution);
        } else {
            hold(&mut self.solution, &self.rhs, &self.held, &self.filter);
            self.update_residual();
            self.blocks.smooth_from_residual(&self.residual, &mut self.solution);
            hold(&mut self.solution, &self.rhs, &self.held, &self.filter);
        }
    }

    /// Level 0's residual `b − A x`: of the operator and its bending, or, with held particles,
    /// of the filtered blocks, with the held part of each held particle's residual dropped
    /// (it is zero: the cycle keeps `(I − S) x = (I − S) b`).
    fn update_residual(&mut self) {
        if self.held.is_empty() {
            self.fine.residual(&self.rhs, &self.solution, &mut self.residual);
            if let Some(bending) = &self.bending {
                bending.subtract_product(&self.solution, &mut self.residual, self.fine.is_parallel());
            }
        } else {
            self.blocks.residual(&self.rhs, &self.solution, &mut self.residual);
            for &p in &self.held {
                let s = self.filter[p];
                let r = s.apply(Vec3::new(self.residual[0][p], self.residual[1][p], self.residual[2][p]));
                (self.residual[0][p], self.residual[1][p], self.residual[2][p]) = (r.x, r.y, r.z);
            }
        }
    }

    /// The number of levels, the fine one included.
    #[cfg(test)]
    pub fn depth(&self) -> usize {
        self.coarse.len() + 1
    }

    /// The smoothers' dampings of the coarse levels.
    #[cfg(test)]
    pub fn dampings(&self) -> Vec<f64> {
        self.coarse.iter().map(|level| level.operator.damping()).collect()
    }
}

/// `coarse.rhs = Pᵀ fine`, zero on the coarse level's pins.
fn restrict<T: Real>(fine: &Field<T>, nx: usize, ny: usize, parallel: bool, coarse: &mut Level<T>) {
    let (cx, cy) = (coarse.operator.nx, coarse.operator.ny);
    for (fine_axis, coarse_axis) in fine.iter().zip(coarse.rhs.iter_mut()) {
        restrict_scalar(fine_axis, nx, ny, coarse_axis, cx, cy, parallel);
    }
    zero_pinned(&mut coarse.rhs, &coarse.operator.pinned);
}

/// `fine += P coarse.solution`.
fn prolong<T: Real>(coarse: &Level<T>, fine: &mut Field<T>, nx: usize, parallel: bool) {
    let (cx, cy) = (coarse.operator.nx, coarse.operator.ny);
    for (fine_axis, coarse_axis) in fine.iter_mut().zip(coarse.solution.iter()) {
        prolong_add(coarse_axis, cx, cy, fine_axis, nx, parallel);
    }
}

/// On each held particle, `x ← S x + (I − S) b`: the filtered system is the identity on the
/// held part, which the cycle therefore solves exactly.
fn hold<T: Real>(x: &mut Field<T>, b: &Field<T>, held: &[usize], filter: &[Sym3<T>]) {
    for &p in held {
        let s = filter[p];
        let xp = Vec3::new(x[0][p], x[1][p], x[2][p]);
        let bp = Vec3::new(b[0][p], b[1][p], b[2][p]);
        let kept = s.apply(xp) + bp - s.apply(bp);
        (x[0][p], x[1][p], x[2][p]) = (kept.x, kept.y, kept.z);
    }
}

fn zero_pinned<T: Real>(field: &mut Field<T>, pinned: &[usize]) {
    for axis in field.iter_mut() {
        for &p in pinned {
            axis[p] = T::ZERO;
        }
    }
}

/// The coarse parents of fine index `i` along an axis of `coarse` points, with their weights:
/// an even index is a coarse point; an odd one lies halfway between two, or past the last one
/// on an even-sized axis, where it takes the last coarse value.
#[inline]
pub(crate) fn parents<T: Real>(i: usize, coarse: usize) -> [(usize, T); 2] {
    let half = T::from_f64(0.5);
    if i.is_multiple_of(2) {
        [(i / 2, T::ONE), (i / 2, T::ZERO)]
    } else if i.div_ceil(2) < coarse {
        [(i / 2, half), (i.div_ceil(2), half)]
    } else {
        [(i / 2, T::ONE), (i / 2, T::ZERO)]
    }
}

/// Coarse particles that a pinned fine particle takes its value from alone.
fn coarse_pins(pinned: &[usize], nx: usize, cx: usize, cy: usize) -> Vec<usize> {
    let mut pins: Vec<usize> = pinned
        .iter()
        .filter_map(|&p| {
            let (i, j) = (p % nx, p / nx);
            let single = |i: usize, c: usize| {
                let [(a, _), (_, w)] = parents::<f64>(i, c);
                (w == 0.0).then_some(a)
            };
            Some(single(j, cy)? * cx + single(i, cx)?)
        })
        .collect();
    pins.sort_unstable();
    pins.dedup();
    pins
}

/// `rows` of an `n_rows × width` array, cut into pieces of whole rows handed to `piece` with the
/// index of their first row: on the pool's threads when `parallel`, else in one piece. Each
/// row is computed alone, so the cut changes no bits.
fn by_rows<T: Send>(
    rows: &mut [T],
    width: usize,
    parallel: bool,
    piece: impl Fn(usize, &mut [T]) + Sync + Send,
) {
    let n_rows = rows.len().checked_div(width).unwrap_or(0);
    let band = if parallel { n_rows.div_ceil(4 * rayon::current_num_threads()) } else { n_rows };
    in_bands([rows], n_rows, width, band.max(1), &|first, _, [rows]| piece(first, rows));
}

/// `coarse = Pᵀ fine` for one scalar array. Each coarse row gathers the fine rows whose parent
/// it is, in their order, so that its sum does not depend on how the rows are split.
fn restrict_scalar<T: Real>(
    fine: &[T],
    nx: usize,
    ny: usize,
    coarse: &mut [T],
    cx: usize,
    cy: usize,
    parallel: bool,
) {
    by_rows(coarse, cx, parallel, |first, rows| {
        for (k, out) in rows.chunks_exact_mut(cx).enumerate() {
            let parent = first + k;
            out.fill(T::ZERO);
            for j in (2 * parent).saturating_sub(1)..(2 * parent + 2).min(ny) {
                for (p, weight) in parents::<T>(j, cy) {
                    if p == parent && weight != T::ZERO {
                        restrict_row_add(&fine[j * nx..(j + 1) * nx], out, weight);
                    }
                }
            }
        }
    });
}

/// `out += weight · (Pᵀ along the row) f` for one fine row `f`.
///
/// Interior coarse points gather their fine point and half of each neighbour in a loop free of
/// branches, so that it vectorises; the two ends take the general form.
#[inline]
fn restrict_row_add<T: Real>(f: &[T], out: &mut [T], weight: T) {
    let (nx, cx) = (f.len(), out.len());
    let half = T::from_f64(0.5);
    let general = |c: usize| {
        let mut sum = f[2 * c];
        if c > 0 {
            sum += f[2 * c - 1] * half;
        }
        if 2 * c + 1 < nx {
            sum += f[2 * c + 1] * if c + 1 < cx { half } else { T::ONE };
        }
        sum
    };
    out[0] += general(0) * weight;
    if cx < 2 {
        return;
    }
    // Fine points from 1 in pairs: pair `c - 1` is `(f[2c - 1], f[2c])`, and pair `c` starts
    // with `f[2c + 1]`.
    let (pairs, _) = f[1..].as_chunks::<2>();
    let interior = &mut out[1..cx - 1];
    for ((value, left), right) in interior.iter_mut().zip(&pairs[..cx - 2]).zip(&pairs[1..cx - 1]) {
        let mut sum = left[1];
        sum += left[0] * half;
        sum += right[0] * half;
        *value += sum * weight;
    }
    out[cx - 1] += general(cx - 1) * weight;
}

/// `fine += P coarse` for one scalar array, each fine row from its parent coarse rows.
pub(crate) fn prolong_add<T: Real>(
    coarse: &[T],
    cx: usize,
    cy: usize,
    fine: &mut [T],
    nx: usize,
    parallel: bool,
) {
    let half = T::from_f64(0.5);
    by_rows(fine, nx, parallel, |first, rows| {
        for (k, f) in rows.chunks_exact_mut(nx).enumerate() {
            let [(a, wa), (b, wb)] = parents::<T>(first + k, cy);
            let (ra, rb) = (&coarse[a * cx..(a + 1) * cx], &coarse[b * cx..(b + 1) * cx]);
            // The coarse row interpolated between its parents, at coarse column `c`.
            let row = |c: usize| ra[c] * wa + rb[c] * wb;
            // Fine points in pairs `(2c, 2c + 1)`: a coarse point, then the midpoint to the next;
            // a branch-free loop up to the last coarse point, which may have no midpoint after it.
            let (pairs, _) = f.as_chunks_mut::<2>();
            let inner = cx - 1;
            let (ra0, ra1, rb0, rb1) = (&ra[..inner], &ra[1..], &rb[..inner], &rb[1..]);
            for ((((pair, &a0), &a1), &b0), &b1) in
                pairs[..inner].iter_mut().zip(ra0).zip(ra1).zip(rb0).zip(rb1)
            {
                let (here, next) = (a0 * wa + b0 * wb, a1 * wa + b1 * wb);
                pair[0] += here;
                pair[1] += (here + next) * half;
            }
            let last = row(inner);
            f[2 * inner] += last;
            if 2 * inner + 1 < nx {
                f[2 * inner + 1] += last;
            }
        }
    });
}

/// Fills `coarsest` with the coarsest level `operator`, with the identity on its pinned
/// particles and `I − S_p` added on each `held` particle `p` of `filter`, as the cycle's level
/// sees them, and factors it; the fallback is the inverse of the diagonal entries.
fn factor_coarsest<T: Real>(
    coarsest: &mut DenseCholesky,
    operator: &BlockStencil<T>,
    held: &[usize],
    filter: &[Sym3<T>],
) {
    coarsest.clear();
    operator.for_each_block(|p, q, block| {
        for (e, &value) in block.iter().enumerate() {
            let (a, b) = (e / 3, e % 3);
            coarsest.add(3 * p + a, 3 * q + b, value.to_f64());
            if p != q {
                coarsest.add(3 * q + b, 3 * p + a, value.to_f64());
            }
        }
    });
    let identity = Sym3::<T>::identity();
    let extra = operator.pinned.iter().map(|&p| (p, identity));
    let held =
        held.iter().map(|&p| (p, Sym3::from_entries(identity.entries()) + filter[p] * (T::ZERO - T::ONE)));
    for (p, [xx, yy, zz, xy, xz, yz]) in extra.chain(held).map(|(p, s)| (p, s.entries().map(|e| e.to_f64())))
    {
        let block = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
        for (a, row) in block.iter().enumerate() {
            for (b, &value) in row.iter().enumerate() {
                coarsest.add(3 * p + a, 3 * p + b, value);
            }
        }
    }
    coarsest.factor(|p| {
        let [xx, yy, zz, ..] = operator.diagonal_block(p).entries().map(|e| e.to_f64());
        let inverse = |d: f64| if d > 0.0 { 1.0 / d } else { 0.0 };
        [[inverse(xx), 0.0, 0.0], [0.0, inverse(yy), 0.0], [0.0, 0.0, inverse(zz)]]
    });
}

/// `x = A⁻¹ b` on the coarsest level, by its factor.
fn solve_coarsest<T: Real>(coarsest: &mut DenseCholesky, b: &Field<T>, x: &mut Field<T>) {
    for (u, w) in coarsest.work().iter_mut().enumerate() {
        *w = b[u % 3][u / 3].to_f64();
    }
    coarsest.solve();
    for (u, &w) in coarsest.work().iter().enumerate() {
        x[u % 3][u / 3] = T::from_f64(w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::forces::bending::{BendingElements, grid_bending};

    /// A deterministic field of values in [-1, 1].
    fn wiggle(n: usize, seed: f64) -> Vec<f64> {
        (0..n).map(|p| (p as f64 * 0.7315 + seed).sin()).collect()
    }

    #[test]
    fn restriction_is_the_transpose_of_interpolation_on_odd_and_even_grids() {
        for (nx, ny) in [(7usize, 9usize), (8, 6), (16, 16), (1, 1), (2, 3), (3, 2)] {
            let (cx, cy) = (nx.div_ceil(2), ny.div_ceil(2));
            let (fine, coarse) = (wiggle(nx * ny, 0.3), wiggle(cx * cy, 1.1));
            let mut interpolated = vec![0.0; nx * ny];
            prolong_add(&coarse, cx, cy, &mut interpolated, nx, false);
            let mut restricted = vec![0.0; cx * cy];
            restrict_scalar(&fine, nx, ny, &mut restricted, cx, cy, false);
            let left: f64 = interpolated.iter().zip(&fine).map(|(a, b)| a * b).sum();
            let right: f64 = coarse.iter().zip(&restricted).map(|(a, b)| a * b).sum();
            assert!((left - right).abs() <= 1e-12 * left.abs().max(1.0), "{nx}×{ny}: {left} vs {right}");
            // Interpolation reproduces a constant, the extrapolated edge included.
            let mut ones = vec![0.0; nx * ny];
            prolong_add(&vec![1.0; cx * cy], cx, cy, &mut ones, nx, false);
            assert!(ones.iter().all(|&v| v == 1.0));
            // And a linear ramp, exactly; a point past the last coarse one takes that one's value.
            let ramp: Vec<f64> = (0..cx * cy).map(|c| (3 * (c % cx) + 5 * (c / cx)) as f64).collect();
            let mut interpolated = vec![0.0; nx * ny];
            prolong_add(&ramp, cx, cy, &mut interpolated, nx, false);
            let clamp = |i: usize, coarse: usize| if i % 2 == 1 && i / 2 + 1 >= coarse { i - 1 } else { i };
            for (p, &value) in interpolated.iter().enumerate() {
                let (i, j) = (clamp(p % nx, cx), clamp(p / nx, cy));
                assert_eq!(value, 1.5 * i as f64 + 2.5 * j as f64, "{nx}×{ny} at {p}");
            }
        }
    }

    #[test]
    fn transfers_split_over_threads_give_the_same_bits() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        for (nx, ny) in [(37usize, 29usize), (40, 40), (9, 64)] {
            let (cx, cy) = (nx.div_ceil(2), ny.div_ceil(2));
            let (fine, coarse) = (wiggle(nx * ny, 0.7), wiggle(cx * cy, 2.3));
            let transfers = |parallel: bool| {
                let mut restricted = vec![0.0; cx * cy];
                restrict_scalar(&fine, nx, ny, &mut restricted, cx, cy, parallel);
                let mut interpolated = fine.clone();
                prolong_add(&coarse, cx, cy, &mut interpolated, nx, parallel);
                (restricted, interpolated)
            };
            let (alone, split) = (transfers(false), pool.install(|| transfers(true)));
            let bits = |values: &[f64]| values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&alone.0), bits(&split.0), "{nx}×{ny} restriction");
            assert_eq!(bits(&alone.1), bits(&split.1), "{nx}×{ny} interpolation");
        }
    }

    /// An `nx × ny` cloth of 5 cm spacing with the cloth's six families, bent out of its plane,
    /// pinned at `pinned`, with a fabric's bending elements when `fabric`: its hierarchy in
    /// `f64` and the step's system at 1/600 s.
    fn bent_cloth(
        nx: usize,
        ny: usize,
        pinned: Vec<usize>,
        fabric: bool,
    ) -> (Multigrid<f64>, GridOperator<f64>) {
        let spacing = 0.05;
        let family = |offset: [isize; 2]| {
            let length = spacing * ((offset[0] * offset[0] + offset[1] * offset[1]) as f64).sqrt();
            Family { offset, rest_length: length, stiffness: 5000.0, damping: 0.5 }
        };
        let families: Vec<_> = [[1, 0], [0, 1], [1, 1], [-1, 1], [2, 0], [0, 2]].map(family).to_vec();
        let n = nx * ny;
        let bending = fabric.then(|| {
            let elements = grid_bending(0, [nx, ny], [spacing, spacing], 2e-3, 1e-2);
            let hinges = BendingElements::<f64>::new(&elements).unwrap();
            BendingMatrices::of_hinges(&hinges, nx, ny, &pinned).unwrap()
        });
        let multigrid = Multigrid::new(nx, ny, families.clone(), pinned.clone(), bending).unwrap();
        let mut positions = zero_field(n);
        let [px, py, pz] = positions.arrays_mut();
        for (p, ((x, y), z)) in px.iter_mut().zip(py.iter_mut()).zip(pz.iter_mut()).enumerate() {
            let (i, j) = ((p % nx) as f64, (p / nx) as f64);
            (*x, *y, *z) = (i * spacing * 1.01, 0.02 * (0.4 * i).sin() * (0.3 * j).cos(), j * spacing * 0.99);
        }
        let (h, drag) = (1.0 / 600.0, 4.0);
        let mass = vec![(1.0 + h * drag) / n as f64; n];
        let mut system = GridOperator::new(nx, ny, &families, pinned);
        system.assemble(&positions, &mass, &families, 1.0, h, None);
        (multigrid, system)
    }

    const H: f64 = 1.0 / 600.0;

    /// The filter of a particle held in the plane of normal `n`: `I − n nᵀ`.
    fn plane_filter(n: [f64; 3]) -> Sym3<f64> {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = Vec3::new(n[0] / length, n[1] / length, n[2] / length);
        Sym3::identity() + Sym3::outer(n) * -1.0
    }

    /// A filter holding the particles of rows `rows` in planes of varying normals, and the
    /// particle `(1, 1)` in a line (two directions held).
    fn filter_of(nx: usize, ny: usize, rows: std::ops::Range<usize>) -> Vec<Sym3<f64>> {
        let mut filter = vec![Sym3::identity(); nx * ny];
        for j in rows {
            for i in 0..nx {
                let p = j * nx + i;
                filter[p] = plane_filter([(0.3 * p as f64).sin(), 1.0, (0.7 * p as f64).cos()]);
            }
        }
        filter[nx + 1] = Sym3::outer(Vec3::new(0.0, 0.6, 0.8));
        filter
    }

    fn vector(n: usize, seed: f64, pinned: &[usize]) -> Field<f64> {
        let mut field = Field::from_arrays(std::array::from_fn(|a| wiggle(n, seed + a as f64)));
        for axis in &mut field {
            for &p in pinned {
                axis[p] = 0.0;
            }
        }
        field
    }

    /// A level as a dense `3n × 3n` matrix.
    fn dense(level: &BlockStencil<f64>) -> Vec<Vec<f64>> {
        let n = level.len();
        let mut matrix = vec![vec![0.0; 3 * n]; 3 * n];
        level.for_each_block(|p, q, block| {
            for (e, &value) in block.iter().enumerate() {
                let (a, b) = (e / 3, e % 3);
                matrix[3 * p + a][3 * q + b] = value;
                matrix[3 * q + b][3 * p + a] = value;
            }
        });
        matrix
    }

    /// The cycle's interpolation from a `cx × cy` level to an `nx × ny` one as a dense matrix,
    /// zero on the fine level's `pinned` particles, as the cycle leaves it.
    fn interpolation(nx: usize, ny: usize, cx: usize, cy: usize, pinned: &[usize]) -> Vec<Vec<f64>> {
        let mut matrix = vec![vec![0.0; 3 * cx * cy]; 3 * nx * ny];
        for c in 0..cx * cy {
            let mut unit = vec![0.0; cx * cy];
            unit[c] = 1.0;
            let mut column = vec![0.0; nx * ny];
            prolong_add(&unit, cx, cy, &mut column, nx, false);
            for (p, &w) in column.iter().enumerate().filter(|&(p, _)| !pinned.contains(&p)) {
                for a in 0..3 {
                    matrix[3 * p + a][3 * c + a] = w;
                }
            }
        }
        matrix
    }

    /// `Pᵀ A P` with the rows and columns of the coarse `pinned` particles zero.
    fn galerkin(a: &[Vec<f64>], p: &[Vec<f64>], pinned: &[usize]) -> Vec<Vec<f64>> {
        let (fine, coarse) = (p.len(), p[0].len());
        let ap: Vec<Vec<f64>> = (0..fine)
            .map(|r| (0..coarse).map(|c| (0..fine).map(|k| a[r][k] * p[k][c]).sum()).collect())
            .collect();
        let mut result: Vec<Vec<f64>> = (0..coarse)
            .map(|r| (0..coarse).map(|c| (0..fine).map(|k| p[k][r] * ap[k][c]).sum()).collect())
            .collect();
        for &q in pinned {
            for a in 0..3 {
                result[3 * q + a].fill(0.0);
                for row in &mut result {
                    row[3 * q + a] = 0.0;
                }
            }
        }
        result
    }

    fn largest_difference(a: &[Vec<f64>], b: &[Vec<f64>]) -> (f64, f64) {
        let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        let difference =
            a.iter().flatten().zip(b.iter().flatten()).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        (difference, scale)
    }

    /// Level 0's blocks are the system and its bending, filtered; every coarse level is
    /// `Pᵀ A P` of the level above, computed densely, on odd and even grids with pins, with and
    /// without a filter and bending elements.
    #[test]
    fn each_coarse_level_is_the_dense_galerkin_product_of_the_level_above() {
        for (nx, ny, fabric, filtered) in
            [(11, 9, false, false), (12, 10, true, false), (11, 10, true, true), (12, 9, false, true)]
        {
            let pinned = vec![0, nx - 1, 4 * nx + 5];
            let (mut multigrid, system) = bent_cloth(nx, ny, pinned.clone(), fabric);
            let filter = filtered.then(|| filter_of(nx, ny, 6..ny));
            multigrid.assemble(Some(&system), H, filter.as_deref());
            assert_eq!(multigrid.depth(), 3, "{nx}×{ny}");
            assert_eq!(multigrid.held.len(), if filtered { (ny - 6) * nx + 1 } else { 0 });
            // Level 0: the blocks apply the system and its bending to a field that is zero on
            // the pins; with a filter, `S A S` (the held part is applied apart).
            let s = |x: &Field<f64>| {
                let mut y = x.clone();
                if let Some(filter) = &filter {
                    for p in 0..nx * ny {
                        let v = filter[p].apply(Vec3::new(x[0][p], x[1][p], x[2][p]));
                        (y[0][p], y[1][p], y[2][p]) = (v.x, v.y, v.z);
                    }
                }
                y
            };
            let x = vector(nx * ny, 0.2, &pinned);
            let (mut expected, mut got) = (zero_field(nx * ny), zero_field(nx * ny));
            system.apply(&s(&x), &mut expected);
            if let Some(bending) = &multigrid.bending {
                let mut minus = zero_field(nx * ny);
                bending.subtract_product(&s(&x), &mut minus, false);
                for (e, m) in expected.iter_mut().zip(minus.iter()) {
                    for (e, m) in e.iter_mut().zip(m) {
                        *e -= m;
                    }
                }
            }
            let mut expected = s(&expected);
            zero_pinned(&mut expected, &pinned);
            multigrid.blocks.apply(&x, &mut got);
            let scale = expected.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for (e, g) in expected.iter().flatten().zip(got.iter().flatten()) {
                assert!((e - g).abs() <= 1e-12 * scale, "{nx}×{ny} level 0: {g} against {e}");
            }
            let mut above = (&multigrid.blocks, nx, ny, pinned.clone());
            for level in &multigrid.coarse {
                let (fine, fx, fy, fine_pinned) = above;
                let (cx, cy) = (level.operator.nx, level.operator.ny);
                let p = interpolation(fx, fy, cx, cy, &fine_pinned);
                let reference = galerkin(&dense(fine), &p, &level.operator.pinned);
                let (difference, scale) = largest_difference(&dense(&level.operator), &reference);
                assert!(difference <= 1e-12 * scale, "{fx}×{fy} → {cx}×{cy}: {difference} of {scale}");
                above = (&level.operator, cx, cy, level.operator.pinned.clone());
            }
        }
    }

    #[test]
    fn the_v_cycle_is_symmetric_and_positive_definite() {
        for (fabric, filtered) in [(false, false), (true, false), (false, true), (true, true)] {
            let pinned = vec![0, 19];
            let (mut multigrid, system) = bent_cloth(20, 20, pinned.clone(), fabric);
            let filter = filtered.then(|| filter_of(20, 20, 8..14));
            multigrid.assemble(Some(&system), H, filter.as_deref());
            // 20 → 10 → 5 → 3.
            assert_eq!(multigrid.depth(), 4);
            let (mut a, mut b) = (vector(400, 0.0, &pinned), vector(400, 5.0, &pinned));
            let (mut ba, mut bb) = (zero_field(400), zero_field(400));
            multigrid.precondition(&mut a, &mut ba);
            multigrid.precondition(&mut b, &mut bb);
            let (ab, ba_) = (dot(&a, &bb), dot(&b, &ba));
            assert!((ab - ba_).abs() <= 1e-12 * ab.abs(), "{fabric} {filtered}: a·Bb = {ab}, b·Ba = {ba_}");
            assert!(dot(&a, &ba) > 0.0 && dot(&b, &bb) > 0.0);
            // Pinned particles stay out of the correction.
            assert_eq!([ba[0][0], ba[1][19], bb[2][0]], [0.0; 3]);
            // The coarse levels' smoothers are damped below 2 / λmax.
            for damping in multigrid.dampings() {
                assert!(damping > 0.3 && damping <= 0.9, "{damping}");
            }
        }
    }

    /// With a filter, the cycle is the identity on each held particle's held part and keeps
    /// the rest of its output in the free part: `(I − S) B r = (I − S) r`, and a field with no
    /// held part gives a correction with none.
    #[test]
    fn a_filtered_cycle_keeps_the_held_directions_exactly() {
        let (nx, ny, pinned) = (20, 20, vec![0, 19]);
        let (mut multigrid, system) = bent_cloth(nx, ny, pinned.clone(), true);
        let filter = filter_of(nx, ny, 8..14);
        multigrid.assemble(Some(&system), H, Some(&filter));
        let held = |f: &Field<f64>, p: usize| {
            let v = Vec3::new(f[0][p], f[1][p], f[2][p]);
            v - filter[p].apply(v)
        };
        let mut r = vector(nx * ny, 1.0, &pinned);
        let mut z = zero_field(nx * ny);
        multigrid.precondition(&mut r, &mut z);
        let largest = z.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for &p in &multigrid.held {
            let error = (held(&z, p) - held(&r, p)).length();
            assert!(error <= 1e-13 * largest, "particle {p}: {error}");
        }
        // The free part alone.
        for p in 0..nx * ny {
            let v = filter[p].apply(Vec3::new(r[0][p], r[1][p], r[2][p]));
            (r[0][p], r[1][p], r[2][p]) = (v.x, v.y, v.z);
        }
        multigrid.precondition(&mut r, &mut z);
        for &p in &multigrid.held {
            assert!(held(&z, p).length() <= 1e-13 * largest, "particle {p}: {:?}", held(&z, p));
        }
    }

    #[test]
    fn one_v_cycle_removes_most_of_the_error_of_a_stiff_cloth() {
        let pinned = vec![0, 19];
        let (mut multigrid, system) = bent_cloth(20, 20, pinned.clone(), false);
        multigrid.assemble(Some(&system), H, None);
        let x = vector(400, 0.0, &pinned);
        // b = A x, then x ≈ B b: a good preconditioner leaves a small error in the energy norm.
        let mut b = zero_field(400);
        multigrid.fine().apply(&x, &mut b);
        let mut approximate = zero_field(400);
        multigrid.precondition(&mut b, &mut approximate);
        let error = Field::from_arrays(std::array::from_fn(|a| {
            x[a].iter().zip(&approximate[a]).map(|(u, v)| u - v).collect()
        }));
        let mut a_error = zero_field(400);
        multigrid.fine().apply(&error, &mut a_error);
        let reduction = (dot(&error, &a_error) / dot(&x, &b)).sqrt();
        assert!(reduction < 0.5, "the V-cycle leaves {reduction} of the error");
    }

    fn dot(a: &Field<f64>, b: &Field<f64>) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>()).sum()
    }
}
