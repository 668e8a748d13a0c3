//! A sphere collider: a solid ball, tested along the particle's path as well as at its end.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use glam::DVec3;

use super::Surface;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

/// The largest dip into the sphere, relative to its radius, that counts as grazing.
pub(super) const GRAZE: f64 = 1e-3;

#[derive(Clone, Copy, Debug)]
pub(super) struct Sphere<T> {
    center: Vec3<T>,
    radius: T,
}

impl<T: Real> Sphere<T> {
    pub fn new(center: DVec3, radius: f64) -> Self {
        Self { center: Vec3::from_dvec3(center), radius: T::from_f64(radius) }
    }

    pub fn signed_distance(&self, x: Vec3<T>) -> T {
        (x - self.center).length() - self.radius
    }

    /// Whether `x` is inside the sphere or on it: the test [`inside`](Self::inside) starts with.
    #[inline(always)]
    pub fn reaches(&self, x: Vec3<T>) -> bool {
        (x - self.center).length_squared() <= self.radius * self.radius
    }

    /// The surface point straight out from the centre, for a particle inside or on the surface. A
    /// particle exactly at the centre has no such direction; it goes out upwards (+y).
    pub fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        if !self.reaches(x) {
            return None;
        }
        let offset = x - self.center;
        let distance2 = offset.length_squared();
        let distance = distance2.sqrt();
        let normal = if distance > T::ZERO {
            offset * (T::ONE / distance)
        } else {
            Vec3::new(T::ZERO, T::ONE, T::ZERO)
        };
        Some(self.at(normal))
    }

    /// Where the segment from `start` (outside) to `end` first meets the sphere, if it does.
    pub fn entry(&self, start: Vec3<T>, end: Vec3<T>) -> Option<Surface<T>> {
        let from_center = start - self.center;
        let c = from_center.length_squared() - self.radius * self.radius;
        if !(c > T::ZERO) {
            return None;
        }
        let d = end - start;
        let a = d.length_squared();
        let b = from_center.dot(d);
        // Entry needs motion towards the centre and a real root of |start + s d - centre| = r.
        if !(a > T::ZERO) || b >= T::ZERO {
            return None;
        }
        let discriminant = b * b - a * c;
        if discriminant < T::ZERO {
            return None;
        }
        let s = (-b - discriminant.sqrt()) / a;
        if !(s <= T::ONE) {
            return None;
        }
        let offset = from_center + d * s;
        let distance = offset.length();
        (distance > T::ZERO).then(|| self.at(offset * (T::ONE / distance)))
    }

    /// Where a particle that went into the sphere and out again within the step, from `start` to
    /// `end` (both outside), first met it. A path that only grazes the surface, dipping less than
    /// [`GRAZE`] of the radius (as a particle sliding over the sphere does between two surface
    /// points), is not a passage.
    pub fn passage(&self, start: Vec3<T>, end: Vec3<T>) -> Option<Surface<T>> {
        if self.dips(start, end) { self.entry(start, end) } else { None }
    }

    /// Whether the segment from `start` to `end` (of positive length) comes closer to the centre
    /// than the grazing depth: the test [`passage`](Self::passage) starts with. Branch-free: a
    /// segment of zero length computes a meaningless `s` and is refused at the end.
    #[inline(always)]
    pub fn dips(&self, start: Vec3<T>, end: Vec3<T>) -> bool {
        let d = end - start;
        let a = d.length_squared();
        let s = ((self.center - start).dot(d) / a).max(T::ZERO).min(T::ONE);
        let deepest = (start + d * s - self.center).length_squared();
        let shallow = self.radius * (T::ONE - T::from_f64(GRAZE));
        (a > T::ZERO) & (deepest < shallow * shallow)
    }

    fn at(&self, normal: Vec3<T>) -> Surface<T> {
        Surface { point: self.center + normal * self.radius, normal }
    }
}
