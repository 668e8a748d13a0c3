//! Jobs: the queue, the worker pool, cancellation, progress and the job store.
//!
//! [`Jobs`] admits a scene against the [`Limits`], stores a [`JobRecord`] in a [`JobStore`] and
//! queues it for a fixed pool of worker threads, which run it with
//! [`run::execute`](crate::run::execute) off the async runtime. A panic fails only its job; a
//! watchdog stops jobs past their wall time; progress comes from the run's lock-free
//! [`Control`](crate::run::Control). Results are encoded once and kept in the store. [`Sweeps`] queues
//! every run of a sweep as a job and assembles its table from their results. The HTTP API talks
//! to this module, never to the solver.

mod encode;
mod fingerprint;
mod id;
mod limits;
mod memory;
mod pool;
mod queue;
mod record;
mod service;
mod status;
mod store;
mod sweeps;

pub use encode::encode_result;
pub use fingerprint::fingerprint;
pub use id::JobId;
pub use limits::Limits;
pub use memory::MemoryStore;
pub use record::{Idempotency, JobRecord, Plan, now_ms};
pub use service::{BeforeRun, Cancelled, Jobs, JobsConfig, Submission, SubmitError, Submitted};
pub use status::{Failure, JobStatus};
pub use store::{Inserted, JobStore, Outcome, Page, StoreError, StoredResult};
pub use sweeps::{SweepRecord, SweepState, SweepSubmitError, Sweeps};
