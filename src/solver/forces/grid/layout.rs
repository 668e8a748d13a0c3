//! The shape of a cloth's springs: the stencil families a grid body's spring list is made of.
//!
//! A cloth's springs follow a fixed stencil, six families of the form `(i + ai, j + aj)` to
//! `(i + bi, j + bj)` with non-negative offsets, each with one rest length, stiffness and damping.
//! A spring list is only evaluated by stencil when it is exactly what the stencil generates, so
//! that the grid pass and the spring list describe the same springs.

use crate::solver::forces::spring_blocks::LANES;
use crate::solver::math::real::Real;
use crate::solver::model::{Spring, SpringGrid};

/// One spring family of a grid: its stencil offsets and its parameters.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Family<T> {
    /// `[ai, aj, bi, bj]`: the spring joins `(i + ai, j + aj)` to `(i + bi, j + bj)`.
    pub(super) offsets: [usize; 4],
    pub(super) rest_length: T,
    pub(super) stiffness: T,
    pub(super) damping: T,
}

/// The shape of a grid body's springs.
#[derive(Clone, Debug)]
pub(crate) struct Layout<T> {
    pub(crate) nx: usize,
    pub(super) ny: usize,
    pub(super) families: Vec<Family<T>>,
    /// The most rows a spring spans: row `j`'s springs reach rows `j..=j + reach`.
    pub(super) reach: usize,
}

impl<T> Layout<T> {
    /// The length of a row's force accumulator: a row, rounded up to whole vectors, with room for
    /// a family's column offset.
    pub(super) fn stride(&self) -> usize {
        self.nx.next_multiple_of(LANES) + LANES
    }
}

impl<T: Real> Layout<T> {
    /// The layout of `springs[grid.springs]`, if they are exactly the springs its stencil
    /// generates (in the builder's order) with one rest length, stiffness and damping per family
    /// in precision `T`; `None` otherwise, and the springs stay on the general path.
    pub(super) fn of(grid: &SpringGrid, springs: &[Spring<T>]) -> Option<Self> {
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
        Some(Layout { nx, ny, families, reach })
    }
}
