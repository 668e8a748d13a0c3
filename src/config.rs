//! The settings of `drape serve`: one flag per setting, each also a `DRAPE_*` environment
//! variable, with defaults that work on a fresh machine.

use std::net::SocketAddr;
use std::time::Duration;

use clap::Args;

use crate::api::{AllowedHosts, ApiConfig, AuthToken};
use crate::assets::MeshLimits;
use crate::jobs::store::{MemoryStore, StoreUrl};
use crate::jobs::{AssetLimits, JobsConfig, Limits};

/// How the server runs and what it accepts.
#[derive(Args, Clone, Debug)]
pub struct Config {
    /// Address to listen on (port 0 picks a free port).
    #[arg(long, env = "DRAPE_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Where jobs and results are kept: `sqlite://PATH` (one instance; the file is created),
    /// `postgres://USER@HOST/DB` (any number of instances sharing one queue) or `memory`.
    #[arg(long, env = "DRAPE_STORE", default_value = "sqlite://drape.db")]
    pub store: StoreUrl,
    /// Seconds a result is kept after its job ends.
    #[arg(long, env = "DRAPE_RESULT_TTL", default_value = "86400", value_parser = seconds)]
    pub result_ttl: Duration,
    /// Seconds a running job stays this instance's without a renewal (renewed 4 times a second);
    /// a job whose instance died runs again elsewhere after this.
    #[arg(long, env = "DRAPE_LEASE", default_value = "30", value_parser = lease_seconds)]
    pub lease: Duration,
    /// Worker threads that run simulations [default: one per core].
    #[arg(long, env = "DRAPE_WORKERS", value_parser = clap::value_parser!(u16).range(1..))]
    pub workers: Option<u16>,
    /// Jobs that may wait for a worker; more are refused with 429 and Retry-After.
    #[arg(long, env = "DRAPE_QUEUE_CAPACITY", default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..))]
    pub queue_capacity: u32,
    /// Largest request body, in bytes (413 above).
    #[arg(long, env = "DRAPE_BODY_LIMIT", default_value_t = 4 << 20)]
    pub body_limit: usize,
    /// The limits every run must fit.
    #[command(flatten)]
    pub limits: LimitArgs,
    /// Most variants one sweep may make (POST /sweeps answers 422 above).
    #[arg(long, env = "DRAPE_MAX_SWEEP_VARIANTS", default_value_t = ApiConfig::default().max_sweep_variants)]
    pub max_sweep_variants: u64,
    /// Longest a job may run, in seconds; it is then stopped and marked failed.
    #[arg(long, env = "DRAPE_JOB_WALL_TIME", default_value = "300", value_parser = seconds)]
    pub job_wall_time: Duration,
    /// Largest run POST /simulate takes, in element-steps (the work --max-work counts);
    /// larger runs get 413 and a pointer to POST /jobs.
    #[arg(long, env = "DRAPE_SIMULATE_WORK_BUDGET", default_value_t = ApiConfig::default().simulate_work_budget)]
    pub simulate_work_budget: u64,
    /// Longest time to answer a request, in seconds (408 after); it must cover a /simulate run.
    #[arg(long, env = "DRAPE_REQUEST_TIMEOUT", default_value = "330", value_parser = seconds)]
    pub request_timeout: Duration,
    /// Seconds a connection may take from the first byte of a request to the end of its headers;
    /// it is then closed without an answer.
    #[arg(long, env = "DRAPE_HEADER_READ_TIMEOUT", default_value = "10", value_parser = positive_seconds)]
    pub header_read_timeout: Duration,
    /// Seconds a connection may stay open with no request in flight (after its last response,
    /// or from its opening) before it is closed.
    #[arg(long, env = "DRAPE_IDLE_TIMEOUT", default_value = "60", value_parser = positive_seconds)]
    pub idle_timeout: Duration,
    /// Requests handled at once; more get 503.
    #[arg(long, env = "DRAPE_MAX_CONCURRENT_REQUESTS", default_value_t = 1024)]
    pub max_concurrent_requests: usize,
    /// Origins a web page may call from (comma-separated; `*` for any).
    #[arg(long, env = "DRAPE_CORS_ORIGINS", default_value = "*", value_delimiter = ',')]
    pub cors_origins: Vec<String>,
    /// A bearer token clients must send (`Authorization: Bearer <token>`) on every request but
    /// `/healthz`; repeat the flag for several (the variable takes them comma-separated).
    /// Without one, anyone who reaches the port may use the API.
    #[arg(long = "auth-token", env = "DRAPE_AUTH_TOKENS", value_delimiter = ',', hide_env_values = true)]
    pub auth_tokens: Vec<AuthToken>,
    /// Host names (without port) requests may be addressed to, comma-separated; `*` for any
    /// [default: `localhost,127.0.0.1,[::1]` on a loopback address, any elsewhere].
    #[arg(long, env = "DRAPE_ALLOWED_HOSTS", value_delimiter = ',', value_parser = host_name)]
    pub allowed_hosts: Option<Vec<String>>,
    /// With `--store memory`: ended jobs kept with their results; older ones are forgotten.
    #[arg(long, env = "DRAPE_RETAIN_JOBS", default_value_t = MemoryStore::DEFAULT_RETAIN)]
    pub retain_jobs: usize,
    /// Starts a job may have without ending before it is failed instead of started again: a job
    /// that crashes the server (or loses its instance) each time it runs ends after this many.
    #[arg(long, env = "DRAPE_MAX_ATTEMPTS", default_value_t = JobsConfig::default().max_attempts,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub max_attempts: u32,
    /// Largest mesh file POST /assets takes, in bytes (suffixes K, M, G: powers of 1024); an
    /// upload is also held to --body-limit.
    #[arg(long, env = "DRAPE_MAX_ASSET_BYTES", default_value = "4M", value_parser = byte_size)]
    pub max_asset_bytes: u64,
    /// Uploaded meshes the store may hold (POST /assets answers 413 above).
    #[arg(long, env = "DRAPE_MAX_ASSETS", default_value_t = AssetLimits::default().max_assets)]
    pub max_assets: u64,
    /// Bytes of uploaded mesh files the store may hold over all assets (suffixes K, M, G).
    #[arg(long, env = "DRAPE_MAX_ASSET_STORAGE", default_value = "1G", value_parser = byte_size)]
    pub max_asset_storage: u64,
    /// Seconds running jobs get to finish on SIGINT or SIGTERM before they are cancelled.
    #[arg(long, env = "DRAPE_SHUTDOWN_GRACE", default_value = "30", value_parser = seconds)]
    pub shutdown_grace: Duration,
}

impl Config {
    /// Worker threads, given or one per core.
    fn jobs_workers(&self) -> usize {
        self.workers.map_or_else(|| JobsConfig::default().workers, usize::from)
    }

    /// The job system's part.
    pub fn jobs(&self) -> JobsConfig {
        JobsConfig {
            workers: self.jobs_workers(),
            queue_capacity: self.queue_capacity as usize,
            wall_time: self.job_wall_time,
            limits: self.limits.limits(self.jobs_workers()),
            before_run: None,
            lease: self.lease,
            result_ttl: self.result_ttl,
            idle_poll: JobsConfig::default().idle_poll,
            max_attempts: self.max_attempts,
            assets: AssetLimits {
                mesh: self.limits.mesh_limits(),
                max_bytes: self.max_asset_bytes,
                max_assets: self.max_assets,
                max_total_bytes: self.max_asset_storage,
            },
        }
    }

    /// The HTTP side's part.
    pub fn api(&self) -> ApiConfig {
        ApiConfig {
            body_limit: self.body_limit,
            simulate_work_budget: self.simulate_work_budget,
            request_timeout: self.request_timeout,
            max_concurrent_requests: self.max_concurrent_requests,
            cors_origins: self.cors_origins.clone(),
            max_sweep_variants: self.max_sweep_variants,
            auth_tokens: self.auth_tokens.clone(),
            header_read_timeout: self.header_read_timeout,
            idle_timeout: self.idle_timeout,
            allowed_hosts: match &self.allowed_hosts {
                Some(names) => AllowedHosts::from_names(names),
                None => AllowedHosts::default_for(self.addr.ip()),
            },
        }
    }
}

/// The limits of a run: flags and `DRAPE_*` variables shared by `drape serve`, `drape run` and
/// `drape sweep`, so that the command line refuses what the server refuses.
#[derive(Args, Clone, Debug, PartialEq, Eq)]
pub struct LimitArgs {
    /// Most particles in one scene.
    #[arg(long, env = "DRAPE_MAX_PARTICLES", default_value_t = Limits::default().max_particles)]
    pub max_particles: u64,
    /// Most springs in one scene.
    #[arg(long, env = "DRAPE_MAX_SPRINGS", default_value_t = Limits::default().max_springs)]
    pub max_springs: u64,
    /// Most steps in one run.
    #[arg(long, env = "DRAPE_MAX_STEPS", default_value_t = Limits::default().max_steps)]
    pub max_steps: u64,
    /// Most values in one result: frames × (particles × 3 per vector field + springs for strain).
    #[arg(long, env = "DRAPE_MAX_OUTPUT_VALUES", default_value_t = Limits::default().max_output_values)]
    pub max_output_values: u64,
    /// Most work in one run, in element-steps: particles, springs, collider tests
    /// (colliders × particles), self-collision pairs and wind triangles, each per step, RK4 and
    /// implicit Euler counted per force evaluation, error-estimate companions included.
    #[arg(long, env = "DRAPE_MAX_WORK", default_value_t = Limits::default().max_work)]
    pub max_work: u64,
    /// Memory the runs may hold at once, in bytes (suffixes K, M, G, T: powers of 1024); each
    /// of the runs at once (workers, sweep threads) gets an equal share after 64 MiB for the
    /// rest of the process [default: half the machine's memory].
    #[arg(long, env = "DRAPE_MEMORY_BUDGET", value_parser = byte_size)]
    pub memory_budget: Option<u64>,
    /// Most triangles in one mesh file (an uploaded asset or a `file` a scene names), after its
    /// polygons are split; its vertices are held to --max-particles.
    #[arg(long, env = "DRAPE_MAX_ASSET_TRIANGLES", default_value_t = AssetLimits::default().mesh.max_triangles)]
    pub max_asset_triangles: u64,
}

impl Default for LimitArgs {
    fn default() -> Self {
        let limits = Limits::default();
        Self {
            max_particles: limits.max_particles,
            max_springs: limits.max_springs,
            max_steps: limits.max_steps,
            max_output_values: limits.max_output_values,
            max_work: limits.max_work,
            memory_budget: None,
            max_asset_triangles: AssetLimits::default().mesh.max_triangles,
        }
    }
}

/// Memory kept out of the runs' shares for the rest of the process: the async runtime, requests
/// and responses, the store's connections.
pub const MEMORY_RESERVE: u64 = 64 << 20;

impl LimitArgs {
    /// The budget, given or half the machine's memory (8 GiB when that cannot be read).
    pub fn memory_budget(&self) -> u64 {
        self.memory_budget.unwrap_or_else(|| machine_memory().map_or(8 << 30, |total| total / 2))
    }

    /// The largest mesh a file may hold.
    pub fn mesh_limits(&self) -> MeshLimits {
        MeshLimits { max_vertices: self.max_particles, max_triangles: self.max_asset_triangles }
    }

    /// The limits of each of `runs_at_once` runs sharing the memory budget.
    pub fn limits(&self, runs_at_once: usize) -> Limits {
        let runs = runs_at_once.max(1) as u64;
        Limits {
            max_particles: self.max_particles,
            max_springs: self.max_springs,
            max_steps: self.max_steps,
            max_output_values: self.max_output_values,
            max_work: self.max_work,
            max_memory: self.memory_budget().saturating_sub(MEMORY_RESERVE) / runs,
        }
    }
}

/// The machine's memory in bytes, from `MemTotal` in `/proc/meminfo`.
fn machine_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Reads a byte count: digits, optionally followed by `K`, `M`, `G` or `T` (powers of 1024),
/// with or without a trailing `B` or `iB`.
pub fn byte_size(text: &str) -> Result<u64, String> {
    let trimmed = text.trim();
    let unit_start = trimmed.find(|c: char| !c.is_ascii_digit()).unwrap_or(trimmed.len());
    let (digits, unit) = trimmed.split_at(unit_start);
    let shift = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 0,
        "K" | "KB" | "KIB" => 10,
        "M" | "MB" | "MIB" => 20,
        "G" | "GB" | "GIB" => 30,
        "T" | "TB" | "TIB" => 40,
        _ => return Err(format!("`{text}` is not a byte count (e.g. 536870912, 512M, 4G)")),
    };
    let value: u64 = digits.parse().map_err(|_| format!("`{text}` is not a byte count (e.g. 512M, 4G)"))?;
    value.checked_mul(1 << shift).filter(|&b| b > 0).ok_or_else(|| format!("`{text}` is out of range"))
}

/// Reads a non-negative, finite number of seconds.
fn seconds(text: &str) -> Result<Duration, String> {
    let value: f64 = text.parse().map_err(|_| format!("`{text}` is not a number of seconds"))?;
    Duration::try_from_secs_f64(value)
        .map_err(|_| format!("`{text}` is not a non-negative, finite number of seconds"))
}

/// Reads a number of seconds above zero.
fn positive_seconds(text: &str) -> Result<Duration, String> {
    let duration = seconds(text)?;
    if duration.is_zero() {
        return Err(format!("`{text}` would close every connection at once; give more than 0 seconds"));
    }
    Ok(duration)
}

/// Reads a host name for `--allowed-hosts`: a name or address, with or without a port, or `*`.
fn host_name(text: &str) -> Result<String, String> {
    let name = text.trim();
    let allowed = |c: char| c.is_ascii_alphanumeric() || "-.:[]_*".contains(c);
    if name.is_empty() || !name.chars().all(allowed) {
        return Err(format!("`{text}` is not a host name, an address or `*`"));
    }
    Ok(name.to_string())
}

/// Reads a lease: long enough to be renewed several times over.
fn lease_seconds(text: &str) -> Result<Duration, String> {
    let lease = seconds(text)?;
    if lease < Duration::from_secs(1) {
        return Err(format!("a lease of {text} s is too short to be renewed in time; give at least 1"));
    }
    Ok(lease)
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        config: Config,
    }

    #[test]
    fn defaults_and_flags() {
        let cli = Cli::parse_from(["drape"]);
        assert_eq!(cli.config.addr.to_string(), "127.0.0.1:8080");
        let budget = cli.config.limits.memory_budget();
        let workers = cli.config.jobs().workers as u64;
        assert_eq!(
            cli.config.jobs().limits,
            Limits { max_memory: (budget - MEMORY_RESERVE) / workers, ..Limits::default() }
        );
        assert_eq!(cli.config.cors_origins, ["*"]);
        assert_eq!(cli.config.store, StoreUrl::Sqlite("drape.db".into()));
        assert_eq!(cli.config.jobs().result_ttl, Duration::from_secs(86_400));
        assert_eq!(cli.config.jobs().lease, Duration::from_secs(30));
        assert_eq!(cli.config.api().max_sweep_variants, 10_000);
        assert_eq!(cli.config.jobs().max_attempts, 3);
        assert_eq!(cli.config.api().auth_tokens, []);
        assert_eq!(cli.config.api().header_read_timeout, Duration::from_secs(10));
        assert_eq!(cli.config.api().idle_timeout, Duration::from_secs(60));
        assert_eq!(cli.config.api().allowed_hosts, AllowedHosts::loopback());
        let elsewhere = Cli::parse_from(["drape", "--addr", "0.0.0.0:8080"]);
        assert_eq!(elsewhere.config.api().allowed_hosts, AllowedHosts::Any);
        let cli = Cli::parse_from([
            "drape",
            "--workers",
            "3",
            "--job-wall-time",
            "1.5",
            "--cors-origins",
            "http://a,http://b",
            "--max-sweep-variants",
            "12",
            "--max-attempts",
            "5",
            "--auth-token",
            "first",
            "--auth-token",
            "second",
            "--allowed-hosts",
            "drape.example,localhost",
            "--memory-budget",
            "1G",
            "--max-work",
            "1000",
        ]);
        assert_eq!(cli.config.jobs().limits.max_memory, ((1 << 30) - MEMORY_RESERVE) / 3);
        assert_eq!(cli.config.jobs().limits.max_work, 1000);
        assert_eq!(cli.config.jobs().workers, 3);
        assert_eq!(cli.config.jobs().wall_time, Duration::from_millis(1500));
        assert_eq!(cli.config.cors_origins, ["http://a", "http://b"]);
        assert_eq!(cli.config.api().max_sweep_variants, 12);
        assert_eq!(cli.config.jobs().max_attempts, 5);
        let tokens = ["first", "second"].map(|t| AuthToken::parse(t).unwrap());
        assert_eq!(cli.config.api().auth_tokens, tokens);
        assert_eq!(
            cli.config.api().allowed_hosts,
            AllowedHosts::Names(vec!["drape.example".into(), "localhost".into()])
        );
    }

    #[test]
    fn byte_sizes_take_binary_suffixes() {
        assert_eq!(byte_size("512"), Ok(512));
        assert_eq!(byte_size("512M"), Ok(512 << 20));
        assert_eq!(byte_size("4G"), Ok(4 << 30));
        assert_eq!(byte_size("4GiB"), Ok(4 << 30));
        assert_eq!(byte_size("2k"), Ok(2048));
        assert!(byte_size("4X").is_err() && byte_size("G").is_err() && byte_size("99999999999T").is_err());
    }

    #[test]
    fn bad_values_are_refused() {
        for args in [
            ["drape", "--workers", "0"],
            ["drape", "--job-wall-time", "-1"],
            ["drape", "--shutdown-grace", "soon"],
            ["drape", "--store", "mysql://db"],
            ["drape", "--lease", "0.2"],
            ["drape", "--max-attempts", "0"],
            ["drape", "--auth-token", "has space"],
            ["drape", "--auth-token", ""],
            ["drape", "--idle-timeout", "0"],
            ["drape", "--allowed-hosts", ""],
            ["drape", "--allowed-hosts", "localhost,,127.0.0.1"],
            ["drape", "--allowed-hosts", "http://drape.example/"],
            ["drape", "--header-read-timeout", "-2"],
            ["drape", "--memory-budget", "lots"],
            ["drape", "--memory-budget", "0"],
        ] {
            assert!(Cli::try_parse_from(args).is_err(), "{args:?}");
        }
    }
}
