//! The drape coefficient of a drape tester's final state: `(S - A_d) / (A_s - A_d)`, with `S` the
//! area of the specimen's shadow (its projection along y onto the x-z plane, united with the
//! support disk), `A_d` the support disk's area and `A_s` the specimen's rest area (see
//! [`DrapeTester`]). 1 is a specimen that stays flat, 0 one that hangs straight down.
//!
//! The shadow is the union of the projected triangles, which folds make non-convex and
//! overlapping, so its area is measured by scanline rasterisation: rows of height `δ`, each row's
//! covered length along its centre line exact (the spans of the triangles and of the disk's
//! chord it crosses, sorted and merged), the area the sum of `δ` times each length. That is the
//! midpoint rule for `S = ∫ L(z) dz`, `L` the shadow's chord length, so its error is at most
//! `δ · TV(L)`: in each row `|∫ L - δ L(mid)| ≤ δ · (variation of L in the row)`. `L` changes
//! only as the outline moves along x, so `TV(L) ≤ P`, the outline's length. The outline lies on
//! the specimen's boundary edges, the edges where it folds over (whose two triangles lie on the
//! same side of the edge in projection) and the disk's circle, so `P` is at most the projected
//! length of those edges plus `2π r`, which the measurement sums first. `δ` is then chosen as
//! [`RASTER_ERROR_BOUND`] `· (A_s - A_d) / P`, which bounds the coefficient's error by
//! [`RASTER_ERROR_BOUND`] whatever the shape of the shadow. A flat 30 cm specimen on an 18 cm
//! disk has `P ≈ 1.5` m, so `δ ≈ 60 µm` and about 5000 rows.

use std::f64::consts::TAU;

use glam::DVec3;

use crate::scene::DrapeTester;

/// The most the rasterisation can move the coefficient: `δ` is chosen so that it cannot move it
/// further.
pub const RASTER_ERROR_BOUND: f64 = 0.002;
/// The most rows a specimen's triangles may cross in all, per triangle; a shadow whose outline
/// is so long that it would need more (a crumpled, not a draped, specimen) is not measured.
/// Together with [`MAX_ROWS`] it bounds the work of the measurement before it starts.
pub const MAX_ROW_CROSSINGS_PER_TRIANGLE: u64 = 4096;
/// The most rows a shadow is cut into.
pub const MAX_ROWS: u64 = 1 << 20;

/// A circle in the projection plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// Centre, `[x, z]`.
    pub center: [f64; 2],
    /// Radius.
    pub radius: f64,
}

/// The drape coefficient of the tester's specimen at `positions` (every particle's), whose
/// triangles are `triangles` (the model's); `None` when the shadow cannot be measured within the
/// bounds above or the specimen is no larger than the support.
pub fn drape_coefficient(tester: &DrapeTester, positions: &[DVec3], triangles: &[[u32; 3]]) -> Option<f64> {
    let annulus = tester.specimen_area - tester.support_area();
    if annulus <= 0.0 {
        return None;
    }
    let points: Vec<[f64; 2]> = positions.iter().map(|p| [p.x, p.z]).collect();
    let specimen = triangles.get(tester.triangles.clone())?;
    let support = Circle { center: tester.support_center, radius: tester.support_radius };
    let outline = outline_bound(&points, specimen) + TAU * support.radius;
    let row = RASTER_ERROR_BOUND * annulus / outline;
    let shadow = shadow_area(&points, specimen, Some(support), row)?;
    Some((shadow - tester.support_area()) / annulus)
}

/// An upper bound on the length of the outline of the union of `triangles` projected to
/// `points`: the total length of the edges that can lie on it, those on one triangle only and
/// those whose triangles are not on opposite sides of them (the outline of a union runs along
/// edges, and an edge with a triangle strictly on each side is inside it).
pub fn outline_bound(points: &[[f64; 2]], triangles: &[[u32; 3]]) -> f64 {
    // (first end, second end, side of the far vertex), ends in increasing order.
    let mut edges: Vec<(u32, u32, i8)> = Vec::with_capacity(3 * triangles.len());
    for &[a, b, c] in triangles {
        for (p, q, far) in [(a, b, c), (b, c, a), (c, a, b)] {
            let (p, q) = (p.min(q), p.max(q));
            let side = cross(points[p as usize], points[q as usize], points[far as usize]);
            edges.push((
                p,
                q,
                if side > 0.0 {
                    1
                } else if side < 0.0 {
                    -1
                } else {
                    0
                },
            ));
        }
    }
    edges.sort_unstable();
    edges
        .chunk_by(|x, y| (x.0, x.1) == (y.0, y.1))
        .filter(|group| !matches!(group, [(_, _, -1), (_, _, 1)]))
        .map(|group| {
            let ([pu, pv], [qu, qv]) = (points[group[0].0 as usize], points[group[0].1 as usize]);
            (qu - pu).hypot(qv - pv)
        })
        .sum()
}

/// `(q - p) × (r - p)`: positive when `r` is left of the line from `p` to `q`.
fn cross(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> f64 {
    (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
}

/// The area of the union of `triangles` (over `points`, `[x, z]`) and `disk`, by rows of height
/// `row` (see the module's note); `None` when that takes more than [`MAX_ROWS`] rows or more
/// than [`MAX_ROW_CROSSINGS_PER_TRIANGLE`] row crossings per triangle, or a point is not finite.
pub fn shadow_area(
    points: &[[f64; 2]],
    triangles: &[[u32; 3]],
    disk: Option<Circle>,
    row: f64,
) -> Option<f64> {
    let extent = |t: &[u32; 3]| {
        let v = t.map(|i| points[i as usize][1]);
        (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]))
    };
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for t in triangles {
        let (lo, hi) = extent(t);
        (low, high) = (low.min(lo), high.max(hi));
    }
    if let Some(d) = disk {
        (low, high) = (low.min(d.center[1] - d.radius), high.max(d.center[1] + d.radius));
    }
    if !(low.is_finite() && high.is_finite() && row.is_finite() && row > 0.0) {
        return (low > high && triangles.is_empty()).then_some(0.0);
    }
    let rows = ((high - low) / row).ceil();
    let crossings: f64 = triangles.iter().map(&extent).map(|(lo, hi)| (hi - lo) / row + 1.0).sum();
    let crossings_allowed = (triangles.len() as u64).saturating_mul(MAX_ROW_CROSSINGS_PER_TRIANGLE);
    if rows > MAX_ROWS as f64 || crossings > crossings_allowed.max(MAX_ROWS) as f64 {
        return None;
    }

    let mut order: Vec<usize> = (0..triangles.len()).collect();
    order.sort_by(|&a, &b| extent(&triangles[a]).0.total_cmp(&extent(&triangles[b]).0));
    let mut waiting = order.into_iter().peekable();
    let mut active: Vec<usize> = Vec::new();
    let mut spans: Vec<(f64, f64)> = Vec::new();
    let mut area = 0.0;
    for k in 0..rows as u64 {
        let v = low + (k as f64 + 0.5) * row;
        while let Some(&t) = waiting.peek() {
            if extent(&triangles[t]).0 > v {
                break;
            }
            active.push(t);
            waiting.next();
        }
        active.retain(|&t| extent(&triangles[t]).1 >= v);
        spans.clear();
        spans.extend(active.iter().filter_map(|&t| span(points, triangles[t], v)));
        if let Some(d) = disk {
            let dv = v - d.center[1];
            let half = d.radius * d.radius - dv * dv;
            if half > 0.0 {
                let half = half.sqrt();
                spans.push((d.center[0] - half, d.center[0] + half));
            }
        }
        area += row * covered_length(&mut spans);
    }
    Some(area)
}

/// Where the line `z = v` crosses triangle `t`: the span `(x_low, x_high)`, or `None`. An edge
/// counts as crossed when one end is at or below `v` and the other above, so a line through a
/// vertex is counted once.
fn span(points: &[[f64; 2]], t: [u32; 3], v: f64) -> Option<(f64, f64)> {
    let (mut low, mut high, mut crossed) = (f64::INFINITY, f64::NEG_INFINITY, 0);
    for (p, q) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
        let ([pu, pv], [qu, qv]) = (points[p as usize], points[q as usize]);
        if (pv <= v) != (qv <= v) {
            let u = pu + (v - pv) / (qv - pv) * (qu - pu);
            (low, high) = (low.min(u), high.max(u));
            crossed += 1;
        }
    }
    (crossed >= 2).then_some((low, high))
}

/// The length of the union of `spans` (sorted here).
fn covered_length(spans: &mut [(f64, f64)]) -> f64 {
    spans.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut total = 0.0;
    let mut current: Option<(f64, f64)> = None;
    for &(a, b) in spans.iter() {
        current = match current {
            Some((lo, hi)) if a <= hi => Some((lo, hi.max(b))),
            Some((lo, hi)) => {
                total += hi - lo;
                Some((a, b))
            }
            None => Some((a, b)),
        };
    }
    total + current.map_or(0.0, |(lo, hi)| hi - lo)
}

#[cfg(test)]
mod tests;
