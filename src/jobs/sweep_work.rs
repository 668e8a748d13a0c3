//! A worker's turn at a sweep: it claims a batch of one sweep's runs, runs them one after
//! another, stores their ends, and goes back to the queue.
//!
//! The policy between sweeps and single jobs: a worker takes a queued job first, and only when
//! none is queued a batch of runs of the oldest sweep with runs waiting. It starts no further run
//! of the batch once [`BATCH_TIME`] has passed since the batch began, and puts the runs it did
//! not start back in the queue. A worker's first batch is one run; each next batch holds as many
//! runs as the last batch's time per run fits in [`BATCH_AIM`], up to [`BATCH_RUNS`], and one run
//! again after a batch that outlasted [`BATCH_TIME`]: long runs are claimed one at a time, so the
//! workers of every instance share them, and tiny ones many at a time, so that their claims and
//! stores cost little beside them. So a job queued while a sweep runs
//! waits for at most one run plus [`BATCH_TIME`] for a worker, while a sweep's runs cost one
//! claim per batch rather than a job each. Sweeps are served oldest first; a steady stream of
//! single jobs delays them, never the reverse.
//!
//! A run keeps only what its table row needs: its status, why it failed, and its final positions
//! and statistics as JSON. The ends of the runs a worker ran are stored together, in one
//! transaction, once [`STORE_EVERY`] has passed since the last were stored and when the batch is
//! over: tiny runs cost one write for dozens of them, and a long run's end is stored as it comes. A run started more than `--max-attempts` times without ending is
//! failed instead of run; a run of a cancelled sweep ends `cancelled`; at shutdown the runs of
//! the batch not ended go back to the queue.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use super::encode::encode_result;
use super::id::JobId;
use super::live::{CANCELLED, SHUT_DOWN};
use super::record::{Plan, now_ms};
use super::shared::Shared;
use super::status::JobStatus;
use super::store::{ClaimedRun, ClaimedRuns, RunEnd, StoreError, attempts_exhausted};
use super::sweep_live::Batch;
use crate::run::{Stats, Status, execute};
use crate::solver::parallel;
use crate::sweep::Sweep;

/// Runs a worker claims at once.
pub(super) const BATCH_RUNS: u32 = 256;
/// How long a worker keeps starting runs of one batch.
pub(super) const BATCH_TIME: Duration = Duration::from_millis(200);
/// How long a batch is sized to take, from the time per run of the batch before it.
const BATCH_AIM: Duration = Duration::from_millis(50);
/// How long the ends of runs may wait to be stored together.
const STORE_EVERY: Duration = Duration::from_millis(20);

/// Claims a batch of at most `size` runs of a sweep and runs it; returns the size of the next
/// batch, or `None` if there were no runs to claim.
pub(super) fn run_sweep_batch(shared: &Shared, size: u32) -> Result<Option<u32>, StoreError> {
    let lease = shared.lease();
    let claimed = shared.runtime.block_on(shared.store.claim_sweep_runs(&lease, now_ms(), size))?;
    let Some(ClaimedRuns { sweep: id, runs }) = claimed else { return Ok(None) };
    let batch = Arc::new(Batch::new(id.clone()));
    shared.batches().push(Arc::clone(&batch));
    tracing::debug!(sweep = %id, runs = runs.len(), "sweep runs claimed");
    let sweep = shared.sweep_blocking(&id);
    let mut ends = Ends { pending: Vec::new(), stored: Instant::now() };
    // The batch runs on a thread of the solver's pool, where each run's entry into the pool
    // hands nothing to another thread: two thread switches a run, which cost a tiny run as much
    // as some of its steps, are saved.
    let (released, ran) = parallel::install(|| {
        let began = Instant::now();
        let mut released = false;
        for (done, run) in runs.iter().enumerate() {
            let out_of_turn = done > 0 && began.elapsed() > BATCH_TIME;
            if out_of_turn
                || shared.stopped.load(Ordering::Relaxed)
                || batch.shutting_down.load(Ordering::Relaxed)
            {
                release(shared, &batch, &runs[done..]);
                released = true;
                break;
            }
            let end = match &sweep {
                _ if run.cancel_requested || batch.cancelled.load(Ordering::Relaxed) => {
                    ended(run.index, JobStatus::Cancelled, Some(CANCELLED.into()), None)
                }
                _ if run.attempts > shared.config.max_attempts => ended(
                    run.index,
                    JobStatus::Failed,
                    Some(attempts_exhausted(shared.config.max_attempts)),
                    None,
                ),
                Ok(Some(sweep)) => run_one(shared, &batch, sweep, run.index),
                Ok(None) => ended(run.index, JobStatus::Failed, Some(format!("sweep {id} is gone")), None),
                Err(e) => ended(run.index, JobStatus::Failed, Some(e.to_string()), None),
            };
            let finished = matches!(end.status, JobStatus::Succeeded | JobStatus::Diverged);
            if batch.shutting_down.load(Ordering::Relaxed) && !finished {
                release(shared, &batch, &runs[done..]);
                break;
            }
            ends.pending.push(end);
            if ends.stored.elapsed() >= STORE_EVERY {
                ends.store(shared, &id);
            }
        }
        (released, began.elapsed())
    });
    ends.store(shared, &id);
    let next_size = if released { 1 } else { next_batch_size(runs.len(), ran) };
    shared.batches().retain(|b| !Arc::ptr_eq(b, &batch));
    shared.changed();
    Ok(Some(next_size))
}

/// The size of the batch after one of `runs` runs that took `took`: as many runs as fit in
/// [`BATCH_AIM`] at its time per run, from 1 to [`BATCH_RUNS`]; 1 after a batch past [`BATCH_TIME`].
fn next_batch_size(runs: usize, took: Duration) -> u32 {
    if took > BATCH_TIME {
        return 1;
    }
    let per_run = took.as_nanos() / runs.max(1) as u128;
    let fit = BATCH_AIM.as_nanos() / per_run.max(1);
    u32::try_from(fit).unwrap_or(BATCH_RUNS).clamp(1, BATCH_RUNS)
}

/// Ends of runs not yet stored, and when the last were.
struct Ends {
    pending: Vec<RunEnd>,
    stored: Instant,
}

impl Ends {
    /// Stores the pending ends of `sweep`'s runs in one transaction.
    fn store(&mut self, shared: &Shared, sweep: &JobId) {
        self.stored = Instant::now();
        if self.pending.is_empty() {
            return;
        }
        let ends = std::mem::take(&mut self.pending);
        let count = ends.len();
        match shared.runtime.block_on(shared.store.finish_sweep_runs(sweep, &shared.owner, ends)) {
            Ok(recorded) if recorded == count => {}
            Ok(recorded) => {
                tracing::warn!(sweep = %sweep, runs = count - recorded, "lost the lease of runs; their ends here are not recorded")
            }
            Err(e) => {
                tracing::error!(sweep = %sweep, runs = count, error = %e, "cannot store the ends of sweep runs; they run again once their lease lapses")
            }
        }
    }
}

/// Puts runs not ended back in the queue.
fn release(shared: &Shared, batch: &Batch, runs: &[ClaimedRun]) {
    let indices: Vec<u32> = runs.iter().map(|run| run.index).collect();
    if let Err(e) =
        shared.runtime.block_on(shared.store.release_sweep_runs(&batch.sweep, &shared.owner, &indices))
    {
        tracing::error!(sweep = %batch.sweep, error = %e, "cannot put sweep runs back in the queue; they run again once their lease lapses");
    }
}

fn ended(index: u32, status: JobStatus, message: Option<String>, result: Option<bytes::Bytes>) -> RunEnd {
    RunEnd { index, status, message, result }
}

/// Runs one run of `sweep` (the reference is run 0 when there is one) and says how it ended.
fn run_one(shared: &Shared, batch: &Batch, sweep: &Sweep, index: u32) -> RunEnd {
    let scene = match (&sweep.reference, index) {
        (Some(reference), 0) => Some(reference),
        (Some(_), n) => sweep.variants.get(n as usize - 1).map(|v| &v.scene),
        (None, n) => sweep.variants.get(n as usize).map(|v| &v.scene),
    };
    let Some(scene) = scene else {
        return ended(index, JobStatus::Failed, Some(format!("the sweep has no run {index}")), None);
    };
    let control = batch.next_run();
    let ran = catch_unwind(AssertUnwindSafe(|| {
        let compiled = shared.config.limits.admit(scene).map_err(|errors| {
            let reasons: Vec<String> = errors.iter().map(ToString::to_string).collect();
            format!("the run exceeds this instance's limits: {}", reasons.join("; "))
        })?;
        let began = Instant::now();
        let recording = execute(&compiled.compiled, &control);
        count_work(shared, &compiled.plan, &recording.stats, began.elapsed());
        // A sweep run's result is its final positions: quick to encode whatever stopped the run.
        let encoded = encode_result(&recording, &compiled.compiled.output, &|| false)
            .map_err(|e| format!("the result could not be encoded: {e}"))?;
        Ok::<_, String>((recording.stats, encoded.bytes))
    }));
    let (stats, bytes) = match ran {
        Ok(Ok(ran)) => ran,
        Ok(Err(message)) => return ended(index, JobStatus::Failed, Some(message), None),
        Err(_) => return ended(index, JobStatus::Failed, Some("the simulation panicked".into()), None),
    };
    match stats.status {
        Status::Succeeded => ended(index, JobStatus::Succeeded, None, Some(bytes)),
        Status::Diverged => {
            let reason = stats.diverged.as_ref().map(|d| d.reason.clone());
            ended(index, JobStatus::Diverged, reason, Some(bytes))
        }
        Status::Cancelled if batch.timed_out.load(Ordering::Relaxed) => ended(
            index,
            JobStatus::Failed,
            Some(format!(
                "the run exceeded the wall-time limit of {} s",
                shared.config.wall_time.as_secs_f64()
            )),
            None,
        ),
        Status::Cancelled if batch.shutting_down.load(Ordering::Relaxed) => {
            ended(index, JobStatus::Cancelled, Some(SHUT_DOWN.into()), None)
        }
        Status::Cancelled => ended(index, JobStatus::Cancelled, Some(CANCELLED.into()), Some(bytes)),
        Status::Failed => ended(index, JobStatus::Failed, stats.failure.clone(), None),
    }
}

/// Adds a sweep run to the service's throughput counters as a job's end adds a job: its
/// particle-steps (the companions' only when it succeeded) and its time on the worker.
fn count_work(shared: &Shared, plan: &Plan, stats: &Stats, took: Duration) {
    let companions = if stats.status == Status::Succeeded { plan.companion_steps } else { 0 };
    let work = plan.particles.saturating_mul(stats.steps.saturating_add(companions));
    shared.particle_steps.fetch_add(work, Ordering::Relaxed);
    shared.busy_nanos.fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::{BATCH_RUNS, next_batch_size};

    #[test]
    fn a_batch_is_sized_by_the_time_per_run_of_the_last() {
        let ms = Duration::from_millis;
        // Runs of 70 µs: as many as fit in 50 ms, up to the most a worker claims.
        assert_eq!(next_batch_size(1, Duration::from_micros(70)), BATCH_RUNS);
        assert_eq!(next_batch_size(4, ms(20)), 10);
        assert_eq!(next_batch_size(5, ms(50)), 5);
        // A run longer than the aim, or a batch past its time, is claimed alone.
        assert_eq!(next_batch_size(1, ms(150)), 1);
        assert_eq!(next_batch_size(256, ms(201)), 1);
    }
}
