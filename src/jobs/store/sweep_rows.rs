//! What the store keeps of a sweep: its entry (the document it was submitted with, and how many
//! runs it makes) and one row per run, claimed under a lease like a job.
//!
//! Runs are numbered in table order: the reference is run 0 when the sweep has one, then the
//! variants. A run's row keeps only what the table needs: its status, why it failed or stopped,
//! and its result (the final positions and statistics, as the JSON a job's result would be).

use bytes::Bytes;

use crate::jobs::id::JobId;
use crate::jobs::record::Idempotency;
use crate::jobs::status::JobStatus;

/// A sweep as stored, without its document.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SweepEntry {
    /// Its id.
    pub id: JobId,
    /// When it was submitted, in milliseconds since the Unix epoch.
    pub created_ms: u64,
    /// Runs it makes, the reference included.
    pub runs: u32,
    /// Whether run 0 is the reference.
    pub has_reference: bool,
    /// The client's `Idempotency-Key`, with the fingerprint of the document first sent with it.
    pub idempotency: Option<Idempotency>,
}

/// What [`JobStore::insert_sweep`](super::JobStore::insert_sweep) did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InsertedSweep {
    /// The sweep was added.
    New,
    /// Another sweep already holds the sweep's idempotency key; nothing was added.
    KeyTaken(Box<SweepSummary>),
}

/// A sweep and how far its runs have got.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SweepSummary {
    /// The sweep.
    pub entry: SweepEntry,
    /// A client asked to cancel it.
    pub cancel_requested: bool,
    /// Runs that have ended.
    pub finished: u32,
    /// Runs a worker holds now.
    pub running: u32,
}

impl SweepSummary {
    /// Whether every run has ended.
    pub fn is_complete(&self) -> bool {
        self.finished >= self.entry.runs
    }
}

/// Runs of one sweep handed to a worker by [`JobStore::claim_sweep_runs`](super::JobStore::claim_sweep_runs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClaimedRuns {
    /// The sweep.
    pub sweep: JobId,
    /// The runs, in run order.
    pub runs: Vec<ClaimedRun>,
}

/// One claimed run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClaimedRun {
    /// Its number in the sweep.
    pub index: u32,
    /// Its starts, this one included.
    pub attempts: u32,
    /// Its sweep was cancelled while an earlier holder ran it: it is to be ended, not run.
    pub cancel_requested: bool,
}

/// A run held by an instance, as [`JobStore::renew_sweep_runs`](super::JobStore::renew_sweep_runs) found it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HeldRun {
    /// Its sweep.
    pub sweep: JobId,
    /// Its number in the sweep.
    pub index: u32,
    /// A client asked to cancel its sweep.
    pub cancel_requested: bool,
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub struct RunEnd {
    /// Its number in the sweep.
    pub index: u32,
    /// The end state.
    pub status: JobStatus,
    /// Why it failed or stopped.
    pub message: Option<String>,
    /// Its result as JSON (final positions and statistics), if it ended with one.
    pub result: Option<Bytes>,
}

/// A run as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredRun {
    /// Where it is in its life.
    pub status: JobStatus,
    /// Why it failed or stopped.
    pub message: Option<String>,
    /// Its result as JSON, once it ended with one.
    pub result: Option<Bytes>,
}
