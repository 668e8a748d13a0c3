//! A compiled scene: the stages it needs, its state, and the step that advances it.
//!
//! A step runs, in a fixed order, only the stages the scene has: force accumulation (gravity,
//! drag, springs, bending, wind) and integration (the integrator evaluates the forces as often as it
//! needs, at the times it needs), then the strain limit, self-collision, the colliders, and the
//! stability watch. Self-collision runs before the colliders so that its small pushes can never
//! leave a particle inside a collider. When a stage after the integrator moved particles, the
//! integrator is told, so that nothing it cached goes stale. A step allocates nothing: every
//! buffer is made in [`Simulation::new`].

use glam::DVec3;

use crate::solver::constraints::contacts::{Collider, Contacts, HOLD_STIFFNESS};
use crate::solver::constraints::self_collision::{PairCapReached, SelfCollision};
use crate::solver::constraints::strain_limit::StrainLimit;
use crate::solver::diagnostics::{self, Energy};
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::forces::springs;
use crate::solver::forces::wind::WindConfig;
use crate::solver::integrators::implicit::LinearSolveStats;
use crate::solver::integrators::{IntegratorKind, IntegratorSettings, Stepper};
use crate::solver::interrupt::Interrupt;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::model::Model;
use crate::solver::pin_motion::{MovingPins, PinMotion};
use crate::solver::stability::{self, Divergence, DivergenceReason};
use crate::solver::state::State;
use crate::solver::{normals, parallel};

/// Every stage name a simulation or a run can report, in the order a step runs them: the
/// forces, then the constraints and contacts. `normals` is also the per-frame normals a run's
/// output asks for.
pub const STAGE_NAMES: [&str; 15] = [
    "gravity",
    "drag",
    "springs",
    "bending",
    "normals",
    "wind",
    "pin_motion",
    "strain_limit",
    "self_collision",
    "plane",
    "sphere",
    "box",
    "cylinder",
    "mesh",
    "moving_colliders",
];

/// Everything about a run that is not the bodies themselves.
#[derive(Clone, Debug, PartialEq)]
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
    /// Wind, if any.
    pub wind: Option<WindConfig>,
    /// Fixed shapes the particles cannot enter, resolved in this order.
    pub colliders: Vec<Collider>,
    /// The largest strain any spring may end a step with (a positive fraction), if limited.
    pub strain_limit: Option<f64>,
    /// Self-collision thickness, in metres (positive): unjoined particles keep twice it apart.
    pub self_collision: Option<f64>,
    /// Pinned particles carried along motions.
    pub pin_motions: Vec<PinMotion>,
    /// The most candidate pairs self-collision may hold in one step; a step that meets more
    /// fails with [`StepError::LimitReached`].
    pub max_self_collision_pairs: usize,
}

impl Default for Config {
    /// Symplectic Euler at 1 ms, standard gravity, nothing else.
    fn default() -> Self {
        Self {
            integrator: IntegratorKind::SymplecticEuler,
            settings: IntegratorSettings::default(),
            dt: 1e-3,
            gravity: DVec3::new(0.0, -9.81, 0.0),
            drag: 0.0,
            wind: None,
            colliders: Vec::new(),
            strain_limit: None,
            self_collision: None,
            pin_motions: Vec::new(),
            max_self_collision_pairs: usize::MAX,
        }
    }
}

/// Why a step did not complete.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The state blew up.
    #[error("the simulation diverged at step {} (t = {} s): {}", .0.step, .0.time, .0.reason)]
    Diverged(Divergence),
    /// The simulation's [`Interrupt`] was raised; the step was given up part-way.
    #[error("the simulation was interrupted")]
    Interrupted,
    /// Self-collision met more candidate pairs than [`Config::max_self_collision_pairs`] and
    /// left them unresolved: the state is sound, but stepping on is not meaningful.
    #[error("{0}")]
    LimitReached(PairCapReached),
}

impl StepError {
    /// The divergence, if the step diverged.
    pub fn divergence(self) -> Option<Divergence> {
        match self {
            Self::Diverged(d) => Some(d),
            Self::Interrupted | Self::LimitReached(_) => None,
        }
    }
}

/// A scene compiled for stepping in precision `T`.
#[derive(Debug)]
pub struct Simulation<T: Real> {
    dynamics: Dynamics<T>,
    state: State<T>,
    stepper: Stepper<T>,
    strain_limit: Option<StrainLimit<T>>,
    self_collision: Option<SelfCollision<T>>,
    contacts: Option<Contacts<T>>,
    moving_colliders: bool,
    moving_pins: Option<MovingPins>,
    triangles: Vec<[u32; 3]>,
    integrator: IntegratorKind,
    dt: f64,
    h: T,
    steps_taken: u64,
    stable_dt: Option<f64>,
    runaway_limit: f64,
    stages: Vec<&'static str>,
    interrupt: Option<Interrupt>,
}

impl<T: Real> Simulation<T> {
    /// Compiles a model and a configuration into a simulation at time zero.
    pub fn new(model: &Model, config: &Config) -> Self {
        let mut dynamics = Dynamics::new(model, config.gravity, config.drag);
        if let Some(wind) = &config.wind {
            dynamics = dynamics.with_wind(model, wind);
        }
        let n = model.particle_count();
        let mut state = State {
            positions: model.positions.iter().map(|&p| Vec3::from_dvec3(p)).collect(),
            velocities: model.velocities.iter().map(|&v| Vec3::from_dvec3(v)).collect(),
        };
        let moving_pins = MovingPins::new(&config.pin_motions, &model.positions);
        if let Some(pins) = &moving_pins {
            // At rest where the motion starts, moving as it starts.
            pins.place(&mut state, -config.dt, config.dt);
        }
        let strain_limit = config.strain_limit.map(|limit| StrainLimit::new(limit, n));
        let self_collision = config
            .self_collision
            .map(|thickness| SelfCollision::new(model, thickness, config.max_self_collision_pairs));
        let contacts = Contacts::new(&config.colliders, n).map(|c| match config.integrator {
            IntegratorKind::ImplicitEuler => c.with_carried_friction(),
            _ => c,
        });
        if let Some(contacts) = &contacts {
            contacts.project_out(&mut state.positions, &dynamics.inverse_masses);
        }
        let stepper = Stepper::new(config.integrator, &dynamics, config.settings);
        let initial = diagnostics::energy(&dynamics, &state);
        let runaway_limit = stability::runaway_limit(
            initial.kinetic + initial.spring,
            released_energy(model, config.gravity)
                + wind_energy(model, config.wind.as_ref())
                + collider_energy(model, &config.colliders),
        );
        let mut stages: Vec<&'static str> = dynamics.stages().collect();
        stages.extend(moving_pins.as_ref().map(|_| "pin_motion"));
        stages.extend(strain_limit.as_ref().map(|_| "strain_limit"));
        stages.extend(self_collision.as_ref().map(|_| "self_collision"));
        stages.extend(contacts.iter().flat_map(Contacts::stages));
        stages.extend(contacts.as_ref().filter(|c| c.any_moving()).map(|_| "moving_colliders"));
        Self {
            strain_limit,
            self_collision,
            moving_colliders: contacts.as_ref().is_some_and(Contacts::any_moving),
            moving_pins,
            contacts,
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
            interrupt: None,
        }
    }

    /// Gives up any later step as soon as `interrupt` is raised (see [`Interrupt`]).
    pub fn set_interrupt(&mut self, interrupt: Interrupt) {
        self.stepper.set_interrupt(interrupt.clone());
        self.interrupt = Some(interrupt);
    }

    fn interrupted(&self) -> bool {
        self.interrupt.as_ref().is_some_and(Interrupt::is_raised)
    }

    /// Advances one step. After any error the state is not to be used.
    pub fn step(&mut self) -> Result<(), StepError> {
        if self.interrupted() {
            return Err(StepError::Interrupted);
        }
        let t = self.time();
        if let Some(contacts) = &mut self.contacts {
            if contacts.begin_step(&self.state.positions, &mut self.state.velocities, self.h) {
                self.stepper.state_changed();
            }
            if let Some(held) = contacts.held() {
                self.stepper.hold(held, T::from_f64(HOLD_STIFFNESS));
            }
            if self.moving_colliders {
                contacts.move_colliders(t, self.dt);
            }
        }
        let sums = self
            .stepper
            .step(&mut self.state, &mut self.dynamics, t, self.h)
            .map_err(|_| StepError::Interrupted)?;
        let inverse_masses = &self.dynamics.inverse_masses;
        let mut moved = false;
        if let Some(pins) = &self.moving_pins {
            pins.place(&mut self.state, t, self.dt);
            moved = true;
        }
        if let Some(limit) = &mut self.strain_limit {
            let contacts = self.contacts.as_ref();
            moved |= limit.apply(&mut self.state, &self.dynamics.springs, inverse_masses, contacts, self.h);
        }
        if let Some(self_collision) = &mut self.self_collision {
            // A crumpled state can make a pass long: an interruption is not kept waiting for it.
            if self.interrupt.as_ref().is_some_and(Interrupt::is_raised) {
                return Err(StepError::Interrupted);
            }
            moved |=
                self_collision.resolve(&mut self.state, inverse_masses).map_err(StepError::LimitReached)?;
        }
        if let Some(contacts) = &mut self.contacts {
            moved |= contacts.resolve(&mut self.state, inverse_masses);
        }
        if moved {
            self.stepper.state_changed();
        }
        self.steps_taken += 1;
        // The integrator's sums describe the state it left, valid unless a later stage could
        // have changed it.
        let later_stages = self.strain_limit.is_some()
            || self.self_collision.is_some()
            || self.contacts.is_some()
            || self.moving_pins.is_some();
        self.watch(sums.filter(|_| !later_stages)).map_err(StepError::Diverged)
    }

    /// Checks that the state is finite and its kinetic energy within the scene's means, from
    /// `Σ m |v|²` and the sum of every position component when the step already summed them.
    fn watch(&self, sums: Option<(T, T)>) -> Result<(), Divergence> {
        let (twice_kinetic, position_sum) =
            sums.unwrap_or_else(|| watch_sums(&self.dynamics.masses, &self.state));
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

    /// The contacts the next implicit solve holds, when contacts are carried from step to step.
    #[cfg(test)]
    pub(crate) fn held_contacts(&self) -> Option<crate::solver::integrators::implicit::Holds<'_, T>> {
        self.contacts.as_ref().and_then(Contacts::held)
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

    /// The scene's explicit stability bound (see [`stable_step`](stability::stable_step)), scaled
    /// for this integrator, or `None` when nothing limits the step.
    pub fn stable_dt(&self) -> Option<f64> {
        self.stable_dt.map(|h| h * self.integrator.stability_factor())
    }

    /// The integrator, for tests that look inside it.
    #[cfg(test)]
    pub(crate) fn stepper(&self) -> &crate::solver::integrators::Stepper<T> {
        &self.stepper
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

/// The kinetic energy of every particle moving with the wind at its fastest: `½ Σ m |u|²`.
fn wind_energy(model: &Model, wind: Option<&WindConfig>) -> f64 {
    wind.map_or(0.0, |w| 0.5 * model.total_mass() * w.peak_speed().powi(2))
}

/// The kinetic energy of every particle leaving a moving collider at twice the fastest speed of
/// its surface near the particles (a perfectly elastic bounce off a moving wall doubles the
/// wall's speed).
fn collider_energy(model: &Model, colliders: &[Collider]) -> f64 {
    let reach = model.positions.iter().map(|p| p.length()).fold(1.0, f64::max);
    let peak =
        colliders.iter().filter_map(|c| c.motion.as_ref()).map(|m| m.peak_speed(reach)).fold(0.0, f64::max);
    0.5 * model.total_mass() * (2.0 * peak).powi(2)
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

/// `Σ m |v|²` and the sum of every position component, for the divergence watch. A large state
/// is cut in halves summed side by side on the solver's threads; the cuts depend on the particle
/// count only, so the sums do not depend on the thread count.
fn watch_sums<T: Real>(masses: &[T], state: &State<T>) -> (T, T) {
    let [vx, vy, vz] = state.velocities.axes();
    let [x, y, z] = state.positions.axes();
    sums_in_halves(masses, [vx, vy, vz, x, y, z])
}

/// The most particles [`watch_sums`] adds on one thread.
const WATCH_PIECE: usize = 4 * parallel::MIN_PARTICLES_PER_BAND;

/// [`watch_sums`] of `masses` and the velocities then positions `axes`, in halves.
fn sums_in_halves<T: Real>(masses: &[T], axes: [&[T]; 6]) -> (T, T) {
    if masses.len() <= WATCH_PIECE {
        return lane_sums(masses, axes);
    }
    let middle = (masses.len() / 2).next_multiple_of(LANES);
    let (low, high) = parallel::join(
        || sums_in_halves(&masses[..middle], axes.map(|axis| &axis[..middle])),
        || sums_in_halves(&masses[middle..], axes.map(|axis| &axis[middle..])),
    );
    (low.0 + high.0, low.1 + high.1)
}

/// The watch's sums in eight interleaved lanes, which vectorise, where one running sum would
/// wait on every addition.
fn lane_sums<'a, T: Real>(masses: &[T], [vx, vy, vz, x, y, z]: [&'a [T]; 6]) -> (T, T) {
    let (mass_blocks, _) = masses.as_chunks::<LANES>();
    let blocks =
        |axis: &'a [T]| -> &'a [[T; LANES]] { axis[..mass_blocks.len() * LANES].as_chunks::<LANES>().0 };
    let (bvx, bvy, bvz, bx, by, bz) = (blocks(vx), blocks(vy), blocks(vz), blocks(x), blocks(y), blocks(z));
    let mut kinetic = [T::ZERO; LANES];
    let mut position = [T::ZERO; LANES];
    for (block, m) in mass_blocks.iter().enumerate() {
        let (vx, vy, vz, x, y, z) =
            (&bvx[block], &bvy[block], &bvz[block], &bx[block], &by[block], &bz[block]);
        for lane in 0..LANES {
            kinetic[lane] += m[lane] * (vx[lane] * vx[lane] + vy[lane] * vy[lane] + vz[lane] * vz[lane]);
            position[lane] += x[lane] + y[lane] + z[lane];
        }
    }
    for p in mass_blocks.len() * LANES..masses.len() {
        kinetic[0] += masses[p] * (vx[p] * vx[p] + vy[p] * vy[p] + vz[p] * vz[p]);
        position[0] += x[p] + y[p] + z[p];
    }
    let total = |lanes: [T; LANES]| lanes.into_iter().fold(T::ZERO, |sum, lane| sum + lane);
    (total(kinetic), total(position))
}

/// The lanes of the watch's sums: eight `f32` fill a 256-bit vector register.
const LANES: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn watch_sums_of_a_large_state_are_its_halves_added() {
        let n = 3 * WATCH_PIECE + 13;
        let masses: Vec<f32> = (0..n).map(|p| 1.0 + (p % 7) as f32).collect();
        let state = State {
            positions: (0..n).map(|p| Vec3::new((p % 5) as f32, 0.5, -2.0)).collect(),
            velocities: (0..n).map(|p| Vec3::new(1.0, -((p % 3) as f32), 2.0)).collect(),
        };
        let (kinetic, position) = watch_sums(&masses, &state);
        let exact: f64 = (0..n).map(|p| (1.0 + (p % 7) as f64) * (5.0 + ((p % 3) * (p % 3)) as f64)).sum();
        assert!((kinetic as f64 - exact).abs() < 1e-6 * exact, "{kinetic} against {exact}");
        let exact: f64 = (0..n).map(|p| (p % 5) as f64 - 1.5).sum();
        assert!((position as f64 - exact).abs() < 1e-6 * exact.abs(), "{position} against {exact}");
        let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool");
        assert_eq!(one_thread.install(|| watch_sums(&masses, &state)), (kinetic, position));
    }

    #[test]
    fn watch_sums_add_every_particle_once() {
        // 37 particles: four whole blocks and a remainder.
        let masses: Vec<f64> = (0..37).map(|p| 1.0 + p as f64).collect();
        let state = State {
            positions: (0..37).map(|p| Vec3::new(p as f64, 0.5, -2.0)).collect(),
            velocities: (0..37).map(|p| Vec3::new(1.0, -(p as f64), 2.0)).collect(),
        };
        let (kinetic, position) = watch_sums(&masses, &state);
        // Σ (1 + p)(5 + p²) and Σ (p - 1.5) over p = 0..37, exact in f64.
        let expected_kinetic: f64 = (0..37).map(|p| (1.0 + p as f64) * (5.0 + (p * p) as f64)).sum();
        assert_eq!(kinetic, expected_kinetic);
        assert_eq!(position, 666.0 - 1.5 * 37.0);
    }
}
