//! `GET /sweeps/{id}/events`: server-sent events that follow a sweep to its end.
//!
//! The stream reads the sweep's progress from the store [`SAMPLES_PER_SECOND`] times a second
//! (its runs may run on any instance sharing the store) and sends a `progress` event (the sweep
//! as `GET /sweeps` lists it: `progress.finished`, `progress.running`, `progress.runs`) when it
//! has moved, then one `end` event carrying the sweep with its table as `GET /sweeps/{id}` shows
//! it, and closes. A batch of runs ending on this instance makes it look again at once, so the
//! `end` of a sweep run here is sent as soon as it is stored; progress is still sent at most
//! [`SAMPLES_PER_SECOND`] times a second.

use std::convert::Infallible;
use std::time::Duration;

use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::Stream;
use futures_util::stream;
use tokio::time::{Instant, MissedTickBehavior, interval_at};

use super::AppState;
use super::events::SAMPLES_PER_SECOND;
use super::extract::SweepPath;
use super::problem::AppError;
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
    let period = Duration::from_secs(1) / SAMPLES_PER_SECOND;
    let mut ticks = interval_at(Instant::now() + period, period);
    ticks.set_missed_tick_behavior(MissedTickBehavior::Delay);
    let changes = state.jobs.sweep_changes();
    let follow = Follow { state, id, changes, last: None, sample_due: true, ended: false };
    let stream = stream::unfold((follow, ticks), |(mut follow, mut ticks)| async move {
        let event = follow.next(&mut ticks).await?;
        Some((Ok(event), (follow, ticks)))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

struct Follow {
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

impl Follow {
    /// The next event, or `None` once the end has been sent.
    async fn next(&mut self, ticks: &mut tokio::time::Interval) -> Option<Event> {
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

    fn error(&mut self) -> Event {
        self.ended = true;
        Event::default().event("error").data(r#"{"detail":"the sweep can no longer be read"}"#)
    }
}
