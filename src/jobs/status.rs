//! The life of a job: `queued`, `running`, then one of the end states.

use serde::{Deserialize, Serialize};

/// Where a job is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JobStatus {
    /// Waiting for a worker.
    Queued,
    /// A worker is stepping it.
    Running,
    /// Ran to the end (or to rest); the result is ready.
    Succeeded,
    /// Stopped without a result: it panicked, exceeded its wall time, or could not be stored.
    Failed,
    /// The simulation blew up; the result up to the last finite frame is ready.
    Diverged,
    /// Stopped because a client (or shutdown) asked.
    Cancelled,
}

impl JobStatus {
    /// Every status, in life order.
    pub const ALL: [Self; 6] =
        [Self::Queued, Self::Running, Self::Succeeded, Self::Failed, Self::Diverged, Self::Cancelled];

    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Queued => "queued",
            Self::Running => "running",
            Self::Succeeded => "succeeded",
            Self::Failed => "failed",
            Self::Diverged => "diverged",
            Self::Cancelled => "cancelled",
        }
    }

    /// Whether the job has ended and will not change again.
    pub fn is_final(self) -> bool {
        !matches!(self, Self::Queued | Self::Running)
    }
}

/// Why a job failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Failure {
    /// It ran longer than the wall-time limit: the scene asks for more than this server gives.
    WallTime,
    /// The simulation panicked: a defect in drape.
    Panicked,
    /// The result could not be encoded.
    Encoding,
    /// It was started `--max-attempts` times and never ended: each run crashed its instance or
    /// lost it, so it is not run again.
    Attempts,
    /// A stage whose size is known only as it runs (self-collision's pairs) met more than the
    /// job may hold.
    Limit,
}

impl Failure {
    /// Every kind of failure.
    pub const ALL: [Self; 5] = [Self::WallTime, Self::Panicked, Self::Encoding, Self::Attempts, Self::Limit];

    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::WallTime => "wall_time",
            Self::Panicked => "panicked",
            Self::Encoding => "encoding",
            Self::Attempts => "attempts",
            Self::Limit => "limit",
        }
    }
}
