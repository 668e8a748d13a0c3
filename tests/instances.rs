//! Two `drape serve` processes on one PostgreSQL database share one queue: every job runs
//! exactly once while both live, either answers for any job, a cancellation sent to one stops a
//! job running on the other, and when one is killed in the middle of a job the other runs it.

#![cfg(unix)]

mod deadline;
mod pg;
mod serve;

use std::collections::HashMap;

use serve::{Server, ended, job, result, submit, submit_sweep, sweep, under_way, wait_for, wait_for_sweep};

/// About 20 ms of work: long enough that both instances get some of the 40 jobs.
const SMALL: &str = r#"{"duration": 1, "dt": 0.001, "bodies": [{"type": "chain", "count": 500}],
                       "output": {"frames": "final"}}"#;
/// A few seconds of work.
const MEDIUM: &str = r#"{"duration": 15, "dt": 0.001, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 20000}],
                        "output": {"frames": "final"}}"#;
/// Far longer than the test: it ends only by cancellation.
const LONG: &str = r#"{"duration": 1000, "dt": 0.001, "gravity": [0, 0, 0],
                      "bodies": [{"type": "chain", "count": 10000}],
                      "output": {"frames": "none"}}"#;

fn counts(starts: impl IntoIterator<Item = String>) -> HashMap<String, usize> {
    let mut counts = HashMap::new();
    for id in starts {
        *counts.entry(id).or_insert(0) += 1;
    }
    counts
}

/// Whether the job was started by `one` rather than `two`, once either log shows it.
async fn runs_on(id: &str, one: &Server, two: &Server) -> bool {
    tokio::time::timeout(serve::PATIENCE, async {
        loop {
            match (one.starts().iter().any(|s| s == id), two.starts().iter().any(|s| s == id)) {
                (true, false) => return true,
                (false, true) => return false,
                (true, true) => panic!("job {id} was started by both instances"),
                (false, false) => tokio::time::sleep(std::time::Duration::from_millis(10)).await,
            }
        }
    })
    .await
    .expect("an instance logs the start of the job")
}

/// A sweep of `count` variants of a 500-particle chain, about 20 ms each.
fn sweep_of(count: usize) -> String {
    let dts: Vec<f64> = (0..count).map(|n| 0.001 + 0.00001 * n as f64).collect();
    serde_json::json!({
        "scene": {"duration": 1, "bodies": [{"type": "chain", "count": 500}], "error_estimate": "none"},
        "vary": {"/dt": dts},
    })
    .to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "needs PostgreSQL on 127.0.0.1:5432 (or DRAPE_TEST_POSTGRES); see README.md, Run the tests"]
async fn two_instances_share_the_sweeps_of_one_postgres_database() {
    let database = pg::TestDatabase::create().await;
    let dir = tempfile::tempdir().unwrap();
    let args = ["--workers", "1", "--lease", "1"];
    let one = Server::start(dir.path(), &database.url, &args);
    let two = Server::start(dir.path(), &database.url, &args);
    let client = reqwest::Client::new();

    // Posted to one, read through the other; both run its runs, each once.
    let id = submit_sweep(&client, &one.base, &sweep_of(40)).await;
    let done = wait_for_sweep(&client, &two.base, &id, |s| s["complete"] == true).await;
    assert_eq!(done["progress"]["finished"], 40);
    for row in done["rows"].as_array().unwrap() {
        assert_eq!(row["status"], "succeeded", "{row}");
        assert_eq!(row["steps"].as_f64(), Some((1.0 / row["dt"].as_f64().unwrap()).round()), "{row}");
    }
    let csv = client.get(format!("{}/sweeps/{id}?format=csv", one.base)).send().await.unwrap();
    assert_eq!(csv.status(), 200);
    assert_eq!(csv.text().await.unwrap().lines().count(), 41, "a header and a record per variant");
    let listed: serde_json::Value =
        client.get(format!("{}/sweeps", two.base)).send().await.unwrap().json().await.unwrap();
    assert_eq!(listed["sweeps"][0]["id"], id.as_str());

    // A long sweep posted to one and cancelled through the other stops on both: its running
    // runs end cancelled and its waiting ones never start.
    let long = serde_json::json!({
        "scene": {"duration": 1000, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 10000}],
                  "output": {"frames": "none"}},
        "vary": {"/dt": [0.001, 0.0011, 0.0012, 0.0013, 0.0014, 0.0015]},
    });
    let long = submit_sweep(&client, &one.base, &long.to_string()).await;
    wait_for_sweep(&client, &two.base, &long, |s| s["progress"]["running"].as_u64() >= Some(1)).await;
    let events = client.get(format!("{}/sweeps/{long}/events", one.base)).send().await.unwrap();
    let response = client.delete(format!("{}/sweeps/{long}", two.base)).send().await.unwrap();
    assert_eq!(response.status(), 202);
    let cancelled = wait_for_sweep(&client, &one.base, &long, |s| s["complete"] == true).await;
    for row in cancelled["rows"].as_array().unwrap() {
        assert_eq!(row["status"], "cancelled", "{row}");
    }
    let stream =
        tokio::time::timeout(serve::PATIENCE, events.text()).await.expect("the stream ends").unwrap();
    let blocks: Vec<&str> = stream.split("\n\n").filter(|b| !b.trim().is_empty()).collect();
    assert!(blocks[0].starts_with("event: progress\ndata: "), "{stream:?}");
    let end = blocks.last().and_then(|b| b.strip_prefix("event: end\ndata: ")).expect("an end event last");
    let end: serde_json::Value = serde_json::from_str(end).unwrap();
    assert_eq!((end["id"].as_str(), end["complete"].as_bool()), (Some(long.as_str()), Some(true)));
    assert_eq!(sweep(&client, &two.base, &long).await["cancel_requested"], true);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "needs PostgreSQL on 127.0.0.1:5432 (or DRAPE_TEST_POSTGRES); see README.md, Run the tests"]
async fn two_instances_share_one_postgres_queue() {
    let database = pg::TestDatabase::create().await;
    let dir = tempfile::tempdir().unwrap();
    // A one-second lease, so the survivor takes over a dead instance's job quickly.
    let args = ["--workers", "2", "--lease", "1", "--queue-capacity", "100"];
    let one = Server::start(dir.path(), &database.url, &args);
    let two = Server::start(dir.path(), &database.url, &args);
    let client = reqwest::Client::new();

    // 40 jobs, submitted through both.
    let mut ids = Vec::new();
    for n in 0..40 {
        let base = if n % 2 == 0 { &one.base } else { &two.base };
        ids.push(submit(&client, base, SMALL).await);
    }
    for (n, id) in ids.iter().enumerate() {
        // Each asked of the instance it was not submitted to.
        let base = if n % 2 == 0 { &two.base } else { &one.base };
        let job = wait_for(&client, base, id, ended).await;
        assert_eq!((job["status"].as_str(), job["attempts"].as_u64()), (Some("succeeded"), Some(1)), "{job}");
        assert_eq!(result(&client, base, id).await["stats"]["steps"], 1000); // 1 s / 0.001 s
    }
    let (ran_one, ran_two) = (counts(one.starts()), counts(two.starts()));
    for id in &ids {
        let runs = ran_one.get(id).unwrap_or(&0) + ran_two.get(id).unwrap_or(&0);
        assert_eq!(runs, 1, "job {id} ran {runs} times");
    }
    eprintln!("instance one ran {} jobs, instance two {}", ran_one.len(), ran_two.len());

    // A cancellation asked of either instance reaches the job wherever it runs.
    let long = submit(&client, &one.base, LONG).await;
    wait_for(&client, &one.base, &long, under_way).await;
    let (runner, other) = if runs_on(&long, &one, &two).await { (&one, &two) } else { (&two, &one) };
    // The other instance follows the job's events through the store.
    let events = client.get(format!("{}/jobs/{long}/events", other.base)).send().await.unwrap();
    let response = client.delete(format!("{}/jobs/{long}", other.base)).send().await.unwrap();
    assert_eq!(response.status(), 202);
    let cancelled = wait_for(&client, &runner.base, &long, ended).await;
    let stream =
        tokio::time::timeout(serve::PATIENCE, events.text()).await.expect("the stream ends").unwrap();
    let end = stream
        .split("\n\n")
        .find_map(|block| block.strip_prefix("event: end\ndata: "))
        .unwrap_or_else(|| panic!("no end event in {stream:?}"));
    assert_eq!(serde_json::from_str::<serde_json::Value>(end).unwrap()["status"], "cancelled");
    assert_eq!(
        (cancelled["status"].as_str(), cancelled["message"].as_str()),
        (Some("cancelled"), Some("cancelled by request"))
    );

    // Kill the instance running a job; the other finishes it.
    let medium = submit(&client, &one.base, MEDIUM).await;
    wait_for(&client, &one.base, &medium, under_way).await;
    let (doomed, survivor) = if runs_on(&medium, &one, &two).await { (one, two) } else { (two, one) };
    doomed.kill();
    let finished = wait_for(&client, &survivor.base, &medium, ended).await;
    assert_eq!(
        (finished["status"].as_str(), finished["attempts"].as_u64()),
        (Some("succeeded"), Some(2)),
        "{finished}"
    );
    assert_eq!(finished["progress"]["step"], 15_000); // 15 s / 0.001 s
    assert_eq!(counts(survivor.starts()).get(&medium), Some(&1), "the survivor ran it once, from the start");
    assert_eq!(
        job(&client, &survivor.base, &ids[0]).await["status"],
        "succeeded",
        "the survivor answers for all"
    );
    drop(survivor);
}
