//! The implicit system of a single grid cloth, solved by conjugate gradients preconditioned with
//! a multigrid V-cycle.
//!
//! A scene that is one cloth and nothing else (every particle on the grid, every spring from its
//! stencil, one rest length, stiffness and damping per family, one family per offset) has a system that
//! [`GridOperator`] stores as row stencils and [`Multigrid`] inverts approximately in a few
//! products. Block Jacobi's iteration count grows with the stiffness ratio `h² k / m` and with
//! the resolution; one V-cycle removes the error at every wavelength, so the count stays small
//! and nearly independent of both.
//!
//! The V-cycle is always in `f32`. An `f64` run keeps its own `f64` system, on which conjugate
//! gradients computes its products and residuals, and hands the cycle a rounded copy: most of a
//! solve's memory traffic is in the cycle's products, and a preconditioner only has to be about
//! right, so the `f64` solve still reaches its tolerance on its own residual in about the same
//! number of iterations. An `f32` run assembles its system straight into the cycle's fine level.
//!
//! The cycle's fine level is renewed every step, but its coarse levels, whose Galerkin products
//! cost more than the solve's iterations, are refilled only when a solve needs them: at the first
//! step, when the step size changes, and when a solve on older coarse levels has taken
//! [`LAG_SLACK`] iterations more than the last solve that began on coarse levels of its own. That
//! solve then refills them and restarts conjugate gradients from where it is, so a lagging
//! preconditioner costs at most those iterations. After such a solve the next 2, then 4, up to
//! [`MOST_STEPS_REFILLED`] steps refill at their start before one tries older levels again, so
//! that solves which never keep up on older levels (a cloth solved far below the default
//! reduction, whose every solve is long) lose only a slack's iterations now and then. A cycle
//! with older coarse levels is still symmetric; should it stop being definite on a residual,
//! the solve refills them too.

use std::any::{Any, TypeId};

use rayon::prelude::*;

use super::grid_operator::{Family, Field, GridOperator, RightHandSide, zero_field};
use super::level_bending::BendingMatrices;
use super::multigrid::Multigrid;
use super::stopping::Stopping;
use super::{SolveOutcome, StepInput, dot_slices};
use crate::solver::forces::bending::BendingElements;
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::integrators::Interrupted;
use crate::solver::interrupt::Interrupt;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;

#[derive(Debug)]
pub(crate) struct GridSolver<T> {
    /// The step's system, unless `T` is the preconditioner's precision: then the system is the
    /// multigrid's fine level.
    system: Option<GridOperator<T>>,
    families: Vec<Family<T>>,
    base_mass: Vec<T>,
    /// `base_mass (1 + h drag)` for the current step.
    mass: Vec<T>,
    /// The preconditioner, in `f32` whatever `T`: a V-cycle only needs to be roughly right, and
    /// in `f32` it streams half the bytes of an `f64` one. The residual and the products that
    /// conjugate gradients converges on stay in `T`.
    multigrid: Multigrid<f32>,
    pinned: Vec<usize>,
    rhs: Field<T>,
    /// Per family, each spring's right-hand-side term, between the assembly's two passes.
    pull: Vec<Field<T>>,
    /// The solution `Δv`, kept as the next step's starting guess.
    delta_v: Field<T>,
    residual: Field<T>,
    search: Field<T>,
    preconditioned: Field<T>,
    product: Field<T>,
    /// The sums of the pieces of a dot product, three axes of `⌈n / PIECE⌉`.
    pieces: Vec<f64>,
    /// Bending hinges, whose constant block `h D + h² C` is added to every product.
    bending: Option<BendingElements<T>>,
    /// The current step.
    h: T,
    /// Whether the multigrid's coarse levels were refilled from this step's system.
    coarse_fresh: bool,
    /// Iterations of the last solve whose coarse levels were refilled from its own system at its
    /// start, or `None` before the first: a solve on older coarse levels that takes
    /// [`LAG_SLACK`] more refills them and starts again.
    fresh_iterations: Option<usize>,
    /// Solves on older coarse levels that fell behind since the last one that did not.
    fallen_behind: u32,
    /// Steps that refill the coarse levels at their start before one tries older ones again.
    steps_to_refill: usize,
    /// How many times the coarse levels were refilled.
    refills: u64,
}

/// How many iterations more than the last solve on coarse levels of its own system a solve on
/// older ones may take before it refills them and restarts.
const LAG_SLACK: usize = 1;

/// The most steps that refill the coarse levels at their start after a solve on older ones fell
/// behind.
const MOST_STEPS_REFILLED: usize = 32;

impl<T: Real> GridSolver<T> {
    /// The solver for `dynamics`, if it is a single grid cloth as described above.
    pub fn new(dynamics: &Dynamics<T>) -> Option<Self> {
        Self::with_preconditioner(dynamics, true)
    }

    /// The solver for `dynamics` whose V-cycle leaves the bending elements out, as a baseline.
    #[cfg(test)]
    pub fn without_bending_in_the_preconditioner(dynamics: &Dynamics<T>) -> Option<Self> {
        Self::with_preconditioner(dynamics, false)
    }

    /// The solver for `dynamics`; its V-cycle has the bending elements when `bending` and they
    /// reach no further than its stencils.
    fn with_preconditioner(dynamics: &Dynamics<T>, bending: bool) -> Option<Self> {
        let [grid] = dynamics.spring_grids.as_slice() else { return None };
        let [nx, ny] = grid.resolution;
        let n = dynamics.masses.len();
        if grid.first_particle != 0 || nx * ny != n || grid.springs != (0..dynamics.springs.len()) {
            return None;
        }
        let mut families = Vec::with_capacity(grid.stencil.len());
        let mut next = dynamics.springs.iter();
        for &[ai, aj, bi, bj] in &grid.stencil {
            let mut family: Option<Family<T>> = None;
            for j in 0..ny.saturating_sub(aj.max(bj)) {
                for i in 0..nx.saturating_sub(ai.max(bi)) {
                    let s = next.next()?;
                    let (a, b) = ((j + aj) * nx + i + ai, (j + bj) * nx + i + bi);
                    if (s.i as usize, s.j as usize) != (a, b) {
                        return None;
                    }
                    let offset = [bi as isize - ai as isize, bj as isize - aj as isize];
                    // Store every family from its lower particle, so that offsets point forwards.
                    let offset = if offset[1] > 0 || (offset[1] == 0 && offset[0] > 0) {
                        offset
                    } else {
                        [-offset[0], -offset[1]]
                    };
                    let this = Family {
                        offset,
                        rest_length: s.rest_length,
                        stiffness: s.stiffness,
                        damping: s.damping,
                    };
                    match family {
                        None => family = Some(this),
                        Some(f) if f == this => {}
                        Some(_) => return None,
                    }
                }
            }
            families.extend(family);
        }
        let repeated =
            families.iter().enumerate().any(|(k, f)| families[..k].iter().any(|g| g.offset == f.offset));
        if next.next().is_some() || repeated || families.iter().any(|f| f.offset == [0, 0]) {
            return None;
        }
        let pinned: Vec<usize> = (0..n).filter(|&p| dynamics.inverse_masses[p] == T::ZERO).collect();
        let round = |value: T| value.to_f64() as f32;
        let low_families = families
            .iter()
            .map(|f| Family {
                offset: f.offset,
                rest_length: round(f.rest_length),
                stiffness: round(f.stiffness),
                damping: round(f.damping),
            })
            .collect();
        let low_bending = match &dynamics.bending {
            Some(hinges) if bending => BendingMatrices::of_hinges(hinges, nx, ny, &pinned),
            _ => None,
        };
        let multigrid = Multigrid::new(nx, ny, low_families, pinned.clone(), low_bending)?;
        let system = (TypeId::of::<T>() != TypeId::of::<f32>())
            .then(|| GridOperator::new(nx, ny, &families, pinned.clone()));
        if multigrid.fine().is_parallel() {
            // Starts the thread pool now rather than inside a step.
            rayon::current_num_threads();
        }
        Some(Self {
            system,
            pull: families.iter().map(|_| zero_field(n)).collect(),
            families,
            base_mass: dynamics.masses.clone(),
            mass: dynamics.masses.clone(),
            multigrid,
            pinned,
            rhs: zero_field(n),
            delta_v: zero_field(n),
            residual: zero_field(n),
            search: zero_field(n),
            preconditioned: zero_field(n),
            product: zero_field(n),
            pieces: vec![0.0; 3 * n.div_ceil(PIECE)],
            bending: dynamics.bending.clone(),
            h: T::ZERO,
            coarse_fresh: false,
            fresh_iterations: None,
            fallen_behind: 0,
            steps_to_refill: 0,
            refills: 0,
        })
    }

    /// The number of multigrid levels, the fine one included.
    #[cfg(test)]
    pub fn depth(&self) -> usize {
        self.multigrid.depth()
    }

    /// Solves the step's system; `Δv` is then [`delta_v`](Self::delta_v). Gives up, leaving
    /// `Δv` part-way, as soon as `interrupt` is raised.
    pub fn solve(
        &mut self,
        input: &StepInput<'_, T>,
        stopping: Stopping,
        interrupt: Option<&Interrupt>,
    ) -> Result<SolveOutcome<T>, Interrupted> {
        if self.multigrid.fine().is_parallel() {
            // The whole solve runs on one worker of the pool, so that the parallel products in
            // it share work through the workers' own queues: each entry into the pool from
            // outside goes through its shared queue, which allocates a block every 63 entries.
            rayon::scope(|_| self.solve_here(input, stopping, interrupt))
        } else {
            self.solve_here(input, stopping, interrupt)
        }
    }

    fn solve_here(
        &mut self,
        input: &StepInput<'_, T>,
        stopping: Stopping,
        interrupt: Option<&Interrupt>,
    ) -> Result<SolveOutcome<T>, Interrupted> {
        let h = input.h;
        for (rhs, force) in self.rhs.iter_mut().zip(input.forces) {
            for (r, &f) in rhs.iter_mut().zip(force) {
                *r = f * h;
            }
        }
        let scale = T::ONE + h * input.drag;
        for (m, &base) in self.mass.iter_mut().zip(&self.base_mass) {
            *m = base * scale;
        }
        let rhs = RightHandSide { velocities: input.velocities, rhs: &mut self.rhs, pull: &mut self.pull };
        let system = match &mut self.system {
            Some(system) => system,
            None => shared(self.multigrid.fine_mut()),
        };
        system.assemble(input.positions, &self.mass, &self.families, T::ONE, h, Some(rhs));
        let new_step = h != self.h;
        self.h = h;
        if let Some(hinges) = &self.bending {
            hinges.add_velocity_term(h, input.velocities.arrays(), self.rhs.arrays_mut());
        }
        let system = match &mut self.system {
            Some(system) => system,
            None => shared(self.multigrid.fine_mut()),
        };
        for held in input.held {
            let p = held.particle;
            let at = |field: &Field<T>| Vec3::new(field[0][p], field[1][p], field[2][p]);
            let (block, pull) = held.terms(self.mass[p], at(input.positions), at(input.velocities), h);
            system.add_to_diagonal(p, block);
            for (axis, value) in self.rhs.iter_mut().zip(pull.to_array()) {
                axis[p] += value;
            }
        }
        let round = |value: T| value.to_f64() as f32;
        let stale = self.multigrid.assemble_fine::<T>(self.system.as_ref(), round(h), None);
        self.coarse_fresh = false;
        let waiting = self.steps_to_refill > 0;
        self.steps_to_refill = self.steps_to_refill.saturating_sub(1);
        if stale || new_step || waiting || self.fresh_iterations.is_none() {
            self.refill_coarse();
        }
        zero_pinned(&mut self.rhs, &self.pinned);
        zero_pinned(&mut self.delta_v, &self.pinned);
        self.conjugate_gradients(stopping, interrupt)
    }

    fn refill_coarse(&mut self) {
        self.multigrid.refill_coarse();
        self.coarse_fresh = true;
        self.refills += 1;
    }

    /// How many times the coarse levels were refilled, over all solves.
    #[cfg(test)]
    pub fn refills(&self) -> u64 {
        self.refills
    }

    /// `z = B r` by one V-cycle, and `r·z`.
    fn precondition(&mut self) -> f64 {
        self.multigrid.precondition(&mut self.residual, &mut self.preconditioned);
        let parallel = self.multigrid.fine().is_parallel();
        dot_pieces(&self.residual, &self.preconditioned, &mut self.pieces, parallel)
    }

    /// The last solution.
    pub fn delta_v(&self) -> &Field<T> {
        &self.delta_v
    }

    fn conjugate_gradients(
        &mut self,
        stopping: Stopping,
        interrupt: Option<&Interrupt>,
    ) -> Result<SolveOutcome<T>, Interrupted> {
        let parallel = self.multigrid.fine().is_parallel();
        let pieces = &mut self.pieces;
        let rhs_norm = dot_pieces(&self.rhs, &self.rhs, pieces, parallel).sqrt();
        if rhs_norm == 0.0 {
            for axis in &mut self.delta_v {
                axis.fill(T::ZERO);
            }
            return Ok(SolveOutcome { iterations: 0, relative_residual: T::ZERO, reached_target: true });
        }
        // r = b - A x0 from the previous step's solution.
        system(&self.system, &self.multigrid).residual(&self.rhs, &self.delta_v, &mut self.residual);
        if let Some(hinges) = &self.bending {
            let (a, b) = (T::ZERO - self.h * self.h, T::ZERO - self.h);
            hinges.add_product(a, b, self.delta_v.arrays(), self.residual.arrays_mut());
            zero_pinned(&mut self.residual, &self.pinned);
        }
        let mut residual_norm = dot_pieces(&self.residual, &self.residual, pieces, parallel).sqrt();
        let target = stopping.target(rhs_norm, residual_norm);
        let mut iterations = 0;
        // The iteration at which conjugate gradients last (re)started, with a fresh search
        // direction: at the start, or when the coarse levels were refilled part-way.
        let mut start = 0;
        let lag_limit = self.fresh_iterations.map_or(usize::MAX, |n| n + LAG_SLACK);
        let mut rz = 0.0;
        while residual_norm > target && iterations < stopping.max_iterations {
            if interrupt.is_some_and(Interrupt::is_raised) {
                return Err(Interrupted);
            }
            let mut rz_next = self.precondition();
            // Older coarse levels that slow the solve, or no longer make the cycle definite,
            // are refilled, and the solve restarts from where it is.
            let definite = rz_next > 0.0;
            if !self.coarse_fresh && (iterations >= lag_limit || !definite) {
                self.fallen_behind += 1;
                self.steps_to_refill = 1usize
                    .checked_shl(self.fallen_behind)
                    .map_or(MOST_STEPS_REFILLED, |n| n.min(MOST_STEPS_REFILLED));
                self.refill_coarse();
                start = iterations;
                rz_next = self.precondition();
            }
            // s = z on a (re)start, z + β s after.
            let restart = start == iterations;
            let beta = if restart { T::ZERO } else { T::from_f64(rz_next / rz) };
            let pieces = &mut self.pieces;
            for (s, z) in self.search.iter_mut().zip(&self.preconditioned) {
                let update = |(s, z): (&mut [T], &[T])| {
                    for (s, &z) in s.iter_mut().zip(z) {
                        *s = if restart { z } else { z + *s * beta };
                    }
                };
                if parallel {
                    s.par_chunks_mut(PIECE).zip(z.par_chunks(PIECE)).for_each(update);
                } else {
                    update((s, z));
                }
            }
            rz = rz_next;
            system(&self.system, &self.multigrid).apply(&self.search, &mut self.product);
            if let Some(hinges) = &self.bending {
                hinges.add_product(self.h * self.h, self.h, self.search.arrays(), self.product.arrays_mut());
                zero_pinned(&mut self.product, &self.pinned);
            }
            let curvature = dot_pieces(&self.search, &self.product, pieces, parallel);
            if curvature <= 0.0 || !curvature.is_finite() {
                break;
            }
            let alpha = T::from_f64(rz / curvature);
            // x += α s and r -= α q, with |r|² summed piece by piece as `dot_pieces` does.
            let per_axis = pieces.len() / 3;
            let axes = pieces.chunks_mut(per_axis);
            for (a, sums) in axes.enumerate() {
                let (dv, r) = (&mut self.delta_v[a], &mut self.residual[a]);
                let (s, q) = (&self.search[a], &self.product[a]);
                let update = |((((dv, r), s), q), sum): UpdatePiece<'_, T>| {
                    for p in 0..dv.len() {
                        dv[p] += s[p] * alpha;
                        r[p] -= q[p] * alpha;
                    }
                    *sum = dot_slices(r, r);
                };
                if parallel {
                    dv.par_chunks_mut(PIECE)
                        .zip(r.par_chunks_mut(PIECE))
                        .zip(s.par_chunks(PIECE))
                        .zip(q.par_chunks(PIECE))
                        .zip(sums.par_iter_mut())
                        .for_each(update);
                } else {
                    dv.chunks_mut(PIECE)
                        .zip(r.chunks_mut(PIECE))
                        .zip(s.chunks(PIECE))
                        .zip(q.chunks(PIECE))
                        .zip(sums.iter_mut())
                        .for_each(update);
                }
            }
            residual_norm = pieces.iter().sum::<f64>().sqrt();
            iterations += 1;
        }
        if start == 0 {
            if self.coarse_fresh {
                self.fresh_iterations = Some(iterations);
            } else {
                self.fallen_behind = 0;
            }
        }
        Ok(SolveOutcome {
            iterations,
            relative_residual: T::from_f64(residual_norm / rhs_norm),
            reached_target: residual_norm <= target,
        })
    }
}

/// One piece of CG's update: `Δv` and `r` to update from `s` and `A s`, and the sum of `r·r`.
type UpdatePiece<'a, T> = ((((&'a mut [T], &'a mut [T]), &'a [T]), &'a [T]), &'a mut f64);

/// Fields are summed in pieces of this many entries per axis, each piece's sum in `f64` by
/// [`dot_slices`], the pieces' sums then added in order: the pieces do not depend on the number
/// of threads, so neither do the bits.
const PIECE: usize = 4096;

/// `Σ a·b` over the three axes, by pieces (see [`PIECE`]), on the pool's threads when
/// `parallel`; `pieces` holds the pieces' sums.
fn dot_pieces<T: Real>(a: &Field<T>, b: &Field<T>, pieces: &mut [f64], parallel: bool) -> f64 {
    let per_axis = pieces.len() / 3;
    for ((a, b), sums) in a.iter().zip(b).zip(pieces.chunks_mut(per_axis)) {
        let piece = |((a, b), sum): ((&[T], &[T]), &mut f64)| *sum = dot_slices(a, b);
        if parallel {
            a.par_chunks(PIECE).zip(b.par_chunks(PIECE)).zip(sums.par_iter_mut()).for_each(piece);
        } else {
            a.chunks(PIECE).zip(b.chunks(PIECE)).zip(sums.iter_mut()).for_each(piece);
        }
    }
    pieces.iter().sum()
}

/// The step's system: its own operator, or the multigrid's fine level when `T` is `f32`.
fn system<'a, T: Real>(
    own: &'a Option<GridOperator<T>>,
    multigrid: &'a Multigrid<f32>,
) -> &'a GridOperator<T> {
    match own {
        Some(system) => system,
        None => (multigrid.fine() as &dyn Any).downcast_ref().expect("the system is the fine level"),
    }
}

/// The multigrid's fine level as the step's system, when `T` is `f32`.
fn shared<T: Real>(fine: &mut GridOperator<f32>) -> &mut GridOperator<T> {
    (fine as &mut dyn Any).downcast_mut().expect("the system is the fine level")
}

fn zero_pinned<T: Real>(field: &mut Field<T>, pinned: &[usize]) {
    for axis in field.iter_mut() {
        for &p in pinned {
            axis[p] = T::ZERO;
        }
    }
}
