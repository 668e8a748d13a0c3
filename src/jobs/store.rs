//! The job store: where jobs, their status and progress, and their results live.
//!
//! A trait with async methods, so a database backend (which does its I/O on the async runtime)
//! fits as well as the in-memory one. The queue and the workers hold a `dyn JobStore`; worker
//! threads, which are not runtime threads, drive its futures with the runtime's handle. Results
//! are stored once, already encoded, and served as they are.

use async_trait::async_trait;
use bytes::Bytes;
use thiserror::Error;

use super::{Failure, JobId, JobRecord, JobStatus};

/// A stored result: the encoded bytes and their media type.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredResult {
    /// The media type of `bytes`, e.g. `application/json`.
    pub media_type: &'static str,
    /// The encoded result.
    pub bytes: Bytes,
}

/// How a job ended.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The end state.
    pub status: JobStatus,
    /// Steps taken.
    pub steps_done: u64,
    /// Why it failed or was cancelled.
    pub message: Option<String>,
    /// What kind of failure, for a failed job.
    pub failure: Option<Failure>,
    /// The result's `stats` object.
    pub stats: Option<serde_json::Value>,
    /// The encoded result, if the job ended with one.
    pub result: Option<StoredResult>,
}

/// What [`JobStore::insert`] did.
#[derive(Clone, Debug, PartialEq)]
pub enum Inserted {
    /// The job was added.
    New,
    /// Another job already holds the job's idempotency key; nothing was added.
    KeyTaken(Box<JobRecord>),
}

/// A page of the job listing, newest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Page {
    /// Jobs to skip.
    pub offset: u64,
    /// Jobs to return at most.
    pub limit: u64,
}

/// A store that could not do what was asked.
#[derive(Debug, Error)]
pub enum StoreError {
    /// The job is not in the store.
    #[error("no job {0}")]
    NotFound(JobId),
    /// The backend failed (a database error, a lost connection).
    #[error("job store failure: {0}")]
    Backend(String),
}

/// Where jobs live. Every method is atomic with respect to the others.
#[async_trait]
pub trait JobStore: Send + Sync + 'static {
    /// Adds a queued job, unless its idempotency key is already held by another job.
    async fn insert(&self, job: JobRecord) -> Result<Inserted, StoreError>;

    /// The job with this id.
    async fn get(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError>;

    /// The job that holds this idempotency key.
    async fn find_by_key(&self, key: &str) -> Result<Option<JobRecord>, StoreError>;

    /// Jobs, newest first.
    async fn list(&self, page: Page) -> Result<Vec<JobRecord>, StoreError>;

    /// How many jobs there are in each status.
    async fn count_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError>;

    /// Marks a queued job as started.
    async fn mark_running(&self, id: &JobId, started_ms: u64) -> Result<(), StoreError>;

    /// Records the steps a running job has taken; ignored once the job has ended.
    async fn set_progress(&self, id: &JobId, steps_done: u64) -> Result<(), StoreError>;

    /// Records how a job ended, with its result if it has one.
    async fn finish(&self, id: &JobId, finished_ms: u64, outcome: Outcome) -> Result<(), StoreError>;

    /// The result of an ended job.
    async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError>;
}
