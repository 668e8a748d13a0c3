//! A bounding-volume hierarchy over a fixed set of triangles: the nearest triangle to a point
//! within a radius, and the first triangle a segment crosses.
//!
//! Built once, top down: a node's triangles are split at the median of their centroids along
//! the longest axis of the centroids' bounds, down to leaves of at most [`LEAF_SIZE`]. The tree
//! is flat: one array of nodes (the two children of a node are neighbours, so a node holds one
//! index) and the triangles' corners in leaf order, so that a leaf's triangles are read from
//! consecutive memory. A median split keeps the depth at `⌈log₂(n / LEAF_SIZE)⌉ + 1`, so a
//! query walks it with a fixed stack and allocates nothing. Boxes are computed from the corners
//! in the simulation's precision, so they bound the triangles exactly as the tests see them.

use crate::solver::constraints::contacts::triangle::{self, Feature, TrianglePlanes};
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

/// The most triangles a leaf holds.
pub const LEAF_SIZE: usize = 4;
/// The deepest a walk can go: far beyond the depth of a median split of any array.
const STACK: usize = 64;

#[derive(Clone, Copy, Debug)]
struct Node<T> {
    lower: Vec3<T>,
    upper: Vec3<T>,
    /// A leaf's first triangle, or an inner node's first child (the second follows it).
    first: u32,
    /// A leaf's triangle count; 0 for an inner node.
    count: u32,
}

/// The nearest point of the triangles to a query point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Nearest<T> {
    /// The triangle, as its index in the order given to [`TriangleBvh::new`].
    pub triangle: usize,
    /// The nearest point.
    pub point: Vec3<T>,
    /// The feature of the triangle it lies on.
    pub feature: Feature,
    /// Its squared distance to the query point.
    pub distance_squared: T,
}

/// A hierarchy of triangles in precision `T`.
#[derive(Clone, Debug)]
pub struct TriangleBvh<T> {
    nodes: Vec<Node<T>>,
    /// Corners, in leaf order.
    corners: Vec<[Vec3<T>; 3]>,
    /// The planes of each triangle, in leaf order.
    planes: Vec<TrianglePlanes<T>>,
    /// For each triangle in leaf order, its index in the order given.
    order: Vec<u32>,
}

impl<T: Real> TriangleBvh<T> {
    /// The hierarchy of these triangles (any number, each given by its corners).
    pub fn new(corners: &[[Vec3<T>; 3]]) -> Self {
        let count = corners.len();
        let mut order: Vec<u32> = (0..count as u32).collect();
        let centroids: Vec<Vec3<T>> =
            corners.iter().map(|&[a, b, c]| (a + b + c) * T::from_f64(1.0 / 3.0)).collect();
        let mut nodes = Vec::with_capacity((2 * count.div_ceil(LEAF_SIZE)).max(1));
        nodes.push(Node { lower: Vec3::ZERO, upper: Vec3::ZERO, first: 0, count: 0 });
        let mut builder = Builder { corners, centroids: &centroids, order: &mut order, nodes: &mut nodes };
        builder.split(0, 0, count);
        let corners: Vec<_> = order.iter().map(|&t| corners[t as usize]).collect();
        let planes = corners.iter().map(|&c| TrianglePlanes::new(c)).collect();
        Self { nodes, corners, planes, order }
    }

    /// How many triangles it holds.
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// Whether it holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }

    /// The box around every triangle, as its lower and upper corners.
    pub(crate) fn bounds(&self) -> (Vec3<T>, Vec3<T>) {
        (self.nodes[0].lower, self.nodes[0].upper)
    }

    /// Bytes it holds.
    pub fn memory(&self) -> usize {
        self.nodes.len() * size_of::<Node<T>>()
            + self.corners.len() * (size_of::<[Vec3<T>; 3]>() + size_of::<TrianglePlanes<T>>() + 4)
    }

    /// The point of the triangles nearest to `p` no farther than `radius` (infinite: any
    /// distance), if any. Of equally near points, the first met in the tree's fixed order.
    pub(crate) fn nearest(&self, p: Vec3<T>, radius: T) -> Option<Nearest<T>> {
        if self.corners.is_empty() {
            return None;
        }
        let mut best_squared = radius * radius;
        let mut best: Option<Nearest<T>> = None;
        let mut stack = [0u32; STACK];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let node = self.nodes[stack[depth] as usize];
            if box_distance_squared(node.lower, node.upper, p) > best_squared {
                continue;
            }
            if node.count == 0 {
                // The nearer child is walked first, so that the bound tightens sooner.
                let (left, right) = (node.first, node.first + 1);
                let near_left =
                    box_distance_squared(self.nodes[left as usize].lower, self.nodes[left as usize].upper, p)
                        <= box_distance_squared(
                            self.nodes[right as usize].lower,
                            self.nodes[right as usize].upper,
                            p,
                        );
                let (near, far) = if near_left { (left, right) } else { (right, left) };
                stack[depth] = far;
                stack[depth + 1] = near;
                depth += 2;
                continue;
            }
            for slot in node.first..node.first + node.count {
                self.consider_nearest(slot, p, &mut best_squared, &mut best);
            }
        }
        best
    }

    /// [`nearest`](Self::nearest) among the triangles in `slots` (positions in leaf order, as
    /// [`within`](Self::within) gives them) only.
    pub(crate) fn nearest_among(&self, slots: &[u32], p: Vec3<T>, radius: T) -> Option<Nearest<T>> {
        let mut best_squared = radius * radius;
        let mut best = None;
        for &slot in slots {
            self.consider_nearest(slot, p, &mut best_squared, &mut best);
        }
        best
    }

    /// The squared distance from `p` to the triangle in `slot`.
    pub(crate) fn distance_squared(&self, slot: u32, p: Vec3<T>) -> T {
        (p - triangle::nearest_point(self.corners[slot as usize], p).0).length_squared()
    }

    /// The plane of the triangle in `slot`, as [`TrianglePlanes::plane`] gives it.
    pub(crate) fn plane(&self, slot: u32) -> (Vec3<T>, T) {
        self.planes[slot as usize].plane()
    }

    /// Whether the triangle in slot `b` lies in the plane of the one in slot `a` (see
    /// [`TrianglePlanes::same_plane`]).
    pub(crate) fn same_plane(&self, a: u32, b: u32) -> bool {
        self.planes[a as usize].same_plane(&self.planes[b as usize], self.corners[b as usize])
    }

    /// How far the foot of `p` on the plane of the triangle in `slot` is inside the flat region
    /// that triangle makes with those of `slots` in its plane (see
    /// [`same_plane`](Self::same_plane)), less what rounding can take: an end whose foot is
    /// nearer than this to `p`'s has its foot in that region, so that its nearest point on these
    /// triangles is its foot ([`over_face`](Self::over_face)). Negative when `p`'s foot is
    /// outside the region. With no such neighbour, the
    /// [`inner_margin`](TrianglePlanes::inner_margin) of the triangle alone.
    ///
    /// The region's border is made of the edges no other triangle of it runs along the other way
    /// (neighbours in one plane, wound alike, run along their shared edge in opposite
    /// directions): the margin is the distance from the foot to the nearest of those edges.
    pub(crate) fn flat_margin(&self, slots: &[u32], slot: u32, p: Vec3<T>) -> T {
        let plane = &self.planes[slot as usize];
        let neighbour = |&other: &u32| other != slot && self.same_plane(slot, other);
        if !slots.iter().any(neighbour) {
            return plane.inner_margin(p);
        }
        let (normal, offset) = plane.plane();
        let foot = p - normal * (normal.dot(p) - offset);
        let region = || std::iter::once(slot).chain(slots.iter().copied().filter(neighbour));
        let (mut contained, mut margin) = (false, T::from_f64(f64::INFINITY));
        for t in region() {
            let (corners, planes) = (self.corners[t as usize], &self.planes[t as usize]);
            let rounding = planes.rounding(p);
            let inside = planes.inside_edges(foot).into_iter().fold(T::from_f64(f64::INFINITY), T::min);
            contained |= inside >= -rounding;
            for k in 0..3 {
                let (from, to) = (corners[k], corners[(k + 1) % 3]);
                let shared = region().any(|u| {
                    let other = self.corners[u as usize];
                    u != t && (0..3).any(|j| other[j] == to && other[(j + 1) % 3] == from)
                });
                if !shared {
                    // The foot may be off by a rounding, and so may the edge's own points.
                    let distance = segment_distance(from, to, foot);
                    margin = margin.min(distance - rounding * T::from_f64(3.0));
                }
            }
        }
        if contained { margin } else { T::from_f64(f64::NEG_INFINITY) }
    }

    /// The nearest point to `p` of the triangle in `slot`, when `p` is known to lie over the
    /// flat region of [`flat_margin`](Self::flat_margin): its foot on the plane, unless that is
    /// farther than `radius`. For a point over the triangle's own face, what
    /// [`nearest_among`](Self::nearest_among) gives for that triangle alone.
    pub(crate) fn over_face(&self, slot: u32, p: Vec3<T>, radius: T) -> Option<Nearest<T>> {
        let (point, distance_squared) = self.planes[slot as usize].foot(p, radius * radius)?;
        let triangle = self.order[slot as usize] as usize;
        Some(Nearest { triangle, point, feature: Feature::Face, distance_squared })
    }

    /// The index, in the order given, of the triangle in `slot`.
    pub(crate) fn triangle(&self, slot: u32) -> usize {
        self.order[slot as usize] as usize
    }

    /// Keeps the nearest point of the triangle in `slot` to `p` as `best` when it is nearer.
    #[inline(always)]
    fn consider_nearest(&self, slot: u32, p: Vec3<T>, best_squared: &mut T, best: &mut Option<Nearest<T>>) {
        let slot = slot as usize;
        let Some((point, feature, distance_squared)) =
            self.planes[slot].nearest(self.corners[slot], p, *best_squared)
        else {
            return;
        };
        if distance_squared < *best_squared || (best.is_none() && distance_squared <= *best_squared) {
            *best_squared = distance_squared;
            *best = Some(Nearest { triangle: self.order[slot] as usize, point, feature, distance_squared });
        }
    }

    /// Calls `visit` with the slot (position in leaf order) of each triangle no farther than
    /// `radius` from `p`, in the tree's fixed order, until it returns `false`. Returns whether
    /// every such triangle was visited.
    pub(crate) fn within(&self, p: Vec3<T>, radius: T, mut visit: impl FnMut(u32) -> bool) -> bool {
        if self.corners.is_empty() {
            return true;
        }
        let radius_squared = radius * radius;
        let mut stack = [0u32; STACK];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let node = self.nodes[stack[depth] as usize];
            if box_distance_squared(node.lower, node.upper, p) > radius_squared {
                continue;
            }
            if node.count == 0 {
                stack[depth] = node.first + 1;
                stack[depth + 1] = node.first;
                depth += 2;
                continue;
            }
            for slot in node.first..node.first + node.count {
                let (corners, planes) = (self.corners[slot as usize], &self.planes[slot as usize]);
                let near = planes.nearest(corners, p, radius_squared);
                if near.is_some_and(|(_, _, distance_squared)| distance_squared <= radius_squared)
                    && !visit(slot)
                {
                    return false;
                }
            }
        }
        true
    }

    /// The first crossing of the segment from `start` to `end` with a triangle that `counts`
    /// (given the triangle's index and the segment's direction `end - start`): the triangle and
    /// the segment's parameter there, in [0, 1]. Of crossings at the same parameter, the first
    /// met in the tree's fixed order.
    pub(crate) fn first_crossing(
        &self,
        start: Vec3<T>,
        end: Vec3<T>,
        counts: impl Fn(usize, Vec3<T>) -> bool,
    ) -> Option<(usize, T)> {
        if self.corners.is_empty() {
            return None;
        }
        let d = end - start;
        let (mut lower, mut upper) = (start, start);
        extend(&mut lower, &mut upper, end);
        let mut best: Option<(usize, T)> = None;
        let mut stack = [0u32; STACK];
        let mut depth = 1;
        while depth > 0 {
            depth -= 1;
            let node = self.nodes[stack[depth] as usize];
            if !overlaps(node.lower, node.upper, lower, upper) {
                continue;
            }
            if node.count == 0 {
                stack[depth] = node.first + 1;
                stack[depth + 1] = node.first;
                depth += 2;
                continue;
            }
            for slot in node.first..node.first + node.count {
                if let Some(s) = self.consider_crossing(slot, start, end, &counts, &mut best) {
                    // Nothing beyond the crossing can come first: the box shrinks to the part before it.
                    (lower, upper) = (start, start);
                    extend(&mut lower, &mut upper, start + d * s);
                }
            }
        }
        best
    }

    /// [`first_crossing`](Self::first_crossing) among the triangles in `slots` (positions in
    /// leaf order, as [`within`](Self::within) gives them) only.
    pub(crate) fn first_crossing_among(
        &self,
        slots: &[u32],
        start: Vec3<T>,
        end: Vec3<T>,
        counts: impl Fn(usize, Vec3<T>) -> bool,
    ) -> Option<(usize, T)> {
        let mut best = None;
        for &slot in slots {
            self.consider_crossing(slot, start, end, &counts, &mut best);
        }
        best
    }

    /// Keeps the crossing of the segment from `start` to `end` with the triangle in `slot` as
    /// `best` when it counts and comes first, and returns its parameter then. A segment that
    /// stays on one side of the triangle's plane is ruled out by its planes alone.
    #[inline(always)]
    fn consider_crossing(
        &self,
        slot: u32,
        start: Vec3<T>,
        end: Vec3<T>,
        counts: &impl Fn(usize, Vec3<T>) -> bool,
        best: &mut Option<(usize, T)>,
    ) -> Option<T> {
        let slot = slot as usize;
        if self.planes[slot].apart(start, end) {
            return None;
        }
        let d = end - start;
        let s = triangle::crossing(self.corners[slot], start, d)?;
        let t = self.order[slot] as usize;
        let first = best.is_none_or(|(_, b)| s < b) && counts(t, d);
        first.then(|| {
            *best = Some((t, s));
            s
        })
    }
}

/// Builds the tree in place: `order[first..first + count]` are a node's triangles.
struct Builder<'a, T> {
    corners: &'a [[Vec3<T>; 3]],
    centroids: &'a [Vec3<T>],
    order: &'a mut [u32],
    nodes: &'a mut Vec<Node<T>>,
}

impl<T: Real> Builder<'_, T> {
    fn split(&mut self, node: usize, first: usize, count: usize) {
        let triangles = &mut self.order[first..first + count];
        let (mut lower, mut upper) = (Vec3::splat(T::ZERO), Vec3::splat(T::ZERO));
        let (mut centre_lower, mut centre_upper) = (lower, upper);
        for (i, &t) in triangles.iter().enumerate() {
            let [a, b, c] = self.corners[t as usize];
            let centroid = self.centroids[t as usize];
            if i == 0 {
                (lower, upper, centre_lower, centre_upper) = (a, a, centroid, centroid);
            }
            for corner in [a, b, c] {
                extend(&mut lower, &mut upper, corner);
            }
            extend(&mut centre_lower, &mut centre_upper, centroid);
        }
        if count <= LEAF_SIZE {
            self.nodes[node] = Node { lower, upper, first: first as u32, count: count as u32 };
            return;
        }
        let spread = (centre_upper - centre_lower).to_array();
        let axis = if spread[0] >= spread[1] && spread[0] >= spread[2] {
            0
        } else if spread[1] >= spread[2] {
            1
        } else {
            2
        };
        let half = count / 2;
        let centroids = self.centroids;
        triangles.select_nth_unstable_by(half, |&p, &q| {
            let (p, q) = (centroids[p as usize].to_array()[axis], centroids[q as usize].to_array()[axis]);
            p.partial_cmp(&q).unwrap_or(std::cmp::Ordering::Equal)
        });
        let child = self.nodes.len();
        let empty = Node { lower, upper, first: 0, count: 0 };
        self.nodes.extend([empty, empty]);
        self.nodes[node] = Node { lower, upper, first: child as u32, count: 0 };
        self.split(child, first, half);
        self.split(child + 1, first + half, count - half);
    }
}

fn extend<T: Real>(lower: &mut Vec3<T>, upper: &mut Vec3<T>, p: Vec3<T>) {
    *lower = Vec3::new(lower.x.min(p.x), lower.y.min(p.y), lower.z.min(p.z));
    *upper = Vec3::new(upper.x.max(p.x), upper.y.max(p.y), upper.z.max(p.z));
}

/// The distance from `p` to the segment from `a` to `b`.
fn segment_distance<T: Real>(a: Vec3<T>, b: Vec3<T>, p: Vec3<T>) -> T {
    let along = b - a;
    let length_squared = along.length_squared();
    let s = if length_squared > T::ZERO { (p - a).dot(along) / length_squared } else { T::ZERO };
    (p - (a + along * s.max(T::ZERO).min(T::ONE))).length()
}

/// Squared distance from `p` to the box; zero inside it.
#[inline(always)]
fn box_distance_squared<T: Real>(lower: Vec3<T>, upper: Vec3<T>, p: Vec3<T>) -> T {
    let gap = |lo: T, hi: T, x: T| (lo - x).max(x - hi).max(T::ZERO);
    let (dx, dy, dz) = (gap(lower.x, upper.x, p.x), gap(lower.y, upper.y, p.y), gap(lower.z, upper.z, p.z));
    dx * dx + dy * dy + dz * dz
}

#[inline(always)]
fn overlaps<T: Real>(lower: Vec3<T>, upper: Vec3<T>, q_lower: Vec3<T>, q_upper: Vec3<T>) -> bool {
    (lower.x <= q_upper.x)
        & (q_lower.x <= upper.x)
        & (lower.y <= q_upper.y)
        & (q_lower.y <= upper.y)
        & (lower.z <= q_upper.z)
        & (q_lower.z <= upper.z)
}
