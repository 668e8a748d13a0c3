//! `GET /jobs/{id}/events`: server-sent events that follow a job to its end.
//!
//! The stream samples the job's progress (read lock-free from the run's `Control`) at most
//! [`SAMPLES_PER_SECOND`](super::sse::SAMPLES_PER_SECOND) times a second and sends a `progress` event (`step`, `steps`, `t`,
//! `fraction`) when it has moved, then one `end` event carrying the job as `GET /jobs/{id}` shows
//! it, and closes. A status change of a job running here wakes the stream at once, so the end is
//! not delayed; a job queued or running on another instance is followed through the store at the
//! same rate. If this server shuts down while the job is not running here, the stream ends with
//! an `error` event: the job stays in the store for another instance.

use std::convert::Infallible;

use axum::extract::State;
use axum::response::sse::{Event, Sse};
use futures_util::Stream;
use serde_json::json;
use tokio::sync::watch;
use tokio::time::Interval;

use super::AppState;
use super::extract::JobPath;
use super::problem::AppError;
use super::sse::{Follow, sampled};
use super::views::{job_view, progress};
use crate::jobs::{JobId, JobStatus, Jobs};

/// Opens the event stream of a job.
pub async fn events(
    State(state): State<AppState>,
    JobPath(id): JobPath,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, AppError> {
    if state.jobs.get(&id).await?.is_none() {
        return Err(AppError::JobNotFound { id: id.to_string() });
    }
    let follow = FollowJob {
        status: state.jobs.watch(&id),
        jobs: state.jobs,
        id,
        last_step: None,
        sample_due: true,
        ended: false,
    };
    Ok(sampled(follow))
}

struct FollowJob {
    jobs: Jobs,
    id: JobId,
    status: Option<watch::Receiver<JobStatus>>,
    last_step: Option<u64>,
    /// Whether a sample period has passed since the last `progress` event.
    sample_due: bool,
    ended: bool,
}

impl Follow for FollowJob {
    async fn next(&mut self, ticks: &mut Interval) -> Option<Event> {
        loop {
            if self.ended {
                return None;
            }
            let job = match self.jobs.get(&self.id).await {
                Ok(Some(job)) => job,
                Ok(None) | Err(_) => {
                    self.ended = true;
                    return Some(
                        Event::default().event("error").data(r#"{"detail":"the job can no longer be read"}"#),
                    );
                }
            };
            if job.status.is_final() {
                self.ended = true;
                return Some(Event::default().event("end").data(job_view(&job).to_string()));
            }
            if self.status.is_none() {
                // The job may have started here since the stream opened.
                self.status = self.jobs.watch(&self.id);
                if self.status.is_none() && self.jobs.handing_over() {
                    self.ended = true;
                    let detail = json!({"detail": format!(
                        "this server is shutting down; job {} stays {} in the store and runs on another \
                         instance or after a restart", self.id, job.status.name())});
                    return Some(Event::default().event("error").data(detail.to_string()));
                }
            }
            if self.sample_due && self.last_step != Some(job.steps_done) {
                self.last_step = Some(job.steps_done);
                self.sample_due = false;
                return Some(Event::default().event("progress").data(progress(&job).to_string()));
            }
            self.wait(ticks).await;
        }
    }
}

impl FollowJob {
    /// Waits for the next sample time or a status change, whichever comes first.
    async fn wait(&mut self, ticks: &mut Interval) {
        match &mut self.status {
            Some(status) => {
                tokio::select! {
                    _ = ticks.tick() => self.sample_due = true,
                    changed = status.changed() => if changed.is_err() { self.status = None },
                }
            }
            None => {
                ticks.tick().await;
                self.sample_due = true;
            }
        }
    }
}
