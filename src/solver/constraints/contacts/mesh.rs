//! A triangle-mesh collider: particles keep `thickness` away from its triangles, and never pass
//! through one within a step.
//!
//! A step's contact with a mesh has two parts. First the particle's path from its
//! start-of-step position to its end is tested against the triangles (through the hierarchy):
//! where it first crosses one, the particle is stopped there, `thickness` out on the side it came
//! from, however fast it went. Then the triangle nearest to where it is (within `thickness`)
//! pushes it out to `thickness` from its nearest point, along the direction from that point (or
//! along the triangle's normal, when it is too close to have a direction). An open mesh is a
//! two-sided sheet: a particle stays on the side it is on. A closed mesh (see
//! [`surface_topology`](super::surface_topology)) is a solid: its path counts only where it
//! enters, and a particle found inside (by the pseudo-normal of its nearest feature) goes out to
//! the nearest surface. Every step begins with no particle inside (they are put out when the
//! simulation is built), and a particle can only enter by crossing a triangle, which the path
//! test stops, so each step looks for the inside only within `thickness` of the surface; putting
//! particles out ([`MeshShape::inside`]) searches at any depth.

use crate::solver::constraints::contacts::Surface;
use crate::solver::constraints::contacts::TriangleSurface;
use crate::solver::constraints::contacts::mesh_lanes::FacePlanes;
use crate::solver::constraints::contacts::nearby_triangles::{CAPACITY, KEEP, Kept, NearbyBand, REACH};
use crate::solver::constraints::contacts::surface_topology::Topology;
use crate::solver::constraints::contacts::triangle::Feature;
use crate::solver::constraints::contacts::triangle_bvh::{Nearest, TriangleBvh};
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

/// Below this fraction of the thickness, the direction from the nearest point is too uncertain
/// to push along, and the triangle's normal is used.
pub(super) const DIRECTION_FLOOR: f64 = 1e-3;

#[derive(Clone, Debug)]
pub(super) struct MeshShape<T> {
    bvh: TriangleBvh<T>,
    /// Unit normal of each triangle (outward for a closed mesh).
    normals: Vec<Vec3<T>>,
    /// The triangles' planes by slot, which particles resting on them keep.
    faces: FacePlanes<T>,
    /// For a closed mesh, per triangle, the pseudo-normals of its edges and of its corners.
    pseudo_normals: Option<Vec<[[Vec3<T>; 3]; 2]>>,
    thickness: T,
    /// The box around the triangles, widened by the thickness.
    lower: Vec3<T>,
    upper: Vec3<T>,
}

impl<T: Real> MeshShape<T> {
    pub fn new(surface: &TriangleSurface, thickness: f64) -> Self {
        let topology = Topology::of(surface);
        let convert = |v: glam::DVec3| Vec3::from_dvec3(v);
        let corners: Vec<[Vec3<T>; 3]> = topology.corners.iter().map(|c| c.map(convert)).collect();
        let bvh = TriangleBvh::new(&corners);
        let thickness = T::from_f64(thickness);
        let (lower, upper) = bvh.bounds();
        let normals: Vec<Vec3<T>> = topology.normals.iter().map(|&n| convert(n)).collect();
        Self {
            faces: FacePlanes::new(&bvh, &normals),
            normals,
            pseudo_normals: topology
                .pseudo_normals
                .map(|p| p.iter().map(|t| t.map(|f| f.map(convert))).collect()),
            thickness,
            lower: lower - Vec3::splat(thickness),
            upper: upper + Vec3::splat(thickness),
            bvh,
        }
    }

    /// The distance particles keep from the triangles.
    pub fn thickness(&self) -> T {
        self.thickness
    }

    /// Whether the mesh is closed (a solid).
    pub fn is_closed(&self) -> bool {
        self.pseudo_normals.is_some()
    }

    /// Distance to the nearest triangle, negative inside a closed mesh (not counting the
    /// thickness). A mesh with no triangle of positive area is infinitely far.
    pub fn signed_distance(&self, x: Vec3<T>) -> T {
        let Some(near) = self.bvh.nearest(x, T::from_f64(f64::INFINITY)) else {
            return T::from_f64(f64::INFINITY);
        };
        let distance = near.distance_squared.sqrt();
        if self.is_inside(x, &near) { -distance } else { distance }
    }

    /// Whether the segment from `start` to `end` comes within the thickness of the box around
    /// the triangles: the test [`contact`](Self::contact) starts with. Branch-free.
    #[inline(always)]
    pub fn reaches(&self, start: Vec3<T>, end: Vec3<T>) -> bool {
        let (lower, upper) = (self.lower, self.upper);
        (start.x.min(end.x) <= upper.x)
            & (start.x.max(end.x) >= lower.x)
            & (start.y.min(end.y) <= upper.y)
            & (start.y.max(end.y) >= lower.y)
            & (start.z.min(end.z) <= upper.z)
            & (start.z.max(end.z) >= lower.z)
    }

    /// Where `x` goes when it is within the thickness of a triangle or inside a closed mesh at
    /// any depth, and the outward normal there.
    pub fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        if !self.reaches(x, x) {
            return None;
        }
        let radius = if self.is_closed() { T::from_f64(f64::INFINITY) } else { self.thickness };
        let near = self.bvh.nearest(x, radius)?;
        self.pushed_out(x, &near, None)
    }

    /// The contact of a particle that moved from `start` to `end` in a step, if it has one: where
    /// it ends and the outward normal there. With `nearby` (the triangles near a band's
    /// particles, and this particle's index in the band), the triangles kept near the particle
    /// stand for the hierarchy while its path stays near them, and are gathered anew when it
    /// does not.
    pub fn contact(
        &self,
        start: Vec3<T>,
        end: Vec3<T>,
        nearby: Option<(&mut NearbyBand<T>, usize)>,
    ) -> Option<Surface<T>> {
        let mut slots = [0u32; CAPACITY];
        let keep = self.thickness * T::from_f64(KEEP);
        let kept = nearby.as_ref().and_then(|(nearby, p)| nearby.kept(*p, start, end, keep, &mut slots));
        let d = end - start;
        let closed = self.is_closed();
        let enters = |t: usize, d: Vec3<T>| !closed || d.dot(self.normals[t]) < T::ZERO;
        let crossing = match kept {
            _ if d.length_squared() == T::ZERO => None,
            Some(Kept { clear: true, .. }) => None,
            Some(Kept { count, .. }) => self.bvh.first_crossing_among(&slots[..count], start, end, enters),
            None => self.bvh.first_crossing(start, end, enters),
        };
        let mut end = end;
        let mut crossed = None;
        if let Some((t, s)) = crossing {
            let n = self.normals[t];
            let normal = if d.dot(n) < T::ZERO { n } else { -n };
            end = start + d * s + normal * self.thickness;
            crossed = Some(Surface { point: end, normal });
        }
        if let Some(Kept { over_face: true, .. }) = kept {
            let nearest = self.bvh.over_face(slots[0], end, self.thickness);
            return nearest.and_then(|near| self.pushed_out(end, &near, Some(start)));
        }
        // A stop at a crossing can leave the kept triangles' reach: those near it are gathered.
        let near = match (kept, nearby) {
            (Some(Kept { count, .. }), _) if crossed.is_none() => Some(count),
            (_, Some((nearby, p))) => {
                let reach = self.thickness * T::from_f64(REACH);
                nearby.gather(p, end, &self.bvh, &self.faces, reach, &mut slots)
            }
            (_, None) => None,
        };
        let nearest = match near {
            Some(count) => self.bvh.nearest_among(&slots[..count], end, self.thickness),
            None => self.bvh.nearest(end, self.thickness),
        };
        match nearest {
            Some(near) => self.pushed_out(end, &near, Some(start)).or(crossed),
            None => crossed,
        }
    }

    /// Where `x`, whose nearest point of the mesh is `near`, goes: out to the thickness along the
    /// direction from `near` (reversed inside a closed mesh), or `None` when it is farther than
    /// that and outside. With no usable direction, along the triangle's normal: outward for a
    /// closed mesh, towards `from` (else as wound) for an open one.
    fn pushed_out(&self, x: Vec3<T>, near: &Nearest<T>, from: Option<Vec3<T>>) -> Option<Surface<T>> {
        let inside = self.is_inside(x, near);
        let distance = near.distance_squared.sqrt();
        if !inside && distance > self.thickness {
            return None;
        }
        let face = self.normals[near.triangle];
        let normal = if distance > self.thickness * T::from_f64(DIRECTION_FLOOR) {
            let away = (x - near.point) * (T::ONE / distance);
            if inside { -away } else { away }
        } else if self.is_closed() {
            face
        } else {
            match from {
                Some(from) if (from - near.point).dot(face) < T::ZERO => -face,
                _ => face,
            }
        };
        Some(Surface { point: near.point + normal * self.thickness, normal })
    }

    /// Whether `x` is inside a closed mesh, judged by the pseudo-normal of the feature its
    /// nearest point `near` lies on; never for an open mesh.
    fn is_inside(&self, x: Vec3<T>, near: &Nearest<T>) -> bool {
        let Some(pseudo) = &self.pseudo_normals else { return false };
        let [edges, corners] = &pseudo[near.triangle];
        let normal = match near.feature {
            Feature::Face => self.normals[near.triangle],
            Feature::Edge(k) => edges[k as usize],
            Feature::Vertex(k) => corners[k as usize],
        };
        (x - near.point).dot(normal) < T::ZERO
    }
}
