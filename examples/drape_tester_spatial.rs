//! Checks the spatial error estimate on the drape tester against a disk with more rings: the
//! table of `docs/accuracy.md` ("Spatial error").
//!
//! ```sh
//! cargo run --release --example drape_tester_spatial -- RINGS [FACTOR [TIMES]]
//! ```
//!
//! The scene is `examples/drape_tester.json`'s 30 cm cotton disk over its 18 cm support, with
//! implicit Euler at 0.004 s, drag 1 and no `stop_at_rest`, at `RINGS` rings. A reference with
//! `FACTOR` times the rings (default 4) runs once to the last of `TIMES` (seconds, comma
//! separated, multiples of the step; default `0.1,0.2,0.3`), recording a frame at each. Then for
//! each time the run at `RINGS` rings with `error_estimate: "resolution"` runs to it, and the
//! table gives its estimate (largest and root-mean-square), its distance from the reference read
//! at the run's particles ([`MaterialPoints`], linearly in the reference's triangles), their
//! ratio, and the observed order and `reliable` the estimate reports.
//!
//! The reference of 256 rings (197,377 particles) for a run of 64 takes about a quarter of an
//! hour on two cores.

use std::time::Instant;

use drape::run::{Control, EstimateOutcome, Recording, execute};
use drape::scene::{MaterialPoints, Scene};
use glam::DVec3;
use serde_json::{Value, json};

const DT: f64 = 0.004;

/// The drape tester at `rings` rings to `duration`, with the estimate and output given.
fn drape_tester(rings: usize, duration: f64, estimate: &str, output: Value) -> Scene {
    let mut scene: Value =
        serde_json::from_str(include_str!("drape_tester.json")).expect("the example parses");
    let n = 2 * rings + 1;
    scene["bodies"][0]["resolution"] = json!([n, n]);
    scene["duration"] = json!(duration);
    scene["dt"] = json!(DT);
    scene["drag"] = json!(1.0);
    scene["stop_at_rest"] = Value::Null;
    scene["error_estimate"] = json!(estimate);
    scene["output"] = output;
    Scene::from_json(scene.to_string().as_bytes()).expect("the scene is valid")
}

/// The particles' positions in frame `frame` of a recording.
fn positions(recording: &Recording, frame: usize) -> Vec<DVec3> {
    let samples = recording.frames.positions.as_ref().expect("positions are recorded").to_f64();
    let n = recording.particles;
    samples[3 * frame * n..3 * (frame + 1) * n]
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0], p[1], p[2]))
        .collect()
}

fn largest_and_rms(distances: &[f64]) -> (f64, f64) {
    let largest = distances.iter().copied().fold(0.0, f64::max);
    (largest, (distances.iter().map(|d| d * d).sum::<f64>() / distances.len() as f64).sqrt())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let rings: usize = args.first().and_then(|a| a.parse().ok()).expect("usage: RINGS [FACTOR [TIMES]]");
    let factor: usize = args.get(1).map_or(4, |a| a.parse().expect("FACTOR is a whole number"));
    let times: Vec<f64> = args
        .get(2)
        .map_or("0.1,0.2,0.3", String::as_str)
        .split(',')
        .map(|t| t.parse().expect("TIMES are seconds"))
        .collect();
    let end = times.iter().copied().fold(0.0, f64::max);

    let started = Instant::now();
    let frames = json!({"frames": "all", "fps": 1.0 / DT, "fields": ["positions"]});
    let fine = drape_tester(factor * rings, end, "none", frames);
    let reference = execute(&fine.compile(), &Control::new());
    println!(
        "drape tester, {rings} rings against {} ({} particles, {:.0} s), implicit Euler at {DT} s\n",
        factor * rings,
        reference.particles,
        started.elapsed().as_secs_f64()
    );
    println!("| t | estimate max / rms | distance max / rms | ratio max / rms | observed order | reliable |");
    println!("| --- | --- | --- | --- | --- | --- |");
    for t in times {
        let scene = drape_tester(rings, t, "resolution", json!({"frames": "final", "fields": ["positions"]}));
        let run = execute(&scene.compile(), &Control::new());
        let frame =
            reference.frames.times.iter().position(|&s| (s - t).abs() < 0.5 * DT).expect("a frame at t");
        let on_reference = MaterialPoints::between(&scene, &fine);
        let distances: Vec<f64> = on_reference
            .read(&positions(&reference, frame))
            .zip(positions(&run, 0))
            .map(|(a, b)| a.distance(b))
            .collect();
        let (max, rms) = largest_and_rms(&distances);
        let error = run.stats.error.expect("the run has an estimate");
        match error.outcome {
            EstimateOutcome::Estimate { max: e_max, rms: e_rms, observed_order, reliable } => println!(
                "| {t} s | {:.1} / {:.1} mm | {:.1} / {:.1} mm | {:.2} / {:.2} | {} | {} |",
                e_max * 1e3,
                e_rms * 1e3,
                max * 1e3,
                rms * 1e3,
                e_max / max,
                e_rms / rms,
                observed_order.map_or("none".into(), |p| format!("{p:.2}")),
                reliable.map_or("none", |r| if r { "yes" } else { "no" })
            ),
            outcome => println!("| {t} s | {outcome:?} | {:.1} / {:.1} mm | | | |", max * 1e3, rms * 1e3),
        }
    }
}
