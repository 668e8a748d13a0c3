//! The handle through which a caller follows and cancels a run from another thread.
//!
//! Cancelling raises the run's [`Interrupt`], the flag its simulations (the main run and the
//! error estimate's companions) look at inside every step, so a cancellation reaches a run even
//! in the middle of a long linear solve; encoders given the control stop at their next write.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::solver::Interrupt;

/// Progress and cancellation of one run, shared between the runner and its caller.
#[derive(Debug, Default)]
pub struct Control {
    cancelled: Interrupt,
    steps_done: AtomicU64,
}

impl Control {
    /// A fresh handle: not cancelled, no progress.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks the run to stop: the step under way gives up at its next look at the flag.
    pub fn cancel(&self) {
        self.cancelled.raise();
    }

    /// Whether cancellation was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.is_raised()
    }

    /// The flag a simulation of this run is handed.
    pub fn interrupt(&self) -> Interrupt {
        self.cancelled.clone()
    }

    /// Steps taken so far.
    pub fn steps_done(&self) -> u64 {
        self.steps_done.load(Ordering::Relaxed)
    }

    pub(super) fn set_progress(&self, steps: u64) {
        self.steps_done.store(steps, Ordering::Relaxed);
    }
}
