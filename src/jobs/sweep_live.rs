//! [`Batch`]: what this process knows of a batch of a sweep's runs while a worker runs it: the
//! current run's `Control` and start, and the flags that say how the batch is being stopped. The
//! watchdog reads it to enforce the wall time, and a cancellation stops it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use super::id::JobId;
use crate::run::Control;

/// A batch of one sweep's runs in the hands of a worker here.
pub(super) struct Batch {
    pub(super) sweep: JobId,
    /// The run under way: its control and when it started.
    current: Mutex<(Arc<Control>, Instant)>,
    /// The run under way passed the wall time.
    pub(super) timed_out: AtomicBool,
    /// A client cancelled the sweep.
    pub(super) cancelled: AtomicBool,
    /// Shutdown stopped the batch: its runs go back to the queue.
    pub(super) shutting_down: AtomicBool,
}

impl Batch {
    pub(super) fn new(sweep: JobId) -> Self {
        Self {
            sweep,
            current: Mutex::new((Arc::new(Control::new()), Instant::now())),
            timed_out: AtomicBool::new(false),
            cancelled: AtomicBool::new(false),
            shutting_down: AtomicBool::new(false),
        }
    }

    /// Starts the next run: a fresh control, stopped at once if the batch is.
    pub(super) fn next_run(&self) -> Arc<Control> {
        let control = Arc::new(Control::new());
        self.timed_out.store(false, Ordering::Relaxed);
        *self.current.lock().unwrap_or_else(PoisonError::into_inner) = (Arc::clone(&control), Instant::now());
        if self.stopping() {
            control.cancel();
        }
        control
    }

    /// Whether the batch is to stop: its sweep was cancelled or the server shuts down.
    pub(super) fn stopping(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed) || self.shutting_down.load(Ordering::Relaxed)
    }

    fn stop_current(&self) {
        self.current.lock().unwrap_or_else(PoisonError::into_inner).0.cancel();
    }

    /// Stops the run under way and the rest of the batch: the sweep was cancelled.
    pub(super) fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
        self.stop_current();
    }

    /// Stops the run under way and the rest of the batch, to be run again by the next instance.
    pub(super) fn shut_down(&self) {
        self.shutting_down.store(true, Ordering::Relaxed);
        self.stop_current();
    }

    /// Stops the run under way if it has run longer than `wall_time`.
    pub(super) fn enforce(&self, wall_time: Duration) {
        let current = self.current.lock().unwrap_or_else(PoisonError::into_inner);
        if current.1.elapsed() > wall_time {
            self.timed_out.store(true, Ordering::Relaxed);
            current.0.cancel();
        }
    }
}
