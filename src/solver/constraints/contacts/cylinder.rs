//! A cylinder collider with its axis along y: a round table. A particle inside leaves through
//! the nearest of its top, bottom and side.

use glam::DVec3;

use super::Surface;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

#[derive(Clone, Copy, Debug)]
pub(super) struct Cylinder<T> {
    center: Vec3<T>,
    radius: T,
    half_height: T,
}

impl<T: Real> Cylinder<T> {
    pub fn new(center: DVec3, radius: f64, height: f64) -> Self {
        Self {
            center: Vec3::from_dvec3(center),
            radius: T::from_f64(radius),
            half_height: T::from_f64(0.5 * height),
        }
    }

    pub fn signed_distance(&self, x: Vec3<T>) -> T {
        let local = x - self.center;
        let radial = (local.x * local.x + local.z * local.z).sqrt() - self.radius;
        let axial = local.y.abs() - self.half_height;
        let outside =
            (radial.max(T::ZERO) * radial.max(T::ZERO) + axial.max(T::ZERO) * axial.max(T::ZERO)).sqrt();
        outside + radial.max(axial).min(T::ZERO)
    }

    /// Whether `x` is inside the cylinder or on it: the test [`inside`](Self::inside) starts with.
    #[inline(always)]
    pub fn reaches(&self, x: Vec3<T>) -> bool {
        let local = x - self.center;
        let radial2 = local.x * local.x + local.z * local.z;
        (local.y.abs() <= self.half_height) & (radial2 <= self.radius * self.radius)
    }

    pub fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        if !self.reaches(x) {
            return None;
        }
        let local = x - self.center;
        let radial2 = local.x * local.x + local.z * local.z;
        let radial = radial2.sqrt();
        let side = self.radius - radial;
        let top = self.half_height - local.y;
        let bottom = self.half_height + local.y;
        let (zero, one) = (T::ZERO, T::ONE);
        if side < top && side < bottom {
            // A particle on the axis has no radial direction; it goes out along +x.
            let out = if radial > zero {
                Vec3::new(local.x / radial, zero, local.z / radial)
            } else {
                Vec3::new(one, zero, zero)
            };
            let point =
                Vec3::new(self.center.x + out.x * self.radius, x.y, self.center.z + out.z * self.radius);
            Some(Surface { point, normal: out })
        } else if top <= bottom {
            let point = Vec3::new(x.x, self.center.y + self.half_height, x.z);
            Some(Surface { point, normal: Vec3::new(zero, one, zero) })
        } else {
            let point = Vec3::new(x.x, self.center.y - self.half_height, x.z);
            Some(Surface { point, normal: Vec3::new(zero, -one, zero) })
        }
    }
}
