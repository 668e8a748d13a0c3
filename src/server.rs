//! Running the HTTP service: bind, serve, and shut down gracefully.
//!
//! Each connection is served by hyper's HTTP/1.1 (keep-alive, upgrades) under the header-read
//! and idle timeouts of `connection.rs`, so clients that open connections and stall are dropped.
//!
//! The job store named by `--store` is opened (and migrated) before the address is printed.
//! On the shutdown signal the server stops accepting connections and the job system stops
//! taking jobs: running ones get the grace period to finish. Then, on a durable store, queued
//! jobs stay queued and those still running are stopped (inside a step, or a linear solve, if
//! need be) and go back to the queue for the next instance; on the memory store both are
//! cancelled. A worker thread that still has not returned a second later is left behind, its
//! job handed back, so that the process exits (`Jobs::shutdown`). Open requests,
//! such as a `/simulate` waiting for its job or an event stream, end when their jobs do or, for
//! jobs left to the next instance, at once.

use std::future::Future;
use std::time::Duration;

use connection::Timeouts;
use tokio::net::TcpListener;
use tokio::sync::watch;

use crate::api::{AppState, app};
use crate::config::Config;
use crate::jobs::Jobs;

mod connection;

/// How long the accept loop waits after a failed accept before it tries again.
const ACCEPT_ERROR_PAUSE: Duration = Duration::from_millis(100);

/// Serves until `shutdown` completes, then shuts down within the configured grace period.
pub async fn run(config: Config, shutdown: impl Future<Output = ()> + Send + 'static) -> std::io::Result<()> {
    let listener = TcpListener::bind(config.addr).await?;
    let jobs_config = config.jobs();
    // Workers, the watchdog and the HTTP side each hold a connection at times.
    let connections = u32::try_from(jobs_config.workers).unwrap_or(u32::MAX).saturating_add(4);
    let store = config.store.open(connections, config.retain_jobs).await.map_err(std::io::Error::other)?;
    tracing::info!(store = %config.store, "job store open");
    let jobs = Jobs::start(store, jobs_config);
    // The first line on standard output is the address, for scripts and tests that pick port 0.
    println!("drape listening on http://{}", listener.local_addr()?);
    tracing::info!(addr = %listener.local_addr()?, workers = jobs.config().workers, "serving");
    if !config.addr.ip().is_loopback() && config.auth_tokens.is_empty() {
        tracing::warn!(
            addr = %config.addr,
            "serving beyond this machine without --auth-token: anyone who reaches the port can submit, read and cancel every job"
        );
    }
    serve(listener, AppState::new(jobs, config.api()), shutdown, config.shutdown_grace).await
}

/// Serves `state` on `listener` until `shutdown`, then stops the jobs within `grace`.
pub async fn serve(
    listener: TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
    grace: Duration,
) -> std::io::Result<()> {
    let jobs = state.jobs.clone();
    let timeouts =
        Timeouts { header_read: state.config.header_read_timeout, idle: state.config.idle_timeout };
    let router = app(state);
    let (stopping_tx, stopping_rx) = tokio::sync::oneshot::channel::<()>();
    let signal = async move {
        shutdown.await;
        tracing::info!("shutting down: no new connections or jobs");
        let _ = stopping_tx.send(());
    };
    let jobs_stopped = tokio::spawn({
        let jobs = jobs.clone();
        async move {
            if stopping_rx.await.is_ok() {
                jobs.shutdown(grace).await;
            }
        }
    });
    // Connections watch `closing` to finish once their requests are answered; each holds a
    // receiver of `open` until it ends, so that its sender's `closed` waits for them all.
    let (closing, _) = watch::channel(false);
    let (open, open_rx) = watch::channel(());
    tokio::pin!(signal);
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => {
                    let (router, closing, open) = (router.clone(), closing.subscribe(), open_rx.clone());
                    tokio::spawn(async move {
                        connection::serve(stream, router, timeouts, closing).await;
                        drop(open);
                    });
                }
                Err(error) => {
                    // Out of file descriptors, or a connection reset before it was accepted:
                    // pause rather than spin, and keep serving the connections already open.
                    tracing::warn!(%error, "could not accept a connection");
                    tokio::time::sleep(ACCEPT_ERROR_PAUSE).await;
                }
            },
            () = &mut signal => break,
        }
    }
    drop(listener);
    closing.send_replace(true);
    drop(open_rx);
    open.closed().await;
    if jobs_stopped.await.is_err() {
        tracing::error!("the job system did not stop cleanly");
    }
    tracing::info!("stopped");
    Ok(())
}

/// Completes on SIGINT (Ctrl-C) or SIGTERM.
pub async fn shutdown_signal() {
    let interrupt = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = interrupt => {}
        () = terminate => {}
    }
}
