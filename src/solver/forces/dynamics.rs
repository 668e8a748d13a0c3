//! What accelerates the particles: their masses, gravity, drag, springs, bending and wind.
//!
//! [`Dynamics`] is everything a force evaluation needs besides the state, so that every
//! integrator can evaluate `a(x, v, t)` on any trial state (RK4 evaluates four per step).
//! A force that a scene does not have is `None` and costs nothing. Wind keeps scratch (vertex
//! normals), so an evaluation takes `&mut self`.

use super::bending::BendingElements;
use super::body;
use super::grid::{self, BodyTerms, GridSprings};
use super::spring_runs::SpringRuns;
use super::wind::{Wind, WindConfig};
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::{Model, Spring, SpringGrid};

/// Particle masses and the forces acting on them.
#[derive(Clone, Debug)]
pub struct Dynamics<T> {
    /// Masses, in kg.
    pub masses: Vec<T>,
    /// Inverse masses, in 1/kg; zero for a pinned particle, which no force moves.
    pub inverse_masses: Vec<T>,
    /// Gravitational acceleration, when not zero.
    pub gravity: Option<Vec3<T>>,
    /// Drag rate in 1/s (force `-drag · m · v`), when positive.
    pub drag: Option<T>,
    /// Every spring.
    pub springs: Vec<Spring<T>>,
    /// The grid bodies whose springs a stencil pass evaluates.
    grids: Vec<GridSprings<T>>,
    /// The springs no grid covers, sorted into runs.
    listed_springs: SpringRuns<T>,
    /// Dihedral bending, when a body bends by hinges.
    pub(crate) bending: Option<BendingElements<T>>,
    /// The bending forces a fused pass starts its rows from (empty without bending).
    bending_forces: Vectors<T>,
    /// Wind on the surface triangles, when the scene has any.
    pub(crate) wind: Option<Wind<T>>,
    /// The model's grid records, for solvers that exploit the grid structure.
    pub(crate) spring_grids: Vec<SpringGrid>,
}

impl<T: Real> Dynamics<T> {
    /// Converts a model's particles and springs, with the given gravity and drag.
    pub fn new(model: &Model, gravity: glam::DVec3, drag: f64) -> Self {
        let masses: Vec<T> = model.masses.iter().map(|&m| T::from_f64(m)).collect();
        let inverse_masses = model
            .masses
            .iter()
            .zip(&model.pinned)
            .map(|(&m, &pinned)| if pinned { T::ZERO } else { T::from_f64(1.0 / m) })
            .collect();
        let springs = model
            .springs
            .iter()
            .map(|s| Spring {
                i: s.i,
                j: s.j,
                rest_length: T::from_f64(s.rest_length),
                stiffness: T::from_f64(s.stiffness),
                damping: T::from_f64(s.damping),
                kind: s.kind,
            })
            .collect::<Vec<_>>();
        let grids = grid::grids(model, &springs);
        let listed: Vec<Spring<T>> = springs
            .iter()
            .enumerate()
            .filter(|(k, _)| !grids.iter().any(|g| g.springs().contains(k)))
            .map(|(_, s)| *s)
            .collect();
        let listed_springs = SpringRuns::new(&listed, model.particle_count());
        Self {
            masses,
            inverse_masses,
            gravity: (gravity != glam::DVec3::ZERO).then(|| Vec3::from_dvec3(gravity)),
            drag: (drag > 0.0).then(|| T::from_f64(drag)),
            springs,
            grids,
            listed_springs,
            bending: BendingElements::new(&model.bending),
            bending_forces: Vectors::zeros(if model.bending.is_empty() { 0 } else { model.particle_count() }),
            wind: None,
            spring_grids: model.grids.clone(),
        }
    }

    /// Adds wind acting on the model's triangles.
    pub fn with_wind(mut self, model: &Model, wind: &WindConfig) -> Self {
        self.wind = Some(Wind::new(wind, &model.triangles, model.particle_count()));
        self
    }

    /// The names of the force stages present, in the order they are applied.
    pub fn stages(&self) -> impl Iterator<Item = &'static str> {
        [
            self.gravity.map(|_| "gravity"),
            self.drag.map(|_| "drag"),
            (!self.springs.is_empty()).then_some("springs"),
            self.bending.as_ref().map(|_| "bending"),
        ]
        .into_iter()
        .flatten()
        .chain(self.wind.iter().flat_map(|w| w.stages().iter().copied()))
    }

    /// Total force on each particle at state `(x, v)` and time `t` (seconds), written into
    /// `forces`.
    pub fn forces(&mut self, x: &Vectors<T>, v: &Vectors<T>, t: f64, forces: &mut Vectors<T>) {
        body::set_forces(forces, v, &self.masses, self.gravity, self.drag);
        for grid in &mut self.grids {
            grid.add_forces(x, v, forces);
        }
        self.listed_springs.add_forces(x, v, forces);
        if let Some(hinges) = &self.bending {
            hinges.add_forces(x, v, forces);
        }
        if let Some(wind) = &mut self.wind {
            wind.add_forces(x, v, t, forces);
        }
    }

    /// Whether this scene's passes can fuse the forces with what an integrator does with them
    /// (see [`fused_grid`](Self::fused_grid)): one grid body that is every particle, and no other
    /// force than gravity, drag, its springs and bending.
    pub(crate) fn has_fused_passes(&self) -> bool {
        matches!(self.grids.as_slice(), [grid] if grid.particles() == (0..self.masses.len()))
            && self.wind.is_none()
            && self.listed_springs.is_empty()
    }

    /// For a scene that [has fused passes](Self::has_fused_passes), its one grid and the
    /// particles' masses, gravity and drag as the grid's passes take them, so that an integrator
    /// can run its update inside the grid's force pass
    /// ([`fused_symplectic`](crate::solver::integrators::fused_symplectic), RK4's stages);
    /// `None` for any other scene. The bending forces at `(x, v)`, when the scene bends by
    /// elements, are evaluated first, in a pass of their own, for the rows to start from.
    pub(crate) fn fused_grid(
        &mut self,
        x: &Vectors<T>,
        v: &Vectors<T>,
    ) -> Option<(&mut GridSprings<T>, BodyTerms<'_, T>)> {
        if !self.has_fused_passes() {
            return None;
        }
        if let Some(bending) = &self.bending {
            self.bending_forces.fill(Vec3::ZERO);
            bending.add_forces(x, v, &mut self.bending_forces);
        }
        let terms = BodyTerms {
            masses: &self.masses,
            inverse_masses: &self.inverse_masses,
            gravity: self.gravity.unwrap_or(Vec3::ZERO),
            drag: self.drag.unwrap_or(T::ZERO),
            extra: self.bending.as_ref().map(|_| self.bending_forces.axes()),
        };
        Some((&mut self.grids[0], terms))
    }

    /// Acceleration of each particle at state `(x, v)` and time `t`, written into
    /// `accelerations`; zero for pinned particles.
    pub fn accelerations(&mut self, x: &Vectors<T>, v: &Vectors<T>, t: f64, accelerations: &mut Vectors<T>) {
        if let Some((grid, inputs)) = self.fused_grid(x, v) {
            // One grid and nothing else: forces and division in one pass over the rows.
            grid.accelerations(&inputs, x, v, accelerations);
            return;
        }
        self.forces(x, v, t, accelerations);
        for axis in accelerations.axes_mut() {
            for (a, &w) in axis.iter_mut().zip(&self.inverse_masses) {
                *a *= w;
            }
        }
    }
}
