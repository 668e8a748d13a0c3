//! The in-memory job store: a map behind one mutex, for tests and single-process use.
//!
//! Everything is lost when the process ends. Only the most recent ended jobs are kept (with
//! their results), so memory stays bounded; queued and running jobs are never dropped. The lock
//! is held only to copy a record in or out, never across an `await`.

use std::collections::{BTreeMap, HashMap};
use std::sync::Mutex;

use async_trait::async_trait;

use super::{
    AssetRecord, AssetRoom, CancelRequest, Claim, Claimed, ClaimedRun, ClaimedRuns, HeldRun, Inserted,
    InsertedSweep, JobStore, Lease, Outcome, Page, PutAsset, Renewed, RunEnd, StoreError, StoredResult,
    StoredRun, SweepEntry, SweepSummary, attempts_exhausted,
};
use crate::jobs::id::JobId;
use crate::jobs::record::JobRecord;
use crate::jobs::status::{Failure, JobStatus};

/// Jobs in a map, in submission order.
pub struct MemoryStore {
    state: Mutex<State>,
    /// Ended jobs kept; older ones are forgotten.
    retain: usize,
}

#[derive(Default)]
struct State {
    /// Jobs that have ended.
    ended: usize,
    jobs: HashMap<JobId, Entry>,
    /// Submission order: sequence number to id.
    order: BTreeMap<u64, JobId>,
    keys: HashMap<String, JobId>,
    next: u64,
    /// Uploaded meshes with their compact form, in upload order.
    assets: Vec<(AssetRecord, Vec<u8>)>,
    /// Sweeps with their runs, in submission order.
    sweeps: Vec<SweepState>,
}

struct SweepState {
    entry: SweepEntry,
    document: String,
    cancel_requested: bool,
    runs: Vec<RunState>,
}

struct RunState {
    stored: StoredRun,
    attempts: u32,
    lease: Option<Lease>,
    cancel_requested: bool,
}

impl RunState {
    fn claimable(&self, now_ms: u64) -> bool {
        match self.stored.status {
            JobStatus::Queued => true,
            JobStatus::Running => self.lease.as_ref().is_none_or(|l| l.until_ms < now_ms),
            _ => false,
        }
    }

    fn held_by(&self, owner: &str) -> bool {
        self.stored.status == JobStatus::Running && self.lease.as_ref().is_some_and(|l| l.owner == owner)
    }
}

impl SweepState {
    fn summary(&self) -> SweepSummary {
        let count =
            |f: &dyn Fn(JobStatus) -> bool| self.runs.iter().filter(|r| f(r.stored.status)).count() as u32;
        SweepSummary {
            entry: self.entry.clone(),
            cancel_requested: self.cancel_requested,
            finished: count(&JobStatus::is_final),
            running: count(&|s| s == JobStatus::Running),
        }
    }
}

struct Entry {
    record: JobRecord,
    scene: String,
    lease: Option<Lease>,
    cancel_requested: bool,
    result: Option<StoredResult>,
}

impl Entry {
    fn held_by(&self, owner: &str) -> bool {
        self.record.status == JobStatus::Running && self.lease.as_ref().is_some_and(|l| l.owner == owner)
    }

    fn claimable(&self, now_ms: u64) -> bool {
        match self.record.status {
            JobStatus::Queued => true,
            JobStatus::Running => self.lease.as_ref().is_none_or(|l| l.until_ms < now_ms),
            _ => false,
        }
    }

    fn end(&mut self, finished_ms: u64, outcome: Outcome) {
        let record = &mut self.record;
        record.status = outcome.status;
        record.finished_ms = Some(finished_ms);
        record.steps_done = outcome.steps_done;
        record.message = outcome.message;
        record.failure = outcome.failure;
        record.stats = outcome.stats;
        self.result = outcome.result;
        self.lease = None;
    }
}

impl MemoryStore {
    /// Ended jobs kept by [`MemoryStore::new`].
    pub const DEFAULT_RETAIN: usize = 1000;

    /// An empty store that keeps the [`DEFAULT_RETAIN`](Self::DEFAULT_RETAIN) most recent ended jobs.
    pub fn new() -> Self {
        Self::retaining(Self::DEFAULT_RETAIN)
    }

    /// An empty store that keeps the `retain` most recent ended jobs (at least one).
    pub fn retaining(retain: usize) -> Self {
        Self { state: Mutex::default(), retain: retain.max(1) }
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        let mut state = self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        f(&mut state)
    }
}

impl Default for MemoryStore {
    fn default() -> Self {
        Self::new()
    }
}

impl State {
    fn entry(&mut self, id: &JobId) -> Result<&mut Entry, StoreError> {
        self.jobs.get_mut(id).ok_or_else(|| StoreError::NotFound(id.clone()))
    }

    /// Counts a job that just ended, and forgets the oldest ended jobs until at most `retain`
    /// are left.
    fn ended_one(&mut self, retain: usize) {
        self.ended += 1;
        let mut excess = self.ended.saturating_sub(retain);
        let mut evicted = Vec::new();
        for (&sequence, id) in &self.order {
            if excess == 0 {
                break;
            }
            if self.jobs[id].record.status.is_final() {
                evicted.push(sequence);
                excess -= 1;
            }
        }
        for sequence in evicted {
            let id = self.order.remove(&sequence).expect("listed in order");
            let entry = self.jobs.remove(&id).expect("every ordered job is stored");
            if let Some(key) = entry.record.idempotency {
                self.keys.remove(&key.key);
            }
            self.ended -= 1;
        }
    }
}

fn cancelled(steps_done: u64, message: &str) -> Outcome {
    Outcome {
        status: JobStatus::Cancelled,
        steps_done,
        message: Some(message.to_string()),
        failure: None,
        stats: None,
        result: None,
    }
}

#[async_trait]
impl JobStore for MemoryStore {
    fn durable(&self) -> bool {
        false
    }

    async fn insert(&self, job: JobRecord, scene: &str) -> Result<Inserted, StoreError> {
        self.with(|s| {
            if let Some(key) = &job.idempotency {
                if let Some(holder) = s.keys.get(&key.key) {
                    return Ok(Inserted::KeyTaken(Box::new(s.jobs[holder].record.clone())));
                }
                s.keys.insert(key.key.clone(), job.id.clone());
            }
            s.order.insert(s.next, job.id.clone());
            s.next += 1;
            let entry = Entry {
                record: job,
                scene: scene.to_string(),
                lease: None,
                cancel_requested: false,
                result: None,
            };
            s.jobs.insert(entry.record.id.clone(), entry);
            Ok(Inserted::New)
        })
    }

    async fn get(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError> {
        Ok(self.with(|s| s.jobs.get(id).map(|e| e.record.clone())))
    }

    async fn find_by_key(&self, key: &str) -> Result<Option<JobRecord>, StoreError> {
        Ok(self.with(|s| s.keys.get(key).map(|id| s.jobs[id].record.clone())))
    }

    async fn list(&self, page: Page) -> Result<Vec<JobRecord>, StoreError> {
        Ok(self.with(|s| {
            s.order
                .values()
                .rev()
                .skip(page.offset.try_into().unwrap_or(usize::MAX))
                .take(page.limit.try_into().unwrap_or(usize::MAX))
                .map(|id| s.jobs[id].record.clone())
                .collect()
        }))
    }

    async fn count_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError> {
        Ok(self.with(|s| {
            JobStatus::ALL
                .iter()
                .map(|&status| (status, s.jobs.values().filter(|e| e.record.status == status).count() as u64))
                .collect()
        }))
    }

    async fn count_queued(&self) -> Result<u64, StoreError> {
        Ok(self.with(|s| s.jobs.values().filter(|e| e.record.status == JobStatus::Queued).count() as u64))
    }

    async fn claim(
        &self,
        lease: &Lease,
        now_ms: u64,
        max_attempts: u32,
    ) -> Result<Option<Claim>, StoreError> {
        Ok(self.with(|s| {
            let id = s.order.values().find(|id| s.jobs[*id].claimable(now_ms))?.clone();
            let entry = s.jobs.get_mut(&id)?;
            if entry.record.attempts >= max_attempts {
                entry.end(
                    now_ms,
                    Outcome {
                        status: JobStatus::Failed,
                        steps_done: 0,
                        message: Some(attempts_exhausted(max_attempts)),
                        failure: Some(Failure::Attempts),
                        stats: None,
                        result: None,
                    },
                );
                let record = entry.record.clone();
                s.ended_one(self.retain);
                return Some(Claim::GaveUp(record));
            }
            entry.lease = Some(lease.clone());
            let record = &mut entry.record;
            record.status = JobStatus::Running;
            record.started_ms = Some(now_ms);
            record.steps_done = 0;
            record.attempts += 1;
            Some(Claim::Run(Claimed { record: record.clone(), scene: entry.scene.clone() }))
        }))
    }

    async fn renew(&self, id: &JobId, lease: &Lease, steps_done: u64) -> Result<Renewed, StoreError> {
        self.with(|s| {
            let entry = s.entry(id)?;
            if !entry.held_by(&lease.owner) {
                return Ok(Renewed::Lost);
            }
            entry.lease = Some(lease.clone());
            entry.record.steps_done = steps_done;
            Ok(Renewed::Held { cancel_requested: entry.cancel_requested })
        })
    }

    async fn finish(
        &self,
        id: &JobId,
        owner: &str,
        finished_ms: u64,
        outcome: Outcome,
    ) -> Result<bool, StoreError> {
        self.with(|s| {
            let entry = s.entry(id)?;
            if !entry.held_by(owner) {
                return Ok(false);
            }
            entry.end(finished_ms, outcome);
            s.ended_one(self.retain);
            Ok(true)
        })
    }

    async fn release(&self, id: &JobId, owner: &str) -> Result<(), StoreError> {
        self.with(|s| {
            let entry = s.entry(id)?;
            if entry.held_by(owner) {
                entry.lease = None;
                entry.record.status = JobStatus::Queued;
                entry.record.steps_done = 0;
                entry.record.attempts = entry.record.attempts.saturating_sub(1);
            }
            Ok(())
        })
    }

    async fn request_cancel(
        &self,
        id: &JobId,
        now_ms: u64,
        message: &str,
    ) -> Result<Option<CancelRequest>, StoreError> {
        Ok(self.with(|s| {
            let entry = s.jobs.get_mut(id)?;
            Some(if entry.record.status.is_final() {
                CancelRequest::AlreadyEnded(entry.record.clone())
            } else if entry.claimable(now_ms) {
                entry.end(now_ms, cancelled(entry.record.steps_done, message));
                let record = entry.record.clone();
                s.ended_one(self.retain);
                CancelRequest::Cancelled(record)
            } else {
                entry.cancel_requested = true;
                CancelRequest::Requested(entry.record.clone())
            })
        }))
    }

    async fn cancel_queued(&self, now_ms: u64, message: &str) -> Result<Vec<JobId>, StoreError> {
        Ok(self.with(|s| {
            let mut ids = Vec::new();
            for entry in s.jobs.values_mut().filter(|e| e.record.status == JobStatus::Queued) {
                entry.end(now_ms, cancelled(0, message));
                ids.push(entry.record.id.clone());
            }
            for _ in &ids {
                s.ended_one(self.retain);
            }
            ids
        }))
    }

    async fn drop_results(&self, before_ms: u64) -> Result<u64, StoreError> {
        Ok(self.with(|s| {
            let mut dropped = 0;
            for entry in s.jobs.values_mut() {
                if entry.result.is_some() && entry.record.finished_ms.is_some_and(|t| t < before_ms) {
                    entry.result = None;
                    dropped += 1;
                }
            }
            dropped
        }))
    }

    async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError> {
        Ok(self.with(|s| s.jobs.get(id).and_then(|e| e.result.clone())))
    }

    async fn put_asset(
        &self,
        asset: &AssetRecord,
        mesh: &[u8],
        room: AssetRoom,
    ) -> Result<PutAsset, StoreError> {
        Ok(self.with(|s| {
            if let Some((existing, _)) = s.assets.iter().find(|(a, _)| a.id == asset.id) {
                return PutAsset::Exists(existing.clone());
            }
            let assets = s.assets.len() as u64;
            let bytes = s.assets.iter().map(|(a, _)| a.bytes).sum::<u64>();
            if assets >= room.max_assets || bytes.saturating_add(asset.bytes) > room.max_bytes {
                return PutAsset::Full { assets, bytes };
            }
            s.assets.push((asset.clone(), mesh.to_vec()));
            PutAsset::Added
        }))
    }

    async fn asset(&self, id: &str) -> Result<Option<AssetRecord>, StoreError> {
        Ok(self.with(|s| s.assets.iter().find(|(a, _)| a.id == id).map(|(a, _)| a.clone())))
    }

    async fn asset_mesh(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        Ok(self.with(|s| s.assets.iter().find(|(a, _)| a.id == id).map(|(_, mesh)| mesh.clone())))
    }

    async fn list_assets(&self) -> Result<Vec<AssetRecord>, StoreError> {
        Ok(self.with(|s| s.assets.iter().rev().map(|(a, _)| a.clone()).collect()))
    }

    async fn delete_asset(&self, id: &str) -> Result<bool, StoreError> {
        Ok(self.with(|s| {
            let before = s.assets.len();
            s.assets.retain(|(a, _)| a.id != id);
            s.assets.len() < before
        }))
    }

    async fn insert_sweep(&self, sweep: &SweepEntry, document: &str) -> Result<InsertedSweep, StoreError> {
        let queued = || RunState {
            stored: StoredRun { status: JobStatus::Queued, message: None, result: None },
            attempts: 0,
            lease: None,
            cancel_requested: false,
        };
        Ok(self.with(|s| {
            if let Some(holder) = sweep.idempotency.as_ref().and_then(|key| s.sweep_keyed(&key.key)) {
                return InsertedSweep::KeyTaken(Box::new(holder.summary()));
            }
            s.sweeps.push(SweepState {
                entry: sweep.clone(),
                document: document.to_string(),
                cancel_requested: false,
                runs: (0..sweep.runs).map(|_| queued()).collect(),
            });
            InsertedSweep::New
        }))
    }

    async fn find_sweep_by_key(&self, key: &str) -> Result<Option<SweepSummary>, StoreError> {
        Ok(self.with(|s| s.sweep_keyed(key).map(SweepState::summary)))
    }

    async fn sweep(&self, id: &JobId) -> Result<Option<SweepSummary>, StoreError> {
        Ok(self.with(|s| s.sweep(id).map(SweepState::summary)))
    }

    async fn sweep_document(&self, id: &JobId) -> Result<Option<String>, StoreError> {
        Ok(self.with(|s| s.sweep(id).map(|sweep| sweep.document.clone())))
    }

    async fn list_sweeps(&self, page: Page) -> Result<Vec<SweepSummary>, StoreError> {
        let skip = usize::try_from(page.offset).unwrap_or(usize::MAX);
        let take = usize::try_from(page.limit).unwrap_or(usize::MAX);
        Ok(self.with(|s| s.sweeps.iter().rev().skip(skip).take(take).map(SweepState::summary).collect()))
    }

    async fn sweep_runs(&self, id: &JobId) -> Result<Vec<StoredRun>, StoreError> {
        Ok(self.with(|s| {
            s.sweep(id).map(|sweep| sweep.runs.iter().map(|r| r.stored.clone()).collect()).unwrap_or_default()
        }))
    }

    async fn claim_sweep_runs(
        &self,
        lease: &Lease,
        now_ms: u64,
        max_runs: u32,
    ) -> Result<Option<ClaimedRuns>, StoreError> {
        Ok(self.with(|s| {
            let sweep = s.sweeps.iter_mut().find(|sweep| sweep.runs.iter().any(|r| r.claimable(now_ms)))?;
            let mut claimed = Vec::new();
            for (index, run) in sweep.runs.iter_mut().enumerate() {
                if claimed.len() >= max_runs as usize {
                    break;
                }
                if run.claimable(now_ms) {
                    run.stored.status = JobStatus::Running;
                    run.lease = Some(lease.clone());
                    run.attempts += 1;
                    claimed.push(ClaimedRun {
                        index: index as u32,
                        attempts: run.attempts,
                        cancel_requested: run.cancel_requested,
                    });
                }
            }
            Some(ClaimedRuns { sweep: sweep.entry.id.clone(), runs: claimed })
        }))
    }

    async fn renew_sweep_runs(&self, lease: &Lease) -> Result<Vec<HeldRun>, StoreError> {
        Ok(self.with(|s| {
            let mut held = Vec::new();
            for sweep in &mut s.sweeps {
                for (index, run) in sweep.runs.iter_mut().enumerate() {
                    if run.held_by(&lease.owner) {
                        run.lease = Some(lease.clone());
                        held.push(HeldRun {
                            sweep: sweep.entry.id.clone(),
                            index: index as u32,
                            cancel_requested: run.cancel_requested,
                        });
                    }
                }
            }
            held
        }))
    }

    async fn finish_sweep_run(&self, sweep: &JobId, owner: &str, end: RunEnd) -> Result<bool, StoreError> {
        Ok(self.with(|s| {
            let Some(run) = s.sweep_mut(sweep).and_then(|sweep| sweep.runs.get_mut(end.index as usize))
            else {
                return false;
            };
            if !run.held_by(owner) {
                return false;
            }
            run.stored = StoredRun { status: end.status, message: end.message, result: end.result };
            run.lease = None;
            true
        }))
    }

    async fn release_sweep_runs(&self, sweep: &JobId, owner: &str, runs: &[u32]) -> Result<(), StoreError> {
        self.with(|s| {
            let Some(sweep) = s.sweep_mut(sweep) else { return };
            for &index in runs {
                if let Some(run) = sweep.runs.get_mut(index as usize).filter(|run| run.held_by(owner)) {
                    run.stored.status = JobStatus::Queued;
                    run.attempts = run.attempts.saturating_sub(1);
                    run.lease = None;
                }
            }
        });
        Ok(())
    }

    async fn cancel_sweep(
        &self,
        id: &JobId,
        now_ms: u64,
        message: &str,
    ) -> Result<Option<SweepSummary>, StoreError> {
        Ok(self.with(|s| {
            let sweep = s.sweep_mut(id)?;
            sweep.cancel_requested = true;
            for run in &mut sweep.runs {
                if run.claimable(now_ms) {
                    run.stored = StoredRun {
                        status: JobStatus::Cancelled,
                        message: Some(message.into()),
                        result: None,
                    };
                    run.lease = None;
                } else if run.stored.status == JobStatus::Running {
                    run.cancel_requested = true;
                }
            }
            Some(sweep.summary())
        }))
    }
}

impl State {
    fn sweep(&self, id: &JobId) -> Option<&SweepState> {
        self.sweeps.iter().find(|sweep| &sweep.entry.id == id)
    }

    fn sweep_keyed(&self, key: &str) -> Option<&SweepState> {
        self.sweeps.iter().find(|sweep| sweep.entry.idempotency.as_ref().is_some_and(|i| i.key == key))
    }

    fn sweep_mut(&mut self, id: &JobId) -> Option<&mut SweepState> {
        self.sweeps.iter_mut().find(|sweep| &sweep.entry.id == id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::record::{Idempotency, Plan};

    fn job(key: &str) -> JobRecord {
        let plan = Plan { particles: 1, springs: 0, steps: 1, companion_steps: 0, dt: 1.0, duration: 1.0 };
        JobRecord::queued(JobId::new(), plan, Some(Idempotency { key: key.into(), fingerprint: 0 }))
    }

    fn ended() -> Outcome {
        Outcome {
            status: JobStatus::Succeeded,
            steps_done: 1,
            message: None,
            failure: None,
            stats: None,
            result: None,
        }
    }

    fn block_on<F: std::future::Future>(future: F) -> F::Output {
        futures_util::FutureExt::now_or_never(future).expect("the memory store never waits")
    }

    #[test]
    fn only_the_most_recent_ended_jobs_are_kept() {
        let store = MemoryStore::retaining(2);
        let jobs: Vec<JobRecord> = ["a", "b", "c", "d"].map(job).into();
        let lease = Lease { owner: "me".into(), until_ms: u64::MAX };
        for j in &jobs {
            assert_eq!(block_on(store.insert(j.clone(), "{}")).unwrap(), Inserted::New);
            block_on(store.claim(&lease, 0, 3)).unwrap().unwrap();
        }
        // a stays running; b, c and d end in that order, so b is forgotten.
        for j in &jobs[1..] {
            assert!(block_on(store.finish(&j.id, "me", 0, ended())).unwrap());
        }
        let kept: Vec<JobId> =
            block_on(store.list(Page { offset: 0, limit: 10 })).unwrap().into_iter().map(|j| j.id).collect();
        assert_eq!(kept, [jobs[3].id.clone(), jobs[2].id.clone(), jobs[0].id.clone()]);
        assert!(block_on(store.get(&jobs[1].id)).unwrap().is_none());
        // The forgotten job's idempotency key is free again.
        assert!(block_on(store.find_by_key("b")).unwrap().is_none());
        assert!(block_on(store.find_by_key("c")).unwrap().is_some());
    }
}
