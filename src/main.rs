//! The `drape` command: run a scene from the shell.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use drape::output::{Format, encode};
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
    /// Runs a scene and prints its result (or writes it to a file).
    Run {
        /// The scene, as a JSON file (`-` reads standard input).
        scene: PathBuf,
        /// Write the result here instead of standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Encode the result as json, glb, obj, npy, npz or pc2 (default: the scene's
        /// `output.format`). npy becomes npz when the scene asks for more than positions.
        #[arg(short, long)]
        format: Option<Format>,
    },
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Run { scene, output, format } => run(&scene, output.as_deref(), format),
    }
}

fn run(path: &std::path::Path, output: Option<&std::path::Path>, format: Option<Format>) -> ExitCode {
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
    let format = format.unwrap_or(scene.output.format);
    if let Err(problems) = drape::output::check(format, &scene.output) {
        eprintln!("drape: {} cannot be encoded as {}:", path.display(), format.name());
        problems.iter().for_each(|fe| eprintln!("  {fe}"));
        return ExitCode::from(2);
    }
    let format = format.for_fields(&scene.output.fields);
    let recording = execute(&scene.compile(), &Control::new());
    let written = match output {
        Some(file) => std::fs::File::create(file).and_then(|file| encode(&recording, format, file)),
        None => {
            let mut out = std::io::stdout().lock();
            encode(&recording, format, &mut out)
                .and_then(|_| if format == Format::Json { writeln!(out) } else { Ok(()) })
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
