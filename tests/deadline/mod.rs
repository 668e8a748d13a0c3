//! Deadlines for the waits in the integration tests: a test that waits for something (a job to
//! end, a server to print its address, a log line, a process to exit) waits at most [`PATIENCE`]
//! and then fails naming what it waited for, instead of hanging the suite.
//!
//! These deadlines only stop hangs; they are far above any time the awaited thing should take,
//! even on a loaded two-core machine, and say nothing about performance.

#![allow(dead_code)]

use std::future::Future;
use std::time::{Duration, Instant};

/// The longest any wait in these tests may take before the test fails.
pub const PATIENCE: Duration = Duration::from_secs(120);

/// How often the polls here look again.
const POLL_INTERVAL: Duration = Duration::from_millis(10);

/// Polls `done` on this thread until it gives a value, for at most [`PATIENCE`]; panics naming
/// `what` was awaited if it never does.
pub fn wait_until<T>(what: &str, mut done: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + PATIENCE;
    loop {
        if let Some(value) = done() {
            return value;
        }
        assert!(Instant::now() < deadline, "gave up after {PATIENCE:?} waiting for {what}");
        std::thread::sleep(POLL_INTERVAL);
    }
}

/// Awaits `future` for at most [`PATIENCE`]; panics naming `what` was awaited if it does not end.
pub async fn within<T>(what: &str, future: impl Future<Output = T>) -> T {
    match tokio::time::timeout(PATIENCE, future).await {
        Ok(value) => value,
        Err(_) => panic!("gave up after {PATIENCE:?} waiting for {what}"),
    }
}

/// Polls the async `check` until it gives a value, for at most [`PATIENCE`]; panics naming
/// `what` was awaited if it never does.
pub async fn poll_until_some<T, F: Future<Output = Option<T>>>(
    what: &str,
    mut check: impl FnMut() -> F,
) -> T {
    within(what, async {
        loop {
            if let Some(value) = check().await {
                return value;
            }
            tokio::time::sleep(POLL_INTERVAL).await;
        }
    })
    .await
}
