//! [`Shared`]: the state the service ([`Jobs`](super::Jobs)) and its worker and watchdog threads
//! hold together: the store, the configuration, the runtime the workers reach the store through,
//! the counters, and the jobs running here with their [`Live`] entries. It records a job's start
//! and end here; neither the service nor the pool is imported, so both can build on it. It also
//! holds the batches of sweep runs running here ([`Batch`]) and the sweeps they come from, each
//! read from the store and checked once per process.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;

use tokio::sync::watch;

use super::doorbell::Doorbell;
use super::handoff::Handoff;
use super::id::JobId;
use super::jobs_config::JobsConfig;
use super::live::Live;
use super::record::now_ms;
use super::store::{JobStore, Lease, Outcome, StoreError};
use super::sweep_live::Batch;
use crate::scene::{Field, FrameSelection, Scene};
use crate::sweep::{Sweep, SweepError};

/// The job system's state, shared by [`Jobs`](super::Jobs) and its threads.
pub(super) struct Shared {
    pub(super) store: Arc<dyn JobStore>,
    pub(super) config: JobsConfig,
    pub(super) runtime: tokio::runtime::Handle,
    /// This instance's name in leases: unique per process.
    pub(super) owner: String,
    pub(super) doorbell: Doorbell,
    /// Models compiled at admission for jobs whose submitter waits for them here.
    pub(super) handoff: Arc<Handoff>,
    pub(super) running: AtomicUsize,
    pub(super) particle_steps: AtomicU64,
    pub(super) busy_nanos: AtomicU64,
    pub(super) stopped: AtomicBool,
    pub(super) workers_gone: AtomicBool,
    /// Submissions between their room check and their insert.
    pub(super) admitting: AtomicUsize,
    /// One admission at a time: each compiles its scene (up to the particle and spring limits),
    /// and that memory is held outside every job's share, as are the models in `handoff`.
    pub(super) admission: tokio::sync::Semaphore,
    /// Bumped whenever a job starts or ends here, to wake waiters.
    pub(super) changes: watch::Sender<u64>,
    pub(super) live: Mutex<HashMap<JobId, Arc<Live>>>,
    pub(super) threads: Mutex<Vec<JoinHandle<()>>>,
    /// Batches of sweep runs running here.
    pub(super) batches: Mutex<Vec<Arc<Batch>>>,
    /// The most recently used sweeps, as run for their table.
    pub(super) sweeps: Mutex<Vec<(JobId, Arc<Sweep>)>>,
}

/// Sweeps kept checked in [`Shared::sweeps`].
const SWEEPS_KEPT: usize = 8;

impl Shared {
    /// The jobs running here.
    pub(super) fn live(&self) -> MutexGuard<'_, HashMap<JobId, Arc<Live>>> {
        self.live.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub(super) fn live_jobs(&self) -> Vec<(JobId, Arc<Live>)> {
        self.live().iter().map(|(id, live)| (id.clone(), Arc::clone(live))).collect()
    }

    /// The batches of sweep runs running here.
    pub(super) fn batches(&self) -> MutexGuard<'_, Vec<Arc<Batch>>> {
        self.batches.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The sweep with this id as its runs are run for its table, read from the store and checked
    /// the first time; `None` if the store has no such sweep. Call it off the async runtime: it
    /// blocks on the store and checks every variant.
    pub(super) fn sweep_blocking(&self, id: &JobId) -> Result<Option<Arc<Sweep>>, StoreError> {
        if let Some(sweep) = self.kept_sweep(id) {
            return Ok(Some(sweep));
        }
        let Some(document) = self.runtime.block_on(self.store.sweep_document(id))? else { return Ok(None) };
        let sweep = serde_json::from_str(&document)
            .map_err(|e| e.to_string())
            .and_then(|document| sweep_for_table(document, u64::MAX).map_err(|e| e.to_string()))
            .map_err(|e| StoreError::Backend(format!("the stored sweep {id} cannot be read: {e}")))?;
        let sweep = Arc::new(sweep);
        self.keep_sweep(id, Arc::clone(&sweep));
        Ok(Some(sweep))
    }

    /// The sweep with this id if it is kept here, checked, as run for its table.
    pub(super) fn kept_sweep(&self, id: &JobId) -> Option<Arc<Sweep>> {
        let sweeps = self.sweeps.lock().unwrap_or_else(PoisonError::into_inner);
        sweeps.iter().find(|(kept, _)| kept == id).map(|(_, sweep)| Arc::clone(sweep))
    }

    /// Keeps a sweep checked, as run for its table, among the most recently used.
    pub(super) fn keep_sweep(&self, id: &JobId, sweep: Arc<Sweep>) {
        let mut sweeps = self.sweeps.lock().unwrap_or_else(PoisonError::into_inner);
        if sweeps.len() >= SWEEPS_KEPT {
            sweeps.remove(0);
        }
        sweeps.push((id.clone(), sweep));
    }

    /// A lease for this instance from now.
    pub(super) fn lease(&self) -> Lease {
        Lease { owner: self.owner.clone(), until_ms: now_ms() + self.config.lease.as_millis() as u64 }
    }

    /// Whether a job runs here.
    pub(super) fn is_live(&self, id: &JobId) -> bool {
        self.live().contains_key(id)
    }

    /// Wakes whoever waits for a job to start or end here.
    pub(super) fn changed(&self) {
        self.changes.send_modify(|n| *n += 1);
    }

    /// Records that a job started here.
    pub(super) fn started(&self, id: &JobId, live: &Arc<Live>) {
        self.live().insert(id.clone(), Arc::clone(live));
        self.changed();
    }

    /// [`record_end`](Self::record_end) from a worker thread.
    pub(super) fn finish(&self, id: &JobId, live: &Live, outcome: Outcome) {
        self.runtime.block_on(self.record_end(id, live, outcome));
    }

    /// Records the end of a job run here (unless it is no longer ours, or goes back to the
    /// queue), logs it once it is committed, tells its watchers, and forgets it. Only the first
    /// call for a job does anything.
    pub(super) async fn record_end(&self, id: &JobId, live: &Live, outcome: Outcome) {
        if live.ending.swap(true, Ordering::SeqCst) {
            return;
        }
        let status = outcome.status;
        if live.released.load(Ordering::Relaxed) {
            match self.store.release(id, &self.owner).await {
                Ok(()) => tracing::info!(job = %id, "job put back in the queue for the next instance"),
                Err(e) => tracing::error!(job = %id, error = %e, "cannot put the job back in the queue"),
            }
        } else if live.lease_lost.load(Ordering::Relaxed) {
            tracing::warn!(job = %id, "the job is no longer this instance's; its end here is not recorded");
        } else {
            let result = outcome.result.clone();
            match self.store.finish(id, &self.owner, now_ms(), outcome).await {
                Ok(true) => {
                    let wall_time_s = live.started.elapsed().as_secs_f64();
                    tracing::info!(job = %id, status = status.name(), wall_time_s, "job ended");
                    *live.result.lock().unwrap_or_else(PoisonError::into_inner) = result;
                    live.status.send_replace(status);
                }
                Ok(false) => tracing::warn!(job = %id, "lost the job's lease; its end here is not recorded"),
                Err(e) => tracing::error!(
                    job = %id,
                    error = %e,
                    "cannot store the end of the job; it runs again once its lease lapses"
                ),
            }
        }
        self.live().remove(id);
        self.changed();
    }
}

/// Checks a sweep document and sets every run to keep only its final positions, as JSON: all a
/// table row needs.
pub(super) fn sweep_for_table(document: serde_json::Value, max_variants: u64) -> Result<Sweep, SweepError> {
    let mut sweep = Sweep::from_value(document, max_variants)?;
    sweep.reference.iter_mut().for_each(keep_final_positions);
    sweep.variants.iter_mut().for_each(|variant| keep_final_positions(&mut variant.scene));
    Ok(sweep)
}

/// A sweep run keeps only its final positions, as JSON, which is all its table row needs and
/// what [`read_json_final`](crate::output::read_json_final) reads back.
pub(super) fn keep_final_positions(scene: &mut Scene) {
    scene.output.frames = FrameSelection::Final;
    scene.output.fields = vec![Field::Positions];
    scene.output.format = crate::output::Format::Json;
}
