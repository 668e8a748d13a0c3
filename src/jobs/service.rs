//! [`Jobs`]: the one door to running simulations, used by the HTTP API.
//!
//! It admits a scene (limits, idempotency, room in the queue) and stores it as a queued job; the
//! store is the queue, and this process's workers (or another instance's, on a shared store)
//! claim it from there. It answers questions about any job in the store: its record (with live
//! progress if it runs here), its result, its end. Jobs running in this process have a [`Live`]
//! entry (their `Control` and a status channel); everything else comes from the store.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use thiserror::Error;
use tokio::sync::watch;

use super::doorbell::Doorbell;
use super::handoff::{Handoff, KeptModel};
use super::id::JobId;
use super::jobs_config::JobsConfig;
use super::limits::Limits;
use super::live::{CANCELLED, Live, Progress, SHUT_DOWN};
use super::pool::{spawn_watchdog, spawn_workers};
use super::record::{Idempotency, JobRecord, now_ms};
use super::shared::Shared;
use super::status::JobStatus;
use super::store::{CancelRequest, Inserted, JobStore, Outcome, Page, StoreError, StoredResult};
use crate::scene::{FieldError, Scene};

/// A scene to run, as received.
pub struct Submission {
    /// The validated scene.
    pub scene: Scene,
    /// The document it was read from, stored so any instance can run the job.
    pub document: serde_json::Value,
    /// [`fingerprint`](super::fingerprint) of the document it was read from.
    pub fingerprint: u64,
    /// The client's `Idempotency-Key`.
    pub idempotency_key: Option<String>,
    /// Refuse the job if its work (element-steps, see [`Cost`](super::Cost)) exceeds this.
    pub max_work: Option<u64>,
}

/// A job accepted by [`Jobs::submit`].
#[derive(Debug)]
pub struct Submitted {
    /// The job as stored.
    pub job: JobRecord,
    /// Whether it is an earlier job with the same idempotency key and body.
    pub repeated: bool,
}

/// A job that has ended, with its result if it has one.
#[derive(Debug)]
pub struct Ended {
    /// The job as stored.
    pub job: JobRecord,
    /// Its result, as stored.
    pub result: Option<StoredResult>,
}

/// Why a submission was refused.
#[derive(Debug, Error)]
pub enum SubmitError {
    /// The scene exceeds a limit; each field to change is named.
    #[error("the scene exceeds this server's limits")]
    OverLimit(Vec<FieldError>),
    /// The run is larger than the caller's `max_work`.
    #[error("the run needs {work} element-steps, over the budget of {budget}")]
    OverBudget {
        /// Element-steps of the run.
        work: u64,
        /// The budget.
        budget: u64,
        /// The field of the stage that costs the most work.
        pointer: String,
        /// That stage, and its share of the work.
        stage: &'static str,
        /// Its element-steps.
        stage_work: u64,
    },
    /// The idempotency key was first used with another body.
    #[error("the Idempotency-Key `{key}` was already used for job {job} with a different scene")]
    KeyReused {
        /// The key.
        key: String,
        /// The job that holds it.
        job: JobId,
    },
    /// No place is left in the queue.
    #[error("the queue is full")]
    QueueFull,
    /// The server is shutting down and takes no new jobs.
    #[error("the server is shutting down")]
    ShuttingDown,
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// What [`Jobs::cancel`] did.
#[derive(Debug)]
pub enum Cancelled {
    /// The job was waiting; it was taken out of the queue and will not run.
    Dropped(JobRecord),
    /// The job is running; it stops within a step or a solver iteration (within a second if it
    /// runs on another instance).
    Stopping(JobRecord),
    /// The job had already ended.
    AlreadyEnded(JobRecord),
}

/// How often a waiter looks at a job that does not run here.
const REMOTE_POLL: Duration = Duration::from_millis(100);

/// The job system: workers over a store. Cheap to clone.
#[derive(Clone)]
pub struct Jobs {
    pub(super) shared: Arc<Shared>,
}

impl Jobs {
    /// Starts the workers, the watchdog and the result sweep. Call it inside a tokio runtime:
    /// workers use that runtime to reach the store.
    pub fn start(store: Arc<dyn JobStore>, config: JobsConfig) -> Self {
        let workers = config.workers.max(1);
        let shared = Arc::new(Shared {
            store,
            config,
            runtime: tokio::runtime::Handle::current(),
            owner: format!("{}-{}", std::process::id(), JobId::new()),
            doorbell: Doorbell::new(workers),
            handoff: Arc::new(Handoff::new(workers)),
            running: AtomicUsize::new(0),
            particle_steps: AtomicU64::new(0),
            busy_nanos: AtomicU64::new(0),
            stopped: AtomicBool::new(false),
            workers_gone: AtomicBool::new(false),
            admitting: AtomicUsize::new(0),
            admission: tokio::sync::Semaphore::new(1),
            changes: watch::Sender::new(0),
            live: Mutex::new(HashMap::new()),
            threads: Mutex::new(Vec::new()),
            batches: Mutex::new(Vec::new()),
            sweeps: Mutex::new(Vec::new()),
        });
        let mut threads = spawn_workers(&shared, workers);
        threads.push(spawn_watchdog(&shared));
        *shared.threads.lock().unwrap_or_else(PoisonError::into_inner) = threads;
        tokio::spawn(sweep_results(Arc::downgrade(&shared)));
        Self { shared }
    }

    /// Runs `check` with the limits on a blocking thread, one admission at a time: it may
    /// compile scenes, which allocates their particles and springs.
    pub(super) async fn admitting<T: Send + 'static>(
        &self,
        check: impl FnOnce(&Limits) -> T + Send + 'static,
    ) -> Result<T, StoreError> {
        let _turn = self
            .shared
            .admission
            .acquire()
            .await
            .map_err(|e| StoreError::Backend(format!("admission closed: {e}")))?;
        let limits = *self.limits();
        tokio::task::spawn_blocking(move || check(&limits))
            .await
            .map_err(|e| StoreError::Backend(format!("admission task failed: {e}")))
    }

    /// The limits scenes are admitted under.
    pub fn limits(&self) -> &Limits {
        &self.shared.config.limits
    }

    /// The configuration the jobs run under.
    pub fn config(&self) -> &JobsConfig {
        &self.shared.config
    }

    /// This instance's name in the leases of the jobs it runs.
    pub fn instance(&self) -> &str {
        &self.shared.owner
    }

    /// Whether the job system has stopped and, its store being durable, leaves the jobs it is
    /// not running to the next instance.
    pub fn handing_over(&self) -> bool {
        self.shared.stopped.load(Ordering::Relaxed) && self.shared.store.durable()
    }

    /// Admits and queues a scene, or finds the earlier job with the same idempotency key.
    pub async fn submit(&self, submission: Submission) -> Result<Submitted, SubmitError> {
        self.queue(submission, false).await.map(|(submitted, _)| submitted)
    }

    /// Admits and queues a scene like [`submit`](Self::submit), for a caller that waits for the
    /// job on this instance (`POST /simulate`): the model compiled at admission is kept, while
    /// the returned [`KeptModel`] lives, for this instance's worker to run instead of compiling
    /// the stored scene again.
    pub async fn submit_to_wait(
        &self,
        submission: Submission,
    ) -> Result<(Submitted, KeptModel), SubmitError> {
        self.queue(submission, true).await
    }

    /// Admits and queues a scene, keeping its compiled model for this instance's workers if
    /// `hand_on`.
    async fn queue(
        &self,
        submission: Submission,
        hand_on: bool,
    ) -> Result<(Submitted, KeptModel), SubmitError> {
        let Submission { scene, document, fingerprint, idempotency_key, max_work } = submission;
        let idempotency = idempotency_key.map(|key| Idempotency { key, fingerprint });
        if let Some(key) = &idempotency
            && let Some(earlier) = self.shared.store.find_by_key(&key.key).await?
        {
            return repeat_of(earlier, key).map(|submitted| (submitted, KeptModel::NONE));
        }

        // A full queue refuses before any work.
        let shared = &self.shared;
        if shared.stopped.load(Ordering::Relaxed) {
            return Err(SubmitError::ShuttingDown);
        }
        let admitting = Admitting::enter(&shared.admitting);
        let queued = shared.store.count_queued().await?;
        if queued.saturating_add(admitting.others as u64) >= shared.config.queue_capacity as u64 {
            return Err(SubmitError::QueueFull);
        }
        // Admission counts particles and springs, then compiles (which allocates them), so it
        // runs off the async threads; the model is dropped there too unless it is handed on.
        let (plan, cost, compiled) = self
            .admitting(move |limits| {
                limits.admit(&scene).map(|a| (a.plan, a.cost, hand_on.then_some(a.compiled)))
            })
            .await?
            .map_err(SubmitError::OverLimit)?;
        if let Some(budget) = max_work
            && cost.work() > budget
        {
            let largest = cost.largest(|s| s.work).expect("a run has a stage");
            return Err(SubmitError::OverBudget {
                work: cost.work(),
                budget,
                pointer: largest.pointer.clone(),
                stage: largest.stage,
                stage_work: largest.work,
            });
        }

        let id = JobId::new();
        // Kept before the insert, so a worker that claims the job at once finds it.
        let kept = compiled.map_or(KeptModel::NONE, |compiled| shared.handoff.keep(&id, compiled));
        let record = JobRecord::queued(id.clone(), plan, idempotency.clone());
        match shared.store.insert(record.clone(), &document.to_string()).await? {
            Inserted::New => {}
            Inserted::KeyTaken(earlier) => {
                return repeat_of(
                    *earlier,
                    idempotency.as_ref().expect("only a keyed job can find its key taken"),
                )
                .map(|submitted| (submitted, KeptModel::NONE));
            }
        }
        drop(admitting);
        shared.doorbell.ring();
        tracing::info!(job = %id, particles = plan.particles, steps = plan.steps, "job queued");
        Ok((Submitted { job: record, repeated: false }, kept))
    }

    /// The job, with its live progress if it is running here.
    ///
    /// The live progress is taken before the stored record is read. A job's live status turns
    /// final only once its end is stored, so a read that crosses the end gives either the running
    /// job or the whole ended record, never an end without its message and stats.
    pub async fn get(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError> {
        let progress = self.shared.live().get(id).map(|live| live.progress());
        let mut record = self.shared.store.get(id).await?;
        if let (Some(record), Some(progress)) = (&mut record, progress) {
            progress.overlay(record);
        }
        Ok(record)
    }

    /// Jobs, newest first, with the live progress of those running here (taken before the
    /// listing is read, as in [`get`](Self::get)).
    pub async fn list(&self, page: Page) -> Result<Vec<JobRecord>, StoreError> {
        let progress: HashMap<JobId, Progress> =
            self.shared.live().iter().map(|(id, live)| (id.clone(), live.progress())).collect();
        let mut jobs = self.shared.store.list(page).await?;
        for job in &mut jobs {
            if let Some(progress) = progress.get(&job.id) {
                progress.overlay(job);
            }
        }
        Ok(jobs)
    }

    /// The stored result of an ended job.
    pub async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError> {
        self.shared.store.result(id).await
    }

    /// A channel holding the job's status while it runs here; `None` otherwise.
    pub fn watch(&self, id: &JobId) -> Option<watch::Receiver<JobStatus>> {
        self.shared.live().get(id).map(|live| live.status.subscribe())
    }

    /// Waits until the job has ended and returns its record. A job that runs here wakes the
    /// waiter as it ends; one that runs elsewhere is looked at every [`REMOTE_POLL`]. Returns the
    /// job unfinished if this instance hands over on shutdown.
    pub async fn wait(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError> {
        Ok(self.wait_for_end(id).await?.map(|(job, _)| job))
    }

    /// Waits like [`wait`](Self::wait) and returns the job with its result, if it ended with
    /// one. The result of a job that ran here comes from memory, as it was stored; only that of
    /// a job run by another instance is read from the store.
    pub async fn wait_with_result(&self, id: &JobId) -> Result<Option<Ended>, StoreError> {
        let Some((job, live)) = self.wait_for_end(id).await? else { return Ok(None) };
        let kept = live.and_then(|live| live.result.lock().unwrap_or_else(PoisonError::into_inner).clone());
        let result = match kept {
            Some(result) => Some(result),
            None if job.status.is_final() => self.shared.store.result(id).await?,
            None => None,
        };
        Ok(Some(Ended { job, result }))
    }

    /// The job once it has ended (or this instance hands over), and its [`Live`] entry if it
    /// was last seen running here.
    async fn wait_for_end(&self, id: &JobId) -> Result<Option<(JobRecord, Option<Arc<Live>>)>, StoreError> {
        let mut changes = self.shared.changes.subscribe();
        loop {
            let live = self.shared.live().get(id).cloned();
            if let Some(live) = &live {
                // Subscribing to the job's own channel holds it open even after the job is
                // forgotten. A job whose end is not recorded here (the store failed, it went back
                // to the queue) never turns final on it: any start or end here looks again.
                let mut status = live.status.subscribe();
                tokio::select! {
                    _ = status.wait_for(|s| s.is_final()) => {}
                    _ = changes.changed() => {}
                }
            }
            let job = self.shared.store.get(id).await?;
            match job {
                None => return Ok(None),
                Some(job) if job.status.is_final() || self.handing_over() => return Ok(Some((job, live))),
                Some(_) => {}
            }
            tokio::select! {
                _ = changes.changed() => {}
                () = tokio::time::sleep(REMOTE_POLL) => {}
            }
        }
    }

    /// Cancels a job: a queued one is dropped, a running one stops within a step (or a solver
    /// iteration inside one) if it runs here, and within a lease renewal if it runs on another
    /// instance.
    pub async fn cancel(&self, id: &JobId) -> Result<Option<Cancelled>, StoreError> {
        let shared = &self.shared;
        if let Some(live) = shared.live().get(id) {
            live.control.cancel();
        }
        let Some(request) = shared.store.request_cancel(id, now_ms(), CANCELLED).await? else {
            return Ok(None);
        };
        Ok(Some(match request {
            CancelRequest::Cancelled(job) => {
                shared.changes.send_modify(|n| *n += 1);
                Cancelled::Dropped(job)
            }
            CancelRequest::Requested(job) => Cancelled::Stopping(self.get(id).await?.unwrap_or(job)),
            CancelRequest::AlreadyEnded(job) => Cancelled::AlreadyEnded(job),
        }))
    }

    /// How many jobs are in each status.
    pub async fn count_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError> {
        self.shared.store.count_by_status().await
    }

    /// Jobs waiting for a worker, in the whole store.
    pub async fn queue_len(&self) -> Result<u64, StoreError> {
        self.shared.store.count_queued().await
    }

    /// Jobs being run by this instance.
    pub fn running(&self) -> usize {
        self.shared.running.load(Ordering::Relaxed)
    }

    /// Particle-steps taken by ended jobs, and the worker time they took.
    pub fn throughput(&self) -> (u64, Duration) {
        let s = &self.shared;
        (s.particle_steps.load(Ordering::Relaxed), Duration::from_nanos(s.busy_nanos.load(Ordering::Relaxed)))
    }

    /// Stops taking jobs and lets running ones finish for up to `grace`. Then, on a durable
    /// store, jobs still running go back to the queue and queued ones stay queued, for the next
    /// instance; on the memory store, which ends with the process, both are cancelled. A job
    /// stopped at the end of the grace period has [`STOP_WAIT`] to return (a cancelled run
    /// stops within a step or a solver iteration); one whose thread is still busy after that is
    /// released (or cancelled) from here and its thread left behind, so this returns within
    /// `grace + STOP_WAIT` and a little store time whatever the jobs do.
    pub async fn shutdown(&self, grace: Duration) {
        let shared = &self.shared;
        shared.stopped.store(true, Ordering::Relaxed);
        shared.doorbell.ring_all();
        let durable = shared.store.durable();
        if !durable {
            match shared.store.cancel_queued(now_ms(), SHUT_DOWN).await {
                Ok(ids) => {
                    ids.iter().for_each(|id| tracing::info!(job = %id, "queued job cancelled by shutdown"))
                }
                Err(e) => tracing::error!(error = %e, "cannot cancel the queued jobs"),
            }
            shared.changed();
        }
        let deadline = Instant::now() + grace;
        let busy = || shared.running.load(Ordering::Relaxed) > 0 || !shared.batches().is_empty();
        while busy() && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        // A batch stops its run and puts its runs back in the queue.
        shared.batches().iter().for_each(|batch| batch.shut_down());
        for (id, live) in shared.live_jobs() {
            live.shutting_down.store(true, Ordering::Relaxed);
            if durable {
                tracing::warn!(job = %id, "stopping a job still running at the end of the grace period; it stays queued");
                live.released.store(true, Ordering::Relaxed);
            } else {
                tracing::warn!(job = %id, "cancelling a job still running at the end of the grace period");
            }
            live.control.cancel();
        }
        let mut threads = std::mem::take(&mut *shared.threads.lock().unwrap_or_else(PoisonError::into_inner));
        // The watchdog was started last; it keeps enforcing wall time until the workers exit.
        let watchdog = threads.pop();
        let stop_by = Instant::now() + STOP_WAIT;
        while !threads.iter().all(JoinHandle::is_finished) && Instant::now() < stop_by {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let (finished, stuck): (Vec<_>, Vec<_>) = threads.into_iter().partition(JoinHandle::is_finished);
        finished.into_iter().for_each(|t| drop(t.join()));
        shared.workers_gone.store(true, Ordering::Relaxed);
        if let Some(watchdog) = watchdog {
            // It wakes every WATCHDOG_PERIOD, so this wait is short.
            let joined = tokio::task::spawn_blocking(move || watchdog.join().is_ok()).await;
            if !matches!(joined, Ok(true)) {
                tracing::error!("the watchdog thread could not be joined");
            }
        }
        if !stuck.is_empty() {
            tracing::error!(
                threads = stuck.len(),
                "worker threads did not return in time; leaving them behind"
            );
        }
        for (id, live) in shared.live_jobs() {
            let steps_done = live.control.steps_done();
            let outcome = Outcome {
                status: JobStatus::Cancelled,
                steps_done,
                message: Some(SHUT_DOWN.into()),
                failure: None,
                stats: None,
                result: None,
            };
            shared.record_end(&id, &live, outcome).await;
        }
    }
}

/// How long a job stopped by shutdown has to return before it is given up on.
pub const STOP_WAIT: Duration = Duration::from_secs(1);

/// Counts a submission between its room check and its insert, so submissions arriving together
/// cannot overfill the queue.
struct Admitting<'a> {
    counter: &'a AtomicUsize,
    others: usize,
}

impl<'a> Admitting<'a> {
    fn enter(counter: &'a AtomicUsize) -> Self {
        Self { counter, others: counter.fetch_add(1, Ordering::AcqRel) }
    }
}

impl Drop for Admitting<'_> {
    fn drop(&mut self) {
        self.counter.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Drops results older than the retention time, a few times per retention time (at least once a
/// minute), until the job system is gone.
async fn sweep_results(shared: Weak<Shared>) {
    let Some(ttl) = shared.upgrade().map(|s| s.config.result_ttl) else { return };
    let period = (ttl / 4).clamp(Duration::from_millis(100), Duration::from_secs(60));
    loop {
        tokio::time::sleep(period).await;
        let Some(shared) = shared.upgrade() else { return };
        if shared.stopped.load(Ordering::Relaxed) {
            return;
        }
        let before = now_ms().saturating_sub(ttl.as_millis() as u64);
        match shared.store.drop_results(before).await {
            Ok(0) => {}
            Ok(n) => tracing::info!(results = n, "dropped results past their retention time"),
            Err(e) => tracing::warn!(error = %e, "cannot drop old results"),
        }
    }
}

fn repeat_of(earlier: JobRecord, key: &Idempotency) -> Result<Submitted, SubmitError> {
    match &earlier.idempotency {
        Some(held) if held.fingerprint == key.fingerprint => Ok(Submitted { job: earlier, repeated: true }),
        _ => Err(SubmitError::KeyReused { key: key.key.clone(), job: earlier.id }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::store::MemoryStore;
    use crate::scene::Compiled;

    /// A job system with one worker that notes the particles of every model it runs.
    fn noting_particles() -> (Jobs, Arc<Mutex<Vec<usize>>>) {
        let ran = Arc::new(Mutex::new(Vec::new()));
        let noted = Arc::clone(&ran);
        let config = JobsConfig {
            workers: 1,
            before_run: Some(Arc::new(move |compiled: &Compiled| {
                noted.lock().unwrap().push(compiled.model.particle_count());
            })),
            ..JobsConfig::default()
        };
        (Jobs::start(Arc::new(MemoryStore::new()), config), ran)
    }

    /// A submission whose stored document (a chain of 7) differs from its scene (a chain of 3),
    /// so the particles the worker runs tell which model it ran: the one compiled at admission
    /// (3) or the stored document compiled by the worker (7).
    fn telling_submission() -> Submission {
        let chain = |count: u32| {
            serde_json::json!({"duration": 0.01, "dt": 0.01, "error_estimate": "none",
                               "bodies": [{"type": "chain", "count": count}]})
        };
        Submission {
            scene: Scene::from_value(chain(3)).unwrap(),
            document: chain(7),
            fingerprint: 0,
            idempotency_key: None,
            max_work: None,
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_job_waited_for_here_runs_the_model_compiled_at_admission() {
        let (jobs, ran) = noting_particles();
        let (submitted, kept) = jobs.submit_to_wait(telling_submission()).await.unwrap();
        let ended = jobs.wait(&submitted.job.id).await.unwrap().unwrap();
        assert_eq!(ended.status, JobStatus::Succeeded);
        assert_eq!(*ran.lock().unwrap(), [3], "the worker ran the admitted model, not a second compile");
        assert!(!jobs.shared.handoff.holds(&submitted.job.id), "the worker took it");
        drop(kept);
        jobs.shutdown(Duration::ZERO).await;
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_queued_job_runs_its_stored_scene_and_keeps_no_model() {
        let (jobs, ran) = noting_particles();
        let submitted = jobs.submit(telling_submission()).await.unwrap();
        assert!(!jobs.shared.handoff.holds(&submitted.job.id));
        let ended = jobs.wait(&submitted.job.id).await.unwrap().unwrap();
        assert_eq!(ended.status, JobStatus::Succeeded);
        assert_eq!(*ran.lock().unwrap(), [7], "the worker compiled the stored document");
        jobs.shutdown(Duration::ZERO).await;
    }
}
