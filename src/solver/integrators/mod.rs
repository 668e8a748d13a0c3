//! Time integrators: how a step turns accelerations into new positions and velocities.
//!
//! Each integrator owns the scratch buffers it needs, allocated once, so that a step allocates
//! nothing. Pinned particles have zero inverse mass, hence zero acceleration and velocity, and
//! every integrator leaves them exactly where they are.
//!
//! For a scene that is one cloth with no other force than gravity, drag and its springs, two
//! integrators run their update inside the grid's force pass, row by row, rather than after it:
//! symplectic Euler in [`fused_symplectic`], RK4's stages in [`rk4`]. The update's arithmetic is
//! that of the unfused path; only the pass that holds it changes.

mod euler;
pub(crate) mod fused_symplectic;
pub(crate) mod implicit;
mod rk4;
mod verlet;

use crate::solver::forces::dynamics::Dynamics;
use crate::solver::interrupt::Interrupt;
use crate::solver::math::real::Real;
use crate::solver::state::State;

pub use implicit::LinearSolveStats;

/// A step given up part-way because its [`Interrupt`] was raised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Interrupted;

/// The integration methods a scene can choose.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IntegratorKind {
    /// Forward Euler: `x += h v`, then `v += h a(x_old, v_old)`. First order; energy grows.
    ExplicitEuler,
    /// Semi-implicit Euler: `v += h a`, then `x += h v`. First order, symplectic.
    SymplecticEuler,
    /// Position Verlet (in velocity form) with a damping factor. Second order.
    Verlet,
    /// Classic fourth-order Runge-Kutta on the whole state. Fourth order.
    Rk4,
    /// Linearised backward Euler (Baraff-Witkin) solved by preconditioned conjugate gradients.
    /// First order; stable at any step.
    ImplicitEuler,
}

impl IntegratorKind {
    /// Every integrator, in the order the public contract lists them.
    pub const ALL: [Self; 5] =
        [Self::ExplicitEuler, Self::SymplecticEuler, Self::Verlet, Self::Rk4, Self::ImplicitEuler];

    /// The name the public contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::ExplicitEuler => "explicit_euler",
            Self::SymplecticEuler => "symplectic_euler",
            Self::Verlet => "verlet",
            Self::Rk4 => "rk4",
            Self::ImplicitEuler => "implicit_euler",
        }
    }

    /// The order of accuracy `p`: the global error shrinks as `hᵖ`.
    pub fn order(self) -> u32 {
        match self {
            Self::ExplicitEuler | Self::SymplecticEuler | Self::ImplicitEuler => 1,
            Self::Verlet => 2,
            Self::Rk4 => 4,
        }
    }

    /// The largest stable step relative to the symplectic-Euler bound of
    /// [`stable_step`](crate::solver::stability::stable_step) on an undamped oscillator: `2√2/ω`
    /// for RK4 against `2/ω`. Explicit Euler is only stable where damping is strong enough and
    /// implicit Euler is stable at any step; both are given the plain bound.
    pub fn stability_factor(self) -> f64 {
        match self {
            Self::Rk4 => std::f64::consts::SQRT_2,
            _ => 1.0,
        }
    }
}

/// Settings of the integrators that have any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegratorSettings {
    /// Verlet's damping factor: the fraction of the drift velocity removed per step (default 0).
    pub verlet_damping: f64,
    /// Implicit Euler's conjugate-gradient tolerance on the relative residual (default 1e-6).
    pub tolerance: f64,
    /// Implicit Euler's conjugate-gradient stop on the reduction of its starting guess's
    /// residual, 0 to solve to `tolerance` (default 0.01; see `implicit::stopping`).
    pub reduction: f64,
    /// Implicit Euler's conjugate-gradient iteration cap per step (default 200).
    pub max_iterations: usize,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        Self { verlet_damping: 0.0, tolerance: 1e-6, reduction: 0.01, max_iterations: 200 }
    }
}

/// An integrator with its scratch buffers.
#[derive(Debug)]
pub(crate) enum Stepper<T> {
    ExplicitEuler(euler::Euler<T>),
    SymplecticEuler(euler::Euler<T>),
    Verlet(verlet::Verlet<T>),
    Rk4(Box<rk4::Rk4<T>>),
    ImplicitEuler(Box<implicit::Implicit<T>>),
}

impl<T: Real> Stepper<T> {
    pub fn new(kind: IntegratorKind, dynamics: &Dynamics<T>, settings: IntegratorSettings) -> Self {
        let n = dynamics.masses.len();
        match kind {
            IntegratorKind::ExplicitEuler => Self::ExplicitEuler(euler::Euler::new(n)),
            IntegratorKind::SymplecticEuler => Self::SymplecticEuler(euler::Euler::symplectic(dynamics)),
            IntegratorKind::Verlet => Self::Verlet(verlet::Verlet::new(n, settings.verlet_damping)),
            IntegratorKind::Rk4 => Self::Rk4(Box::new(rk4::Rk4::new(dynamics))),
            IntegratorKind::ImplicitEuler => {
                Self::ImplicitEuler(Box::new(implicit::Implicit::new(dynamics, settings)))
            }
        }
    }

    /// Advances `state` by one step of `h` seconds from time `t`. When the step could also sum
    /// what the stability watch needs over the new state, it returns those sums (`Σ m |v|²` and
    /// the sum of every position component, in particle order). An implicit step whose solve
    /// was interrupted leaves the state as it was.
    pub fn step(
        &mut self,
        state: &mut State<T>,
        dynamics: &mut Dynamics<T>,
        t: f64,
        h: T,
    ) -> Result<Option<(T, T)>, Interrupted> {
        match self {
            Self::ExplicitEuler(e) => e.explicit_step(state, dynamics, t, h),
            Self::SymplecticEuler(e) => return Ok(e.symplectic_step(state, dynamics, t, h)),
            Self::Verlet(v) => v.step(state, dynamics, t, h),
            Self::Rk4(r) => r.step(state, dynamics, t, h),
            Self::ImplicitEuler(i) => i.step(state, dynamics, t, h)?,
        }
        Ok(None)
    }

    /// Hands the integrators that loop within a step (the implicit solves) a flag that stops
    /// them part-way.
    pub fn set_interrupt(&mut self, interrupt: Interrupt) {
        if let Self::ImplicitEuler(i) = self {
            i.set_interrupt(interrupt);
        }
    }

    /// Holds the particles of `holds` against their surfaces in the next step, for the
    /// integrators that solve (implicit Euler), with the stiffness `stiffness m / h²`; the others
    /// take no notice.
    pub fn hold(&mut self, holds: implicit::Holds<'_, T>, stiffness: T) {
        if let Self::ImplicitEuler(i) = self {
            i.hold(holds, stiffness);
        }
    }

    /// Tells the integrator that something outside it (a constraint, a contact) changed the
    /// state, so that anything it cached from the last step must be recomputed.
    pub fn state_changed(&mut self) {
        if let Self::Verlet(v) = self {
            v.invalidate();
        }
    }

    /// The linear solver's figures, for integrators that solve one.
    pub fn linear_solve_stats(&self) -> Option<LinearSolveStats> {
        match self {
            Self::ImplicitEuler(i) => Some(i.stats()),
            _ => None,
        }
    }
}
