//! A level of the grid multigrid as general 3×3 blocks over a fixed stencil, filled as the
//! Galerkin product `Pᵀ A P` of the level above, with its damped block-Jacobi smoother.
//!
//! The multigrid's transfers are bilinear (`P` gives a fine particle the weights 1, ½ or ¼ of
//! its coarse parents, which lie at most one fine step away), so a coarse block `Pᵀ A P[a, b]`
//! gathers the blocks between the children of `a` and those of `b`. A level 0 that reaches two
//! particles along each axis (springs two apart, bending elements) gives coarse levels that reach
//! two again, and so does every level after: each level is the 25 blocks of a 5×5 neighbourhood
//! at most, of which the diagonal and the twelve ahead are stored (the twelve behind are their
//! transposes). The pattern is fixed when the solver is built; a step refills the values.
//!
//! The blocks are general rather than symmetric: a step's filter (a particle held in a plane or
//! a line keeps only the part `S_p` of its velocity change, `I − n nᵀ` for a contact normal `n`)
//! makes level 0 the filtered system `S A S`, whose coupling `S_p A_pq S_q` is not symmetric
//! when `S_p ≠ S_q`. Pinned particles are the filter `S = 0`: on a level's pinned particles the
//! rows, columns and diagonal are all zero, so the product of the level above is
//! `Pᵀ Z A Z P` with `Z` the zeroing of the pins that the cycle applies after each
//! interpolation.
//!
//! Block Jacobi damped by `ω` converges on a level when `ω λmax(D⁻¹ A) < 2`. On level 0, a sum of
//! spring blocks, `λmax ≤ 2`; on a Galerkin level it is not (2.4 to 2.7 on a cloth in contact),
//! so each coarse level is damped by `min(0.9, 1.8 / λmax)`, with `λmax` estimated by a few power
//! iterations on `D⁻¹ A` (the Rayleigh quotient `vᵀ A v / vᵀ D v`), warm-started from the last
//! step's vector.

use crate::solver::arrays::Arrays;
use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use crate::solver::parallel::in_bands;

use super::dot_slices;
use super::grid_operator::{Field, GridOperator, JACOBI_DAMPING, PARALLEL_PARTICLES};
use super::level_bending::LevelBending;
use super::multigrid::parents;

/// The stencil's offsets ahead of a particle (`dj > 0`, or `dj == 0` and `di > 0`) within two
/// particles along each axis, in the order of their slots.
pub(crate) const OFFSETS: [[isize; 2]; FORWARD] =
    [[1, 0], [2, 0], [-2, 1], [-1, 1], [0, 1], [1, 1], [2, 1], [-2, 2], [-1, 2], [0, 2], [1, 2], [2, 2]];

/// The number of offsets ahead.
pub(crate) const FORWARD: usize = 12;

/// How far a block may reach along each axis.
const REACH: isize = 2;

/// A block's nine entries per offset, row-major.
const ENTRIES: usize = 9 * FORWARD;

/// The damping's cap, and the bound `ω λmax` kept below 2.
const MAX_DAMPING: f64 = 0.9;
const DAMPED_RADIUS: f64 = 1.8;

/// Power iterations for a level's first damping, and for each later one from the last vector.
const FIRST_POWER_ITERATIONS: usize = 12;
const POWER_ITERATIONS: usize = 3;

/// Where a coarse block between a particle and one `[di, dj]` away is summed, at
/// `dj * 5 + di + 2` for `dj` in 0..=2: 0 the diagonal, `s + 1` the slot `s` ahead, [`BEHIND`]
/// a block behind.
const SUMS_OF: [u8; 15] = [BEHIND, BEHIND, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12];
const BEHIND: u8 = u8::MAX;

/// A general 3×3 block, row-major.
type Block<T> = [T; 9];

/// The slot of an offset ahead within reach, or `None`.
pub(crate) fn slot([di, dj]: [isize; 2]) -> Option<usize> {
    let ahead = dj > 0 || (dj == 0 && di > 0);
    (ahead && di.abs() <= REACH && dj <= REACH).then(|| {
        if dj == 0 { (di - 1) as usize } else { (2 + (dj - 1) * (2 * REACH + 1) + di + REACH) as usize }
    })
}

/// A symmetric operator on an `nx × ny` grid stored as blocks (see the module docs), with its
/// damped block-Jacobi smoother.
#[derive(Debug)]
pub(crate) struct BlockStencil<T> {
    pub nx: usize,
    pub ny: usize,
    /// Per particle: the diagonal block `[xx, yy, zz, xy, xz, yz]`.
    diagonal: Arrays<T, 6>,
    /// Per particle `p`, entries `9 s..9 s + 9`: the block `A[p, p + OFFSETS[s]]`, zero where
    /// `p + OFFSETS[s]` is off the grid.
    couplings: Arrays<T, ENTRIES>,
    /// The slots that may hold a non-zero block.
    used: [bool; FORWARD],
    /// Per particle: the smoother's block, `ω D⁻¹` on a coarse level.
    smoother: Arrays<T, 6>,
    /// Particles held fixed: their rows, columns and diagonal are zero.
    pub pinned: Vec<usize>,
    /// Whether products and smoothing are split over the pool's threads.
    parallel: bool,
    /// Whether the power iteration's vector holds the last step's.
    warm: bool,
    /// The smoother's damping `ω` of the last update.
    damping: f64,
}

impl<T: Real> BlockStencil<T> {
    /// A level of zeros on an `nx × ny` grid whose blocks may be non-zero at the offsets of the
    /// `used` slots.
    pub fn new(nx: usize, ny: usize, used: [bool; FORWARD], pinned: Vec<usize>) -> Self {
        let n = nx * ny;
        Self {
            nx,
            ny,
            diagonal: Arrays::zeros(n),
            couplings: Arrays::zeros(n),
            used,
            smoother: Arrays::zeros(n),
            pinned,
            parallel: n >= PARALLEL_PARTICLES,
            warm: false,
            damping: MAX_DAMPING,
        }
    }

    /// The slots a Galerkin product of this level may fill: every offset within reach whose
    /// partner can be on a grid of `cx × cy`.
    pub fn coarse_slots(cx: usize, cy: usize) -> [bool; FORWARD] {
        OFFSETS.map(|[di, dj]| (di.unsigned_abs() < cx) && (dj as usize) < cy)
    }

    /// Whether products and smoothing are split over the pool's threads.
    pub fn is_parallel(&self) -> bool {
        self.parallel
    }

    /// The number of particles.
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// The smoother's damping of the last update.
    #[cfg(test)]
    pub fn damping(&self) -> f64 {
        self.damping
    }

    /// Rows per band of a product: all of them on a serial level.
    fn band_rows(&self) -> usize {
        if self.parallel { self.ny.div_ceil(4 * rayon::current_num_threads()).max(1) } else { self.ny }
    }

    /// The diagonal block of particle `p`.
    pub fn diagonal_block(&self, p: usize) -> Sym3<T> {
        Sym3::from_entries(self.diagonal.arrays().map(|a| a[p]))
    }

    /// The block `A[p, p + OFFSETS[s]]`.
    pub fn coupling_block(&self, p: usize, s: usize) -> Block<T> {
        let c = self.couplings.arrays();
        std::array::from_fn(|e| c[9 * s + e][p])
    }

    /// Calls `block(p, q, A[p, q])` for every stored block: each diagonal, and each coupling
    /// ahead once (`A[q, p]` is its transpose).
    pub fn for_each_block(&self, mut block: impl FnMut(usize, usize, Block<T>)) {
        for p in 0..self.len() {
            block(p, p, general(self.diagonal_block(p)));
            let (i, j) = ((p % self.nx) as isize, (p / self.nx) as isize);
            for (s, &[di, dj]) in OFFSETS.iter().enumerate().filter(|&(s, _)| self.used[s]) {
                if self.on_grid(i + di, j + dj) {
                    block(p, (j + dj) as usize * self.nx + (i + di) as usize, self.coupling_block(p, s));
                }
            }
        }
    }

    fn on_grid(&self, i: isize, j: isize) -> bool {
        (0..self.nx as isize).contains(&i) && (0..self.ny as isize).contains(&j)
    }

    /// Level 0 as blocks: the step's `system` (its springs and masses) plus `bending`, filtered
    /// by `S_p` (`filter[p]`) on the `held` particles and by zero on the pinned ones.
    pub fn fill_from_system(
        &mut self,
        system: &GridOperator<T>,
        bending: Option<&LevelBending<T>>,
        held: &[usize],
        filter: &[Sym3<T>],
    ) {
        let (nx, band) = (self.nx, self.band_rows());
        let used = self.used;
        // The system's couplings are written whole; only the other slots in use start at zero.
        let mut written = [false; FORWARD];
        for s in system.coupling_arrays().filter_map(|(offset, _)| slot(offset)) {
            written[s] = true;
        }
        let diagonal = system.diagonal_arrays();
        let rows = (self.diagonal.arrays_mut(), self.couplings.arrays_mut());
        in_bands(rows, self.ny, nx, band, &|first, count, (mut d, mut c)| {
            let at = first * nx;
            for (to, from) in d.iter_mut().zip(&diagonal) {
                to[..count * nx].copy_from_slice(&from[at..at + count * nx]);
            }
            for s in (0..FORWARD).filter(|&s| used[s] && !written[s]) {
                for entry in &mut c[9 * s..9 * s + 9] {
                    entry.fill(T::ZERO);
                }
            }
            for (offset, [ux, uy, uz, sigma]) in system.coupling_arrays() {
                let Some(s) = slot(offset) else { continue };
                let rows = at..at + count * nx;
                let (u, sigma) = ([&ux[rows.clone()], &uy[rows.clone()], &uz[rows.clone()]], &sigma[rows]);
                // One entry of the blocks at a time, so that each pass runs along whole arrays.
                for r in 0..3 {
                    for e in 0..3 {
                        let entry = c[9 * s + 3 * r + e][..count * nx].iter_mut().zip(u[r]).zip(u[e]);
                        if r == e {
                            for (((to, &a), &b), &sigma) in entry.zip(sigma) {
                                *to = T::ZERO - (a * b + sigma);
                            }
                        } else {
                            for ((to, &a), &b) in entry {
                                *to = T::ZERO - a * b;
                            }
                        }
                    }
                }
            }
        });
        if let Some(bending) = bending {
            let [dxx, dyy, dzz, ..] = self.diagonal.arrays_mut();
            for (p, &g) in bending.diagonal().iter().enumerate() {
                dxx[p] += g;
                dyy[p] += g;
                dzz[p] += g;
            }
            let c = self.couplings.arrays_mut();
            for (offset, coupling) in bending.couplings() {
                let s = slot(offset).expect("level 0's bending is within the stencil's reach");
                for (p, &g) in coupling.iter().enumerate().filter(|&(_, &g)| g != T::ZERO) {
                    for e in [0, 4, 8] {
                        c[9 * s + e][p] += g;
                    }
                }
            }
        }
        for &p in held {
            self.filter_particle(p, &general(filter[p]));
        }
        for k in 0..self.pinned.len() {
            self.filter_particle(self.pinned[k], &[T::ZERO; 9]);
        }
    }

    /// Multiplies row and column `p` by the symmetric `s`: `A[p, q] ← s A[p, q]` and
    /// `A[q, p] ← A[q, p] s`.
    fn filter_particle(&mut self, p: usize, s: &Block<T>) {
        let d = multiply(s, &multiply(&general(self.diagonal_block(p)), s));
        for (a, e) in self.diagonal.iter_mut().zip([d[0], d[4], d[8], d[1], d[2], d[5]]) {
            a[p] = e;
        }
        let (i, j) = ((p % self.nx) as isize, (p / self.nx) as isize);
        let used = self.used;
        for (s_, &[di, dj]) in OFFSETS.iter().enumerate().filter(|&(s_, _)| used[s_]) {
            if self.on_grid(i + di, j + dj) {
                let block = multiply(s, &self.coupling_block(p, s_));
                self.set_coupling(p, s_, &block);
            }
            if self.on_grid(i - di, j - dj) {
                let q = (j - dj) as usize * self.nx + (i - di) as usize;
                let block = multiply(&self.coupling_block(q, s_), s);
                self.set_coupling(q, s_, &block);
            }
        }
    }

    fn set_coupling(&mut self, p: usize, s: usize, block: &Block<T>) {
        let c = self.couplings.arrays_mut();
        for (e, &value) in block.iter().enumerate() {
            c[9 * s + e][p] = value;
        }
    }

    /// This level's blocks as runs over its particles, entry by entry (see [`BlockRuns`]).
    fn block_runs(&self) -> BlockRuns<'_, T> {
        let diagonal = self.diagonal.arrays();
        let couplings = self.couplings.arrays();
        let ahead: [[&[T]; 9]; FORWARD] =
            std::array::from_fn(|s| std::array::from_fn(|e| couplings[9 * s + e]));
        BlockRuns {
            diagonal: AS_GENERAL.map(|e| diagonal[e]),
            ahead,
            behind: ahead.map(|b| TRANSPOSED.map(|e| b[e])),
        }
    }

    /// This level as the Galerkin product `Pᵀ A P` of `fine`, the level above, with the rows,
    /// columns and diagonal of this level's pinned particles zero. The bilinear `P` is the
    /// product of an interpolation along y and one along x, so `Pᵀ A P` is taken one axis at a
    /// time: `across` (the level above's width, this level's height) becomes `fine` coarsened
    /// along y, and this level `across` coarsened along x. A pass gathers or scatters along one
    /// axis the three children and two parents that the product in one pass would take along
    /// both, and the pass along y runs over whole rows of blocks. Every block is summed in one
    /// fixed order, so the bits do not depend on how the rows are split over the pool's threads.
    /// `weights` are those of each fine column's parents (see [`parent_weights`]).
    pub fn fill_galerkin(
        &mut self,
        fine: &BlockStencil<T>,
        across: &mut BlockStencil<T>,
        weights: &[Vec<T>; 2],
    ) {
        across.fill_coarsened_along_y(fine);
        self.fill_coarsened_along_x(across, weights);
        for k in 0..self.pinned.len() {
            self.filter_particle(self.pinned[k], &[T::ZERO; 9]);
        }
    }

    /// This level (as wide as `fine`) as `fine` coarsened along y: `Qᵀ A Q` with `Q` the
    /// interpolation along y. Coarse row `cj` gathers, for each fine child row and each block
    /// of that row (the diagonal, the blocks ahead and the transposes of those behind), the share
    /// of the partner's row that coarse row `cj + dj` takes, one whole row of blocks at a time.
    /// Blocks that land behind are skipped: their partners' rows hold their transposes.
    fn fill_coarsened_along_y(&mut self, fine: &BlockStencil<T>) {
        let (nx, cy, ny) = (self.nx, self.ny, fine.ny);
        debug_assert_eq!(nx, fine.nx);
        let band = self.band_rows();
        let fine_used = fine.used;
        let BlockRuns { diagonal, ahead, behind } = fine.block_runs();
        let rows = (self.diagonal.arrays_mut(), self.couplings.arrays_mut());
        in_bands(rows, cy, nx, band, &|first, count, (mut d, mut c)| {
            for run in d.iter_mut().chain(c.iter_mut()) {
                run.fill(T::ZERO);
            }
            for cj in first..first + count {
                let out = (cj - first) * nx;
                // Adds `w` times the blocks `block[k]`, k in `from`, between fine (i, fj) and
                // (i + di, gj), to the coarse blocks between (i, cj) and the parents of
                // (i + di, gj), for the particles i from `first_column` on.
                let mut spread = |block: &[&[T]; 9],
                                  from: std::ops::Range<usize>,
                                  first_column: usize,
                                  w: T,
                                  di: isize,
                                  gj: usize| {
                    for (pj, wp) in parents::<T>(gj, cy) {
                        let dj = pj as isize - cj as isize;
                        if wp == T::ZERO || !(0..=REACH).contains(&dj) {
                            continue;
                        }
                        let to = out + first_column..out + first_column + from.len();
                        let w = w * wp;
                        let sum = SUMS_OF[(dj * 5 + di + 2) as usize];
                        if sum == BEHIND {
                            continue;
                        }
                        each_run_of(sum, &mut d, &mut c, |run, e| {
                            add_scaled(&mut run[to.clone()], &block[e][from.clone()], w)
                        });
                    }
                };
                for (fj, w) in children::<T>(cj, cy, ny) {
                    let row = fj * nx;
                    spread(&diagonal, row..row + nx, 0, w, 0, fj);
                    for s in (0..FORWARD).filter(|&s| fine_used[s]) {
                        let [di, dj] = OFFSETS[s];
                        // Blocks ahead are zero where their partner is off the grid.
                        if fj + (dj as usize) < ny {
                            spread(&ahead[s], row..row + nx, 0, w, di, fj + dj as usize);
                        }
                        // The block between (i, fj) and (i - di, fj - dj), the transpose of the
                        // one stored at its partner, for the i whose partner is on the grid.
                        if let Some(gj) = fj.checked_sub(dj as usize) {
                            let columns = di.max(0) as usize..(nx as isize + di.min(0)) as usize;
                            let at = gj * nx + (columns.start as isize - di) as usize;
                            spread(&behind[s], at..at + columns.len(), columns.start, w, -di, gj);
                        }
                    }
                }
            }
        });
    }

    /// This level (as tall as `fine`) as `fine` coarsened along x, row by row: each fine block
    /// of a row (the diagonal, the blocks ahead, and the transposes of those behind on the same
    /// row) goes to the coarse blocks between its particle's parents and its partner's parents.
    /// Fine column `i` has its first parent at `i / 2` and its second at `i / 2 + 1`, with the
    /// weights `weights[0][i]` and `weights[1][i]` (see [`parent_weights`]); on the columns of
    /// one parity, a block and a choice of the two parents land at one coarse offset, so each
    /// such choice is one run over the row with a stride of two. Blocks that land behind are
    /// skipped, as along y.
    fn fill_coarsened_along_x(&mut self, fine: &BlockStencil<T>, weights: &[Vec<T>; 2]) {
        let (cx, ny, nx) = (self.nx, self.ny, fine.nx);
        debug_assert_eq!((ny, weights[0].len()), (fine.ny, nx));
        let band = self.band_rows();
        let fine_used = fine.used;
        let BlockRuns { diagonal, ahead, behind } = fine.block_runs();
        let rows = (self.diagonal.arrays_mut(), self.couplings.arrays_mut());
        in_bands(rows, ny, cx, band, &|first, count, (mut d, mut c)| {
            for run in d.iter_mut().chain(c.iter_mut()) {
                run.fill(T::ZERO);
            }
            for j in first..first + count {
                let out = (j - first) * cx;
                // Adds the blocks `block[row + i + shift]` between fine (i, j) and (i + di, j + dj),
                // for the columns i in `columns`.
                let mut spread = |block: &[&[T]; 9],
                                  shift: isize,
                                  columns: std::ops::Range<usize>,
                                  di: isize,
                                  dj: usize| {
                    for parity in 0..2 {
                        // Column i = 2m + parity; its partner's first parent is m + below.
                        let below = (parity as isize + di).div_euclid(2);
                        let partner_parity = (parity as isize + di).rem_euclid(2) as usize;
                        let m_first = (columns.start + 1 - parity) / 2;
                        let m_end = (columns.end + 1 - parity) / 2;
                        // An even column is a coarse point: its second parent has weight zero.
                        for own in 0..=parity {
                            for other in 0..=partner_parity {
                                let offset = below + other as isize - own as isize;
                                let sum = SUMS_OF[dj * 5 + (offset + 2) as usize];
                                if sum == BEHIND {
                                    continue;
                                }
                                let m_end = m_end.min(cx - own);
                                if m_first >= m_end {
                                    continue;
                                }
                                // The runs' weights, a chunk of columns at a time.
                                let mut m = m_first;
                                while m < m_end {
                                    let len = (m_end - m).min(RUN_CHUNK);
                                    let i = 2 * m + parity;
                                    let mut w = [T::ZERO; RUN_CHUNK];
                                    let wa = weights[own][i..].iter().step_by(2);
                                    let wb = weights[other][(i as isize + di) as usize..].iter().step_by(2);
                                    for ((w, &a), &b) in w[..len].iter_mut().zip(wa).zip(wb) {
                                        *w = a * b;
                                    }
                                    let at = ((j * nx + i) as isize + shift) as usize;
                                    let add = |run: &mut [T], from: &[T]| {
                                        let run = &mut run[out + own + m..out + own + m + len];
                                        // Every other entry: the first of each pair.
                                        let from = from[at..at + 2 * len - 1].chunks(2);
                                        for ((r, f), &w) in run.iter_mut().zip(from).zip(&w[..len]) {
                                            *r = f[0].mul_add(w, *r);
                                        }
                                    };
                                    each_run_of(sum, &mut d, &mut c, |run, e| add(run, block[e]));
                                    m += len;
                                }
                            }
                        }
                    }
                };
                spread(&diagonal, 0, 0..nx, 0, 0);
                for s in (0..FORWARD).filter(|&s| fine_used[s]) {
                    let [di, dj] = OFFSETS[s];
                    if j + (dj as usize) < ny {
                        let columns = (-di).max(0) as usize..(nx as isize - di.max(0)) as usize;
                        spread(&ahead[s], 0, columns, di, dj as usize);
                    }
                    // A partner behind on an earlier row lands behind.
                    if dj == 0 {
                        spread(&behind[s], -di, di as usize..nx, -di, 0);
                    }
                }
            }
        });
    }

    /// The smoother `ω D⁻¹` with `ω = min(0.9, 1.8 / λmax(D⁻¹ A))`, `λmax` by power iteration
    /// (see the module docs) from the vector `power`, which the level keeps between steps;
    /// `product` is scratch.
    pub fn update_smoother(&mut self, power: &mut Field<T>, product: &mut Field<T>) {
        let (nx, ny) = (self.nx, self.ny);
        let diagonal = self.diagonal.arrays();
        let piece = if self.parallel { 16 } else { ny };
        in_bands(self.smoother.arrays_mut(), ny, nx, piece, &|first, _, mut s| {
            for m in 0..s[0].len() {
                let block = Sym3::from_entries(diagonal.map(|a| a[first * nx + m]));
                for (s, e) in s.iter_mut().zip(block.inverse().entries()) {
                    s[m] = e;
                }
            }
        });
        let iterations = if self.warm { POWER_ITERATIONS } else { FIRST_POWER_ITERATIONS };
        if !self.warm {
            start_vector(power, &self.pinned);
        }
        let largest = self.largest_eigenvalue(power, product, iterations);
        self.warm = largest.is_finite();
        self.damping = if largest.is_finite() && largest > 0.0 {
            MAX_DAMPING.min(DAMPED_RADIUS / largest)
        } else {
            MAX_DAMPING
        };
        let omega = T::from_f64(self.damping);
        for s in self.smoother.iter_mut() {
            for s in s.iter_mut() {
                *s *= omega;
            }
        }
    }

    /// The Rayleigh quotient `vᵀ A v / vᵀ D v` after `iterations` power iterations
    /// `v ← D⁻¹ A v` from `power`, with the smoother holding `D⁻¹`; `NaN` when there is nothing
    /// to iterate on.
    fn largest_eigenvalue(&self, power: &mut Field<T>, product: &mut Field<T>, iterations: usize) -> f64 {
        let mut largest = f64::NAN;
        for _ in 0..iterations {
            self.apply(power, product);
            let along: f64 = (0..3).map(|a| dot_slices(&power[a], &product[a])).sum();
            let mut weight = 0.0;
            for p in 0..self.len() {
                let v = Vec3::new(power[0][p], power[1][p], power[2][p]);
                let dv = self.diagonal_block(p).apply(v);
                weight += (v.x * dv.x + v.y * dv.y + v.z * dv.z).to_f64();
            }
            largest = along / weight;
            // v ← D⁻¹ A v, scaled to unit length.
            self.smooth_from_zero(product, power);
            let norm: f64 = (0..3).map(|a| dot_slices(&power[a], &power[a])).sum::<f64>().sqrt();
            if !(norm.is_finite() && norm > 0.0) {
                start_vector(power, &self.pinned);
                return f64::NAN;
            }
            let scale = T::from_f64(1.0 / norm);
            for axis in power.iter_mut() {
                for v in axis.iter_mut() {
                    *v *= scale;
                }
            }
        }
        largest
    }

    /// `y = A x`.
    pub fn apply(&self, x: &Field<T>, y: &mut Field<T>) {
        self.apply_all(x, None, y);
    }

    /// `r = b - A x`.
    pub fn residual(&self, b: &Field<T>, x: &Field<T>, r: &mut Field<T>) {
        self.apply_all(x, Some(b), r);
    }

    /// `y = A x`, or `y = b - A x` with `b`, by bands of rows; each `y[p]` is summed in one
    /// fixed order (the diagonal, then each slot ahead and behind), whatever the bands.
    ///
    /// A band is one stretch of the arrays per slot and direction: a block is zero wherever its
    /// partner is off the grid, so running on past a row's end into the next adds exact zeros.
    fn apply_all(&self, x: &Field<T>, b: Option<&Field<T>>, y: &mut Field<T>) {
        let (nx, ny, n) = (self.nx, self.ny, self.len());
        let (diagonal, couplings, x) = (self.diagonal.arrays(), self.couplings.arrays(), x.arrays());
        in_bands(y.arrays_mut(), ny, nx, self.band_rows(), &|first, count, mut y| {
            let rows = first * nx..(first + count) * nx;
            let d = diagonal.map(|a| &a[rows.clone()]);
            symmetric_products::<T, false>(y.each_mut().map(|y| &mut y[..]), d, x.map(|x| &x[rows.clone()]));
            for (s, &[di, dj]) in OFFSETS.iter().enumerate().filter(|&(s, _)| self.used[s]) {
                let shift = (dj * nx as isize + di) as usize;
                let block: [&[T]; 9] = std::array::from_fn(|e| couplings[9 * s + e]);
                // A[p, p + off] x[p + off].
                let ahead = rows.start..rows.end.min(n.saturating_sub(shift));
                if !ahead.is_empty() {
                    let out = ahead.start - rows.start..ahead.end - rows.start;
                    let q = ahead.start + shift..ahead.end + shift;
                    add_block_products::<T, false>(
                        y.each_mut().map(|y| &mut y[out.clone()]),
                        block.map(|a| &a[ahead.clone()]),
                        x.map(|x| &x[q.clone()]),
                    );
                }
                // A[p, p - off] x[p - off] = A[p - off, p]ᵀ x[p - off].
                let behind = rows.start.max(shift)..rows.end;
                if !behind.is_empty() {
                    let out = behind.start - rows.start..behind.end - rows.start;
                    let q = behind.start - shift..behind.end - shift;
                    add_block_products::<T, true>(
                        y.each_mut().map(|y| &mut y[out.clone()]),
                        block.map(|a| &a[q.clone()]),
                        x.map(|x| &x[q.clone()]),
                    );
                }
            }
            if let Some(b) = b {
                for (y, b) in y.iter_mut().zip(b.iter()) {
                    for (y, &b) in y.iter_mut().zip(&b[rows.clone()]) {
                        *y = b - *y;
                    }
                }
            }
        });
    }

    /// `x = W r`: one smoothing sweep from a zero guess.
    pub fn smooth_from_zero(&self, r: &Field<T>, x: &mut Field<T>) {
        self.smoother_products::<false>(r, x);
    }

    /// `x += W r`: one smoothing sweep from the residual `r = b - A x`.
    pub fn smooth_from_residual(&self, r: &Field<T>, x: &mut Field<T>) {
        self.smoother_products::<true>(r, x);
    }

    fn smoother_products<const ADD: bool>(&self, r: &Field<T>, x: &mut Field<T>) {
        let (smoother, r, nx) = (self.smoother.arrays(), r.arrays(), self.nx);
        let piece = if self.parallel { 16 } else { self.ny };
        in_bands(x.arrays_mut(), self.ny, nx, piece, &|first, count, x| {
            let at = first * nx..(first + count) * nx;
            symmetric_products::<T, ADD>(x, smoother.map(|a| &a[at.clone()]), r.map(|a| &a[at.clone()]));
        });
    }

    /// Sets the smoother's block of every particle to `block(p)`: level 0's smoother, which
    /// the multigrid builds from the system's own.
    pub fn set_smoother(&mut self, block: impl Fn(usize) -> Sym3<T>) {
        let mut s = self.smoother.arrays_mut();
        for p in 0..self.nx * self.ny {
            for (s, e) in s.iter_mut().zip(block(p).entries()) {
                s[p] = e;
            }
        }
    }
}

/// Level 0's smoother on a filtered system: the system's own block-Jacobi smoother `ω D̃⁻¹` on
/// free particles (`D̃` its diagonal block with its shift for the bending), and on a particle
/// held by `s` the same on its free part and the identity on its held part,
/// `ω (s D̃ s + I − s)⁻¹ + (1 − ω)(I − s)`: the held part of the filtered system is the identity
/// itself, so the cycle returns it exactly.
pub(crate) fn held_smoother<T: Real>(system: &GridOperator<T>, p: usize, s: Sym3<T>) -> Sym3<T> {
    let mut d = system.block(p, p);
    if let Some(&shift) = system.smoother_shift().get(p) {
        d += Sym3::identity() * shift;
    }
    let s = general(s);
    let held: Block<T> = std::array::from_fn(|e| if e % 4 == 0 { T::ONE - s[e] } else { T::ZERO - s[e] });
    let filtered = multiply(&s, &multiply(&general(d), &s));
    let sum: Block<T> = std::array::from_fn(|e| filtered[e] + held[e]);
    let omega = T::from_f64(JACOBI_DAMPING);
    let inverse = symmetric(&sum).inverse().entries();
    let held = symmetric(&held).entries();
    Sym3::from_entries(std::array::from_fn(|e| inverse[e] * omega + held[e] * (T::ONE - omega)))
}

/// The weights of the parents of each of `fine` points along an axis of `coarse`: of the first
/// parent, at `i / 2`, and of the second, at `i / 2 + 1` (zero where a point has one parent).
pub(crate) fn parent_weights<T: Real>(fine: usize, coarse: usize) -> [Vec<T>; 2] {
    let parents = (0..fine).map(|i| (i, parents::<T>(i, coarse)));
    let first = parents.clone().map(|(_, [(_, w), _])| w).collect();
    let second = parents.map(|(i, [_, (p, w)])| if p == i / 2 + 1 { w } else { T::ZERO }).collect();
    [first, second]
}

/// The fine points along an axis of `fine` points that take a share of coarse point `c` (of
/// `coarse`), with their weights; absent ones have weight zero.
fn children<T: Real>(c: usize, coarse: usize, fine: usize) -> impl Iterator<Item = (usize, T)> {
    ((2 * c).saturating_sub(1)..(2 * c + 2).min(fine))
        .flat_map(move |i| parents::<T>(i, coarse).into_iter().map(move |(p, w)| (i, p, w)))
        .filter(move |&(_, p, w)| p == c && w != T::ZERO)
        .map(|(i, _, w)| (i, w))
}

/// A field with a fixed pattern of values in [-1, 1] on every axis, zero on `pinned`.
fn start_vector<T: Real>(field: &mut Field<T>, pinned: &[usize]) {
    for (a, axis) in field.iter_mut().enumerate() {
        for (p, v) in axis.iter_mut().enumerate() {
            *v = T::from_f64((p as f64 * 0.7315 + 1.9 * a as f64).sin());
        }
        for &p in pinned {
            axis[p] = T::ZERO;
        }
    }
}

/// A symmetric block as a general one.
pub(crate) fn general<T: Real>(s: Sym3<T>) -> Block<T> {
    let [xx, yy, zz, xy, xz, yz] = s.entries();
    [xx, xy, xz, xy, yy, yz, xz, yz, zz]
}

/// The symmetric part's entries of a block whose lower triangle mirrors its upper one.
fn symmetric<T: Real>(b: &Block<T>) -> Sym3<T> {
    Sym3::from_entries([b[0], b[4], b[8], b[1], b[2], b[5]])
}

fn multiply<T: Real>(a: &Block<T>, b: &Block<T>) -> Block<T> {
    std::array::from_fn(|e| {
        let (r, c) = (e / 3, e % 3);
        a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c]
    })
}

/// Columns whose weights a run of the pass along x computes at once.
const RUN_CHUNK: usize = 64;

/// Entry `e` of a symmetric block as a general one is entry `AS_GENERAL[e]` of its six.
const AS_GENERAL: [usize; 9] = [0, 3, 4, 3, 1, 5, 4, 5, 2];

/// Entry `e` of a block's transpose is entry `TRANSPOSED[e]` of the block.
const TRANSPOSED: [usize; 9] = [0, 3, 6, 1, 4, 7, 2, 5, 8];

/// A level's blocks as runs over its particles, entry `e` of each block (row-major) in run `[e]`:
/// the diagonal block, the blocks ahead at each slot, and at each slot the transposes of the
/// blocks ahead (a particle's run holds the block its partner behind sees).
struct BlockRuns<'a, T> {
    diagonal: [&'a [T]; 9],
    ahead: [[&'a [T]; 9]; FORWARD],
    behind: [[&'a [T]; 9]; FORWARD],
}

/// Calls `add(run, e)` for each run of a band that the sum `sum` (see [`SUMS_OF`]; not
/// [`BEHIND`]) is kept in, with the entry `e` of a general block that goes there: the six upper
/// entries of the diagonal `d`, or the nine of slot `sum − 1` of the couplings `c`.
fn each_run_of<T>(sum: u8, d: &mut [&mut [T]], c: &mut [&mut [T]], mut add: impl FnMut(&mut [T], usize)) {
    if sum == 0 {
        for (run, e) in d.iter_mut().zip([0, 4, 8, 1, 2, 5]) {
            add(run, e);
        }
    } else {
        let s = sum as usize - 1;
        for (e, run) in c[9 * s..9 * s + 9].iter_mut().enumerate() {
            add(run, e);
        }
    }
}

/// `to += w from`, element by element.
#[inline(always)]
fn add_scaled<T: Real>(to: &mut [T], from: &[T], w: T) {
    for (t, &f) in to.iter_mut().zip(from) {
        *t = f.mul_add(w, *t);
    }
}

/// `y = D x` (or `y += D x` with `ADD`) for a run of symmetric blocks `d`.
#[inline(always)]
fn symmetric_products<T: Real, const ADD: bool>(y: [&mut [T]; 3], d: [&[T]; 6], x: [&[T]; 3]) {
    let len = y[0].len();
    let [y0, y1, y2] = y.map(|s| &mut s[..len]);
    let [axx, ayy, azz, axy, axz, ayz] = d.map(|s| &s[..len]);
    let [x0, x1, x2] = x.map(|s| &s[..len]);
    for k in 0..len {
        let (u, v, w) = (x0[k], x1[k], x2[k]);
        let r0 = axx[k].mul_add(u, axy[k].mul_add(v, axz[k] * w));
        let r1 = axy[k].mul_add(u, ayy[k].mul_add(v, ayz[k] * w));
        let r2 = axz[k].mul_add(u, ayz[k].mul_add(v, azz[k] * w));
        if ADD {
            y0[k] += r0;
            y1[k] += r1;
            y2[k] += r2;
        } else {
            (y0[k], y1[k], y2[k]) = (r0, r1, r2);
        }
    }
}

/// `y += B x` (or `y += Bᵀ x` with `TRANSPOSE`) for a run of general blocks `b`.
#[inline(always)]
fn add_block_products<T: Real, const TRANSPOSE: bool>(y: [&mut [T]; 3], b: [&[T]; 9], x: [&[T]; 3]) {
    let len = y[0].len();
    let [y0, y1, y2] = y.map(|s| &mut s[..len]);
    let b = b.map(|s| &s[..len]);
    let [x0, x1, x2] = x.map(|s| &s[..len]);
    // Row r of the block (or column r of its transpose) is entries `at(r, 0..3)`.
    let at = |r: usize, c: usize| if TRANSPOSE { b[3 * c + r] } else { b[3 * r + c] };
    let (b00, b01, b02) = (at(0, 0), at(0, 1), at(0, 2));
    let (b10, b11, b12) = (at(1, 0), at(1, 1), at(1, 2));
    let (b20, b21, b22) = (at(2, 0), at(2, 1), at(2, 2));
    for k in 0..len {
        let (u, v, w) = (x0[k], x1[k], x2[k]);
        y0[k] += b00[k].mul_add(u, b01[k].mul_add(v, b02[k] * w));
        y1[k] += b10[k].mul_add(u, b11[k].mul_add(v, b12[k] * w));
        y2[k] += b20[k].mul_add(u, b21[k].mul_add(v, b22[k] * w));
    }
}
