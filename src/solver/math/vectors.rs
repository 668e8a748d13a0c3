//! Arrays of 3-vectors stored as structure of arrays: one contiguous array per axis.
//!
//! Every per-particle quantity that a step sweeps over (positions, velocities, forces, an
//! integrator's scratch) is a [`Vectors`]. Loops over one axis at a time read consecutive scalars,
//! which the compiler turns into full-width vector instructions, and a row of a cloth is a
//! contiguous run in each axis. The axes lie in one [`Arrays`] block, each starting on a cache
//! line. Code that works one particle at a time uses [`Vectors::get`] and [`Vectors::set`].

use super::real::Real;
use super::vec3::Vec3;
use crate::solver::arrays::Arrays;

/// `len` 3-vectors, stored as three arrays of equal length (x, y, z).
#[derive(Clone, Debug, Default)]
pub struct Vectors<T> {
    axes: Arrays<T, 3>,
}

impl<T: Real> PartialEq for Vectors<T> {
    fn eq(&self, other: &Self) -> bool {
        self.axes() == other.axes()
    }
}

impl<T: Real> Vectors<T> {
    /// `len` zero vectors.
    pub fn zeros(len: usize) -> Self {
        Self { axes: Arrays::zeros(len) }
    }

    /// The number of vectors.
    #[inline]
    pub fn len(&self) -> usize {
        self.axes.len()
    }

    /// Whether there are no vectors.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.axes.is_empty()
    }

    /// Vector `i`.
    #[inline(always)]
    pub fn get(&self, i: usize) -> Vec3<T> {
        let [x, y, z] = self.axes.arrays();
        Vec3::new(x[i], y[i], z[i])
    }

    /// Sets vector `i`.
    #[inline(always)]
    pub fn set(&mut self, i: usize, v: Vec3<T>) {
        let [x, y, z] = self.axes.arrays_mut();
        (x[i], y[i], z[i]) = (v.x, v.y, v.z);
    }

    /// Adds `v` to vector `i`.
    #[inline(always)]
    pub fn add(&mut self, i: usize, v: Vec3<T>) {
        let [x, y, z] = self.axes.arrays_mut();
        x[i] += v.x;
        y[i] += v.y;
        z[i] += v.z;
    }

    /// Subtracts `v` from vector `i`.
    #[inline(always)]
    pub fn sub(&mut self, i: usize, v: Vec3<T>) {
        let [x, y, z] = self.axes.arrays_mut();
        x[i] -= v.x;
        y[i] -= v.y;
        z[i] -= v.z;
    }

    /// Every vector, in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Vec3<T>> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// One axis: 0 for x, 1 for y, 2 for z.
    #[inline]
    pub fn axis(&self, axis: usize) -> &[T] {
        &self.axes[axis]
    }

    /// One axis, to write.
    #[inline]
    pub fn axis_mut(&mut self, axis: usize) -> &mut [T] {
        &mut self.axes[axis]
    }

    /// The three axes.
    #[inline]
    pub fn axes(&self) -> [&[T]; 3] {
        self.axes.arrays()
    }

    /// The three axes, to write.
    #[inline]
    pub fn axes_mut(&mut self) -> [&mut [T]; 3] {
        self.axes.arrays_mut()
    }

    /// Sets every vector to `v`.
    pub fn fill(&mut self, v: Vec3<T>) {
        for (axis, value) in self.axes.iter_mut().zip(v.to_array()) {
            axis.fill(value);
        }
    }

    /// Copies `other`, which has the same length.
    pub fn copy_from(&mut self, other: &Self) {
        for (axis, source) in self.axes.iter_mut().zip(other.axes.iter()) {
            axis.copy_from_slice(source);
        }
    }

    /// The vectors in `range`, as three slices.
    #[inline]
    pub fn range(&self, range: std::ops::Range<usize>) -> [&[T]; 3] {
        self.axes.arrays().map(|axis| &axis[range.clone()])
    }

    /// The vectors in `range`, as three slices to write.
    #[inline]
    pub fn range_mut(&mut self, range: std::ops::Range<usize>) -> [&mut [T]; 3] {
        self.axes.arrays_mut().map(|axis| &mut axis[range.clone()])
    }
}

impl<T: Real> FromIterator<Vec3<T>> for Vectors<T> {
    fn from_iter<I: IntoIterator<Item = Vec3<T>>>(iter: I) -> Self {
        let mut axes: [Vec<T>; 3] = Default::default();
        for v in iter {
            for (axis, value) in axes.iter_mut().zip(v.to_array()) {
                axis.push(value);
            }
        }
        Self { axes: Arrays::from_arrays(axes) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_round_trip_through_their_axes() {
        let mut v: Vectors<f64> = (0..5).map(|i| Vec3::new(i as f64, 10.0 + i as f64, -(i as f64))).collect();
        assert_eq!(v.len(), 5);
        assert_eq!(v.get(3), Vec3::new(3.0, 13.0, -3.0));
        v.add(3, Vec3::new(1.0, 1.0, 1.0));
        v.sub(4, Vec3::new(4.0, 14.0, -4.0));
        assert_eq!(v.axes()[1], &[10.0, 11.0, 12.0, 14.0, 0.0]);
        assert_eq!(v.get(4), Vec3::ZERO);
        let [x, _, z] = v.range(1..3);
        assert_eq!((x, z), (&[1.0, 2.0][..], &[-1.0, -2.0][..]));
        v.fill(Vec3::splat(2.0));
        assert!(v.iter().all(|e| e == Vec3::splat(2.0)));
    }
}
