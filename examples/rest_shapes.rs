//! Drapes an example to rest at several implicit Euler steps and compares each rest shape with
//! the smallest step's: the table of `docs/accuracy.md` ("Rest shapes against smaller steps").
//!
//! ```sh
//! cargo run --release --example rest_shapes -- [SCENE.json [N [MAX_TIME [1/DT ...]]]]
//! ```
//!
//! The scene (default `examples/tablecloth.json`) has its first body's resolution set to `N × N`
//! (default 128), its own solver settings dropped, and runs as a user would run it to rest:
//! implicit Euler with `stop_at_rest` 0.005 m/s, to rest or to `MAX_TIME` (default 10 s), without
//! an error estimate. It runs at each step given (default 1/600, 1/1200 and 1/2400 s); the last is
//! the reference.
//!
//! A drape with friction has many rest shapes, one for each way its folds can fall, and which one
//! a run reaches depends on its path: two steps can both be at rest, in equilibrium, and still
//! have their folds a few centimetres apart. So the table gives the distance from the reference
//! twice: particle by particle (largest and root-mean-square), and by what does not depend on
//! where each fold fell: the lowest point, the mean height, and the mean and largest distance
//! from the vertical axis through the origin (where the examples centre their colliders).

use drape::run::{Control, execute};
use drape::scene::Scene;
use glam::DVec3;
use serde_json::{Value, json};

const REST_SPEED: f64 = 0.005;
const DEFAULT_STEPS: [f64; 3] = [600.0, 1200.0, 2400.0];

/// One run: its step, when it came to rest (if it did), its wall time and its final positions.
struct RestShape {
    dt: f64,
    at_rest: Option<f64>,
    wall: f64,
    positions: Vec<DVec3>,
}

/// What the rest shape looks like, whichever way its folds fell: the lowest point, the mean
/// height, and the mean and largest distance from the vertical axis, in metres.
fn measures(positions: &[DVec3]) -> [f64; 4] {
    let n = positions.len() as f64;
    let radius = |p: &DVec3| p.x.hypot(p.z);
    [
        positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min),
        positions.iter().map(|p| p.y).sum::<f64>() / n,
        positions.iter().map(radius).sum::<f64>() / n,
        positions.iter().map(radius).fold(0.0, f64::max),
    ]
}

fn run(scene: &Value, n: usize, max_time: f64, dt: f64) -> RestShape {
    let mut scene = scene.clone();
    let object = scene.as_object_mut().expect("a scene is an object");
    object.remove("solver");
    object.insert("integrator".into(), json!("implicit_euler"));
    object.insert("dt".into(), json!(dt));
    object.insert("duration".into(), json!(max_time));
    object.insert("stop_at_rest".into(), json!(REST_SPEED));
    object.insert("error_estimate".into(), json!("none"));
    object.insert("output".into(), json!({"frames": "final", "fields": ["positions"]}));
    scene["bodies"][0]["resolution"] = json!([n, n]);
    let compiled = Scene::from_json(scene.to_string().as_bytes()).expect("the scene is valid").compile();
    let recording = execute(&compiled, &Control::new());
    let all = recording.frames.positions.as_ref().expect("positions are recorded").to_f64();
    let positions = all[all.len() - 3 * recording.particles..]
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0], p[1], p[2]))
        .collect();
    RestShape { dt, at_rest: recording.stats.stopped_at_rest, wall: recording.stats.wall_time_s, positions }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .cloned()
        .unwrap_or_else(|| format!("{}/examples/tablecloth.json", env!("CARGO_MANIFEST_DIR")));
    let n: usize = args.get(1).map_or(128, |a| a.parse().expect("N is a whole number"));
    let max_time: f64 = args.get(2).map_or(10.0, |a| a.parse().expect("MAX_TIME is in seconds"));
    let steps: Vec<f64> = if args.len() > 3 {
        args[3..].iter().map(|a| a.trim_start_matches("1/").parse().expect("a step is 1/DT")).collect()
    } else {
        DEFAULT_STEPS.to_vec()
    };
    let text = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let scene: Value = serde_json::from_slice(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
    let runs: Vec<RestShape> =
        steps.iter().map(|&per_second| run(&scene, n, max_time, 1.0 / per_second)).collect();
    let reference = runs.last().expect("at least one step");
    let reference_measures = measures(&reference.positions);
    println!(
        "| dt | at rest | wall | from the reference (largest, rms) | lowest point | mean height | mean radius | widest |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for run in &runs {
        let distances: Vec<f64> =
            run.positions.iter().zip(&reference.positions).map(|(a, b)| (*a - *b).length()).collect();
        let largest = distances.iter().copied().fold(0.0, f64::max);
        let rms = (distances.iter().map(|d| d * d).sum::<f64>() / distances.len() as f64).sqrt();
        let at_rest = run.at_rest.map_or(format!("no, by {max_time} s"), |t| format!("{t:.2} s"));
        let cells: Vec<String> = measures(&run.positions)
            .iter()
            .zip(reference_measures)
            .map(|(m, r)| format!("{:.1} mm ({:+.1})", 1e3 * m, 1e3 * (m - r)))
            .collect();
        println!(
            "| 1/{:.0} s | {at_rest} | {:.1} s | {:.1} mm, {:.1} mm | {} |",
            1.0 / run.dt,
            run.wall,
            1e3 * largest,
            1e3 * rms,
            cells.join(" | ")
        );
    }
}
