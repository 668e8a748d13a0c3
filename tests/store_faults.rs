//! The job system over a store that fails on command, as one on a full disk does: a claim that
//! cannot be stored starts nothing, an instance never runs two copies of a job, "job ended" is
//! logged only once the end is committed, a normal end is never taken for a lost lease, and a
//! read that crosses a job's end never shows the end without its record.

use std::io::Write;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use async_trait::async_trait;
use drape::jobs::{
    AssetRecord, AssetRoom, CancelRequest, Claim, ClaimedRuns, HeldRun, Inserted, InsertedSweep, JobId,
    JobRecord, JobStatus, JobStore, Jobs, JobsConfig, Lease, MemoryStore, Outcome, Page, PutAsset, Renewed,
    RunEnd, StoreError, StoredResult, StoredRun, Submission, SweepEntry, SweepSummary,
};
use drape::scene::{Compiled, Scene};
use serde_json::json;

/// The longest any wait here may take before the test fails.
const PATIENCE: Duration = Duration::from_secs(60);

/// A memory store that fails the next `fail_claims` claims and `fail_finishes` ends, fails
/// every renewal while `fail_renewals` is set, with `renew_after_end` holds each renewal
/// until an end was committed, and with `read_across_end` answers a read that finds a job not
/// yet ended only once an end was committed and published. It logs each committed end.
#[derive(Default)]
struct Faulty {
    inner: MemoryStore,
    fail_claims: AtomicU32,
    fail_finishes: AtomicU32,
    fail_renewals: AtomicBool,
    renew_after_end: AtomicBool,
    read_across_end: AtomicBool,
    ends_committed: AtomicUsize,
    end_committed: tokio::sync::Notify,
}

fn take_one(counter: &AtomicU32) -> bool {
    counter.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1)).is_ok()
}

fn disk_full() -> StoreError {
    StoreError::Backend("database or disk is full".into())
}

impl Faulty {
    /// With `read_across_end`, waits until an end was committed and the worker that stored it
    /// has had time to publish it.
    async fn after_an_end_when_reading_across(&self) {
        if !self.read_across_end.load(Ordering::SeqCst) {
            return;
        }
        let committed = self.end_committed.notified();
        if self.ends_committed.load(Ordering::SeqCst) == 0 {
            let _ = tokio::time::timeout(PATIENCE, committed).await;
        }
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
}

#[async_trait]
impl JobStore for Faulty {
    fn durable(&self) -> bool {
        true
    }
    async fn insert(&self, job: JobRecord, scene: &str) -> Result<Inserted, StoreError> {
        self.inner.insert(job, scene).await
    }
    async fn get(&self, id: &JobId) -> Result<Option<JobRecord>, StoreError> {
        let record = self.inner.get(id).await?;
        if record.as_ref().is_some_and(|job| !job.status.is_final()) {
            self.after_an_end_when_reading_across().await;
        }
        Ok(record)
    }
    async fn find_by_key(&self, key: &str) -> Result<Option<JobRecord>, StoreError> {
        self.inner.find_by_key(key).await
    }
    async fn list(&self, page: Page) -> Result<Vec<JobRecord>, StoreError> {
        let jobs = self.inner.list(page).await?;
        if jobs.iter().any(|job| !job.status.is_final()) {
            self.after_an_end_when_reading_across().await;
        }
        Ok(jobs)
    }
    async fn count_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError> {
        self.inner.count_by_status().await
    }
    async fn count_queued(&self) -> Result<u64, StoreError> {
        self.inner.count_queued().await
    }
    async fn claim(
        &self,
        lease: &Lease,
        now_ms: u64,
        max_attempts: u32,
    ) -> Result<Option<Claim>, StoreError> {
        if take_one(&self.fail_claims) {
            return Err(disk_full());
        }
        self.inner.claim(lease, now_ms, max_attempts).await
    }
    async fn renew(&self, id: &JobId, lease: &Lease, steps_done: u64) -> Result<Renewed, StoreError> {
        if self.fail_renewals.load(Ordering::SeqCst) {
            return Err(disk_full());
        }
        if self.renew_after_end.load(Ordering::SeqCst) && self.ends_committed.load(Ordering::SeqCst) == 0 {
            let committed = self.end_committed.notified();
            if self.ends_committed.load(Ordering::SeqCst) == 0 {
                let _ = tokio::time::timeout(PATIENCE, committed).await;
            }
        }
        self.inner.renew(id, lease, steps_done).await
    }
    async fn finish(
        &self,
        id: &JobId,
        owner: &str,
        finished_ms: u64,
        outcome: Outcome,
    ) -> Result<bool, StoreError> {
        if take_one(&self.fail_finishes) {
            return Err(disk_full());
        }
        let ended = self.inner.finish(id, owner, finished_ms, outcome).await?;
        if ended {
            tracing::info!(job = %id, "store committed the end");
            self.ends_committed.fetch_add(1, Ordering::SeqCst);
            self.end_committed.notify_waiters();
            if self.renew_after_end.load(Ordering::SeqCst) {
                // The held renewal answers well before the worker learns its end was stored.
                tokio::time::sleep(Duration::from_millis(300)).await;
            }
        }
        Ok(ended)
    }
    async fn release(&self, id: &JobId, owner: &str) -> Result<(), StoreError> {
        self.inner.release(id, owner).await
    }
    async fn request_cancel(
        &self,
        id: &JobId,
        now_ms: u64,
        message: &str,
    ) -> Result<Option<CancelRequest>, StoreError> {
        self.inner.request_cancel(id, now_ms, message).await
    }
    async fn cancel_queued(&self, now_ms: u64, message: &str) -> Result<Vec<JobId>, StoreError> {
        self.inner.cancel_queued(now_ms, message).await
    }
    async fn drop_results(&self, before_ms: u64) -> Result<u64, StoreError> {
        self.inner.drop_results(before_ms).await
    }
    async fn result(&self, id: &JobId) -> Result<Option<StoredResult>, StoreError> {
        self.inner.result(id).await
    }
    async fn put_asset(
        &self,
        asset: &AssetRecord,
        mesh: &[u8],
        room: AssetRoom,
    ) -> Result<PutAsset, StoreError> {
        self.inner.put_asset(asset, mesh, room).await
    }
    async fn asset(&self, id: &str) -> Result<Option<AssetRecord>, StoreError> {
        self.inner.asset(id).await
    }
    async fn asset_mesh(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        self.inner.asset_mesh(id).await
    }
    async fn list_assets(&self) -> Result<Vec<AssetRecord>, StoreError> {
        self.inner.list_assets().await
    }
    async fn delete_asset(&self, id: &str) -> Result<bool, StoreError> {
        self.inner.delete_asset(id).await
    }
    async fn insert_sweep(&self, sweep: &SweepEntry, document: &str) -> Result<InsertedSweep, StoreError> {
        self.inner.insert_sweep(sweep, document).await
    }
    async fn find_sweep_by_key(&self, key: &str) -> Result<Option<SweepSummary>, StoreError> {
        self.inner.find_sweep_by_key(key).await
    }
    async fn sweep(&self, id: &JobId) -> Result<Option<SweepSummary>, StoreError> {
        self.inner.sweep(id).await
    }
    async fn sweep_document(&self, id: &JobId) -> Result<Option<String>, StoreError> {
        self.inner.sweep_document(id).await
    }
    async fn list_sweeps(&self, page: Page) -> Result<Vec<SweepSummary>, StoreError> {
        self.inner.list_sweeps(page).await
    }
    async fn sweep_runs(&self, id: &JobId) -> Result<Vec<StoredRun>, StoreError> {
        self.inner.sweep_runs(id).await
    }
    async fn claim_sweep_runs(
        &self,
        lease: &Lease,
        now_ms: u64,
        max_runs: u32,
    ) -> Result<Option<ClaimedRuns>, StoreError> {
        self.inner.claim_sweep_runs(lease, now_ms, max_runs).await
    }
    async fn renew_sweep_runs(&self, lease: &Lease) -> Result<Vec<HeldRun>, StoreError> {
        self.inner.renew_sweep_runs(lease).await
    }
    async fn finish_sweep_run(&self, sweep: &JobId, owner: &str, end: RunEnd) -> Result<bool, StoreError> {
        self.inner.finish_sweep_run(sweep, owner, end).await
    }
    async fn release_sweep_runs(&self, sweep: &JobId, owner: &str, runs: &[u32]) -> Result<(), StoreError> {
        self.inner.release_sweep_runs(sweep, owner, runs).await
    }
    async fn cancel_sweep(
        &self,
        id: &JobId,
        now_ms: u64,
        message: &str,
    ) -> Result<Option<SweepSummary>, StoreError> {
        self.inner.cancel_sweep(id, now_ms, message).await
    }
}

/// Everything logged by this test binary, one line per event.
fn log() -> &'static Mutex<Vec<u8>> {
    static LOG: OnceLock<Arc<Mutex<Vec<u8>>>> = OnceLock::new();
    LOG.get_or_init(|| {
        let log = Arc::new(Mutex::new(Vec::new()));
        let writer = Arc::clone(&log);
        tracing_subscriber::fmt()
            .with_ansi(false)
            .with_writer(move || Lines(Arc::clone(&writer)))
            .with_max_level(tracing::Level::INFO)
            .init();
        log
    })
}

struct Lines(Arc<Mutex<Vec<u8>>>);

impl Write for Lines {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The logged lines that name the job.
fn lines_of(id: &JobId) -> Vec<String> {
    let text = String::from_utf8(log().lock().unwrap().clone()).unwrap();
    let tag = format!("job={id}");
    text.lines().filter(|line| line.split_whitespace().any(|word| word == tag)).map(str::to_string).collect()
}

fn count(lines: &[String], what: &str) -> usize {
    lines.iter().filter(|line| line.contains(what)).count()
}

/// Counts the runs a hook sees, and the most at once; each run first sleeps `pause`.
#[derive(Default)]
struct Runs {
    started: AtomicUsize,
    now: AtomicUsize,
    most: AtomicUsize,
}

fn config(store_runs: &Arc<Runs>, pause: Duration, workers: usize) -> JobsConfig {
    let runs = Arc::clone(store_runs);
    JobsConfig {
        workers,
        idle_poll: Duration::from_millis(20),
        lease: Duration::from_secs(1),
        before_run: Some(Arc::new(move |_: &Compiled| {
            runs.started.fetch_add(1, Ordering::SeqCst);
            let now = runs.now.fetch_add(1, Ordering::SeqCst) + 1;
            runs.most.fetch_max(now, Ordering::SeqCst);
            std::thread::sleep(pause);
            runs.now.fetch_sub(1, Ordering::SeqCst);
        })),
        ..JobsConfig::default()
    }
}

async fn submit(jobs: &Jobs) -> JobId {
    let document = json!({"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3}],
                          "output": {"frames": "final"}});
    let scene = Scene::from_value(document.clone()).unwrap();
    let submission = Submission { scene, document, fingerprint: 0, idempotency_key: None, max_work: None };
    jobs.submit(submission).await.unwrap().job.id
}

async fn wait(jobs: &Jobs, id: &JobId) -> JobRecord {
    tokio::time::timeout(PATIENCE, jobs.wait(id)).await.expect("the job ended in time").unwrap().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_claim_that_cannot_be_stored_starts_nothing_and_the_worker_tries_again() {
    log();
    let store = Arc::new(Faulty { fail_claims: AtomicU32::new(3), ..Faulty::default() });
    let runs = Arc::new(Runs::default());
    let jobs = Jobs::start(Arc::clone(&store) as Arc<dyn JobStore>, config(&runs, Duration::ZERO, 1));
    let id = submit(&jobs).await;
    let job = wait(&jobs, &id).await;
    assert_eq!((job.status, job.attempts, job.steps_done), (JobStatus::Succeeded, 1, 10));
    assert_eq!(runs.started.load(Ordering::SeqCst), 1, "started once, after the store took a claim");
    assert_eq!(store.fail_claims.load(Ordering::SeqCst), 0, "all three failing claims were tried");
    jobs.shutdown(Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_whose_lease_lapsed_here_is_not_run_a_second_time_by_this_instance() {
    log();
    // Renewals fail: the 1 s lease lapses while the job runs, and the other worker claims it.
    let store = Arc::new(Faulty { fail_renewals: AtomicBool::new(true), ..Faulty::default() });
    let runs = Arc::new(Runs::default());
    let jobs =
        Jobs::start(Arc::clone(&store) as Arc<dyn JobStore>, config(&runs, Duration::from_millis(1600), 2));
    let id = submit(&jobs).await;
    let job = wait(&jobs, &id).await;
    assert_eq!(job.status, JobStatus::Succeeded);
    assert_eq!((runs.started.load(Ordering::SeqCst), runs.most.load(Ordering::SeqCst)), (1, 1));
    let lines = lines_of(&id);
    assert!(count(&lines, "claimed a job this instance already runs") >= 1, "{lines:#?}");
    assert_eq!(count(&lines, "job started"), 1, "{lines:#?}");
    jobs.shutdown(Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_end_that_cannot_be_stored_is_not_logged_as_ended_and_the_job_runs_again() {
    log();
    let store = Arc::new(Faulty { fail_finishes: AtomicU32::new(1), ..Faulty::default() });
    let runs = Arc::new(Runs::default());
    let jobs = Jobs::start(Arc::clone(&store) as Arc<dyn JobStore>, config(&runs, Duration::ZERO, 1));
    let id = submit(&jobs).await;
    // The first end is lost; the job's lease lapses after a second and it runs again.
    let job = wait(&jobs, &id).await;
    assert_eq!((job.status, job.attempts), (JobStatus::Succeeded, 2));
    assert_eq!(runs.started.load(Ordering::SeqCst), 2);
    let lines = lines_of(&id);
    assert_eq!(count(&lines, "cannot store the end of the job"), 1, "{lines:#?}");
    assert_eq!(count(&lines, "job ended"), 1, "{lines:#?}");
    let committed = lines.iter().position(|l| l.contains("store committed the end")).unwrap();
    let ended = lines.iter().position(|l| l.contains("job ended")).unwrap();
    assert!(committed < ended, "\"job ended\" follows the commit: {lines:#?}");
    jobs.shutdown(Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_renewal_that_finds_the_job_just_ended_here_is_not_a_lost_lease() {
    log();
    // The job runs through a renewal, which the store answers only after the end is committed.
    let store = Arc::new(Faulty { renew_after_end: AtomicBool::new(true), ..Faulty::default() });
    let runs = Arc::new(Runs::default());
    let jobs =
        Jobs::start(Arc::clone(&store) as Arc<dyn JobStore>, config(&runs, Duration::from_millis(600), 1));
    let id = submit(&jobs).await;
    let job = wait(&jobs, &id).await;
    assert_eq!(job.status, JobStatus::Succeeded);
    // The held renewal answers once the end is committed; give it time to be logged.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let lines = lines_of(&id);
    assert_eq!(count(&lines, "job ended"), 1, "{lines:#?}");
    assert_eq!(count(&lines, "lease"), 0, "{lines:#?}");
    jobs.shutdown(Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_read_that_crosses_the_end_of_a_job_gives_it_running_never_ended_without_its_record() {
    log();
    let store = Arc::new(Faulty::default());
    let runs = Arc::new(Runs::default());
    let jobs =
        Jobs::start(Arc::clone(&store) as Arc<dyn JobStore>, config(&runs, Duration::from_millis(300), 1));
    let id = submit(&jobs).await;
    tokio::time::timeout(PATIENCE, async {
        while runs.started.load(Ordering::SeqCst) == 0 {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await
    .expect("the job starts");
    // Both reads find the job running in the store and answer after its end is published.
    store.read_across_end.store(true, Ordering::SeqCst);
    let page = Page { offset: 0, limit: 10 };
    let (read, listed) = tokio::join!(jobs.get(&id), jobs.list(page));
    store.read_across_end.store(false, Ordering::SeqCst);
    let read = read.unwrap().expect("the job exists");
    let listed = listed.unwrap().into_iter().find(|job| job.id == id).expect("the job is listed");
    for job in [&read, &listed] {
        assert_eq!(
            (job.status, job.finished_ms, job.stats.is_some()),
            (JobStatus::Running, None, false),
            "{job:?}"
        );
    }
    let ended = wait(&jobs, &id).await;
    assert_eq!((ended.status, ended.steps_done, ended.stats.is_some()), (JobStatus::Succeeded, 10, true));
    assert!(ended.finished_ms.is_some());
    jobs.shutdown(Duration::ZERO).await;
}
