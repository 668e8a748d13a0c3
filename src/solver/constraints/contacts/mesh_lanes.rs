//! The common case of a mesh contact, a block of particles at a time in vector lanes: a particle
//! resting on the mesh, whose path crosses no triangle and ends over the face of its anchor's
//! nearest triangle, or of a neighbour in its plane (the one-triangle case of
//! [`NearbyTriangles`](super::nearby_triangles::NearbyTriangles)).
//!
//! For such a particle the whole contact of [`MeshShape::contact`] is its height over that
//! triangle's plane: its nearest point is its foot on the plane, it is pushed out to the
//! thickness along the direction from the foot, and the response follows. A block reads its
//! particles' anchors, bounds and planes (each particle keeps its nearest triangle's plane, so
//! that every read is of consecutive memory), then computes every lane with no branch, in the
//! same operations as the one-particle path, so that a lane gives the same position and
//! velocity. A lane that is not in that case (a path that strays from its anchor, an end over an
//! edge, or one too near the plane to have a direction) keeps its values and is left to the
//! one-particle path.

use crate::solver::constraints::contacts::carried_friction::{BandFriction, Next};
use crate::solver::constraints::contacts::mesh::{DIRECTION_FLOOR, MeshShape};
use crate::solver::constraints::contacts::nearby_triangles::{KEEP, NearbyBand, Settled};
use crate::solver::constraints::contacts::triangle_bvh::TriangleBvh;
use crate::solver::constraints::contacts::{Band, respond};
use crate::solver::forces::spring_blocks::{self as blocks, LANES};
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

/// A triangle's plane as the lanes read it: the unit normal and offset of its
/// [`TrianglePlanes`](super::triangle::TrianglePlanes), turned (both negated, which changes no
/// bit of a foot or a distance) to face as the mesh's normal of the triangle does: outward for
/// a closed mesh, so that a point with a negative height over it is inside.
#[derive(Clone, Copy, Debug, Default)]
struct FacePlane<T> {
    normal: Vec3<T>,
    offset: T,
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
                if normal.dot(normals[bvh.triangle(slot)]) < T::ZERO {
                    FacePlane { normal: -normal, offset: -offset }
                } else {
                    FacePlane { normal, offset }
                }
            })
            .collect();
        if planes.is_empty() {
            planes.push(FacePlane::default());
        }
        Self(planes)
    }

    /// The unit normal and offset of the triangle in `slot`.
    pub fn plane(&self, slot: u32) -> (Vec3<T>, T) {
        let face = self.0[slot as usize];
        (face.normal, face.offset)
    }
}

/// Resolves the contacts of the particles of `band` in the one-triangle case, in `rest.len()`
/// blocks of [`LANES`] from particle `first`, against a fixed mesh with the band's kept
/// triangles in `nearby`. Returns whether any particle was touched, and marks in `rest` (bit
/// `l` of a block's byte for its lane `l`) the free particles left to the one-particle path
/// (those of them that pass [`MeshShape::reaches`]). The blocks run with no call between them,
/// and read arrays of one length, so that what they share is read once and a block's bounds
/// are checked once.
pub(super) fn resolve_blocks<T: Real>(
    mesh: &MeshShape<T>,
    nearby: &NearbyBand<T>,
    band: &mut Band<T>,
    first: usize,
    rest: &mut [u8],
    friction: T,
    restitution: T,
) -> bool {
    let end = first + rest.len() * LANES;
    let (mut band, settled) = (band.first(end), nearby.settled(end));
    let closed = mesh.is_closed();
    let mut touched = false;
    for (k, rest) in rest.iter_mut().enumerate() {
        let block = first + k * LANES;
        let resolved = match (closed, band.friction.is_some()) {
            (true, true) => resolve::<T, true, true>(mesh, &settled, &mut band, block, friction, restitution),
            (true, false) => {
                resolve::<T, true, false>(mesh, &settled, &mut band, block, friction, restitution)
            }
            (false, true) => {
                resolve::<T, false, true>(mesh, &settled, &mut band, block, friction, restitution)
            }
            (false, false) => {
                resolve::<T, false, false>(mesh, &settled, &mut band, block, friction, restitution)
            }
        };
        touched |= resolved.touched;
        *rest = resolved.rest;
    }
    touched
}

/// What a block's lanes did.
struct Resolved {
    /// Whether any particle was touched.
    touched: bool,
    /// The free particles not in the one-triangle case, lane `l` as bit `l`.
    rest: u8,
}

#[inline(always)]
fn resolve<T: Real, const CLOSED: bool, const CARRY: bool>(
    mesh: &MeshShape<T>,
    settled: &Settled<T>,
    band: &mut Band<T>,
    block: usize,
    friction: T,
    restitution: T,
) -> Resolved {
    fn whole<T>(axis: &mut [T], first: usize) -> &mut [T; LANES] {
        (&mut axis[first..first + LANES]).try_into().expect("a whole block")
    }
    let settled = settled.lanes(block);
    let [nx, ny, nz, offsets] = settled.planes;
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
    // Built only where friction is carried, so that an explicit run does no work for them.
    let carried = CARRY.then(|| BandFriction::lanes(band.friction.as_ref(), block));
    let mut next = CARRY.then_some([Next::NONE; LANES]);
    for lane in 0..LANES {
        let at = |axes: [&[T; LANES]; 3]| Vec3::new(axes[0][lane], axes[1][lane], axes[2][lane]);
        let (from, end) = (at(start), at(x.each_ref().map(|a| &**a)));
        let anchor = at(settled.anchors.each_ref());
        let (strayed, went) = ((from - anchor).length_squared(), (end - anchor).length_squared());
        let farthest = strayed.max(went);
        let alone =
            (farthest <= keep * keep) & (farthest < settled.clear[lane]) & (went < settled.settled[lane]);
        let normal = Vec3::new(nx[lane], ny[lane], nz[lane]);
        let height = normal.dot(end) - offsets[lane];
        let distance_squared = height * height;
        let foot = end - normal * height;
        let distance = distance_squared.sqrt();
        // The plane faces outward on a closed mesh. Where the sign of this height and that of
        // the one-particle path's `(end - foot)·n` could differ, the distance is below the floor
        // and the lane is not answered.
        let inside = CLOSED && height < T::ZERO;
        // The one-particle path's direction from the foot: discarded when too short to have one.
        let away = (end - foot) * (T::ONE / distance);
        let direction = if inside { -away } else { away };
        let steady = distance > floor;
        let near = (distance_squared <= thickness * thickness) & (inside | (distance <= thickness));
        // An answered end lies within the thickness of its triangle's face, so inside the box
        // that `MeshShape::reaches` tests: that test is left to the particles not answered.
        let free = inverse_masses[lane] != T::ZERO;
        let answered = free & alone & steady;
        let hit = answered & near;
        let onto = foot + direction * thickness;
        let before = at(v.each_ref().map(|a| &**a));
        let mut velocity = before;
        let carried = carried.map(|carried| carried[lane]);
        let given = carried.map(|c| c.given(end, direction));
        let response = respond(&mut velocity, direction, friction, restitution, given);
        if let (Some(next), Some(carried)) = (&mut next, carried) {
            next[lane] = response.carry_on(&carried, carried.before, onto, true);
        }
        let pick = |touched: Vec3<T>, kept: Vec3<T>| if hit { touched } else { kept };
        let (onto, velocity) = (pick(onto, end), pick(velocity, before));
        (out[0][lane], out[1][lane], out[2][lane]) = (onto.x, onto.y, onto.z);
        (out[3][lane], out[4][lane], out[5][lane]) = (velocity.x, velocity.y, velocity.z);
        hits[lane] = hit;
        rest[lane] = free & !answered;
    }
    for (axis, values) in x.iter_mut().chain(v.iter_mut()).zip(&out) {
        **axis = *values;
    }
    if let (Some(carry), Some(next)) = (&mut band.friction, &next) {
        carry.set_lanes(block, hits, next);
    }
    let rest = rest.iter().enumerate().fold(0, |bits, (lane, &rest)| bits | u8::from(rest) << lane);
    Resolved { touched: hits.into_iter().fold(false, |any, hit| any | hit), rest }
}
