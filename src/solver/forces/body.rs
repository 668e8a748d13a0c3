//! Gravity and drag: the forces on each particle in proportion to its mass, which every force
//! evaluation starts from before the springs and wind add theirs.

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;

/// Sets every particle's force to gravity and drag, `(g - drag v) m`, or `g m` without drag.
pub(crate) fn set_forces<T: Real>(
    forces: &mut Vectors<T>,
    v: &Vectors<T>,
    masses: &[T],
    gravity: Option<Vec3<T>>,
    drag: Option<T>,
) {
    let body = gravity.unwrap_or(Vec3::ZERO).to_array();
    for ((f, v), g) in forces.axes_mut().into_iter().zip(v.axes()).zip(body) {
        match drag {
            Some(drag) => {
                for ((f, &m), &v) in f.iter_mut().zip(masses).zip(v) {
                    *f = (g - v * drag) * m;
                }
            }
            None => {
                for (f, &m) in f.iter_mut().zip(masses) {
                    *f = g * m;
                }
            }
        }
    }
}

/// Gravity and drag on a band's rows: what their forces start from.
pub(crate) struct BodyForce<'a, T> {
    /// The band's first particle within the body.
    pub(crate) offset: usize,
    pub(crate) nx: usize,
    pub(crate) v: [&'a [T]; 3],
    pub(crate) masses: &'a [T],
    pub(crate) gravity: [T; 3],
    pub(crate) drag: T,
    /// A force over the body's particles to add, computed before the pass (bending's).
    pub(crate) extra: Option<[&'a [T]; 3]>,
}

impl<T: Real> BodyForce<'_, T> {
    /// `(g - drag v) m` for each particle of `row` (numbered within the band), plus the extra
    /// force if any.
    #[inline]
    pub(crate) fn start(&self, row: usize, force: [&mut [T]; 3]) {
        let cells = self.offset + row * self.nx..self.offset + (row + 1) * self.nx;
        let masses = &self.masses[cells.clone()];
        for (axis, ((f, v), g)) in force.into_iter().zip(self.v).zip(self.gravity).enumerate() {
            for ((f, &v), &m) in f.iter_mut().zip(&v[cells.clone()]).zip(masses) {
                *f = (g - v * self.drag) * m;
            }
            if let Some(extra) = self.extra {
                for (f, &e) in f.iter_mut().zip(&extra[axis][cells.clone()]) {
                    *f += e;
                }
            }
        }
    }
}
