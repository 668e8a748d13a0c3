//! The sampled stream of server-sent events that `GET /jobs/{id}/events` and
//! `GET /sweeps/{id}/events` both send: a [`Follow`] is asked for its next event whenever it has
//! one to give, at most [`SAMPLES_PER_SECOND`] samples a second, until it has sent its end.

use std::convert::Infallible;
use std::future::Future;
use std::time::Duration;

use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::Stream;
use futures_util::stream;
use tokio::time::{Instant, Interval, MissedTickBehavior, interval_at};

/// The most `progress` events a second.
pub const SAMPLES_PER_SECOND: u32 = 4;

/// What follows a job or a sweep to its end, one event at a time.
pub(super) trait Follow: Send + 'static {
    /// The next event, waiting on `ticks` for a sample time between two, or `None` once the
    /// end has been sent.
    fn next(&mut self, ticks: &mut Interval) -> impl Future<Output = Option<Event>> + Send;
}

/// The events of `follow` as a response, with keep-alive comments while none is due.
pub(super) fn sampled(follow: impl Follow) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    let period = Duration::from_secs(1) / SAMPLES_PER_SECOND;
    let mut ticks = interval_at(Instant::now() + period, period);
    ticks.set_missed_tick_behavior(MissedTickBehavior::Delay);
    let stream = stream::unfold((follow, ticks), |(mut follow, mut ticks)| async move {
        let event = follow.next(&mut ticks).await?;
        Some((Ok(event), (follow, ticks)))
    });
    Sse::new(stream).keep_alive(KeepAlive::default())
}
