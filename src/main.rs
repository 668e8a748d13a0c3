//! The `drape` command: serve the HTTP API, or run a scene or a sweep from the shell, here or,
//! with `--server`, on a drape server.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::AtomicUsize;

use clap::{Parser, Subcommand};

use drape::assets::{has_references, resolve_files};
use drape::client::{ClientArgs, Exit};
use drape::config::LimitArgs;
use drape::jobs::{admit_for_table, sweep_over_limit};
use drape::output::{Format, encode};
use drape::progress;
use drape::run::{Control, Status, execute};
use drape::scene::Scene;
use drape::sweep::{Sweep, Thresholds, run_locally_with, write_csv, write_svg};

/// Cloth and mass-spring simulation.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serves the HTTP API (see /openapi.json) until SIGINT or SIGTERM.
    Serve(Box<drape::config::Config>),
    /// Runs a scene and prints its JSON result (or writes it to a file).
    ///
    /// Exit status: 0 succeeded, 1 the run failed or diverged (a diverged run's result is still
    /// written), 2 a bad scene (each field named). With --server the scene runs there and its
    /// result is written here the same way, with the same statuses and 3 when the server could
    /// not be reached or refused the work.
    Run {
        /// The scene, as a JSON file (`-` reads standard input).
        scene: PathBuf,
        /// Write the result here instead of standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Encode the result as json, glb, obj, npy, npz or pc2 (default: the scene's
        /// `output.format`). npy becomes npz when the scene asks for more than positions; fields
        /// the format cannot carry are not recorded, and named on standard error.
        #[arg(short, long)]
        format: Option<Format>,
        /// Draw no progress bar (one is drawn on standard error only when it is a terminal).
        #[arg(short, long)]
        quiet: bool,
        /// The limits the run must fit (as `drape serve` applies them; the memory budget is the
        /// run's alone).
        #[command(flatten)]
        limits: LimitArgs,
        #[command(flatten)]
        client: ClientArgs,
    },
    /// Runs every variant of a sweep and prints its table (JSON, or CSV with --csv).
    ///
    /// With --server the sweep runs there; the exit status is then 0, 1 a threshold crossed,
    /// 2 a bad sweep, 3 the server could not be reached or refused the work.
    Sweep {
        /// The sweep, as a JSON file (`-` reads standard input).
        sweep: PathBuf,
        /// Print the table as CSV instead of JSON.
        #[arg(long)]
        csv: bool,
        /// Also write the work-precision plot (error against wall time) as SVG to this file.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Runs at a time (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Refuse sweeps with more variants than this.
        #[arg(long, default_value_t = 1000)]
        max_variants: u64,
        /// Draw no progress bar (one is drawn on standard error only when it is a terminal).
        #[arg(short, long)]
        quiet: bool,
        /// Exit 1 if a run's error (against the reference, else its own estimate) is above this,
        /// in metres, or a run did not succeed.
        #[arg(long)]
        max_error: Option<f64>,
        /// Exit 1 if an integrator's observed convergence order is below this (needs `/dt` varied
        /// and a reference).
        #[arg(long)]
        min_order: Option<f64>,
        /// The limits every run must fit (as `drape serve` applies them; the memory budget is
        /// shared by the runs at once).
        #[command(flatten)]
        limits: LimitArgs,
        #[command(flatten)]
        client: ClientArgs,
    },
    /// Queues a scene on a server (--server or DRAPE_SERVER) and prints the job as JSON (its id,
    /// status and links) without waiting; with --wait, follows it and writes its result as
    /// `drape run --server` does. Exit status: 0 queued (or succeeded), 1 the run failed or
    /// diverged, 2 a bad scene, 3 the server could not be reached or refused the work.
    Submit {
        /// The scene, as a JSON file (`-` reads standard input).
        scene: PathBuf,
        /// Wait for the run and write its result (as `drape run --server`).
        #[arg(long)]
        wait: bool,
        /// With --wait: write the result here instead of standard output.
        #[arg(short, long, requires = "wait")]
        output: Option<PathBuf>,
        /// Store the result in this format (json, glb, obj, npy, npz or pc2) instead of the
        /// scene's `output.format`.
        #[arg(short, long)]
        format: Option<Format>,
        /// Draw no progress bar while waiting.
        #[arg(short, long)]
        quiet: bool,
        /// The limits a mesh file the scene names must fit.
        #[command(flatten)]
        limits: LimitArgs,
        #[command(flatten)]
        client: ClientArgs,
    },
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Serve(config) => serve(*config),
        Command::Run { scene, output, format, quiet, limits, client } => match client.server() {
            Some(server) => {
                let options = drape::client::RunOptions {
                    output: output.as_deref(),
                    format,
                    progress: progress::wanted(quiet),
                };
                remote(&scene, None, &limits, |name, text| {
                    drape::client::run(&server, name, text, &options, client.idempotency_key.as_deref())
                })
            }
            None => run(&scene, output.as_deref(), format, progress::wanted(quiet), &limits),
        },
        Command::Submit { scene, wait, output, format, quiet, limits, client } => {
            let Some(server) = client.server() else {
                eprintln!("drape: submit needs a server: --server URL or DRAPE_SERVER");
                return Exit::BadInput.into();
            };
            let key = client.idempotency_key.as_deref();
            remote(&scene, None, &limits, |name, text| {
                if wait {
                    let options = drape::client::RunOptions {
                        output: output.as_deref(),
                        format,
                        progress: progress::wanted(quiet),
                    };
                    drape::client::run(&server, name, text, &options, key)
                } else {
                    drape::client::submit(&server, text, format, key)
                }
            })
        }
        Command::Sweep {
            sweep,
            csv,
            plot,
            threads,
            max_variants,
            quiet,
            max_error,
            min_order,
            limits,
            client,
        } => {
            let thresholds = Thresholds { max_error, min_order };
            if let Some(server) = client.server() {
                let options = drape::client::SweepOptions {
                    csv,
                    plot: plot.as_deref(),
                    progress: progress::wanted(quiet),
                    thresholds,
                };
                return remote(&sweep, Some("scene"), &limits, |name, text| {
                    drape::client::sweep(&server, name, text, &options, client.idempotency_key.as_deref())
                });
            }
            let threads =
                threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            let options = SweepOptions {
                csv,
                plot: plot.as_deref(),
                threads,
                max_variants,
                progress: progress::wanted(quiet),
                thresholds,
            };
            run_sweep(&sweep, options, &limits)
        }
    }
}

fn serve(config: drape::config::Config) -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "info,tower_http=info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let runtime = match tokio::runtime::Builder::new_multi_thread().enable_all().build() {
        Ok(runtime) => runtime,
        Err(e) => {
            eprintln!("drape: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    let addr = config.addr;
    match runtime.block_on(drape::server::run(config, drape::server::shutdown_signal())) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("drape: cannot serve on {addr}: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Sends the scene (or sweep, whose base scene is under `member`) in the file at `path` to a
/// server through `send`, with its mesh files read and put in place here, since the server reads
/// no paths.
fn remote(
    path: &Path,
    member: Option<&str>,
    limits: &LimitArgs,
    send: impl FnOnce(&str, Vec<u8>) -> Exit,
) -> ExitCode {
    match read_input(path).and_then(|text| with_mesh_files(text, path, member, limits)) {
        Ok(text) => send(&path.display().to_string(), text).into(),
        Err(code) => code,
    }
}

/// Reads a file, or standard input for `-`.
fn read_input(path: &Path) -> Result<Vec<u8>, ExitCode> {
    let text = if path.as_os_str() == "-" {
        let mut text = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut text).map(|_| text)
    } else {
        std::fs::read(path)
    };
    text.map_err(|e| {
        eprintln!("drape: cannot read {}: {e}", path.display());
        ExitCode::from(2)
    })
}

/// The scene (or a sweep's base scene, under `member`) of `text` read from `path`, with every
/// mesh `file` it names read, relative to the file's directory (the working directory for
/// standard input), and put in place. Text that is not JSON is left for the parse to report.
fn with_mesh_files(
    text: Vec<u8>,
    path: &Path,
    member: Option<&str>,
    limits: &LimitArgs,
) -> Result<Vec<u8>, ExitCode> {
    let Ok(mut document) = serde_json::from_slice::<serde_json::Value>(&text) else { return Ok(text) };
    let prefix = member.map_or(String::new(), |m| format!("/{m}"));
    let Some(scene) = (match member {
        Some(m) => document.get_mut(m),
        None => Some(&mut document),
    }) else {
        return Ok(text);
    };
    if !has_references(scene) {
        return Ok(text);
    }
    let directory = match path.parent() {
        Some(parent) if path.as_os_str() != "-" && !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    match resolve_files(scene, &prefix, directory, limits.mesh_limits()) {
        Ok(()) => Ok(serde_json::to_vec(&document).expect("a JSON value serializes")),
        Err(errors) => {
            eprintln!("drape: {} names meshes that cannot be read:", path.display());
            errors.iter().for_each(|fe| eprintln!("  {fe}"));
            Err(ExitCode::from(2))
        }
    }
}

/// How `drape sweep` runs and prints.
struct SweepOptions<'a> {
    csv: bool,
    plot: Option<&'a Path>,
    threads: usize,
    max_variants: u64,
    progress: bool,
    thresholds: Thresholds,
}

fn run_sweep(path: &Path, options: SweepOptions<'_>, limits: &LimitArgs) -> ExitCode {
    let SweepOptions { csv, plot, threads, max_variants, progress, thresholds } = options;
    let text = match read_input(path).and_then(|text| with_mesh_files(text, path, Some("scene"), limits)) {
        Ok(text) => text,
        Err(code) => return code,
    };
    let sweep = match Sweep::from_json(&text, max_variants) {
        Ok(sweep) => sweep,
        Err(e) => {
            eprintln!("drape: {} is not a valid sweep:", path.display());
            match e.field_errors() {
                [] => eprintln!("  {e}"),
                errors => errors.iter().for_each(|fe| eprintln!("  {fe}")),
            }
            return ExitCode::from(2);
        }
    };
    if let Err(reason) = thresholds.check(&sweep) {
        eprintln!("drape: {reason}");
        return ExitCode::from(2);
    }
    let runs_at_once = threads.max(1).min(sweep.variants.len() + usize::from(sweep.reference.is_some()));
    let limits = limits.limits(runs_at_once);
    let document: serde_json::Value = serde_json::from_slice(&text).unwrap_or_default();
    let problems = sweep_over_limit(&document, &sweep, &limits);
    if !problems.is_empty() {
        eprintln!("drape: {} exceeds the limits (the flags named lift them):", path.display());
        problems.iter().for_each(|fe| eprintln!("  {fe}"));
        return ExitCode::from(2);
    }
    let compile = |scene: &Scene| {
        admit_for_table(scene, &limits).map_err(|errors| {
            let reasons: Vec<String> = errors.iter().map(ToString::to_string).collect();
            format!("the run exceeds the limits: {}", reasons.join("; "))
        })
    };
    let finished = AtomicUsize::new(0);
    let runs = sweep.variants.len() + usize::from(sweep.reference.is_some());
    let table = progress::follow_sweep(progress, &finished, runs, || {
        run_locally_with(&sweep, threads, &compile, &finished)
    });
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let printed = if csv {
        write_csv(&table, &mut out)
    } else {
        serde_json::to_writer_pretty(&mut out, &table)
            .map_err(std::io::Error::other)
            .and_then(|_| writeln!(out))
    };
    let plotted = match plot {
        Some(file) => {
            std::fs::File::create(file).and_then(|f| write_svg(&table, &path.display().to_string(), f))
        }
        None => Ok(()),
    };
    if let Err(e) = printed.and_then(|_| out.flush()).and(plotted) {
        eprintln!("drape: cannot write the table: {e}");
        return ExitCode::FAILURE;
    }
    let crossings = thresholds.crossings(&table);
    if crossings.is_empty() {
        return ExitCode::SUCCESS;
    }
    eprintln!("drape: {} crosses the thresholds:", path.display());
    crossings.iter().for_each(|line| eprintln!("  {line}"));
    ExitCode::FAILURE
}

fn run(
    path: &Path,
    output: Option<&Path>,
    format: Option<Format>,
    show_progress: bool,
    limits: &LimitArgs,
) -> ExitCode {
    let text = match read_input(path).and_then(|text| with_mesh_files(text, path, None, limits)) {
        Ok(text) => text,
        Err(code) => return code,
    };
    let mut scene = match Scene::from_json(&text) {
        Ok(scene) => scene,
        Err(e) => {
            eprintln!("drape: {} is not a valid scene:", path.display());
            match e.field_errors() {
                [] => eprintln!("  {e}"),
                errors => errors.iter().for_each(|fe| eprintln!("  {fe}")),
            }
            return ExitCode::from(2);
        }
    };
    let format = format.unwrap_or(scene.output.format);
    // A format chosen here over the scene's gets what it can carry; the rest is not recorded.
    let carried = drape::output::carried(format, &scene.output.fields);
    if !carried.omitted.is_empty() {
        let names: Vec<&str> = carried.omitted.iter().map(|f| f.name()).collect();
        eprintln!(
            "drape: {} cannot carry {}; the result leaves them out (json and npz carry every field)",
            format.name(),
            names.join(", ")
        );
        scene.output.fields = carried.fields;
    }
    if let Err(problems) = drape::output::check(format, &scene.output) {
        eprintln!("drape: {} cannot be encoded as {}:", path.display(), format.name());
        problems.iter().for_each(|fe| eprintln!("  {fe}"));
        return ExitCode::from(2);
    }
    let format = format.for_fields(&scene.output.fields);
    let compiled = match limits.limits(1).admit(&scene) {
        Ok(admitted) => admitted.compiled,
        Err(errors) => {
            eprintln!("drape: {} exceeds the limits (the flags named lift them):", path.display());
            errors.iter().for_each(|fe| eprintln!("  {fe}"));
            return ExitCode::from(2);
        }
    };
    let control = Control::new();
    let recording = progress::follow_run(show_progress, &control, compiled.steps, compiled.config.dt, || {
        execute(&compiled, &control)
    });
    if recording.stats.status == Status::Failed {
        let reason = recording.stats.failure.as_deref().unwrap_or("a stage met more than the run may hold");
        eprintln!("drape: the run of {} failed: {reason}", path.display());
        return ExitCode::FAILURE;
    }
    let written = match output {
        Some(file) => std::fs::File::create(file)
            .map(std::io::BufWriter::new)
            .and_then(|mut w| encode(&recording, format, &mut w).and_then(|_| w.flush())),
        None => {
            let mut out = std::io::BufWriter::new(std::io::stdout().lock());
            encode(&recording, format, &mut out)
                .and_then(|_| if format == Format::Json { writeln!(out) } else { Ok(()) })
                .and_then(|_| out.flush())
        }
    };
    if let Err(e) = written {
        eprintln!("drape: cannot write the result: {e}");
        return ExitCode::FAILURE;
    }
    // A diverged run's result is written (up to its last finite frame), and the exit status says
    // it diverged, as `drape run --server` does.
    if recording.stats.status == Status::Diverged {
        let reason = recording.stats.diverged.as_ref().map_or("", |d| d.reason.as_str());
        eprintln!("drape: the run of {} diverged: {reason}", path.display());
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
