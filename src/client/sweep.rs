//! A sweep sent to a server: `drape sweep --server` queues it, follows it through its events
//! (`GET /sweeps/{id}/events`: `progress` events, then the `end` event that carries the table),
//! and prints, plots and gates its table as `drape sweep` does. If the stream ends before its
//! `end` (a proxy that cuts it, a server that shuts down), the sweep is looked at
//! (`GET /sweeps/{id}`) until it is complete.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use serde_json::Value;

use super::events;
use super::http::{ClientError, read_json};
use super::{Exit, Server, idempotency_key};
use crate::progress;
use crate::sweep::{Table, Thresholds, write_csv, write_svg};

/// How often a sweep is looked at when its events cannot be followed.
const POLL: Duration = Duration::from_millis(250);

/// What `drape sweep --server` prints, and the thresholds its table must keep.
pub struct SweepOptions<'a> {
    /// Print the table as CSV instead of JSON.
    pub csv: bool,
    /// Also write the work-precision plot as SVG here.
    pub plot: Option<&'a Path>,
    /// Draw a progress bar on standard error.
    pub progress: bool,
    /// The bounds the table must keep, else [`Exit::RunFailed`].
    pub thresholds: Thresholds,
}

/// Queues the sweep `document` (read from `name`) on `server`, waits for every run, prints its
/// table and checks it against the thresholds.
pub fn sweep(
    server: &Server,
    name: &str,
    document: Vec<u8>,
    options: &SweepOptions<'_>,
    salt: Option<&str>,
) -> Exit {
    // The thresholds are checked before anything is sent; a document that is not JSON is the
    // server's to report.
    if let Ok(value) = serde_json::from_slice::<Value>(&document) {
        let pointers: Vec<String> =
            value["vary"].as_object().map(|v| v.keys().cloned().collect()).unwrap_or_default();
        let has_reference = value.get("reference").is_some_and(|r| !r.is_null());
        if let Err(reason) = options.thresholds.check_for(&pointers, has_reference) {
            eprintln!("drape: {reason}");
            return Exit::BadInput;
        }
    }
    let table = match queue_and_wait(server, document, options.progress, salt) {
        Ok(table) => table,
        Err(e) => return e.report(),
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let printed = if options.csv {
        write_csv(&table, &mut out)
    } else {
        serde_json::to_writer_pretty(&mut out, &table)
            .map_err(std::io::Error::other)
            .and_then(|_| writeln!(out))
    };
    let plotted = match options.plot {
        Some(file) => std::fs::File::create(file).and_then(|f| write_svg(&table, name, f)),
        None => Ok(()),
    };
    if let Err(e) = printed.and_then(|_| out.flush()).and(plotted) {
        eprintln!("drape: cannot write the table: {e}");
        return Exit::RunFailed;
    }
    let crossings = options.thresholds.crossings(&table);
    if crossings.is_empty() {
        return Exit::Succeeded;
    }
    eprintln!("drape: {name} crosses the thresholds:");
    crossings.iter().for_each(|line| eprintln!("  {line}"));
    Exit::RunFailed
}

/// `POST /sweeps`, then the sweep's table once every run has ended.
fn queue_and_wait(
    server: &Server,
    document: Vec<u8>,
    show: bool,
    salt: Option<&str>,
) -> Result<Table, ClientError> {
    let key = idempotency_key("POST /sweeps", &document, salt);
    let sweep = read_json(&server.url("/sweeps"), server.post("/sweeps", &document, &key)?)?;
    let id = sweep["id"].as_str().unwrap_or_default().to_string();
    let runs = sweep["progress"]["runs"].as_u64().unwrap_or(0) as usize;
    let finished = AtomicUsize::new(0);
    let view = progress::follow_sweep(show, &finished, runs, || follow(server, &id, sweep, &finished))?;
    let target = format!("/sweeps/{id}");
    Table::from_json(&view).map_err(|reason| ClientError::Unexpected { url: server.url(&target), reason })
}

/// Follows sweep `id`, as `queued` shows it, to its end, counting its ended runs in `finished`:
/// from its events while the server sends them, else by looking at it every [`POLL`]. The sweep
/// with its complete table.
fn follow(server: &Server, id: &str, queued: Value, finished: &AtomicUsize) -> Result<Value, ClientError> {
    let publish = |sweep: &Value| {
        finished.store(sweep["progress"]["finished"].as_u64().unwrap_or(0) as usize, Ordering::Relaxed);
    };
    let complete = |sweep: &Value| sweep["complete"] == true;
    publish(&queued);
    // A repeated request may find the sweep already complete.
    if complete(&queued) {
        return Ok(queued);
    }
    if let Some(sweep) = events::follow(server, &format!("/sweeps/{id}/events"), publish, complete) {
        return Ok(sweep);
    }
    let target = format!("/sweeps/{id}");
    loop {
        let sweep = server.get_json(&target)?;
        publish(&sweep);
        if complete(&sweep) {
            return Ok(sweep);
        }
        std::thread::sleep(POLL);
    }
}
