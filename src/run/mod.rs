//! Running one compiled scene: stepping it, recording the frames and fields asked for, and
//! reporting how it went.
//!
//! [`execute`] is synchronous and blocking; the command line calls it directly and the job
//! workers call it on their own threads. It steps in batches, and between batches publishes
//! progress and honours cancellation through a [`Control`] shared with the caller (atomics only,
//! so the step loop takes no lock). Cancellation also reaches inside a step: the simulation holds
//! the control's [`Interrupt`](crate::solver::Interrupt) and gives up its step part-way, and the
//! run ends cancelled with the frames recorded before. Only the fields the scene asks for are
//! computed.
//!
//! With `stop_at_rest` a run ends at the first check (every [`BATCH`] steps, or every
//! [`REST_CHECK_PERIOD`] of simulated time rounded to whole steps if that is fewer, and at each
//! frame) after step 0 at which it is at rest, and rest means rest: every particle is slower than
//! the scene's speed, by its velocity and by its displacement over the last step (a particle that
//! friction holds on a collider can creep with no velocity), and every free (unpinned) particle is
//! balanced, its velocity changed by one whole step (forces, integrator, constraints, contacts) by
//! less than [`Rest::acceleration`] times the step. That residual acceleration
//! `|v(n+1) - v(n)| / dt` is about zero for a particle held still by springs, pins or a collider
//! (contacts are projections, not forces, so the force sum on a particle lying on a surface is not
//! zero, but the step's change of its velocity is), and about `|g|` for a particle just released,
//! so a cloth that starts still is not at rest before it has begun to fall. The positions and
//! velocities of the step before each check are kept in buffers made once before the first step,
//! and only when the scene asks to stop at rest.

mod colliders;
mod control;
mod drape_coefficient;
mod error_estimate;
mod recording;
mod resolution_estimate;
mod schedule;

use std::time::Instant;

pub use colliders::{ColliderShape, RecordedCollider, RigidTransform};
pub use control::Control;
pub use drape_coefficient::{
    MAX_ROW_CROSSINGS_PER_TRIANGLE, MAX_ROWS, RASTER_ERROR_BOUND, drape_coefficient,
};
pub use error_estimate::{
    CompanionStep, ErrorEstimate, EstimateOutcome, companion_step, planned_companion_steps,
};
pub use recording::{Diverged, Frames, Recording, Samples, Stats, Status};
pub use resolution_estimate::ORDER_RANGE;

use glam::DVec3;

use crate::scene::{Compiled, ErrorEstimateName, Field, FrameSelection, Precision};
use crate::solver::{Real, Simulation, State, StepError, Vec3, parallel};
use schedule::FrameSchedule;

/// Steps between checks of cancellation, progress and rest, when no frame falls sooner.
const BATCH: u64 = 64;

/// The simulated time, in seconds, between two checks of rest when it is fewer steps than
/// [`BATCH`]: a run at frame-size steps is checked as often as one recording frames at 30 fps,
/// whether or not it records frames. A check reads the state twice and copies it once, a
/// small part of an implicit step; explicit steps, kept small by stability, mostly reach
/// [`BATCH`] first.
const REST_CHECK_PERIOD: f64 = 1.0 / 30.0;

/// Runs a compiled scene to the end, to divergence, to rest, or until cancelled, with the error
/// estimate the scene asks for. The run executes on the solver's thread pool, so that its bands
/// and its error estimate's companions share the cores without oversubscribing them.
pub fn execute(compiled: &Compiled, control: &Control) -> Recording {
    parallel::install(|| match compiled.error_estimate {
        ErrorEstimateName::None => simulate(compiled, control, true).recording,
        ErrorEstimateName::Resolution => {
            resolution_estimate::execute_with_resolution_estimate(compiled, control)
        }
        method => error_estimate::execute_with_estimate(compiled, control, method),
    })
}

/// Builds what a run of `compiled` builds before its first step (its simulation in the scene's
/// precision, the frame schedule and the recorder's buffers), takes no step, and drops it all.
/// It is what [`execute`] would allocate up front, so that an admitted scene can be checked to
/// build without running it.
pub fn prepare(compiled: &Compiled) {
    fn prepare_in<T: Real>(compiled: &Compiled)
    where
        Samples: From<Vec<T>>,
    {
        let simulation = Simulation::<T>::new(&compiled.model, &compiled.config);
        let schedule = FrameSchedule::new(compiled);
        let recorder = Recorder::<T>::new(compiled, &simulation);
        drop((recorder, schedule, simulation));
    }
    parallel::install(|| match compiled.precision {
        Precision::F32 => prepare_in::<f32>(compiled),
        Precision::F64 => prepare_in::<f64>(compiled),
    })
}

/// A run's recording and, if it finished, the positions it ended with.
struct Outcome {
    recording: Recording,
    final_positions: Option<Vec<DVec3>>,
}

/// One run without an error estimate; `publish_progress` is false for companion runs, which
/// share the caller's cancellation but not its progress.
fn simulate(compiled: &Compiled, control: &Control, publish_progress: bool) -> Outcome {
    match compiled.precision {
        Precision::F32 => simulate_in::<f32>(compiled, control, publish_progress),
        Precision::F64 => simulate_in::<f64>(compiled, control, publish_progress),
    }
}

fn simulate_in<T: Real>(compiled: &Compiled, control: &Control, publish_progress: bool) -> Outcome
where
    Samples: From<Vec<T>>,
{
    let started = Instant::now();
    let mut simulation = Simulation::<T>::new(&compiled.model, &compiled.config);
    simulation.set_interrupt(control.interrupt());
    let schedule = FrameSchedule::new(compiled);
    let mut recorder = Recorder::<T>::new(compiled, &simulation);
    let mut next_frame = 0;
    let mut status = Status::Succeeded;
    let mut divergence = None;
    let mut failure = None;
    let mut rest_time = None;
    let mut rest = compiled.stop_at_rest.map(|speed| Rest::new(compiled, speed, &simulation));
    let steps_between_rest_checks = ((REST_CHECK_PERIOD / simulation.dt()).round() as u64).clamp(1, BATCH);

    loop {
        let taken = simulation.steps_taken();
        if schedule.steps.get(next_frame) == Some(&taken) {
            recorder.record(&simulation, schedule.time_of(taken));
            next_frame += 1;
        }
        if taken >= compiled.steps {
            break;
        }
        if control.is_cancelled() {
            status = Status::Cancelled;
            break;
        }
        if let Some(rest) = &rest
            && taken > 0
            && rest.holds(simulation.state(), simulation.dt(), &compiled.model.pinned)
        {
            rest_time = Some(schedule.time_of(taken));
            if schedule.steps.get(next_frame.wrapping_sub(1)) != Some(&taken) {
                recorder.record(&simulation, schedule.time_of(taken));
            }
            break;
        }
        let batch = if rest.is_some() { steps_between_rest_checks } else { BATCH };
        let target = schedule.steps.get(next_frame).copied().unwrap_or(compiled.steps).min(taken + batch);
        let stepped = match &mut rest {
            // The last step of the batch is taken apart, so that the check after it sees the
            // state it started from.
            Some(rest) => (taken..target - 1).try_for_each(|_| simulation.step()).and_then(|()| {
                rest.remember(simulation.state());
                simulation.step()
            }),
            None => (taken..target).try_for_each(|_| simulation.step()),
        };
        match stepped {
            Ok(()) => {}
            Err(StepError::Diverged(d)) => {
                status = Status::Diverged;
                divergence = Some(d);
                break;
            }
            Err(StepError::Interrupted) => {
                status = Status::Cancelled;
                break;
            }
            Err(StepError::LimitReached(reached)) => {
                status = Status::Failed;
                failure = Some(reached.to_string());
                break;
            }
        }
        if publish_progress {
            control.set_progress(simulation.steps_taken());
        }
    }
    if publish_progress {
        control.set_progress(simulation.steps_taken());
    }

    let finished = status == Status::Succeeded;
    let final_positions: Option<Vec<DVec3>> =
        finished.then(|| simulation.state().positions.iter().map(|p| p.to_dvec3()).collect());
    let drape_coefficient = compiled
        .drape_tester
        .as_ref()
        .zip(final_positions.as_ref())
        .and_then(|(tester, positions)| drape_coefficient(tester, positions, &compiled.model.triangles));
    let stable_dt = simulation.stable_dt();
    let mut stages: Vec<&'static str> = simulation.stages().to_vec();
    let wants_normals =
        compiled.output.fields.contains(&Field::Normals) && compiled.output.frames != FrameSelection::None;
    if wants_normals && !compiled.model.triangles.is_empty() && !stages.contains(&"normals") {
        stages.push("normals");
    }
    let stats = Stats {
        status,
        wall_time_s: started.elapsed().as_secs_f64(),
        steps: simulation.steps_taken(),
        dt: simulation.dt(),
        dt_source: compiled.dt_source,
        integrator: simulation.integrator(),
        precision: compiled.precision,
        stages,
        energy: finished.then(|| simulation.energy()),
        max_strain: finished.then(|| simulation.max_strain()),
        stable_dt,
        diverged: divergence.map(|d| Diverged {
            step: d.step,
            t: d.time,
            reason: d.reason.to_string(),
            suggested_dt: stable_dt.map(|h| 0.5 * h),
        }),
        failure,
        stopped_at_rest: rest_time,
        linear_solver: simulation.linear_solve_stats(),
        error: None,
        drape_coefficient,
    };
    Outcome { recording: recorder.finish(compiled, stats, finished), final_positions }
}

/// What a run that stops at rest checks, and the state it checks against: the rule
/// `stop_at_rest` applies, for any caller stepping a [`Simulation`] itself.
pub struct Rest<T> {
    /// The scene's `stop_at_rest`: every particle must be slower than this, in m/s.
    speed: f64,
    /// The residual acceleration below which a free particle counts as balanced, in m/s²: 1 % of
    /// `|gravity|`, or the speed limit per second (`stop_at_rest` / 1 s) if that is larger, as it
    /// is when there is no gravity. 1 % of `|g|` means the particle's unbalanced force is under a
    /// hundredth of its weight; a particle just released feels all of it. The speed per second
    /// means that left alone the particle stays below the speed limit for at least a second more.
    acceleration: f64,
    /// The state at the start of the last step taken.
    previous: State<T>,
}

impl<T: Real> Rest<T> {
    /// The rule for `compiled` with the speed limit `speed` (m/s), starting from `simulation`'s
    /// state.
    pub fn new(compiled: &Compiled, speed: f64, simulation: &Simulation<T>) -> Self {
        let acceleration = (0.01 * compiled.config.gravity.length()).max(speed / 1.0);
        Self { speed, acceleration, previous: simulation.state().clone() }
    }

    /// Keeps `state` as the start of the next step, which [`holds`](Self::holds) compares with.
    pub fn remember(&mut self, state: &State<T>) {
        self.previous.positions.copy_from(&state.positions);
        self.previous.velocities.copy_from(&state.velocities);
    }

    /// Whether `state`, one step of `dt` after the remembered one, is at rest: every particle
    /// slower than the speed, by its velocity and by its displacement over the step, and every
    /// free particle's velocity changed by less than the acceleration times `dt`.
    ///
    /// The displacement counts because a particle that a collider's friction holds has its
    /// velocity set to the surface's after the step but keeps the step's slide along the surface
    /// (the projection of `solver::constraints::contacts`): such a particle creeps with no
    /// velocity at all.
    pub fn holds(&self, state: &State<T>, dt: f64, pinned: &[bool]) -> bool {
        let speed = T::from_f64(self.speed * self.speed);
        let reach = T::from_f64((self.speed * dt).powi(2));
        let change = (self.acceleration * dt).powi(2);
        let before = &self.previous;
        state.velocities.iter().all(|v| v.length_squared() < speed)
            && state
                .positions
                .iter()
                .zip(before.positions.iter())
                .all(|(x, y)| (x - y).length_squared() < reach)
            && state
                .velocities
                .iter()
                .zip(before.velocities.iter())
                .zip(pinned)
                .all(|((v, u), &pinned)| pinned || (v - u).to_dvec3().length_squared() < change)
    }
}

/// Accumulates the fields of each recorded frame into flat buffers.
struct Recorder<T> {
    frames: FrameBuffers<T>,
    normals_scratch: Vec<Vec3<T>>,
    strain_scratch: Vec<f64>,
}

struct FrameBuffers<T> {
    times: Vec<f64>,
    positions: Option<Vec<T>>,
    velocities: Option<Vec<T>>,
    normals: Option<Vec<T>>,
    energy: Option<Vec<crate::solver::Energy>>,
    strain: Option<Vec<f64>>,
}

impl<T: Real> Recorder<T>
where
    Samples: From<Vec<T>>,
{
    fn new(compiled: &Compiled, simulation: &Simulation<T>) -> Self {
        let records_frames = compiled.output.frames != FrameSelection::None;
        let wants = |f: Field| records_frames && compiled.output.fields.contains(&f);
        let n = compiled.model.particle_count();
        Self {
            frames: FrameBuffers {
                times: Vec::new(),
                positions: wants(Field::Positions).then(Vec::new),
                velocities: wants(Field::Velocities).then(Vec::new),
                normals: wants(Field::Normals).then(Vec::new),
                energy: wants(Field::Energy).then(Vec::new),
                strain: wants(Field::Strain).then(Vec::new),
            },
            normals_scratch: if wants(Field::Normals) { vec![Vec3::ZERO; n] } else { Vec::new() },
            strain_scratch: if wants(Field::Strain) {
                vec![0.0; simulation.dynamics().springs.len()]
            } else {
                Vec::new()
            },
        }
    }

    fn record(&mut self, simulation: &Simulation<T>, t: f64) {
        let f = &mut self.frames;
        f.times.push(t);
        let state = simulation.state();
        if let Some(buffer) = &mut f.positions {
            buffer.extend(state.positions.iter().flat_map(|p| p.to_array()));
        }
        if let Some(buffer) = &mut f.velocities {
            buffer.extend(state.velocities.iter().flat_map(|v| v.to_array()));
        }
        if let Some(buffer) = &mut f.normals {
            simulation.vertex_normals(&mut self.normals_scratch);
            buffer.extend(self.normals_scratch.iter().flat_map(|n| n.to_array()));
        }
        if let Some(buffer) = &mut f.energy {
            buffer.push(simulation.energy());
        }
        if let Some(buffer) = &mut f.strain {
            simulation.spring_strains(&mut self.strain_scratch);
            buffer.extend_from_slice(&self.strain_scratch);
        }
    }

    fn finish(self, compiled: &Compiled, stats: Stats, finished: bool) -> Recording {
        let f = self.frames;
        let has_final = finished && !f.times.is_empty();
        Recording {
            particles: compiled.model.particle_count(),
            springs: compiled.model.springs.len(),
            triangles: compiled.model.triangles.clone(),
            bodies: compiled.bodies.clone(),
            selection: compiled.output.frames,
            frames: Frames {
                times: f.times.clone(),
                positions: f.positions.map(Samples::from),
                velocities: f.velocities.map(Samples::from),
                normals: f.normals.map(Samples::from),
                energy: f.energy,
                strain: f.strain,
            },
            colliders: compiled
                .config
                .colliders
                .iter()
                .enumerate()
                .map(|(index, collider)| {
                    let mut recorded = RecordedCollider::from_solver(index, collider);
                    recorded.frames = collider.motion.as_ref().map(|m| {
                        f.times
                            .iter()
                            .map(|&t| {
                                let at = m.at(t);
                                RigidTransform {
                                    translation: at.translation.to_array(),
                                    rotation: at.rotation.to_array(),
                                }
                            })
                            .collect()
                    });
                    recorded
                })
                .collect(),
            has_final,
            stats,
        }
    }
}

#[cfg(test)]
mod tests;
