//! The worker threads that run jobs, and the watchdog that enforces their wall time and holds
//! their leases.
//!
//! Each worker is a plain thread that claims a job from the store, reads and compiles its scene
//! (or takes the model compiled at admission, see [`handoff`](super::handoff)), runs it with
//! [`run::execute`](crate::run::execute) inside `catch_unwind` (so a panic fails that job alone),
//! encodes the result and stores it. A claim is committed before the job starts; a worker whose
//! claim fails backs off and starts nothing, and a claimed job this instance already runs (its
//! lease lapsed while the store failed) is not started a second time. "job ended" is logged once
//! the end is committed. Workers talk to the async store by blocking on the
//! runtime's handle, which is allowed because they are not runtime threads; the solver's step
//! loop never touches the store. The watchdog thread wakes many times a second: it cancels,
//! through their `Control`, jobs past their wall time (the worker then marks them failed), and
//! every [`RENEW_PERIOD`] renews the leases of running jobs, copies their progress to the store
//! and stops those cancelled through another instance or no longer this instance's; it does the
//! same for the batches of sweep runs ([`sweep_work`](super::sweep_work)), which a worker takes
//! when no job is queued.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::encode::{EncodingCancelled, encode_result};
use super::id::JobId;
use super::live::Live;
use super::record::now_ms;
use super::shared::Shared;
use super::status::{Failure, JobStatus};
use super::store::{Claim, Claimed, Outcome, Renewed, StoredResult};
use super::sweep_live::Batch;
use super::sweep_work::run_sweep_batch;
use crate::output::stats_json;
use crate::run::{Status, execute};
use crate::scene::{Compiled, Scene};

/// How often the watchdog checks deadlines.
const WATCHDOG_PERIOD: Duration = Duration::from_millis(25);
/// How often leases are renewed and progress copied to the store; a cancellation asked of
/// another instance reaches the job within this.
pub(super) const RENEW_PERIOD: Duration = Duration::from_millis(250);

/// The longest a worker waits before trying the store again after a failed claim.
const MOST_BACKOFF: Duration = Duration::from_secs(5);

/// Starts `count` workers.
pub(super) fn spawn_workers(shared: &Arc<Shared>, count: usize) -> Vec<JoinHandle<()>> {
    (0..count)
        .map(|n| {
            let shared = Arc::clone(shared);
            std::thread::Builder::new()
                .name(format!("drape-worker-{n}"))
                .spawn(move || work(&shared))
                .expect("the operating system can start a worker thread")
        })
        .collect()
}

/// A worker's loop: claim, run, record, until the job system stops.
fn work(shared: &Shared) {
    let mut backoff = shared.config.idle_poll;
    let mut batch_size = 1;
    while !shared.stopped.load(Ordering::Relaxed) {
        let lease = shared.lease();
        match shared.runtime.block_on(shared.store.claim(&lease, now_ms(), shared.config.max_attempts)) {
            Ok(Some(Claim::Run(claimed))) => {
                backoff = shared.config.idle_poll;
                if shared.is_live(&claimed.record.id) {
                    // Its lease lapsed while this instance ran it (renewals failed), and this
                    // claim took it again: the copy already running keeps it.
                    tracing::warn!(job = %claimed.record.id, "claimed a job this instance already runs; not starting it again");
                } else {
                    run_job(shared, claimed);
                }
            }
            Ok(Some(Claim::GaveUp(record))) => {
                tracing::error!(
                    job = %record.id,
                    attempts = record.attempts,
                    "job failed: it was started --max-attempts times without ending, so it is not run again"
                );
                shared.changed();
            }
            // No job is queued: a batch of a sweep's runs, then the queue again.
            Ok(None) => match run_sweep_batch(shared, batch_size) {
                Ok(Some(next_size)) => {
                    backoff = shared.config.idle_poll;
                    batch_size = next_size;
                }
                Ok(None) => {
                    backoff = shared.config.idle_poll;
                    shared.doorbell.wait(shared.config.idle_poll);
                }
                Err(e) => {
                    tracing::error!(error = %e, retry_in_s = backoff.as_secs_f64(), "cannot claim sweep runs; starting none until a claim is stored");
                    sleep_unless_stopped(shared, backoff);
                    backoff = (backoff * 2).min(MOST_BACKOFF);
                }
            },
            Err(e) => {
                tracing::error!(error = %e, retry_in_s = backoff.as_secs_f64(), "cannot claim a job; starting none until a claim is stored");
                sleep_unless_stopped(shared, backoff);
                backoff = (backoff * 2).min(MOST_BACKOFF);
            }
        }
    }
}

/// Sleeps for `duration`, or less if the job system stops meanwhile.
fn sleep_unless_stopped(shared: &Shared, duration: Duration) {
    let until = Instant::now() + duration;
    while !shared.stopped.load(Ordering::Relaxed) {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return;
        }
        std::thread::sleep(left.min(WATCHDOG_PERIOD));
    }
}

/// Reads a claimed job's stored scene and admits it under this instance's limits.
fn compile(shared: &Shared, scene: &str) -> Result<Compiled, String> {
    let document = serde_json::from_str(scene).map_err(|e| format!("the stored scene is not JSON: {e}"))?;
    let scene = Scene::from_value(document).map_err(|e| format!("the stored scene is not valid: {e}"))?;
    let admitted = shared.config.limits.admit(&scene).map_err(|errors| {
        let reasons: Vec<String> = errors.iter().map(ToString::to_string).collect();
        format!("the scene exceeds this instance's limits: {}", reasons.join("; "))
    })?;
    Ok(admitted.compiled)
}

fn run_job(shared: &Shared, claimed: Claimed) {
    let Claimed { record, scene } = claimed;
    let id = &record.id;
    let live = Arc::new(Live::new(record.plan));
    shared.running.fetch_add(1, Ordering::Relaxed);
    shared.started(id, &live);
    tracing::info!(
        job = %id,
        attempt = record.attempts,
        particles = live.plan.particles,
        steps = live.plan.steps,
        "job started"
    );

    let ran = catch_unwind(AssertUnwindSafe(|| {
        // The model compiled at admission if its submitter waits for it here, else the stored
        // scene compiled now.
        let compiled = match shared.handoff.take(id) {
            Some(compiled) => compiled,
            None => compile(shared, &scene)?,
        };
        if let Some(hook) = &shared.config.before_run {
            hook(&compiled);
        }
        let recording = execute(&compiled, &live.control);
        // A run a client cancelled keeps the frames it made, so its encoding stops only for the
        // wall time or a shutdown; any other run's stops for any cancellation.
        let run_cancelled = recording.stats.status == Status::Cancelled;
        let stop = || {
            if run_cancelled {
                live.timed_out.load(Ordering::Relaxed) || live.shutting_down.load(Ordering::Relaxed)
            } else {
                live.control.is_cancelled()
            }
        };
        let encoded = encode_result(&recording, &compiled.output, &stop);
        let stopped_encoding = encoded.as_ref().is_err_and(|e| EncodingCancelled::is(e) || stop());
        Ok((recording.stats, encoded, stopped_encoding))
    }));

    let steps_done = live.control.steps_done();
    let stopped = |stats: &crate::run::Stats, result| {
        let (status, message) = if live.timed_out.load(Ordering::Relaxed) {
            (
                JobStatus::Failed,
                format!(
                    "the job exceeded the wall-time limit of {} s after {steps_done} of {} steps",
                    shared.config.wall_time.as_secs_f64(),
                    live.plan.steps
                ),
            )
        } else {
            (JobStatus::Cancelled, live.cancel_reason())
        };
        let failure = (status == JobStatus::Failed).then_some(Failure::WallTime);
        let result = if failure.is_none() { result } else { None };
        Outcome {
            status,
            steps_done,
            message: Some(message),
            failure,
            stats: Some(stats_json(stats)),
            result,
        }
    };
    let outcome = match ran {
        Ok(Ok((stats, Ok(result), _))) => match stats.status {
            Status::Succeeded => success(JobStatus::Succeeded, steps_done, None, &stats, result),
            Status::Diverged => {
                let reason = stats.diverged.as_ref().map(|d| d.reason.clone());
                success(JobStatus::Diverged, steps_done, reason, &stats, result)
            }
            Status::Cancelled => stopped(&stats, Some(result)),
            Status::Failed => Outcome {
                status: JobStatus::Failed,
                steps_done,
                message: stats.failure.clone(),
                failure: Some(Failure::Limit),
                stats: Some(stats_json(&stats)),
                result: None,
            },
        },
        // Stopped while encoding: the run's own end no longer matters.
        Ok(Ok((stats, Err(_), true))) => stopped(&stats, None),
        Ok(Ok((_, Err(e), false))) => {
            failed(steps_done, Failure::Encoding, format!("the result could not be encoded: {e}"))
        }
        // A scene that was valid when submitted: another instance with other limits, or a newer
        // drape that reads it differently. Not the client's doing, so it counts as a defect.
        Ok(Err(unreadable)) => failed(0, Failure::Panicked, unreadable),
        Err(panic) => failed(
            steps_done,
            Failure::Panicked,
            format!("the simulation panicked: {}", panic_message(panic.as_ref())),
        ),
    };
    shared.running.fetch_sub(1, Ordering::Relaxed);
    let elapsed = live.started.elapsed();
    // Companion runs of the error estimate are counted when the run finished with them.
    let companions = if outcome.status == JobStatus::Succeeded { live.plan.companion_steps } else { 0 };
    let work = live.plan.particles.saturating_mul(steps_done.saturating_add(companions));
    shared.particle_steps.fetch_add(work, Ordering::Relaxed);
    shared.busy_nanos.fetch_add(elapsed.as_nanos() as u64, Ordering::Relaxed);
    shared.finish(id, &live, outcome);
}

fn success(
    status: JobStatus,
    steps_done: u64,
    message: Option<String>,
    stats: &crate::run::Stats,
    result: StoredResult,
) -> Outcome {
    Outcome {
        status,
        steps_done,
        message,
        failure: None,
        stats: Some(stats_json(stats)),
        result: Some(result),
    }
}

fn failed(steps_done: u64, failure: Failure, message: String) -> Outcome {
    Outcome {
        status: JobStatus::Failed,
        steps_done,
        message: Some(message),
        failure: Some(failure),
        stats: None,
        result: None,
    }
}

fn panic_message(payload: &(dyn Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(no message)")
}

/// Starts the watchdog; it stops once `shared.workers_gone` is set.
pub(super) fn spawn_watchdog(shared: &Arc<Shared>) -> JoinHandle<()> {
    let shared = Arc::clone(shared);
    std::thread::Builder::new()
        .name("drape-watchdog".into())
        .spawn(move || {
            let mut last_renewal = Instant::now();
            while !shared.workers_gone.load(Ordering::Relaxed) {
                std::thread::sleep(WATCHDOG_PERIOD);
                let running: Vec<(JobId, Arc<Live>)> = shared.live_jobs();
                for (_, live) in &running {
                    if live.started.elapsed() > shared.config.wall_time {
                        live.timed_out.store(true, Ordering::Relaxed);
                        live.control.cancel();
                    }
                }
                let batches = shared.batches().clone();
                batches.iter().for_each(|batch| batch.enforce(shared.config.wall_time));
                if last_renewal.elapsed() >= RENEW_PERIOD {
                    last_renewal = Instant::now();
                    for (id, live) in &running {
                        if !live.ending.load(Ordering::Relaxed) {
                            renew(&shared, id, live);
                        }
                    }
                    if !batches.is_empty() {
                        renew_sweep_runs(&shared, &batches);
                    }
                }
            }
        })
        .expect("the operating system can start the watchdog thread")
}

/// Renews the leases of the sweep runs this instance holds, and stops the batches of sweeps a
/// client cancelled through any instance.
fn renew_sweep_runs(shared: &Shared, batches: &[Arc<Batch>]) {
    match shared.runtime.block_on(shared.store.renew_sweep_runs(&shared.lease())) {
        Ok(held) => {
            for run in held.iter().filter(|run| run.cancel_requested) {
                batches.iter().filter(|b| b.sweep == run.sweep).for_each(|b| b.cancel());
            }
        }
        Err(e) => tracing::warn!(error = %e, "cannot renew the leases of sweep runs"),
    }
}

/// Renews a running job's lease with its progress, and stops it if a client cancelled it through
/// any instance or it is no longer this instance's.
fn renew(shared: &Shared, id: &JobId, live: &Live) {
    let lease = shared.lease();
    match shared.runtime.block_on(shared.store.renew(id, &lease, live.control.steps_done())) {
        Ok(Renewed::Held { cancel_requested: false }) => {}
        Ok(Renewed::Held { cancel_requested: true }) => live.control.cancel(),
        // A job whose end is being recorded here is, or is about to be, no longer running in
        // the store: its end was read after the renewal, so this is not a lost lease.
        Ok(Renewed::Lost) if live.ending.load(Ordering::Acquire) => {}
        Ok(Renewed::Lost) => {
            tracing::warn!(job = %id, "the job's lease was lost; stopping it here");
            live.lease_lost.store(true, Ordering::Relaxed);
            live.control.cancel();
        }
        Err(e) => tracing::warn!(job = %id, error = %e, "cannot renew the job's lease"),
    }
}
