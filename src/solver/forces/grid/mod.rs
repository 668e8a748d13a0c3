//! The springs of a cloth evaluated as row stencils: the fast force pass for grid bodies.
//!
//! A grid body's springs are a few stencil families ([`layout`]). Each pass sweeps its rows in
//! order ([`kernel`]), in bands of rows on the solver's threads ([`bands`]), and hands every
//! row's force, once complete, to a sink ([`sinks`]): into a forces array, into accelerations, or
//! into an integrator's update fused into the pass (symplectic Euler in
//! [`fused_symplectic`](crate::solver::integrators::fused_symplectic), RK4's stages in
//! [`rk4`](crate::solver::integrators::rk4)).
//!
//! The result is the same force as the general spring-list loop, summed in a different, fixed
//! order: deterministic, and equal to it up to rounding.

pub(crate) mod bands;
pub(crate) mod kernel;
mod layout;
pub(crate) mod sinks;

#[cfg(test)]
mod tests;

use std::ops::Range;

use crate::solver::forces::body::BodyForce;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::{Model, Spring, SpringGrid};
use bands::{Band, Sharing, in_bands};
use layout::Layout;
use sinks::{AccelerationRows, Accelerations, AddTo, Store};

/// A cloth body whose springs are evaluated by stencil, with its per-band scratch.
#[derive(Clone, Debug)]
pub(crate) struct GridSprings<T> {
    first: usize,
    springs: Range<usize>,
    pub(crate) layout: Layout<T>,
    bands: Vec<Band<T>>,
    /// For a grid whose bands are optional, the one band it runs in while no other thread takes
    /// a band (empty otherwise).
    whole: Vec<Band<T>>,
    /// For such a grid, whether its next pass runs in bands.
    sharing: Option<Sharing>,
}

/// What the body forces and the accelerations need from outside the grid: the particles'
/// masses, gravity, the drag rate and any force computed before the pass.
pub(crate) struct BodyTerms<'a, T> {
    pub masses: &'a [T],
    pub inverse_masses: &'a [T],
    pub gravity: Vec3<T>,
    pub drag: T,
    /// Forces over every particle the rows start from besides gravity and drag (bending's).
    pub extra: Option<[&'a [T]; 3]>,
}

impl<T: Real> GridSprings<T> {
    /// The grid's stencil evaluator, if `springs[grid.springs]` are exactly the springs its stencil
    /// generates (see [`Layout::of`]); `None` otherwise, and the springs stay on the general path.
    pub fn new(grid: &SpringGrid, springs: &[Spring<T>]) -> Option<Self> {
        let layout = Layout::of(grid, springs)?;
        let (needed, optional) = bands::band_counts(&layout);
        let (first, springs) = (grid.first_particle, grid.springs.clone());
        Some(if needed == 1 && optional > 1 {
            Self::with_optional_bands(first, springs, layout, optional)
        } else {
            Self::with_bands(first, springs, layout, needed)
        })
    }

    /// The particles of the body.
    pub fn particles(&self) -> Range<usize> {
        self.first..self.first + self.layout.nx * self.layout.ny
    }

    /// The springs of the model's list this body evaluates.
    pub fn springs(&self) -> Range<usize> {
        self.springs.clone()
    }

    /// Adds every spring force of the body to `forces`.
    pub fn add_forces(&mut self, x: &Vectors<T>, v: &Vectors<T>, forces: &mut Vectors<T>) {
        let range = self.particles();
        let (x, v) = (x.range(range.clone()), v.range(range.clone()));
        let nx = self.layout.nx;
        self.pass(|layout, bands| {
            in_bands(bands, nx, forces.range_mut(range), &|band, out| {
                band.sweep(layout, x, v, &mut AddTo { nx, out });
            })
        });
    }

    /// The acceleration of every particle of the body (gravity, drag and the springs, over the
    /// mass; zero for a pinned particle) into `out`, in one pass: the same values, by the same
    /// operations, as the forces pass followed by the division by the masses.
    pub fn accelerations(
        &mut self,
        inputs: &BodyTerms<T>,
        x: &Vectors<T>,
        v: &Vectors<T>,
        out: &mut Vectors<T>,
    ) {
        let range = self.particles();
        self.accelerations_by_rows(inputs, x, v, out.range_mut(range), &Store);
    }

    /// Computes the accelerations of the body's particles row by row, as
    /// [`accelerations`](Self::accelerations) does, and hands each row to `update` with the
    /// row's part of `outputs` (arrays over the body's particles), in the same pass: what an
    /// integrator does with the accelerations costs no pass of its own.
    pub fn accelerations_by_rows<const O: usize>(
        &mut self,
        inputs: &BodyTerms<T>,
        x: &Vectors<T>,
        v: &Vectors<T>,
        outputs: [&mut [T]; O],
        update: &impl AccelerationRows<T, O>,
    ) {
        let range = self.particles();
        let (x, v) = (x.range(range.clone()), v.range(range.clone()));
        let masses = &inputs.masses[range.clone()];
        let inverse_masses = &inputs.inverse_masses[range.clone()];
        let (nx, first) = (self.layout.nx, self.first);
        self.pass(|layout, bands| {
            in_bands(bands, nx, outputs, &|band, outputs| {
                let offset = band.rows.start * nx;
                let gravity = inputs.gravity.to_array();
                let extra = inputs.extra.map(|f| f.map(|axis| &axis[range.clone()]));
                let body = BodyForce { offset, nx, v, masses, gravity, drag: inputs.drag, extra };
                let sink = &mut Accelerations { body, first, inverse_masses, outputs, update };
                band.sweep(layout, x, v, sink);
            })
        });
    }
}

/// The grid records of a model whose springs this module can evaluate.
pub(crate) fn grids<T: Real>(model: &Model, springs: &[Spring<T>]) -> Vec<GridSprings<T>> {
    model.grids.iter().filter_map(|g| GridSprings::new(g, springs)).collect()
}
