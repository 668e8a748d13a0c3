//! A geometric multigrid V-cycle on a grid cloth, used as the conjugate-gradient preconditioner.
//!
//! Level 0 is the step's system on the cloth's grid, or its copy in the hierarchy's precision
//! (an `f64` step is preconditioned in `f32`). Each coarser level keeps every other
//! particle in both directions (`⌈n/2⌉`; on an even grid the last fine column and row are
//! extrapolated from the last coarse one) and is the same cloth rediscretised there: the same
//! spring families between the coarse particles at their current positions, with doubled rest
//! lengths, the same stiffness and damping (a spring sheet's membrane stiffness does not depend
//! on its spacing), and masses lumped by restriction. Rediscretising costs about a third of the
//! fine assembly, where a Galerkin product `Pᵀ A P` would cost several fine products.
//! A fabric's bending elements, whose Jacobian is constant, are the exception: each level carries
//! them beside its springs as a stencil built once ([`level_bending`](super::level_bending)).
//!
//! Transfers are bilinear interpolation `P` and its transpose, and a coarse particle is held
//! fixed when a pinned fine particle takes its value alone. Each output row of a transfer is
//! computed alone from its input rows (a coarse row gathers its fine children), so on a grid
//! whose products run on the pool's threads the transfers are split over them too, with the same
//! bits. Smoothing is damped block Jacobi, one sweep before and one after the coarse correction,
//! and the coarsest level (at most [`COARSEST_PARTICLES`] particles) is solved exactly by a dense
//! Cholesky factorisation in `f64`. Pre- and post-smoothing match and the transfers are each
//! other's transposes, so the cycle is a symmetric positive definite operator, as conjugate
//! gradients needs.

use crate::solver::math::real::Real;
use std::any::Any;

use super::grid_operator::{Family, Field, GridOperator, zero_field};
use super::level_bending::{BendingMatrices, LevelBending};
use crate::solver::parallel::in_bands;

/// The coarsest level has at most this many particles and is solved directly.
pub(crate) const COARSEST_PARTICLES: usize = 16;

/// One level of the hierarchy with its vectors.
#[derive(Debug)]
struct Level<T> {
    operator: GridOperator<T>,
    /// Coarse levels: the injected positions (level 0 reads the step's positions).
    positions: Field<T>,
    /// Lumped particle masses, without drag.
    base_mass: Vec<T>,
    /// `base_mass (1 + h drag)` for the current step.
    mass: Vec<T>,
    /// The cycle's right-hand side, correction and residual on this level.
    rhs: Field<T>,
    solution: Field<T>,
    residual: Field<T>,
    /// The bending elements' part of the level, applied beside `operator`.
    bending: Option<LevelBending<T>>,
}

/// The hierarchy, its transfers and the coarsest level's dense factor.
#[derive(Debug)]
pub(crate) struct Multigrid<T> {
    levels: Vec<Level<T>>,
    families: Vec<Family<T>>,
    coarsest: DenseCholesky,
}

impl<T: Real> Multigrid<T> {
    /// The hierarchy for an `nx × ny` grid, with `bending` (level 0's) on every level when
    /// given, or `None` when the grid cannot be coarsened to a direct solve (a strip too narrow
    /// to halve).
    pub fn new(
        nx: usize,
        ny: usize,
        families: Vec<Family<T>>,
        masses: &[T],
        pinned: Vec<usize>,
        bending: Option<BendingMatrices>,
    ) -> Option<Self> {
        let mut levels = vec![Level::new(nx, ny, &families, masses.to_vec(), pinned, bending)];
        loop {
            let fine = levels.last()?;
            let (nx, ny) = (fine.operator.nx, fine.operator.ny);
            if nx * ny <= COARSEST_PARTICLES {
                break;
            }
            if nx < 5 || ny < 5 {
                return None;
            }
            let (cx, cy) = (nx.div_ceil(2), ny.div_ceil(2));
            let mut mass = vec![T::ZERO; cx * cy];
            restrict_scalar(&fine.base_mass, nx, ny, &mut mass, cx, cy, false);
            let pinned = coarse_pins(&fine.operator.pinned, nx, cx, cy);
            let bending = match &fine.bending {
                Some(bending) => Some(bending.matrices().coarsened(cx, cy, &pinned)?),
                None => None,
            };
            levels.push(Level::new(cx, cy, &families, mass, pinned, bending));
        }
        let last = levels.last()?;
        let coarsest = DenseCholesky::new(last.operator.len());
        Some(Self { levels, families, coarsest })
    }

    /// Assembles every level for a step of `h` at `positions`. The fine level is a copy of the
    /// step's `system` (assembled at `positions`) in this hierarchy's precision, or, without
    /// `system`, the step's system itself, already assembled through
    /// [`fine_mut`](Self::fine_mut).
    pub fn assemble<S: Real>(
        &mut self,
        system: Option<&GridOperator<S>>,
        positions: &Field<S>,
        h: T,
        drag: T,
    ) {
        let scale = T::ONE + h * drag;
        let mut rest_scale = T::ONE;
        let h64 = h.to_f64();
        let mut bending_changed = false;
        for level in &mut self.levels {
            if let Some(bending) = &mut level.bending
                && bending.set_step(h64 * h64, h64)
            {
                level.operator.smoother_shift_mut().copy_from_slice(bending.smoother_shift());
                bending_changed = true;
            }
        }
        match system {
            Some(system) => self.levels[0].operator.copy_from(system),
            // The fine level was assembled before its smoother's shift changed.
            None if bending_changed => self.levels[0].operator.update_smoother(),
            None => {}
        }
        for l in 1..self.levels.len() {
            rest_scale = rest_scale + rest_scale;
            let (finer, rest) = self.levels.split_at_mut(l);
            let (fine, level) = (&finer[l - 1], &mut rest[0]);
            for (m, &base) in level.mass.iter_mut().zip(&level.base_mass) {
                *m = base * scale;
            }
            let (nx, cx, cy) = (fine.operator.nx, level.operator.nx, level.operator.ny);
            if l == 1 {
                inject(positions, nx, &mut level.positions, cx, cy);
            } else {
                inject(&fine.positions, nx, &mut level.positions, cx, cy);
            }
            level.operator.assemble(&level.positions, &level.mass, &self.families, rest_scale, h, None);
        }
        let last = self.levels.last().expect("a hierarchy has a level");
        self.coarsest.factor(&last.operator, last.bending.as_ref());
    }

    /// The fine level's operator.
    pub fn fine(&self) -> &GridOperator<T> {
        &self.levels[0].operator
    }

    /// The fine level's operator, to assemble the step's system in place when it has this
    /// hierarchy's precision.
    pub fn fine_mut(&mut self) -> &mut GridOperator<T> {
        &mut self.levels[0].operator
    }

    /// `z = B r`, one V-cycle from a zero guess; `r` and `z` are fine-level fields, zero (and
    /// kept zero) on pinned particles. Fields of another precision are rounded on the way in and
    /// out.
    pub fn precondition<S: Real>(&mut self, r: &mut Field<S>, z: &mut Field<S>) {
        let fine = &mut self.levels[0];
        let same = (r as &mut dyn Any).downcast_mut::<Field<T>>();
        if let Some(r) = same {
            // Swapping the vectors in is free; the cycle works on the levels' own fields.
            std::mem::swap(r, &mut fine.rhs);
            let z = (z as &mut dyn Any).downcast_mut::<Field<T>>().expect("r and z share a type");
            std::mem::swap(z, &mut fine.solution);
            self.cycle();
            let fine = &mut self.levels[0];
            std::mem::swap(r, &mut fine.rhs);
            std::mem::swap(z, &mut fine.solution);
            return;
        }
        for (to, from) in fine.rhs.iter_mut().zip(r.iter()) {
            for (t, &f) in to.iter_mut().zip(from) {
                *t = T::from_f64(f.to_f64());
            }
        }
        self.cycle();
        for (to, from) in z.iter_mut().zip(&self.levels[0].solution) {
            for (t, &f) in to.iter_mut().zip(from) {
                *t = S::from_f64(f.to_f64());
            }
        }
    }

    fn cycle(&mut self) {
        let last = self.levels.len() - 1;
        for l in 0..last {
            let (finer, coarser) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &mut coarser[0]);
            fine.operator.smooth_from_zero(&fine.rhs, &mut fine.solution);
            fine.update_residual();
            let (nx, ny, cx, cy) =
                (fine.operator.nx, fine.operator.ny, coarse.operator.nx, coarse.operator.ny);
            let parallel = fine.operator.is_parallel();
            for (fine_axis, coarse_axis) in fine.residual.iter().zip(coarse.rhs.iter_mut()) {
                restrict_scalar(fine_axis, nx, ny, coarse_axis, cx, cy, parallel);
            }
            zero_pinned(&mut coarse.rhs, &coarse.operator.pinned);
        }
        let coarsest = &mut self.levels[last];
        self.coarsest.solve(&coarsest.rhs, &mut coarsest.solution);
        zero_pinned(&mut coarsest.solution, &coarsest.operator.pinned);
        for l in (0..last).rev() {
            let (finer, coarser) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &mut coarser[0]);
            let (nx, cx, cy) = (fine.operator.nx, coarse.operator.nx, coarse.operator.ny);
            let parallel = fine.operator.is_parallel();
            for (fine_axis, coarse_axis) in fine.solution.iter_mut().zip(coarse.solution.iter()) {
                prolong_add(coarse_axis, cx, cy, fine_axis, nx, parallel);
            }
            zero_pinned(&mut fine.solution, &fine.operator.pinned);
            fine.update_residual();
            fine.operator.smooth_from_residual(&fine.residual, &mut fine.solution);
        }
    }

    /// The number of levels, the fine one included.
    #[cfg(test)]
    pub fn depth(&self) -> usize {
        self.levels.len()
    }
}

impl<T: Real> Level<T> {
    fn new(
        nx: usize,
        ny: usize,
        families: &[Family<T>],
        base_mass: Vec<T>,
        pinned: Vec<usize>,
        bending: Option<BendingMatrices>,
    ) -> Self {
        let n = nx * ny;
        let operator = GridOperator::new(nx, ny, families, pinned);
        Self {
            operator: if bending.is_some() { operator.with_smoother_shift() } else { operator },
            positions: zero_field(n),
            mass: base_mass.clone(),
            base_mass,
            rhs: zero_field(n),
            solution: zero_field(n),
            residual: zero_field(n),
            bending: bending.map(LevelBending::new),
        }
    }

    /// `residual = rhs - (A + G) solution`, of the operator `A` and the bending `G`.
    fn update_residual(&mut self) {
        self.operator.residual(&self.rhs, &self.solution, &mut self.residual);
        if let Some(bending) = &self.bending {
            bending.subtract_product(&self.solution, &mut self.residual, self.operator.is_parallel());
        }
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

/// Coarse positions: every other fine particle in both directions.
fn inject<S: Real, T: Real>(fine: &Field<S>, nx: usize, coarse: &mut Field<T>, cx: usize, cy: usize) {
    for (f, c) in fine.iter().zip(coarse.iter_mut()) {
        for j in 0..cy {
            let source = &f[2 * j * nx..];
            for (i, value) in c[j * cx..(j + 1) * cx].iter_mut().enumerate() {
                *value = T::from_f64(source[2 * i].to_f64());
            }
        }
    }
}

/// A dense Cholesky factorisation `A = L Lᵀ` of the coarsest level, in `f64`.
#[derive(Debug)]
struct DenseCholesky {
    size: usize,
    /// Row-major; the lower triangle holds `L` after factoring.
    matrix: Vec<f64>,
    work: Vec<f64>,
    /// Whether the last factorisation succeeded; if not, the solve falls back to the diagonal.
    factored: bool,
}

impl DenseCholesky {
    fn new(particles: usize) -> Self {
        let size = 3 * particles;
        Self { size, matrix: vec![0.0; size * size], work: vec![0.0; size], factored: false }
    }

    /// Factors `operator` plus, on each axis, `bending`.
    fn factor<T: Real>(&mut self, operator: &GridOperator<T>, bending: Option<&LevelBending<T>>) {
        let (n, size) = (operator.len(), self.size);
        self.matrix.fill(0.0);
        let (nx, ny) = (operator.nx as isize, operator.ny as isize);
        for p in 0..n {
            let (i, j) = ((p % operator.nx) as isize, (p / operator.nx) as isize);
            let neighbours = std::iter::once([0, 0])
                .chain(operator.offsets().iter().copied())
                .chain(operator.offsets().iter().map(|&[di, dj]| [-di, -dj]));
            for [di, dj] in neighbours {
                let (qi, qj) = (i + di, j + dj);
                if !(0..nx).contains(&qi) || !(0..ny).contains(&qj) {
                    continue;
                }
                let q = (qj * nx + qi) as usize;
                let [xx, yy, zz, xy, xz, yz] = operator.block(p, q).entries().map(|e| e.to_f64());
                let block = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
                for (a, block_row) in block.iter().enumerate() {
                    for (b, &value) in block_row.iter().enumerate() {
                        self.matrix[(3 * p + a) * size + 3 * q + b] = value;
                    }
                }
            }
        }
        if let Some(bending) = bending {
            bending.for_each_entry(|p, q, g| {
                for a in 0..3 {
                    self.matrix[(3 * p + a) * size + 3 * q + a] += g;
                }
            });
        }
        self.factored = true;
        for k in 0..size {
            let mut pivot = self.matrix[k * size + k];
            for m in 0..k {
                pivot -= self.matrix[k * size + m] * self.matrix[k * size + m];
            }
            if pivot <= 0.0 || !pivot.is_finite() {
                self.factored = false;
                break;
            }
            let pivot = pivot.sqrt();
            self.matrix[k * size + k] = pivot;
            for r in k + 1..size {
                let mut value = self.matrix[r * size + k];
                for m in 0..k {
                    value -= self.matrix[r * size + m] * self.matrix[k * size + m];
                }
                self.matrix[r * size + k] = value / pivot;
            }
        }
        if !self.factored {
            self.matrix.fill(0.0);
            for p in 0..n {
                let [xx, yy, zz, ..] = operator.block(p, p).entries().map(|e| e.to_f64());
                for (a, d) in [xx, yy, zz].into_iter().enumerate() {
                    self.matrix[(3 * p + a) * size + 3 * p + a] = if d > 0.0 { 1.0 / d } else { 0.0 };
                }
            }
        }
    }

    fn solve<T: Real>(&mut self, b: &Field<T>, x: &mut Field<T>) {
        let size = self.size;
        for (u, w) in self.work.iter_mut().enumerate() {
            *w = b[u % 3][u / 3].to_f64();
        }
        if self.factored {
            for r in 0..size {
                let mut value = self.work[r];
                for m in 0..r {
                    value -= self.matrix[r * size + m] * self.work[m];
                }
                self.work[r] = value / self.matrix[r * size + r];
            }
            for r in (0..size).rev() {
                let mut value = self.work[r];
                for m in r + 1..size {
                    value -= self.matrix[m * size + r] * self.work[m];
                }
                self.work[r] = value / self.matrix[r * size + r];
            }
        } else {
            for (u, w) in self.work.iter_mut().enumerate() {
                *w *= self.matrix[u * size + u];
            }
        }
        for (u, &w) in self.work.iter().enumerate() {
            x[u % 3][u / 3] = T::from_f64(w);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// A 20×20 cloth of 5 cm spacing with the cloth's six families, bent out of its plane.
    fn bent_cloth() -> (Multigrid<f64>, Field<f64>, Field<f64>) {
        let n = 20;
        let spacing = 0.05;
        let family = |offset: [isize; 2]| {
            let length = spacing * ((offset[0] * offset[0] + offset[1] * offset[1]) as f64).sqrt();
            Family { offset, rest_length: length, stiffness: 5000.0, damping: 0.5 }
        };
        let families = vec![
            family([1, 0]),
            family([0, 1]),
            family([1, 1]),
            family([-1, 1]),
            family([2, 0]),
            family([0, 2]),
        ];
        let masses = vec![1.0 / (n * n) as f64; n * n];
        let mut multigrid = Multigrid::new(n, n, families.clone(), &masses, vec![0, n - 1], None).unwrap();
        let mut positions = zero_field(n * n);
        let [px, py, pz] = positions.arrays_mut();
        for (p, ((x, y), z)) in px.iter_mut().zip(py.iter_mut()).zip(pz.iter_mut()).enumerate() {
            let (i, j) = ((p % n) as f64, (p / n) as f64);
            (*x, *y, *z) = (i * spacing * 1.01, 0.02 * (0.4 * i).sin() * (0.3 * j).cos(), j * spacing * 0.99);
        }
        let (h, drag) = (1.0 / 600.0, 4.0);
        let mass: Vec<f64> = masses.iter().map(|m| m * (1.0 + h * drag)).collect();
        let mut system = GridOperator::new(n, n, &families, vec![0, n - 1]);
        system.assemble(&positions, &mass, &families, 1.0, h, None);
        multigrid.assemble(Some(&system), &positions, h, drag);
        let vector = |seed: f64| {
            let mut field = Field::from_arrays(std::array::from_fn(|a| wiggle(n * n, seed + a as f64)));
            for axis in &mut field {
                (axis[0], axis[n - 1]) = (0.0, 0.0);
            }
            field
        };
        (multigrid, vector(0.0), vector(5.0))
    }

    #[test]
    fn the_v_cycle_is_symmetric_and_positive_definite() {
        let (mut multigrid, mut a, mut b) = bent_cloth();
        // 20 → 10 → 5 → 3.
        assert_eq!(multigrid.depth(), 4);
        let (mut ba, mut bb) = (zero_field(400), zero_field(400));
        multigrid.precondition(&mut a, &mut ba);
        multigrid.precondition(&mut b, &mut bb);
        let (ab, ba_) = (dot(&a, &bb), dot(&b, &ba));
        assert!((ab - ba_).abs() <= 1e-10 * ab.abs(), "a·Bb = {ab}, b·Ba = {ba_}");
        assert!(dot(&a, &ba) > 0.0 && dot(&b, &bb) > 0.0);
        // Pinned particles stay out of the correction.
        assert_eq!([ba[0][0], ba[1][19], bb[2][0]], [0.0; 3]);
    }

    #[test]
    fn one_v_cycle_removes_most_of_the_error_of_a_stiff_cloth() {
        let (mut multigrid, x, _) = bent_cloth();
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
