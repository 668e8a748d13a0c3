//! The `drape` command: serve the HTTP API, or run a scene from the shell.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use drape::run::{Control, execute};
use drape::scene::Scene;

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
    Run {
        /// The scene, as a JSON file (`-` reads standard input).
        scene: PathBuf,
        /// Write the result here instead of standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Serve(config) => serve(*config),
        Command::Run { scene, output } => run(&scene, output.as_deref()),
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

fn run(path: &std::path::Path, output: Option<&std::path::Path>) -> ExitCode {
    let text = if path.as_os_str() == "-" {
        let mut text = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut text).map(|_| text)
    } else {
        std::fs::read(path)
    };
    let text = match text {
        Ok(text) => text,
        Err(e) => {
            eprintln!("drape: cannot read {}: {e}", path.display());
            return ExitCode::from(2);
        }
    };
    let scene = match Scene::from_json(&text) {
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
    let recording = execute(&scene.compile(), &Control::new());
    let written = match output {
        Some(file) => std::fs::File::create(file)
            .map(std::io::BufWriter::new)
            .and_then(|mut w| drape::output::write_json(&recording, &mut w).and_then(|_| w.flush())),
        None => {
            let mut out = std::io::BufWriter::new(std::io::stdout().lock());
            drape::output::write_json(&recording, &mut out)
                .and_then(|_| writeln!(out))
                .and_then(|_| out.flush())
        }
    };
    match written {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("drape: cannot write the result: {e}");
            ExitCode::FAILURE
        }
    }
}
