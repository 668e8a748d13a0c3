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
//! Each particle's entries are read and written only by the band of particles that holds it:
//! relaxed atomics (plain loads and stores) let the bands share the arrays without cutting them.
//! Each value has its own array, so that a block of consecutive particles reads each from
//! consecutive memory.
//!
//! [`mesh_lanes`]: super::mesh_lanes

use std::sync::atomic::{AtomicU8, AtomicU32, Ordering::Relaxed};

use crate::solver::constraints::contacts::triangle_bvh::TriangleBvh;
use crate::solver::forces::spring_blocks::LANES;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

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

/// The triangles kept for a particle's path, as [`NearbyTriangles::kept`] gives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Kept {
    /// How many slots were copied: every triangle gathered, or only the one that can be nearest.
    pub count: usize,
    /// Whether the path stays nearer to the anchor than any triangle is, so that it crosses none.
    pub clear: bool,
    /// Whether the end's nearest point is its foot on the plane of the one slot copied.
    pub over_face: bool,
}

/// The triangles near each particle, by their slots in the hierarchy's leaf order.
#[derive(Debug)]
pub(super) struct NearbyTriangles {
    /// Per axis, each particle's anchor, as `f32` bits.
    anchors: [Vec<AtomicU32>; 3],
    /// Per particle, as `f32` bits: the square of the distance from its anchor within which its
    /// path crosses nothing.
    clear: Vec<AtomicU32>,
    /// Per particle, as `f32` bits: the square of the distance from its anchor within which its
    /// end's nearest point is its foot on the plane of the anchor's nearest triangle; zero when
    /// nothing usable is gathered.
    settled: Vec<AtomicU32>,
    /// Per particle, the slot of its anchor's nearest triangle.
    nearest: Vec<AtomicU32>,
    /// How many of a particle's slots are in use, or [`NONE`].
    counts: Vec<AtomicU8>,
    /// [`CAPACITY`] slots per particle.
    slots: Vec<AtomicU32>,
}

/// What a block of [`LANES`] consecutive particles keeps for the one-triangle case, in the
/// simulation's precision: the anchors per axis, the squared distances of [`NearbyTriangles`]'s
/// `clear` and `settled`, and the slot of the anchor's nearest triangle.
pub(super) struct SettledLanes<T> {
    pub anchors: [[T; LANES]; 3],
    pub clear: [T; LANES],
    pub settled: [T; LANES],
    pub nearest: [u32; LANES],
}

impl NearbyTriangles {
    /// Room for `particles` particles, with nothing gathered.
    pub fn new(particles: usize) -> Self {
        let zeros = || (0..particles).map(|_| AtomicU32::new(0)).collect::<Vec<_>>();
        Self {
            anchors: [zeros(), zeros(), zeros()],
            clear: zeros(),
            settled: zeros(),
            nearest: zeros(),
            counts: (0..particles).map(|_| AtomicU8::new(NONE)).collect(),
            slots: (0..particles * CAPACITY).map(|_| AtomicU32::new(0)).collect(),
        }
    }

    /// The one-triangle values of the [`LANES`] particles from `first`, as
    /// [`kept`](Self::kept) reads them.
    #[inline(always)]
    pub fn settled_lanes<T: Real>(&self, first: usize) -> SettledLanes<T> {
        let real = |bits: &AtomicU32| T::from_f64(f32::from_bits(bits.load(Relaxed)) as f64);
        let mut lanes = SettledLanes {
            anchors: [[T::ZERO; LANES]; 3],
            clear: [T::ZERO; LANES],
            settled: [T::ZERO; LANES],
            nearest: [0; LANES],
        };
        let [x, y, z] = self.anchors.each_ref().map(|axis| &axis[first..first + LANES]);
        let (clear, settled) = (&self.clear[first..first + LANES], &self.settled[first..first + LANES]);
        let nearest = &self.nearest[first..first + LANES];
        for lane in 0..LANES {
            lanes.anchors[0][lane] = real(&x[lane]);
            lanes.anchors[1][lane] = real(&y[lane]);
            lanes.anchors[2][lane] = real(&z[lane]);
            lanes.clear[lane] = real(&clear[lane]);
            lanes.settled[lane] = real(&settled[lane]);
            lanes.nearest[lane] = nearest[lane].load(Relaxed);
        }
        lanes
    }

    /// The triangles gathered for particle `p` that its path from `start` to `end` can meet,
    /// copied into `slots`, when the path stays within `keep` of its anchor: all of them, or
    /// only the anchor's nearest when the path crosses none and ends that near the anchor.
    #[inline]
    pub fn kept<T: Real>(
        &self,
        p: usize,
        start: Vec3<T>,
        end: Vec3<T>,
        keep: T,
        slots: &mut [u32; CAPACITY],
    ) -> Option<Kept> {
        let count = self.counts[p].load(Relaxed);
        if count == NONE {
            return None;
        }
        let anchor = self.anchor(p);
        let (from, to) = ((start - anchor).length_squared(), (end - anchor).length_squared());
        let near = from.max(to) <= keep * keep;
        if !near {
            return None;
        }
        let real = |bits: &AtomicU32| T::from_f64(f32::from_bits(bits.load(Relaxed)) as f64);
        let clear = from.max(to) < real(&self.clear[p]);
        if clear && count > 0 && to < real(&self.settled[p]) {
            slots[0] = self.nearest[p].load(Relaxed);
            return Some(Kept { count: 1, clear, over_face: true });
        }
        let count = count as usize;
        let kept = &self.slots[p * CAPACITY..p * CAPACITY + count];
        for (slot, kept) in slots.iter_mut().zip(kept) {
            *slot = kept.load(Relaxed);
        }
        Some(Kept { count, clear, over_face: false })
    }

    /// Gathers the triangles of `bvh` within `reach` of `at` for particle `p`, and copies them
    /// into `slots`: how many there are, or `None` when more than [`CAPACITY`] are that near.
    pub fn gather<T: Real>(
        &self,
        p: usize,
        at: Vec3<T>,
        bvh: &TriangleBvh<T>,
        reach: T,
        slots: &mut [u32; CAPACITY],
    ) -> Option<usize> {
        let rounded = at.to_array().map(|x| x.to_f64() as f32);
        for (axis, x) in self.anchors.iter().zip(rounded) {
            axis[p].store(x.to_bits(), Relaxed);
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
            self.counts[p].store(NONE, Relaxed);
            self.settled[p].store(0, Relaxed);
            return None;
        }
        for (kept, &slot) in self.slots[p * CAPACITY..].iter().zip(&slots[..count]) {
            kept.store(slot, Relaxed);
        }
        self.counts[p].store(count as u8, Relaxed);
        self.bound(p, bvh, &slots[..count], reach);
        Some(count)
    }

    /// Keeps particle `p`'s bounds, from the distances of its anchor to the triangles gathered
    /// within `reach` of it (every triangle nearer than `reach`).
    fn bound<T: Real>(&self, p: usize, bvh: &TriangleBvh<T>, slots: &[u32], reach: T) {
        let anchor = self.anchor::<T>(p);
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
        let bits = |x: T| (x.to_f64() as f32).to_bits();
        self.clear[p].store(bits(clear * clear), Relaxed);
        self.settled[p].store(bits(settled * settled), Relaxed);
        self.nearest[p].store(nearest, Relaxed);
    }

    fn anchor<T: Real>(&self, p: usize) -> Vec3<T> {
        let [x, y, z] =
            self.anchors.each_ref().map(|axis| T::from_f64(f32::from_bits(axis[p].load(Relaxed)) as f64));
        Vec3::new(x, y, z)
    }
}

/// A copy starts with nothing gathered, which only costs its first steps a walk.
impl Clone for NearbyTriangles {
    fn clone(&self) -> Self {
        Self::new(self.counts.len())
    }
}
