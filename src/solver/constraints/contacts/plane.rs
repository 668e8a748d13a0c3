//! A plane collider: the half-space behind a plane is solid.

use glam::DVec3;

use super::carried_friction::{BandFriction, Next};
use super::{Surface, respond};
use crate::solver::forces::spring_blocks::LANES;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

#[derive(Clone, Copy, Debug)]
pub(super) struct Plane<T> {
    point: Vec3<T>,
    /// Unit length.
    normal: Vec3<T>,
}

impl<T: Real> Plane<T> {
    /// A normal of zero length (refused by scene validation) is taken as +y.
    pub fn new(point: DVec3, normal: DVec3) -> Self {
        let normal = normal.try_normalize().unwrap_or(DVec3::Y);
        Self { point: Vec3::from_dvec3(point), normal: Vec3::from_dvec3(normal) }
    }

    pub fn signed_distance(&self, x: Vec3<T>) -> T {
        (x - self.point).dot(self.normal)
    }

    /// Whether `x` is behind the plane or on it: the test [`inside`](Self::inside) starts with.
    #[inline(always)]
    pub fn reaches(&self, x: Vec3<T>) -> bool {
        self.signed_distance(x) <= T::ZERO
    }

    pub fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        let depth = self.signed_distance(x);
        self.reaches(x).then(|| Surface { point: x - self.normal * depth, normal: self.normal })
    }

    /// Resolves the contacts of the [`LANES`] particles from `first` side by side, in vector
    /// lanes with no branch: a lane whose particle is free and touches takes the point
    /// [`inside`](Self::inside) gives and the velocity [`respond`] gives, the same values as
    /// one particle at a time; the others keep theirs, and their carried friction. `CARRY` says
    /// whether `carry` is given, so that a step without carried friction does no work for it.
    /// `(friction, restitution)` is the collider's response. Returns whether any particle was
    /// touched.
    #[inline(always)]
    pub fn resolve_lanes<const CARRY: bool>(
        &self,
        positions: [&mut [T]; 3],
        velocities: [&mut [T]; 3],
        inverse_masses: &[T],
        carry: Option<&mut BandFriction<T>>,
        first: usize,
        (friction, restitution): (T, T),
    ) -> bool {
        fn block<T>(axis: &mut [T], first: usize) -> &mut [T; LANES] {
            (&mut axis[first..first + LANES]).try_into().expect("a whole block")
        }
        let (mut x, mut v) = (positions.map(|a| block(a, first)), velocities.map(|a| block(a, first)));
        let inverse_masses: &[T; LANES] =
            inverse_masses[first..first + LANES].try_into().expect("a whole block");
        // Computed from copies into arrays and written back after, so that the loop is one
        // vector instruction wide.
        let (mut out, mut hits) = ([[T::ZERO; LANES]; 6], [false; LANES]);
        let carried = BandFriction::lanes(carry.as_deref().filter(|_| CARRY), first);
        let mut next = [Next::NONE; LANES];
        for lane in 0..LANES {
            let at = Vec3::new(x[0][lane], x[1][lane], x[2][lane]);
            let depth = self.signed_distance(at);
            let hit = (depth <= T::ZERO) & (inverse_masses[lane] != T::ZERO);
            let onto = at - self.normal * depth;
            let mut velocity = Vec3::new(v[0][lane], v[1][lane], v[2][lane]);
            let given = CARRY.then(|| carried[lane].given(at, self.normal));
            let response = respond(&mut velocity, self.normal, friction, restitution, given);
            if CARRY {
                next[lane] = response.carry_on(&carried[lane], carried[lane].before, onto, true);
            }
            let pick = |touched: Vec3<T>, kept: Vec3<T>| if hit { touched } else { kept };
            let (onto, velocity) =
                (pick(onto, at), pick(velocity, Vec3::new(v[0][lane], v[1][lane], v[2][lane])));
            (out[0][lane], out[1][lane], out[2][lane]) = (onto.x, onto.y, onto.z);
            (out[3][lane], out[4][lane], out[5][lane]) = (velocity.x, velocity.y, velocity.z);
            hits[lane] = hit;
        }
        for (axis, values) in x.iter_mut().chain(v.iter_mut()).zip(&out) {
            **axis = *values;
        }
        if let Some(carry) = carry {
            carry.set_lanes(first, hits, &next);
        }
        hits.into_iter().fold(false, |any, hit| any | hit)
    }
}
