//! Steps scenes in contact with implicit Euler at frame-size steps and compares each end with a
//! small-step reference: the table of `docs/decisions.md` ("Implicit Euler's default step in
//! contact is half the frame interval").
//!
//! ```sh
//! cargo run --release --example contact_steps -- [SCENE.json ...]
//! ```
//!
//! Each scene (default: the examples that drape a cloth or drop a body onto colliders) runs to
//! its `duration` with implicit Euler at 1/1200 s, the reference, and at 1/30, 1/60 and 1/120 s
//! with the error estimate a scene gets by default. For each step the table gives the wall time,
//! the distance of the final positions from the reference's (largest and root-mean-square), the
//! estimate the run reports, the largest spring strain of any frame (60 a second) beside the
//! reference's, the fastest particle at the end, and the particles' mean height beside the
//! reference's (a drape that slid off its collider, or a body that collapsed, shows there
//! first).

use drape::run::{Control, EstimateOutcome, Recording, execute};
use drape::scene::Scene;
use glam::DVec3;
use serde_json::{Value, json};

const REFERENCE_DT: f64 = 1.0 / 1200.0;
const FRAMES_PER_SECOND: [f64; 3] = [30.0, 60.0, 120.0];
const DEFAULT_SCENES: [&str; 5] =
    ["drape_sphere.json", "drape_mesh_sphere.json", "drape_torus.json", "tablecloth.json", "jelly_cube.json"];

/// The final positions and velocities of `scene` run at `dt` with `estimate`.
fn run(scene: &Value, dt: f64, estimate: &str) -> (Vec<DVec3>, Vec<DVec3>, Recording) {
    let mut scene = scene.clone();
    scene["integrator"] = json!("implicit_euler");
    scene["dt"] = json!(dt);
    scene["stop_at_rest"] = Value::Null;
    scene["error_estimate"] = json!(estimate);
    scene["output"] = json!({"fps": 60, "frames": "all", "fields": ["positions", "velocities", "strain"]});
    let compiled = Scene::from_json(scene.to_string().as_bytes()).expect("the scene is valid").compile();
    let recording = execute(&compiled, &Control::new());
    let last = |samples: Option<&drape::run::Samples>| {
        let all = samples.expect("the field is recorded").to_f64();
        all[all.len() - 3 * recording.particles..]
            .chunks_exact(3)
            .map(|p| DVec3::new(p[0], p[1], p[2]))
            .collect::<Vec<_>>()
    };
    (last(recording.frames.positions.as_ref()), last(recording.frames.velocities.as_ref()), recording)
}

fn largest_and_rms(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let largest = values.clone().fold(0.0, f64::max);
    let (sum, count) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (largest, (sum / count as f64).sqrt())
}

/// The largest spring strain `(l - L) / L` of any recorded frame (60 a second).
fn largest_strain(recording: &Recording) -> f64 {
    recording.frames.strain.as_ref().expect("strains are recorded").iter().copied().fold(0.0, f64::max)
}

fn mean_height(positions: &[DVec3]) -> f64 {
    positions.iter().map(|p| p.y).sum::<f64>() / positions.len() as f64
}

fn main() {
    let named: Vec<String> = std::env::args().skip(1).collect();
    let paths: Vec<String> = if named.is_empty() {
        DEFAULT_SCENES.iter().map(|name| format!("{}/examples/{name}", env!("CARGO_MANIFEST_DIR"))).collect()
    } else {
        named
    };
    println!(
        "| scene | dt | wall | distance from 1/1200 s (largest, rms) | estimate (largest, rms) | largest strain (reference) | fastest at the end | mean height (reference) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for path in paths {
        let text = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let scene: Value = serde_json::from_slice(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
        let name = path.rsplit('/').next().unwrap_or(&path);
        let (reference, _, reference_run) = run(&scene, REFERENCE_DT, "none");
        for fps in FRAMES_PER_SECOND {
            let (x, v, recording) = run(&scene, 1.0 / fps, "richardson");
            let (far, rms) = largest_and_rms(x.iter().zip(&reference).map(|(a, b)| (*a - *b).length()));
            let (fastest, _) = largest_and_rms(v.iter().map(|v| v.length()));
            let estimate = match recording.stats.error.as_ref().map(|e| &e.outcome) {
                Some(&EstimateOutcome::Estimate { max, rms, .. }) => {
                    format!("{:.0} mm, {:.0} mm", 1e3 * max, 1e3 * rms)
                }
                _ => "none".to_string(),
            };
            println!(
                "| {name} | 1/{fps} s | {:.2} s | {:.0} mm, {:.0} mm | {estimate} | {:.2} ({:.2}) | {:.3} m/s | {:.3} m ({:.3} m) |",
                recording.stats.wall_time_s,
                1e3 * far,
                1e3 * rms,
                largest_strain(&recording),
                largest_strain(&reference_run),
                fastest,
                mean_height(&x),
                mean_height(&reference)
            );
        }
    }
}
