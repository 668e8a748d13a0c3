//! A scene sent to a server: `drape run --server` queues it, follows it to its end and writes
//! its result as `drape run` would; `drape submit` only queues it and prints the job.

use std::io::{self, Read, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use serde_json::Value;

use super::events;
use super::http::{ClientError, read_json, unreachable};
use super::{Exit, Server, idempotency_key};
use crate::output::{Format, carried};
use crate::progress;
use crate::scene::Scene;

/// How often a job is looked at when its events cannot be followed.
const POLL: Duration = Duration::from_millis(250);

/// What `drape run --server` writes, and how it shows progress.
pub struct RunOptions<'a> {
    /// Write the result here instead of standard output.
    pub output: Option<&'a Path>,
    /// The format to encode the result in, instead of the scene's `output.format`.
    pub format: Option<Format>,
    /// Draw a progress bar on standard error.
    pub progress: bool,
}

/// Queues the scene `document` (read from `name`) on `server`, follows the job to its end and
/// writes its result. A diverged run's result is written too, and exits [`Exit::RunFailed`].
pub fn run(
    server: &Server,
    name: &str,
    document: Vec<u8>,
    options: &RunOptions<'_>,
    salt: Option<&str>,
) -> Exit {
    let job = match queue(server, document, options.format, salt) {
        Ok(job) => job,
        Err(e) => return e.report(),
    };
    let id = job["id"].as_str().unwrap_or_default().to_string();
    let steps = job["progress"]["steps"].as_u64().unwrap_or(0);
    let job = match follow(server, &id, steps, options.progress) {
        Ok(job) => job,
        Err(e) => return e.report(),
    };
    let status = job["status"].as_str().unwrap_or_default();
    if !matches!(status, "succeeded" | "diverged") {
        let reason = job["message"].as_str().unwrap_or("no reason given");
        eprintln!("drape: the run of {name} {status} ({}): {reason}", server.url(&format!("/jobs/{id}")));
        return Exit::RunFailed;
    }
    if let Err(e) = write_result(server, &id, options.output) {
        return e;
    }
    if status == "diverged" {
        let diverged = &job["stats"]["diverged"];
        eprintln!(
            "drape: the run of {name} diverged at step {} (t = {} s): {}; a step of {} s would hold",
            diverged["step"],
            diverged["t"],
            diverged["reason"].as_str().unwrap_or("unstable"),
            diverged["suggested_dt"]
        );
        return Exit::RunFailed;
    }
    Exit::Succeeded
}

/// Queues the scene `document` on `server` and prints the job as the server shows it (its id,
/// status and links), without waiting for it to run.
pub fn submit(server: &Server, document: Vec<u8>, format: Option<Format>, salt: Option<&str>) -> Exit {
    match queue(server, document, format, salt) {
        Ok(job) => {
            println!("{}", serde_json::to_string_pretty(&job).expect("a JSON value serializes"));
            Exit::Succeeded
        }
        Err(e) => e.report(),
    }
}

/// `POST /jobs`: the job the server queued for the scene (or had queued for the same request).
fn queue(
    server: &Server,
    document: Vec<u8>,
    format: Option<Format>,
    salt: Option<&str>,
) -> Result<Value, ClientError> {
    let body = match format {
        Some(format) => carried_only(document, format),
        None => document,
    };
    let target = format.map_or("/jobs".to_string(), |f| format!("/jobs?format={}", f.name()));
    let key = idempotency_key(&format!("POST {target}"), &body, salt);
    let response = server.post(&target, &body, &key)?;
    read_json(&server.url(&target), response)
}

/// The scene set to record only the fields `format` carries, as `drape run --format` does,
/// naming the others on standard error. A scene that does not parse is sent as it is, for the
/// server to say what is wrong with it.
fn carried_only(document: Vec<u8>, format: Format) -> Vec<u8> {
    let Ok(scene) = Scene::from_json(&document) else { return document };
    let carried = carried(format, &scene.output.fields);
    if carried.omitted.is_empty() {
        return document;
    }
    let Ok(mut value) = serde_json::from_slice::<Value>(&document) else { return document };
    let names: Vec<&str> = carried.omitted.iter().map(|f| f.name()).collect();
    eprintln!(
        "drape: {} cannot carry {}; the result leaves them out (json and npz carry every field)",
        format.name(),
        names.join(", ")
    );
    value["output"]["fields"] = carried.fields.iter().map(|f| f.name()).collect();
    serde_json::to_vec(&value).expect("a JSON value serializes")
}

/// Follows job `id` of `steps` steps to its end, drawing its progress if `show`: from its events
/// while the server sends them, else by looking at it every [`POLL`].
fn follow(server: &Server, id: &str, steps: u64, show: bool) -> Result<Value, ClientError> {
    let step = AtomicU64::new(0);
    let t = AtomicU64::new(0.0f64.to_bits());
    let publish = |progress: &Value| {
        step.store(progress["step"].as_u64().unwrap_or(0), Ordering::Relaxed);
        t.store(progress["t"].as_f64().unwrap_or(0.0).to_bits(), Ordering::Relaxed);
    };
    let read = || (step.load(Ordering::Relaxed), f64::from_bits(t.load(Ordering::Relaxed)));
    progress::follow_steps(show, steps, read, || {
        if let Some(job) = events::follow(server, &format!("/jobs/{id}/events"), publish, ended) {
            return Ok(job);
        }
        loop {
            let job = server.get_json(&format!("/jobs/{id}"))?;
            if ended(&job) {
                return Ok(job);
            }
            publish(&job["progress"]);
            std::thread::sleep(POLL);
        }
    })
}

fn ended(job: &Value) -> bool {
    !matches!(job["status"].as_str(), Some("queued" | "running") | None)
}

/// Writes job `id`'s result, in the format it was stored in, to `output` or standard output
/// (a JSON result there ends with a line break, as `drape run` prints it).
fn write_result(server: &Server, id: &str, output: Option<&Path>) -> Result<(), Exit> {
    let target = format!("/jobs/{id}/result");
    let response = server.get(&target, "*/*").map_err(|e| e.report())?;
    let json =
        response.headers().get("content-type").is_some_and(|t| t.as_bytes().starts_with(b"application/json"));
    let mut body = response.into_body().into_reader();
    let copied = match output {
        Some(file) => std::fs::File::create(file)
            .map_err(Copy::Write)
            .and_then(|f| copy(&mut body, io::BufWriter::new(f), false)),
        None => copy(&mut body, io::BufWriter::new(io::stdout().lock()), json),
    };
    match copied {
        Ok(()) => Ok(()),
        Err(Copy::Read(e)) => Err(unreachable(&server.url(&target), e).report()),
        Err(Copy::Write(e)) => {
            eprintln!("drape: cannot write the result: {e}");
            Err(Exit::RunFailed)
        }
    }
}

/// Which side of a copy failed.
enum Copy {
    Read(io::Error),
    Write(io::Error),
}

fn copy(from: &mut impl Read, mut to: impl Write, line_break: bool) -> Result<(), Copy> {
    let mut buffer = vec![0; 64 * 1024];
    loop {
        let n = match from.read(&mut buffer) {
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            read => read.map_err(Copy::Read)?,
        };
        if n == 0 {
            break;
        }
        to.write_all(&buffer[..n]).map_err(Copy::Write)?;
    }
    if line_break {
        to.write_all(b"\n").map_err(Copy::Write)?;
    }
    to.flush().map_err(Copy::Write)
}
