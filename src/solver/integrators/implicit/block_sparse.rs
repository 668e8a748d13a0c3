//! Sparse matrices of general 3×3 blocks whose pattern is fixed when they are built: the levels
//! and transfers of the spring-list solver's algebraic multigrid ([`aggregation`](super::aggregation)).
//!
//! A matrix is stored by rows (block compressed sparse rows, columns sorted within a row). Only
//! its values change after it is built, so every product of the hierarchy is planned once as a
//! list of destination slots and refilled each step by walking its operands in the same order.

use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;

/// A general 3×3 matrix, by rows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Block<T>(pub [[T; 3]; 3]);

impl<T: Real> Block<T> {
    pub const ZERO: Self = Self([[T::ZERO; 3]; 3]);

    pub fn identity() -> Self {
        Self::diagonal(T::ONE)
    }

    /// `s I`.
    pub fn diagonal(s: T) -> Self {
        let mut m = Self::ZERO;
        for a in 0..3 {
            m.0[a][a] = s;
        }
        m
    }

    pub fn from_sym(s: &Sym3<T>) -> Self {
        let [xx, yy, zz, xy, xz, yz] = s.entries();
        Self([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    }

    /// The symmetric part `(B + Bᵀ) / 2`.
    pub fn symmetric_part(&self) -> Sym3<T> {
        let m = &self.0;
        let half = T::from_f64(0.5);
        Sym3::from_entries([
            m[0][0],
            m[1][1],
            m[2][2],
            (m[0][1] + m[1][0]) * half,
            (m[0][2] + m[2][0]) * half,
            (m[1][2] + m[2][1]) * half,
        ])
    }

    pub fn transpose(&self) -> Self {
        Self(std::array::from_fn(|a| std::array::from_fn(|b| self.0[b][a])))
    }

    pub fn scaled(&self, s: T) -> Self {
        Self(self.0.map(|row| row.map(|e| e * s)))
    }

    /// `B v`.
    #[inline(always)]
    pub fn apply(&self, v: Vec3<T>) -> Vec3<T> {
        let m = &self.0;
        Vec3::new(
            m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
        )
    }

    /// `Bᵀ v`.
    #[inline(always)]
    pub fn apply_transpose(&self, v: Vec3<T>) -> Vec3<T> {
        let m = &self.0;
        Vec3::new(
            m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z,
            m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
            m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z,
        )
    }

    /// `B C`.
    #[inline(always)]
    pub fn times(&self, c: &Self) -> Self {
        let (b, c) = (&self.0, &c.0);
        Self(std::array::from_fn(|r| {
            std::array::from_fn(|k| b[r][0] * c[0][k] + b[r][1] * c[1][k] + b[r][2] * c[2][k])
        }))
    }

    /// `self += Bᵀ C`.
    #[inline(always)]
    pub fn add_transpose_mul(&mut self, b: &Self, c: &Self) {
        let (b, c) = (&b.0, &c.0);
        for (r, row) in self.0.iter_mut().enumerate() {
            for (k, e) in row.iter_mut().enumerate() {
                *e += b[0][r] * c[0][k] + b[1][r] * c[1][k] + b[2][r] * c[2][k];
            }
        }
    }

    /// `self += B C`.
    #[inline(always)]
    pub fn add_mul(&mut self, b: &Self, c: &Self) {
        let (b, c) = (&b.0, &c.0);
        for (row, b) in self.0.iter_mut().zip(b) {
            for (k, e) in row.iter_mut().enumerate() {
                *e += b[0] * c[0][k] + b[1] * c[1][k] + b[2] * c[2][k];
            }
        }
    }

    /// `self += s C`.
    #[inline(always)]
    pub fn add_scaled(&mut self, s: T, c: &Self) {
        for (row, c_row) in self.0.iter_mut().zip(&c.0) {
            for (e, &c) in row.iter_mut().zip(c_row) {
                *e += s * c;
            }
        }
    }
}

/// A sparse matrix of 3×3 blocks with a fixed pattern.
#[derive(Clone, Debug)]
pub(crate) struct BlockCsr<T> {
    columns: usize,
    /// Row `r`'s entries are `starts[r]..starts[r + 1]`.
    starts: Vec<usize>,
    /// Each entry's column, sorted within a row.
    column_of: Vec<u32>,
    pub blocks: Vec<Block<T>>,
}

impl<T: Real> BlockCsr<T> {
    /// A zero matrix with `columns` columns and, for each row, the given columns (sorted and
    /// deduplicated here).
    pub fn from_rows(columns: usize, rows: Vec<Vec<u32>>) -> Self {
        let mut starts = Vec::with_capacity(rows.len() + 1);
        let mut column_of = Vec::new();
        starts.push(0);
        for mut row in rows {
            row.sort_unstable();
            row.dedup();
            column_of.extend_from_slice(&row);
            starts.push(column_of.len());
        }
        let blocks = vec![Block::ZERO; column_of.len()];
        Self { columns, starts, column_of, blocks }
    }

    pub fn rows(&self) -> usize {
        self.starts.len() - 1
    }

    #[cfg(test)]
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// The entries of row `r`.
    #[inline(always)]
    pub fn row(&self, r: usize) -> std::ops::Range<usize> {
        self.starts[r]..self.starts[r + 1]
    }

    /// The column of entry `e`.
    #[inline(always)]
    pub fn column(&self, e: usize) -> usize {
        self.column_of[e] as usize
    }

    /// The columns of row `r`.
    pub fn row_columns(&self, r: usize) -> &[u32] {
        &self.column_of[self.row(r)]
    }

    /// The entry at `(r, c)`, if the pattern has it.
    pub fn slot(&self, r: usize, c: usize) -> Option<usize> {
        let row = self.row(r);
        self.column_of[row.clone()].binary_search(&(c as u32)).ok().map(|k| row.start + k)
    }

    pub fn clear(&mut self) {
        self.blocks.fill(Block::ZERO);
    }

    /// `y = B x`.
    pub fn apply(&self, x: &[Vec3<T>], y: &mut [Vec3<T>]) {
        for (r, y) in y.iter_mut().enumerate() {
            let mut sum = Vec3::ZERO;
            for e in self.row(r) {
                sum += self.blocks[e].apply(x[self.column(e)]);
            }
            *y = sum;
        }
    }

    /// `y = Bᵀ x`.
    pub fn apply_transpose(&self, x: &[Vec3<T>], y: &mut [Vec3<T>]) {
        debug_assert_eq!(y.len(), self.columns);
        y.fill(Vec3::ZERO);
        for (r, &x) in x.iter().enumerate() {
            for e in self.row(r) {
                y[self.column(e)] += self.blocks[e].apply_transpose(x);
            }
        }
    }

    /// `y += B x`.
    pub fn apply_add(&self, x: &[Vec3<T>], y: &mut [Vec3<T>]) {
        for (r, y) in y.iter_mut().enumerate() {
            for e in self.row(r) {
                *y += self.blocks[e].apply(x[self.column(e)]);
            }
        }
    }

    /// For each entry, the entry holding its transpose's place `(c, r)`, for a square matrix
    /// whose pattern is symmetric.
    pub fn transpose_slots(&self) -> Vec<u32> {
        (0..self.rows())
            .flat_map(|r| self.row(r).map(move |e| (r, e)))
            .map(|(r, e)| self.slot(self.column(e), r).expect("a symmetric pattern") as u32)
            .collect()
    }

    /// Makes a square matrix exactly symmetric, `B ← (B + Bᵀ) / 2`, given its
    /// [`transpose_slots`](Self::transpose_slots).
    pub fn symmetrise(&mut self, transpose_slots: &[u32]) {
        let half = T::from_f64(0.5);
        for (e, &t) in transpose_slots.iter().enumerate() {
            let t = t as usize;
            if t < e {
                continue;
            }
            let mean = |a: &Block<T>, b: &Block<T>| {
                let mut m = *a;
                m.add_scaled(T::ONE, &b.transpose());
                m.scaled(half)
            };
            let upper = mean(&self.blocks[e], &self.blocks[t]);
            self.blocks[t] = upper.transpose();
            self.blocks[e] = upper;
        }
    }

    /// The dense matrix, by rows of scalars.
    #[cfg(test)]
    pub fn to_dense(&self) -> Vec<Vec<f64>> {
        let mut dense = vec![vec![0.0; 3 * self.columns]; 3 * self.rows()];
        for r in 0..self.rows() {
            for e in self.row(r) {
                let c = self.column(e);
                for a in 0..3 {
                    for b in 0..3 {
                        dense[3 * r + a][3 * c + b] = self.blocks[e].0[a][b].to_f64();
                    }
                }
            }
        }
        dense
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(seed: f64) -> Block<f64> {
        Block(std::array::from_fn(|a| std::array::from_fn(|b| (seed + 3.0 * a as f64 + b as f64).sin())))
    }

    #[test]
    fn block_products_match_their_definitions() {
        let (b, c) = (block(0.3), block(1.7));
        let v = Vec3::new(0.2, -1.1, 0.7);
        let bc = b.times(&c);
        let direct = b.apply(c.apply(v));
        assert!((bc.apply(v) - direct).length() < 1e-14);
        assert!((b.apply_transpose(v) - b.transpose().apply(v)).length() < 1e-14);
        let mut sum = Block::ZERO;
        sum.add_transpose_mul(&b, &c);
        assert!((sum.apply(v) - b.transpose().times(&c).apply(v)).length() < 1e-14);
    }

    #[test]
    fn a_product_and_its_transpose_are_adjoint() {
        let pattern = vec![vec![0, 2], vec![1, 2], vec![0, 1, 2]];
        let mut m = BlockCsr::<f64>::from_rows(3, pattern);
        for (e, b) in m.blocks.iter_mut().enumerate() {
            *b = block(e as f64);
        }
        let x: Vec<_> = (0..3).map(|p| Vec3::new(p as f64, 1.0, -0.5 * p as f64)).collect();
        let y: Vec<_> = (0..3).map(|p| Vec3::new(0.3, -(p as f64), 2.0)).collect();
        let (mut mx, mut mty) = (vec![Vec3::ZERO; 3], vec![Vec3::ZERO; 3]);
        m.apply(&x, &mut mx);
        m.apply_transpose(&y, &mut mty);
        let left: f64 = mx.iter().zip(&y).map(|(a, b)| a.dot(*b)).sum();
        let right: f64 = x.iter().zip(&mty).map(|(a, b)| a.dot(*b)).sum();
        assert!((left - right).abs() < 1e-12, "{left} against {right}");
        let transposes = m.transpose_slots();
        m.symmetrise(&transposes);
        let dense = m.to_dense();
        for (a, row) in dense.iter().enumerate() {
            for (b, &value) in row.iter().enumerate() {
                assert_eq!(value, dense[b][a]);
            }
        }
    }
}
