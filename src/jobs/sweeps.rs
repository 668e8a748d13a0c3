//! Sweeps through the job system: [`Jobs::submit_sweep`] checks a whole [`Sweep`] and stores it
//! as one entry with a row per run (its reference and every variant); workers of any instance
//! sharing the store run its runs in batches (see [`sweep_work`](super::sweep_work)), and its
//! table is assembled from the runs' stored outcomes whenever it is asked for.
//!
//! A sweep is checked whole before it is stored: the document ([`Sweep::from_value`]), then every
//! run against the server's [`Limits`](super::Limits). A run refused by the limits is named by the
//! `vary` entry that chose the offending value (`/vary/~1dt/3`), or by the base scene's field when
//! no varied value is to blame. However many runs it makes, a sweep takes no room in the job
//! queue: its runs wait in their own rows, so a sweep of thousands of variants is accepted by a
//! server with a small `--queue-capacity`, and stays in the store across restarts.
//!
//! A sweep submitted with an idempotency key is stored with it: the same key with the same
//! document (by [`fingerprint`](super::fingerprint)) finds the sweep it made, on any instance
//! sharing the store, and the same key with another document is refused, as for a job.

use std::io;
use std::sync::Arc;

use serde_json::Value;
use thiserror::Error;

use super::id::JobId;
use super::limits::Limits;
use super::live::CANCELLED;
use super::record::{Idempotency, now_ms};
use super::service::{Jobs, SubmitError};
use super::shared::{keep_final_positions, sweep_for_table};
use super::status::JobStatus;
use super::store::{InsertedSweep, Page, StoreError, StoredRun, SweepEntry, SweepSummary};
use crate::output::read_json_final;
use crate::scene::{FieldError, Scene};
use crate::sweep::{Finished, Outcome, Sweep, SweepError, Table, write_csv, write_svg};

/// Why a sweep document is not a sweep that can run: not JSON, invalid pointers or values, or
/// more variants than allowed. The sweep module's own error, under the name the job system gives
/// it, so that the API need not reach past the job system for it.
pub use crate::sweep::SweepError as SweepDocumentError;

/// A sweep's table (its rows and observed orders), which serializes as the JSON the API shows.
pub use crate::sweep::Table as SweepTable;

/// The table of a sweep as it stands, and how many of its runs have ended.
#[derive(Debug)]
pub struct SweepState {
    /// The sweep as stored.
    pub summary: SweepSummary,
    /// Variants of the sweep (runs, less the reference).
    pub variants: usize,
    /// The table, with pending rows for runs not yet ended.
    pub table: Table,
    /// Runs that have ended (reference included).
    pub finished: usize,
    /// Runs in all (reference included).
    pub runs: usize,
}

impl SweepState {
    /// The table as CSV: one row per run, the varied values first.
    pub fn csv(&self) -> io::Result<Vec<u8>> {
        let mut bytes = Vec::new();
        write_csv(&self.table, &mut bytes)?;
        Ok(bytes)
    }

    /// The work-precision plot of the table as SVG: error against wall time, log-log, one
    /// series per integrator, under `title`.
    pub fn svg(&self, title: &str) -> io::Result<Vec<u8>> {
        let mut bytes = Vec::new();
        write_svg(&self.table, title, &mut bytes)?;
        Ok(bytes)
    }
}

/// A sweep accepted by [`Jobs::submit_sweep`].
#[derive(Debug)]
pub struct SweepSubmitted {
    /// The sweep as stored.
    pub summary: SweepSummary,
    /// Whether it is an earlier sweep with the same idempotency key and document.
    pub repeated: bool,
}

/// Why a sweep was refused.
#[derive(Debug, Error)]
pub enum SweepSubmitError {
    /// The document is not a sweep that can run.
    #[error(transparent)]
    Invalid(#[from] SweepError),
    /// Some runs exceed the server's limits; each problem is at a JSON Pointer into the sweep
    /// document.
    #[error("the sweep exceeds this server's limits")]
    OverLimit(Vec<FieldError>),
    /// The server is shutting down, or the store failed.
    #[error(transparent)]
    Submit(#[from] SubmitError),
    /// The idempotency key was first used with another document.
    #[error("the Idempotency-Key `{key}` was already used for sweep {sweep} with a different document")]
    KeyReused {
        /// The key.
        key: String,
        /// The sweep that holds it.
        sweep: JobId,
    },
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

impl Jobs {
    /// Checks a sweep document (at most `max_variants` variants, every run within the limits)
    /// and stores it with a queued row for its reference and each variant, or finds the earlier
    /// sweep with the same idempotency key.
    pub async fn submit_sweep(
        &self,
        document: Value,
        max_variants: u64,
        idempotency: Option<Idempotency>,
    ) -> Result<SweepSubmitted, SweepSubmitError> {
        if let Some(key) = &idempotency
            && let Some(earlier) = self.shared.store.find_sweep_by_key(&key.key).await?
        {
            return repeat_of(earlier, key);
        }
        let vary_lists = vary_lists(&document);
        let stored = document.to_string();
        let sweep = sweep_for_table(document, max_variants)?;
        let (sweep, problems) = self
            .admitting(move |limits| {
                let problems = over_limit(&sweep, &vary_lists, limits);
                (sweep, problems)
            })
            .await?;
        if !problems.is_empty() {
            return Err(SweepSubmitError::OverLimit(problems));
        }
        if self.shared.stopped.load(std::sync::atomic::Ordering::Relaxed) {
            return Err(SubmitError::ShuttingDown.into());
        }
        let runs = sweep.variants.len() + usize::from(sweep.reference.is_some());
        let entry = SweepEntry {
            id: JobId::new(),
            created_ms: now_ms(),
            runs: u32::try_from(runs).map_err(|_| SweepError::TooManyVariants {
                variants: runs as u64,
                limit: u64::from(u32::MAX),
            })?,
            has_reference: sweep.reference.is_some(),
            idempotency,
        };
        if let InsertedSweep::KeyTaken(earlier) = self.shared.store.insert_sweep(&entry, &stored).await? {
            let key = entry.idempotency.as_ref().expect("only a keyed sweep can find its key taken");
            return repeat_of(*earlier, key);
        }
        // Checked once: this instance's workers and tables use it as it is.
        self.shared.keep_sweep(&entry.id, Arc::new(sweep));
        self.shared.doorbell.ring_all();
        tracing::info!(sweep = %entry.id, runs, "sweep queued");
        let summary = SweepSummary { entry, cancel_requested: false, finished: 0, running: 0 };
        Ok(SweepSubmitted { summary, repeated: false })
    }

    /// The sweep with this id, with how far its runs have got.
    pub async fn sweep(&self, id: &JobId) -> Result<Option<SweepSummary>, StoreError> {
        self.shared.store.sweep(id).await
    }

    /// A channel that changes whenever a batch of sweep runs (or a job) ends on this instance,
    /// so a follower of a sweep learns of its end without waiting for its next look.
    pub fn sweep_changes(&self) -> tokio::sync::watch::Receiver<u64> {
        self.shared.changes.subscribe()
    }

    /// Sweeps, newest first.
    pub async fn list_sweeps(&self, page: Page) -> Result<Vec<SweepSummary>, StoreError> {
        self.shared.store.list_sweeps(page).await
    }

    /// The sweep's table as it stands: ended runs read back from their results, others pending.
    /// Reading the sweep and its runs back and assembling the table, CPU work that grows with
    /// the sweep, runs on the blocking pool.
    pub async fn sweep_state(&self, summary: SweepSummary) -> Result<SweepState, StoreError> {
        let runs = self.shared.store.sweep_runs(&summary.entry.id).await?;
        let shared = Arc::clone(&self.shared);
        tokio::task::spawn_blocking(move || {
            let id = &summary.entry.id;
            let sweep = shared.sweep_blocking(id)?.ok_or_else(|| StoreError::NotFound(id.clone()))?;
            Ok(assemble(summary, &sweep, runs))
        })
        .await
        .map_err(|e| StoreError::Backend(format!("assembling the sweep table failed: {e}")))?
    }

    /// The table of a sweep [`submit_sweep`](Self::submit_sweep) has just stored: its runs
    /// are all queued, so none is read back.
    pub async fn queued_sweep_state(&self, summary: SweepSummary) -> Result<SweepState, StoreError> {
        let Some(sweep) = self.shared.kept_sweep(&summary.entry.id) else {
            return self.sweep_state(summary).await;
        };
        let queued = || StoredRun { status: JobStatus::Queued, message: None, result: None };
        let runs = (0..summary.entry.runs).map(|_| queued()).collect();
        Ok(assemble(summary, &sweep, runs))
    }

    /// Cancels a sweep: its runs not started end at once, and those running (here or on another
    /// instance) stop within a lease renewal. `None` if there is no such sweep.
    pub async fn cancel_sweep(&self, id: &JobId) -> Result<Option<SweepSummary>, StoreError> {
        let summary = self.shared.store.cancel_sweep(id, now_ms(), CANCELLED).await?;
        if summary.is_some() {
            self.shared.batches().iter().filter(|batch| &batch.sweep == id).for_each(|batch| batch.cancel());
            self.shared.changed();
        }
        Ok(summary)
    }
}

/// The earlier sweep that holds `key`, if it was made from the same document.
fn repeat_of(earlier: SweepSummary, key: &Idempotency) -> Result<SweepSubmitted, SweepSubmitError> {
    match &earlier.entry.idempotency {
        Some(held) if held.fingerprint == key.fingerprint => {
            Ok(SweepSubmitted { summary: earlier, repeated: true })
        }
        _ => Err(SweepSubmitError::KeyReused { key: key.key.clone(), sweep: earlier.entry.id }),
    }
}

/// The table of `sweep` from its stored runs.
fn assemble(summary: SweepSummary, sweep: &Sweep, runs: Vec<StoredRun>) -> SweepState {
    let finished = runs.iter().filter(|run| run.status.is_final()).count();
    let outcomes: Vec<Outcome> = runs.into_iter().map(outcome).collect();
    let (reference, variants) = match sweep.reference {
        Some(_) => (outcomes.first(), outcomes.get(1..).unwrap_or_default()),
        None => (None, &outcomes[..]),
    };
    let table = Table::assemble(sweep, reference, variants);
    SweepState { variants: sweep.variants.len(), runs: outcomes.len(), summary, table, finished }
}

/// A stored run as a table row's outcome.
fn outcome(run: StoredRun) -> Outcome {
    match run.result {
        Some(bytes) if run.status.is_final() => match read_json_final(&bytes) {
            Ok((stats, final_positions)) => Outcome::Finished(Box::new(Finished { stats, final_positions })),
            Err(e) => Outcome::Pending {
                status: JobStatus::Failed.name().into(),
                detail: Some(format!("the run's result cannot be read: {e}")),
            },
        },
        _ => Outcome::Pending { status: run.status.name().into(), detail: run.message },
    }
}

/// Every limit a run of `sweep` (read from `document`) exceeds when run for its table (final
/// positions only), each at the `vary` entry to blame or at the base scene's field: what
/// `POST /sweeps` refuses, for a sweep run elsewhere (`drape sweep`).
pub fn sweep_over_limit(document: &Value, sweep: &Sweep, limits: &Limits) -> Vec<FieldError> {
    let mut sweep = sweep.clone();
    sweep.reference.iter_mut().for_each(keep_final_positions);
    sweep.variants.iter_mut().for_each(|v| keep_final_positions(&mut v.scene));
    over_limit(&sweep, &vary_lists(document), limits)
}

/// A scene as a sweep runs it for its table, admitted under `limits` (with its self-collision
/// cap set), or the limits it exceeds.
pub fn admit_for_table(scene: &Scene, limits: &Limits) -> Result<crate::scene::Compiled, Vec<FieldError>> {
    let mut scene = scene.clone();
    keep_final_positions(&mut scene);
    limits.admit(&scene).map(|admitted| admitted.compiled)
}

/// The values listed under each `vary` pointer, in document order.
fn vary_lists(document: &Value) -> Vec<(String, Vec<Value>)> {
    document
        .get("vary")
        .and_then(Value::as_object)
        .map(|vary| {
            vary.iter().map(|(p, v)| (p.clone(), v.as_array().cloned().unwrap_or_default())).collect()
        })
        .unwrap_or_default()
}

/// Every limit a run exceeds, at the `vary` entry whose value is to blame, or else at the base
/// scene's (or reference's) field; each pointer is reported once.
fn over_limit(sweep: &Sweep, vary_lists: &[(String, Vec<Value>)], limits: &Limits) -> Vec<FieldError> {
    let mut problems: Vec<FieldError> = Vec::new();
    let mut report = |problem: FieldError| {
        if !problems.iter().any(|p| p.pointer == problem.pointer) {
            problems.push(problem);
        }
    };
    if let Some(reference) = &sweep.reference {
        for e in limits.admit(reference).err().unwrap_or_default() {
            report(FieldError::new(
                format!("/reference{}", e.pointer),
                format!("the reference run: {}", e.detail),
            ));
        }
    }
    for (index, variant) in sweep.variants.iter().enumerate() {
        for e in limits.admit(&variant.scene).err().unwrap_or_default() {
            let culprit = sweep.pointers.iter().zip(&variant.values).find(|(p, _)| {
                e.pointer == **p
                    || e.pointer.starts_with(&format!("{p}/"))
                    || p.starts_with(&format!("{}/", e.pointer))
            });
            let pointer = match culprit {
                Some((p, value)) => {
                    let choice = vary_lists
                        .iter()
                        .find(|(q, _)| q == p)
                        .and_then(|(_, list)| list.iter().position(|v| v == value))
                        .unwrap_or(0);
                    format!("/vary/{}/{choice}", escape(p))
                }
                None => format!("/scene{}", e.pointer),
            };
            report(FieldError::new(pointer, format!("variant {index}: {}", e.detail)));
        }
    }
    problems
}

/// A JSON object key as a JSON Pointer token (RFC 6901).
fn escape(key: &str) -> String {
    key.replace('~', "~0").replace('/', "~1")
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::{Finished, Outcome, Table, outcome};
    use crate::jobs::encode::encode_result;
    use crate::jobs::shared::sweep_for_table;
    use crate::jobs::status::JobStatus;
    use crate::jobs::store::StoredRun;
    use crate::run::{Control, execute};

    #[test]
    fn a_table_from_stored_results_is_the_table_of_the_runs() {
        // The single spring, in both precisions, against an RK4 reference.
        let scene = json!({"duration": 1.0, "gravity": [0, 0, 0], "error_estimate": "none",
            "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [1.1, 0, 0], "count": 2, "mass": 2.0,
                        "spring": {"k": 100, "rest_length": 1.0}, "pin": [0]}]});
        let document = json!({"scene": scene, "vary": {"/precision": ["f32", "f64"], "/dt": [0.01, 0.005]},
                              "reference": {"integrator": "rk4", "dt": 1e-4}});
        let sweep = sweep_for_table(document, 100).unwrap();
        let scenes = sweep.reference.iter().chain(sweep.variants.iter().map(|v| &v.scene));
        let (mut in_memory, mut stored) = (Vec::new(), Vec::new());
        for scene in scenes {
            let compiled = scene.compile();
            let recording = execute(&compiled, &Control::new());
            let bytes = encode_result(&recording, &compiled.output, &|| false).unwrap().bytes;
            let run = StoredRun { status: JobStatus::Succeeded, message: None, result: Some(bytes) };
            stored.push(outcome(run));
            in_memory.push(Outcome::Finished(Box::new(Finished::from(recording))));
        }
        let local = Table::assemble(&sweep, in_memory.first(), &in_memory[1..]);
        assert_eq!(Table::assemble(&sweep, stored.first(), &stored[1..]), local);
        // Every row is compared with the reference, the f32 runs as the f32 values they computed.
        assert!(local.rows.iter().all(|r| r.reference_error.is_some_and(|(max, _)| max > 0.0)), "{local:?}");
        assert_eq!(local.convergence().len(), 2);
    }
}
