//! The settings of `drape serve`: one flag per setting, each also a `DRAPE_*` environment
//! variable, with defaults that work on a fresh machine.

use std::net::SocketAddr;
use std::time::Duration;

use clap::Args;

use crate::api::ApiConfig;
use crate::jobs::{JobsConfig, Limits, StoreUrl};

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
    /// Most variants one sweep may make (POST /sweeps answers 422 above).
    #[arg(long, env = "DRAPE_MAX_SWEEP_VARIANTS", default_value_t = ApiConfig::default().max_sweep_variants)]
    pub max_sweep_variants: u64,
    /// Longest a job may run, in seconds; it is then stopped and marked failed.
    #[arg(long, env = "DRAPE_JOB_WALL_TIME", default_value = "300", value_parser = seconds)]
    pub job_wall_time: Duration,
    /// Largest run POST /simulate takes, in particle-steps (particles × steps, error-estimate
    /// companions included); larger runs get 413 and a pointer to POST /jobs.
    #[arg(long, env = "DRAPE_SIMULATE_WORK_BUDGET", default_value_t = ApiConfig::default().simulate_work_budget)]
    pub simulate_work_budget: u64,
    /// Longest time to answer a request, in seconds (408 after); it must cover a /simulate run.
    #[arg(long, env = "DRAPE_REQUEST_TIMEOUT", default_value = "330", value_parser = seconds)]
    pub request_timeout: Duration,
    /// Requests handled at once; more get 503.
    #[arg(long, env = "DRAPE_MAX_CONCURRENT_REQUESTS", default_value_t = 1024)]
    pub max_concurrent_requests: usize,
    /// Origins a web page may call from (comma-separated; `*` for any).
    #[arg(long, env = "DRAPE_CORS_ORIGINS", default_value = "*", value_delimiter = ',')]
    pub cors_origins: Vec<String>,
    /// With `--store memory`: ended jobs kept with their results; older ones are forgotten.
    #[arg(long, env = "DRAPE_RETAIN_JOBS", default_value_t = crate::jobs::MemoryStore::DEFAULT_RETAIN)]
    pub retain_jobs: usize,
    /// Seconds running jobs get to finish on SIGINT or SIGTERM before they are cancelled.
    #[arg(long, env = "DRAPE_SHUTDOWN_GRACE", default_value = "30", value_parser = seconds)]
    pub shutdown_grace: Duration,
}

impl Config {
    /// The job system's part.
    pub fn jobs(&self) -> JobsConfig {
        JobsConfig {
            workers: self.workers.map_or_else(|| JobsConfig::default().workers, usize::from),
            queue_capacity: self.queue_capacity as usize,
            wall_time: self.job_wall_time,
            limits: Limits {
                max_particles: self.max_particles,
                max_springs: self.max_springs,
                max_steps: self.max_steps,
                max_output_values: self.max_output_values,
            },
            before_run: None,
            lease: self.lease,
            result_ttl: self.result_ttl,
            idle_poll: JobsConfig::default().idle_poll,
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
        }
    }
}

/// Reads a non-negative, finite number of seconds.
fn seconds(text: &str) -> Result<Duration, String> {
    let value: f64 = text.parse().map_err(|_| format!("`{text}` is not a number of seconds"))?;
    Duration::try_from_secs_f64(value)
        .map_err(|_| format!("`{text}` is not a non-negative, finite number of seconds"))
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
        assert_eq!(cli.config.jobs().limits, Limits::default());
        assert_eq!(cli.config.cors_origins, ["*"]);
        assert_eq!(cli.config.store, StoreUrl::Sqlite("drape.db".into()));
        assert_eq!(cli.config.jobs().result_ttl, Duration::from_secs(86_400));
        assert_eq!(cli.config.jobs().lease, Duration::from_secs(30));
        assert_eq!(cli.config.api().max_sweep_variants, 1000);
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
        ]);
        assert_eq!(cli.config.jobs().workers, 3);
        assert_eq!(cli.config.jobs().wall_time, Duration::from_millis(1500));
        assert_eq!(cli.config.cors_origins, ["http://a", "http://b"]);
        assert_eq!(cli.config.api().max_sweep_variants, 12);
    }

    #[test]
    fn bad_values_are_refused() {
        for args in [
            ["drape", "--workers", "0"],
            ["drape", "--job-wall-time", "-1"],
            ["drape", "--shutdown-grace", "soon"],
            ["drape", "--store", "mysql://db"],
            ["drape", "--lease", "0.2"],
        ] {
            assert!(Cli::try_parse_from(args).is_err(), "{args:?}");
        }
    }
}
