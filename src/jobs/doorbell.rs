//! [`Doorbell`]: how a job queued here wakes an idle worker at once instead of at its next look
//! at the store.

use std::sync::{Condvar, Mutex, PoisonError};
use std::time::Duration;

/// Wakes idle workers when a job is submitted here; a worker that misses a ring finds the job
/// at its next [`JobsConfig::idle_poll`](super::JobsConfig::idle_poll).
///
/// Rings are counted, so one that comes while every worker is between its look at the store and
/// its wait is not lost; the count is held to the number of workers, as each ring past that
/// would only send a worker to find the queue already empty.
pub(super) struct Doorbell {
    rings: Mutex<usize>,
    bell: Condvar,
    most: usize,
}

impl Doorbell {
    /// A bell for `workers` workers.
    pub(super) fn new(workers: usize) -> Self {
        Self { rings: Mutex::new(0), bell: Condvar::new(), most: workers.max(1) }
    }

    /// Wakes one waiting worker, or the next one to wait.
    pub(super) fn ring(&self) {
        let mut rings = self.rings.lock().unwrap_or_else(PoisonError::into_inner);
        *rings = (*rings + 1).min(self.most);
        self.bell.notify_one();
    }

    /// Wakes every worker: the job system stops.
    pub(super) fn ring_all(&self) {
        *self.rings.lock().unwrap_or_else(PoisonError::into_inner) = self.most;
        self.bell.notify_all();
    }

    /// Waits for a ring, or `timeout`; returns whether it was rung.
    pub(super) fn wait(&self, timeout: Duration) -> bool {
        let rings = self.rings.lock().unwrap_or_else(PoisonError::into_inner);
        let (mut rings, _) = self
            .bell
            .wait_timeout_while(rings, timeout, |rings| *rings == 0)
            .unwrap_or_else(PoisonError::into_inner);
        let rung = *rings > 0;
        *rings = rings.saturating_sub(1);
        rung
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    #[test]
    fn rings_are_counted_up_to_the_number_of_workers() {
        let bell = Doorbell::new(2);
        assert!(!bell.wait(Duration::ZERO), "nothing rang yet");
        for _ in 0..10 {
            bell.ring();
        }
        // Ten jobs queued while both workers were busy send at most two of them to the store.
        assert!(bell.wait(Duration::ZERO));
        assert!(bell.wait(Duration::ZERO));
        assert!(!bell.wait(Duration::ZERO));
    }

    #[test]
    fn a_ring_wakes_a_waiting_worker() {
        let bell = Arc::new(Doorbell::new(1));
        let waiter = {
            let bell = Arc::clone(&bell);
            // Far longer than any test runs: the wait can only end by the ring.
            std::thread::spawn(move || bell.wait(Duration::from_secs(24 * 3600)))
        };
        bell.ring();
        assert!(waiter.join().unwrap(), "the worker was woken by the ring");
    }
}
