//! What accelerates the particles: their masses, gravity, drag, springs and wind.
//!
//! [`Dynamics`] is everything a force evaluation needs besides the state, so that every
//! integrator can evaluate `a(x, v, t)` on any trial state (RK4 evaluates four per step).
//! A force that a scene does not have is `None` and costs nothing. Wind keeps scratch (vertex
//! normals), so an evaluation takes `&mut self`.

use super::grid_springs::{self, GridSprings};
use super::model::{Model, Spring, SpringGrid};
use super::wind::{Wind, WindConfig};
use super::{Real, State, Vec3, springs};

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
    /// The springs no grid covers, evaluated from the list.
    listed_springs: Vec<Spring<T>>,
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
        let grids = grid_springs::grids(model, &springs);
        let listed_springs = springs
            .iter()
            .enumerate()
            .filter(|(k, _)| !grids.iter().any(|g| g.springs().contains(k)))
            .map(|(_, s)| *s)
            .collect();
        Self {
            masses,
            inverse_masses,
            gravity: (gravity != glam::DVec3::ZERO).then(|| Vec3::from_dvec3(gravity)),
            drag: (drag > 0.0).then(|| T::from_f64(drag)),
            springs,
            grids,
            listed_springs,
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
        ]
        .into_iter()
        .flatten()
        .chain(self.wind.iter().flat_map(|w| w.stages().iter().copied()))
    }

    /// Total force on each particle at state `(x, v)` and time `t` (seconds), written into
    /// `forces`.
    pub fn forces(&mut self, x: &[Vec3<T>], v: &[Vec3<T>], t: f64, forces: &mut [Vec3<T>]) {
        let body = self.gravity.unwrap_or(Vec3::ZERO);
        match self.drag {
            Some(drag) => {
                for ((f, &m), &v) in forces.iter_mut().zip(&self.masses).zip(v) {
                    *f = (body - v * drag) * m;
                }
            }
            None => {
                for (f, &m) in forces.iter_mut().zip(&self.masses) {
                    *f = body * m;
                }
            }
        }
        for grid in &mut self.grids {
            grid.add_forces(x, v, &self.masses, forces);
        }
        springs::add_forces(&self.listed_springs, x, v, forces);
        if let Some(wind) = &mut self.wind {
            wind.add_forces(x, v, t, forces);
        }
    }

    /// One symplectic Euler step in a single pass over the particles, for a scene that is one
    /// grid body and nothing else (no other springs, no wind): the forces start in the grid's
    /// per-axis arrays as the body forces, the springs add to them, and the update writes the new
    /// state. Returns the stability watch's sums over the new state (see
    /// [`GridSprings::symplectic_update`]), or `None`, having done nothing, for any other scene.
    pub(crate) fn fused_symplectic_step(&mut self, state: &mut State<T>, h: T) -> Option<(T, T)> {
        let [grid] = self.grids.as_mut_slice() else { return None };
        if self.wind.is_some()
            || !self.listed_springs.is_empty()
            || grid.particles() != (0..self.masses.len())
        {
            return None;
        }
        let body = self.gravity.unwrap_or(Vec3::ZERO);
        let masses = &self.masses;
        match self.drag {
            Some(drag) => {
                grid.load(&state.positions, &state.velocities, masses, |m, v| (body - v * drag) * m)
            }
            None => grid.load(&state.positions, &state.velocities, masses, |m, _| body * m),
        }
        grid.add_springs();
        Some(grid.symplectic_update(
            masses,
            &self.inverse_masses,
            h,
            &mut state.positions,
            &mut state.velocities,
        ))
    }

    /// Acceleration of each particle at state `(x, v)` and time `t`, written into
    /// `accelerations`; zero for pinned particles.
    pub fn accelerations(&mut self, x: &[Vec3<T>], v: &[Vec3<T>], t: f64, accelerations: &mut [Vec3<T>]) {
        self.forces(x, v, t, accelerations);
        for (a, &w) in accelerations.iter_mut().zip(&self.inverse_masses) {
            *a *= w;
        }
    }
}
