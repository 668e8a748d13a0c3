//! Linearised backward Euler (Baraff and Witkin, 1998) with a preconditioned conjugate-gradient
//! solve.
//!
//! One step solves `(M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f + h ∂f/∂x v)`, then sets `v += Δv` and
//! `x += h v`. Per spring the system has the 3×3 block `S = h D + h² K` (damping and stiffness
//! blocks); drag adds `h · drag · m` to the mass diagonal. The stiffness block drops its
//! transverse part while a spring is compressed, where it is negative
//! ([`stiffness_block`](crate::solver::forces::springs::stiffness_block)), so the system is
//! symmetric positive definite, CG converges at any step size, and a compressed fold's push
//! outward is taken explicitly, as the force has it. Pinned particles are filtered out of the
//! solve (their rows and columns are held at zero), so they never move. The previous step's `Δv`
//! is the starting guess (zero for the first). A solve runs until its residual is below
//! `reduction` (default 0.01) times that guess's residual, which keeps its error a fraction of the
//! step's own ([`stopping`]; the first solve goes without), or below `tolerance` (default 1e-6)
//! times the right-hand side's norm, or to the iteration cap.
//!
//! Two solvers share this step:
//! - a scene that is one grid cloth ([`grid_solver`]) stores the system as row stencils
//!   ([`grid_operator`]) and preconditions with a geometric multigrid V-cycle ([`multigrid`]),
//!   which converges in a handful of iterations however stiff the cloth;
//! - any other spring graph ([`spring_list`]) applies the system from the spring list and
//!   preconditions with a smoothed-aggregation algebraic multigrid V-cycle ([`aggregation`])
//!   built from the spring graph.
//!
//! The step reads the state and evaluates the forces in one place at its start and writes the
//! state in one place at its end; the solvers work on their own per-axis copies.
//!
//! Wind enters the right-hand side at the start of the step but not the matrix: it is weak next
//! to the springs, and its derivative (through the moving normals) is neither symmetric nor cheap.

mod aggregation;
mod block_sparse;
mod dense_cholesky;
mod galerkin;
mod grid_operator;
mod grid_solver;
mod level_bending;
mod multigrid;
mod spring_list;
mod stopping;
#[cfg(test)]
mod tests;

use super::{IntegratorSettings, Interrupted};
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::interrupt::Interrupt;
use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::state::State;
use grid_operator::{Field, zero_field};
use grid_solver::GridSolver;
use spring_list::SpringListSolver;
use stopping::Stopping;

/// How the conjugate-gradient solves of a run went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinearSolveStats {
    /// The relative residual at which a solve stops.
    pub tolerance: f64,
    /// The reduction of its starting guess's residual at which a solve stops.
    pub reduction: f64,
    /// The iteration cap per solve.
    pub max_iterations: usize,
    /// Iterations of the last solve.
    pub last_iterations: usize,
    /// The most iterations any solve took.
    pub most_iterations: usize,
    /// Iterations over all solves.
    pub total_iterations: u64,
    /// Solves that hit the cap before reaching either target.
    pub unconverged_solves: u64,
    /// Relative residual at the end of the last solve.
    pub last_residual: f64,
}

/// What a solver needs of a step: the state and forces as per-axis copies, the step and drag.
pub(crate) struct StepInput<'a, T> {
    pub positions: &'a Field<T>,
    pub velocities: &'a Field<T>,
    pub forces: &'a Field<T>,
    pub h: T,
    pub drag: T,
    /// The contacts the solve holds: each particle, its contact normal, and the held spring's
    /// block `κ m n nᵀ` ([`Held`]).
    pub held: &'a [Held<T>],
}

/// A particle the solve holds against a surface: the stiffness `κ m / h²` along the normal `n`,
/// which adds the block `κ m n nᵀ` to the system's diagonal (its mass part scaled as the
/// system's is) and `-κ m (v·n) n` to the right-hand side, so that the particle keeps `1 / (1 +
/// κ)` of the inward motion the solve would give it. A stuck particle is held in all three
/// directions to its anchor `a` instead: the block `κ m I` and `-κ m (v + (x - a) / h)`, the
/// implicit spring `κ m / h² (a - x')` at the step's end `x' = x + h v'`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Held<T> {
    pub particle: usize,
    pub normal: Vec3<T>,
    /// The anchor of a stuck particle.
    pub anchor: Option<Vec3<T>>,
    /// `κ`, the spring's stiffness in units of `m / h²`.
    pub stiffness: T,
}

impl<T: Real> Held<T> {
    /// The block the spring adds to the diagonal of a particle whose system mass (its mass with
    /// drag's share) is `mass`, and what it adds to the right-hand side at position `x` and
    /// velocity `v`, for a step of `h`.
    pub fn terms(&self, mass: T, x: Vec3<T>, v: Vec3<T>, h: T) -> (Sym3<T>, Vec3<T>) {
        let k = self.stiffness * mass;
        match self.anchor {
            Some(anchor) => (Sym3::identity() * k, (v + (x - anchor) * (T::ONE / h)) * (T::ZERO - k)),
            None => (Sym3::outer(self.normal) * k, self.normal * (T::ZERO - k * v.dot(self.normal))),
        }
    }
}

/// The contacts a solve holds: each particle's contact normal (zero where it is not held), and,
/// where contacts carry friction, which held particles are stuck and to which anchors.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Holds<'a, T> {
    pub normals: &'a Vectors<T>,
    pub anchored: Option<(&'a Vectors<T>, &'a [bool])>,
}

impl<'a, T> Holds<'a, T> {
    /// Particles held along `normals`, none stuck.
    #[cfg(test)]
    pub fn along(normals: &'a Vectors<T>) -> Self {
        Self { normals, anchored: None }
    }
}

/// How one solve ended.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SolveOutcome<T> {
    pub iterations: usize,
    pub relative_residual: T,
    /// Whether the residual reached the stopping rule's target (rather than the cap).
    pub reached_target: bool,
}

#[derive(Debug)]
enum Solver<T> {
    Grid(Box<GridSolver<T>>),
    SpringList(Box<SpringListSolver<T>>),
}

#[derive(Debug)]
pub(crate) struct Implicit<T> {
    solver: Solver<T>,
    /// The state and the forces at the start of the step, per axis.
    positions: Field<T>,
    velocities: Field<T>,
    forces: Field<T>,
    /// What `Dynamics::forces` fills.
    particle_forces: Vectors<T>,
    /// `Δv` of the spring-list solver.
    delta_v: Field<T>,
    stopping: Stopping,
    /// Whether a solve has run, so that the next starts from the last step's `Δv`.
    warm: bool,
    stats: LinearSolveStats,
    /// The contacts the next solve holds.
    held: Vec<Held<T>>,
    /// Raised from another thread to give up a solve part-way.
    interrupt: Option<Interrupt>,
}

impl<T: Real> Implicit<T> {
    pub fn new(dynamics: &Dynamics<T>, settings: IntegratorSettings) -> Self {
        let solver = match GridSolver::new(dynamics) {
            Some(grid) => Solver::Grid(Box::new(grid)),
            None => Solver::SpringList(Box::new(SpringListSolver::new(dynamics))),
        };
        Self::with_solver(solver, dynamics, settings)
    }

    /// The spring-list solver preconditioned by block Jacobi whatever the scene, to compare
    /// with.
    #[cfg(test)]
    fn with_spring_list(dynamics: &Dynamics<T>, settings: IntegratorSettings) -> Self {
        let solver = SpringListSolver::with_block_jacobi(dynamics);
        Self::with_solver(Solver::SpringList(Box::new(solver)), dynamics, settings)
    }

    fn with_solver(solver: Solver<T>, dynamics: &Dynamics<T>, settings: IntegratorSettings) -> Self {
        let n = dynamics.masses.len();
        Self {
            solver,
            positions: zero_field(n),
            velocities: zero_field(n),
            forces: zero_field(n),
            particle_forces: Vectors::zeros(n),
            delta_v: zero_field(n),
            stopping: Stopping {
                tolerance: settings.tolerance,
                reduction: settings.reduction,
                max_iterations: settings.max_iterations,
            },
            warm: false,
            stats: LinearSolveStats {
                tolerance: settings.tolerance,
                reduction: settings.reduction,
                max_iterations: settings.max_iterations,
                ..LinearSolveStats::default()
            },
            held: Vec::with_capacity(n),
            interrupt: None,
        }
    }

    /// Gives up any later solve as soon as `interrupt` is raised.
    pub fn set_interrupt(&mut self, interrupt: Interrupt) {
        self.interrupt = Some(interrupt);
    }

    pub fn stats(&self) -> LinearSolveStats {
        self.stats
    }

    /// Holds each particle with a non-zero normal in `holds` against its surface in the next
    /// solve, with the stiffness `stiffness m / h²`: along that normal, or toward its anchor if
    /// it is stuck.
    pub fn hold(&mut self, holds: Holds<'_, T>, stiffness: T) {
        self.held.clear();
        let held = holds.normals.iter().enumerate().filter(|(_, n)| *n != Vec3::ZERO);
        self.held.extend(held.map(|(particle, normal)| {
            let anchor = holds.anchored.filter(|(_, stuck)| stuck[particle]).map(|(a, _)| a.get(particle));
            Held { particle, normal, anchor, stiffness }
        }));
    }

    /// One step; when interrupted, the state is left as it was.
    pub fn step(
        &mut self,
        state: &mut State<T>,
        dynamics: &mut Dynamics<T>,
        t: f64,
        h: T,
    ) -> Result<(), Interrupted> {
        // The one place that reads the state and evaluates the forces.
        dynamics.forces(&state.positions, &state.velocities, t, &mut self.particle_forces);
        let copies = [
            (&mut self.positions, &state.positions),
            (&mut self.velocities, &state.velocities),
            (&mut self.forces, &self.particle_forces),
        ];
        for (field, vectors) in copies {
            for (axis, source) in field.iter_mut().zip(vectors.axes()) {
                axis.copy_from_slice(source);
            }
        }

        let input = StepInput {
            positions: &self.positions,
            velocities: &self.velocities,
            forces: &self.forces,
            h,
            drag: dynamics.drag.unwrap_or(T::ZERO),
            held: &self.held,
        };
        let interrupt = self.interrupt.as_ref();
        // The first solve starts from zero, whose residual is the whole right-hand side rather
        // than the step's error, so it goes to the tolerance.
        let stopping = if self.warm { self.stopping } else { Stopping { reduction: 0.0, ..self.stopping } };
        let (outcome, delta_v) = match &mut self.solver {
            Solver::Grid(grid) => (grid.solve(&input, stopping, interrupt)?, grid.delta_v()),
            Solver::SpringList(list) => {
                (list.solve(&input, dynamics, stopping, interrupt, &mut self.delta_v)?, &self.delta_v)
            }
        };
        self.warm = true;
        record(&mut self.stats, outcome);

        // The one place that writes the state.
        let axes = state.positions.axes_mut().into_iter().zip(state.velocities.axes_mut());
        for ((x, v), dv) in axes.zip(delta_v) {
            for ((x, v), &dv) in x.iter_mut().zip(v.iter_mut()).zip(dv) {
                *v = (*v + dv).kept_speed();
                *x += *v * h;
            }
        }
        Ok(())
    }
}

fn record<T: Real>(stats: &mut LinearSolveStats, outcome: SolveOutcome<T>) {
    {
        stats.last_iterations = outcome.iterations;
        stats.most_iterations = stats.most_iterations.max(outcome.iterations);
        stats.total_iterations += outcome.iterations as u64;
        stats.last_residual = outcome.relative_residual.to_f64();
        if !outcome.reached_target {
            stats.unconverged_solves += 1;
        }
    }
}

/// `Σ a·b` of two arrays in `f64`, in eight interleaved partial sums (so that the loop
/// vectorises) added in a fixed order: the same inputs always give the same bits.
pub(crate) fn dot_slices<T: Real>(a: &[T], b: &[T]) -> f64 {
    const LANES: usize = 8;
    let mut lanes = [0.0f64; LANES];
    let (a_chunks, b_chunks) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: f64 =
        a_chunks.remainder().iter().zip(b_chunks.remainder()).map(|(&x, &y)| x.to_f64() * y.to_f64()).sum();
    for (x, y) in a_chunks.zip(b_chunks) {
        for k in 0..LANES {
            lanes[k] += x[k].to_f64() * y[k].to_f64();
        }
    }
    lanes.iter().sum::<f64>() + tail
}
