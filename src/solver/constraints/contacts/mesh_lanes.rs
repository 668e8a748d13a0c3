//! The common case of a mesh contact, a block of particles at a time in vector lanes: a particle
//! resting on the mesh, whose path crosses no triangle and ends over the face of its anchor's
//! nearest triangle, or of a neighbour in its plane (the one-triangle case of
//! [`NearbyTriangles`](super::nearby_triangles::NearbyTriangles)).
//!
//! For such a particle the whole contact of [`MeshShape::contact`] is its height over that
//! triangle's plane: its nearest point is its foot on the plane, it is pushed out to the
//! thickness along the direction from the foot, and the response follows. A block reads its
//! particles' anchors and bounds and the planes of their triangles into arrays, then computes
//! every lane with no branch, in the same operations as the one-particle path, so that a lane
//! gives the same position and velocity. A lane that is not in that case (a path that strays
//! from its anchor, an end over an edge, or one too near the plane to have a direction) keeps its
//! values and is left to the one-particle path.

use crate::solver::constraints::contacts::mesh::{DIRECTION_FLOOR, MeshShape};
use crate::solver::constraints::contacts::nearby_triangles::{KEEP, NearbyTriangles};
use crate::solver::constraints::contacts::triangle_bvh::TriangleBvh;
use crate::solver::constraints::contacts::{Band, respond};
use crate::solver::forces::spring_blocks::{self as blocks, LANES};
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

/// A triangle's plane as the lanes read it: the unit normal and offset of its
/// [`TrianglePlanes`](super::triangle::TrianglePlanes), and its normal as the mesh keeps it
/// (outward for a closed mesh), which tells a closed mesh's inside.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct FacePlane<T> {
    normal: Vec3<T>,
    offset: T,
    outward: Vec3<T>,
}

/// The plane of every triangle, in the hierarchy's leaf order (by slot); one of no area for an
/// empty mesh, so that any slot a particle keeps can be read.
#[derive(Clone, Debug)]
pub(super) struct FacePlanes<T>(Vec<FacePlane<T>>);

impl<T: Real> FacePlanes<T> {
    /// The planes of `bvh`'s triangles, with `normals` the mesh's normals in the order given.
    pub fn new(bvh: &TriangleBvh<T>, normals: &[Vec3<T>]) -> Self {
        let mut planes: Vec<FacePlane<T>> = (0..bvh.len() as u32)
            .map(|slot| {
                let (normal, offset) = bvh.plane(slot);
                FacePlane { normal, offset, outward: normals[bvh.triangle(slot)] }
            })
            .collect();
        if planes.is_empty() {
            planes.push(FacePlane::default());
        }
        Self(planes)
    }
}

/// What a block's lanes did.
pub(super) struct Resolved {
    /// Whether any particle was touched.
    pub touched: bool,
    /// The free particles that may have a contact and are not in the one-triangle case.
    pub rest: [bool; LANES],
}

/// Resolves the contacts of the [`LANES`] particles of `band` from `block` that are in the
/// one-triangle case, against a fixed mesh with particle `p`'s kept triangles in `nearby`.
#[inline(always)]
pub(super) fn resolve_lanes<T: Real>(
    mesh: &MeshShape<T>,
    nearby: &NearbyTriangles,
    band: &mut Band<T>,
    block: usize,
    friction: T,
    restitution: T,
) -> Resolved {
    if mesh.is_closed() {
        resolve::<T, true>(mesh, nearby, band, block, friction, restitution)
    } else {
        resolve::<T, false>(mesh, nearby, band, block, friction, restitution)
    }
}

#[inline(always)]
fn resolve<T: Real, const CLOSED: bool>(
    mesh: &MeshShape<T>,
    nearby: &NearbyTriangles,
    band: &mut Band<T>,
    block: usize,
    friction: T,
    restitution: T,
) -> Resolved {
    fn whole<T>(axis: &mut [T], first: usize) -> &mut [T; LANES] {
        (&mut axis[first..first + LANES]).try_into().expect("a whole block")
    }
    let settled = nearby.settled_lanes::<T>(band.first + block);
    // The gathers of the triangles' planes, one lane at a time, before the arithmetic, so that
    // the arithmetic is one vector instruction wide.
    let (mut plane, mut outward) = ([[T::ZERO; LANES]; 4], [[T::ZERO; LANES]; 3]);
    for lane in 0..LANES {
        let face = mesh.faces().0[settled.nearest[lane] as usize];
        let [nx, ny, nz] = face.normal.to_array();
        (plane[0][lane], plane[1][lane], plane[2][lane], plane[3][lane]) = (nx, ny, nz, face.offset);
        if CLOSED {
            let [ox, oy, oz] = face.outward.to_array();
            (outward[0][lane], outward[1][lane], outward[2][lane]) = (ox, oy, oz);
        }
    }
    let start = blocks::axes(band.start, block);
    let (mut x, mut v) = (
        band.positions.each_mut().map(|a| whole(a, block)),
        band.velocities.each_mut().map(|a| whole(a, block)),
    );
    let inverse_masses: &[T; LANES] =
        band.inverse_masses[block..block + LANES].try_into().expect("a whole block");
    let thickness = mesh.thickness();
    let keep = thickness * T::from_f64(KEEP);
    let floor = thickness * T::from_f64(DIRECTION_FLOOR);
    let (mut out, mut hits, mut rest) = ([[T::ZERO; LANES]; 6], [false; LANES], [false; LANES]);
    for lane in 0..LANES {
        let at = |axes: [&[T; LANES]; 3]| Vec3::new(axes[0][lane], axes[1][lane], axes[2][lane]);
        let (from, end) = (at(start), at(x.each_ref().map(|a| &**a)));
        let anchor = at(settled.anchors.each_ref());
        let (strayed, went) = ((from - anchor).length_squared(), (end - anchor).length_squared());
        let farthest = strayed.max(went);
        let alone =
            (farthest <= keep * keep) & (farthest < settled.clear[lane]) & (went < settled.settled[lane]);
        let normal = Vec3::new(plane[0][lane], plane[1][lane], plane[2][lane]);
        let height = normal.dot(end) - plane[3][lane];
        let distance_squared = height * height;
        let foot = end - normal * height;
        let distance = distance_squared.sqrt();
        let inside = CLOSED && (end - foot).dot(at(outward.each_ref())) < T::ZERO;
        // The one-particle path's direction from the foot: discarded when too short to have one.
        let away = (end - foot) * (T::ONE / distance);
        let direction = if inside { -away } else { away };
        let steady = distance > floor;
        let near = (distance_squared <= thickness * thickness) & (inside | (distance <= thickness));
        let candidate = (inverse_masses[lane] != T::ZERO) & mesh.reaches(from, end);
        let answered = candidate & alone & steady;
        let hit = answered & near;
        let onto = foot + direction * thickness;
        let before = at(v.each_ref().map(|a| &**a));
        let mut velocity = before;
        respond(&mut velocity, direction, friction, restitution);
        let pick = |touched: Vec3<T>, kept: Vec3<T>| if hit { touched } else { kept };
        let (onto, velocity) = (pick(onto, end), pick(velocity, before));
        (out[0][lane], out[1][lane], out[2][lane]) = (onto.x, onto.y, onto.z);
        (out[3][lane], out[4][lane], out[5][lane]) = (velocity.x, velocity.y, velocity.z);
        hits[lane] = hit;
        rest[lane] = candidate & !answered;
    }
    for (axis, values) in x.iter_mut().chain(v.iter_mut()).zip(&out) {
        **axis = *values;
    }
    Resolved { touched: hits.into_iter().fold(false, |any, hit| any | hit), rest }
}
