//! The implicit system of any spring graph, applied matrix-free from the spring list and solved
//! by conjugate gradients preconditioned with smoothed-aggregation multigrid.
//!
//! This is the general path: chains, lattices, meshes, several bodies, or a cloth joined to
//! other springs. Each spring's block `S = h D + h² K` is built once per step and the product
//! `A x = M x + Σ_s ±S (x_i - x_j)` streams through the spring list. Bending hinges add their
//! constant `h D + h² C` (see [`hinges`](crate::solver::forces::bending)) to the product. The
//! preconditioner is a V-cycle of the [`aggregation`](super::aggregation) hierarchy built from
//! the spring graph and refilled from the step's blocks; the inverse of each particle's diagonal
//! block (block Jacobi) is kept to compare with.

use super::aggregation::{Aggregation, FineSystem};
use super::grid_operator::Field;
use super::stopping::Stopping;
use super::{SolveOutcome, StepInput};
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::forces::springs::{direction, stiffness_block};
use crate::solver::integrators::Interrupted;
use crate::solver::interrupt::Interrupt;
use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;

#[derive(Debug)]
pub(crate) struct SpringListSolver<T> {
    /// Per spring: `h D + h² K`.
    blocks: Vec<Sym3<T>>,
    /// The preconditioner; block Jacobi (`preconditioner`) without it.
    aggregation: Option<Box<Aggregation<T>>>,
    /// Per particle: inverse of the diagonal block of the system.
    preconditioner: Vec<Sym3<T>>,
    /// Per particle: `m (1 + h · drag)`, the mass part of the diagonal.
    mass_diagonal: Vec<T>,
    /// Per particle: 1 for free, 0 for pinned (the filter).
    free: Vec<T>,
    positions: Vec<Vec3<T>>,
    velocities: Vec<Vec3<T>>,
    rhs: Vec<Vec3<T>>,
    /// The solution `Δv`, kept as the next step's starting guess.
    delta_v: Vec<Vec3<T>>,
    residual: Vec<Vec3<T>>,
    search: Vec<Vec3<T>>,
    preconditioned: Vec<Vec3<T>>,
    product: Vec<Vec3<T>>,
    /// The step, for the hinges' part of the product.
    h: T,
    /// Per particle: the hinges' part of the diagonal (the same on each axis).
    hinge_diagonal: Vec<T>,
    /// The blocks of the contacts the step's solve holds, by particle.
    held: Vec<(usize, Sym3<T>)>,
}

impl<T: Real> SpringListSolver<T> {
    pub fn new(dynamics: &Dynamics<T>) -> Self {
        Self::with_aggregation_depth(dynamics, usize::MAX)
    }

    /// The solver preconditioned by an aggregation hierarchy of at most `depth` levels (with
    /// one, a symmetric block Gauss-Seidel sweep).
    pub fn with_aggregation_depth(dynamics: &Dynamics<T>, depth: usize) -> Self {
        let held: Vec<bool> = dynamics.inverse_masses.iter().map(|&w| w == T::ZERO).collect();
        let aggregation =
            Aggregation::with_depth(held.len(), &dynamics.springs, dynamics.bending.as_ref(), &held, depth);
        Self { aggregation: Some(Box::new(aggregation)), ..Self::with_block_jacobi(dynamics) }
    }

    /// The solver preconditioned by block Jacobi.
    pub fn with_block_jacobi(dynamics: &Dynamics<T>) -> Self {
        let n = dynamics.masses.len();
        let zeros = || vec![Vec3::ZERO; n];
        let free =
            dynamics.inverse_masses.iter().map(|&w| if w > T::ZERO { T::ONE } else { T::ZERO }).collect();
        Self {
            aggregation: None,
            blocks: vec![Sym3::ZERO; dynamics.springs.len()],
            preconditioner: vec![Sym3::ZERO; n],
            mass_diagonal: vec![T::ZERO; n],
            free,
            positions: zeros(),
            velocities: zeros(),
            rhs: zeros(),
            delta_v: zeros(),
            residual: zeros(),
            search: zeros(),
            preconditioned: zeros(),
            product: zeros(),
            h: T::ZERO,
            hinge_diagonal: vec![T::ZERO; if dynamics.bending.is_some() { n } else { 0 }],
            held: Vec::with_capacity(n),
        }
    }

    /// Solves the step's system and writes `Δv` into `delta_v`; gives up, writing nothing, as
    /// soon as `interrupt` is raised.
    pub fn solve(
        &mut self,
        input: &StepInput<'_, T>,
        dynamics: &Dynamics<T>,
        stopping: Stopping,
        interrupt: Option<&Interrupt>,
        delta_v: &mut Field<T>,
    ) -> Result<SolveOutcome<T>, Interrupted> {
        self.assemble(input, dynamics, interrupt)?;
        let outcome = self.conjugate_gradients(dynamics, stopping, interrupt)?;
        for (p, dv) in self.delta_v.iter().enumerate() {
            (delta_v[0][p], delta_v[1][p], delta_v[2][p]) = (dv.x, dv.y, dv.z);
        }
        Ok(outcome)
    }

    /// Builds the spring blocks, the preconditioner and the right-hand side
    /// `h f - h² Σ K (v_i - v_j)`, filtered; gives up in the preconditioner's refill as soon as
    /// `interrupt` is raised.
    fn assemble(
        &mut self,
        input: &StepInput<'_, T>,
        dynamics: &Dynamics<T>,
        interrupt: Option<&Interrupt>,
    ) -> Result<(), Interrupted> {
        let h = input.h;
        let at = |field: &Field<T>, p: usize| Vec3::new(field[0][p], field[1][p], field[2][p]);
        for p in 0..self.positions.len() {
            self.positions[p] = at(input.positions, p);
            self.velocities[p] = at(input.velocities, p);
        }
        let (x, v) = (&self.positions, &self.velocities);
        let h2 = h * h;
        let drag = dynamics.drag.unwrap_or(T::ZERO);
        for p in 0..x.len() {
            self.mass_diagonal[p] = dynamics.masses[p] * (T::ONE + h * drag);
            self.rhs[p] = at(input.forces, p) * h;
            self.preconditioner[p] = Sym3::identity() * self.mass_diagonal[p];
        }
        for (s, block) in dynamics.springs.iter().zip(&mut self.blocks) {
            let (i, j) = (s.i as usize, s.j as usize);
            let Some((n, l)) = direction(x[j] - x[i]) else {
                *block = Sym3::ZERO;
                continue;
            };
            let stiffness = stiffness_block(s, n, l);
            *block = Sym3::outer(n) * (h * s.damping) + stiffness * h2;
            let pull = stiffness.apply(v[i] - v[j]) * h2;
            self.rhs[i] -= pull;
            self.rhs[j] += pull;
            self.preconditioner[i] += *block;
            self.preconditioner[j] += *block;
        }
        self.h = h;
        if let Some(hinges) = &dynamics.bending {
            hinges.add_product_points(T::ZERO, h2, v, &mut self.rhs, true);
            let mut diagonal = std::mem::take(&mut self.hinge_diagonal);
            diagonal.fill(T::ZERO);
            hinges.add_diagonal(h2, h, &mut diagonal);
            for (block, &d) in self.preconditioner.iter_mut().zip(&diagonal) {
                *block += Sym3::identity() * d;
            }
            self.hinge_diagonal = diagonal;
        }
        self.held.clear();
        for held in input.held {
            let p = held.particle;
            let (block, pull) = held.terms(self.mass_diagonal[p], x[p], v[p], h);
            self.held.push((p, block));
            self.preconditioner[p] += block;
            self.rhs[p] += pull;
        }
        for p in 0..x.len() {
            self.preconditioner[p] = self.preconditioner[p].inverse();
            self.rhs[p] *= self.free[p];
            self.delta_v[p] *= self.free[p];
        }
        if let Some(aggregation) = &mut self.aggregation {
            let bending = dynamics.bending.as_ref().map(|hinges| (hinges, h2, h));
            let system = FineSystem {
                mass_diagonal: &self.mass_diagonal,
                spring_blocks: &self.blocks,
                bending,
                held_blocks: &self.held,
            };
            aggregation.refill(&system, None, interrupt)?;
        }
        Ok(())
    }

    /// `product = A search`, filtered.
    fn apply_system(&mut self, dynamics: &Dynamics<T>) {
        for ((q, &p), &m) in self.product.iter_mut().zip(&self.search).zip(&self.mass_diagonal) {
            *q = p * m;
        }
        for (s, block) in dynamics.springs.iter().zip(&self.blocks) {
            let (i, j) = (s.i as usize, s.j as usize);
            let d = block.apply(self.search[i] - self.search[j]);
            self.product[i] += d;
            self.product[j] -= d;
        }
        if let Some(hinges) = &dynamics.bending {
            hinges.add_product_points(self.h * self.h, self.h, &self.search, &mut self.product, false);
        }
        for &(p, block) in &self.held {
            self.product[p] += block.apply(self.search[p]);
        }
        for (q, &f) in self.product.iter_mut().zip(&self.free) {
            *q *= f;
        }
    }

    /// Preconditioned conjugate gradients from the previous solution.
    fn conjugate_gradients(
        &mut self,
        dynamics: &Dynamics<T>,
        stopping: Stopping,
        interrupt: Option<&Interrupt>,
    ) -> Result<SolveOutcome<T>, Interrupted> {
        let rhs_norm = dot(&self.rhs, &self.rhs).sqrt();
        if rhs_norm == T::ZERO {
            self.delta_v.fill(Vec3::ZERO);
            return Ok(SolveOutcome { iterations: 0, relative_residual: T::ZERO, reached_target: true });
        }
        // r = b - A x0.
        self.search.copy_from_slice(&self.delta_v);
        self.apply_system(dynamics);
        for ((r, &b), &q) in self.residual.iter_mut().zip(&self.rhs).zip(&self.product) {
            *r = b - q;
        }
        self.precondition();
        self.search.copy_from_slice(&self.preconditioned);
        let mut rz = dot(&self.residual, &self.preconditioned);
        let mut iterations = 0;
        let mut residual_norm = dot(&self.residual, &self.residual).sqrt();
        let target = T::from_f64(stopping.target(rhs_norm.to_f64(), residual_norm.to_f64()));
        while residual_norm > target && iterations < stopping.max_iterations {
            if interrupt.is_some_and(Interrupt::is_raised) {
                return Err(Interrupted);
            }
            self.apply_system(dynamics);
            let curvature = dot(&self.search, &self.product);
            if curvature <= T::ZERO || !curvature.is_finite() {
                break;
            }
            let alpha = rz / curvature;
            for p in 0..self.delta_v.len() {
                self.delta_v[p] += self.search[p] * alpha;
                self.residual[p] -= self.product[p] * alpha;
            }
            self.precondition();
            let rz_next = dot(&self.residual, &self.preconditioned);
            let beta = rz_next / rz;
            rz = rz_next;
            for (s, &z) in self.search.iter_mut().zip(&self.preconditioned) {
                *s = z + *s * beta;
            }
            residual_norm = dot(&self.residual, &self.residual).sqrt();
            iterations += 1;
        }
        Ok(SolveOutcome {
            iterations,
            relative_residual: residual_norm / rhs_norm,
            reached_target: residual_norm <= target,
        })
    }

    fn precondition(&mut self) {
        if let Some(aggregation) = &mut self.aggregation {
            aggregation.apply(&self.residual, &mut self.preconditioned);
            return;
        }
        for ((z, r), m) in self.preconditioned.iter_mut().zip(&self.residual).zip(&self.preconditioner) {
            *z = m.apply(*r);
        }
    }
}

/// `Σ a·b`, accumulated in `f64` so that `f32` runs keep a usable residual.
fn dot<T: Real>(a: &[Vec3<T>], b: &[Vec3<T>]) -> T {
    T::from_f64(a.iter().zip(b).map(|(a, b)| a.to_dvec3().dot(b.to_dvec3())).sum::<f64>())
}

#[cfg(test)]
impl<T: Real> SpringListSolver<T> {
    /// `|b - A Δv| / |b|` of the step's system for a given `Δv`, computed afresh from the spring
    /// list.
    pub fn relative_residual_of(
        &mut self,
        input: &StepInput<'_, T>,
        dynamics: &Dynamics<T>,
        delta_v: &Field<T>,
    ) -> f64 {
        self.assemble(input, dynamics, None).expect("nothing interrupts it");
        for (p, s) in self.search.iter_mut().enumerate() {
            *s = Vec3::new(delta_v[0][p], delta_v[1][p], delta_v[2][p]);
        }
        self.apply_system(dynamics);
        let (mut residual, mut rhs) = (0.0, 0.0);
        for (b, q) in self.rhs.iter().zip(&self.product) {
            residual += (b.to_dvec3() - q.to_dvec3()).length_squared();
            rhs += b.to_dvec3().length_squared();
        }
        (residual / rhs).sqrt()
    }
}
