//! What the service measurements share besides the launcher: the `drape` binary they run, the
//! peers' hanging cloth as a scene, the submission of a sweep, medians and CPU times. The `drape serve` child they measure
//! is started by the tests' launcher, `tests/serve/mod.rs`, which they include as well.

#![allow(dead_code)]

use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::{Value, json};

/// The `drape` binary built beside this example (`target/release/drape`), or `$DRAPE_BIN`.
pub fn drape_binary() -> Result<PathBuf, String> {
    if let Some(path) = std::env::var_os("DRAPE_BIN") {
        return Ok(PathBuf::from(path));
    }
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    // target/release/examples/NAME → target/release/drape
    let binary = exe
        .parent()
        .and_then(Path::parent)
        .map(|dir| dir.join("drape"))
        .ok_or("cannot find the target directory")?;
    if !binary.exists() {
        return Err(format!("{} is missing: run `cargo build --release` first", binary.display()));
    }
    let (built, this) = (modified(&binary), modified(&exe));
    if built < this.map(|t| t - std::time::Duration::from_secs(600)) {
        eprintln!(
            "warning: {} is older than this example; `cargo build --release` rebuilds it",
            binary.display()
        );
    }
    Ok(binary)
}

fn modified(path: &Path) -> Option<std::time::SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

/// The peers' hanging cloth (`docs/performance.md`): `n` × `n` particles on 1 m², 1 kg,
/// every spring family at k = 5000 N/m and damping 0.5, drag 0.01 per particle (0.01·N² 1/s as a
/// rate), two corners pinned, symplectic Euler in f32, the final frame's positions only.
pub fn peers_cloth(n: u32, dt: f64, duration: f64) -> Value {
    let spring = json!({"k": 5000, "damping": 0.5});
    json!({
        "duration": duration,
        "integrator": "symplectic_euler",
        "precision": "f32",
        "dt": dt,
        "drag": 0.01 * f64::from(n * n),
        "bodies": [{
            "type": "cloth", "name": "sheet", "size": [1.0, 1.0], "resolution": [n, n],
            "center": [0.5, 1.0, 0.5], "orientation": "horizontal", "mass": 1.0,
            "springs": {"structural": spring, "shear": spring, "bending": spring},
            "pin": [[0, 0], [n - 1, 0]]
        }],
        "output": {"frames": "final", "fields": ["positions"]}
    })
}

/// `POST /sweeps` of the sweep `body` to the server at `base`: the id of the sweep it queued, or
/// an error with what it answered instead of `202`.
pub async fn post_sweep(client: &reqwest::Client, base: &str, body: &[u8]) -> Result<String, Box<dyn Error>> {
    let response = client
        .post(format!("{base}/sweeps"))
        .header("content-type", "application/json")
        .body(body.to_vec())
        .send()
        .await?;
    if response.status() != 202 {
        return Err(format!("POST /sweeps answered {}: {}", response.status(), response.text().await?).into());
    }
    Ok(response.json::<Value>().await?["id"].as_str().ok_or("no sweep id")?.to_string())
}

/// The median of some samples (the mean of the middle two for an even count).
pub fn median(samples: &[f64]) -> f64 {
    let mut sorted = samples.to_vec();
    sorted.sort_by(f64::total_cmp);
    let middle = sorted.len() / 2;
    if sorted.len().is_multiple_of(2) { (sorted[middle - 1] + sorted[middle]) / 2.0 } else { sorted[middle] }
}

/// The smallest sample.
pub fn min(samples: &[f64]) -> f64 {
    samples.iter().copied().fold(f64::INFINITY, f64::min)
}

/// CPU time (user + system) the process has used so far, in seconds, from `/proc/PID/stat`.
pub fn cpu_seconds(pid: u32) -> Result<f64, String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).map_err(|e| e.to_string())?;
    // The command name (field 2) may hold spaces; the fields after its closing parenthesis are
    // state (3), ..., utime (14), stime (15).
    let after = stat.rsplit_once(')').ok_or("an unreadable /proc/PID/stat")?.1;
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i - 3).and_then(|f| f.parse::<u64>().ok()).ok_or("no CPU times");
    let ticks_per_second = clock_ticks()?;
    Ok((ticks(14)? + ticks(15)?) as f64 / ticks_per_second)
}

fn clock_ticks() -> Result<f64, String> {
    let out = Command::new("getconf").arg("CLK_TCK").output().map_err(|e| format!("getconf: {e}"))?;
    String::from_utf8_lossy(&out.stdout).trim().parse().map_err(|e| format!("CLK_TCK: {e}"))
}

/// The whole machine's CPU time so far, from `/proc/stat`: busy and idle (idle + I/O wait), in
/// seconds summed over the cores.
pub struct MachineTime {
    /// Time spent running anything.
    pub busy: f64,
    /// Time no core had anything to run.
    pub idle: f64,
}

/// The machine's CPU time so far.
pub fn machine_seconds() -> Result<MachineTime, String> {
    let stat = std::fs::read_to_string("/proc/stat").map_err(|e| e.to_string())?;
    let line = stat.lines().find(|l| l.starts_with("cpu ")).ok_or("no cpu line in /proc/stat")?;
    let ticks: Vec<u64> = line.split_whitespace().skip(1).filter_map(|f| f.parse().ok()).collect();
    if ticks.len() < 8 {
        return Err("a short cpu line in /proc/stat".into());
    }
    // user nice system idle iowait irq softirq steal (guest time is already in user).
    let idle = ticks[3] + ticks[4];
    let busy = ticks[0] + ticks[1] + ticks[2] + ticks[5] + ticks[6] + ticks[7];
    let per_second = clock_ticks()?;
    Ok(MachineTime { busy: busy as f64 / per_second, idle: idle as f64 / per_second })
}
