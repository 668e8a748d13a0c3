//! Linearised backward Euler (Baraff and Witkin, 1998) with a block-Jacobi preconditioned
//! conjugate-gradient solve.
//!
//! One step solves `(M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f + h ∂f/∂x v)`, then sets `v += Δv` and
//! `x += h v`. The matrix is assembled per spring as a 3×3 block `S = h D + h² K` (damping and
//! stiffness blocks) and applied matrix-free; the drag term adds `h · drag · m` to the mass
//! diagonal. The stiffness block drops its transverse part under compression, so the system is
//! symmetric positive definite and CG converges at any step size. Pinned particles are filtered
//! out of the solve (their rows and columns are held at zero), so they never move. The previous
//! step's `Δv` is the starting guess, which makes slowly changing motion converge in a few
//! iterations.
//!
//! Wind enters the right-hand side at the start of the step but not the matrix: it is weak next
//! to the springs, and its derivative (through the moving normals) is neither symmetric nor cheap.

use super::super::dynamics::Dynamics;
use super::super::springs::{direction, stiffness_block};
use super::super::sym3::Sym3;
use super::super::{Real, State, Vec3, Vectors};
use super::IntegratorSettings;

/// How the conjugate-gradient solves of a run went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinearSolveStats {
    /// The relative residual each solve aims for.
    pub tolerance: f64,
    /// The iteration cap per solve.
    pub max_iterations: usize,
    /// Iterations of the last solve.
    pub last_iterations: usize,
    /// The most iterations any solve took.
    pub most_iterations: usize,
    /// Iterations over all solves.
    pub total_iterations: u64,
    /// Solves that hit the cap before reaching the tolerance.
    pub unconverged_solves: u64,
    /// Relative residual at the end of the last solve.
    pub last_residual: f64,
}

#[derive(Debug)]
pub(crate) struct Implicit<T> {
    /// Per spring: `h D + h² K`.
    blocks: Vec<Sym3<T>>,
    /// Per particle: inverse of the diagonal block of the system (the preconditioner).
    preconditioner: Vec<Sym3<T>>,
    /// Per particle: `m (1 + h · drag)`, the mass part of the diagonal.
    mass_diagonal: Vec<T>,
    /// Per particle: 1 for free, 0 for pinned (the filter).
    free: Vec<T>,
    forces: Vectors<T>,
    rhs: Vec<Vec3<T>>,
    /// The solution `Δv`, kept as the next step's starting guess.
    delta_v: Vec<Vec3<T>>,
    residual: Vec<Vec3<T>>,
    search: Vec<Vec3<T>>,
    preconditioned: Vec<Vec3<T>>,
    product: Vec<Vec3<T>>,
    tolerance: T,
    stats: LinearSolveStats,
}

impl<T: Real> Implicit<T> {
    pub fn new(dynamics: &Dynamics<T>, settings: IntegratorSettings) -> Self {
        let n = dynamics.masses.len();
        let zeros = || vec![Vec3::ZERO; n];
        let free =
            dynamics.inverse_masses.iter().map(|&w| if w > T::ZERO { T::ONE } else { T::ZERO }).collect();
        Self {
            blocks: vec![Sym3::ZERO; dynamics.springs.len()],
            preconditioner: vec![Sym3::ZERO; n],
            mass_diagonal: vec![T::ZERO; n],
            free,
            forces: Vectors::zeros(n),
            rhs: zeros(),
            delta_v: zeros(),
            residual: zeros(),
            search: zeros(),
            preconditioned: zeros(),
            product: zeros(),
            tolerance: T::from_f64(settings.tolerance),
            stats: LinearSolveStats {
                tolerance: settings.tolerance,
                max_iterations: settings.max_iterations,
                ..LinearSolveStats::default()
            },
        }
    }

    pub fn stats(&self) -> LinearSolveStats {
        self.stats
    }

    pub fn step(&mut self, state: &mut State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        self.assemble(state, dynamics, t, h);
        self.solve(dynamics);
        for (p, &dv) in self.delta_v.iter().enumerate() {
            let v = state.velocities.get(p) + dv;
            state.velocities.set(p, v);
            state.positions.set(p, state.positions.get(p) + v * h);
        }
    }

    /// Builds the spring blocks, the preconditioner and the right-hand side
    /// `h f - h² Σ K (v_i - v_j)`, filtered.
    fn assemble(&mut self, state: &State<T>, dynamics: &mut Dynamics<T>, t: f64, h: T) {
        let (x, v) = (&state.positions, &state.velocities);
        dynamics.forces(x, v, t, &mut self.forces);
        let h2 = h * h;
        let drag = dynamics.drag.unwrap_or(T::ZERO);
        for p in 0..x.len() {
            self.mass_diagonal[p] = dynamics.masses[p] * (T::ONE + h * drag);
            self.rhs[p] = self.forces.get(p) * h;
            self.preconditioner[p] = Sym3::identity() * self.mass_diagonal[p];
        }
        for (s, block) in dynamics.springs.iter().zip(&mut self.blocks) {
            let (i, j) = (s.i as usize, s.j as usize);
            let Some((n, l)) = direction(x.get(j) - x.get(i)) else {
                *block = Sym3::ZERO;
                continue;
            };
            let stiffness = stiffness_block(s, n, l);
            *block = Sym3::outer(n) * (h * s.damping) + stiffness * h2;
            let pull = stiffness.apply(v.get(i) - v.get(j)) * h2;
            self.rhs[i] -= pull;
            self.rhs[j] += pull;
            self.preconditioner[i] += *block;
            self.preconditioner[j] += *block;
        }
        for p in 0..x.len() {
            self.preconditioner[p] = self.preconditioner[p].inverse();
            self.rhs[p] *= self.free[p];
            self.delta_v[p] *= self.free[p];
        }
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
        for (q, &f) in self.product.iter_mut().zip(&self.free) {
            *q *= f;
        }
    }

    /// Preconditioned conjugate gradients from the previous solution.
    fn solve(&mut self, dynamics: &Dynamics<T>) {
        let rhs_norm = dot(&self.rhs, &self.rhs).sqrt();
        if rhs_norm == T::ZERO {
            self.delta_v.fill(Vec3::ZERO);
            self.record(0, T::ZERO);
            return;
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
        let target = self.tolerance * rhs_norm;
        let mut iterations = 0;
        let mut residual_norm = dot(&self.residual, &self.residual).sqrt();
        while residual_norm > target && iterations < self.stats.max_iterations {
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
        self.record(iterations, residual_norm / rhs_norm);
    }

    fn precondition(&mut self) {
        for ((z, r), m) in self.preconditioned.iter_mut().zip(&self.residual).zip(&self.preconditioner) {
            *z = m.apply(*r);
        }
    }

    fn record(&mut self, iterations: usize, relative_residual: T) {
        let stats = &mut self.stats;
        stats.last_iterations = iterations;
        stats.most_iterations = stats.most_iterations.max(iterations);
        stats.total_iterations += iterations as u64;
        stats.last_residual = relative_residual.to_f64();
        if relative_residual > self.tolerance {
            stats.unconverged_solves += 1;
        }
    }
}

/// `Σ a·b`, accumulated in `f64` so that `f32` runs keep a usable residual.
fn dot<T: Real>(a: &[Vec3<T>], b: &[Vec3<T>]) -> T {
    T::from_f64(a.iter().zip(b).map(|(a, b)| a.to_dvec3().dot(b.to_dvec3())).sum::<f64>())
}
