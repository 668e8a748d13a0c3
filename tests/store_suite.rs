//! One suite of job-store tests, run against every backend: memory, SQLite (a file in a temp
//! directory) and PostgreSQL (a database made for each test and dropped after it).
//!
//! Claims take the time as an argument, so lease expiry is tested without sleeping.

mod deadline;
mod pg;

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use drape::jobs::{
    AssetRecord, AssetRoom, CancelRequest, Claim, Claimed, Failure, Idempotency, Inserted, InsertedSweep,
    JobId, JobRecord, JobStatus, JobStore, Jobs, JobsConfig, Lease, MemoryStore, Outcome, Page, Plan,
    PostgresStore, PutAsset, Renewed, RunEnd, SqliteStore, StoredResult, Submission, SweepEntry,
};
use drape::scene::Scene;
use serde_json::json;

/// A store and what must live as long as it.
struct Harness {
    store: Arc<dyn JobStore>,
    _dir: Option<tempfile::TempDir>,
    _database: Option<pg::TestDatabase>,
}

async fn memory() -> Harness {
    Harness { store: Arc::new(MemoryStore::new()), _dir: None, _database: None }
}

async fn sqlite() -> Harness {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("drape.db")).await.unwrap();
    Harness { store: Arc::new(store), _dir: Some(dir), _database: None }
}

async fn postgres() -> Harness {
    let database = pg::TestDatabase::create().await;
    let store = PostgresStore::open(&database.url, 8).await.unwrap();
    Harness { store: Arc::new(store), _dir: None, _database: Some(database) }
}

const T0: u64 = 1_700_000_000_000;
const LEASE_MS: u64 = 30_000;

fn plan() -> Plan {
    Plan { particles: 3, springs: 2, steps: 10, companion_steps: 5, dt: 0.01, duration: 0.1 }
}

fn job(key: Option<(&str, u64)>) -> JobRecord {
    let idempotency = key.map(|(key, fingerprint)| Idempotency { key: key.into(), fingerprint });
    JobRecord { created_ms: T0, ..JobRecord::queued(JobId::new(), plan(), idempotency) }
}

fn scene_of(job: &JobRecord) -> String {
    json!({"duration": 0.1, "tag": job.id.as_str()}).to_string()
}

async fn add(store: &dyn JobStore) -> JobRecord {
    let job = job(None);
    assert_eq!(store.insert(job.clone(), &scene_of(&job)).await.unwrap(), Inserted::New);
    job
}

fn lease(owner: &str, now: u64) -> Lease {
    Lease { owner: owner.into(), until_ms: now + LEASE_MS }
}

fn succeeded(steps: u64, bytes: &[u8]) -> Outcome {
    Outcome {
        status: JobStatus::Succeeded,
        steps_done: steps,
        message: None,
        failure: None,
        stats: Some(json!({"steps": steps, "status": "succeeded"})),
        result: Some(StoredResult { media_type: "application/json", bytes: Bytes::copy_from_slice(bytes) }),
    }
}

/// The `--max-attempts` the suite's claims run under.
const MAX_ATTEMPTS: u32 = 3;

async fn claim(store: &dyn JobStore, owner: &str, now: u64) -> Option<Claimed> {
    match store.claim(&lease(owner, now), now, MAX_ATTEMPTS).await.unwrap()? {
        Claim::Run(claimed) => Some(claimed),
        Claim::GaveUp(job) => panic!("job {} was given up after {} attempts", job.id, job.attempts),
    }
}

async fn jobs_round_trip_and_list_newest_first(store: Arc<dyn JobStore>) {
    let store = &*store;
    let keyed = job(Some(("key-1", u64::MAX - 7)));
    assert_eq!(store.insert(keyed.clone(), "{}").await.unwrap(), Inserted::New);
    let (b, c) = (add(store).await, add(store).await);
    assert_eq!(
        store.get(&keyed.id).await.unwrap(),
        Some(keyed.clone()),
        "every field, the fingerprint's 64 bits too"
    );
    assert_eq!(store.get(&JobId::new()).await.unwrap(), None);
    let ids = |jobs: Vec<JobRecord>| jobs.into_iter().map(|j| j.id).collect::<Vec<_>>();
    assert_eq!(
        ids(store.list(Page { offset: 0, limit: 10 }).await.unwrap()),
        [c.id.clone(), b.id.clone(), keyed.id]
    );
    assert_eq!(ids(store.list(Page { offset: 1, limit: 1 }).await.unwrap()), [b.id]);
    assert_eq!(store.count_queued().await.unwrap(), 3);
    claim(store, "a", T0).await.unwrap();
    let counts: HashMap<JobStatus, u64> = store.count_by_status().await.unwrap().into_iter().collect();
    assert_eq!(counts.len(), JobStatus::ALL.len());
    assert_eq!(
        (counts[&JobStatus::Queued], counts[&JobStatus::Running], counts[&JobStatus::Succeeded]),
        (2, 1, 0)
    );
    assert_eq!(store.count_queued().await.unwrap(), 2);
}

async fn an_idempotency_key_is_held_by_one_job(store: Arc<dyn JobStore>) {
    let first = job(Some(("sweep-17/run-3", 42)));
    assert_eq!(store.insert(first.clone(), "{}").await.unwrap(), Inserted::New);
    let second = job(Some(("sweep-17/run-3", 43)));
    assert_eq!(
        store.insert(second.clone(), "{}").await.unwrap(),
        Inserted::KeyTaken(Box::new(first.clone()))
    );
    assert_eq!(store.get(&second.id).await.unwrap(), None, "nothing was added");
    assert_eq!(store.find_by_key("sweep-17/run-3").await.unwrap(), Some(first));
    assert_eq!(store.find_by_key("other").await.unwrap(), None);
    assert_eq!(store.count_queued().await.unwrap(), 1);
}

async fn claims_take_the_oldest_job_with_its_scene_and_count_attempts(store: Arc<dyn JobStore>) {
    let store = &*store;
    let (a, b) = (add(store).await, add(store).await);
    let first = claim(store, "one", T0 + 5).await.unwrap();
    assert_eq!(first.record.id, a.id);
    assert_eq!(first.scene, scene_of(&a));
    assert_eq!(
        (first.record.status, first.record.attempts, first.record.started_ms),
        (JobStatus::Running, 1, Some(T0 + 5))
    );
    assert_eq!(store.get(&a.id).await.unwrap().unwrap(), first.record);
    assert_eq!(claim(store, "two", T0 + 6).await.unwrap().record.id, b.id);
    assert!(claim(store, "three", T0 + 7).await.is_none(), "both jobs are held under live leases");
}

async fn a_lapsed_lease_hands_the_job_to_another_instance(store: Arc<dyn JobStore>) {
    let store = &*store;
    let a = add(store).await;
    claim(store, "dead", T0).await.unwrap();
    assert!(claim(store, "alive", T0 + LEASE_MS).await.is_none(), "the lease holds until it lapses");
    let again = claim(store, "alive", T0 + LEASE_MS + 1).await.unwrap();
    assert_eq!((again.record.id.clone(), again.record.attempts), (a.id.clone(), 2));
    assert_eq!(again.scene, scene_of(&a));
    // The first owner, back from a pause, finds the job gone and cannot record an end.
    assert_eq!(store.renew(&a.id, &lease("dead", T0 + LEASE_MS + 2), 7).await.unwrap(), Renewed::Lost);
    assert!(!store.finish(&a.id, "dead", T0 + LEASE_MS + 3, succeeded(10, b"dead")).await.unwrap());
    assert!(store.finish(&a.id, "alive", T0 + LEASE_MS + 4, succeeded(10, b"alive")).await.unwrap());
    assert_eq!(store.result(&a.id).await.unwrap().unwrap().bytes, &b"alive"[..]);
    let ended = store.get(&a.id).await.unwrap().unwrap();
    assert_eq!(
        (ended.status, ended.attempts, ended.finished_ms),
        (JobStatus::Succeeded, 2, Some(T0 + LEASE_MS + 4))
    );
    assert!(claim(store, "alive", T0 + 10 * LEASE_MS).await.is_none(), "an ended job is never claimed");
}

async fn renewals_record_progress_and_carry_cancellation(store: Arc<dyn JobStore>) {
    let store = &*store;
    let a = add(store).await;
    claim(store, "one", T0).await.unwrap();
    assert_eq!(
        store.renew(&a.id, &lease("one", T0 + 100), 4).await.unwrap(),
        Renewed::Held { cancel_requested: false }
    );
    assert_eq!(store.get(&a.id).await.unwrap().unwrap().steps_done, 4);
    assert_eq!(store.renew(&a.id, &lease("other", T0 + 100), 5).await.unwrap(), Renewed::Lost);
    // The renewal moved the lease: past the first lease's end the job is still held.
    assert!(claim(store, "two", T0 + LEASE_MS + 50).await.is_none());

    match store.request_cancel(&a.id, T0 + 200, "cancelled by request").await.unwrap() {
        Some(CancelRequest::Requested(job)) => assert_eq!(job.status, JobStatus::Running),
        other => panic!("a running job is flagged, not ended: {other:?}"),
    }
    assert_eq!(
        store.renew(&a.id, &lease("one", T0 + 300), 6).await.unwrap(),
        Renewed::Held { cancel_requested: true }
    );
    let outcome = Outcome {
        status: JobStatus::Cancelled,
        steps_done: 6,
        message: Some("cancelled by request".into()),
        failure: None,
        stats: None,
        result: None,
    };
    assert!(store.finish(&a.id, "one", T0 + 400, outcome).await.unwrap());
    let ended = store.get(&a.id).await.unwrap().unwrap();
    assert_eq!(
        (ended.status, ended.steps_done, ended.message.as_deref()),
        (JobStatus::Cancelled, 6, Some("cancelled by request"))
    );
    assert!(matches!(
        store.request_cancel(&a.id, T0 + 500, "x").await.unwrap(),
        Some(CancelRequest::AlreadyEnded(_))
    ));
    assert_eq!(
        store.renew(&a.id, &lease("one", T0 + 600), 7).await.unwrap(),
        Renewed::Lost,
        "an ended job is no one's"
    );
}

async fn cancelling_a_queued_or_abandoned_job_ends_it_at_once(store: Arc<dyn JobStore>) {
    let store = &*store;
    let (queued, abandoned) = (add(store).await, add(store).await);
    claim(store, "a", T0).await.unwrap();
    claim(store, "b", T0).await.unwrap();
    // `queued` went first; put it back as shutdown does, then cancel it.
    store.release(&queued.id, "a").await.unwrap();
    assert_eq!(store.get(&queued.id).await.unwrap().unwrap().status, JobStatus::Queued);
    match store.request_cancel(&queued.id, T0 + 1, "cancelled by request").await.unwrap() {
        Some(CancelRequest::Cancelled(job)) => {
            assert_eq!(
                (job.status, job.finished_ms, job.message.as_deref()),
                (JobStatus::Cancelled, Some(T0 + 1), Some("cancelled by request"))
            );
        }
        other => panic!("{other:?}"),
    }
    // `abandoned`'s instance died: its lease lapsed, so nobody is left to read a flag.
    match store.request_cancel(&abandoned.id, T0 + LEASE_MS + 1, "cancelled by request").await.unwrap() {
        Some(CancelRequest::Cancelled(job)) => assert_eq!(job.status, JobStatus::Cancelled),
        other => panic!("{other:?}"),
    }
    assert!(claim(store, "c", T0 + 10 * LEASE_MS).await.is_none());
    assert!(store.request_cancel(&JobId::new(), T0, "x").await.unwrap().is_none());
}

async fn a_released_job_runs_again_from_the_start(store: Arc<dyn JobStore>) {
    let store = &*store;
    let a = add(store).await;
    claim(store, "a", T0).await.unwrap();
    store.renew(&a.id, &lease("a", T0 + 10), 5).await.unwrap();
    store.release(&a.id, "someone else").await.unwrap();
    assert_eq!(
        store.get(&a.id).await.unwrap().unwrap().status,
        JobStatus::Running,
        "only the owner releases"
    );
    store.release(&a.id, "a").await.unwrap();
    let released = store.get(&a.id).await.unwrap().unwrap();
    // A release (a shutdown) is not a start that failed to end: its attempt is given back.
    assert_eq!((released.status, released.steps_done, released.attempts), (JobStatus::Queued, 0, 0));
    let again = claim(store, "b", T0 + 20).await.unwrap();
    assert_eq!((again.record.id, again.record.attempts), (a.id, 1));
}

/// A job whose every start ended with its instance (three lapsed leases) is failed on the
/// claim after the third, with the reason, and is never handed out again; the next job runs.
async fn a_job_started_max_attempts_times_without_ending_is_failed_not_run(store: Arc<dyn JobStore>) {
    let store = &*store;
    let (poison, next) = (add(store).await, add(store).await);
    let mut now = T0;
    for attempt in 1..=MAX_ATTEMPTS {
        let claimed = claim(store, &format!("crashed-{attempt}"), now).await.unwrap();
        assert_eq!((claimed.record.id.clone(), claimed.record.attempts), (poison.id.clone(), attempt));
        now += LEASE_MS + 1;
    }
    let given_up = match store.claim(&lease("fourth", now), now, MAX_ATTEMPTS).await.unwrap() {
        Some(Claim::GaveUp(job)) => job,
        other => panic!("the job was handed out a fourth time: {other:?}"),
    };
    let reason = "the job was started 3 times without ending (--max-attempts 3): it may crash the server";
    assert_eq!(
        (
            given_up.id.clone(),
            given_up.status,
            given_up.attempts,
            given_up.failure,
            given_up.message.as_deref()
        ),
        (poison.id.clone(), JobStatus::Failed, 3, Some(Failure::Attempts), Some(reason))
    );
    assert_eq!(given_up.finished_ms, Some(now));
    assert_eq!(store.get(&poison.id).await.unwrap().unwrap(), given_up);
    assert!(
        !store.finish(&poison.id, "crashed-3", now + 1, succeeded(10, b"late")).await.unwrap(),
        "its last instance cannot record an end"
    );
    let claimed = claim(store, "fourth", now + 2).await.unwrap();
    assert_eq!((claimed.record.id, claimed.record.attempts), (next.id, 1));
    assert!(claim(store, "fifth", now + 3).await.is_none(), "the failed job is never claimed");
}

async fn results_are_kept_whole_until_their_retention_ends(store: Arc<dyn JobStore>) {
    let store = &*store;
    let (old, new) = (add(store).await, add(store).await);
    // A result of the size and repetitiveness of real output: numbers in JSON.
    let body: String = (0..20_000).map(|i| format!("{:.6},", (i as f64 * 0.37).sin())).collect();
    for (job, at) in [(&old, T0 + 1_000), (&new, T0 + 5_000)] {
        claim(store, "a", T0).await.unwrap();
        assert!(store.finish(&job.id, "a", at, succeeded(10, body.as_bytes())).await.unwrap());
    }
    let result = store.result(&old.id).await.unwrap().unwrap();
    assert_eq!((result.media_type, result.bytes.as_ref()), ("application/json", body.as_bytes()));
    let ended = store.get(&old.id).await.unwrap().unwrap();
    assert_eq!(ended.stats, Some(json!({"steps": 10, "status": "succeeded"})));
    assert_eq!(store.drop_results(T0 + 1_000).await.unwrap(), 0, "a result ended exactly at the cut is kept");
    assert_eq!(store.drop_results(T0 + 2_000).await.unwrap(), 1);
    assert_eq!(store.result(&old.id).await.unwrap(), None);
    assert_eq!(
        store.get(&old.id).await.unwrap().unwrap().status,
        JobStatus::Succeeded,
        "the job itself stays"
    );
    assert_eq!(store.result(&new.id).await.unwrap().unwrap().bytes.as_ref(), body.as_bytes());

    // A failure keeps its kind and has no result; a binary result keeps its media type.
    let (failed, binary) = (add(store).await, add(store).await);
    claim(store, "a", T0).await.unwrap();
    claim(store, "a", T0).await.unwrap();
    let outcome = Outcome {
        status: JobStatus::Failed,
        steps_done: 3,
        message: Some("the job exceeded the wall-time limit".into()),
        failure: Some(Failure::WallTime),
        stats: None,
        result: None,
    };
    assert!(store.finish(&failed.id, "a", T0 + 6_000, outcome).await.unwrap());
    let ended = store.get(&failed.id).await.unwrap().unwrap();
    assert_eq!(
        (ended.status, ended.failure, ended.steps_done),
        (JobStatus::Failed, Some(Failure::WallTime), 3)
    );
    assert_eq!(store.result(&failed.id).await.unwrap(), None);
    let glb: Vec<u8> = (0..=255u8).cycle().take(5000).collect();
    let outcome = Outcome {
        result: Some(StoredResult { media_type: "model/gltf-binary", bytes: Bytes::from(glb.clone()) }),
        ..succeeded(10, b"")
    };
    assert!(store.finish(&binary.id, "a", T0 + 6_000, outcome).await.unwrap());
    let result = store.result(&binary.id).await.unwrap().unwrap();
    assert_eq!((result.media_type, result.bytes.as_ref()), ("model/gltf-binary", glb.as_slice()));
}

async fn shutdown_cancels_only_queued_jobs(store: Arc<dyn JobStore>) {
    let store = &*store;
    let (running, q1, q2) = (add(store).await, add(store).await, add(store).await);
    claim(store, "a", T0).await.unwrap();
    let mut cancelled =
        store.cancel_queued(T0 + 1, "the server shut down before the job finished").await.unwrap();
    cancelled.sort();
    let mut expected = vec![q1.id.clone(), q2.id];
    expected.sort();
    assert_eq!(cancelled, expected);
    assert_eq!(store.get(&running.id).await.unwrap().unwrap().status, JobStatus::Running);
    assert_eq!(
        store.get(&q1.id).await.unwrap().unwrap().message.as_deref(),
        Some("the server shut down before the job finished")
    );
}

/// Claimers racing for 60 jobs: each job is handed out exactly once.
async fn racing_claimers_never_share_a_job(store: Arc<dyn JobStore>) {
    let mut ids = Vec::new();
    for _ in 0..60 {
        ids.push(add(&*store).await.id);
    }
    let claimers: Vec<_> = (0..6)
        .map(|n| {
            let store = Arc::clone(&store);
            tokio::spawn(async move {
                let mut got = Vec::new();
                while let Some(claimed) = claim(&*store, &format!("instance-{n}"), T0).await {
                    got.push(claimed.record.id);
                }
                got
            })
        })
        .collect();
    let mut claimed = Vec::new();
    for claimer in claimers {
        claimed.extend(claimer.await.unwrap());
    }
    claimed.sort();
    ids.sort();
    assert_eq!(claimed, ids);
}

/// A job queued through this instance wakes an idle worker: with workers looking in the store
/// on their own only once an hour, each of several jobs queued one after another still runs to
/// its end. The wait is bounded by the tests' patience, far below the hour of the idle poll, so
/// a job that waited for the poll fails here rather than hanging the suite.
async fn a_queued_job_wakes_an_idle_worker(store: Arc<dyn JobStore>) {
    let idle_poll = Duration::from_secs(3600);
    let jobs = Jobs::start(store, JobsConfig { workers: 1, idle_poll, ..JobsConfig::default() });
    for count in 2..5 {
        let document = json!({"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": count}],
                              "output": {"frames": "final"}});
        let scene = Scene::from_value(document.clone()).unwrap();
        let submission =
            Submission { scene, document, fingerprint: 0, idempotency_key: None, max_work: None };
        let id = jobs.submit(submission).await.unwrap().job.id;
        assert!(deadline::PATIENCE < idle_poll / 2);
        let ended = deadline::within("the job to run without waiting for the idle poll", jobs.wait(&id))
            .await
            .unwrap()
            .unwrap();
        assert_eq!((ended.status, ended.steps_done, ended.attempts), (JobStatus::Succeeded, 10, 1));
    }
    jobs.shutdown(Duration::ZERO).await;
}

fn asset(tag: u8, bytes: u64) -> AssetRecord {
    AssetRecord {
        id: format!("sha256:{}", format!("{tag:02x}").repeat(32)),
        vertices: 3 + u64::from(tag),
        triangles: 1 + u64::from(tag),
        bytes,
        created_ms: T0 + u64::from(tag),
    }
}

const ROOMY: AssetRoom = AssetRoom { max_assets: 100, max_bytes: 1 << 20 };

async fn assets_are_stored_once_listed_newest_first_and_deleted(store: Arc<dyn JobStore>) {
    let (a, b) = (asset(1, 10), asset(2, 20));
    let mesh_a: Vec<u8> = (0..=255).collect();
    assert_eq!(store.put_asset(&a, &mesh_a, ROOMY).await.unwrap(), PutAsset::Added);
    // The same id again keeps the first upload, its time included.
    let again = AssetRecord { created_ms: T0 + 99, ..a.clone() };
    assert_eq!(store.put_asset(&again, b"other", ROOMY).await.unwrap(), PutAsset::Exists(a.clone()));
    assert_eq!(store.put_asset(&b, b"b", ROOMY).await.unwrap(), PutAsset::Added);
    assert_eq!(store.asset(&a.id).await.unwrap(), Some(a.clone()));
    assert_eq!(store.asset_mesh(&a.id).await.unwrap(), Some(mesh_a));
    assert_eq!(store.list_assets().await.unwrap(), vec![b.clone(), a.clone()]);
    assert!(store.delete_asset(&a.id).await.unwrap());
    assert!(!store.delete_asset(&a.id).await.unwrap());
    assert_eq!(store.asset(&a.id).await.unwrap(), None);
    assert_eq!(store.asset_mesh(&a.id).await.unwrap(), None);
    assert_eq!(store.list_assets().await.unwrap(), vec![b]);
}

async fn assets_never_pass_their_room(store: Arc<dyn JobStore>) {
    let room = AssetRoom { max_assets: 2, max_bytes: 100 };
    assert_eq!(store.put_asset(&asset(1, 60), b"1", room).await.unwrap(), PutAsset::Added);
    assert_eq!(
        store.put_asset(&asset(2, 41), b"2", room).await.unwrap(),
        PutAsset::Full { assets: 1, bytes: 60 }
    );
    assert_eq!(store.put_asset(&asset(3, 40), b"3", room).await.unwrap(), PutAsset::Added);
    assert_eq!(
        store.put_asset(&asset(4, 0), b"4", room).await.unwrap(),
        PutAsset::Full { assets: 2, bytes: 100 }
    );
    // One already stored is found, not refused, when the store is full.
    assert_eq!(store.put_asset(&asset(3, 40), b"3", room).await.unwrap(), PutAsset::Exists(asset(3, 40)));
    assert!(store.delete_asset(&asset(1, 60).id).await.unwrap());
    assert_eq!(store.put_asset(&asset(2, 41), b"2", room).await.unwrap(), PutAsset::Added);
}

fn sweep_entry(runs: u32, has_reference: bool) -> SweepEntry {
    SweepEntry { id: JobId::new(), created_ms: T0, runs, has_reference, idempotency: None }
}

fn keyed_sweep(runs: u32, key: &str, fingerprint: u64) -> SweepEntry {
    SweepEntry { idempotency: Some(Idempotency { key: key.into(), fingerprint }), ..sweep_entry(runs, false) }
}

/// The indices and attempts of the runs `owner` claims at `now`, and their sweep.
async fn claim_runs(
    store: &dyn JobStore,
    owner: &str,
    now: u64,
    max: u32,
) -> Option<(JobId, Vec<(u32, u32)>)> {
    let claimed = store.claim_sweep_runs(&lease(owner, now), now, max).await.unwrap()?;
    Some((claimed.sweep, claimed.runs.iter().map(|r| (r.index, r.attempts)).collect()))
}

fn run_end(index: u32, result: &[u8]) -> RunEnd {
    RunEnd {
        index,
        status: JobStatus::Succeeded,
        message: None,
        result: Some(Bytes::copy_from_slice(result)),
    }
}

async fn sweeps_are_stored_with_a_row_per_run_and_listed_newest_first(store: Arc<dyn JobStore>) {
    let (old, new) = (sweep_entry(3, true), sweep_entry(2000, false));
    store.insert_sweep(&old, r#"{"tag": "old"}"#).await.unwrap();
    store.insert_sweep(&new, r#"{"tag": "new"}"#).await.unwrap();
    let summary = store.sweep(&old.id).await.unwrap().unwrap();
    assert_eq!(
        (summary.entry, summary.finished, summary.running, summary.cancel_requested),
        (old.clone(), 0, 0, false)
    );
    assert_eq!(store.sweep_document(&new.id).await.unwrap().unwrap(), r#"{"tag": "new"}"#);
    let runs = store.sweep_runs(&new.id).await.unwrap();
    assert_eq!(runs.len(), 2000);
    assert!(runs.iter().all(|r| r.status == JobStatus::Queued && r.result.is_none()));
    let listed: Vec<JobId> = store
        .list_sweeps(Page { offset: 0, limit: 10 })
        .await
        .unwrap()
        .into_iter()
        .map(|s| s.entry.id)
        .collect();
    assert_eq!(listed, [new.id.clone(), old.id.clone()]);
    let second: Vec<JobId> = store
        .list_sweeps(Page { offset: 1, limit: 10 })
        .await
        .unwrap()
        .into_iter()
        .map(|s| s.entry.id)
        .collect();
    assert_eq!(second, [old.id]);
    let unknown = JobId::new();
    assert!(store.sweep(&unknown).await.unwrap().is_none());
    assert!(store.sweep_runs(&unknown).await.unwrap().is_empty());
    assert!(store.cancel_sweep(&unknown, T0, "cancelled").await.unwrap().is_none());
}

async fn sweep_runs_are_claimed_in_batches_of_the_oldest_sweep_under_a_lease(store: Arc<dyn JobStore>) {
    let (first, second) = (sweep_entry(3, true), sweep_entry(2, false));
    store.insert_sweep(&first, "{}").await.unwrap();
    store.insert_sweep(&second, "{}").await.unwrap();
    assert_eq!(claim_runs(&*store, "a", T0, 2).await, Some((first.id.clone(), vec![(0, 1), (1, 1)])));
    assert_eq!(claim_runs(&*store, "b", T0, 2).await, Some((first.id.clone(), vec![(2, 1)])));
    assert_eq!(store.sweep(&first.id).await.unwrap().unwrap().running, 3);

    // The end of a run is stored by its holder only, with its result.
    assert!(!store.finish_sweep_run(&first.id, "b", run_end(0, b"not b's")).await.unwrap());
    assert!(store.finish_sweep_run(&first.id, "a", run_end(0, b"{\"final\": 1}")).await.unwrap());
    let runs = store.sweep_runs(&first.id).await.unwrap();
    assert_eq!(
        (runs[0].status, runs[0].result.as_deref()),
        (JobStatus::Succeeded, Some(&b"{\"final\": 1}"[..]))
    );
    assert_eq!((runs[1].status, runs[2].status), (JobStatus::Running, JobStatus::Running));
    let summary = store.sweep(&first.id).await.unwrap().unwrap();
    assert_eq!((summary.finished, summary.running), (1, 2));

    // Renewals keep the runs an owner holds; a released run waits again with its attempt back.
    let held = store.renew_sweep_runs(&lease("a", T0 + 10)).await.unwrap();
    assert_eq!(held.iter().map(|h| (h.sweep.clone(), h.index)).collect::<Vec<_>>(), [(first.id.clone(), 1)]);
    store.release_sweep_runs(&first.id, "b", &[2]).await.unwrap();
    assert_eq!(claim_runs(&*store, "c", T0 + 20, 5).await, Some((first.id.clone(), vec![(2, 1)])));
    // `b` released nothing it did not hold; run 1's lease (renewed at T0 + 10) lapses later.
    assert_eq!(claim_runs(&*store, "c", T0 + 20, 5).await, Some((second.id.clone(), vec![(0, 1), (1, 1)])));
    assert_eq!(claim_runs(&*store, "c", T0 + 20, 5).await, None);
    assert_eq!(claim_runs(&*store, "d", T0 + 11 + LEASE_MS, 5).await, Some((first.id.clone(), vec![(1, 2)])));
    assert!(!store.finish_sweep_run(&first.id, "a", run_end(1, b"late")).await.unwrap(), "a's lease lapsed");
}

async fn cancelling_a_sweep_ends_its_waiting_runs_and_flags_its_running_ones(store: Arc<dyn JobStore>) {
    let sweep = sweep_entry(4, false);
    store.insert_sweep(&sweep, "{}").await.unwrap();
    assert_eq!(claim_runs(&*store, "a", T0 + 10, 1).await, Some((sweep.id.clone(), vec![(0, 1)])));
    assert_eq!(claim_runs(&*store, "b", T0, 1).await, Some((sweep.id.clone(), vec![(1, 1)])));
    // b's lease (from T0) lapses, a's (from T0 + 10) does not: b's run is cancelled at once, like the waiting ones; a's is flagged.
    let summary =
        store.cancel_sweep(&sweep.id, T0 + LEASE_MS + 1, "cancelled by request").await.unwrap().unwrap();
    assert!(summary.cancel_requested);
    let statuses: Vec<JobStatus> =
        store.sweep_runs(&sweep.id).await.unwrap().iter().map(|r| r.status).collect();
    assert_eq!(
        statuses,
        [JobStatus::Running, JobStatus::Cancelled, JobStatus::Cancelled, JobStatus::Cancelled]
    );
    let runs = store.sweep_runs(&sweep.id).await.unwrap();
    assert_eq!(runs[2].message.as_deref(), Some("cancelled by request"));
    let held = store.renew_sweep_runs(&lease("a", T0 + 12)).await.unwrap();
    assert_eq!((held.len(), held[0].cancel_requested), (1, true));
    // If a dies, whoever claims the run learns it is to be ended, not run.
    let claimed = store
        .claim_sweep_runs(&lease("c", T0 + 13 + LEASE_MS), T0 + 13 + LEASE_MS, 5)
        .await
        .unwrap()
        .unwrap();
    assert_eq!((claimed.runs[0].index, claimed.runs[0].cancel_requested), (0, true));
    let ended = RunEnd {
        index: 0,
        status: JobStatus::Cancelled,
        message: Some("cancelled by request".into()),
        result: None,
    };
    assert!(store.finish_sweep_run(&sweep.id, "c", ended).await.unwrap());
    let summary = store.sweep(&sweep.id).await.unwrap().unwrap();
    assert!(summary.is_complete());
    assert_eq!(claim_runs(&*store, "c", T0 + 14 + LEASE_MS, 5).await, None);
}

async fn a_sweep_idempotency_key_is_held_by_one_sweep(store: Arc<dyn JobStore>) {
    let first = keyed_sweep(3, "ci-step", 7);
    assert_eq!(store.insert_sweep(&first, r#"{"tag": "first"}"#).await.unwrap(), InsertedSweep::New);
    let held = store.find_sweep_by_key("ci-step").await.unwrap().unwrap();
    assert_eq!((held.entry.clone(), held.finished), (first.clone(), 0));

    // A second sweep under the key, whatever its fingerprint, is not added: the holder is found.
    for fingerprint in [7, 8] {
        let again = keyed_sweep(5, "ci-step", fingerprint);
        assert_eq!(
            store.insert_sweep(&again, "{}").await.unwrap(),
            InsertedSweep::KeyTaken(Box::new(held.clone()))
        );
        assert!(store.sweep(&again.id).await.unwrap().is_none());
        assert!(store.sweep_runs(&again.id).await.unwrap().is_empty());
    }
    assert_eq!(store.sweep_document(&first.id).await.unwrap().unwrap(), r#"{"tag": "first"}"#);

    // Sweeps without a key never collide, and a key of a job is not a key of a sweep.
    let (a, b) = (sweep_entry(1, false), sweep_entry(1, false));
    assert_eq!(store.insert_sweep(&a, "{}").await.unwrap(), InsertedSweep::New);
    assert_eq!(store.insert_sweep(&b, "{}").await.unwrap(), InsertedSweep::New);
    assert!(store.find_sweep_by_key("other").await.unwrap().is_none());
    assert_eq!(store.insert(job(Some(("ci-step", 7))), "{}").await.unwrap(), Inserted::New);
    let listed = store.list_sweeps(Page { offset: 0, limit: 10 }).await.unwrap();
    assert_eq!(listed.len(), 3);
    assert_eq!(listed[2].entry.idempotency, first.idempotency);
}

async fn the_ends_of_a_batch_are_stored_together_for_the_runs_still_held(store: Arc<dyn JobStore>) {
    let sweep = sweep_entry(3, false);
    store.insert_sweep(&sweep, "{}").await.unwrap();
    assert_eq!(claim_runs(&*store, "a", T0, 1).await, Some((sweep.id.clone(), vec![(0, 1)])));
    assert_eq!(claim_runs(&*store, "b", T0, 1).await, Some((sweep.id.clone(), vec![(1, 1)])));
    // a holds run 0 alone: b's run 1 and the waiting run 2 are not a's to end.
    let ends = vec![run_end(0, b"{\"run\": 0}"), run_end(1, b"not a's"), run_end(2, b"not started")];
    assert_eq!(store.finish_sweep_runs(&sweep.id, "a", ends).await.unwrap(), 1);
    let runs = store.sweep_runs(&sweep.id).await.unwrap();
    let statuses: Vec<JobStatus> = runs.iter().map(|r| r.status).collect();
    assert_eq!(statuses, [JobStatus::Succeeded, JobStatus::Running, JobStatus::Queued]);
    assert_eq!(runs[0].result.as_deref(), Some(&b"{\"run\": 0}"[..]));
    assert_eq!(store.finish_sweep_runs(&sweep.id, "b", vec![run_end(1, b"b's")]).await.unwrap(), 1);
    assert_eq!(store.finish_sweep_runs(&sweep.id, "b", Vec::new()).await.unwrap(), 0);
    let summary = store.sweep(&sweep.id).await.unwrap().unwrap();
    assert_eq!((summary.finished, summary.running), (2, 0));
}

async fn a_hundred_ends_are_stored_at_once_each_with_its_own_result(store: Arc<dyn JobStore>) {
    let sweep = sweep_entry(101, false);
    store.insert_sweep(&sweep, "{}").await.unwrap();
    let (_, claimed) = claim_runs(&*store, "a", T0, 100).await.unwrap();
    assert_eq!(claimed.len(), 100);
    let results: Vec<String> = (0..100).map(|i| format!("{{\"run\": {i}}}")).collect();
    let mut ends: Vec<RunEnd> = (0..100).map(|i| run_end(i, results[i as usize].as_bytes())).collect();
    ends[70] = RunEnd {
        status: JobStatus::Failed,
        message: Some("run 70 failed".into()),
        result: None,
        ..ends[70].clone()
    };
    assert_eq!(store.finish_sweep_runs(&sweep.id, "a", ends).await.unwrap(), 100);
    let runs = store.sweep_runs(&sweep.id).await.unwrap();
    for (i, run) in runs.iter().enumerate().take(100) {
        if i == 70 {
            assert_eq!(
                (run.status, run.message.as_deref(), &run.result),
                (JobStatus::Failed, Some("run 70 failed"), &None)
            );
        } else {
            assert_eq!(
                (run.status, run.result.as_deref()),
                (JobStatus::Succeeded, Some(results[i].as_bytes())),
                "run {i}"
            );
        }
    }
    assert_eq!(runs[100].status, JobStatus::Queued);
    let summary = store.sweep(&sweep.id).await.unwrap().unwrap();
    assert_eq!((summary.finished, summary.running), (100, 0));
}

/// A module named for the backend with one test per suite function, each carrying the
/// attributes in brackets (for PostgreSQL, an `ignore` with what it needs).
macro_rules! suite {
    ($backend:ident $attributes:tt: $($test:ident),* $(,)?) => {
        mod $backend {
            $(suite!(@test $backend $test $attributes);)*
        }
    };
    (@test $backend:ident $test:ident [$(#[$attribute:meta])*]) => {
        $(#[$attribute])*
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn $test() {
            let harness = super::$backend().await;
            super::$test(std::sync::Arc::clone(&harness.store)).await;
        }
    };
}

macro_rules! every_backend {
    ($($test:ident),* $(,)?) => {
        suite!(memory []: $($test),*);
        suite!(sqlite []: $($test),*);
        suite!(postgres [#[ignore = "needs PostgreSQL on 127.0.0.1:5432 (or DRAPE_TEST_POSTGRES); see README.md, Run the tests"]]: $($test),*);
    };
}

every_backend!(
    jobs_round_trip_and_list_newest_first,
    an_idempotency_key_is_held_by_one_job,
    claims_take_the_oldest_job_with_its_scene_and_count_attempts,
    a_lapsed_lease_hands_the_job_to_another_instance,
    renewals_record_progress_and_carry_cancellation,
    cancelling_a_queued_or_abandoned_job_ends_it_at_once,
    a_released_job_runs_again_from_the_start,
    a_job_started_max_attempts_times_without_ending_is_failed_not_run,
    results_are_kept_whole_until_their_retention_ends,
    shutdown_cancels_only_queued_jobs,
    racing_claimers_never_share_a_job,
    a_queued_job_wakes_an_idle_worker,
    assets_are_stored_once_listed_newest_first_and_deleted,
    assets_never_pass_their_room,
    sweeps_are_stored_with_a_row_per_run_and_listed_newest_first,
    sweep_runs_are_claimed_in_batches_of_the_oldest_sweep_under_a_lease,
    cancelling_a_sweep_ends_its_waiting_runs_and_flags_its_running_ones,
    a_sweep_idempotency_key_is_held_by_one_sweep,
    the_ends_of_a_batch_are_stored_together_for_the_runs_still_held,
    a_hundred_ends_are_stored_at_once_each_with_its_own_result,
);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sqlite_store_keeps_its_jobs_across_a_reopen_and_reruns_the_one_that_was_running() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drape.db");
    let (done, running, queued);
    {
        let store = SqliteStore::open(&path).await.unwrap();
        done = add(&store).await;
        running = add(&store).await;
        queued = add(&store).await;
        claim(&store, "old", T0).await.unwrap();
        assert!(store.finish(&done.id, "old", T0 + 1, succeeded(10, b"[1,2,3]")).await.unwrap());
        claim(&store, "old", T0 + 2).await.unwrap();
    }
    let store = SqliteStore::open(&path).await.unwrap();
    assert_eq!(store.result(&done.id).await.unwrap().unwrap().bytes.as_ref(), b"[1,2,3]");
    // The process that held `running` is gone: it is claimed again at once, not after its lease.
    let again = claim(&store, "new", T0 + 3).await.unwrap();
    assert_eq!((again.record.id, again.record.attempts), (running.id, 2));
    let next = claim(&store, "new", T0 + 4).await.unwrap();
    assert_eq!((next.record.id, next.record.attempts), (queued.id, 1));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "needs PostgreSQL on 127.0.0.1:5432 (or DRAPE_TEST_POSTGRES); see README.md, Run the tests"]
async fn postgres_instances_share_one_queue_and_one_key_space() {
    let database = pg::TestDatabase::create().await;
    let (one, two) = (
        PostgresStore::open(&database.url, 4).await.unwrap(),
        PostgresStore::open(&database.url, 4).await.unwrap(),
    );
    let keyed = job(Some(("shared", 1)));
    assert_eq!(one.insert(keyed.clone(), "{}").await.unwrap(), Inserted::New);
    assert_eq!(
        two.insert(job(Some(("shared", 1))), "{}").await.unwrap(),
        Inserted::KeyTaken(Box::new(keyed.clone()))
    );
    let claimed = claim(&two, "two", T0).await.unwrap();
    assert_eq!(claimed.record.id, keyed.id);
    assert!(claim(&one, "one", T0).await.is_none());
    assert_eq!(one.get(&keyed.id).await.unwrap().unwrap().status, JobStatus::Running);

    let sweep = keyed_sweep(2, "shared", 1);
    assert_eq!(one.insert_sweep(&sweep, "{}").await.unwrap(), InsertedSweep::New);
    match two.insert_sweep(&keyed_sweep(2, "shared", 1), "{}").await.unwrap() {
        InsertedSweep::KeyTaken(holder) => assert_eq!(holder.entry, sweep),
        InsertedSweep::New => panic!("the other instance's sweep holds the key"),
    }
}
