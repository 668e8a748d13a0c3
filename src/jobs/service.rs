//! [`Jobs`]: the one door to running simulations, used by the HTTP API.
//!
//! It admits a scene (limits, idempotency, a place in the queue), stores the job, hands it to the
//! worker pool, and answers questions about it: its record with live progress, its result, a
//! channel that changes when its status does. Jobs being queued or run in this process have a
//! [`Live`] entry (their `Control` and a status channel); everything else comes from the store.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use thiserror::Error;
use tokio::sync::watch;

use super::pool::{spawn_watchdog, spawn_workers};
use super::queue::Queue;
use super::store::{Inserted, JobStore, Outcome, Page, StoreError, StoredResult};
use super::{Idempotency, JobId, JobRecord, JobStatus, Limits, Plan, now_ms};
use crate::run::Control;
use crate::scene::{Compiled, FieldError, Scene};

/// A function run on the worker thread just before each simulation; tests use it to make a job
/// panic. It is set only through [`JobsConfig`], never from the command line or HTTP.
pub type BeforeRun = Arc<dyn Fn(&Compiled) + Send + Sync>;

/// How the job system runs.
#[derive(Clone)]
pub struct JobsConfig {
    /// Worker threads.
    pub workers: usize,
    /// Jobs that may wait for a worker.
    pub queue_capacity: usize,
    /// The longest a job may run before it is stopped and failed.
    pub wall_time: Duration,
    /// The largest scene admitted.
    pub limits: Limits,
    /// Run before each simulation (see [`BeforeRun`]).
    pub before_run: Option<BeforeRun>,
}

impl Default for JobsConfig {
    fn default() -> Self {
        Self {
            workers: std::thread::available_parallelism().map_or(1, usize::from),
            queue_capacity: 64,
            wall_time: Duration::from_secs(300),
            limits: Limits::default(),
            before_run: None,
        }
    }
}

/// A scene to run, as received.
pub struct Submission {
    /// The validated scene.
    pub scene: Scene,
    /// [`fingerprint`](super::fingerprint) of the document it was read from.
    pub fingerprint: u64,
    /// The client's `Idempotency-Key`.
    pub idempotency_key: Option<String>,
    /// Refuse the job if its particle-steps exceed this.
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

/// Why a submission was refused.
#[derive(Debug, Error)]
pub enum SubmitError {
    /// The scene exceeds a limit; each field to change is named.
    #[error("the scene exceeds this server's limits")]
    OverLimit(Vec<FieldError>),
    /// The run is larger than the caller's `max_work`.
    #[error("the run needs {work} particle-steps, over the budget of {budget}")]
    OverBudget {
        /// Particle-steps of the run.
        work: u64,
        /// The budget.
        budget: u64,
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
    /// The job is running; it stops at its next batch of steps.
    Stopping(JobRecord),
    /// The job had already ended.
    AlreadyEnded(JobRecord),
}

/// The job system: queue, workers, store. Cheap to clone.
#[derive(Clone)]
pub struct Jobs {
    shared: Arc<Shared>,
}

pub(super) struct Shared {
    pub(super) store: Arc<dyn JobStore>,
    pub(super) queue: Queue<Ticket>,
    pub(super) config: JobsConfig,
    pub(super) runtime: tokio::runtime::Handle,
    pub(super) running: AtomicUsize,
    pub(super) particle_steps: AtomicU64,
    pub(super) busy_nanos: AtomicU64,
    pub(super) stopped: AtomicBool,
    pub(super) workers_gone: AtomicBool,
    live: Mutex<HashMap<JobId, Arc<Live>>>,
    threads: Mutex<Vec<JoinHandle<()>>>,
}

/// A job handed to a worker.
pub(super) struct Ticket {
    pub(super) compiled: Compiled,
    pub(super) live: Arc<Live>,
}

/// What this process knows of a job while it is queued or running.
pub(super) struct Live {
    pub(super) control: Control,
    pub(super) plan: Plan,
    pub(super) status: watch::Sender<JobStatus>,
    pub(super) started: Mutex<Option<Instant>>,
    pub(super) timed_out: AtomicBool,
    shutting_down: AtomicBool,
}

impl Live {
    /// Why a cancelled job was cancelled.
    pub(super) fn cancel_reason(&self) -> String {
        if self.shutting_down.load(Ordering::Relaxed) {
            "the server shut down before the job finished".into()
        } else {
            "cancelled by request".into()
        }
    }
}

impl Shared {
    fn live(&self) -> MutexGuard<'_, HashMap<JobId, Arc<Live>>> {
        self.live.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub(super) fn live_jobs(&self) -> Vec<(JobId, Arc<Live>)> {
        self.live().iter().map(|(id, live)| (id.clone(), Arc::clone(live))).collect()
    }

    /// Records the end of a job, tells its watchers, and forgets it.
    pub(super) fn finish(&self, id: &JobId, live: &Live, outcome: Outcome) {
        let status = outcome.status;
        if let Err(e) = self.runtime.block_on(self.store.finish(id, now_ms(), outcome)) {
            tracing::error!(job = %id, error = %e, "cannot store the end of the job");
        }
        live.status.send_replace(status);
        self.live().remove(id);
    }

    async fn finish_async(&self, id: &JobId, live: &Live, outcome: Outcome) -> Result<(), StoreError> {
        let status = outcome.status;
        let stored = self.store.finish(id, now_ms(), outcome).await;
        live.status.send_replace(status);
        self.live().remove(id);
        stored
    }
}

impl Jobs {
    /// Starts the workers and the watchdog. Call it inside a tokio runtime: workers use that
    /// runtime to reach the store.
    pub fn start(store: Arc<dyn JobStore>, config: JobsConfig) -> Self {
        let workers = config.workers.max(1);
        let shared = Arc::new(Shared {
            store,
            queue: Queue::new(config.queue_capacity),
            config,
            runtime: tokio::runtime::Handle::current(),
            running: AtomicUsize::new(0),
            particle_steps: AtomicU64::new(0),
            busy_nanos: AtomicU64::new(0),
            stopped: AtomicBool::new(false),
            workers_gone: AtomicBool::new(false),
            live: Mutex::new(HashMap::new()),
            threads: Mutex::new(Vec::new()),
        });
        let mut threads = spawn_workers(&shared, workers);
        threads.push(spawn_watchdog(&shared));
        *shared.threads.lock().unwrap_or_else(PoisonError::into_inner) = threads;
        Self { shared }
    }

    /// The limits scenes are admitted under.
    pub fn limits(&self) -> &Limits {
        &self.shared.config.limits
    }

    /// The configuration the jobs run under.
    pub fn config(&self) -> &JobsConfig {
        &self.shared.config
    }

    /// Admits and queues a scene, or finds the earlier job with the same idempotency key.
    pub async fn submit(&self, submission: Submission) -> Result<Submitted, SubmitError> {
        let Submission { scene, fingerprint, idempotency_key, max_work } = submission;
        let idempotency = idempotency_key.map(|key| Idempotency { key, fingerprint });
        if let Some(key) = &idempotency {
            if let Some(earlier) = self.shared.store.find_by_key(&key.key).await? {
                return repeat_of(earlier, key);
            }
        }

        // A full queue refuses before any work; the slot is freed if admission fails.
        let shared = &self.shared;
        let Some(slot) = shared.queue.reserve() else {
            return Err(if shared.stopped.load(Ordering::Relaxed) {
                SubmitError::ShuttingDown
            } else {
                SubmitError::QueueFull
            });
        };
        // Admission counts particles and springs, then compiles (which allocates them), so it
        // runs off the async threads.
        let limits = *self.limits();
        let (compiled, plan) = tokio::task::spawn_blocking(move || limits.admit(&scene))
            .await
            .map_err(|e| StoreError::Backend(format!("admission task failed: {e}")))?
            .map_err(SubmitError::OverLimit)?;
        if let Some(budget) = max_work {
            if plan.work() > budget {
                return Err(SubmitError::OverBudget { work: plan.work(), budget });
            }
        }

        let id = JobId::new();
        let record = JobRecord::queued(id.clone(), plan, idempotency.clone());
        let live = Arc::new(Live {
            control: Control::new(),
            plan,
            status: watch::Sender::new(JobStatus::Queued),
            started: Mutex::new(None),
            timed_out: AtomicBool::new(false),
            shutting_down: AtomicBool::new(false),
        });
        shared.live().insert(id.clone(), Arc::clone(&live));
        match shared.store.insert(record.clone()).await {
            Ok(Inserted::New) => {}
            Ok(Inserted::KeyTaken(earlier)) => {
                shared.live().remove(&id);
                return repeat_of(
                    *earlier,
                    idempotency.as_ref().expect("only a keyed job can find its key taken"),
                );
            }
            Err(e) => {
                shared.live().remove(&id);
                return Err(e.into());
            }
        }
        if slot.push(id.clone(), Ticket { compiled, live: Arc::clone(&live) }).is_err() {
            live.shutting_down.store(true, Ordering::Relaxed);
            shared.finish_async(&id, &live, cancelled_unrun(&live)).await?;
            return Err(SubmitError::ShuttingDown);
        }
        tracing::info!(job = %id, particles = plan.particles, steps = plan.steps, "job queued");
        Ok(Submitted { job: record, repeated: false })
    }

    /// The job, with its live progress if it is running here.
    pub async fn get(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError> {
        let live = self.shared.live().get(id).cloned();
        let mut record = self.shared.store.get(id).await?;
        if let (Some(record), Some(live)) = (&mut record, live) {
            if !record.status.is_final() {
                record.status = *live.status.borrow();
                record.steps_done = live.control.steps_done();
            }
        }
        Ok(record)
    }

    /// Jobs, newest first.
    pub async fn list(&self, page: Page) -> Result<Vec<JobRecord>, StoreError> {
        let mut jobs = self.shared.store.list(page).await?;
        let live = self.shared.live();
        for job in jobs.iter_mut().filter(|job| !job.status.is_final()) {
            if let Some(l) = live.get(&job.id) {
                job.status = *l.status.borrow();
                job.steps_done = l.control.steps_done();
            }
        }
        Ok(jobs)
    }

    /// The stored result of an ended job.
    pub async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError> {
        self.shared.store.result(id).await
    }

    /// A channel holding the job's status while it is queued or running here; `None` otherwise.
    pub fn watch(&self, id: &JobId) -> Option<watch::Receiver<JobStatus>> {
        self.shared.live().get(id).map(|live| live.status.subscribe())
    }

    /// Waits until the job has ended and returns its record.
    pub async fn wait(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError> {
        if let Some(mut status) = self.watch(id) {
            // An error means the job was forgotten, which happens only after it ended.
            let _ = status.wait_for(|s| s.is_final()).await;
        }
        self.shared.store.get(id).await
    }

    /// Cancels a job: a queued one is dropped, a running one stops within one batch of steps.
    pub async fn cancel(&self, id: &JobId) -> Result<Option<Cancelled>, StoreError> {
        let shared = &self.shared;
        if let Some(ticket) = shared.queue.remove(id) {
            let live = ticket.live;
            shared.finish_async(id, &live, cancelled_unrun(&live)).await?;
            return Ok(shared.store.get(id).await?.map(Cancelled::Dropped));
        }
        let live = shared.live().get(id).cloned();
        let Some(record) = self.get(id).await? else { return Ok(None) };
        Ok(Some(match live {
            Some(live) if !record.status.is_final() => {
                live.control.cancel();
                Cancelled::Stopping(record)
            }
            _ => Cancelled::AlreadyEnded(record),
        }))
    }

    /// How many jobs are in each status.
    pub async fn count_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError> {
        self.shared.store.count_by_status().await
    }

    /// Jobs waiting for a worker.
    pub fn queue_len(&self) -> usize {
        self.shared.queue.len()
    }

    /// Jobs being run.
    pub fn running(&self) -> usize {
        self.shared.running.load(Ordering::Relaxed)
    }

    /// Particle-steps taken by ended jobs, and the worker time they took.
    pub fn throughput(&self) -> (u64, Duration) {
        let s = &self.shared;
        (s.particle_steps.load(Ordering::Relaxed), Duration::from_nanos(s.busy_nanos.load(Ordering::Relaxed)))
    }

    /// Stops taking jobs, cancels the queued ones, lets running ones finish for up to `grace`,
    /// cancels those still running, and waits for the workers to exit.
    pub async fn shutdown(&self, grace: Duration) {
        let shared = &self.shared;
        shared.stopped.store(true, Ordering::Relaxed);
        for (id, ticket) in shared.queue.close() {
            ticket.live.shutting_down.store(true, Ordering::Relaxed);
            if let Err(e) = shared.finish_async(&id, &ticket.live, cancelled_unrun(&ticket.live)).await {
                tracing::error!(job = %id, error = %e, "cannot store the cancellation");
            }
        }
        let deadline = Instant::now() + grace;
        while shared.running.load(Ordering::Relaxed) > 0 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        for (id, live) in shared.live_jobs() {
            tracing::warn!(job = %id, "cancelling a job still running at the end of the grace period");
            live.shutting_down.store(true, Ordering::Relaxed);
            live.control.cancel();
        }
        let threads = std::mem::take(&mut *shared.threads.lock().unwrap_or_else(PoisonError::into_inner));
        let shared_for_join = Arc::clone(shared);
        let joined = tokio::task::spawn_blocking(move || {
            // The watchdog was started last; it keeps enforcing wall time until the workers exit.
            let mut threads = threads;
            let watchdog = threads.pop();
            threads.into_iter().for_each(|t| drop(t.join()));
            shared_for_join.workers_gone.store(true, Ordering::Relaxed);
            watchdog.into_iter().for_each(|t| drop(t.join()));
        });
        if joined.await.is_err() {
            tracing::error!("a worker thread could not be joined");
        }
    }
}

fn repeat_of(earlier: JobRecord, key: &Idempotency) -> Result<Submitted, SubmitError> {
    match &earlier.idempotency {
        Some(held) if held.fingerprint == key.fingerprint => Ok(Submitted { job: earlier, repeated: true }),
        _ => Err(SubmitError::KeyReused { key: key.key.clone(), job: earlier.id }),
    }
}

fn cancelled_unrun(live: &Live) -> Outcome {
    Outcome {
        status: JobStatus::Cancelled,
        steps_done: 0,
        message: Some(live.cancel_reason()),
        failure: None,
        stats: None,
        result: None,
    }
}
