//! Symmetric 3×3 matrices: the per-spring and per-particle blocks of the implicit system.

use std::ops::{Add, AddAssign, Mul};

use super::real::Real;
use super::vec3::Vec3;

/// A symmetric 3×3 matrix stored as its six distinct entries.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sym3<T> {
    xx: T,
    yy: T,
    zz: T,
    xy: T,
    xz: T,
    yz: T,
}

impl<T: Real> Sym3<T> {
    /// The zero matrix.
    pub const ZERO: Self =
        Self { xx: T::ZERO, yy: T::ZERO, zz: T::ZERO, xy: T::ZERO, xz: T::ZERO, yz: T::ZERO };

    /// The identity.
    pub fn identity() -> Self {
        Self { xx: T::ONE, yy: T::ONE, zz: T::ONE, ..Self::ZERO }
    }

    /// The matrix from its entries in the order `[xx, yy, zz, xy, xz, yz]`.
    #[inline(always)]
    pub fn from_entries([xx, yy, zz, xy, xz, yz]: [T; 6]) -> Self {
        Self { xx, yy, zz, xy, xz, yz }
    }

    /// The entries in the order `[xx, yy, zz, xy, xz, yz]`.
    #[inline(always)]
    pub fn entries(&self) -> [T; 6] {
        [self.xx, self.yy, self.zz, self.xy, self.xz, self.yz]
    }

    /// The outer product `n nᵀ`.
    #[inline(always)]
    pub fn outer(n: Vec3<T>) -> Self {
        Self { xx: n.x * n.x, yy: n.y * n.y, zz: n.z * n.z, xy: n.x * n.y, xz: n.x * n.z, yz: n.y * n.z }
    }

    /// The matrix times a vector.
    #[inline(always)]
    pub fn apply(&self, v: Vec3<T>) -> Vec3<T> {
        Vec3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// The inverse, or the inverse of the diagonal when the matrix is (nearly) singular.
    pub fn inverse(&self) -> Self {
        let c_xx = self.yy * self.zz - self.yz * self.yz;
        let c_xy = self.xz * self.yz - self.xy * self.zz;
        let c_xz = self.xy * self.yz - self.xz * self.yy;
        let det = self.xx * c_xx + self.xy * c_xy + self.xz * c_xz;
        let scale = self.xx.abs() * self.yy.abs() * self.zz.abs();
        if det.abs() <= T::from_f64(1e-12) * scale || !det.is_finite() || scale == T::ZERO {
            let safe = |d: T| if d > T::ZERO { T::ONE / d } else { T::ZERO };
            return Self { xx: safe(self.xx), yy: safe(self.yy), zz: safe(self.zz), ..Self::ZERO };
        }
        let inv = T::ONE / det;
        Self {
            xx: c_xx * inv,
            xy: c_xy * inv,
            xz: c_xz * inv,
            yy: (self.xx * self.zz - self.xz * self.xz) * inv,
            yz: (self.xy * self.xz - self.xx * self.yz) * inv,
            zz: (self.xx * self.yy - self.xy * self.xy) * inv,
        }
    }
}

impl<T: Real> Add for Sym3<T> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            xx: self.xx + o.xx,
            yy: self.yy + o.yy,
            zz: self.zz + o.zz,
            xy: self.xy + o.xy,
            xz: self.xz + o.xz,
            yz: self.yz + o.yz,
        }
    }
}

impl<T: Real> AddAssign for Sym3<T> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<T: Real> Mul<T> for Sym3<T> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: T) -> Self {
        Self {
            xx: self.xx * s,
            yy: self.yy * s,
            zz: self.zz * s,
            xy: self.xy * s,
            xz: self.xz * s,
            yz: self.yz * s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_times_matrix_is_identity() {
        let m = Sym3 { xx: 4.0, yy: 3.0, zz: 2.0, xy: 1.0, xz: 0.5, yz: -0.25 };
        let inv = m.inverse();
        for e in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0)] {
            let back = m.apply(inv.apply(e));
            assert!((back - e).length() < 1e-14, "{back:?} != {e:?}");
        }
    }

    #[test]
    fn singular_matrix_falls_back_to_its_diagonal() {
        let m = Sym3::outer(Vec3::new(1.0, 0.0, 0.0)) * 2.0;
        let inv = m.inverse();
        assert_eq!(inv.apply(Vec3::new(1.0, 1.0, 1.0)), Vec3::new(0.5, 0.0, 0.0));
    }
}
