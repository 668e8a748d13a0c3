//! For each particle, the triangles of a mesh collider near where it was last seen, so that a
//! particle that stays where it is (a cloth resting on the mesh) meets a handful of triangles a
//! step instead of walking the hierarchy twice.
//!
//! The triangles within [`REACH`] thicknesses of a point, the particle's **anchor**, are gathered
//! (at most [`CAPACITY`]). While the particle's path over a step, its start and its end, stays
//! within [`KEEP`] thicknesses of the anchor, every triangle the path can cross is within `KEEP`
//! of the anchor, and every triangle within the thickness of its end within `1 + KEEP`: both
//! among those gathered, so the contact found among them is the one the whole hierarchy gives
//! (the margin up to `REACH` covers rounding). Otherwise (it moved away, or more triangles were
//! near than fit) the hierarchy is walked, and the triangles near where the particle ended are
//! gathered anew. The arrays are made once with the collider's stage; anchors are kept in `f32`
//! in either precision, and the triangles are gathered around the anchor as kept.
//!
//! A particle that stays very near its anchor (one resting on the mesh) needs less still. The
//! anchor's distance to the nearest triangle, `d₁`, and to the next nearest, `d₂` (at least
//! `REACH`), are kept with it. A path within `d₁` of the anchor meets no triangle, so it crosses
//! none; and an end within `(d₂ - d₁) / 2` of the anchor is nearer to the anchor's nearest
//! triangle than to any other (distances change no faster than the point moves), so that
//! triangle alone is the one to test. That distance is also held within how far the anchor is
//! inside the edges of that triangle, so that such an end lies over its face: its nearest point
//! is straight below it, which a block of particles finds side by side ([`mesh_lanes`]).
//!
//! Triangles in the nearest one's plane (a flat part of the mesh cut into triangles, within
//! rounding) give an end over any of them the same nearest point, its foot on that plane: they
//! do not count as the next nearest, and the end is held within the flat region they make
//! together rather than within the one triangle. A particle resting over an edge between two
//! such triangles is then answered as one over a face, where the two would otherwise be equally
//! near.
//!
//! The arrays belong to the stage and are lent out a band of particles at a time
//! ([`NearbyTriangles::band`], cut between particles as the state is), so a band reads and writes
//! its particles' entries as plain numbers. Each value has its own array, so that a block of
//! consecutive particles reads each as one vector load; with it a particle keeps the plane of
//! its anchor's nearest triangle, so that the block needs no gather.
//!
//! [`mesh_lanes`]: super::mesh_lanes

use crate::solver::constraints::contacts::mesh_lanes::FacePlanes;
use crate::solver::constraints::contacts::triangle_bvh::TriangleBvh;
use crate::solver::forces::spring_blocks::LANES;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::parallel::Rows;

/// The most triangles kept for one particle.
pub(super) const CAPACITY: usize = 16;
/// How far, in thicknesses, a particle's path may stray from its anchor for its triangles to
/// be kept.
pub(super) const KEEP: f64 = 0.5;
/// How far, in thicknesses, from the anchor triangles are gathered.
pub(super) const REACH: f64 = 1.6;
/// The count of a particle with nothing usable gathered.
const NONE: u8 = u8::MAX;
/// The share of the distances `d₁` and `(d₂ - d₁) / 2` a path is held to, so that rounding never
/// takes it to the limit.
const SAFETY: f64 = 0.99;

/// The triangles kept for a particle's path, as [`NearbyBand::kept`] gives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Kept {
    /// How many slots were copied: every triangle gathered, or only the one that can be nearest.
    pub count: usize,
    /// Whether the path stays nearer to the anchor than any triangle is, so that it crosses none.
    pub clear: bool,
    /// Whether the end's nearest point is its foot on the plane of the one slot copied.
    pub over_face: bool,
}

/// The triangles near each particle, by their slots in the hierarchy's leaf order. What is kept
/// depends only on the anchors and the mesh, so a copy holds as well as the original.
#[derive(Clone, Debug)]
pub(super) struct NearbyTriangles<T> {
    /// Per axis, each particle's anchor.
    anchors: [Vec<f32>; 3],
    /// Per particle, the square of the distance from its anchor within which its path crosses
    /// nothing.
    clear: Vec<f32>,
    /// Per particle, the square of the distance from its anchor within which its end's nearest
    /// point is its foot on the plane of the anchor's nearest triangle; zero when nothing usable
    /// is gathered.
    settled: Vec<f32>,
    /// Per particle, the slot of its anchor's nearest triangle.
    nearest: Vec<u32>,
    /// Per particle, the plane of that triangle as [`FacePlanes`] keeps it: its normal's three
    /// components, then its offset.
    planes: [Vec<T>; 4],
    /// How many of a particle's slots are in use, or [`NONE`].
    counts: Vec<u8>,
    /// [`CAPACITY`] slots per particle.
    slots: Vec<u32>,
}

impl<T: Real> NearbyTriangles<T> {
    /// Room for `particles` particles, with nothing gathered.
    pub fn new(particles: usize) -> Self {
        Self {
            anchors: [(); 3].map(|_| vec![0.0; particles]),
            clear: vec![0.0; particles],
            settled: vec![0.0; particles],
            nearest: vec![0; particles],
            planes: [(); 4].map(|_| vec![T::ZERO; particles]),
            counts: vec![NONE; particles],
            slots: vec![0; particles * CAPACITY],
        }
    }

    /// Every particle's entries, to be cut into bands as the state is.
    pub fn band(&mut self) -> NearbyBand<'_, T> {
        NearbyBand {
            anchors: self.anchors.each_mut().map(Vec::as_mut_slice),
            clear: &mut self.clear,
            settled: &mut self.settled,
            nearest: &mut self.nearest,
            planes: self.planes.each_mut().map(Vec::as_mut_slice),
            counts: &mut self.counts,
            slots: &mut self.slots,
        }
    }
}

/// The entries of a band of consecutive particles, which it indexes from its first particle.
pub(super) struct NearbyBand<'a, T> {
    anchors: [&'a mut [f32]; 3],
    clear: &'a mut [f32],
    settled: &'a mut [f32],
    nearest: &'a mut [u32],
    planes: [&'a mut [T]; 4],
    counts: &'a mut [u8],
    slots: &'a mut [u32],
}

impl<T: Send> Rows for NearbyBand<'_, T> {
    fn split_at(self, at: usize) -> (Self, Self) {
        let (anchors, later_anchors) = Rows::split_at(self.anchors, at);
        let (clear, later_clear) = self.clear.split_at_mut(at);
        let (settled, later_settled) = self.settled.split_at_mut(at);
        let (nearest, later_nearest) = self.nearest.split_at_mut(at);
        let (planes, later_planes) = Rows::split_at(self.planes, at);
        let (counts, later_counts) = self.counts.split_at_mut(at);
        let (slots, later_slots) = self.slots.split_at_mut(at * CAPACITY);
        (
            Self { anchors, clear, settled, nearest, planes, counts, slots },
            Self {
                anchors: later_anchors,
                clear: later_clear,
                settled: later_settled,
                nearest: later_nearest,
                planes: later_planes,
                counts: later_counts,
                slots: later_slots,
            },
        )
    }
}

/// What a block of [`LANES`] consecutive particles keeps for the one-triangle case, in the
/// simulation's precision: the anchors per axis, the squared distances of [`NearbyTriangles`]'s
/// `clear` and `settled`, and the plane of the anchor's nearest triangle.
pub(super) struct SettledLanes<'a, T> {
    pub anchors: [[T; LANES]; 3],
    pub clear: [T; LANES],
    pub settled: [T; LANES],
    /// The normal's three components, then the offset.
    pub planes: [&'a [T; LANES]; 4],
}

/// What the particles of a band keep for the one-triangle case, every array of one length, so
/// that a block's bounds are checked once.
pub(super) struct Settled<'a, T> {
    anchors: [&'a [f32]; 3],
    clear: &'a [f32],
    settled: &'a [f32],
    planes: [&'a [T]; 4],
}

impl<T: Real> Settled<'_, T> {
    /// The one-triangle values of the [`LANES`] particles from `first`, as
    /// [`NearbyBand::kept`] reads them.
    #[inline(always)]
    pub fn lanes(&self, first: usize) -> SettledLanes<'_, T> {
        // Written out rather than mapped over the arrays, which is left as a call.
        #[inline(always)]
        fn lanes<T: Real>(values: &[f32], first: usize) -> [T; LANES] {
            let values: &[f32; LANES] = values[first..first + LANES].try_into().expect("a whole block");
            let mut lanes = [T::ZERO; LANES];
            for (lane, &x) in lanes.iter_mut().zip(values) {
                *lane = T::from_f64(x as f64);
            }
            lanes
        }
        #[inline(always)]
        fn block<T>(values: &[T], first: usize) -> &[T; LANES] {
            values[first..first + LANES].try_into().expect("a whole block")
        }
        let ([x, y, z], [nx, ny, nz, offsets]) = (&self.anchors, &self.planes);
        SettledLanes {
            anchors: [lanes(x, first), lanes(y, first), lanes(z, first)],
            clear: lanes(self.clear, first),
            settled: lanes(self.settled, first),
            planes: [block(nx, first), block(ny, first), block(nz, first), block(offsets, first)],
        }
    }
}

impl<T: Real> NearbyBand<'_, T> {
    /// The one-triangle values of the band's first `count` particles.
    #[inline(always)]
    pub fn settled(&self, count: usize) -> Settled<'_, T> {
        let ([x, y, z], [nx, ny, nz, offsets]) = (&self.anchors, &self.planes);
        Settled {
            anchors: [&x[..count], &y[..count], &z[..count]],
            clear: &self.clear[..count],
            settled: &self.settled[..count],
            planes: [&nx[..count], &ny[..count], &nz[..count], &offsets[..count]],
        }
    }

    /// The triangles gathered for particle `p` that its path from `start` to `end` can meet,
    /// copied into `slots`, when the path stays within `keep` of its anchor: all of them, or
    /// only the anchor's nearest when the path crosses none and ends that near the anchor.
    #[inline]
    pub fn kept(
        &self,
        p: usize,
        start: Vec3<T>,
        end: Vec3<T>,
        keep: T,
        slots: &mut [u32; CAPACITY],
    ) -> Option<Kept> {
        let count = self.counts[p];
        if count == NONE {
            return None;
        }
        let anchor = self.anchor(p);
        let (from, to) = ((start - anchor).length_squared(), (end - anchor).length_squared());
        let near = from.max(to) <= keep * keep;
        if !near {
            return None;
        }
        let real = |x: f32| T::from_f64(x as f64);
        let clear = from.max(to) < real(self.clear[p]);
        if clear && count > 0 && to < real(self.settled[p]) {
            slots[0] = self.nearest[p];
            return Some(Kept { count: 1, clear, over_face: true });
        }
        let count = count as usize;
        slots[..count].copy_from_slice(&self.slots[p * CAPACITY..p * CAPACITY + count]);
        Some(Kept { count, clear, over_face: false })
    }

    /// Gathers the triangles of `bvh` within `reach` of `at` for particle `p`, and copies them
    /// into `slots`: how many there are, or `None` when more than [`CAPACITY`] are that near.
    /// `faces` are the planes of `bvh`'s triangles.
    pub fn gather(
        &mut self,
        p: usize,
        at: Vec3<T>,
        bvh: &TriangleBvh<T>,
        faces: &FacePlanes<T>,
        reach: T,
        slots: &mut [u32; CAPACITY],
    ) -> Option<usize> {
        for (axis, x) in self.anchors.iter_mut().zip(at.to_array()) {
            axis[p] = x.to_f64() as f32;
        }
        let mut count = 0;
        let all = bvh.within(self.anchor(p), reach, |slot| {
            if count == CAPACITY {
                return false;
            }
            slots[count] = slot;
            count += 1;
            true
        });
        if !all {
            self.counts[p] = NONE;
            self.settled[p] = 0.0;
            return None;
        }
        self.slots[p * CAPACITY..p * CAPACITY + count].copy_from_slice(&slots[..count]);
        self.counts[p] = count as u8;
        self.bound(p, bvh, faces, &slots[..count], reach);
        Some(count)
    }

    /// Keeps particle `p`'s bounds and nearest plane, from the distances of its anchor to the
    /// triangles gathered within `reach` of it (every triangle nearer than `reach`).
    fn bound(&mut self, p: usize, bvh: &TriangleBvh<T>, faces: &FacePlanes<T>, slots: &[u32], reach: T) {
        let anchor = self.anchor(p);
        let distance = |slot: u32| bvh.distance_squared(slot, anchor).sqrt();
        let (mut nearest, mut first) = (0, reach);
        for &slot in slots {
            let distance = distance(slot);
            if distance < first {
                (nearest, first) = (slot, distance);
            }
        }
        // The triangles in the nearest one's plane give the same nearest point over their
        // faces: the next nearest that counts is the nearest of the others.
        let second = slots
            .iter()
            .filter(|&&slot| slot != nearest && !bvh.same_plane(slot, nearest))
            .map(|&slot| distance(slot))
            .fold(reach, T::min);
        let safety = T::from_f64(SAFETY);
        let clear = first * safety;
        let over_face = if slots.is_empty() { T::ZERO } else { bvh.flat_margin(slots, nearest, anchor) };
        let settled = ((second - first) * T::from_f64(0.5)).min(over_face).max(T::ZERO) * safety;
        let single = |x: T| x.to_f64() as f32;
        self.clear[p] = single(clear * clear);
        self.settled[p] = single(settled * settled);
        self.nearest[p] = nearest;
        let (normal, offset) = faces.plane(nearest);
        for (values, x) in self.planes.iter_mut().zip([normal.x, normal.y, normal.z, offset]) {
            values[p] = x;
        }
    }

    fn anchor(&self, p: usize) -> Vec3<T> {
        let [x, y, z] = self.anchors.each_ref().map(|axis| T::from_f64(axis[p] as f64));
        Vec3::new(x, y, z)
    }
}
