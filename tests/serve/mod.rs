//! The one launcher of `drape serve` as a child process, for the integration tests and the
//! service measurements in `examples/` (which include this file by `#[path]`): start it on a
//! store, read the address it prints, talk to it, stop it with SIGTERM or kill it with SIGKILL,
//! and read its log, for instance to count how often each job was started.
//!
//! Every wait here has a deadline ([`PATIENCE`]), so a server that never starts, never answers
//! or never exits fails the test instead of hanging it. The deadlines come from
//! `tests/deadline/mod.rs`, which a crate using this module declares as `mod deadline` beside it.

#![allow(dead_code)]

use crate::deadline;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

pub use deadline::PATIENCE;

/// The `drape` binary Cargo built for this integration test. Examples have no such variable and
/// pass their binary to [`Server::launch`].
fn test_binary() -> &'static Path {
    match option_env!("CARGO_BIN_EXE_drape") {
        Some(path) => Path::new(path),
        None => panic!("only integration tests are given CARGO_BIN_EXE_drape"),
    }
}

/// A running `drape serve`, killed when dropped.
pub struct Server {
    child: Child,
    /// Its base URL, e.g. `http://127.0.0.1:40123`.
    pub base: String,
    log: Arc<Mutex<Vec<String>>>,
}

impl Server {
    /// Starts `drape serve` in `dir` with `args` after the store and a free port.
    pub fn start(dir: &Path, store: &str, args: &[&str]) -> Self {
        Self::start_on(dir, store, "127.0.0.1:0", args)
    }

    /// Starts `drape serve` in `dir` on `addr` with `args` after the store, logging at `info`.
    pub fn start_on(dir: &Path, store: &str, addr: &str, args: &[&str]) -> Self {
        Self::launch(test_binary(), dir, store, addr, args, Some("info"))
    }

    /// Starts `binary serve --store STORE --addr ADDR ARGS` in `dir`, with `RUST_LOG` set to
    /// `log_filter` (or left as the environment has it), and waits within [`PATIENCE`] for the
    /// address it listens on. Its standard error is kept as [`Server::log`].
    pub fn launch(
        binary: &Path,
        dir: &Path,
        store: &str,
        addr: &str,
        args: &[&str],
        log_filter: Option<&str>,
    ) -> Self {
        let mut command = Command::new(binary);
        command
            .current_dir(dir)
            .args(["serve", "--store", store, "--addr", addr])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if let Some(filter) = log_filter {
            command.env("RUST_LOG", filter);
        }
        let mut child = command.spawn().unwrap_or_else(|e| panic!("cannot start {}: {e}", binary.display()));
        let log = Arc::new(Mutex::new(Vec::new()));
        let stderr = BufReader::new(child.stderr.take().unwrap());
        let lines = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in stderr.lines().map_while(Result::ok) {
                lines.lock().unwrap().push(line);
            }
        });
        // The address line is read on a thread of its own so that waiting for it has a deadline.
        let stdout = child.stdout.take().unwrap();
        let (sender, first_line) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(stdout).read_line(&mut line);
            let _ = sender.send(line);
        });
        let line = first_line.recv_timeout(PATIENCE).unwrap_or_default();
        let base = match line.trim().strip_prefix("drape listening on ") {
            Some(base) => base.to_string(),
            None => panic!(
                "drape serve did not print its address within {PATIENCE:?}: {:?}\n{}",
                line,
                log.lock().unwrap().join("\n")
            ),
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

    /// Sends SIGTERM, asking for a graceful shutdown, without waiting for the exit.
    pub fn sigterm(&self) {
        let pid = self.child.id().to_string();
        assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    }

    /// Waits for the process to exit, within `deadline`; returns its status and how long the
    /// wait took.
    pub fn exit_within(mut self, deadline: Duration) -> (ExitStatus, Duration) {
        let since = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return (status, since.elapsed());
            }
            assert!(since.elapsed() < deadline, "drape serve did not exit within {deadline:?}");
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Stops the process with SIGTERM and checks that it exits 0 within [`PATIENCE`].
    pub fn terminate(self) {
        self.terminate_within(PATIENCE);
    }

    /// Stops the process with SIGTERM, checks that it exits 0 within `deadline`, and returns how
    /// long it took.
    pub fn terminate_within(self, deadline: Duration) -> Duration {
        self.sigterm();
        let (status, took) = self.exit_within(deadline);
        assert!(status.success(), "drape serve exits 0 on SIGTERM, not {status}");
        took
    }

    /// The lines the process logged so far.
    pub fn log(&self) -> Vec<String> {
        self.log.lock().unwrap().clone()
    }

    /// Waits, within [`PATIENCE`], for a line of the log that contains `text`, and returns the
    /// whole log up to then.
    pub fn wait_for_log(&self, text: &str) -> Vec<String> {
        deadline::wait_until(&format!("`{text}` in the log of drape serve"), || {
            let log = self.log();
            log.iter().any(|line| line.contains(text)).then_some(log)
        })
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
    deadline::poll_until_some(&format!("job {id} to get there"), || async {
        let job = job(client, base, id).await;
        done(&job).then_some(job)
    })
    .await
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

/// Submits a sweep; returns its id.
pub async fn submit_sweep(client: &reqwest::Client, base: &str, sweep: &str) -> String {
    let response = client
        .post(format!("{base}/sweeps"))
        .header("content-type", "application/json")
        .body(sweep.to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 202);
    response.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string()
}

/// The sweep as `GET /sweeps/{id}` shows it.
pub async fn sweep(client: &reqwest::Client, base: &str, id: &str) -> Value {
    client.get(format!("{base}/sweeps/{id}")).send().await.unwrap().json().await.unwrap()
}

/// Polls the sweep until `done` holds, within [`PATIENCE`].
pub async fn wait_for_sweep(
    client: &reqwest::Client,
    base: &str,
    id: &str,
    done: impl Fn(&Value) -> bool,
) -> Value {
    deadline::poll_until_some(&format!("sweep {id} to get there"), || async {
        let sweep = sweep(client, base, id).await;
        done(&sweep).then_some(sweep)
    })
    .await
}
