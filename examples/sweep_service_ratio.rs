//! The wall time of a 1,000-run sweep of tiny runs through `drape serve` on its SQLite store
//! against `drape sweep` on the same machine, measured in one run, and their ratio.
//!
//! The sweep is 500 steps × 2 integrators (symplectic Euler, Verlet) of a 7-particle chain
//! pinned at one end, 0.1 s each, with no error estimate: runs of well under a millisecond, so
//! what is measured is what the service adds to them. The command line is timed from the start of
//! `drape sweep FILE --csv` to its exit; the service from just before `POST /sweeps` to the
//! arrival of the `end` event of `GET /sweeps/{id}/events`, opened at once after the `202`. The
//! two alternate, a first uncounted round of each warms the caches, and the medians over ROUNDS
//! rounds (default 7) are compared; the ratio of each round's pair is printed too, since the
//! machine's load changes between rounds more than within one.
//!
//! ```sh
//! cargo build --release && cargo run --release --example sweep_service_ratio [-- ROUNDS]
//! ```
//!
//! `DRAPE_BIN` names another `drape` binary to measure (both sides use it).

#[path = "../tests/deadline/mod.rs"]
mod deadline;
#[path = "../tests/serve/mod.rs"]
mod serve;
#[path = "support/serve.rs"]
mod support;

use std::error::Error;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

use serde_json::{Value, json};

use serve::Server;
use support::{drape_binary, median, min, post_sweep};

/// Values of `dt`; each runs with both integrators.
const STEPS: usize = 500;

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), Box<dyn Error>> {
    let rounds: usize = std::env::args().nth(1).map_or(Ok(7), |a| a.parse())?;
    let binary = drape_binary()?;
    let dir = tempfile::tempdir()?;
    let file = dir.path().join("sweep.json");
    std::fs::write(&file, serde_json::to_vec(&tiny_chains())?)?;
    let body = std::fs::read(&file)?;
    let server = Server::launch(&binary, dir.path(), "sqlite://drape.db", "127.0.0.1:0", &[], None);
    let client = reqwest::Client::new();

    let (mut cli, mut service, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for round in 0..=rounds {
        let local = command_line(&binary, dir.path(), &file)?;
        let served = through_service(&client, &server, &body).await?;
        if round > 0 {
            cli.push(local);
            service.push(served);
            ratios.push(served / local);
        }
    }
    println!(
        "{} runs (chain of 7, {STEPS} steps × 2 integrators), {rounds} rounds; median (min) wall time",
        2 * STEPS
    );
    println!(
        "| `drape sweep --csv` (s) | `drape serve --store sqlite`, POST to `end` (s) | ratio of medians | median of ratios |"
    );
    println!("| --- | --- | --- | --- |");
    println!(
        "| {:.3} ({:.3}) | {:.3} ({:.3}) | {:.2} | {:.2} |",
        median(&cli),
        min(&cli),
        median(&service),
        min(&service),
        median(&service) / median(&cli),
        median(&ratios)
    );
    let each: Vec<String> = ratios.iter().map(|r| format!("{r:.2}")).collect();
    println!("ratio of each round: {}", each.join(", "));
    Ok(())
}

/// 500 steps × 2 integrators of a 7-particle chain, tiny runs.
fn tiny_chains() -> Value {
    let dts: Vec<f64> = (0..STEPS).map(|n| 0.001 + 0.000_001 * n as f64).collect();
    json!({
        "scene": {"duration": 0.1, "bodies": [{"type": "chain", "count": 7, "pin": [0]}], "error_estimate": "none"},
        "vary": {"/integrator": ["symplectic_euler", "verlet"], "/dt": dts},
    })
}

/// Seconds `drape sweep FILE --csv` takes, start to exit.
fn command_line(binary: &Path, dir: &Path, file: &Path) -> Result<f64, Box<dyn Error>> {
    let start = Instant::now();
    let status = Command::new(binary)
        .current_dir(dir)
        .arg("sweep")
        .arg(file)
        .arg("--csv")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()?;
    let wall = start.elapsed().as_secs_f64();
    if !status.success() {
        return Err(format!("drape sweep exited with {status}").into());
    }
    Ok(wall)
}

/// Seconds from just before `POST /sweeps` to the `end` event of the sweep's event stream.
async fn through_service(
    client: &reqwest::Client,
    server: &Server,
    body: &[u8],
) -> Result<f64, Box<dyn Error>> {
    let start = Instant::now();
    let id = post_sweep(client, &server.base, body).await?;
    let mut events = client.get(format!("{}/sweeps/{id}/events", server.base)).send().await?;
    let mut text = String::new();
    let ended = |text: &str| text.split_once("event: end").is_some_and(|(_, rest)| rest.contains("\n\n"));
    while !ended(&text) {
        let chunk = events.chunk().await?.ok_or("the event stream ended before its `end` event")?;
        text.push_str(&String::from_utf8_lossy(&chunk));
    }
    let wall = start.elapsed().as_secs_f64();
    // The `end` event carries the table: every run must have succeeded.
    let table = text.split("event: end").nth(1).unwrap_or_default();
    if table.contains("\"status\":\"failed\"") || table.contains("\"status\":\"cancelled\"") {
        return Err(format!("sweep {id} has runs that did not succeed").into());
    }
    Ok(wall)
}
