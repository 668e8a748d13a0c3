//! [`Live`]: what this process knows of a job while one of its workers runs it: the run's
//! `Control`, its status channel, its start, the flags that say how it is being stopped, and its
//! result once stored.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use tokio::sync::watch;

use super::record::{JobRecord, Plan};
use super::status::JobStatus;
use super::store::StoredResult;
use crate::run::Control;

/// What this process knows of a job while it runs here.
pub(super) struct Live {
    pub(super) control: Control,
    pub(super) plan: Plan,
    pub(super) status: watch::Sender<JobStatus>,
    pub(super) started: Instant,
    pub(super) timed_out: AtomicBool,
    /// The job is no longer this instance's (its lease lapsed and it was claimed again, or it was
    /// cancelled elsewhere meanwhile): its end is not recorded here.
    pub(super) lease_lost: AtomicBool,
    /// Shutdown stopped it and it goes back to the queue, to run again after a restart.
    pub(super) released: AtomicBool,
    /// Its end is being recorded (or was): the watchdog leaves its lease alone, and a second
    /// recording (a worker returning after shutdown gave up on it) does nothing.
    pub(super) ending: AtomicBool,
    pub(super) shutting_down: AtomicBool,
    /// The result once it is stored, for whoever waits on the job here: `POST /simulate`
    /// answers with it without reading it back from the store.
    pub(super) result: Mutex<Option<StoredResult>>,
}

impl Live {
    pub(super) fn new(plan: Plan) -> Self {
        Self {
            control: Control::new(),
            plan,
            status: watch::Sender::new(JobStatus::Running),
            started: Instant::now(),
            timed_out: AtomicBool::new(false),
            lease_lost: AtomicBool::new(false),
            released: AtomicBool::new(false),
            ending: AtomicBool::new(false),
            shutting_down: AtomicBool::new(false),
            result: Mutex::new(None),
        }
    }

    /// Its status and steps taken, as of now.
    pub(super) fn progress(&self) -> Progress {
        Progress { status: *self.status.borrow(), steps_done: self.control.steps_done() }
    }

    /// Why a cancelled job was cancelled.
    pub(super) fn cancel_reason(&self) -> String {
        if self.shutting_down.load(Ordering::Relaxed) { SHUT_DOWN.into() } else { CANCELLED.into() }
    }
}

/// A running job's status and steps taken, as this process last knew them.
#[derive(Clone, Copy, Debug)]
pub(super) struct Progress {
    status: JobStatus,
    steps_done: u64,
}

impl Progress {
    /// Brings a stored record that has not ended up to date; an ended record is already whole.
    pub(super) fn overlay(&self, record: &mut JobRecord) {
        if !record.status.is_final() {
            record.status = self.status;
            record.steps_done = self.steps_done;
        }
    }
}

/// Why a job stopped by shutdown ended.
pub(super) const SHUT_DOWN: &str = "the server shut down before the job finished";
/// Why a job a client cancelled ended.
pub(super) const CANCELLED: &str = "cancelled by request";
