//! The worker threads that run jobs, and the watchdog that enforces their wall time.
//!
//! Each worker is a plain thread that takes a job from the queue, runs it with
//! [`run::execute`](crate::run::execute) inside `catch_unwind` (so a panic fails that job alone),
//! encodes the result and stores it. Workers talk to the async store by blocking on the
//! runtime's handle, which is allowed because they are not runtime threads. The watchdog thread
//! wakes a few times a second: it cancels, through their `Control`, jobs past their wall time
//! (the worker then marks them failed), and copies the progress of running jobs to the store.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::service::{Live, Shared, Ticket};
use super::store::Outcome;
use super::{Failure, JobId, JobStatus, encode_result, now_ms};
use crate::output::stats_json;
use crate::run::{Status, execute};

/// How often the watchdog checks deadlines and publishes progress to the store.
const WATCHDOG_PERIOD: Duration = Duration::from_millis(25);
/// How often progress is copied to the store.
const STORE_PROGRESS_PERIOD: Duration = Duration::from_millis(500);

/// Starts `count` workers.
pub(super) fn spawn_workers(shared: &Arc<Shared>, count: usize) -> Vec<JoinHandle<()>> {
    (0..count)
        .map(|n| {
            let shared = Arc::clone(shared);
            std::thread::Builder::new()
                .name(format!("drape-worker-{n}"))
                .spawn(move || {
                    while let Some((id, ticket)) = shared.queue.pop() {
                        run_job(&shared, &id, ticket);
                    }
                })
                .expect("the operating system can start a worker thread")
        })
        .collect()
}

fn run_job(shared: &Shared, id: &JobId, ticket: Ticket) {
    let Ticket { compiled, live } = ticket;
    let started = Instant::now();
    *live.started.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(started);
    shared.running.fetch_add(1, Ordering::Relaxed);
    if let Err(e) = shared.runtime.block_on(shared.store.mark_running(id, now_ms())) {
        tracing::error!(job = %id, error = %e, "cannot mark the job running");
    }
    live.status.send_replace(JobStatus::Running);
    tracing::info!(job = %id, particles = live.plan.particles, steps = live.plan.steps, "job started");

    let ran = catch_unwind(AssertUnwindSafe(|| {
        if let Some(hook) = &shared.config.before_run {
            hook(&compiled);
        }
        let recording = execute(&compiled, &live.control);
        let encoded = encode_result(&recording, &compiled.output);
        (recording.stats, encoded)
    }));

    let steps_done = live.control.steps_done();
    let outcome = match ran {
        Ok((stats, Ok(result))) => {
            let (status, message) = match stats.status {
                Status::Succeeded => (JobStatus::Succeeded, None),
                Status::Diverged => (JobStatus::Diverged, stats.diverged.as_ref().map(|d| d.reason.clone())),
                Status::Cancelled if live.timed_out.load(Ordering::Relaxed) => (
                    JobStatus::Failed,
                    Some(format!(
                        "the job exceeded the wall-time limit of {} s after {steps_done} of {} steps",
                        shared.config.wall_time.as_secs_f64(),
                        live.plan.steps
                    )),
                ),
                Status::Cancelled => (JobStatus::Cancelled, Some(live.cancel_reason())),
            };
            let failure = (status == JobStatus::Failed).then_some(Failure::WallTime);
            let result = failure.is_none().then_some(result);
            Outcome { status, steps_done, message, failure, stats: Some(stats_json(&stats)), result }
        }
        Ok((_, Err(e))) => {
            failed(steps_done, Failure::Encoding, format!("the result could not be encoded: {e}"))
        }
        Err(panic) => failed(
            steps_done,
            Failure::Panicked,
            format!("the simulation panicked: {}", panic_message(panic.as_ref())),
        ),
    };
    shared.running.fetch_sub(1, Ordering::Relaxed);
    let elapsed = started.elapsed();
    // Companion runs of the error estimate are counted when the run finished with them.
    let companions = if outcome.status == JobStatus::Succeeded { live.plan.companion_steps } else { 0 };
    let work = live.plan.particles.saturating_mul(steps_done.saturating_add(companions));
    shared.particle_steps.fetch_add(work, Ordering::Relaxed);
    shared.busy_nanos.fetch_add(elapsed.as_nanos() as u64, Ordering::Relaxed);
    tracing::info!(job = %id, status = outcome.status.name(), wall_time_s = elapsed.as_secs_f64(), "job ended");
    shared.finish(id, &live, outcome);
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
            let mut last_store_update = Instant::now();
            while !shared.workers_gone.load(Ordering::Relaxed) {
                std::thread::sleep(WATCHDOG_PERIOD);
                let running: Vec<(JobId, Arc<Live>)> = shared.live_jobs();
                for (_, live) in &running {
                    let started = *live.started.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                    if started.is_some_and(|t| t.elapsed() > shared.config.wall_time) {
                        live.timed_out.store(true, Ordering::Relaxed);
                        live.control.cancel();
                    }
                }
                if last_store_update.elapsed() >= STORE_PROGRESS_PERIOD {
                    last_store_update = Instant::now();
                    for (id, live) in
                        running.iter().filter(|(_, live)| *live.status.borrow() == JobStatus::Running)
                    {
                        // A job may end between the check and the write; stores ignore progress
                        // on an ended job.
                        let _ =
                            shared.runtime.block_on(shared.store.set_progress(id, live.control.steps_done()));
                    }
                }
            }
        })
        .expect("the operating system can start the watchdog thread")
}
