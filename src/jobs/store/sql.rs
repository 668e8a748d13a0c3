//! The job store over SQL, shared by the SQLite and PostgreSQL backends.
//!
//! Both keep the same two tables (`jobs` and `results`, see `migrations/`) and run the same
//! statements, written once here with `$n` placeholders (SQLite reads them as `?n`). They differ
//! only in how a worker claims a job: PostgreSQL locks the chosen row with `FOR UPDATE SKIP
//! LOCKED`, so instances claiming at once never wait for or take the same job; SQLite has one
//! writer at a time, so the claiming `UPDATE` alone is atomic. [`sql_store!`] writes the
//! [`JobStore`](super::JobStore) implementation for a backend's pool type.
//!
//! A claim runs in an explicit transaction and is handed over only once its commit succeeded:
//! an `UPDATE ... RETURNING` in autocommit gives its row before the commit, whose failure (a
//! full disk) would then go unseen, and the job, still queued, would be claimed again and run
//! twice with `attempts` never counted. A job given up after `--max-attempts` is failed in the
//! same transaction, its `attempts` left at the number of starts.
//!
//! Results are deflate-compressed on the way in and inflated on the way out, except a sweep
//! run's small result: a few hundred bytes of JSON cost far more to deflate and inflate than to
//! store as they are.

use std::io::{Read, Write};

use bytes::Bytes;
use flate2::Compression;
use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;

use super::StoreError;
use crate::jobs::id::JobId;
use crate::jobs::record::{Idempotency, JobRecord, Plan};
use crate::jobs::status::{Failure, JobStatus};

/// The columns of a job as [`JobRow`] reads them.
pub(super) const COLUMNS: &str = "id, status, created_ms, started_ms, finished_ms, particles, springs, steps, \
     companion_steps, dt, duration, steps_done, message, failure, stats, idem_key, idem_fingerprint, attempts";

/// The columns of a sweep (`s`) as [`SweepRow`] reads them, with its runs counted.
const SWEEP_COLUMNS: &str = "s.id, s.created_ms, s.runs, s.has_reference, s.cancel_requested, \
     s.idem_key, s.idem_fingerprint, \
     (SELECT COUNT(*) FROM sweep_runs r WHERE r.sweep_id = s.id AND r.status NOT IN ('queued', 'running')) \
     AS finished, \
     (SELECT COUNT(*) FROM sweep_runs r WHERE r.sweep_id = s.id AND r.status = 'running') AS running";

/// A sweep as a row of `sweeps`, with its runs counted.
#[derive(sqlx::FromRow)]
pub(super) struct SweepRow {
    id: String,
    created_ms: i64,
    runs: i64,
    has_reference: bool,
    cancel_requested: bool,
    idem_key: Option<String>,
    idem_fingerprint: Option<i64>,
    finished: i64,
    running: i64,
}

impl SweepRow {
    pub(super) fn into_summary(self) -> Result<super::SweepSummary, StoreError> {
        let id = JobId::parse(&self.id).ok_or_else(|| corrupt(format!("a sweep id `{}`", self.id)))?;
        let count = |n: i64| u32::try_from(n).map_err(|_| corrupt(format!("a sweep of {n} runs")));
        Ok(super::SweepSummary {
            entry: super::SweepEntry {
                id,
                created_ms: self.created_ms as u64,
                runs: count(self.runs)?,
                has_reference: self.has_reference,
                idempotency: idempotency(self.idem_key, self.idem_fingerprint),
            },
            cancel_requested: self.cancel_requested,
            finished: count(self.finished)?,
            running: count(self.running)?,
        })
    }
}

/// A run as a row of `sweep_runs`.
#[derive(sqlx::FromRow)]
pub(super) struct RunRow {
    status: String,
    message: Option<String>,
    result: Option<Vec<u8>>,
}

impl RunRow {
    pub(super) fn into_run(self) -> Result<super::StoredRun, StoreError> {
        Ok(super::StoredRun {
            status: status(&self.status)?,
            message: self.message,
            result: self.result.as_deref().map(unpack_run_result).transpose()?,
        })
    }
}

/// A claimed or renewed run: its sweep, number, attempts (when claimed) and cancel flag.
pub(super) fn held_run(
    sweep: &str,
    index: i64,
    cancel_requested: bool,
) -> Result<super::HeldRun, StoreError> {
    Ok(super::HeldRun {
        sweep: JobId::parse(sweep).ok_or_else(|| corrupt(format!("a sweep id `{sweep}`")))?,
        index: u32::try_from(index).map_err(|_| corrupt(format!("a run numbered {index}")))?,
        cancel_requested,
    })
}

fn status(name: &str) -> Result<JobStatus, StoreError> {
    JobStatus::ALL.into_iter().find(|s| s.name() == name).ok_or_else(|| corrupt(format!("a status `{name}`")))
}

/// The columns of an asset as [`AssetRow`] reads them.
const ASSET_COLUMNS: &str = "id, vertices, triangles, bytes, created_ms";

/// An asset as a row of `assets`.
#[derive(sqlx::FromRow)]
pub(super) struct AssetRow {
    id: String,
    vertices: i64,
    triangles: i64,
    bytes: i64,
    created_ms: i64,
}

impl AssetRow {
    pub(super) fn into_record(self) -> super::AssetRecord {
        super::AssetRecord {
            id: self.id,
            vertices: self.vertices as u64,
            triangles: self.triangles as u64,
            bytes: self.bytes as u64,
            created_ms: self.created_ms as u64,
        }
    }
}

/// The statements of a backend, with its placeholders.
pub(super) struct Statements {
    pub insert: String,
    pub get: String,
    pub find_by_key: String,
    pub list: String,
    pub count_by_status: String,
    pub count_queued: String,
    pub claim: String,
    pub give_up: String,
    pub renew: String,
    pub finish: String,
    pub store_result: String,
    pub release: String,
    pub cancel_now: String,
    pub flag_cancel: String,
    pub cancel_queued: String,
    pub drop_results: String,
    pub result: String,
    pub put_asset: String,
    pub asset_usage: String,
    pub asset: String,
    pub asset_mesh: String,
    pub list_assets: String,
    pub delete_asset: String,
    pub insert_sweep: String,
    pub insert_sweep_runs: String,
    pub find_sweep_by_key: String,
    pub sweep: String,
    pub sweep_document: String,
    pub list_sweeps: String,
    pub sweep_runs: String,
    pub claim_sweep_runs: String,
    pub renew_sweep_runs: String,
    pub finish_sweep_run: String,
    /// Ends `n` runs of one sweep in one statement, at index `n - 1`, up to [`RUN_ENDS_AT_ONCE`].
    pub finish_sweep_runs: Vec<String>,
    pub release_sweep_run: String,
    pub flag_sweep_cancel: String,
    pub cancel_sweep_runs_now: String,
    pub flag_sweep_runs_cancel: String,
}

/// Which backend the statements are for.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Dialect {
    Sqlite,
    Postgres,
}

impl Statements {
    pub(super) fn new(dialect: Dialect) -> Self {
        let lock = match dialect {
            Dialect::Postgres => "FOR UPDATE SKIP LOCKED",
            Dialect::Sqlite => "",
        };
        let claimable = "status IN ('queued', 'running') AND (status = 'queued' OR lease_until_ms < $3)";
        let placeholders = |sql: String| match dialect {
            Dialect::Postgres => sql,
            Dialect::Sqlite => sql.replace('$', "?"),
        };
        let ended = "scene = NULL, lease_owner = NULL, lease_until_ms = NULL";
        Self {
            insert: placeholders(
                "INSERT INTO jobs (id, status, created_ms, particles, springs, steps, companion_steps, dt, \
                 duration, idem_key, idem_fingerprint, scene) \
                 VALUES ($1, 'queued', $2, $3, $4, $5, $11, $6, $7, $8, $9, $10) \
                 ON CONFLICT (idem_key) DO NOTHING"
                    .into(),
            ),
            get: placeholders(format!("SELECT {COLUMNS} FROM jobs WHERE id = $1")),
            find_by_key: placeholders(format!("SELECT {COLUMNS} FROM jobs WHERE idem_key = $1")),
            list: placeholders(format!("SELECT {COLUMNS} FROM jobs ORDER BY seq DESC LIMIT $1 OFFSET $2")),
            count_by_status: "SELECT status, COUNT(*) FROM jobs GROUP BY status".into(),
            count_queued: "SELECT COUNT(*) FROM jobs WHERE status = 'queued'".into(),
            claim: placeholders(format!(
                "UPDATE jobs SET status = 'running', lease_owner = $1, lease_until_ms = $2, started_ms = $3, \
                 steps_done = 0, attempts = attempts + 1 \
                 WHERE id = (SELECT id FROM jobs WHERE {claimable} ORDER BY seq LIMIT 1 {lock}) \
                 AND {claimable} RETURNING {COLUMNS}, scene"
            )),
            give_up: placeholders(format!(
                "UPDATE jobs SET status = 'failed', finished_ms = $1, steps_done = 0, message = $2, \
                 failure = 'attempts', attempts = attempts - 1, {ended} \
                 WHERE id = $3 AND lease_owner = $4 RETURNING {COLUMNS}"
            )),
            renew: placeholders(
                "UPDATE jobs SET lease_until_ms = $1, steps_done = $2 \
                 WHERE id = $3 AND status = 'running' AND lease_owner = $4 RETURNING cancel_requested"
                    .into(),
            ),
            finish: placeholders(format!(
                "UPDATE jobs SET status = $1, finished_ms = $2, steps_done = $3, message = $4, stats = $5, \
                 failure = $8, {ended} WHERE id = $6 AND status = 'running' AND lease_owner = $7"
            )),
            store_result: placeholders(
                "INSERT INTO results (job_id, media_type, body, finished_ms) VALUES ($1, $2, $3, $4)".into(),
            ),
            release: placeholders(
                "UPDATE jobs SET status = 'queued', steps_done = 0, attempts = attempts - 1, \
                 lease_owner = NULL, lease_until_ms = NULL \
                 WHERE id = $1 AND status = 'running' AND lease_owner = $2"
                    .into(),
            ),
            cancel_now: placeholders(format!(
                "UPDATE jobs SET status = 'cancelled', finished_ms = $1, message = $2, {ended} \
                 WHERE id = $3 AND status IN ('queued', 'running') \
                 AND (status = 'queued' OR lease_until_ms < $1) RETURNING {COLUMNS}"
            )),
            flag_cancel: placeholders(format!(
                "UPDATE jobs SET cancel_requested = TRUE WHERE id = $1 AND status = 'running' RETURNING {COLUMNS}"
            )),
            cancel_queued: placeholders(format!(
                "UPDATE jobs SET status = 'cancelled', finished_ms = $1, message = $2, {ended} \
                 WHERE status = 'queued' RETURNING id"
            )),
            drop_results: placeholders("DELETE FROM results WHERE finished_ms < $1".into()),
            result: placeholders("SELECT media_type, body FROM results WHERE job_id = $1".into()),
            // SQLite reads `ON CONFLICT` after `INSERT ... SELECT` only when the SELECT has a WHERE.
            put_asset: placeholders(
                "INSERT INTO assets (id, vertices, triangles, bytes, created_ms, mesh) \
                 SELECT $1, $2, $3, $4, $5, $6 \
                 WHERE (SELECT COUNT(*) FROM assets) < $7 \
                 AND (SELECT COALESCE(SUM(bytes), 0) FROM assets) + $4 <= $8 \
                 ON CONFLICT (id) DO NOTHING"
                    .into(),
            ),
            asset_usage: "SELECT COUNT(*), CAST(COALESCE(SUM(bytes), 0) AS BIGINT) FROM assets".into(),
            asset: placeholders(format!("SELECT {ASSET_COLUMNS} FROM assets WHERE id = $1")),
            asset_mesh: placeholders("SELECT mesh FROM assets WHERE id = $1".into()),
            list_assets: format!("SELECT {ASSET_COLUMNS} FROM assets ORDER BY seq DESC"),
            delete_asset: placeholders("DELETE FROM assets WHERE id = $1".into()),
            insert_sweep: placeholders(
                "INSERT INTO sweeps (id, created_ms, runs, has_reference, document, idem_key, idem_fingerprint) \
                 VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (idem_key) DO NOTHING"
                    .into(),
            ),
            // One statement makes every run's row, however many there are.
            insert_sweep_runs: placeholders(
                "WITH RECURSIVE n (i) AS (SELECT 0 UNION ALL SELECT i + 1 FROM n WHERE i + 1 < $2) \
                 INSERT INTO sweep_runs (sweep_id, idx, status) SELECT $1, i, 'queued' FROM n"
                    .into(),
            ),
            find_sweep_by_key: placeholders(format!("SELECT {SWEEP_COLUMNS} FROM sweeps s WHERE s.idem_key = $1")),
            sweep: placeholders(format!("SELECT {SWEEP_COLUMNS} FROM sweeps s WHERE s.id = $1")),
            sweep_document: placeholders("SELECT document FROM sweeps WHERE id = $1".into()),
            list_sweeps: placeholders(format!(
                "SELECT {SWEEP_COLUMNS} FROM sweeps s ORDER BY s.seq DESC LIMIT $1 OFFSET $2"
            )),
            sweep_runs: placeholders(
                "SELECT status, message, result FROM sweep_runs WHERE sweep_id = $1 ORDER BY idx".into(),
            ),
            // The runs of one sweep, the oldest with runs to claim.
            // The runs are picked in a CTE, evaluated once: PostgreSQL may evaluate an `IN`
            // subquery again for each row it updates, and each time skip other rows.
            claim_sweep_runs: placeholders(format!(
                "WITH picked AS (SELECT seq FROM sweep_runs WHERE {claimable} AND sweep_id = \
                 (SELECT sweep_id FROM sweep_runs WHERE {claimable} ORDER BY seq LIMIT 1) \
                 ORDER BY seq LIMIT $4 {lock}) \
                 UPDATE sweep_runs SET status = 'running', lease_owner = $1, lease_until_ms = $2, \
                 attempts = attempts + 1 \
                 WHERE seq IN (SELECT seq FROM picked) AND {claimable} \
                 RETURNING sweep_id, idx, attempts, cancel_requested"
            )),
            renew_sweep_runs: placeholders(
                "UPDATE sweep_runs SET lease_until_ms = $1 WHERE lease_owner = $2 AND status = 'running' \
                 RETURNING sweep_id, idx, cancel_requested"
                    .into(),
            ),
            finish_sweep_run: placeholders(
                "UPDATE sweep_runs SET status = $1, message = $2, result = $3, lease_owner = NULL, \
                 lease_until_ms = NULL \
                 WHERE sweep_id = $4 AND idx = $5 AND status = 'running' AND lease_owner = $6"
                    .into(),
            ),
            finish_sweep_runs: (1..=RUN_ENDS_AT_ONCE).map(|n| placeholders(finish_runs(n))).collect(),
            release_sweep_run: placeholders(
                "UPDATE sweep_runs SET status = 'queued', attempts = attempts - 1, lease_owner = NULL, \
                 lease_until_ms = NULL \
                 WHERE sweep_id = $1 AND idx = $2 AND status = 'running' AND lease_owner = $3"
                    .into(),
            ),
            flag_sweep_cancel: placeholders("UPDATE sweeps SET cancel_requested = TRUE WHERE id = $1".into()),
            cancel_sweep_runs_now: placeholders(
                "UPDATE sweep_runs SET status = 'cancelled', message = $2, lease_owner = NULL, \
                 lease_until_ms = NULL \
                 WHERE sweep_id = $1 AND status IN ('queued', 'running') \
                 AND (status = 'queued' OR lease_until_ms < $3)"
                    .into(),
            ),
            flag_sweep_runs_cancel: placeholders(
                "UPDATE sweep_runs SET cancel_requested = TRUE WHERE sweep_id = $1 AND status = 'running'".into(),
            ),
        }
    }
}

/// A job as a row of `jobs`.
#[derive(sqlx::FromRow)]
pub(super) struct JobRow {
    id: String,
    status: String,
    created_ms: i64,
    started_ms: Option<i64>,
    finished_ms: Option<i64>,
    particles: i64,
    springs: i64,
    steps: i64,
    companion_steps: i64,
    dt: f64,
    duration: f64,
    steps_done: i64,
    message: Option<String>,
    failure: Option<String>,
    stats: Option<String>,
    idem_key: Option<String>,
    idem_fingerprint: Option<i64>,
    attempts: i64,
}

/// A claimed job's row, with its scene.
#[derive(sqlx::FromRow)]
pub(super) struct ClaimRow {
    #[sqlx(flatten)]
    pub job: JobRow,
    pub scene: Option<String>,
}

impl JobRow {
    pub(super) fn into_record(self) -> Result<JobRecord, StoreError> {
        let id = JobId::parse(&self.id).ok_or_else(|| corrupt(format!("a job id `{}`", self.id)))?;
        let status = status(&self.status)?;
        let stats = self
            .stats
            .map(|text| serde_json::from_str(&text))
            .transpose()
            .map_err(|e| corrupt(format!("stats that are not JSON ({e})")))?;
        let failure = self
            .failure
            .map(|name| {
                Failure::ALL
                    .into_iter()
                    .find(|f| f.name() == name)
                    .ok_or_else(|| corrupt(format!("a failure `{name}`")))
            })
            .transpose()?;
        let idempotency = idempotency(self.idem_key, self.idem_fingerprint);
        Ok(JobRecord {
            id,
            status,
            created_ms: self.created_ms as u64,
            started_ms: self.started_ms.map(|t| t as u64),
            finished_ms: self.finished_ms.map(|t| t as u64),
            plan: Plan {
                particles: self.particles as u64,
                springs: self.springs as u64,
                steps: self.steps as u64,
                companion_steps: self.companion_steps as u64,
                dt: self.dt,
                duration: self.duration,
            },
            steps_done: self.steps_done as u64,
            message: self.message,
            failure,
            stats,
            idempotency,
            attempts: u32::try_from(self.attempts).unwrap_or(u32::MAX),
        })
    }
}

/// Run ends stored by one statement at most.
pub(super) const RUN_ENDS_AT_ONCE: usize = 64;

/// The statement that ends `n` held runs of sweep `$1` for owner `$2`, each given by four
/// parameters from `$3` on: its number, status, message and result. A `VALUES` list's columns
/// are `column1`, `column2`, ... in both SQLite and PostgreSQL.
fn finish_runs(n: usize) -> String {
    let rows: Vec<String> =
        (0..n).map(|i| format!("(${}, ${}, ${}, ${})", 4 * i + 3, 4 * i + 4, 4 * i + 5, 4 * i + 6)).collect();
    format!(
        "UPDATE sweep_runs SET status = v.column2, message = v.column3, result = v.column4, \
         lease_owner = NULL, lease_until_ms = NULL FROM (VALUES {}) AS v \
         WHERE sweep_runs.sweep_id = $1 AND sweep_runs.idx = v.column1 \
         AND sweep_runs.status = 'running' AND sweep_runs.lease_owner = $2",
        rows.join(", ")
    )
}

/// An idempotency key as its two columns hold it.
fn idempotency(key: Option<String>, fingerprint: Option<i64>) -> Option<Idempotency> {
    match (key, fingerprint) {
        (Some(key), Some(fingerprint)) => Some(Idempotency { key, fingerprint: fingerprint as u64 }),
        _ => None,
    }
}

fn corrupt(what: String) -> StoreError {
    StoreError::Backend(format!("the store holds {what}"))
}

/// A database error as a store error.
pub(super) fn backend(e: sqlx::Error) -> StoreError {
    StoreError::Backend(e.to_string())
}

/// A `u64` as the signed 64-bit integer databases store; fingerprints use all 64 bits.
pub(super) fn int(value: u64) -> i64 {
    value as i64
}

/// Deflates a result for storage.
pub(super) fn compress(bytes: &[u8]) -> Result<Vec<u8>, StoreError> {
    let mut encoder = DeflateEncoder::new(Vec::with_capacity(bytes.len() / 4), Compression::fast());
    encoder.write_all(bytes).and_then(|()| encoder.finish()).map_err(|e| StoreError::Backend(e.to_string()))
}

/// Inflates a stored result.
pub(super) fn decompress(bytes: &[u8]) -> Result<Bytes, StoreError> {
    let mut out = Vec::with_capacity(bytes.len() * 4);
    DeflateDecoder::new(bytes)
        .read_to_end(&mut out)
        .map_err(|e| corrupt(format!("a damaged result ({e})")))?;
    Ok(Bytes::from(out))
}

/// Results of sweep runs up to this size are stored as they are.
const RAW_RUN_RESULT: usize = 16 * 1024;

/// A sweep run's result (always JSON) as stored: as it is when small, else deflated.
pub(super) fn pack_run_result(bytes: &[u8]) -> Result<Vec<u8>, StoreError> {
    if bytes.len() <= RAW_RUN_RESULT && bytes.first() == Some(&b'{') {
        return Ok(bytes.to_vec());
    }
    compress(bytes)
}

/// A sweep run's stored result. A JSON object is stored as it is; a deflate stream never
/// starts with the byte `{`: its first byte says a final fixed-code block whose first code is
/// that of a byte from 224 to 239, which no JSON document starts with.
pub(super) fn unpack_run_result(bytes: &[u8]) -> Result<Bytes, StoreError> {
    match bytes.first() {
        Some(b'{') => Ok(Bytes::copy_from_slice(bytes)),
        _ => decompress(bytes),
    }
}

/// The media types a result can have, as the `'static` strings [`StoredResult`] holds.
///
/// [`StoredResult`]: super::StoredResult
pub(super) fn media_type(text: &str) -> Result<&'static str, StoreError> {
    crate::output::Format::ALL
        .into_iter()
        .map(crate::output::Format::media_type)
        .find(|known| *known == text)
        .ok_or_else(|| corrupt(format!("a result of unknown media type `{text}`")))
}

/// Writes `impl JobStore` for a struct with fields `pool` (a sqlx pool) and `sql` ([`Statements`]).
macro_rules! sql_store {
    ($store:ty) => {
        #[async_trait::async_trait]
        impl $crate::jobs::JobStore for $store {
            fn durable(&self) -> bool {
                true
            }

            async fn insert(
                &self,
                job: $crate::jobs::JobRecord,
                scene: &str,
            ) -> Result<$crate::jobs::Inserted, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, int};
                let plan = &job.plan;
                let inserted = sqlx::query(&self.sql.insert)
                    .bind(job.id.as_str())
                    .bind(int(job.created_ms))
                    .bind(int(plan.particles))
                    .bind(int(plan.springs))
                    .bind(int(plan.steps))
                    .bind(plan.dt)
                    .bind(plan.duration)
                    .bind(job.idempotency.as_ref().map(|i| i.key.clone()))
                    .bind(job.idempotency.as_ref().map(|i| int(i.fingerprint)))
                    .bind(scene)
                    .bind(int(plan.companion_steps))
                    .execute(&self.pool)
                    .await
                    .map_err(backend)?;
                if inserted.rows_affected() == 1 {
                    return Ok($crate::jobs::Inserted::New);
                }
                let key = job.idempotency.as_ref().map(|i| i.key.as_str()).unwrap_or_default();
                match self.find_by_key(key).await? {
                    Some(holder) => Ok($crate::jobs::Inserted::KeyTaken(Box::new(holder))),
                    None => {
                        Err($crate::jobs::StoreError::Backend(format!("job {} was not inserted", job.id)))
                    }
                }
            }

            async fn get(
                &self,
                id: &$crate::jobs::JobId,
            ) -> Result<Option<$crate::jobs::JobRecord>, $crate::jobs::StoreError> {
                sqlx::query_as::<_, $crate::jobs::store::sql::JobRow>(&self.sql.get)
                    .bind(id.as_str())
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .map($crate::jobs::store::sql::JobRow::into_record)
                    .transpose()
            }

            async fn find_by_key(
                &self,
                key: &str,
            ) -> Result<Option<$crate::jobs::JobRecord>, $crate::jobs::StoreError> {
                sqlx::query_as::<_, $crate::jobs::store::sql::JobRow>(&self.sql.find_by_key)
                    .bind(key)
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .map($crate::jobs::store::sql::JobRow::into_record)
                    .transpose()
            }

            async fn list(
                &self,
                page: $crate::jobs::Page,
            ) -> Result<Vec<$crate::jobs::JobRecord>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::int;
                sqlx::query_as::<_, $crate::jobs::store::sql::JobRow>(&self.sql.list)
                    .bind(int(page.limit.min(i64::MAX as u64)))
                    .bind(int(page.offset.min(i64::MAX as u64)))
                    .fetch_all(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .into_iter()
                    .map($crate::jobs::store::sql::JobRow::into_record)
                    .collect()
            }

            async fn count_by_status(
                &self,
            ) -> Result<Vec<($crate::jobs::JobStatus, u64)>, $crate::jobs::StoreError> {
                let rows: Vec<(String, i64)> = sqlx::query_as(&self.sql.count_by_status)
                    .fetch_all(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok($crate::jobs::JobStatus::ALL
                    .iter()
                    .map(|&status| {
                        let n = rows.iter().find(|(name, _)| name == status.name()).map_or(0, |(_, n)| *n);
                        (status, n as u64)
                    })
                    .collect())
            }

            async fn count_queued(&self) -> Result<u64, $crate::jobs::StoreError> {
                let (n,): (i64,) = sqlx::query_as(&self.sql.count_queued)
                    .fetch_one(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(n as u64)
            }

            async fn claim(
                &self,
                lease: &$crate::jobs::Lease,
                now_ms: u64,
                max_attempts: u32,
            ) -> Result<Option<$crate::jobs::Claim>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{ClaimRow, JobRow, backend, int};
                use $crate::jobs::{Claim, Claimed, StoreError, attempts_exhausted};
                let mut tx = self.pool.begin().await.map_err(backend)?;
                // `fetch_all` runs the statement to its end inside the transaction.
                let row = sqlx::query_as::<_, ClaimRow>(&self.sql.claim)
                    .bind(&lease.owner)
                    .bind(int(lease.until_ms))
                    .bind(int(now_ms))
                    .fetch_all(&mut *tx)
                    .await
                    .map_err(backend)?
                    .pop();
                let Some(row) = row else { return Ok(None) };
                let record = row.job.into_record()?;
                let claim = if record.attempts > max_attempts {
                    let row = sqlx::query_as::<_, JobRow>(&self.sql.give_up)
                        .bind(int(now_ms))
                        .bind(attempts_exhausted(max_attempts))
                        .bind(record.id.as_str())
                        .bind(&lease.owner)
                        .fetch_all(&mut *tx)
                        .await
                        .map_err(backend)?
                        .pop()
                        .ok_or_else(|| StoreError::Backend(format!("job {} was not given up", record.id)))?;
                    Claim::GaveUp(row.into_record()?)
                } else {
                    let scene = row
                        .scene
                        .ok_or_else(|| StoreError::Backend(format!("job {} has no scene", record.id)))?;
                    Claim::Run(Claimed { record, scene })
                };
                tx.commit().await.map_err(backend)?;
                Ok(Some(claim))
            }

            async fn renew(
                &self,
                id: &$crate::jobs::JobId,
                lease: &$crate::jobs::Lease,
                steps_done: u64,
            ) -> Result<$crate::jobs::Renewed, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, int};
                let row: Option<(bool,)> = sqlx::query_as(&self.sql.renew)
                    .bind(int(lease.until_ms))
                    .bind(int(steps_done))
                    .bind(id.as_str())
                    .bind(&lease.owner)
                    .fetch_optional(&self.pool)
                    .await
                    .map_err(backend)?;
                Ok(match row {
                    Some((cancel_requested,)) => $crate::jobs::Renewed::Held { cancel_requested },
                    None => $crate::jobs::Renewed::Lost,
                })
            }

            async fn finish(
                &self,
                id: &$crate::jobs::JobId,
                owner: &str,
                finished_ms: u64,
                outcome: $crate::jobs::Outcome,
            ) -> Result<bool, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, compress, int};
                let body = match &outcome.result {
                    Some(result) => {
                        let bytes = result.bytes.clone();
                        Some(
                            tokio::task::spawn_blocking(move || compress(&bytes))
                                .await
                                .map_err(|e| $crate::jobs::StoreError::Backend(e.to_string()))??,
                        )
                    }
                    None => None,
                };
                let mut tx = self.pool.begin().await.map_err(backend)?;
                let ended = sqlx::query(&self.sql.finish)
                    .bind(outcome.status.name())
                    .bind(int(finished_ms))
                    .bind(int(outcome.steps_done))
                    .bind(outcome.message)
                    .bind(outcome.stats.map(|s| s.to_string()))
                    .bind(id.as_str())
                    .bind(owner)
                    .bind(outcome.failure.map(|f| f.name()))
                    .execute(&mut *tx)
                    .await
                    .map_err(backend)?;
                if ended.rows_affected() != 1 {
                    return Ok(false);
                }
                if let (Some(result), Some(body)) = (outcome.result, body) {
                    sqlx::query(&self.sql.store_result)
                        .bind(id.as_str())
                        .bind(result.media_type)
                        .bind(body)
                        .bind(int(finished_ms))
                        .execute(&mut *tx)
                        .await
                        .map_err(backend)?;
                }
                tx.commit().await.map_err(backend)?;
                Ok(true)
            }

            async fn release(
                &self,
                id: &$crate::jobs::JobId,
                owner: &str,
            ) -> Result<(), $crate::jobs::StoreError> {
                sqlx::query(&self.sql.release)
                    .bind(id.as_str())
                    .bind(owner)
                    .execute(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(())
            }

            async fn request_cancel(
                &self,
                id: &$crate::jobs::JobId,
                now_ms: u64,
                message: &str,
            ) -> Result<Option<$crate::jobs::CancelRequest>, $crate::jobs::StoreError> {
                use $crate::jobs::CancelRequest;
                use $crate::jobs::store::sql::{JobRow, backend, int};
                // Each statement is atomic; a job that changes between them (a claim, a release)
                // is looked at again.
                for _ in 0..3 {
                    let cancelled = sqlx::query_as::<_, JobRow>(&self.sql.cancel_now)
                        .bind(int(now_ms))
                        .bind(message)
                        .bind(id.as_str())
                        .fetch_optional(&self.pool)
                        .await
                        .map_err(backend)?;
                    if let Some(row) = cancelled {
                        return Ok(Some(CancelRequest::Cancelled(row.into_record()?)));
                    }
                    let flagged = sqlx::query_as::<_, JobRow>(&self.sql.flag_cancel)
                        .bind(id.as_str())
                        .fetch_optional(&self.pool)
                        .await
                        .map_err(backend)?;
                    if let Some(row) = flagged {
                        return Ok(Some(CancelRequest::Requested(row.into_record()?)));
                    }
                    match self.get(id).await? {
                        None => return Ok(None),
                        Some(job) if job.status.is_final() => {
                            return Ok(Some(CancelRequest::AlreadyEnded(job)));
                        }
                        Some(_) => {}
                    }
                }
                Err($crate::jobs::StoreError::Backend(format!(
                    "job {id} kept changing while being cancelled"
                )))
            }

            async fn cancel_queued(
                &self,
                now_ms: u64,
                message: &str,
            ) -> Result<Vec<$crate::jobs::JobId>, $crate::jobs::StoreError> {
                let ids: Vec<(String,)> = sqlx::query_as(&self.sql.cancel_queued)
                    .bind($crate::jobs::store::sql::int(now_ms))
                    .bind(message)
                    .fetch_all(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(ids.into_iter().filter_map(|(id,)| $crate::jobs::JobId::parse(&id)).collect())
            }

            async fn drop_results(&self, before_ms: u64) -> Result<u64, $crate::jobs::StoreError> {
                let dropped = sqlx::query(&self.sql.drop_results)
                    .bind($crate::jobs::store::sql::int(before_ms))
                    .execute(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(dropped.rows_affected())
            }

            async fn result(
                &self,
                id: &$crate::jobs::JobId,
            ) -> Result<Option<$crate::jobs::StoredResult>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, decompress, media_type};
                let row: Option<(String, Vec<u8>)> = sqlx::query_as(&self.sql.result)
                    .bind(id.as_str())
                    .fetch_optional(&self.pool)
                    .await
                    .map_err(backend)?;
                let Some((media, body)) = row else { return Ok(None) };
                let bytes = tokio::task::spawn_blocking(move || decompress(&body))
                    .await
                    .map_err(|e| $crate::jobs::StoreError::Backend(e.to_string()))??;
                Ok(Some($crate::jobs::StoredResult { media_type: media_type(&media)?, bytes }))
            }

            async fn put_asset(
                &self,
                asset: &$crate::jobs::AssetRecord,
                mesh: &[u8],
                room: $crate::jobs::AssetRoom,
            ) -> Result<$crate::jobs::PutAsset, $crate::jobs::StoreError> {
                use $crate::jobs::PutAsset;
                use $crate::jobs::store::sql::{backend, int};
                let added = sqlx::query(&self.sql.put_asset)
                    .bind(&asset.id)
                    .bind(int(asset.vertices))
                    .bind(int(asset.triangles))
                    .bind(int(asset.bytes))
                    .bind(int(asset.created_ms))
                    .bind(mesh)
                    .bind(int(room.max_assets.min(i64::MAX as u64)))
                    .bind(int(room.max_bytes.min(i64::MAX as u64)))
                    .execute(&self.pool)
                    .await
                    .map_err(backend)?;
                if added.rows_affected() == 1 {
                    return Ok(PutAsset::Added);
                }
                if let Some(existing) = self.asset(&asset.id).await? {
                    return Ok(PutAsset::Exists(existing));
                }
                let (assets, bytes): (i64, i64) =
                    sqlx::query_as(&self.sql.asset_usage).fetch_one(&self.pool).await.map_err(backend)?;
                Ok(PutAsset::Full { assets: assets as u64, bytes: bytes as u64 })
            }

            async fn asset(
                &self,
                id: &str,
            ) -> Result<Option<$crate::jobs::AssetRecord>, $crate::jobs::StoreError> {
                Ok(sqlx::query_as::<_, $crate::jobs::store::sql::AssetRow>(&self.sql.asset)
                    .bind(id)
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .map($crate::jobs::store::sql::AssetRow::into_record))
            }

            async fn asset_mesh(&self, id: &str) -> Result<Option<Vec<u8>>, $crate::jobs::StoreError> {
                let row: Option<(Vec<u8>,)> = sqlx::query_as(&self.sql.asset_mesh)
                    .bind(id)
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(row.map(|(mesh,)| mesh))
            }

            async fn list_assets(&self) -> Result<Vec<$crate::jobs::AssetRecord>, $crate::jobs::StoreError> {
                Ok(sqlx::query_as::<_, $crate::jobs::store::sql::AssetRow>(&self.sql.list_assets)
                    .fetch_all(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .into_iter()
                    .map($crate::jobs::store::sql::AssetRow::into_record)
                    .collect())
            }

            async fn delete_asset(&self, id: &str) -> Result<bool, $crate::jobs::StoreError> {
                let deleted = sqlx::query(&self.sql.delete_asset)
                    .bind(id)
                    .execute(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(deleted.rows_affected() == 1)
            }

            async fn insert_sweep(
                &self,
                sweep: &$crate::jobs::SweepEntry,
                document: &str,
            ) -> Result<$crate::jobs::InsertedSweep, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, int};
                let mut tx = self.pool.begin().await.map_err(backend)?;
                let inserted = sqlx::query(&self.sql.insert_sweep)
                    .bind(sweep.id.as_str())
                    .bind(int(sweep.created_ms))
                    .bind(i64::from(sweep.runs))
                    .bind(sweep.has_reference)
                    .bind(document)
                    .bind(sweep.idempotency.as_ref().map(|i| i.key.clone()))
                    .bind(sweep.idempotency.as_ref().map(|i| int(i.fingerprint)))
                    .execute(&mut *tx)
                    .await
                    .map_err(backend)?;
                if inserted.rows_affected() == 0 {
                    tx.rollback().await.map_err(backend)?;
                    let key = sweep.idempotency.as_ref().map(|i| i.key.as_str()).unwrap_or_default();
                    return match self.find_sweep_by_key(key).await? {
                        Some(holder) => Ok($crate::jobs::InsertedSweep::KeyTaken(Box::new(holder))),
                        None => Err($crate::jobs::StoreError::Backend(format!(
                            "sweep {} was not inserted",
                            sweep.id
                        ))),
                    };
                }
                sqlx::query(&self.sql.insert_sweep_runs)
                    .bind(sweep.id.as_str())
                    .bind(i64::from(sweep.runs))
                    .execute(&mut *tx)
                    .await
                    .map_err(backend)?;
                tx.commit().await.map_err(backend)?;
                Ok($crate::jobs::InsertedSweep::New)
            }

            async fn find_sweep_by_key(
                &self,
                key: &str,
            ) -> Result<Option<$crate::jobs::SweepSummary>, $crate::jobs::StoreError> {
                sqlx::query_as::<_, $crate::jobs::store::sql::SweepRow>(&self.sql.find_sweep_by_key)
                    .bind(key)
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .map($crate::jobs::store::sql::SweepRow::into_summary)
                    .transpose()
            }

            async fn sweep(
                &self,
                id: &$crate::jobs::JobId,
            ) -> Result<Option<$crate::jobs::SweepSummary>, $crate::jobs::StoreError> {
                sqlx::query_as::<_, $crate::jobs::store::sql::SweepRow>(&self.sql.sweep)
                    .bind(id.as_str())
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .map($crate::jobs::store::sql::SweepRow::into_summary)
                    .transpose()
            }

            async fn sweep_document(
                &self,
                id: &$crate::jobs::JobId,
            ) -> Result<Option<String>, $crate::jobs::StoreError> {
                let row: Option<(String,)> = sqlx::query_as(&self.sql.sweep_document)
                    .bind(id.as_str())
                    .fetch_optional(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                Ok(row.map(|(document,)| document))
            }

            async fn list_sweeps(
                &self,
                page: $crate::jobs::Page,
            ) -> Result<Vec<$crate::jobs::SweepSummary>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::int;
                sqlx::query_as::<_, $crate::jobs::store::sql::SweepRow>(&self.sql.list_sweeps)
                    .bind(int(page.limit.min(i64::MAX as u64)))
                    .bind(int(page.offset.min(i64::MAX as u64)))
                    .fetch_all(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?
                    .into_iter()
                    .map($crate::jobs::store::sql::SweepRow::into_summary)
                    .collect()
            }

            async fn sweep_runs(
                &self,
                id: &$crate::jobs::JobId,
            ) -> Result<Vec<$crate::jobs::StoredRun>, $crate::jobs::StoreError> {
                let rows = sqlx::query_as::<_, $crate::jobs::store::sql::RunRow>(&self.sql.sweep_runs)
                    .bind(id.as_str())
                    .fetch_all(&self.pool)
                    .await
                    .map_err($crate::jobs::store::sql::backend)?;
                // Inflating runs' results is CPU work that grows with the sweep.
                tokio::task::spawn_blocking(move || rows.into_iter().map(|row| row.into_run()).collect())
                    .await
                    .map_err(|e| $crate::jobs::StoreError::Backend(e.to_string()))?
            }

            async fn claim_sweep_runs(
                &self,
                lease: &$crate::jobs::Lease,
                now_ms: u64,
                max_runs: u32,
            ) -> Result<Option<$crate::jobs::ClaimedRuns>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, held_run, int};
                use $crate::jobs::{ClaimedRun, ClaimedRuns};
                let mut tx = self.pool.begin().await.map_err(backend)?;
                let rows: Vec<(String, i64, i64, bool)> = sqlx::query_as(&self.sql.claim_sweep_runs)
                    .bind(&lease.owner)
                    .bind(int(lease.until_ms))
                    .bind(int(now_ms))
                    .bind(i64::from(max_runs))
                    .fetch_all(&mut *tx)
                    .await
                    .map_err(backend)?;
                tx.commit().await.map_err(backend)?;
                let mut sweep = None;
                let mut runs = Vec::with_capacity(rows.len());
                for (id, index, attempts, cancel_requested) in rows {
                    let held = held_run(&id, index, cancel_requested)?;
                    sweep = Some(held.sweep);
                    let attempts = u32::try_from(attempts).unwrap_or(u32::MAX);
                    runs.push(ClaimedRun { index: held.index, attempts, cancel_requested });
                }
                runs.sort_by_key(|run| run.index);
                Ok(sweep.map(|sweep| ClaimedRuns { sweep, runs }))
            }

            async fn renew_sweep_runs(
                &self,
                lease: &$crate::jobs::Lease,
            ) -> Result<Vec<$crate::jobs::HeldRun>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, held_run, int};
                let rows: Vec<(String, i64, bool)> = sqlx::query_as(&self.sql.renew_sweep_runs)
                    .bind(int(lease.until_ms))
                    .bind(&lease.owner)
                    .fetch_all(&self.pool)
                    .await
                    .map_err(backend)?;
                rows.into_iter().map(|(sweep, index, cancel)| held_run(&sweep, index, cancel)).collect()
            }

            async fn finish_sweep_run(
                &self,
                sweep: &$crate::jobs::JobId,
                owner: &str,
                end: $crate::jobs::RunEnd,
            ) -> Result<bool, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, pack_run_result};
                let result = end.result.as_deref().map(pack_run_result).transpose()?;
                let ended = sqlx::query(&self.sql.finish_sweep_run)
                    .bind(end.status.name())
                    .bind(end.message)
                    .bind(result)
                    .bind(sweep.as_str())
                    .bind(i64::from(end.index))
                    .bind(owner)
                    .execute(&self.pool)
                    .await
                    .map_err(backend)?;
                Ok(ended.rows_affected() == 1)
            }

            async fn finish_sweep_runs(
                &self,
                sweep: &$crate::jobs::JobId,
                owner: &str,
                ends: Vec<$crate::jobs::RunEnd>,
            ) -> Result<usize, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{RUN_ENDS_AT_ONCE, backend, pack_run_result};
                let mut tx = self.pool.begin().await.map_err(backend)?;
                let mut recorded = 0;
                for chunk in ends.chunks(RUN_ENDS_AT_ONCE) {
                    let mut statement = sqlx::query(&self.sql.finish_sweep_runs[chunk.len() - 1])
                        .bind(sweep.as_str())
                        .bind(owner);
                    for end in chunk {
                        let result = end.result.as_deref().map(pack_run_result).transpose()?;
                        statement = statement
                            .bind(i64::from(end.index))
                            .bind(end.status.name())
                            .bind(end.message.clone())
                            .bind(result);
                    }
                    let ended = statement.execute(&mut *tx).await.map_err(backend)?;
                    recorded += usize::try_from(ended.rows_affected()).unwrap_or(0);
                }
                tx.commit().await.map_err(backend)?;
                Ok(recorded)
            }

            async fn release_sweep_runs(
                &self,
                sweep: &$crate::jobs::JobId,
                owner: &str,
                runs: &[u32],
            ) -> Result<(), $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::backend;
                let mut tx = self.pool.begin().await.map_err(backend)?;
                for &index in runs {
                    sqlx::query(&self.sql.release_sweep_run)
                        .bind(sweep.as_str())
                        .bind(i64::from(index))
                        .bind(owner)
                        .execute(&mut *tx)
                        .await
                        .map_err(backend)?;
                }
                tx.commit().await.map_err(backend)
            }

            async fn cancel_sweep(
                &self,
                id: &$crate::jobs::JobId,
                now_ms: u64,
                message: &str,
            ) -> Result<Option<$crate::jobs::SweepSummary>, $crate::jobs::StoreError> {
                use $crate::jobs::store::sql::{backend, int};
                let mut tx = self.pool.begin().await.map_err(backend)?;
                let flagged = sqlx::query(&self.sql.flag_sweep_cancel)
                    .bind(id.as_str())
                    .execute(&mut *tx)
                    .await
                    .map_err(backend)?;
                if flagged.rows_affected() == 0 {
                    return Ok(None);
                }
                sqlx::query(&self.sql.cancel_sweep_runs_now)
                    .bind(id.as_str())
                    .bind(message)
                    .bind(int(now_ms))
                    .execute(&mut *tx)
                    .await
                    .map_err(backend)?;
                sqlx::query(&self.sql.flag_sweep_runs_cancel)
                    .bind(id.as_str())
                    .execute(&mut *tx)
                    .await
                    .map_err(backend)?;
                tx.commit().await.map_err(backend)?;
                self.sweep(id).await
            }
        }
    };
}

pub(super) use sql_store;

#[cfg(test)]
mod tests {
    use super::{RAW_RUN_RESULT, compress, pack_run_result, unpack_run_result};

    #[test]
    fn a_small_run_result_is_stored_as_it_is_and_a_large_one_deflated() {
        let small = br#"{"stats":{"steps":3},"last":{"positions":[0.0,1.5,-2.0]}}"#.to_vec();
        assert_eq!(pack_run_result(&small).unwrap(), small);
        assert_eq!(unpack_run_result(&small).unwrap().as_ref(), &small[..]);

        let large = format!("{{\"last\":{{\"positions\":[{}0]}}}}", "0.25,".repeat(RAW_RUN_RESULT / 4));
        let packed = pack_run_result(large.as_bytes()).unwrap();
        assert!(packed.len() < large.len() / 10, "{} bytes of {}", packed.len(), large.len());
        assert_ne!(packed.first(), Some(&b'{'));
        assert_eq!(unpack_run_result(&packed).unwrap().as_ref(), large.as_bytes());
    }

    #[test]
    fn a_run_result_deflated_when_every_one_was_is_still_read() {
        for document in [&br#"{"a":1}"#[..], br#"{"stats":{"steps":3},"last":{"positions":[0.0,1.5]}}"#] {
            let stored = compress(document).unwrap();
            assert_ne!(stored.first(), Some(&b'{'));
            assert_eq!(unpack_run_result(&stored).unwrap().as_ref(), document);
        }
    }
}
