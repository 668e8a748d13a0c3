//! What the store keeps about a job: its plan, its status and progress, and how it ended.

use std::time::{SystemTime, UNIX_EPOCH};

use super::id::JobId;
use super::status::{Failure, JobStatus};

/// One job as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct JobRecord {
    /// Its id.
    pub id: JobId,
    /// Where it is in its life.
    pub status: JobStatus,
    /// When it was submitted, in milliseconds since the Unix epoch.
    pub created_ms: u64,
    /// When a worker started it.
    pub started_ms: Option<u64>,
    /// When it ended.
    pub finished_ms: Option<u64>,
    /// The size of the run, known before it starts.
    pub plan: Plan,
    /// Steps taken so far, as last published.
    pub steps_done: u64,
    /// Why it failed or was cancelled, in words for a user.
    pub message: Option<String>,
    /// What kind of failure, for a failed job.
    pub failure: Option<Failure>,
    /// The result's `stats` object, once it ended with a result.
    pub stats: Option<serde_json::Value>,
    /// The `Idempotency-Key` it was submitted with, and the fingerprint of its body.
    pub idempotency: Option<Idempotency>,
    /// How many times a worker started it: more than one if an instance died while running it.
    pub attempts: u32,
}

/// The size of a run, worked out from the scene before it is queued.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Particles.
    pub particles: u64,
    /// Springs.
    pub springs: u64,
    /// Steps to take.
    pub steps: u64,
    /// Steps of the error estimate's companion runs, at coarser steps beside the main run.
    pub companion_steps: u64,
    /// The step, in seconds.
    pub dt: f64,
    /// Simulated time, in seconds.
    pub duration: f64,
}

impl Plan {
    /// Particle-steps: the work of the run, companions included.
    pub fn work(&self) -> u64 {
        self.particles.saturating_mul(self.steps.saturating_add(self.companion_steps))
    }
}

/// An idempotency key and the fingerprint of the body first sent with it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Idempotency {
    /// The key, as the client sent it.
    pub key: String,
    /// [`fingerprint`](super::fingerprint) of the scene document.
    pub fingerprint: u64,
}

impl JobRecord {
    /// A job just submitted.
    pub fn queued(id: JobId, plan: Plan, idempotency: Option<Idempotency>) -> Self {
        Self {
            id,
            status: JobStatus::Queued,
            created_ms: now_ms(),
            started_ms: None,
            finished_ms: None,
            plan,
            steps_done: 0,
            message: None,
            failure: None,
            stats: None,
            idempotency,
            attempts: 0,
        }
    }
}

/// The wall clock, in milliseconds since the Unix epoch.
pub fn now_ms() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_millis() as u64)
}
