//! What `drape serve` adds to one run: the peers' 64 × 64 hanging cloth, 500 steps of symplectic
//! Euler (f32, the default Richardson error estimate, the final frame only), run alternately
//!
//! - by `drape run SCENE.json -o RESULT.json`, timed from process start to exit, and
//! - through `POST /simulate` of a running `drape serve`, timed by the client from sending the
//!   request to having read the whole answer, once on `--store memory` and once on the default
//!   SQLite store (`sqlite://drape.db` in a temporary directory),
//!
//! and prints a Markdown table of medians and minima. "Adds" is measured against `drape run` end
//! to end: both read the same scene text, run it and produce the same JSON result. As the run's
//! own time moves by tens of milliseconds on a shared machine, the table also gives, per path,
//! the median over requests of the time beyond the run's own `stats.wall_time_s`: what process
//! start, reading and writing files (`drape run`) or HTTP, queueing, the store and the result's
//! round trip (`drape serve`) add to the same run.
//!
//! ```sh
//! cargo build --release && cargo run --release --example service_overhead [-- REPETITIONS]
//! ```

#[path = "../tests/deadline/mod.rs"]
mod deadline;
#[path = "../tests/serve/mod.rs"]
mod serve;
#[path = "support/serve.rs"]
mod support;

use std::error::Error;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use serde_json::Value;

use serve::Server;
use support::{drape_binary, median, min, peers_cloth};

/// One timing: what the caller saw and what the run reported as its own wall time.
struct Sample {
    seconds: f64,
    run_seconds: f64,
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), Box<dyn Error>> {
    let repetitions: usize = std::env::args().nth(1).map_or(Ok(21), |a| a.parse())?;
    let binary = drape_binary()?;
    let dir = tempfile::tempdir()?;
    let scene_path = dir.path().join("cloth64.json");
    let scene = peers_cloth(64, 5e-5, 0.025);
    std::fs::write(&scene_path, serde_json::to_vec_pretty(&scene)?)?;
    let body = std::fs::read(&scene_path)?;

    let memory = Server::launch(&binary, dir.path(), "memory", "127.0.0.1:0", &[], None);
    let sqlite = Server::launch(&binary, dir.path(), "sqlite://drape.db", "127.0.0.1:0", &[], None);
    let client = reqwest::Client::new();

    let mut samples: [Vec<Sample>; 3] = Default::default();
    // The first round warms caches and connections and is not counted; each round rotates the
    // order so that none of the three always follows another.
    for round in 0..=repetitions {
        for k in 0..3 {
            let which = (round + k) % 3;
            let sample = match which {
                0 => run_command(&binary, &scene_path, &dir.path().join("result.json"))?,
                1 => simulate(&client, &memory.base, &body).await?,
                _ => simulate(&client, &sqlite.base, &body).await?,
            };
            if round > 0 {
                samples[which].push(sample);
            }
        }
    }

    let names = [
        "`drape run` (process start to exit)",
        "`POST /simulate`, `--store memory`",
        "`POST /simulate`, default SQLite store",
    ];
    let wall = |s: &[Sample]| s.iter().map(|x| x.seconds).collect::<Vec<_>>();
    let run = |s: &[Sample]| s.iter().map(|x| x.run_seconds).collect::<Vec<_>>();
    let added = |s: &[Sample]| s.iter().map(|x| x.seconds - x.run_seconds).collect::<Vec<_>>();
    let baseline = median(&wall(&samples[0]));
    println!("64 × 64 cloth, 500 steps, f32, Richardson estimate; {repetitions} interleaved rounds\n");
    println!(
        "| path | median (ms) | min (ms) | median / `drape run` | run's own `stats.wall_time_s`, median (ms) | added to the run, median (ms) | added, % of the run |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for (name, s) in names.iter().zip(&samples) {
        let (w, r, a) = (wall(s), run(s), added(s));
        println!(
            "| {name} | {:.1} | {:.1} | {:.3} | {:.1} | {:.1} | {:.1} |",
            median(&w) * 1e3,
            min(&w) * 1e3,
            median(&w) / baseline,
            median(&r) * 1e3,
            median(&a) * 1e3,
            100.0 * median(&a) / median(&r),
        );
    }
    Ok(())
}

/// `drape run SCENE -o RESULT`, from spawning the process to its exit.
fn run_command(binary: &Path, scene: &Path, result: &Path) -> Result<Sample, Box<dyn Error>> {
    let start = Instant::now();
    let status = Command::new(binary).arg("run").arg(scene).arg("-o").arg(result).status()?;
    let seconds = start.elapsed().as_secs_f64();
    if !status.success() {
        return Err(format!("drape run failed: {status}").into());
    }
    let answer: Value = serde_json::from_slice(&std::fs::read(result)?)?;
    Ok(Sample { seconds, run_seconds: run_wall_time(&answer)? })
}

/// `POST /simulate` with the scene, from sending to having read the whole answer.
async fn simulate(client: &reqwest::Client, base: &str, body: &[u8]) -> Result<Sample, Box<dyn Error>> {
    let start = Instant::now();
    let response = client
        .post(format!("{base}/simulate"))
        .header("content-type", "application/json")
        .body(body.to_vec())
        .send()
        .await?;
    let status = response.status();
    let bytes = response.bytes().await?;
    let seconds = start.elapsed().as_secs_f64();
    if status != 200 {
        return Err(format!("POST /simulate answered {status}: {}", String::from_utf8_lossy(&bytes)).into());
    }
    let answer: Value = serde_json::from_slice(&bytes)?;
    Ok(Sample { seconds, run_seconds: run_wall_time(&answer)? })
}

fn run_wall_time(result: &Value) -> Result<f64, Box<dyn Error>> {
    result["stats"]["wall_time_s"].as_f64().ok_or_else(|| "the result has no stats.wall_time_s".into())
}
