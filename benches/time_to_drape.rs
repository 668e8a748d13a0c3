//! Time to drape: how long a user waits for implicit Euler to bring a cloth to rest on a shape.
//!
//! ```sh
//! cargo bench --bench time_to_drape [-- RUNS] [grid|mesh|table]
//! ```
//!
//! Three scenes, each run as `drape run` runs it, at 1/60 s (implicit Euler's default step in
//! contact at 30 frames a second), from release until it is at rest as `stop_at_rest: 0.005`
//! judges it (every particle slower than 5 mm/s, by its velocity and by its displacement over the
//! step, and balanced, its velocity changed by less than 1 % of gravity over the step; checked
//! every 1/30 s, two steps), or to its limit of simulated time:
//!
//! - `grid 128²`: `examples/drape_sphere.json` at 128 × 128 particles, which takes the grid
//!   solver (conjugate gradients preconditioned by the geometric multigrid), up to 20 s;
//! - `mesh 10k`: the same sheet as a 100 × 100-vertex triangle mesh body, which takes the
//!   spring-list solver (conjugate gradients preconditioned by smoothed-aggregation multigrid),
//!   up to 5 s (a step of it costs several of the grid's);
//! - `table 128²`: `examples/tablecloth.json` at 128 × 128 particles with the solver's default
//!   settings, through the grid solver, up to 20 s.
//!
//! Each scene (or the one named) runs `RUNS` times (default 1: the grid run alone is long); the
//! table gives the median wall time, the steps and simulated time to rest, and the
//! conjugate-gradient iterations per step (mean and most), and the fastest particle's speed and
//! the sheet's lowest point when the run stopped. Iteration counts are deterministic; wall times are not.

use std::time::Duration;

use drape::run::{Control, Samples, execute};
use drape::scene::Scene;
use serde_json::{Value, json};

const DT: f64 = 1.0 / 60.0;
const REST_SPEED: f64 = 0.005;
/// The longest a grid scene runs, in simulated seconds: the ball's sheet comes to rest at 1/60 s
/// somewhere between 6 and 20 s (`docs/performance.md`, "Time to drape").
const GRID_MAX_SIMULATED: f64 = 20.0;
/// The longest the mesh scene runs, in simulated seconds.
const MESH_MAX_SIMULATED: f64 = 5.0;

/// `example` with its cloth at 128², stepped at [`DT`] for at most `duration` seconds.
fn at_128(example: &str, duration: f64) -> Value {
    let mut scene: Value = serde_json::from_str(example).expect("the example parses");
    scene["bodies"][0]["resolution"] = json!([128, 128]);
    scene["dt"] = json!(DT);
    scene["duration"] = json!(duration);
    scene
}

fn grid_scene() -> Value {
    at_128(include_str!("../examples/drape_sphere.json"), GRID_MAX_SIMULATED)
}

/// The tablecloth, without the tight tolerance it sets for its small step.
fn table_scene() -> Value {
    let mut scene = at_128(include_str!("../examples/tablecloth.json"), GRID_MAX_SIMULATED);
    scene.as_object_mut().expect("a scene is an object").remove("solver");
    scene
}

/// The sheet of `drape_sphere.json` as a mesh of `n × n` vertices, two triangles per cell.
fn mesh_scene(n: usize) -> Value {
    let mut scene = grid_scene();
    scene["duration"] = json!(MESH_MAX_SIMULATED);
    let mut vertices = Vec::with_capacity(3 * n * n);
    for j in 0..n {
        for i in 0..n {
            let (u, w) = (i as f64 / (n - 1) as f64 - 0.5, j as f64 / (n - 1) as f64 - 0.5);
            vertices.extend([u, 1.0, w]);
        }
    }
    let mut triangles = Vec::with_capacity(6 * (n - 1) * (n - 1));
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            triangles.extend([a, a + n, a + 1, a + 1, a + n, a + n + 1]);
        }
    }
    scene["bodies"] = json!([{
        "type": "mesh", "name": "sheet", "vertices": vertices, "triangles": triangles, "mass": 0.4,
        "springs": {"structural": {"k": 2000, "damping": 2.0}, "bending": {"k": 20, "damping": 0.02}}
    }]);
    scene
}

struct Run {
    wall: Duration,
    steps: u64,
    at_rest: bool,
    mean_iterations: f64,
    most_iterations: usize,
    /// The fastest particle's speed when the run stopped, in m/s.
    fastest_at_end: f64,
    /// The sheet's lowest point when the run stopped, in metres above the floor.
    lowest_at_end: f64,
}

/// The scene as `drape run` runs it to rest: `stop_at_rest` at [`REST_SPEED`], no error
/// estimate, the final positions and velocities recorded.
fn run_to_rest(scene: &Value) -> Run {
    let mut scene = scene.clone();
    scene["stop_at_rest"] = json!(REST_SPEED);
    scene["error_estimate"] = json!("none");
    scene["output"] = json!({"frames": "final", "fields": ["positions", "velocities"]});
    let compiled = Scene::from_json(scene.to_string().as_bytes()).expect("the scene is valid").compile();
    let recording = execute(&compiled, &Control::new());
    let last = |samples: &Option<Samples>| {
        let all = samples.as_ref().expect("the field is recorded").to_f64();
        all[all.len() - 3 * recording.particles..].to_vec()
    };
    let (positions, velocities) = (last(&recording.frames.positions), last(&recording.frames.velocities));
    let stats = recording.stats;
    let solves = stats.linear_solver.expect("implicit Euler reports its solves");
    Run {
        wall: Duration::from_secs_f64(stats.wall_time_s),
        steps: stats.steps,
        at_rest: stats.stopped_at_rest.is_some(),
        mean_iterations: solves.total_iterations as f64 / stats.steps as f64,
        most_iterations: solves.most_iterations,
        fastest_at_end: velocities
            .chunks_exact(3)
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .fold(0.0, f64::max),
        lowest_at_end: positions.chunks_exact(3).map(|p| p[1]).fold(f64::INFINITY, f64::min),
    }
}

fn main() {
    let runs: usize = std::env::args().skip(1).find_map(|a| a.parse().ok()).unwrap_or(1).max(1);
    let only = std::env::args().skip(1).find(|a| ["grid", "mesh", "table"].contains(&a.as_str()));
    println!("time to drape at dt = 1/60 s, rest below {REST_SPEED} m/s, median of {runs} run(s)");
    println!(
        "{:<10} {:>9} {:>6} {:>9} {:>8} {:>10} {:>5} {:>10} {:>10}",
        "scene", "wall s", "steps", "sim s", "rest", "CG/step", "most", "end m/s", "lowest m"
    );
    let scenes = [("grid 128²", grid_scene()), ("mesh 10k", mesh_scene(100)), ("table 128²", table_scene())];
    for (name, scene) in
        scenes.into_iter().filter(|(name, _)| only.as_ref().is_none_or(|o| name.starts_with(o)))
    {
        let mut all: Vec<Run> = (0..runs).map(|_| run_to_rest(&scene)).collect();
        all.sort_by_key(|r| r.wall);
        let r = &all[all.len() / 2];
        println!(
            "{:<10} {:>9.2} {:>6} {:>9.3} {:>8} {:>10.1} {:>5} {:>10.3} {:>10.3}",
            name,
            r.wall.as_secs_f64(),
            r.steps,
            r.steps as f64 * DT,
            if r.at_rest { "yes" } else { "no" },
            r.mean_iterations,
            r.most_iterations,
            r.fastest_at_end,
            r.lowest_at_end
        );
    }
}
