//! Sweeps run as jobs: every variant of a [`Sweep`] (and its reference) is one job, and the
//! registry remembers which jobs make which sweep so their table can be assembled at any time.
//!
//! [`Sweeps::submit`] checks the whole sweep before queueing anything: the document
//! ([`Sweep::from_value`]), then every run against the server's [`Limits`](super::Limits), then
//! that the runs fit in the queue at all. A run refused by the limits is named by the `vary`
//! entry that chose the offending value (`/vary/~1dt/3`), or by the base scene's field when no
//! varied value is to blame. If the queue fills part-way, the runs already queued are cancelled,
//! so a refused sweep leaves nothing running. The registry is in memory: sweeps are forgotten
//! on restart, and a run whose job the store has forgotten shows as failed.
//!
//! A run's outcome is read from the store once, when its job has ended, and kept with the
//! sweep: clients poll `GET /sweeps/{id}` while a sweep runs, and each poll reads only the runs
//! still under way instead of reading back and parsing every result again.

use std::collections::HashMap;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use bytes::Bytes;
use serde_json::Value;
use thiserror::Error;

use super::id::JobId;
use super::limits::Limits;
use super::record::now_ms;
use super::service::{Jobs, Submission, SubmitError};
use super::status::JobStatus;
use super::store::StoreError;
use crate::output::{Format, read_json};
use crate::scene::{Field, FieldError, FrameSelection, Scene};
use crate::sweep::{Outcome, Sweep, SweepError, Table, write_csv, write_svg};

/// Why a sweep document is not a sweep that can run: not JSON, invalid pointers or values, or
/// more variants than allowed. The sweep module's own error, under the name the job system gives
/// it, so that the API need not reach past the job system for it.
pub use crate::sweep::SweepError as SweepDocumentError;

/// One sweep submitted as jobs.
#[derive(Debug)]
pub struct SweepRecord {
    /// Its id.
    pub id: JobId,
    /// The checked sweep: pointers, variant values and scenes.
    pub sweep: Sweep,
    /// The reference run's job, if the sweep has a reference.
    pub reference_job: Option<JobId>,
    /// One job per variant, in variant order.
    pub variant_jobs: Vec<JobId>,
    /// When it was submitted, in milliseconds since the Unix epoch.
    pub created_ms: u64,
    /// The outcome of every run, in [`jobs`](Self::jobs) order, as last read from the store.
    runs: Mutex<Runs>,
}

/// What is known of a sweep's runs.
#[derive(Debug)]
struct Runs {
    outcomes: Vec<Outcome>,
    /// Which runs have ended; their outcomes are final and are not read again.
    ended: Vec<bool>,
}

impl SweepRecord {
    /// Every job of the sweep: the reference first, then the variants.
    pub fn jobs(&self) -> impl Iterator<Item = &JobId> {
        self.reference_job.iter().chain(&self.variant_jobs)
    }

    fn runs(&self) -> MutexGuard<'_, Runs> {
        self.runs.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The table of a sweep as it stands, and how many of its runs have ended.
#[derive(Debug)]
pub struct SweepState {
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

/// Why a sweep was refused.
#[derive(Debug, Error)]
pub enum SweepSubmitError {
    /// The document is not a sweep that can run.
    #[error(transparent)]
    Invalid(#[from] SweepError),
    /// Some runs exceed the server's limits, or there are more runs than the queue holds; each
    /// problem is at a JSON Pointer into the sweep document.
    #[error("the sweep exceeds this server's limits")]
    OverLimit(Vec<FieldError>),
    /// Queueing failed part-way (a full queue, shutdown, the store); what was queued was cancelled.
    #[error(transparent)]
    Submit(#[from] SubmitError),
    /// The store failed while cancelling.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// The sweeps of this process, by id.
#[derive(Debug, Default)]
pub struct Sweeps {
    sweeps: Mutex<HashMap<JobId, Arc<SweepRecord>>>,
}

impl Sweeps {
    /// Checks a sweep document and queues its reference and every variant as jobs.
    pub async fn submit(
        &self,
        jobs: &Jobs,
        document: Value,
        max_variants: u64,
    ) -> Result<Arc<SweepRecord>, SweepSubmitError> {
        let vary_lists = vary_lists(&document);
        let mut sweep = Sweep::from_value(document, max_variants)?;
        sweep.reference.iter_mut().for_each(keep_final_positions);
        sweep.reference_document.iter_mut().for_each(keep_final_positions_in_document);
        for variant in &mut sweep.variants {
            keep_final_positions(&mut variant.scene);
            keep_final_positions_in_document(&mut variant.document);
        }

        let runs = sweep.variants.len() + usize::from(sweep.reference.is_some());
        let capacity = jobs.config().queue_capacity;
        if runs > capacity {
            return Err(SweepSubmitError::OverLimit(vec![FieldError::new(
                "/vary",
                format!(
                    "the sweep makes {runs} runs; this server queues at most {capacity} at once \
                     (--queue-capacity): split the sweep"
                ),
            )]));
        }
        let (sweep, problems) = jobs
            .admitting(move |limits| {
                let problems = over_limit(&sweep, &vary_lists, limits);
                (sweep, problems)
            })
            .await?;
        if !problems.is_empty() {
            return Err(SweepSubmitError::OverLimit(problems));
        }

        let to_queue: Vec<(Scene, Value)> = sweep
            .reference
            .iter()
            .cloned()
            .zip(sweep.reference_document.iter().cloned())
            .chain(sweep.variants.iter().map(|v| (v.scene.clone(), v.document.clone())))
            .collect();
        let mut queued = Vec::with_capacity(to_queue.len());
        for (scene, document) in to_queue {
            // Sweep runs carry no idempotency key, so their fingerprint is never compared.
            let submission =
                Submission { scene, document, fingerprint: 0, idempotency_key: None, max_work: None };
            match jobs.submit(submission).await {
                Ok(submitted) => queued.push(submitted.job.id),
                Err(e) => {
                    for id in &queued {
                        jobs.cancel(id).await?;
                    }
                    return Err(e.into());
                }
            }
        }
        let count = queued.len();
        let mut queued = queued.into_iter();
        let reference_job = sweep.reference.as_ref().and_then(|_| queued.next());
        let queued_run = || Outcome::Pending { status: JobStatus::Queued.name().into(), detail: None };
        let record = Arc::new(SweepRecord {
            id: JobId::new(),
            sweep,
            reference_job,
            variant_jobs: queued.collect(),
            created_ms: now_ms(),
            runs: Mutex::new(Runs {
                outcomes: (0..count).map(|_| queued_run()).collect(),
                ended: vec![false; count],
            }),
        });
        self.lock().insert(record.id.clone(), Arc::clone(&record));
        tracing::info!(sweep = %record.id, runs, "sweep queued");
        Ok(record)
    }

    /// The sweep with this id.
    pub fn get(&self, id: &JobId) -> Option<Arc<SweepRecord>> {
        self.lock().get(id).cloned()
    }

    /// The sweep's table as it stands: ended runs read back from their results, others pending.
    /// The store is read here, for the runs not known to have ended; reading their results back
    /// and assembling the table, CPU work that grows with the sweep, runs on the blocking pool.
    pub async fn state(&self, jobs: &Jobs, record: &Arc<SweepRecord>) -> Result<SweepState, StoreError> {
        let ended = record.runs().ended.clone();
        let mut fresh = Vec::new();
        for (index, id) in record.jobs().enumerate().filter(|(index, _)| !ended[*index]) {
            fresh.push((index, stored_run(jobs, id).await?));
        }
        let record = Arc::clone(record);
        tokio::task::spawn_blocking(move || assemble(&record, fresh))
            .await
            .map_err(|e| StoreError::Backend(format!("assembling the sweep table failed: {e}")))
    }

    /// Cancels every job of the sweep that has not ended.
    pub async fn cancel(&self, jobs: &Jobs, record: &SweepRecord) -> Result<(), StoreError> {
        for id in record.jobs() {
            jobs.cancel(id).await?;
        }
        Ok(())
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<JobId, Arc<SweepRecord>>> {
        self.sweeps.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A sweep run keeps only its final positions, as JSON, which is all its table row needs and
/// what [`read_json`] reads back.
fn keep_final_positions(scene: &mut Scene) {
    scene.output.frames = FrameSelection::Final;
    scene.output.fields = vec![Field::Positions];
    scene.output.format = Format::Json;
}

/// The same change in the document a worker runs from.
fn keep_final_positions_in_document(document: &mut Value) {
    if let Some(scene) = document.as_object_mut() {
        let output = scene.entry("output").or_insert_with(|| serde_json::json!({}));
        if let Some(output) = output.as_object_mut() {
            output.insert("frames".into(), "final".into());
            output.insert("fields".into(), serde_json::json!(["positions"]));
            output.insert("format".into(), "json".into());
        }
    }
}

/// A run as the store has it: its job's id and stored result, or where it stands without one.
enum StoredRun {
    Result(JobId, Bytes),
    Pending(Outcome),
}

/// Where a run stands, from its job.
async fn stored_run(jobs: &Jobs, id: &JobId) -> Result<StoredRun, StoreError> {
    let Some(job) = jobs.get(id).await? else {
        return Ok(StoredRun::Pending(Outcome::Pending {
            status: "failed".into(),
            detail: Some(format!("job {id} is no longer kept by this server")),
        }));
    };
    if job.status.is_final()
        && let Some(result) = jobs.result(id).await?
    {
        return Ok(StoredRun::Result(id.clone(), result.bytes));
    }
    Ok(StoredRun::Pending(Outcome::Pending { status: job.status.name().into(), detail: job.message }))
}

/// Reads the results of the runs just read from the store back, keeps the outcomes of those
/// that ended, and assembles the table.
fn assemble(record: &SweepRecord, fresh: Vec<(usize, StoredRun)>) -> SweepState {
    let mut runs = record.runs();
    let Runs { outcomes, ended } = &mut *runs;
    // A poll that read the store earlier than another may come second: what has ended stays.
    for (index, run) in fresh {
        if ended[index] {
            continue;
        }
        let outcome = match run {
            StoredRun::Pending(outcome) => outcome,
            StoredRun::Result(id, bytes) => match read_json(&bytes) {
                Ok(recording) => Outcome::Finished(Box::new(recording)),
                Err(e) => Outcome::Pending {
                    status: "failed".into(),
                    detail: Some(format!("job {id}'s result cannot be read: {e}")),
                },
            },
        };
        ended[index] = match &outcome {
            Outcome::Finished(_) => true,
            Outcome::Pending { status, .. } => !matches!(status.as_str(), "queued" | "running"),
        };
        outcomes[index] = outcome;
    }
    let finished = ended.iter().filter(|&&e| e).count();
    let (reference, variants) = match record.reference_job {
        Some(_) => (outcomes.first(), outcomes.get(1..).unwrap_or_default()),
        None => (None, &outcomes[..]),
    };
    let table = Table::assemble(&record.sweep, reference, variants);
    SweepState { table, finished, runs: outcomes.len() }
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
