//! An axis-aligned box collider. A particle inside leaves through the nearest face.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use glam::DVec3;

use super::Surface;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

#[derive(Clone, Copy, Debug)]
pub(super) struct AxisBox<T> {
    center: [T; 3],
    half: [T; 3],
}

impl<T: Real> AxisBox<T> {
    pub fn new(center: DVec3, half_extents: DVec3) -> Self {
        Self { center: Vec3::from_dvec3(center).to_array(), half: Vec3::from_dvec3(half_extents).to_array() }
    }

    pub fn signed_distance(&self, x: Vec3<T>) -> T {
        let x = x.to_array();
        let q: [T; 3] = std::array::from_fn(|a| (x[a] - self.center[a]).abs() - self.half[a]);
        let outside = Vec3::new(q[0].max(T::ZERO), q[1].max(T::ZERO), q[2].max(T::ZERO)).length();
        let inside = q[0].max(q[1]).max(q[2]).min(T::ZERO);
        outside + inside
    }

    /// How far inside each pair of faces `x` is (negative outside them).
    #[inline(always)]
    fn depths(&self, x: [T; 3]) -> [T; 3] {
        std::array::from_fn(|a| self.half[a] - (x[a] - self.center[a]).abs())
    }

    /// Whether `x` is inside the box or on it: the test [`inside`](Self::inside) starts with.
    #[inline(always)]
    pub fn reaches(&self, x: Vec3<T>) -> bool {
        let [dx, dy, dz] = self.depths(x.to_array());
        (dx >= T::ZERO) & (dy >= T::ZERO) & (dz >= T::ZERO)
    }

    pub fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        if !self.reaches(x) {
            return None;
        }
        let mut p = x.to_array();
        let mut nearest: Option<(usize, T)> = None;
        for (a, depth) in self.depths(p).into_iter().enumerate() {
            if nearest.is_none_or(|(_, d)| depth < d) {
                nearest = Some((a, depth));
            }
        }
        let (axis, _) = nearest?;
        // On the centre plane either face is nearest; take the positive one.
        let sign = if p[axis] < self.center[axis] { -T::ONE } else { T::ONE };
        p[axis] = self.center[axis] + sign * self.half[axis];
        let mut normal = [T::ZERO; 3];
        normal[axis] = sign;
        Some(Surface {
            point: Vec3::new(p[0], p[1], p[2]),
            normal: Vec3::new(normal[0], normal[1], normal[2]),
        })
    }
}
