//! The in-memory job store: a map behind one mutex, for tests and single-process use.
//!
//! Everything is lost when the process ends. Only the most recent ended jobs are kept (with
//! their results), so memory stays bounded; queued and running jobs are never dropped. The lock
//! is held only to copy a record in or out, never across an `await`.

use std::collections::{BTreeMap, HashMap};
use std::sync::Mutex;

use async_trait::async_trait;

use super::store::{Inserted, JobStore, Outcome, Page, StoreError, StoredResult};
use super::{JobId, JobRecord, JobStatus};

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
}

struct Entry {
    record: JobRecord,
    result: Option<StoredResult>,
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

    /// Forgets the oldest ended jobs until at most `retain` are left.
    fn evict(&mut self, retain: usize) {
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

#[async_trait]
impl JobStore for MemoryStore {
    async fn insert(&self, job: JobRecord) -> Result<Inserted, StoreError> {
        self.with(|s| {
            if let Some(key) = &job.idempotency {
                if let Some(holder) = s.keys.get(&key.key) {
                    return Ok(Inserted::KeyTaken(Box::new(s.jobs[holder].record.clone())));
                }
                s.keys.insert(key.key.clone(), job.id.clone());
            }
            s.order.insert(s.next, job.id.clone());
            s.next += 1;
            s.jobs.insert(job.id.clone(), Entry { record: job, result: None });
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

    async fn mark_running(&self, id: &JobId, started_ms: u64) -> Result<(), StoreError> {
        self.with(|s| {
            let record = &mut s.entry(id)?.record;
            record.status = JobStatus::Running;
            record.started_ms = Some(started_ms);
            Ok(())
        })
    }

    async fn set_progress(&self, id: &JobId, steps_done: u64) -> Result<(), StoreError> {
        self.with(|s| {
            let record = &mut s.entry(id)?.record;
            if record.status == JobStatus::Running {
                record.steps_done = steps_done;
            }
            Ok(())
        })
    }

    async fn finish(&self, id: &JobId, finished_ms: u64, outcome: Outcome) -> Result<(), StoreError> {
        let retain = self.retain;
        self.with(|s| {
            let entry = s.entry(id)?;
            let newly_ended = !entry.record.status.is_final();
            let record = &mut entry.record;
            record.status = outcome.status;
            record.finished_ms = Some(finished_ms);
            record.steps_done = outcome.steps_done;
            record.message = outcome.message;
            record.failure = outcome.failure;
            record.stats = outcome.stats;
            entry.result = outcome.result;
            if newly_ended {
                s.ended += 1;
                s.evict(retain);
            }
            Ok(())
        })
    }

    async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError> {
        Ok(self.with(|s| s.jobs.get(id).and_then(|e| e.result.clone())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::{Idempotency, Plan};

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
        for j in &jobs {
            assert_eq!(block_on(store.insert(j.clone())).unwrap(), Inserted::New);
        }
        // a stays queued; b, c and d end in that order, so b is forgotten.
        for j in &jobs[1..] {
            block_on(store.finish(&j.id, 0, ended())).unwrap();
        }
        let kept: Vec<JobId> =
            block_on(store.list(Page { offset: 0, limit: 10 })).unwrap().into_iter().map(|j| j.id).collect();
        assert_eq!(kept, [jobs[3].id.clone(), jobs[2].id.clone(), jobs[0].id.clone()]);
        assert!(block_on(store.get(&jobs[1].id)).unwrap().is_none());
        // The forgotten job's idempotency key is free again.
        assert!(block_on(store.find_by_key("b")).unwrap().is_none());
        assert!(block_on(store.find_by_key("c")).unwrap().is_some());
    }

    #[test]
    fn a_taken_key_returns_the_job_holding_it() {
        let store = MemoryStore::new();
        let first = job("k");
        block_on(store.insert(first.clone())).unwrap();
        assert_eq!(block_on(store.insert(job("k"))).unwrap(), Inserted::KeyTaken(Box::new(first)));
    }
}
