//! The in-memory job store: a map behind one mutex, for tests and single-process use.
//!
//! Everything is lost when the process ends. The lock is held only to copy a record in or out,
//! never across an `await`.

use std::collections::{BTreeMap, HashMap};
use std::sync::Mutex;

use async_trait::async_trait;

use super::store::{Inserted, JobStore, Outcome, Page, StoreError, StoredResult};
use super::{JobId, JobRecord, JobStatus};

/// Jobs in a map, in submission order.
#[derive(Default)]
pub struct MemoryStore {
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
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
    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        let mut state = self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        f(&mut state)
    }
}

impl State {
    fn entry(&mut self, id: &JobId) -> Result<&mut Entry, StoreError> {
        self.jobs.get_mut(id).ok_or_else(|| StoreError::NotFound(id.clone()))
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
        self.with(|s| {
            let entry = s.entry(id)?;
            let record = &mut entry.record;
            record.status = outcome.status;
            record.finished_ms = Some(finished_ms);
            record.steps_done = outcome.steps_done;
            record.message = outcome.message;
            record.failure = outcome.failure;
            record.stats = outcome.stats;
            entry.result = outcome.result;
            Ok(())
        })
    }

    async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError> {
        Ok(self.with(|s| s.jobs.get(id).and_then(|e| e.result.clone())))
    }
}
