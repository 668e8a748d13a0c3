//! The exact solve on a multigrid's coarsest level: a dense Cholesky factorisation in `f64` of a
//! small block system, with three unknowns per particle (`3 p + axis`).
//!
//! A coarsest level is a few dozen to a few hundred particles, where a dense factor costs less
//! than the smoothing sweeps it replaces and its solve is exact, which keeps the V-cycle a
//! fixed symmetric operator. A level that is not positive definite (rounding on a nearly
//! singular level in `f32`) cannot be factored; the solve then applies the 3×3 blocks its owner
//! gives instead (an inverse diagonal), which is still symmetric and positive.

/// A dense symmetric matrix, its Cholesky factor, and the right-hand side a solve works in.
#[derive(Debug)]
pub(crate) struct DenseCholesky {
    size: usize,
    /// Row-major; the lower triangle holds `L` after factoring, or the fallback's blocks.
    matrix: Vec<f64>,
    /// The right-hand side before a solve, the solution after.
    work: Vec<f64>,
    /// Whether the last factorisation succeeded.
    factored: bool,
}

impl DenseCholesky {
    /// Room for a system of `particles` particles.
    pub fn new(particles: usize) -> Self {
        let size = 3 * particles;
        Self { size, matrix: vec![0.0; size * size], work: vec![0.0; size], factored: false }
    }

    /// Sets the matrix to zero, to be filled by [`add`](Self::add).
    pub fn clear(&mut self) {
        self.matrix.fill(0.0);
    }

    /// Adds `value` at row `r`, column `c` (both `3 p + axis`).
    pub fn add(&mut self, r: usize, c: usize, value: f64) {
        self.matrix[r * self.size + c] += value;
    }

    /// Factors the matrix filled since [`clear`](Self::clear), whose upper triangle must mirror
    /// the lower one. When it is not positive definite, the solve multiplies each particle's
    /// three unknowns by `fallback(p)` instead.
    pub fn factor(&mut self, fallback: impl Fn(usize) -> [[f64; 3]; 3]) {
        let (size, m) = (self.size, &mut self.matrix);
        self.factored = true;
        for k in 0..size {
            let mut pivot = m[k * size + k];
            for j in 0..k {
                pivot -= m[k * size + j] * m[k * size + j];
            }
            if pivot <= 0.0 || !pivot.is_finite() {
                self.factored = false;
                break;
            }
            let pivot = pivot.sqrt();
            m[k * size + k] = pivot;
            for r in k + 1..size {
                let mut value = m[r * size + k];
                for j in 0..k {
                    value -= m[r * size + j] * m[k * size + j];
                }
                m[r * size + k] = value / pivot;
            }
        }
        if !self.factored {
            m.fill(0.0);
            for p in 0..size / 3 {
                for (a, row) in fallback(p).iter().enumerate() {
                    m[(3 * p + a) * size + 3 * p..][..3].copy_from_slice(row);
                }
            }
        }
    }

    /// The right-hand side of the next [`solve`](Self::solve), and its solution after it.
    pub fn work(&mut self) -> &mut [f64] {
        &mut self.work
    }

    /// Replaces the right-hand side in [`work`](Self::work) by the solution.
    pub fn solve(&mut self) {
        let (size, m, w) = (self.size, &self.matrix, &mut self.work);
        if self.factored {
            for r in 0..size {
                let mut value = w[r];
                for j in 0..r {
                    value -= m[r * size + j] * w[j];
                }
                w[r] = value / m[r * size + r];
            }
            for r in (0..size).rev() {
                let mut value = w[r];
                for j in r + 1..size {
                    value -= m[j * size + r] * w[j];
                }
                w[r] = value / m[r * size + r];
            }
        } else {
            for p in 0..size / 3 {
                let b = [w[3 * p], w[3 * p + 1], w[3 * p + 2]];
                for a in 0..3 {
                    let row = &m[(3 * p + a) * size + 3 * p..][..3];
                    w[3 * p + a] = row[0] * b[0] + row[1] * b[1] + row[2] * b[2];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive definite system of two particles, and its solution.
    fn system() -> (Vec<Vec<f64>>, Vec<f64>) {
        let a: Vec<Vec<f64>> = (0..6)
            .map(|r| (0..6).map(|c| if r == c { 4.0 + r as f64 } else { 1.0 / (1 + r + c) as f64 }).collect())
            .collect();
        let x = vec![1.0, -2.0, 0.5, 3.0, 0.25, -1.0];
        (a, x)
    }

    #[test]
    fn the_solve_inverts_a_positive_definite_matrix() {
        let (a, x) = system();
        let mut dense = DenseCholesky::new(2);
        dense.clear();
        for (r, row) in a.iter().enumerate() {
            for (c, &v) in row.iter().enumerate() {
                dense.add(r, c, v);
            }
        }
        dense.factor(|_| unreachable!("the matrix is positive definite"));
        for (r, row) in a.iter().enumerate() {
            dense.work()[r] = row.iter().zip(&x).map(|(a, x)| a * x).sum();
        }
        dense.solve();
        for (got, want) in dense.work().iter().zip(&x) {
            assert!((got - want).abs() < 1e-13, "{got} against {want}");
        }
    }

    #[test]
    fn an_indefinite_matrix_is_solved_by_its_fallback_blocks() {
        let mut dense = DenseCholesky::new(2);
        dense.clear();
        dense.add(0, 0, 1.0);
        dense.add(3, 3, -1.0);
        let block = |p: usize| [[2.0 + p as f64, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 4.0]];
        dense.factor(block);
        dense.work().copy_from_slice(&[1.0, 1.0, 1.0, 1.0, 0.0, -1.0]);
        dense.solve();
        assert_eq!(dense.work(), &[3.0, 4.0, 4.0, 3.0, 1.0, -4.0]);
    }
}
