//! One triangle: the nearest point on it to a point (and which feature that point is on), and
//! where a segment crosses it.

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

/// The part of a triangle its nearest point lies on. Edge `k` runs from corner `k` to corner
/// `(k + 1) % 3`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Feature {
    /// Inside the triangle.
    Face,
    /// On an edge, between its ends.
    Edge(u8),
    /// At a corner.
    Vertex(u8),
}

/// The point of triangle `[a, b, c]` nearest to `p`, and the feature it lies on (Ericson,
/// *Real-Time Collision Detection*, 5.1.5: the Voronoi regions of the corners, then the edges,
/// then the face). The triangle must have positive area; a denominator that rounds to zero
/// still gives a point on the triangle.
#[inline]
pub(crate) fn nearest_point<T: Real>([a, b, c]: [Vec3<T>; 3], p: Vec3<T>) -> (Vec3<T>, Feature) {
    let ratio = |num: T, den: T| if den > T::ZERO { num / den } else { T::ZERO };
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= T::ZERO && d2 <= T::ZERO {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= T::ZERO && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= T::ZERO && d1 >= T::ZERO && d3 <= T::ZERO {
        return (a + ab * ratio(d1, d1 - d3), Feature::Edge(0));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= T::ZERO && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= T::ZERO && d2 >= T::ZERO && d6 <= T::ZERO {
        return (a + ac * ratio(d2, d2 - d6), Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= T::ZERO && d4 - d3 >= T::ZERO && d5 - d6 >= T::ZERO {
        return (b + (c - b) * ratio(d4 - d3, (d4 - d3) + (d5 - d6)), Feature::Edge(1));
    }
    let sum = va + vb + vc;
    (a + ab * ratio(vb, sum) + ac * ratio(vc, sum), Feature::Face)
}

/// The largest amount by which a crossing may miss the triangle, in barycentric coordinates:
/// enough that a segment through a shared edge or corner meets at least one of the triangles
/// around it despite rounding.
const WATERTIGHT_SLACK: f64 = 1e-6;

/// Where the segment `start + s · d`, `s` in [0, 1], crosses the plane of triangle `[a, b, c]`
/// within the triangle (widened by [`WATERTIGHT_SLACK`]): the parameter `s`. A segment in the
/// triangle's plane does not cross it (Möller and Trumbore's test).
#[inline]
pub(crate) fn crossing<T: Real>([a, b, c]: [Vec3<T>; 3], start: Vec3<T>, d: Vec3<T>) -> Option<T> {
    let (e1, e2) = (b - a, c - a);
    let pvec = d.cross(e2);
    let det = e1.dot(pvec);
    if det == T::ZERO || !det.is_finite() {
        return None;
    }
    let inverse = T::ONE / det;
    let slack = T::from_f64(WATERTIGHT_SLACK);
    let tvec = start - a;
    let u = tvec.dot(pvec) * inverse;
    if !(u >= -slack && u <= T::ONE + slack) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let v = d.dot(qvec) * inverse;
    if !(v >= -slack && u + v <= T::ONE + slack) {
        return None;
    }
    let s = e2.dot(qvec) * inverse;
    (s >= T::ZERO && s <= T::ONE).then_some(s)
}

/// How far, relative to the size of the coordinates involved, a point's height over a
/// triangle's plane as [`TrianglePlanes::height`] computes it may be from the true height: far
/// more than the rounding of `f32`.
const HEIGHT_SLACK: f64 = 1e-5;

/// How far, relative to the size of the coordinates involved, a triangle's corners may be from
/// another's plane for the two to count as lying in one plane: a few roundings of `f32`, the
/// differences between the planes computed for triangles cut from one flat face.
const PLANE_SLACK: f64 = 1e-6;

/// A triangle's plane and the planes through its edges square to it, computed once, so that
/// most triangles are ruled out of a query, or answered, by a few dot products: a point's
/// height over the plane bounds its distance, and a point over the inside of every edge has its
/// nearest point straight below it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TrianglePlanes<T> {
    /// Unit normal, as the corners wind; zero for a triangle of no area.
    normal: Vec3<T>,
    offset: T,
    /// Unit vectors in the triangle's plane, square to each edge and pointing inwards.
    edge_normals: [Vec3<T>; 3],
    edge_offsets: [T; 3],
    /// How far a computed height may be off through the corners' coordinates; infinite for a
    /// triangle of no area, which every quick test leaves to the exact ones.
    slack: T,
}

impl<T: Real> TrianglePlanes<T> {
    pub fn new([a, b, c]: [Vec3<T>; 3]) -> Self {
        let cross = (b - a).cross(c - a);
        let area = cross.length();
        if !(area > T::ZERO && area.is_finite()) {
            return Self {
                normal: Vec3::ZERO,
                offset: T::ZERO,
                edge_normals: [Vec3::ZERO; 3],
                edge_offsets: [T::ZERO; 3],
                slack: T::from_f64(f64::INFINITY),
            };
        }
        let normal = cross * (T::ONE / area);
        let corners = [a, b, c];
        let edge_normals = [0, 1, 2].map(|k| {
            let edge = corners[(k + 1) % 3] - corners[k];
            normal.cross(edge) * (T::ONE / edge.length())
        });
        let size = corners.iter().map(|x| x.x.abs() + x.y.abs() + x.z.abs()).fold(T::ZERO, T::max);
        Self {
            normal,
            offset: normal.dot(a),
            edge_offsets: [0, 1, 2].map(|k| edge_normals[k].dot(corners[k])),
            edge_normals,
            slack: T::from_f64(HEIGHT_SLACK) * size,
        }
    }

    /// How far `p` is over the plane, on the side the normal points to (negative under it).
    #[inline(always)]
    fn height(&self, p: Vec3<T>) -> T {
        self.normal.dot(p) - self.offset
    }

    /// The unit normal (zero for a triangle of no area) and the offset: a point's height over the
    /// plane is `normal · p - offset`, as every test here computes it.
    #[inline(always)]
    pub fn plane(&self) -> (Vec3<T>, T) {
        (self.normal, self.offset)
    }

    /// How far `p` is inside every edge, less what rounding can take: a point nearer to `p` than
    /// this lies over the face, so that [`nearest`](Self::nearest) puts its nearest point straight
    /// below it. Negative when `p` is outside an edge or the triangle has no area.
    pub fn inner_margin(&self, p: Vec3<T>) -> T {
        let inside = self.inside_edges(p).into_iter().fold(T::from_f64(f64::INFINITY), T::min);
        inside - self.rounding(p)
    }

    /// How far `p` is inside each edge's line, measured in the plane (negative outside it).
    pub fn inside_edges(&self, p: Vec3<T>) -> [T; 3] {
        [0, 1, 2].map(|k| self.edge_normals[k].dot(p) - self.edge_offsets[k])
    }

    /// How far a distance computed from `p` by these planes may be off; infinite for a triangle
    /// of no area.
    pub fn rounding(&self, p: Vec3<T>) -> T {
        self.slack + T::from_f64(HEIGHT_SLACK) * (p.x.abs() + p.y.abs() + p.z.abs())
    }

    /// Whether the triangle `other` with corners `corners` lies in this triangle's plane, wound
    /// the same way: every corner within [`PLANE_SLACK`] of the plane (both having area). A point
    /// over `other` is then as far from it as from this plane, but for that slack.
    pub fn same_plane(&self, other: &Self, corners: [Vec3<T>; 3]) -> bool {
        let slack = self.slack.max(other.slack) * T::from_f64(PLANE_SLACK / HEIGHT_SLACK);
        slack.is_finite()
            && self.normal.dot(other.normal) > T::ZERO
            && corners.iter().all(|&corner| self.height(corner).abs() <= slack)
    }

    /// The foot of `p` on the plane, as [`nearest`](Self::nearest) gives it for a point over the
    /// face, with its squared distance, unless that is farther than `bound` (a squared distance).
    #[inline(always)]
    pub fn foot(&self, p: Vec3<T>, bound: T) -> Option<(Vec3<T>, T)> {
        let height = self.height(p);
        (height * height <= bound).then(|| (p - self.normal * height, height * height))
    }

    /// Whether the segment from `start` to `end` stays, with room to spare for rounding, on one
    /// side of the plane, so that it cannot cross the triangle.
    #[inline(always)]
    pub fn apart(&self, start: Vec3<T>, end: Vec3<T>) -> bool {
        let size = |x: Vec3<T>| x.x.abs() + x.y.abs() + x.z.abs();
        let slack = self.slack + T::from_f64(HEIGHT_SLACK) * size(start).max(size(end));
        let (from, to) = (self.height(start), self.height(end));
        (from > slack && to > slack) || (from < -slack && to < -slack)
    }

    /// The point of the triangle nearest to `p`, its feature and its squared distance, unless
    /// the triangle is farther than `bound` (a squared distance): [`nearest_point`] with the
    /// planes' shortcuts. A point over the inside of every edge is nearest to its foot on the
    /// plane; a point outside an edge by `e` at height `h` is at least `√(h² + e²)` away.
    #[inline(always)]
    pub fn nearest(&self, corners: [Vec3<T>; 3], p: Vec3<T>, bound: T) -> Option<(Vec3<T>, Feature, T)> {
        if self.slack.is_finite() {
            let height = self.height(p);
            let outside =
                (0..3).map(|k| self.edge_offsets[k] - self.edge_normals[k].dot(p)).fold(T::ZERO, T::max);
            if height * height + outside * outside > bound {
                return None;
            }
            if outside == T::ZERO {
                return Some((p - self.normal * height, Feature::Face, height * height));
            }
        }
        let (point, feature) = nearest_point(corners, p);
        Some((point, feature, (p - point).length_squared()))
    }
}
