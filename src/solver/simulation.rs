//! A compiled scene: the stages it needs, its state, and the step that advances it.
//!
//! A step runs, in a fixed order, only the stages the scene has: force accumulation and
//! integration (the integrator evaluates the forces as often as it needs), then the stability
//! watch. A step allocates nothing: every buffer is made in [`Simulation::new`].

use glam::DVec3;

use super::diagnostics::{self, Energy};
use super::dynamics::Dynamics;
use super::integrators::{IntegratorKind, IntegratorSettings, LinearSolveStats, Stepper};
use super::model::Model;
use super::stability::{self, Divergence, DivergenceReason};
use super::{Real, State, Vec3, normals, springs};

/// Everything about a run that is not the bodies themselves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// The integration method.
    pub integrator: IntegratorKind,
    /// Settings of the integrators that have any.
    pub settings: IntegratorSettings,
    /// The step, in seconds (positive).
    pub dt: f64,
    /// Gravitational acceleration, in m/s².
    pub gravity: DVec3,
    /// Drag rate, in 1/s: each particle feels `-drag · m · v`.
    pub drag: f64,
}

/// A scene compiled for stepping in precision `T`.
#[derive(Debug)]
pub struct Simulation<T: Real> {
    dynamics: Dynamics<T>,
    state: State<T>,
    stepper: Stepper<T>,
    triangles: Vec<[u32; 3]>,
    integrator: IntegratorKind,
    dt: f64,
    h: T,
    steps_taken: u64,
    stable_dt: Option<f64>,
    runaway_limit: f64,
    stages: Vec<&'static str>,
}

impl<T: Real> Simulation<T> {
    /// Compiles a model and a configuration into a simulation at time zero.
    pub fn new(model: &Model, config: &Config) -> Self {
        let dynamics = Dynamics::new(model, config.gravity, config.drag);
        let state = State {
            positions: model.positions.iter().map(|&p| Vec3::from_dvec3(p)).collect(),
            velocities: model.velocities.iter().map(|&v| Vec3::from_dvec3(v)).collect(),
        };
        let stepper = Stepper::new(config.integrator, &dynamics, config.settings);
        let initial = diagnostics::energy(&dynamics, &state);
        let runaway_limit = stability::runaway_limit(
            initial.kinetic + initial.spring,
            released_energy(model, config.gravity),
        );
        let stages = dynamics.stages().collect();
        Self {
            stable_dt: stability::stable_step(model, config.drag),
            dynamics,
            state,
            stepper,
            triangles: model.triangles.clone(),
            integrator: config.integrator,
            dt: config.dt,
            h: T::from_f64(config.dt),
            steps_taken: 0,
            runaway_limit,
            stages,
        }
    }

    /// Advances one step. On divergence the state is left as it was found, not to be used.
    pub fn step(&mut self) -> Result<(), Divergence> {
        self.stepper.step(&mut self.state, &self.dynamics, self.h);
        self.steps_taken += 1;
        self.watch()
    }

    /// Checks that the state is finite and its kinetic energy within the scene's means.
    fn watch(&self) -> Result<(), Divergence> {
        let mut twice_kinetic = T::ZERO;
        let mut position_sum = T::ZERO;
        for ((&m, v), x) in self.dynamics.masses.iter().zip(&self.state.velocities).zip(&self.state.positions)
        {
            twice_kinetic += m * v.length_squared();
            position_sum += x.x + x.y + x.z;
        }
        let kinetic = 0.5 * twice_kinetic.to_f64();
        let reason = if !kinetic.is_finite() || !position_sum.is_finite() {
            DivergenceReason::NonFinite
        } else if kinetic > self.runaway_limit {
            DivergenceReason::EnergyRunaway { kinetic, limit: self.runaway_limit }
        } else {
            return Ok(());
        };
        Err(Divergence { step: self.steps_taken, time: self.time(), reason })
    }

    /// Simulated time, in seconds: steps taken times the step.
    pub fn time(&self) -> f64 {
        self.steps_taken as f64 * self.dt
    }

    /// Steps taken so far.
    pub fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    /// The step, in seconds.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The integration method.
    pub fn integrator(&self) -> IntegratorKind {
        self.integrator
    }

    /// The current positions and velocities.
    pub fn state(&self) -> &State<T> {
        &self.state
    }

    /// Particle masses and the forces on them.
    pub fn dynamics(&self) -> &Dynamics<T> {
        &self.dynamics
    }

    /// The surface triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The names of the stages a step runs, in order.
    pub fn stages(&self) -> &[&'static str] {
        &self.stages
    }

    /// The scene's explicit stability bound (see [`stable_step`](super::stable_step)), scaled for
    /// this integrator, or `None` when nothing limits the step.
    pub fn stable_dt(&self) -> Option<f64> {
        self.stable_dt.map(|h| h * self.integrator.stability_factor())
    }

    /// The linear solver's figures, for implicit integration.
    pub fn linear_solve_stats(&self) -> Option<LinearSolveStats> {
        self.stepper.linear_solve_stats()
    }

    /// Kinetic, gravitational and spring energy now.
    pub fn energy(&self) -> Energy {
        diagnostics::energy(&self.dynamics, &self.state)
    }

    /// The largest spring strain now.
    pub fn max_strain(&self) -> f64 {
        springs::max_strain(&self.dynamics.springs, &self.state.positions)
    }

    /// Writes the strain of every spring, in spring order.
    pub fn spring_strains(&self, out: &mut [f64]) {
        for (o, s) in out.iter_mut().zip(&self.dynamics.springs) {
            *o = springs::strain(s, &self.state.positions);
        }
    }

    /// Writes the unit normal of every particle (zero off any surface).
    pub fn vertex_normals(&self, out: &mut [Vec3<T>]) {
        normals::vertex_normals(&self.triangles, &self.state.positions, out);
    }
}

/// The most energy gravity can release: every particle falling the scene's extent and one metre
/// more.
fn released_energy(model: &Model, gravity: DVec3) -> f64 {
    let (low, high) = model
        .positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let extent = if model.positions.is_empty() { 0.0 } else { (high - low).length() };
    model.total_mass() * gravity.length() * (extent + 1.0)
}
