//! What a sweep does with each finished row of forces when no integrator is fused into it: add
//! it to a forces array, or turn it into accelerations and hand them to an [`AccelerationRows`]
//! (which is how an integrator's update is fused into the sweep).
//!
//! The sinks' methods are `#[inline]`: the sweep that calls them once per row lives in another
//! module, hence another codegen unit, and without the hint they would stay calls there.

use std::ops::Range;

use super::kernel::RowSink;
use crate::solver::forces::body::BodyForce;
use crate::solver::math::real::Real;

/// What a pass computing accelerations row by row does with each row of them, given the row's
/// part of its `O` output arrays.
pub(crate) trait AccelerationRows<T, const O: usize>: Sync {
    /// Takes the total force `force` on the particles `particles` (indices into the whole state)
    /// and their inverse masses, with the same particles of each output: their accelerations are
    /// `force * inverse_mass`, which the implementation computes where it uses them.
    fn take(&self, particles: Range<usize>, force: [&[T]; 3], inverse_masses: &[T], outputs: [&mut [T]; O]);
}

/// Writes the accelerations into the three outputs, one per axis.
pub(super) struct Store;

impl<T: Real> AccelerationRows<T, 3> for Store {
    #[inline]
    fn take(&self, _: Range<usize>, force: [&[T]; 3], inverse_masses: &[T], outputs: [&mut [T]; 3]) {
        for (out, f) in outputs.into_iter().zip(force) {
            for ((a, &f), &w) in out.iter_mut().zip(f).zip(inverse_masses) {
                *a = f * w;
            }
        }
    }
}

/// A sink that adds each row's spring forces to a band of a forces array: the row starts from
/// what the array holds (gravity and drag) and is written back complete.
pub(super) struct AddTo<'a, T> {
    pub(super) nx: usize,
    pub(super) out: [&'a mut [T]; 3],
}

impl<T: Real> RowSink<T> for AddTo<'_, T> {
    #[inline]
    fn start(&mut self, row: usize, force: [&mut [T]; 3]) {
        let cells = row * self.nx..(row + 1) * self.nx;
        for (f, out) in force.into_iter().zip(&self.out) {
            f.copy_from_slice(&out[cells.clone()]);
        }
    }

    #[inline]
    fn finish(&mut self, row: usize, force: [&mut [T]; 3]) {
        let cells = row * self.nx..(row + 1) * self.nx;
        for (out, f) in self.out.iter_mut().zip(force) {
            out[cells.clone()].copy_from_slice(f);
        }
    }
}

/// A sink that hands each row's total force, whose accelerations are its force times the inverse
/// mass, to an [`AccelerationRows`].
pub(super) struct Accelerations<'a, T, U, const O: usize> {
    pub(super) body: BodyForce<'a, T>,
    /// The body's first particle in the whole state.
    pub(super) first: usize,
    pub(super) inverse_masses: &'a [T],
    /// The band's outputs.
    pub(super) outputs: [&'a mut [T]; O],
    pub(super) update: &'a U,
}

impl<T: Real, U: AccelerationRows<T, O>, const O: usize> RowSink<T> for Accelerations<'_, T, U, O> {
    #[inline]
    fn start(&mut self, row: usize, force: [&mut [T]; 3]) {
        self.body.start(row, force);
    }

    #[inline]
    fn finish(&mut self, row: usize, force: [&mut [T]; 3]) {
        let nx = self.body.nx;
        let local = row * nx..(row + 1) * nx;
        let cells = self.body.offset + local.start..self.body.offset + local.end;
        let inverse_masses = &self.inverse_masses[cells.clone()];
        let particles = self.first + cells.start..self.first + cells.end;
        let outputs = self.outputs.each_mut().map(|out| &mut out[local.clone()]);
        self.update.take(particles, force.map(|f| &*f), inverse_masses, outputs);
    }
}
