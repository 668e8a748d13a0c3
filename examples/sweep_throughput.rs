//! How busy `drape serve` keeps the machine through a sweep of 64 small jobs: the peers' 24 × 24
//! hanging cloth (symplectic Euler, f32, 2,000 steps of 1e-4 s, the default Richardson estimate)
//! with the structural stiffness varied over 64 values, submitted with `POST /sweeps` and polled
//! with `GET /sweeps/{id}` every 50 ms until it is complete.
//!
//! For each sweep it reads the server's CPU time (user + system, all threads) from
//! `/proc/PID/stat` before the submission and once the complete table has arrived, and divides
//! by the wall time between: "cores busy". The machine is shared, so it also reads `/proc/stat`:
//! the cores other processes used meanwhile and the cores left idle (idle and I/O wait). A
//! service that leaves cores idle shows idle cores; one that competes with other work shows
//! fewer cores busy but none idle. From `GET /metrics` it takes the workers' occupancy (time spent
//! on jobs over workers × wall time). It also prints runs per second and how long the last
//! `GET /sweeps/{id}` took. Sweeps alternate between `--store memory` and the default SQLite
//! store, each server with its default number of workers unless WORKERS is given.
//!
//! ```sh
//! cargo build --release && cargo run --release --example sweep_throughput [-- ROUNDS [WORKERS]]
//! ```

#[path = "../tests/deadline/mod.rs"]
mod deadline;
#[path = "../tests/serve/mod.rs"]
mod serve;
#[path = "support/serve.rs"]
mod support;

use std::error::Error;
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use serve::Server;
use support::{cpu_seconds, drape_binary, machine_seconds, median, min, peers_cloth, post_sweep};

const VARIANTS: usize = 64;
const POLL: Duration = Duration::from_millis(50);

/// One sweep, measured.
struct Measured {
    wall_s: f64,
    cores_busy: f64,
    other_cores: f64,
    idle_cores: f64,
    occupancy: f64,
    final_get_s: f64,
    mean_job_s: f64,
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), Box<dyn Error>> {
    let rounds: usize = std::env::args().nth(1).map_or(Ok(3), |a| a.parse())?;
    let workers: Option<String> = std::env::args().nth(2);
    let mut extra: Vec<&str> = Vec::new();
    if let Some(w) = &workers {
        extra.extend(["--workers", w.as_str()]);
    }
    let binary = drape_binary()?;
    let dir = tempfile::tempdir()?;
    let sqlite = Server::launch(&binary, dir.path(), "sqlite://drape.db", "127.0.0.1:0", &extra, None);
    let memory = Server::launch(&binary, dir.path(), "memory", "127.0.0.1:0", &extra, None);
    let client = reqwest::Client::new();

    let stiffnesses: Vec<f64> = (0..VARIANTS).map(|i| 2000.0 + 50.0 * i as f64).collect();
    let sweep = json!({
        "scene": peers_cloth(24, 1e-4, 0.2),
        "vary": {"/bodies/0/springs/structural/k": stiffnesses},
    });
    let body = serde_json::to_vec(&sweep)?;

    let servers = [("`--store memory`", &memory), ("default SQLite store", &sqlite)];
    let mut results: [Vec<Measured>; 2] = Default::default();
    // A first, uncounted sweep on each server warms it up.
    for round in 0..=rounds {
        for k in 0..2 {
            let which = (round + k) % 2;
            let (_, server) = servers[which];
            let measured = run_sweep(&client, server, &body).await?;
            if round > 0 {
                results[which].push(measured);
            }
        }
    }

    println!(
        "{VARIANTS} jobs of a 24 × 24 cloth, 2,000 steps each; {} workers; medians of {rounds} sweeps (min in brackets)\n",
        workers.as_deref().unwrap_or("default")
    );
    println!(
        "| store | wall (s) | cores busy | other processes (cores) | idle (cores) | worker occupancy | jobs/s | mean run (ms) | last `GET /sweeps/{{id}}` (ms) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for ((name, _), runs) in servers.iter().zip(&results) {
        let of = |f: fn(&Measured) -> f64| runs.iter().map(f).collect::<Vec<_>>();
        let wall = of(|m| m.wall_s);
        println!(
            "| {name} | {:.2} ({:.2}) | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {:.0} | {:.1} |",
            median(&wall),
            min(&wall),
            median(&of(|m| m.cores_busy)),
            median(&of(|m| m.other_cores)),
            median(&of(|m| m.idle_cores)),
            median(&of(|m| m.occupancy)),
            VARIANTS as f64 / median(&wall),
            median(&of(|m| m.mean_job_s)) * 1e3,
            median(&of(|m| m.final_get_s)) * 1e3,
        );
    }
    Ok(())
}

async fn run_sweep(
    client: &reqwest::Client,
    server: &Server,
    body: &[u8],
) -> Result<Measured, Box<dyn Error>> {
    let busy_before = worker_busy(client, server).await?;
    let machine_before = machine_seconds()?;
    let cpu_before = cpu_seconds(server.pid())?;
    let start = Instant::now();
    let id = post_sweep(client, &server.base, body).await?;
    let (table, final_get_s) = loop {
        let asked = Instant::now();
        let table: Value = client.get(format!("{}/sweeps/{id}", server.base)).send().await?.json().await?;
        if table["complete"] == true {
            break (table, asked.elapsed().as_secs_f64());
        }
        tokio::time::sleep(POLL).await;
    };
    let wall_s = start.elapsed().as_secs_f64();
    let cpu = cpu_seconds(server.pid())? - cpu_before;
    let machine_after = machine_seconds()?;
    let (busy_after, workers) = (worker_busy(client, server).await?, workers(client, server).await?);

    // The table's rows carry the runs' own wall times.
    let rows = table["rows"].as_array().ok_or("no rows")?;
    let failed = rows.iter().filter(|r| r["status"] != "succeeded").count();
    if failed > 0 {
        return Err(format!("{failed} runs did not succeed: {table}").into());
    }
    let mean_job_s = rows.iter().filter_map(|r| r["wall_time_s"].as_f64()).sum::<f64>() / rows.len() as f64;
    Ok(Measured {
        wall_s,
        cores_busy: cpu / wall_s,
        other_cores: (machine_after.busy - machine_before.busy - cpu) / wall_s,
        idle_cores: (machine_after.idle - machine_before.idle) / wall_s,
        occupancy: (busy_after - busy_before) / (workers * wall_s),
        final_get_s,
        mean_job_s,
    })
}

/// A sample of `GET /metrics`.
async fn metric(client: &reqwest::Client, server: &Server, name: &str) -> Result<f64, Box<dyn Error>> {
    let text = client.get(format!("{}/metrics", server.base)).send().await?.text().await?;
    let line = text
        .lines()
        .find(|l| l.split_whitespace().next() == Some(name))
        .ok_or_else(|| format!("no {name} in /metrics"))?;
    Ok(line.split_whitespace().nth(1).ok_or("no value")?.parse()?)
}

async fn worker_busy(client: &reqwest::Client, server: &Server) -> Result<f64, Box<dyn Error>> {
    metric(client, server, "drape_worker_busy_seconds_total").await
}

async fn workers(client: &reqwest::Client, server: &Server) -> Result<f64, Box<dyn Error>> {
    metric(client, server, "drape_workers").await
}
