//! The floating-point precision a simulation runs in.
//!
//! Every solver type is generic over [`Real`], implemented for `f32` and `f64`, so that one code
//! path serves both precisions. Scenes are built in `f64` and converted once, when a
//! [`Simulation`](crate::solver::simulation::Simulation) is created.

use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A floating-point scalar the solver can run in: `f32` or `f64`.
pub trait Real:
    Copy
    + Debug
    + Default
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Sum
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// The precision's name as the public contract spells it (`"f32"`, `"f64"`).
    const NAME: &'static str;

    /// Converts from `f64`, rounding to nearest.
    fn from_f64(value: f64) -> Self;
    /// Converts to `f64` exactly.
    fn to_f64(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Whether the value is neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// The larger of two values (NaN-ignoring, as `f64::max`).
    fn max(self, other: Self) -> Self;
    /// The smaller of two values (NaN-ignoring, as `f64::min`).
    fn min(self, other: Self) -> Self;
    /// `self * a + b` with one rounding (a fused multiply-add where the target has one).
    fn mul_add(self, a: Self, b: Self) -> Self;

    /// The smallest velocity a step keeps, in m/s: the square root of the smallest normal number
    /// (about 1e-19 in `f32`, 1e-154 in `f64`), so that a kept velocity times any other quantity
    /// of the step stays a normal number.
    const SMALLEST_SPEED: Self;

    /// A velocity component as a step stores it: zero when its magnitude is below
    /// [`SMALLEST_SPEED`](Self::SMALLEST_SPEED).
    ///
    /// A motion spreading into particles at exact rest (a cloth released flat) reaches them with
    /// velocities that shrink by orders of magnitude per particle. Unflushed, they run down
    /// through the subnormal numbers, on which x86 processors can take a slow path that comes to
    /// dominate the step (`docs/decisions.md`); flushed, the motion's front stops where it is far
    /// below anything the state can show.
    #[inline(always)]
    fn kept_speed(self) -> Self {
        if self.abs() < Self::SMALLEST_SPEED { Self::ZERO } else { self }
    }
}

macro_rules! impl_real {
    ($t:ty, $name:literal, $smallest:literal) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const NAME: &'static str = $name;
            const SMALLEST_SPEED: Self = $smallest;

            #[inline(always)]
            fn from_f64(value: f64) -> Self {
                value as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                <$t>::max(self, other)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                <$t>::min(self, other)
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                <$t>::mul_add(self, a, b)
            }
        }
    };
}

impl_real!(f32, "f32", 1.0842022e-19);
impl_real!(f64, "f64", 1.4916681462400413e-154);

#[cfg(test)]
mod tests {
    use super::Real;

    #[test]
    fn the_smallest_kept_speed_squared_is_the_smallest_normal_number() {
        assert_eq!(f32::SMALLEST_SPEED * f32::SMALLEST_SPEED, f32::MIN_POSITIVE);
        assert_eq!(f64::SMALLEST_SPEED * f64::SMALLEST_SPEED, f64::MIN_POSITIVE);
    }

    #[test]
    fn speeds_below_the_smallest_become_zero_and_nothing_else_changes() {
        let smallest = f32::SMALLEST_SPEED;
        for kept in [smallest, -smallest, 1e-3, -2.5, f32::INFINITY] {
            assert_eq!(kept.kept_speed(), kept);
        }
        for dropped in [smallest * 0.99, -smallest * 0.5, 1e-30, f32::MIN_POSITIVE / 4.0, -0.0] {
            assert_eq!(dropped.kept_speed().to_bits(), 0, "{dropped:e}");
        }
        assert!(f32::NAN.kept_speed().is_nan(), "a NaN stays for the watch to see");
    }
}
