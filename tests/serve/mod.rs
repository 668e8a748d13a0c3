//! `drape serve` as a child process: start it on a store, talk to it, kill it with SIGKILL, and
//! read its log to count how often each job was started.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::Value;

/// The longest any wait in these tests may take before the test fails.
pub const PATIENCE: Duration = Duration::from_secs(120);

/// A running `drape serve`.
pub struct Server {
    child: Child,
    /// Its base URL.
    pub base: String,
    log: Arc<Mutex<Vec<String>>>,
}

impl Server {
    /// Starts `drape serve` in `dir` with `args` after the store and a free port.
    pub fn start(dir: &Path, store: &str, args: &[&str]) -> Self {
        Self::start_on(dir, store, "127.0.0.1:0", args)
    }

    /// Starts `drape serve` in `dir` on `addr` with `args` after the store.
    pub fn start_on(dir: &Path, store: &str, addr: &str, args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drape"))
            .current_dir(dir)
            .args(["serve", "--store", store, "--addr", addr])
            .args(args)
            .env("RUST_LOG", "info")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let log = Arc::new(Mutex::new(Vec::new()));
        let stderr = BufReader::new(child.stderr.take().unwrap());
        let lines = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in stderr.lines().map_while(Result::ok) {
                lines.lock().unwrap().push(line);
            }
        });
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let base = match line.trim().strip_prefix("drape listening on ") {
            Some(base) => base.to_string(),
            None => panic!("drape serve did not start: {:?}\n{}", line, log.lock().unwrap().join("\n")),
        };
        Self { child, base, log }
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Kills the process with SIGKILL: no shutdown, no cleanup, as a crash.
    pub fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// Stops the process with SIGTERM and checks that it exits 0.
    pub fn terminate(mut self) {
        let pid = self.child.id().to_string();
        assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
        assert!(self.child.wait().unwrap().success(), "drape serve exits 0 on SIGTERM");
    }

    /// Stops the process with SIGTERM, checks that it exits 0 within `deadline`, and returns how
    /// long it took.
    pub fn terminate_within(mut self, deadline: Duration) -> Duration {
        let pid = self.child.id().to_string();
        let sent = std::time::Instant::now();
        assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                assert!(status.success(), "drape serve exits 0 on SIGTERM");
                return sent.elapsed();
            }
            assert!(sent.elapsed() < deadline, "drape serve did not exit within {deadline:?} of SIGTERM");
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The lines the process logged so far.
    pub fn log(&self) -> Vec<String> {
        self.log.lock().unwrap().clone()
    }

    /// Waits, within [`PATIENCE`], for a line of the log that contains `text`, and returns the
    /// whole log up to then.
    pub fn wait_for_log(&self, text: &str) -> Vec<String> {
        let deadline = std::time::Instant::now() + PATIENCE;
        loop {
            let log = self.log.lock().unwrap().clone();
            if log.iter().any(|line| line.contains(text)) {
                return log;
            }
            assert!(std::time::Instant::now() < deadline, "no `{text}` in the log:\n{}", log.join("\n"));
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Stops the process with SIGTERM and checks that it exits 0 within [`PATIENCE`].
    pub fn terminate_within_patience(self) {
        self.terminate_within(PATIENCE);
    }

    /// How many times each job was started here, from the `job started` lines of the log.
    pub fn starts(&self) -> Vec<String> {
        self.log
            .lock()
            .unwrap()
            .iter()
            .filter(|line| line.contains("job started"))
            .filter_map(|line| line.split_whitespace().find_map(|word| word.strip_prefix("job=")))
            .map(str::to_string)
            .collect()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Submits a scene; returns the job's id.
pub async fn submit(client: &reqwest::Client, base: &str, scene: &str) -> String {
    let response = client
        .post(format!("{base}/jobs"))
        .header("content-type", "application/json")
        .body(scene.to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 202);
    response.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string()
}

/// The job as `GET /jobs/{id}` shows it.
pub async fn job(client: &reqwest::Client, base: &str, id: &str) -> Value {
    client.get(format!("{base}/jobs/{id}")).send().await.unwrap().json().await.unwrap()
}

/// Polls the job until `done` holds, within [`PATIENCE`].
pub async fn wait_for(
    client: &reqwest::Client,
    base: &str,
    id: &str,
    done: impl Fn(&Value) -> bool,
) -> Value {
    tokio::time::timeout(PATIENCE, async {
        loop {
            let job = job(client, base, id).await;
            if done(&job) {
                return job;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .unwrap_or_else(|_| panic!("job {id} did not get there in time"))
}

/// Whether a job has ended.
pub fn ended(job: &Value) -> bool {
    !matches!(job["status"].as_str(), Some("queued" | "running"))
}

/// Whether a job is running and has taken steps.
pub fn under_way(job: &Value) -> bool {
    job["status"] == "running" && job["progress"]["step"].as_u64().is_some_and(|s| s > 0)
}

/// The result of an ended job.
pub async fn result(client: &reqwest::Client, base: &str, id: &str) -> Value {
    let response = client.get(format!("{base}/jobs/{id}/result")).send().await.unwrap();
    assert_eq!(response.status(), 200, "job {id}");
    response.json().await.unwrap()
}
