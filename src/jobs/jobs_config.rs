//! [`JobsConfig`]: how the job system runs (workers, queue, wall time, limits, leases,
//! retention), shared by the service and its worker threads.

use std::sync::Arc;
use std::time::Duration;

use super::assets::AssetLimits;
use super::limits::Limits;
use crate::scene::Compiled;

/// A function run on the worker thread just before each simulation; tests use it to make a job
/// panic. It is set only through [`JobsConfig`], never from the command line or HTTP.
pub type BeforeRun = Arc<dyn Fn(&Compiled) + Send + Sync>;

/// How the job system runs.
#[derive(Clone)]
pub struct JobsConfig {
    /// Worker threads.
    pub workers: usize,
    /// Jobs that may wait for a worker.
    pub queue_capacity: usize,
    /// The longest a job may run before it is stopped and failed.
    pub wall_time: Duration,
    /// The largest scene admitted.
    pub limits: Limits,
    /// Run before each simulation (see [`BeforeRun`]).
    pub before_run: Option<BeforeRun>,
    /// How long a claimed job stays this instance's without a renewal; a job whose instance
    /// died runs again elsewhere after this.
    pub lease: Duration,
    /// How long results are kept after their job ends.
    pub result_ttl: Duration,
    /// How long an idle worker waits before looking in the store again for jobs it was not told
    /// of: queued by another instance sharing the store, or left by one that died. A job queued
    /// through this instance wakes a worker at once.
    pub idle_poll: Duration,
    /// Starts a job may have without ending (each crashed or lost its instance) before it is
    /// failed rather than started again.
    pub max_attempts: u32,
    /// How large uploaded meshes may be, and how many the store may hold.
    pub assets: AssetLimits,
}

impl Default for JobsConfig {
    fn default() -> Self {
        Self {
            workers: std::thread::available_parallelism().map_or(1, usize::from),
            queue_capacity: 64,
            wall_time: Duration::from_secs(300),
            limits: Limits::default(),
            before_run: None,
            lease: Duration::from_secs(30),
            result_ttl: Duration::from_secs(24 * 3600),
            idle_poll: Duration::from_millis(200),
            max_attempts: 3,
            assets: AssetLimits::default(),
        }
    }
}
