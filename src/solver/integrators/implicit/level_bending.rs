//! The bending elements' part of level 0 of the multigrid preconditioner.
//!
//! The elements' Jacobian is constant and acts on each axis alike (`C = Σ c K Kᵀ`, and `D` of
//! the damping constants), so level 0's part of the system `h D + h² C` is a scalar stencil on
//! the grid, built once when the solver is made from the elements, with the rows and columns of
//! pinned particles left out as the solve filters them. A grid's elements reach two particles
//! along a row or column and one across a cell, so the stencil has 13 points. The coarse levels
//! are Galerkin products of level 0 with its bending ([`galerkin`](super::galerkin)): a coarse
//! correction minimises the fine energy of its interpolant, and bilinear interpolation bends
//! along the coarse rows and columns, so the interpolant of a coarse bend has twice the row and
//! column energy of the same bend discretised on the coarse grid; a rediscretised level would be
//! half as stiff as the correction it stands for.
//!
//! Damped block Jacobi needs `A ≤ 2 D̃` of the diagonal `D̃` it inverts. The springs meet it with
//! their own diagonal blocks, but bending elements do not (a checkerboard bend has four times
//! the diagonal's energy on a grid), so the smoother adds half of each row's absolute sum
//! `½ Σ_q |G_pq|` instead of the diagonal `G_pp`: by Gershgorin `G` is below the absolute sums,
//! so the whole level stays below twice the smoother's diagonal, the V-cycle stays symmetric
//! positive definite, and the smoother keeps its damping.

use super::grid_operator::Field;
use crate::solver::forces::bending::BendingElements;
use crate::solver::math::real::Real;
use crate::solver::parallel::in_bands;

/// How far (in particles along each axis) an entry of a stencil may reach.
const REACH: isize = 2;

/// The forward offsets within [`REACH`] (`dj > 0`, or `dj == 0` and `di > 0`), in the order of
/// [`slot`].
fn forward_offsets() -> Vec<[isize; 2]> {
    (0..=REACH)
        .flat_map(|dj| (-REACH..=REACH).map(move |di| [di, dj]))
        .filter(|&[di, dj]| dj > 0 || di > 0)
        .collect()
}

/// The index of a forward offset in [`forward_offsets`].
fn slot([di, dj]: [isize; 2]) -> usize {
    if dj == 0 { (di - 1) as usize } else { (REACH + (dj - 1) * (2 * REACH + 1) + di + REACH) as usize }
}

/// A symmetric operator on an `nx × ny` grid that acts on each axis alike: a diagonal and, per
/// forward offset, the entry `G[p, p + off]` at each lower particle `p` (zero where `p + off`
/// is off the grid).
#[derive(Clone, Debug)]
struct Stencil<T> {
    nx: usize,
    ny: usize,
    offsets: Vec<[isize; 2]>,
    diagonal: Vec<T>,
    couplings: Vec<Vec<T>>,
}

impl<T: Real> Stencil<T> {
    /// Calls `entry(p, q, G[p, q])` for every non-zero entry, both orders of each coupling.
    fn for_each_entry(&self, mut entry: impl FnMut(usize, usize, T)) {
        for (p, &d) in self.diagonal.iter().enumerate().filter(|&(_, &d)| d != T::ZERO) {
            entry(p, p, d);
        }
        for (&[di, dj], coupling) in self.offsets.iter().zip(&self.couplings) {
            let shift = dj * self.nx as isize + di;
            for (p, &g) in coupling.iter().enumerate().filter(|&(_, &g)| g != T::ZERO) {
                let q = (p as isize + shift) as usize;
                entry(p, q, g);
                entry(q, p, g);
            }
        }
    }
}

impl Stencil<f64> {
    /// A stencil of zeros with every offset within [`REACH`].
    fn empty(nx: usize, ny: usize) -> Self {
        let offsets = forward_offsets();
        let n = nx * ny;
        Self {
            nx,
            ny,
            couplings: offsets.iter().map(|_| vec![0.0; n]).collect(),
            offsets,
            diagonal: vec![0.0; n],
        }
    }

    /// Adds `value` to `G[p, q]` when `q` is `p` or forward of it, and does nothing when `q` is
    /// behind `p`: the callers add every entry in both orders, and the entry behind is the
    /// transpose of one ahead. `None` when `q` is out of [`REACH`] of `p`.
    fn add(&mut self, p: usize, q: usize, value: f64) -> Option<()> {
        if p == q {
            self.diagonal[p] += value;
            return Some(());
        }
        let nx = self.nx as isize;
        let (p, q) = (p as isize, q as isize);
        let (di, dj) = (q % nx - p % nx, q / nx - p / nx);
        if di.abs() > REACH || dj.abs() > REACH {
            return None;
        }
        if dj > 0 || (dj == 0 && di > 0) {
            self.couplings[slot([di, dj])][p as usize] += value;
        }
        Some(())
    }

    /// Zeroes the rows and columns of `pinned`.
    fn decouple(&mut self, pinned: &[usize]) {
        let (nx, ny) = (self.nx as isize, self.ny as isize);
        for &p in pinned {
            self.diagonal[p] = 0.0;
            let (i, j) = ((p % self.nx) as isize, (p / self.nx) as isize);
            for (&[di, dj], coupling) in self.offsets.iter().zip(&mut self.couplings) {
                coupling[p] = 0.0;
                let (li, lj) = (i - di, j - dj);
                if (0..nx).contains(&li) && (0..ny).contains(&lj) {
                    coupling[(lj * nx + li) as usize] = 0.0;
                }
            }
        }
    }
}

/// The stiffness and damping stencils of one level, keeping only the offsets where either has a
/// non-zero entry.
#[derive(Clone, Debug)]
pub(crate) struct BendingMatrices {
    stiffness: Stencil<f64>,
    damping: Stencil<f64>,
}

impl BendingMatrices {
    /// Level 0's matrices from `hinges` on an `nx × ny` grid with the rows and columns of `pinned`
    /// left out, or `None` if an element joins particles more than two apart along an axis.
    pub fn of_hinges<T: Real>(
        hinges: &BendingElements<T>,
        nx: usize,
        ny: usize,
        pinned: &[usize],
    ) -> Option<Self> {
        let (mut stiffness, mut damping) = (Stencil::empty(nx, ny), Stencil::empty(nx, ny));
        let mut reached = true;
        hinges.for_each_entry(|p, q, c, d| {
            reached &= stiffness.add(p, q, c).is_some() && damping.add(p, q, d).is_some();
        });
        stiffness.decouple(pinned);
        damping.decouple(pinned);
        reached.then(|| Self::pruned(stiffness, damping))
    }

    /// Both stencils without the offsets at which both are zero everywhere.
    fn pruned(mut stiffness: Stencil<f64>, mut damping: Stencil<f64>) -> Self {
        let keep: Vec<bool> = (0..stiffness.offsets.len())
            .map(|s| stiffness.couplings[s].iter().chain(&damping.couplings[s]).any(|&g| g != 0.0))
            .collect();
        for stencil in [&mut stiffness, &mut damping] {
            let mut kept = keep.iter();
            stencil.offsets.retain(|_| *kept.next().expect("a flag per offset"));
            let mut kept = keep.iter();
            stencil.couplings.retain(|_| *kept.next().expect("a flag per offset"));
        }
        Self { stiffness, damping }
    }
}

/// A level's bending: its matrices, and `a C + b D` of the current step in the level's
/// precision with the smoother's share of it.
#[derive(Debug)]
pub(crate) struct LevelBending<T> {
    matrices: BendingMatrices,
    /// `a C + b D` for `coefficients`.
    step: Stencil<T>,
    /// `(a, b)` of `step`, once set.
    coefficients: Option<(f64, f64)>,
    /// Per particle: what the smoother adds to the diagonal block's `xx`, `yy` and `zz`.
    smoother_shift: Vec<T>,
}

impl<T: Real> LevelBending<T> {
    pub fn new(matrices: BendingMatrices) -> Self {
        let stiffness = &matrices.stiffness;
        let n = stiffness.diagonal.len();
        let step = Stencil {
            nx: stiffness.nx,
            ny: stiffness.ny,
            offsets: stiffness.offsets.clone(),
            diagonal: vec![T::ZERO; n],
            couplings: stiffness.offsets.iter().map(|_| vec![T::ZERO; n]).collect(),
        };
        Self { matrices, step, coefficients: None, smoother_shift: vec![T::ZERO; n] }
    }

    /// Makes the level's operator `a C + b D` (implicit Euler's `a = h²`, `b = h`) and its
    /// smoother shift; returns whether they changed.
    pub fn set_step(&mut self, a: f64, b: f64) -> bool {
        if self.coefficients == Some((a, b)) {
            return false;
        }
        self.coefficients = Some((a, b));
        let (c, d) = (&self.matrices.stiffness, &self.matrices.damping);
        let pairs = std::iter::once((&mut self.step.diagonal, (&c.diagonal, &d.diagonal)))
            .chain(self.step.couplings.iter_mut().zip(c.couplings.iter().zip(&d.couplings)));
        for (to, (c, d)) in pairs {
            for ((t, &c), &d) in to.iter_mut().zip(c).zip(d) {
                *t = T::from_f64(a * c + b * d);
            }
        }
        self.smoother_shift.fill(T::ZERO);
        let shift = &mut self.smoother_shift;
        let half = T::from_f64(0.5);
        self.step.for_each_entry(|p, _, g| shift[p] += half * g.abs());
        true
    }

    /// Per particle: half the absolute sum of the level operator's row, which the smoother adds
    /// to its diagonal block's `xx`, `yy` and `zz` (see the module's documentation).
    pub fn smoother_shift(&self) -> &[T] {
        &self.smoother_shift
    }

    /// `r -= G x` for the level's operator `G` on each axis, by bands of rows on the pool's
    /// threads when `parallel`; every entry is summed in one fixed order (the diagonal, then
    /// each offset ahead and behind), whatever the bands.
    ///
    /// A band is one stretch of the arrays per offset and direction: a coupling is zero wherever
    /// its partner is off the grid, so running on past a row's end into the next adds exact
    /// zeros, and the loops have no remainder per row.
    pub fn subtract_product(&self, x: &Field<T>, r: &mut Field<T>, parallel: bool) {
        let (nx, ny, step) = (self.step.nx, self.step.ny, &self.step);
        let n = nx * ny;
        let band = if parallel { ny.div_ceil(4 * rayon::current_num_threads()).max(1) } else { ny };
        let x = x.arrays();
        in_bands(r.arrays_mut(), ny, nx, band, &|first, count, mut r| {
            let rows = first * nx..(first + count) * nx;
            subtract_products(
                r.each_mut().map(|r| &mut r[..]),
                &step.diagonal[rows.clone()],
                x.map(|x| &x[rows.clone()]),
            );
            for (&[di, dj], coupling) in step.offsets.iter().zip(&step.couplings) {
                let shift = (dj * nx as isize + di) as usize;
                // G[p, p + off] x[p + off] for the p whose p + off is in the arrays.
                let ahead = rows.start..rows.end.min(n - shift);
                if !ahead.is_empty() {
                    let (y, q) = (ahead.start - rows.start..ahead.end - rows.start, ahead.start + shift);
                    let x = x.map(|x| &x[q..q + ahead.len()]);
                    subtract_products(r.each_mut().map(|r| &mut r[y.clone()]), &coupling[ahead], x);
                }
                // G[p, p - off] x[p - off] = G[p - off, p] x[p - off].
                let behind = rows.start.max(shift)..rows.end;
                if !behind.is_empty() {
                    let y = behind.start - rows.start..behind.end - rows.start;
                    let q = behind.start - shift..behind.end - shift;
                    let x = x.map(|x| &x[q.clone()]);
                    subtract_products(r.each_mut().map(|r| &mut r[y.clone()]), &coupling[q], x);
                }
            }
        });
    }

    /// The level operator's diagonal, per particle.
    pub fn diagonal(&self) -> &[T] {
        &self.step.diagonal
    }

    /// Per offset ahead, the level operator's entry `G[p, p + off]` at each lower particle `p`.
    pub fn couplings(&self) -> impl Iterator<Item = ([isize; 2], &[T])> {
        self.step.offsets.iter().copied().zip(self.step.couplings.iter().map(Vec::as_slice))
    }
}

/// `y -= g x` on each axis, entry by entry.
#[inline(always)]
fn subtract_products<T: Real>(y: [&mut [T]; 3], g: &[T], x: [&[T]; 3]) {
    let len = g.len();
    let [y0, y1, y2] = y.map(|y| &mut y[..len]);
    let [x0, x1, x2] = x.map(|x| &x[..len]);
    for k in 0..len {
        y0[k] -= g[k] * x0[k];
        y1[k] -= g[k] * x1[k];
        y2[k] -= g[k] * x2[k];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::forces::bending::grid_bending;
    use crate::solver::integrators::implicit::grid_operator::zero_field;

    /// A fabric's elements on an `nx × ny` grid of spacings 0.1 and 0.12 m, with
    /// `B = 2e-3 N·m` and a damping time of 1e-2 s.
    fn hinges(nx: usize, ny: usize) -> BendingElements<f64> {
        BendingElements::new(&grid_bending(0, [nx, ny], [0.1, 0.12], 2e-3, 1e-2)).unwrap()
    }

    /// A deterministic field of values in [-1, 1], zero on `pinned`.
    fn wiggle(n: usize, seed: f64, pinned: &[usize]) -> Field<f64> {
        let mut field = Field::from_arrays(std::array::from_fn(|a| {
            (0..n).map(|p| (p as f64 * 0.7315 + seed + 1.9 * a as f64).sin()).collect()
        }));
        for axis in &mut field {
            for &p in pinned {
                axis[p] = 0.0;
            }
        }
        field
    }

    /// `G x` of a level.
    fn product(level: &LevelBending<f64>, x: &Field<f64>) -> Field<f64> {
        let mut minus = zero_field(x[0].len());
        level.subtract_product(x, &mut minus, false);
        Field::from_arrays(std::array::from_fn(|a| minus[a].iter().map(|v| -v).collect()))
    }

    fn dot(a: &Field<f64>, b: &Field<f64>) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>()).sum()
    }

    const A: f64 = 1.0 / 360_000.0;
    const B: f64 = 1.0 / 600.0;

    /// Level 0 applies `a C + b D` of the elements exactly, filtered by the pins: the product of
    /// the elements themselves on the free particles, zero on the pinned ones.
    #[test]
    fn level_zero_is_the_elements_product_on_the_free_particles() {
        let (nx, ny) = (13, 11);
        let (hinges, pinned) = (hinges(nx, ny), [0, nx - 1]);
        let mut level = LevelBending::new(BendingMatrices::of_hinges(&hinges, nx, ny, &pinned).unwrap());
        assert!(level.set_step(A, B));
        assert!(!level.set_step(A, B), "the same step changes nothing");
        // Rows and columns reach two particles, cells one across: 6 offsets ahead.
        assert_eq!(level.step.offsets, [[1, 0], [2, 0], [-1, 1], [0, 1], [1, 1], [0, 2]]);
        let x = wiggle(nx * ny, 0.4, &pinned);
        let got = product(&level, &x);
        let mut expected = zero_field(nx * ny);
        hinges.add_product(A, B, x.arrays(), expected.arrays_mut());
        let scale = expected.iter().flat_map(|a| a.iter()).fold(0.0f64, |m, v| m.max(v.abs()));
        for axis in 0..3 {
            for p in 0..nx * ny {
                let want = if pinned.contains(&p) { 0.0 } else { expected[axis][p] };
                assert!(
                    (got[axis][p] - want).abs() <= 1e-12 * scale,
                    "{p}, axis {axis}: {} against {want}",
                    got[axis][p]
                );
            }
        }
    }

    /// A checkerboard bend has 64/20 = 3.2 times the energy of the diagonal on a square grid's
    /// interior (each element family's symbol `c (s_i + s_j)²` peaks at 64 c, the diagonal is
    /// 20 c), so block Jacobi on the diagonal would amplify it; the smoother's shift, half the
    /// rows' absolute sums, keeps `G ≤ 2 shift` with the checkerboard at the bound.
    #[test]
    fn the_smoother_shift_bounds_the_checkerboard_which_the_diagonal_does_not() {
        let n = 64;
        let elements =
            BendingElements::<f64>::new(&grid_bending(0, [n, n], [0.01, 0.01], 1e-3, 0.0)).unwrap();
        let mut level = LevelBending::new(BendingMatrices::of_hinges(&elements, n, n, &[]).unwrap());
        level.set_step(1.0, 0.0);
        let checkerboard: Vec<f64> =
            (0..n * n).map(|p| if (p % n + p / n) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let x = Field::from_arrays([checkerboard.clone(), vec![0.0; n * n], vec![0.0; n * n]]);
        let energy = dot(&x, &product(&level, &x));
        let on_diagonal: f64 = level.step.diagonal.iter().sum();
        let on_shift: f64 = level.smoother_shift().iter().sum();
        let ratio = energy / on_diagonal;
        assert!((ratio - 3.2).abs() < 0.1, "checkerboard over diagonal: {ratio}");
        assert!(energy <= 2.0 * on_shift && energy >= 1.9 * on_shift, "{energy} against 2 × {on_shift}");
    }
}
