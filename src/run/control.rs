//! The handle through which a caller follows and cancels a run from another thread.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Progress and cancellation of one run, shared between the runner and its caller.
#[derive(Debug, Default)]
pub struct Control {
    cancelled: AtomicBool,
    steps_done: AtomicU64,
}

impl Control {
    /// A fresh handle: not cancelled, no progress.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks the run to stop at its next batch boundary.
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }

    /// Whether cancellation was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }

    /// Steps taken so far.
    pub fn steps_done(&self) -> u64 {
        self.steps_done.load(Ordering::Relaxed)
    }

    pub(super) fn set_progress(&self, steps: u64) {
        self.steps_done.store(steps, Ordering::Relaxed);
    }
}
