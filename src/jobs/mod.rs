//! Jobs: the queue, the worker pool, cancellation, progress and the job store.
//!
//! [`Jobs`] admits a scene against the [`Limits`] and stores it as a queued [`JobRecord`] in a
//! [`JobStore`], which is also the queue: a fixed pool of worker threads claims jobs from the
//! store under a lease and runs them with [`run::execute`](crate::run::execute) off the async
//! runtime. A panic fails only its job; a watchdog stops jobs past their wall time, renews the
//! leases of running jobs, copies their progress (from the run's lock-free
//! [`Control`](crate::run::Control)) to the store and picks up cancellations asked of other
//! instances. Results are encoded once and kept in the store, compressed, until the retention
//! time. The stores live in [`store`]: [`MemoryStore`], [`SqliteStore`] (the default) and
//! [`PostgresStore`] (several instances, one queue); [`StoreUrl`] picks one. The HTTP API talks
//! to this module, never to the solver.
//! [`Jobs::submit_sweep`] stores a sweep as one entry with a row per run; workers run its runs
//! in batches when no job is queued, and its table is assembled from the runs' stored outcomes.
//! [`Jobs::upload_asset`] keeps uploaded meshes in the store, and [`Jobs::resolve_assets`] puts
//! them in place of a scene's `"asset"` references at admission.
//! [`check_untrusted`] takes a scene's bytes through all of admission and compilation at once.

mod assets;
mod cost;
mod doorbell;
mod encode;
mod fingerprint;
mod handoff;
mod id;
mod jobs_config;
mod limits;
mod live;
mod pool;
mod record;
mod service;
mod shared;
mod status;
pub mod store;
mod sweep_live;
mod sweep_work;
mod sweeps;
mod untrusted;

pub use assets::{AssetError, AssetLimits, ResolveError, Uploaded};
pub use cost::{Cost, IMPLICIT_PASSES, StageCost};
pub use encode::{EncodingCancelled, TranscodeError, Transcoded, encode_result, transcode};
pub use fingerprint::fingerprint;
pub use handoff::KeptModel;
pub use id::JobId;
pub use jobs_config::{BeforeRun, JobsConfig};
pub use limits::{Admitted, Limits, bytes};
pub use record::{Idempotency, JobRecord, Plan, now_ms};
pub use service::{Cancelled, Ended, Jobs, Submission, SubmitError, Submitted};
pub use status::{Failure, JobStatus};
pub use store::{
    AssetRecord, AssetRoom, CancelRequest, Claim, Claimed, ClaimedRun, ClaimedRuns, HeldRun, Inserted,
    InsertedSweep, JobStore, Lease, MemoryStore, Outcome, Page, PostgresStore, PutAsset, Renewed, RunEnd,
    SqliteStore, StoreError, StoreUrl, StoredResult, StoredRun, SweepEntry, SweepSummary, attempts_exhausted,
};
pub use sweeps::{
    SweepDocumentError, SweepState, SweepSubmitError, SweepSubmitted, SweepTable, admit_for_table,
    sweep_over_limit,
};
pub use untrusted::{Refusal, check_untrusted};
