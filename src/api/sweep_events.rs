//! `GET /sweeps/{id}/events`: server-sent events that follow a sweep to its end.
//!
//! The stream reads the sweep's progress from the store
//! [`SAMPLES_PER_SECOND`](super::sse::SAMPLES_PER_SECOND) times a second
//! (its runs may run on any instance sharing the store) and sends a `progress` event (the sweep
//! as `GET /sweeps` lists it: `progress.finished`, `progress.running`, `progress.runs`) when it
//! has moved, then one `end` event carrying the sweep with its table as `GET /sweeps/{id}` shows
//! it, and closes. A batch of runs ending on this instance makes it look again at once, so the
//! `end` of a sweep run here is sent as soon as it is stored; progress is still sent at most
//! [`SAMPLES_PER_SECOND`](super::sse::SAMPLES_PER_SECOND) times a second.

use std::convert::Infallible;

use axum::extract::State;
use axum::response::sse::{Event, Sse};
use futures_util::Stream;
use tokio::time::Interval;

use super::AppState;
use super::extract::SweepPath;
use super::problem::AppError;
use super::sse::{Follow, sampled};
use super::sweeps::{summary_view, sweep_view};
use crate::jobs::JobId;

/// Opens the event stream of a sweep.
pub async fn events(
    State(state): State<AppState>,
    SweepPath(id): SweepPath,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, AppError> {
    if state.jobs.sweep(&id).await?.is_none() {
        return Err(AppError::SweepNotFound { id: id.to_string() });
    }
    let changes = state.jobs.sweep_changes();
    Ok(sampled(FollowSweep { state, id, changes, last: None, sample_due: true, ended: false }))
}

struct FollowSweep {
    state: AppState,
    id: JobId,
    /// Changes when runs end on this instance.
    changes: tokio::sync::watch::Receiver<u64>,
    /// Runs finished and running at the last `progress` event.
    last: Option<(u32, u32)>,
    /// Whether a sample period has passed since the last `progress` event.
    sample_due: bool,
    ended: bool,
}

impl Follow for FollowSweep {
    async fn next(&mut self, ticks: &mut Interval) -> Option<Event> {
        loop {
            if self.ended {
                return None;
            }
            if !self.sample_due {
                tokio::select! {
                    _ = ticks.tick() => self.sample_due = true,
                    Ok(()) = self.changes.changed() => {}
                }
            }
            let summary = match self.state.jobs.sweep(&self.id).await {
                Ok(Some(summary)) => summary,
                Ok(None) | Err(_) => return Some(self.error()),
            };
            if summary.is_complete() {
                self.ended = true;
                return match self.state.jobs.sweep_state(summary).await {
                    Ok(sweep) => match serde_json::to_string(&sweep_view(&sweep)) {
                        Ok(view) => Some(Event::default().event("end").data(view)),
                        Err(_) => Some(self.error()),
                    },
                    Err(_) => Some(self.error()),
                };
            }
            if !self.sample_due {
                continue;
            }
            let now = Some((summary.finished, summary.running));
            if self.last != now {
                self.last = now;
                self.sample_due = false;
                return Some(Event::default().event("progress").data(summary_view(&summary).to_string()));
            }
            self.sample_due = false;
        }
    }
}

impl FollowSweep {
    fn error(&mut self) -> Event {
        self.ended = true;
        Event::default().event("error").data(r#"{"detail":"the sweep can no longer be read"}"#)
    }
}
