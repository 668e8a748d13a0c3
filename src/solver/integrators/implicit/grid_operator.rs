//! The implicit system of a grid cloth as a symmetric block stencil, stored row by row.
//!
//! On a grid of `nx × ny` particles the system `A = M + Σ_s (e_i - e_j)(e_i - e_j)ᵀ ⊗ S_s` has a
//! 3×3 diagonal block per particle and one coupling block `-S_s` per spring. A spring's block is
//! `S = (h c + h² k (1 - α)) n nᵀ + h² k α I` with `α = max(0, 1 - L/l)` (see
//! [`stiffness_block`](crate::solver::forces::springs::stiffness_block)), a rank-one term plus a
//! multiple of the identity, so it is stored as four numbers, `u = √(h c + h² k (1 - α)) n` and
//! `σ = h² k α`, with `S x = u (u·x) + σ x`: two thirds of the memory and half the arithmetic of
//! a general symmetric block. Every spring family of the stencil joins `p` to `p + off` for one
//! offset `off`, so the couplings are stored per offset, indexed by the lower particle `p`, as
//! four arrays. A product `y = A x` is then a gather: each row of `y` is its diagonal term plus,
//! for every offset, the coupling at `p` times `x[p + off]` and the coupling
//! at `p - off` times `x[p - off]`. Along a grid row those are contiguous slices, so every inner
//! loop runs over plain arrays and vectorises, and every `y[p]` is summed in one fixed order:
//! the result does not depend on how rows are split.
//!
//! The same type serves every level of the multigrid hierarchy: a coarse level is the same cloth
//! rediscretised on every other particle, with its own positions, lumped masses and doubled rest
//! lengths.

use crate::solver::arrays::Arrays;
use crate::solver::forces::springs::step_transverse_factor;
use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use crate::solver::parallel::in_bands;

/// A vector field over the particles, one array per axis.
pub(crate) type Field<T> = Arrays<T, 3>;

/// A field of zeros over `n` particles.
pub(crate) fn zero_field<T: Real>(n: usize) -> Field<T> {
    Arrays::zeros(n)
}

/// One spring family of a grid: every spring joins particle `p` to `p + offset` (grid steps
/// `[di, dj]`, with `dj > 0`, or `dj == 0` and `di > 0`), with shared parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Family<T> {
    pub offset: [isize; 2],
    pub rest_length: T,
    pub stiffness: T,
    pub damping: T,
}

/// What the fine level adds to an assembly: the velocities and the right-hand side to which
/// each spring adds `∓h² K (v_i - v_j)`, with a field per family (`pull`) to hold those terms
/// between the assembly's two passes.
pub(crate) struct RightHandSide<'a, T> {
    pub velocities: &'a Field<T>,
    pub rhs: &'a mut Field<T>,
    pub pull: &'a mut [Field<T>],
}

/// A symmetric block stencil operator on an `nx × ny` grid, with its block-Jacobi smoother.
#[derive(Debug)]
pub(crate) struct GridOperator<T> {
    pub nx: usize,
    pub ny: usize,
    /// The distinct offsets of the couplings.
    offsets: Vec<[isize; 2]>,
    /// Per particle: the diagonal block.
    diagonal: Arrays<T, 6>,
    /// Per offset, per lower particle `p`: `[u_x, u_y, u_z, σ]` of the spring whose block
    /// `-(u uᵀ + σ I)` is `A[p, p + off]`.
    couplings: Vec<Arrays<T, 4>>,
    /// Per particle: `ω D⁻¹`, the damped block-Jacobi smoother.
    smoother: Arrays<T, 6>,
    /// Per particle, on a level with a term applied outside this operator (its bending): what
    /// the smoother adds to `D`'s `xx`, `yy` and `zz` for it. Empty on any other.
    smoother_shift: Vec<T>,
    /// Particles held fixed: their rows and columns are decoupled (only the mass on the diagonal).
    pub pinned: Vec<usize>,
    /// Whether products and smoothing are split over the pool's threads.
    parallel: bool,
}

/// The smoother's damping `ω`: the block-Jacobi iteration matrix `I - ω D⁻¹ A` has spectral
/// radius below one since `λ(D⁻¹A) ≤ 2` for a sum of positive semi-definite spring blocks.
/// Measured on the peers' cloth at 128², 0.9 takes 13 iterations per step where 0.7 takes 14
/// and 0.6 takes 16.
pub(crate) const JACOBI_DAMPING: f64 = 0.9;

/// Grids (and multigrid levels) with at least this many particles split their work over the
/// pool's threads: a 64² cloth (4,096 particles) has enough work in each pass to gain from the
/// split, and the next size down, 32², is a quarter of it (`docs/decisions.md`).
pub(crate) const PARALLEL_PARTICLES: usize = 4_096;

/// The smoother's block `ω (D + shift I)⁻¹` of a particle whose diagonal block is `diagonal`, as
/// its entries.
fn smoother_entries<T: Real>(diagonal: Sym3<T>, shift: Option<&T>) -> [T; 6] {
    let block = match shift {
        Some(&shift) => diagonal + Sym3::identity() * shift,
        None => diagonal,
    };
    (block.inverse() * T::from_f64(JACOBI_DAMPING)).entries()
}

/// Below this squared length a spring has no direction and contributes nothing.
const TINY_SQUARED_LENGTH: f64 = 1e-30;

impl<T: Real> GridOperator<T> {
    /// The operator of `families` (whose offsets are distinct) on an `nx × ny` grid.
    pub fn new(nx: usize, ny: usize, families: &[Family<T>], pinned: Vec<usize>) -> Self {
        let n = nx * ny;
        let offsets: Vec<[isize; 2]> = families.iter().map(|f| f.offset).collect();
        Self {
            nx,
            ny,
            couplings: offsets.iter().map(|_| Arrays::zeros(n)).collect(),
            offsets,
            diagonal: Arrays::zeros(n),
            smoother: Arrays::zeros(n),
            smoother_shift: Vec::new(),
            pinned,
            parallel: n >= PARALLEL_PARTICLES,
        }
    }

    /// The number of particles.
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Whether products with this operator are split over threads.
    pub fn is_parallel(&self) -> bool {
        self.parallel
    }

    /// Builds `M + h D + h² K` at `positions` (`mass` per particle, already including drag),
    /// with spring rest lengths scaled by `rest_scale`. With `rhs`, also adds `-h² K v` to the
    /// right-hand side. The smoother is left as it was: a step's own system in `f64` only
    /// computes products, and the multigrid level that smooths with it calls
    /// [`update_smoother`](Self::update_smoother) once its diagonal is complete.
    ///
    /// Two passes over the rows, each split over the pool's threads on a parallel operator: the
    /// first computes every spring's coupling (and its right-hand-side term) at its lower end; the
    /// second gathers into each particle's diagonal block (and right-hand side) the springs at
    /// both its ends, family by family, in one fixed order. Every row is computed alone, so the
    /// bits do not depend on the split.
    pub fn assemble(
        &mut self,
        positions: &Field<T>,
        mass: &[T],
        families: &[Family<T>],
        rest_scale: T,
        h: T,
        mut rhs: Option<RightHandSide<'_, T>>,
    ) {
        let (nx, ny) = (self.nx, self.ny);
        let band = self.band_rows();
        for (slot, family) in families.iter().enumerate() {
            let Some(Span { dj, i0, len, shift }) = Span::of(family.offset, nx, ny) else { continue };
            let spring = SpringCoefficients {
                rest_length: family.rest_length * rest_scale,
                h_damping: h * family.damping,
                h2_stiffness: h * h * family.stiffness,
            };
            // The springs of row `j` (global) whose lower ends start at `local` in the band.
            let ends = |j: usize, local: usize| {
                let p = j * nx + i0;
                let q = (p as isize + shift) as usize;
                let lower = positions.arrays().map(|a| &a[p..p + len]);
                let upper = positions.arrays().map(|a| &a[q..q + len]);
                (p, q, local + i0, lower, upper)
            };
            let coupling = self.couplings[slot].arrays_mut();
            match rhs.as_mut() {
                Some(RightHandSide { velocities, pull, .. }) => {
                    let rows = (coupling, pull[slot].arrays_mut());
                    in_bands(rows, ny, nx, band, &|first, count, (mut coupling, mut pull)| {
                        for j in first..(first + count).min(ny - dj) {
                            let (p, q, at, xp, xq) = ends(j, (j - first) * nx);
                            let vp = velocities.arrays().map(|a| &a[p..p + len]);
                            let vq = velocities.arrays().map(|a| &a[q..q + len]);
                            let c = coupling.each_mut().map(|a| &mut a[at..at + len]);
                            let pull = pull.each_mut().map(|a| &mut a[at..at + len]);
                            spring_row::<T, true>(&spring, xp, xq, c, Some((vp, vq, pull)));
                        }
                    });
                }
                None => in_bands(coupling, ny, nx, band, &|first, count, mut coupling| {
                    for j in first..(first + count).min(ny - dj) {
                        let (_, _, at, xp, xq) = ends(j, (j - first) * nx);
                        let c = coupling.each_mut().map(|a| &mut a[at..at + len]);
                        spring_row::<T, false>(&spring, xp, xq, c, None);
                    }
                }),
            }
        }
        // Each particle's diagonal block is its mass plus the blocks of the springs at both its
        // ends; its right-hand side loses the term of a spring at its lower end and gains that
        // of one at its upper end. Family by family, a particle takes the spring of the row
        // before first, and of a same-row family the spring at its lower end first.
        let (offsets, couplings) = (&self.offsets, &self.couplings);
        let spans = || offsets.iter().map(|&offset| Span::of(offset, nx, ny));
        let gather_diagonal = |first: usize, count: usize, mut diagonal: [&mut [T]; 6]| {
            for j in first..first + count {
                let local = (j - first) * nx;
                let [dxx, dyy, dzz, dxy, dxz, dyz] = diagonal.each_mut().map(|a| &mut a[local..local + nx]);
                for (p, &m) in mass[j * nx..(j + 1) * nx].iter().enumerate() {
                    (dxx[p], dyy[p], dzz[p]) = (m, m, m);
                    (dxy[p], dxz[p], dyz[p]) = (T::ZERO, T::ZERO, T::ZERO);
                }
                for (span, coupling) in spans().zip(couplings) {
                    let Some(span) = span else { continue };
                    for (at, from, _) in span.ends_in_row(j, nx, ny) {
                        let d = diagonal.each_mut().map(|a| &mut a[local + at..local + at + span.len]);
                        add_spring_blocks(d, coupling.arrays().map(|a| &a[from..from + span.len]));
                    }
                }
            }
        };
        match rhs {
            Some(RightHandSide { rhs, pull, .. }) => {
                let rows = (self.diagonal.arrays_mut(), rhs.arrays_mut());
                in_bands(rows, ny, nx, band, &|first, count, (diagonal, mut rhs)| {
                    gather_diagonal(first, count, diagonal);
                    for j in first..first + count {
                        let local = (j - first) * nx;
                        for (span, pull) in spans().zip(pull.iter()) {
                            let Some(span) = span else { continue };
                            for (at, from, lower) in span.ends_in_row(j, nx, ny) {
                                let at = local + at..local + at + span.len;
                                for (r, pull) in rhs.iter_mut().zip(pull) {
                                    let (r, pull) = (&mut r[at.clone()], &pull[from..from + span.len]);
                                    if lower { sub_assign(r, pull) } else { add_assign(r, pull) }
                                }
                            }
                        }
                    }
                });
            }
            None => in_bands(self.diagonal.arrays_mut(), ny, nx, band, &gather_diagonal),
        }
        self.decouple_pinned(mass);
    }

    /// Rows per band when the operator's products and assembly are split over the pool's
    /// threads: all of them on a serial operator.
    fn band_rows(&self) -> usize {
        if self.parallel { self.ny.div_ceil(4 * rayon::current_num_threads()).max(1) } else { self.ny }
    }

    /// Rows per piece of the element-wise smoother work: sixteen on a parallel operator.
    fn piece_rows(&self) -> usize {
        if self.parallel { 16 } else { self.ny }
    }

    /// This operator as a copy of `source` (the same grid and families) rounded to `T`, with its
    /// own smoother: the preconditioner's copy of the step's system.
    pub fn copy_from<S: Real>(&mut self, source: &GridOperator<S>) {
        let pairs =
            self.diagonal.iter_mut().zip(&source.diagonal).chain(
                self.couplings.iter_mut().zip(&source.couplings).flat_map(|(a, b)| a.iter_mut().zip(b)),
            );
        for (to, from) in pairs {
            for (t, &f) in to.iter_mut().zip(from) {
                *t = T::from_f64(f.to_f64());
            }
        }
        self.update_smoother();
    }

    /// Gives the smoother a shift per particle (zero until set through
    /// [`smoother_shift_mut`](Self::smoother_shift_mut)), for a term the level applies outside
    /// this operator.
    pub fn with_smoother_shift(mut self) -> Self {
        self.smoother_shift = vec![T::ZERO; self.len()];
        self
    }

    /// The smoother's shift per particle, to set before the next assembly or
    /// [`update_smoother`](Self::update_smoother); empty without one.
    pub fn smoother_shift_mut(&mut self) -> &mut [T] {
        &mut self.smoother_shift
    }

    /// Adds `block` to particle `p`'s diagonal block (the smoother is not updated).
    pub fn add_to_diagonal(&mut self, p: usize, block: Sym3<T>) {
        for (axis, value) in self.diagonal.arrays_mut().iter_mut().zip(block.entries()) {
            axis[p] += value;
        }
    }

    /// `ω D⁻¹` from the diagonal blocks and the smoother's shift.
    pub fn update_smoother(&mut self) {
        let (nx, piece) = (self.nx, self.piece_rows());
        let (diagonal, shift) = (self.diagonal.arrays(), &self.smoother_shift);
        in_bands(self.smoother.arrays_mut(), self.ny, nx, piece, &|first, _, mut s| {
            for m in 0..s[0].len() {
                let block = Sym3::from_entries(diagonal.map(|a| a[first * nx + m]));
                for (s, e) in s.iter_mut().zip(smoother_entries(block, shift.get(first * nx + m))) {
                    s[m] = e;
                }
            }
        });
    }

    /// Zeroes the couplings of pinned particles and sets their diagonal to their mass, so that
    /// the system on the free particles is the filtered one and pinned rows stay decoupled.
    fn decouple_pinned(&mut self, mass: &[T]) {
        let (nx, ny) = (self.nx as isize, self.ny as isize);
        let inside = |i: isize, j: isize| (0..nx).contains(&i) && (0..ny).contains(&j);
        for &p in &self.pinned {
            let (i, j) = ((p % self.nx) as isize, (p / self.nx) as isize);
            for (&[di, dj], coupling) in self.offsets.iter().zip(&mut self.couplings) {
                // The coupling to `p + off` is stored at `p`, the one to `p - off` at `p - off`.
                let stored_at = [(i, j, (i + di, j + dj)), (i - di, j - dj, (i - di, j - dj))];
                for (li, lj, (oi, oj)) in stored_at {
                    if inside(oi, oj) {
                        let lower = (lj * nx + li) as usize;
                        for entry in coupling.iter_mut() {
                            entry[lower] = T::ZERO;
                        }
                    }
                }
            }
            let m = mass[p];
            for (entry, value) in self.diagonal.iter_mut().zip([m, m, m, T::ZERO, T::ZERO, T::ZERO]) {
                entry[p] = value;
            }
        }
    }

    /// `y = A x`, or `y = b - A x` with `b`, on the rows `rows` of the grid; `y` holds exactly
    /// those rows.
    fn apply_rows(&self, x: &Field<T>, b: Option<&Field<T>>, y: [&mut [T]; 3], rows: std::ops::Range<usize>) {
        let nx = self.nx;
        let [y0, y1, y2] = y;
        for j in rows.clone() {
            let local = (j - rows.start) * nx;
            let yr = [&mut y0[local..local + nx], &mut y1[local..local + nx], &mut y2[local..local + nx]];
            let p = j * nx;
            let xr = x.arrays().map(|a| &a[p..p + nx]);
            let d = self.diagonal.arrays().map(|a| &a[p..p + nx]);
            block_products::<T, false>(yr, d, xr);
            // A coupling is zero wherever no spring starts (it is never written there), so a pass
            // may run over the whole row wherever the indices it reads stay on the grid: it then
            // adds exact zeros on the extra columns and has no scalar remainder on a row of
            // whole vectors. Near the first and last rows it keeps to the springs' columns.
            let n = self.len() as isize;
            let columns = |i0: usize, i1: usize, first: isize| {
                if first >= 0 && first + nx as isize <= n { (0, nx) } else { (i0, i1) }
            };
            for (&[di, dj], coupling) in self.offsets.iter().zip(&self.couplings) {
                let shift = dj * nx as isize + di;
                let dj = dj as usize;
                // A[p, p + off] x[p + off] on the columns where p + off is on the grid.
                let (i0, i1) = (0.max(-di) as usize, (nx as isize).min(nx as isize - di).max(0) as usize);
                if j + dj < self.ny && i1 > i0 {
                    let (i0, i1) = columns(i0, i1, (j * nx) as isize + shift);
                    let (p, len) = (j * nx + i0, i1 - i0);
                    let q = (p as isize + shift) as usize;
                    let yr = [
                        &mut y0[local + i0..local + i1],
                        &mut y1[local + i0..local + i1],
                        &mut y2[local + i0..local + i1],
                    ];
                    let c = coupling.arrays().map(|a| &a[p..p + len]);
                    subtract_spring_products(yr, c, x.arrays().map(|a| &a[q..q + len]));
                }
                // A[p, p - off] x[p - off] = A[p - off, p]ᵀ x[p - off]; the blocks are symmetric.
                let (i0, i1) = (0.max(di) as usize, (nx as isize).min(nx as isize + di).max(0) as usize);
                if j >= dj && i1 > i0 {
                    let (i0, i1) = columns(i0, i1, (j * nx) as isize - shift);
                    let len = i1 - i0;
                    let q = ((j * nx + i0) as isize - shift) as usize;
                    let yr = [
                        &mut y0[local + i0..local + i1],
                        &mut y1[local + i0..local + i1],
                        &mut y2[local + i0..local + i1],
                    ];
                    let c = coupling.arrays().map(|a| &a[q..q + len]);
                    subtract_spring_products(yr, c, x.arrays().map(|a| &a[q..q + len]));
                }
            }
            if let Some(b) = b {
                for (y, b) in [&mut *y0, &mut *y1, &mut *y2].into_iter().zip(b) {
                    for (y, &b) in y[local..local + nx].iter_mut().zip(&b[p..p + nx]) {
                        *y = b - *y;
                    }
                }
            }
        }
    }

    /// `y = A x`, or `y = b - A x` with `b`. A large grid is cut into bands of rows applied in
    /// parallel; every `y[p]` is summed in the same order either way, so the bits do not depend
    /// on the cut or on the number of threads.
    fn apply_all(&self, x: &Field<T>, b: Option<&Field<T>>, y: &mut Field<T>) {
        in_bands(y.arrays_mut(), self.ny, self.nx, self.band_rows(), &|first, count, y| {
            self.apply_rows(x, b, y, first..first + count)
        });
    }

    /// `y = A x`.
    pub fn apply(&self, x: &Field<T>, y: &mut Field<T>) {
        self.apply_all(x, None, y);
    }

    /// `r = b - A x`.
    pub fn residual(&self, b: &Field<T>, x: &Field<T>, r: &mut Field<T>) {
        self.apply_all(x, Some(b), r);
    }

    /// `x = ω D⁻¹ b`: one smoothing sweep from a zero guess.
    pub fn smooth_from_zero(&self, b: &Field<T>, x: &mut Field<T>) {
        self.smoother_products::<false>(b, x);
    }

    /// `x += ω D⁻¹ r`: one damped block-Jacobi sweep from the residual `r = b - A x`, which the
    /// caller computed (with the terms it applies outside this operator).
    pub fn smooth_from_residual(&self, r: &Field<T>, x: &mut Field<T>) {
        self.smoother_products::<true>(r, x);
    }

    /// `x = ω D⁻¹ r`, or `x += ω D⁻¹ r` with `ADD`; in pieces on the pool's threads on a large
    /// grid (each entry is computed alone, so the pieces change no bits).
    fn smoother_products<const ADD: bool>(&self, r: &Field<T>, x: &mut Field<T>) {
        let (smoother, r) = (self.smoother.arrays(), r.arrays());
        in_bands(x.arrays_mut(), self.ny, self.nx, self.piece_rows(), &|first, count, x| {
            let at = first * self.nx..(first + count) * self.nx;
            block_products::<T, ADD>(x, smoother.map(|a| &a[at.clone()]), r.map(|a| &a[at.clone()]));
        });
    }

    /// The block `A[p, q]` for `q` equal to `p` or one stencil offset away (zero otherwise).
    pub fn block(&self, p: usize, q: usize) -> Sym3<T> {
        if p == q {
            return Sym3::from_entries(self.diagonal.arrays().map(|a| a[p]));
        }
        let (lower, upper) = (p.min(q), p.max(q));
        let (li, lj) = ((lower % self.nx) as isize, (lower / self.nx) as isize);
        let (ui, uj) = ((upper % self.nx) as isize, (upper / self.nx) as isize);
        let offset = [ui - li, uj - lj];
        match self.offsets.iter().position(|&o| o == offset) {
            Some(slot) => {
                let [ux, uy, uz, sigma] = self.couplings[slot].arrays().map(|a| a[lower]);
                let u = Vec3::new(ux, uy, uz);
                (Sym3::outer(u) + Sym3::identity() * sigma) * -T::ONE
            }
            None => Sym3::ZERO,
        }
    }

    /// The diagonal blocks' entries `[xx, yy, zz, xy, xz, yz]`, one array each.
    pub fn diagonal_arrays(&self) -> [&[T]; 6] {
        self.diagonal.arrays()
    }

    /// Per offset, the couplings `[u_x, u_y, u_z, σ]` at each lower particle (see the type's
    /// fields).
    pub fn coupling_arrays(&self) -> impl Iterator<Item = ([isize; 2], [&[T]; 4])> {
        self.offsets.iter().copied().zip(self.couplings.iter().map(Arrays::arrays))
    }

    /// The smoother's block `ω D⁻¹` of particle `p`.
    pub fn smoother_block(&self, p: usize) -> Sym3<T> {
        Sym3::from_entries(self.smoother.arrays().map(|a| a[p]))
    }

    /// The smoother's shift per particle; empty without one.
    pub fn smoother_shift(&self) -> &[T] {
        &self.smoother_shift
    }

    /// The stencil offsets, for walking the couplings of a particle.
    #[cfg(test)]
    pub fn offsets(&self) -> &[[isize; 2]] {
        &self.offsets
    }
}

/// Where a family's springs lie on the grid: rows `0..ny - dj`, columns `i0..i0 + len` of their
/// lower ends, the upper end `shift` particles after the lower.
#[derive(Clone, Copy)]
struct Span {
    dj: usize,
    i0: usize,
    len: usize,
    shift: isize,
}

impl Span {
    /// The span of the family of `offset`, or `None` if it has no spring on this grid.
    fn of([di, dj]: [isize; 2], nx: usize, ny: usize) -> Option<Self> {
        let (i0, i1) = (0.max(-di) as usize, (nx as isize).min(nx as isize - di).max(0) as usize);
        (i1 > i0 && (dj as usize) < ny).then(|| Self {
            dj: dj as usize,
            i0,
            len: i1 - i0,
            shift: dj * nx as isize + di,
        })
    }

    /// The runs of springs with an end on row `j`, in the order a particle takes them: per run,
    /// the first column of those ends on the row, the index of the first spring's lower end, and
    /// whether the ends on the row are the lower ones. The springs from the row before come
    /// first; on a same-row family the particle's spring to the next comes first.
    fn ends_in_row(self, j: usize, nx: usize, ny: usize) -> impl Iterator<Item = (usize, usize, bool)> {
        let lower = (j + self.dj < ny).then_some((self.i0, j * nx + self.i0, true));
        let upper = (j >= self.dj).then(|| {
            let from = ((j - self.dj) * nx + self.i0) as isize;
            ((from + self.shift) as usize - j * nx, from as usize, false)
        });
        let (first, second) = if self.dj > 0 { (upper, lower) } else { (lower, upper) };
        first.into_iter().chain(second)
    }
}

/// One family's coefficients in the step's units.
struct SpringCoefficients<T> {
    rest_length: T,
    h_damping: T,
    h2_stiffness: T,
}

/// The couplings `[u, σ]` of one row of springs from `p` to `q` (see the module docs); with
/// `PULL`, also `h² K (v_p - v_q)` per spring.
///
/// Written branch-free so that the loop vectorises: a spring without a direction gets `n = 0`
/// and `α = 0`, so `S = 0`.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn spring_row<T: Real, const PULL: bool>(
    spring: &SpringCoefficients<T>,
    xp: [&[T]; 3],
    xq: [&[T]; 3],
    coupling: [&mut [T]; 4],
    pull: Option<([&[T]; 3], [&[T]; 3], [&mut [T]; 3])>,
) {
    let len = coupling[0].len();
    let [xp0, xp1, xp2] = xp.map(|a| &a[..len]);
    let [xq0, xq1, xq2] = xq.map(|a| &a[..len]);
    let [ux, uy, uz, sigma] = coupling.map(|a| &mut a[..len]);
    let tiny = T::from_f64(TINY_SQUARED_LENGTH);
    let (rest, hc, h2k) = (spring.rest_length, spring.h_damping, spring.h2_stiffness);
    let (vp, vq, out) = match pull {
        Some((vp, vq, out)) => (vp, vq, out),
        None => ([&[][..]; 3], [&[][..]; 3], [&mut [][..], &mut [][..], &mut [][..]]),
    };
    let [vp0, vp1, vp2] = vp.map(|a| if PULL { &a[..len] } else { a });
    let [vq0, vq1, vq2] = vq.map(|a| if PULL { &a[..len] } else { a });
    let [o0, o1, o2] = out.map(|a| if PULL { &mut a[..len] } else { a });
    for k in 0..len {
        let (dx, dy, dz) = (xq0[k] - xp0[k], xq1[k] - xp1[k], xq2[k] - xp2[k]);
        let l2 = dx * dx + dy * dy + dz * dz;
        let valid = l2 > tiny;
        let inverse_length = if valid { T::ONE / l2.sqrt() } else { T::ZERO };
        let (nx, ny, nz) = (dx * inverse_length, dy * inverse_length, dz * inverse_length);
        let alpha = if valid { step_transverse_factor(rest * inverse_length) } else { T::ZERO };
        let axial = h2k * (T::ONE - alpha);
        let iso = h2k * alpha;
        let scale = (hc + axial).sqrt();
        ux[k] = nx * scale;
        uy[k] = ny * scale;
        uz[k] = nz * scale;
        sigma[k] = iso;
        if PULL {
            let (wx, wy, wz) = (vp0[k] - vq0[k], vp1[k] - vq1[k], vp2[k] - vq2[k]);
            let along = axial * (nx * wx + ny * wy + nz * wz);
            o0[k] = along * nx + iso * wx;
            o1[k] = along * ny + iso * wy;
            o2[k] = along * nz + iso * wz;
        }
    }
}

/// `D += u uᵀ + σ I` for a run of diagonal blocks `d` and couplings `c = [u, σ]`.
#[inline(always)]
fn add_spring_blocks<T: Real>(d: [&mut [T]; 6], c: [&[T]; 4]) {
    let len = d[0].len();
    let [dxx, dyy, dzz, dxy, dxz, dyz] = d.map(|s| &mut s[..len]);
    let [ux, uy, uz, sigma] = c.map(|s| &s[..len]);
    for k in 0..len {
        dxx[k] += ux[k].mul_add(ux[k], sigma[k]);
        dyy[k] += uy[k].mul_add(uy[k], sigma[k]);
        dzz[k] += uz[k].mul_add(uz[k], sigma[k]);
        dxy[k] += ux[k] * uy[k];
        dxz[k] += ux[k] * uz[k];
        dyz[k] += uy[k] * uz[k];
    }
}

/// `y -= u (u·x) + σ x` for a run of couplings `c = [u, σ]`.
#[inline(always)]
fn subtract_spring_products<T: Real>(y: [&mut [T]; 3], c: [&[T]; 4], x: [&[T]; 3]) {
    let len = y[0].len();
    let [y0, y1, y2] = y.map(|s| &mut s[..len]);
    let [ux, uy, uz, sigma] = c.map(|s| &s[..len]);
    let [x0, x1, x2] = x.map(|s| &s[..len]);
    for k in 0..len {
        let along = ux[k].mul_add(x0[k], uy[k].mul_add(x1[k], uz[k] * x2[k]));
        y0[k] -= ux[k].mul_add(along, sigma[k] * x0[k]);
        y1[k] -= uy[k].mul_add(along, sigma[k] * x1[k]);
        y2[k] -= uz[k].mul_add(along, sigma[k] * x2[k]);
    }
}

/// `y = A x` (or `y += A x` with `ADD`) for a run of symmetric blocks `a`.
#[inline(always)]
fn block_products<T: Real, const ADD: bool>(y: [&mut [T]; 3], a: [&[T]; 6], x: [&[T]; 3]) {
    let len = y[0].len();
    let [y0, y1, y2] = y.map(|s| &mut s[..len]);
    let [axx, ayy, azz, axy, axz, ayz] = a.map(|s| &s[..len]);
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
            y0[k] = r0;
            y1[k] = r1;
            y2[k] = r2;
        }
    }
}

#[inline(always)]
fn add_assign<T: Real>(a: &mut [T], b: &[T]) {
    for (a, &b) in a.iter_mut().zip(b) {
        *a += b;
    }
}

#[inline(always)]
fn sub_assign<T: Real>(a: &mut [T], b: &[T]) {
    for (a, &b) in a.iter_mut().zip(b) {
        *a -= b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bent `nx × ny` cloth of 5 cm spacing with the cloth's six families and two pins,
    /// assembled at 1/600 s.
    fn bent_operator(nx: usize, ny: usize) -> GridOperator<f64> {
        let spacing = 0.05;
        let family = |offset: [isize; 2]| {
            let length = spacing * ((offset[0] * offset[0] + offset[1] * offset[1]) as f64).sqrt();
            Family { offset, rest_length: length, stiffness: 5000.0, damping: 0.5 }
        };
        let families: Vec<_> = [[1, 0], [0, 1], [1, 1], [-1, 1], [2, 0], [0, 2]].map(family).to_vec();
        let n = nx * ny;
        let positions = Field::from_arrays(std::array::from_fn(|axis| {
            (0..n)
                .map(|p| {
                    let (i, j) = ((p % nx) as f64, (p / nx) as f64);
                    [i * spacing * 1.01, 0.02 * (0.4 * i).sin() * (0.3 * j).cos(), j * spacing * 0.99][axis]
                })
                .collect()
        }));
        let mut operator = GridOperator::new(nx, ny, &families, vec![0, nx - 1]);
        operator.assemble(&positions, &vec![1.0 / n as f64; n], &families, 1.0, 1.0 / 600.0, None);
        operator
    }

    /// Every product, edges and pinned rows included, equals the sum of the stored blocks times
    /// `x`, block by block.
    #[test]
    fn a_product_is_the_sum_of_its_blocks_times_x() {
        for (nx, ny) in [(9, 7), (16, 5), (8, 8), (3, 11)] {
            let operator = bent_operator(nx, ny);
            let n = nx * ny;
            let x = Field::from_arrays(std::array::from_fn(|a| {
                (0..n).map(|p| ((p * 7 + 3 * a) % 11) as f64 - 5.0).collect()
            }));
            let mut y = zero_field(n);
            operator.apply(&x, &mut y);
            for p in 0..n {
                let (i, j) = ((p % nx) as isize, (p / nx) as isize);
                let mut neighbours = vec![p];
                for &[di, dj] in operator.offsets() {
                    for (qi, qj) in [(i + di, j + dj), (i - di, j - dj)] {
                        if (0..nx as isize).contains(&qi) && (0..ny as isize).contains(&qj) {
                            neighbours.push(qj as usize * nx + qi as usize);
                        }
                    }
                }
                let mut expected = [0.0; 3];
                for q in neighbours {
                    let block = operator.block(p, q);
                    let xq = Vec3::new(x[0][q], x[1][q], x[2][q]);
                    for (e, v) in expected.iter_mut().zip(block.apply(xq).to_array()) {
                        *e += v;
                    }
                }
                for (axis, e) in expected.iter().enumerate() {
                    let got = y[axis][p];
                    assert!(
                        (got - e).abs() <= 1e-12 * e.abs().max(1e-3),
                        "{nx}×{ny}, particle {p}, axis {axis}: {got} against {e}"
                    );
                }
            }
        }
    }
}
