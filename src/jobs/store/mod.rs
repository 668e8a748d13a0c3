//! The job store: where jobs, their status and progress, and their results live, and the queue
//! that workers claim jobs from.
//!
//! A trait with async methods, so a database backend (which does its I/O on the async runtime)
//! fits as well as the in-memory one. The queue and the workers hold a `dyn JobStore`; worker
//! threads, which are not runtime threads, drive its futures with the runtime's handle. Results
//! are stored once, already encoded, and served as they are.
//!
//! Workers take jobs with [`JobStore::claim`], which hands a queued job, or a running one whose
//! lease lapsed, to one owner (a drape instance) until its lease expires; the owner renews the
//! lease while it runs the job, learns there whether a cancellation was asked for, and records
//! the end only while it still holds the job. So several instances can share one store, and a
//! job whose instance died runs again elsewhere.
//!
//! A claim counts an attempt in the same atomic step that hands the job over, so a claim that
//! cannot be committed (a full disk) hands nothing over. A job claimed after `max_attempts`
//! starts that never ended (each crashed or lost its instance) is not handed over but failed:
//! it may be what crashes the instances. A job released at shutdown gets its attempt back.
//!
//! A sweep is one entry ([`SweepEntry`], with its document) and a row per run: workers claim a
//! batch of one sweep's runs at once under a lease ([`JobStore::claim_sweep_runs`]), counting an
//! attempt like a job's claim, and store the ends of the runs they ran together
//! ([`JobStore::finish_sweep_runs`]).
//!
//! The backends are [`MemoryStore`], [`SqliteStore`] (the default) and [`PostgresStore`]
//! (several instances, one queue); the two SQL ones share their statements (`sql`), and
//! [`StoreUrl`] picks and opens one.

use async_trait::async_trait;
use bytes::Bytes;
use thiserror::Error;

mod memory;
mod open;
mod postgres;
mod sql;
mod sqlite;
mod sweep_rows;

pub use memory::MemoryStore;
pub use open::StoreUrl;
pub use postgres::PostgresStore;
pub use sqlite::SqliteStore;
pub use sweep_rows::{
    ClaimedRun, ClaimedRuns, HeldRun, InsertedSweep, RunEnd, StoredRun, SweepEntry, SweepSummary,
};

use crate::jobs::id::JobId;
use crate::jobs::record::JobRecord;
use crate::jobs::status::{Failure, JobStatus};

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

/// A job handed to a worker by [`JobStore::claim`].
#[derive(Clone, Debug, PartialEq)]
pub struct Claimed {
    /// The job, now `running`, its `attempts` counting this one.
    pub record: JobRecord,
    /// The scene document it was submitted with, as JSON text.
    pub scene: String,
}

/// What [`JobStore::claim`] took from the queue.
#[derive(Clone, Debug, PartialEq)]
pub enum Claim {
    /// A job to run.
    Run(Claimed),
    /// A job already started `max_attempts` times without ending: it is now `failed`
    /// ([`Failure::Attempts`], [`attempts_exhausted`] as its message) and is not run.
    GaveUp(JobRecord),
}

/// The message of a job given up after `max_attempts` starts.
pub fn attempts_exhausted(max_attempts: u32) -> String {
    format!(
        "the job was started {max_attempts} times without ending (--max-attempts {max_attempts}): \
         it may crash the server"
    )
}

/// Who holds a claimed job, and until when.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Lease {
    /// The instance that holds it.
    pub owner: String,
    /// When the hold lapses unless renewed, in milliseconds since the Unix epoch.
    pub until_ms: u64,
}

/// What [`JobStore::renew`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Renewed {
    /// The lease was extended; `cancel_requested` says whether a client asked to cancel.
    Held {
        /// A client asked to cancel the job.
        cancel_requested: bool,
    },
    /// The job is no longer this owner's: its lease lapsed and it was claimed again, or it ended.
    Lost,
}

/// What [`JobStore::request_cancel`] did.
#[derive(Clone, Debug, PartialEq)]
pub enum CancelRequest {
    /// The job was not running (queued, or its lease had lapsed): it is now cancelled.
    Cancelled(JobRecord),
    /// The job is running under a live lease: its owner will stop it at its next renewal.
    Requested(JobRecord),
    /// The job had already ended.
    AlreadyEnded(JobRecord),
}

/// An uploaded mesh as the store lists it (its mesh is read with [`JobStore::asset_mesh`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AssetRecord {
    /// `sha256:` and the hex SHA-256 of the uploaded bytes.
    pub id: String,
    /// Vertices of the mesh.
    pub vertices: u64,
    /// Triangles of the mesh.
    pub triangles: u64,
    /// Size of the uploaded file.
    pub bytes: u64,
    /// When it was first uploaded, in milliseconds since the Unix epoch.
    pub created_ms: u64,
}

/// Room the assets may take in the store: [`JobStore::put_asset`] adds none past it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AssetRoom {
    /// Assets at most.
    pub max_assets: u64,
    /// Uploaded bytes of all assets together at most.
    pub max_bytes: u64,
}

/// What [`JobStore::put_asset`] did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PutAsset {
    /// The asset was added.
    Added,
    /// An asset with its id (the same bytes) was already stored; this is it.
    Exists(AssetRecord),
    /// Adding it would pass the [`AssetRoom`]; the store holds this many assets and bytes.
    Full {
        /// Assets stored.
        assets: u64,
        /// Their uploaded bytes.
        bytes: u64,
    },
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
    /// Whether jobs outlive this process (a database), so a shutdown leaves queued jobs queued.
    fn durable(&self) -> bool;

    /// Adds a queued job with its scene document, unless its idempotency key is already held.
    async fn insert(&self, job: JobRecord, scene: &str) -> Result<Inserted, StoreError>;

    /// The job with this id.
    async fn get(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError>;

    /// The job that holds this idempotency key.
    async fn find_by_key(&self, key: &str) -> Result<Option<JobRecord>, StoreError>;

    /// Jobs, newest first.
    async fn list(&self, page: Page) -> Result<Vec<JobRecord>, StoreError>;

    /// How many jobs there are in each status.
    async fn count_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError>;

    /// How many jobs wait for a worker.
    async fn count_queued(&self) -> Result<u64, StoreError>;

    /// Takes the oldest job that is queued, or running under a lease that lapsed before `now_ms`,
    /// marks it running under `lease` and counts the attempt, all in one atomic step that is
    /// committed before it returns; `None` if there is none. A job whose `attempts` already
    /// reached `max_attempts` is failed instead ([`Claim::GaveUp`]).
    async fn claim(&self, lease: &Lease, now_ms: u64, max_attempts: u32)
    -> Result<Option<Claim>, StoreError>;

    /// Extends the lease of a job `lease.owner` holds and records its progress.
    async fn renew(&self, id: &JobId, lease: &Lease, steps_done: u64) -> Result<Renewed, StoreError>;

    /// Records how a job ended, with its result, if `owner` still holds it; returns whether it did.
    async fn finish(
        &self,
        id: &JobId,
        owner: &str,
        finished_ms: u64,
        outcome: Outcome,
    ) -> Result<bool, StoreError>;

    /// Puts a job `owner` holds back in the queue, to run again from the start; the attempt it
    /// was claimed with is not counted.
    async fn release(&self, id: &JobId, owner: &str) -> Result<(), StoreError>;

    /// Cancels a job: at once if it is not running under a live lease at `now_ms`, otherwise by
    /// flagging it for its owner. `None` if there is no such job.
    async fn request_cancel(
        &self,
        id: &JobId,
        now_ms: u64,
        message: &str,
    ) -> Result<Option<CancelRequest>, StoreError>;

    /// Cancels every queued job; returns their ids.
    async fn cancel_queued(&self, now_ms: u64, message: &str) -> Result<Vec<JobId>, StoreError>;

    /// Drops the results of jobs that ended before `before_ms`; returns how many.
    async fn drop_results(&self, before_ms: u64) -> Result<u64, StoreError>;

    /// The result of an ended job.
    async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError>;

    /// Adds an uploaded mesh with its compact form, unless one with its id is stored or it
    /// would pass `room`; the check and the insertion are one statement.
    async fn put_asset(
        &self,
        asset: &AssetRecord,
        mesh: &[u8],
        room: AssetRoom,
    ) -> Result<PutAsset, StoreError>;

    /// The asset with this id.
    async fn asset(&self, id: &str) -> Result<Option<AssetRecord>, StoreError>;

    /// The compact form of the asset with this id.
    async fn asset_mesh(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError>;

    /// Every asset, newest first.
    async fn list_assets(&self) -> Result<Vec<AssetRecord>, StoreError>;

    /// Deletes an asset; returns whether there was one.
    async fn delete_asset(&self, id: &str) -> Result<bool, StoreError>;

    /// Adds a sweep with its document and a queued row for each of its runs, unless its
    /// idempotency key is already held.
    async fn insert_sweep(&self, sweep: &SweepEntry, document: &str) -> Result<InsertedSweep, StoreError>;

    /// The sweep that holds this idempotency key.
    async fn find_sweep_by_key(&self, key: &str) -> Result<Option<SweepSummary>, StoreError>;

    /// The sweep with this id, with how far its runs have got.
    async fn sweep(&self, id: &JobId) -> Result<Option<SweepSummary>, StoreError>;

    /// The document the sweep was submitted with.
    async fn sweep_document(&self, id: &JobId) -> Result<Option<String>, StoreError>;

    /// Sweeps, newest first.
    async fn list_sweeps(&self, page: Page) -> Result<Vec<SweepSummary>, StoreError>;

    /// Every run of a sweep, in run order; empty if there is no such sweep.
    async fn sweep_runs(&self, id: &JobId) -> Result<Vec<StoredRun>, StoreError>;

    /// Takes up to `max_runs` runs of the oldest sweep with runs queued, or running under a lease
    /// that lapsed before `now_ms`, marks them running under `lease` and counts an attempt for
    /// each, in one atomic step committed before it returns; `None` if there are none.
    async fn claim_sweep_runs(
        &self,
        lease: &Lease,
        now_ms: u64,
        max_runs: u32,
    ) -> Result<Option<ClaimedRuns>, StoreError>;

    /// Extends the lease of every run `lease.owner` holds; returns them.
    async fn renew_sweep_runs(&self, lease: &Lease) -> Result<Vec<HeldRun>, StoreError>;

    /// Records how a run ended, if `owner` still holds it; returns whether it did.
    async fn finish_sweep_run(&self, sweep: &JobId, owner: &str, end: RunEnd) -> Result<bool, StoreError>;

    /// Records how each of `ends` ended, for the runs `owner` still holds, in one transaction
    /// where the backend has them; returns how many it recorded.
    async fn finish_sweep_runs(
        &self,
        sweep: &JobId,
        owner: &str,
        ends: Vec<RunEnd>,
    ) -> Result<usize, StoreError> {
        let mut recorded = 0;
        for end in ends {
            recorded += usize::from(self.finish_sweep_run(sweep, owner, end).await?);
        }
        Ok(recorded)
    }

    /// Puts runs `owner` holds back in the queue; the attempts they were claimed with are not
    /// counted.
    async fn release_sweep_runs(&self, sweep: &JobId, owner: &str, runs: &[u32]) -> Result<(), StoreError>;

    /// Cancels a sweep: its queued runs (and running ones whose lease lapsed before `now_ms`) end
    /// `cancelled` with `message` at once, and those running under a live lease are flagged for
    /// their holder. `None` if there is no such sweep.
    async fn cancel_sweep(
        &self,
        id: &JobId,
        now_ms: u64,
        message: &str,
    ) -> Result<Option<SweepSummary>, StoreError>;
}
