//! A plane collider: the half-space behind a plane is solid.

use glam::DVec3;

use super::Surface;
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
}
