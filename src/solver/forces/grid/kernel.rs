//! The row kernel: one band's springs evaluated row by row, each row's force handed on as soon
//! as it is complete.
//!
//! Along a grid row the first ends of a family are consecutive particles and so are the second
//! ends, so a family's springs on one row are two contiguous runs of each axis of the state: no
//! index lists. A family's springs along a row are evaluated a vector block at a time
//! ([`spring_blocks`](crate::solver::forces::spring_blocks)) and each block's forces go straight
//! into the force accumulators of both ends' rows.
//!
//! Rows are visited in order. A spring of row `j` reaches rows `j` to `j + reach` only, so once
//! row `j`'s springs are done, row `j` has its whole force: it is handed on to a [`RowSink`] (the
//! forces array, or an integrator's update, which then needs no force array at all) and its
//! accumulator is reused by row `j + reach + 1`. Only `reach + 1` rows of forces are ever live,
//! and they stay in the first-level cache.

use super::bands::Band;
use super::layout::{Family, Layout};
use crate::solver::forces::spring_blocks::{self as blocks, LANES};
use crate::solver::math::real::Real;

/// What a band does with its rows' forces. Rows are numbered from the band's first.
pub(crate) trait RowSink<T> {
    /// Sets the force a row starts from, before any spring adds to it.
    fn start(&mut self, row: usize, force: [&mut [T]; 3]);
    /// Takes a row's force once every spring has added to it (and may overwrite it).
    fn finish(&mut self, row: usize, force: [&mut [T]; 3]);
}

impl<T: Real> Band<T> {
    /// Evaluates every spring that reaches the band's rows, row after row, handing each row's
    /// total force to `sink` as soon as it is complete.
    pub(crate) fn sweep(
        &mut self,
        layout: &Layout<T>,
        x: [&[T]; 3],
        v: [&[T]; 3],
        sink: &mut impl RowSink<T>,
    ) {
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

/// Evaluates the `len` springs of one family along a row, from particles `p..` to `q..`, and adds
/// their forces to the accumulators in `ring` from `a` (first ends) and subtracts them from `b`
/// (second ends).
///
/// The springs in whole vectors go through [`row_blocks`]. When both ends lie on the same row,
/// the second ends' accumulators overlap the first ends', so their forces wait in `staged` and a
/// second loop subtracts them (one loop updating both would not vectorise). The last, partial
/// vector is a block padded with springs of zero force: the accumulators have room past the row,
/// so no spring is left to a scalar remainder loop, one spring per instruction where a block
/// takes eight.
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
