//! The runner: frame schedules, fields, divergence, rest and cancellation, and the JSON result.

use serde_json::{Value, json};

use super::*;
use crate::scene::Scene;
use crate::solver::HOLD_STIFFNESS;

fn run(scene: Value) -> Recording {
    let scene = Scene::from_json(scene.to_string().as_bytes()).unwrap();
    execute(&scene.compile(), &Control::new())
}

fn small_cloth() -> Value {
    json!({"type": "cloth", "resolution": [6, 6], "pin": [[0, 0], [5, 0]]})
}

#[test]
fn frames_fall_every_frame_interval_and_the_last_on_the_duration() {
    let r = run(json!({"duration": 1.05, "dt": 1e-3, "bodies": [small_cloth()], "output": {"fps": 10}}));
    assert_eq!(r.stats.status, Status::Succeeded);
    // Closed form: 1.05 s / 1e-3 s = 1050 steps.
    assert_eq!(r.stats.steps, 1050);
    let expected: Vec<f64> = (0..=10).map(|k| k as f64 * 0.1).chain([1.05]).collect();
    assert_eq!(r.frames.len(), expected.len());
    for (t, e) in r.frames.times.iter().zip(&expected) {
        assert!((t - e).abs() < 1e-12, "{t} vs {e}");
    }
    assert_eq!(*r.frames.times.last().unwrap(), 1.05);
    assert!(r.has_final);
    // Closed form: 12 frames (t = 0, 0.1, ..., 1.0 and the final 1.05) of 6 × 6 particles, 3 each.
    assert_eq!(r.frames.positions.as_ref().unwrap().len(), 12 * 36 * 3);
}

#[test]
fn final_and_none_keep_one_frame_and_no_frame() {
    let base = |frames| json!({"duration": 0.1, "dt": 1e-3, "bodies": [small_cloth()], "output": {"frames": frames}});
    let last = run(base("final"));
    assert_eq!((last.frames.times.as_slice(), last.has_final), ([0.1].as_slice(), true));
    let none = run(base("none"));
    assert!(none.frames.is_empty() && !none.has_final);
    assert_eq!(none.stats.steps, 100); // 0.1 s / 1e-3 s
    assert_eq!(none.stats.energy.map(|e| e.kinetic > 0.0), Some(true));
}

#[test]
fn only_the_fields_asked_for_are_recorded() {
    let r = run(json!({"duration": 0.1, "dt": 1e-3, "bodies": [small_cloth()],
        "output": {"frames": "final", "fields": ["velocities", "normals", "energy", "strain"]}}));
    let f = &r.frames;
    assert!(f.positions.is_none());
    assert_eq!(f.velocities.as_ref().map(Samples::len), Some(36 * 3));
    assert_eq!(f.normals.as_ref().map(Samples::len), Some(36 * 3));
    assert_eq!(f.strain.as_ref().map(Vec::len), Some(r.springs));
    assert_eq!(f.energy.as_ref().unwrap()[0], r.stats.energy.unwrap());
    assert!(r.stats.stages.contains(&"normals"));
    let normals = f.normals.as_ref().unwrap().to_f64();
    for n in normals.chunks(3) {
        assert!(((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-12);
    }
    let plain = run(json!({"duration": 0.1, "dt": 1e-3, "bodies": [small_cloth()]}));
    assert!(!plain.stats.stages.contains(&"normals"));
}

#[test]
fn a_diverged_run_keeps_its_finite_frames_and_says_why() {
    let r = run(json!({"duration": 1.0, "dt": 0.01, "integrator": "symplectic_euler",
        "bodies": [{"type": "cloth", "resolution": [5, 5], "mass": 0.001, "pin": [[0, 0]],
                    "springs": {"structural": {"k": 1e5}}}],
        "output": {"fps": 100, "fields": ["positions", "velocities"]}}));
    assert_eq!(r.stats.status, Status::Diverged);
    let d = r.stats.diverged.as_ref().unwrap();
    assert!(d.step >= 1 && d.step < 100 && (d.t - d.step as f64 * 0.01).abs() < 1e-12, "{d:?}");
    let suggested = d.suggested_dt.unwrap();
    assert!(suggested < r.stats.stable_dt.unwrap() && suggested < 0.01);
    assert!(!r.has_final && r.stats.energy.is_none());
    assert!(r.frames.len() <= d.step as usize);
    for samples in [&r.frames.positions, &r.frames.velocities] {
        assert!(samples.as_ref().unwrap().to_f64().iter().all(|x| x.is_finite()));
    }
}

#[test]
fn a_run_stops_at_rest_when_asked() {
    let r = run(json!({"duration": 20.0, "dt": 0.01, "integrator": "implicit_euler", "stop_at_rest": 1e-3,
        "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [0, -1, 0], "count": 5, "pin": [0],
                    "spring": {"k": 100, "damping": 1}}],
        "output": {"fps": 1}}));
    assert_eq!(r.stats.status, Status::Succeeded);
    let t = r.stats.stopped_at_rest.expect("the damped chain comes to rest");
    assert!(t < 20.0 && t > 0.0);
    assert_eq!(*r.frames.times.last().unwrap(), t);
    let v = r.frames.positions.as_ref().unwrap();
    assert_eq!(v.len(), r.frames.len() * 15);
}

#[test]
fn a_cancelled_run_stops_before_its_end() {
    let scene = Scene::from_json(
        json!({"duration": 10.0, "dt": 1e-3, "bodies": [small_cloth()]}).to_string().as_bytes(),
    )
    .unwrap();
    let control = Control::new();
    control.cancel();
    let r = execute(&scene.compile(), &control);
    assert_eq!(r.stats.status, Status::Cancelled);
    assert_eq!(r.stats.steps, 0);
    assert_eq!(control.steps_done(), 0);
    assert!(!r.has_final);
}

#[test]
fn progress_reaches_the_step_count() {
    let scene = Scene::from_json(
        json!({"duration": 0.5, "dt": 1e-3, "bodies": [small_cloth()]}).to_string().as_bytes(),
    )
    .unwrap();
    let control = Control::new();
    let r = execute(&scene.compile(), &control);
    assert_eq!(control.steps_done(), r.stats.steps);
    assert_eq!(r.stats.steps, 500); // 0.5 s / 1e-3 s
}

#[test]
fn the_json_result_carries_the_runs_numbers_exactly() {
    for precision in ["f32", "f64"] {
        let r = run(json!({"duration": 0.1, "dt": 1e-3, "precision": precision, "bodies": [small_cloth()],
            "output": {"fps": 20, "fields": ["positions", "energy"]}}));
        let mut bytes = Vec::new();
        crate::output::write_json(&r, &mut bytes).unwrap();
        let v: Value = serde_json::from_slice(&bytes).unwrap();
        // Closed form for a 6 × 6 cloth: 36 particles; 5 × 5 cells of 2 triangles, 3 indices each.
        assert_eq!(v["mesh"]["particles"], 36);
        assert_eq!(v["mesh"]["triangles"].as_array().unwrap().len(), 3 * 50);
        assert_eq!(
            v["mesh"]["bodies"][0],
            json!({"name": "cloth0", "type": "cloth", "offset": 0, "count": 36})
        );
        let frames = v["frames"].as_array().unwrap();
        assert_eq!(frames.len(), 3);
        assert_eq!(v["final"], frames[2]);
        assert_eq!(v["stats"]["precision"], precision);
        assert_eq!(v["stats"]["stages"], json!(["gravity", "springs"]));
        let written: Vec<f64> = frames
            .iter()
            .flat_map(|f| f["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
            .collect();
        match r.frames.positions.as_ref().unwrap() {
            Samples::F32(values) => {
                assert!(values.iter().zip(&written).all(|(a, b)| a.to_bits() == (*b as f32).to_bits()))
            }
            Samples::F64(values) => {
                assert!(values.iter().zip(&written).all(|(a, b)| a.to_bits() == b.to_bits()))
            }
        }
        // Closed form: 3 frames (t = 0, 0.05, 0.1 at 20 fps) of 36 particles, 3 coordinates each.
        assert_eq!(written.len(), 3 * 36 * 3);
    }
}

/// Ten masses of 10 g hang from a pin on springs of k = 500 N/m, starting horizontal, so that
/// they swing and stretch: a nonlinear motion.
fn swinging_chain(integrator: &str, dt: f64, estimate: &str) -> Value {
    json!({"duration": 0.5, "dt": dt, "integrator": integrator, "error_estimate": estimate,
        "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [1, 0, 0], "count": 11, "mass": 0.11,
                    "spring": {"k": 500}, "pin": [0]}],
        "output": {"frames": "final"}})
}

fn final_positions(r: &Recording) -> Vec<f64> {
    r.frames.positions.as_ref().unwrap().to_f64()
}

fn estimate_of(r: &Recording) -> (f64, f64) {
    match &r.stats.error.as_ref().expect("an estimate").outcome {
        EstimateOutcome::Estimate { max, rms, .. } => (*max, *rms),
        EstimateOutcome::Unavailable { reason } => panic!("no estimate: {reason}"),
    }
}

#[test]
fn the_richardson_estimate_is_within_a_factor_two_of_the_true_error() {
    let reference = run(swinging_chain("rk4", 1e-3 / 64.0, "none"));
    let truth = final_positions(&reference);
    for integrator in ["symplectic_euler", "verlet", "rk4"] {
        for dt in [2e-3, 1e-3] {
            let r = run(swinging_chain(integrator, dt, "richardson"));
            let errors: Vec<f64> = final_positions(&r)
                .chunks(3)
                .zip(truth.chunks(3))
                .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
                .collect();
            let true_max = errors.iter().copied().fold(0.0, f64::max);
            let (max, _) = estimate_of(&r);
            let ratio = max / true_max;
            assert!(
                (0.5..=2.0).contains(&ratio),
                "{integrator} at dt {dt}: estimate {max:.3e}, true {true_max:.3e}"
            );
            let error = r.stats.error.as_ref().unwrap();
            assert_eq!(error.order, f64::from(r.stats.integrator.order()));
            assert!(error.extra_wall_time_s > 0.0);
        }
    }
}

#[test]
fn three_runs_measure_the_order() {
    // The methods' textbook orders of accuracy (Hairer, Lubich & Wanner, Geometric Numerical
    // Integration, for symplectic Euler and Störmer–Verlet; RK4 is fourth order by construction).
    for (integrator, order) in [("symplectic_euler", 1.0), ("verlet", 2.0), ("rk4", 4.0)] {
        let r = run(swinging_chain(integrator, 1e-3, "richardson3"));
        let EstimateOutcome::Estimate { observed_order, reliable, .. } = r.stats.error.unwrap().outcome
        else {
            panic!("no estimate")
        };
        let observed = observed_order.unwrap();
        assert!((observed - order).abs() < 0.3, "{integrator}: observed order {observed}");
        assert_eq!(reliable, Some(true));
    }
}

/// The largest distance between the final positions of two runs, in metres.
fn final_distance(a: &Recording, b: &Recording) -> f64 {
    largest_difference(&final_positions(a), &final_positions(b))
}

#[test]
fn a_run_near_its_stability_limit_is_estimated_at_half_its_step() {
    // Just inside the stability bound at dt, so twice that step is outside it: the companions
    // are taken at dt/2 (and dt/4), and the estimate still tracks the true error.
    let scene =
        Scene::from_json(swinging_chain("symplectic_euler", 1e-3, "richardson").to_string().as_bytes())
            .unwrap();
    let bound = crate::solver::stable_step(&scene.compile().model, 0.0).unwrap();
    let reference = run(swinging_chain("rk4", bound / 256.0, "none"));
    for (integrator, factor) in
        [("symplectic_euler", 0.9), ("verlet", 0.9), ("rk4", 0.9 * std::f64::consts::SQRT_2)]
    {
        let dt = factor * bound;
        for method in ["richardson", "richardson3"] {
            let r = run(swinging_chain(integrator, dt, method));
            assert_eq!(r.stats.status, Status::Succeeded);
            let error = r.stats.error.as_ref().unwrap();
            assert_eq!(error.companion_step, Some(CompanionStep::Halved), "{integrator} {method}");
            let (max, _) = estimate_of(&r);
            let true_max = final_distance(&r, &reference);
            let ratio = max / true_max;
            assert!(
                (0.5..=2.0).contains(&ratio),
                "{integrator} {method} at dt {dt:.3e}: estimate {max:.3e}, true {true_max:.3e}"
            );
            assert!(error.extra_wall_time_s > 0.0);
        }
    }
    // Well inside the bound, the companions take the cheaper doubled step.
    let r = run(swinging_chain("symplectic_euler", 0.25 * bound, "richardson"));
    assert_eq!(r.stats.error.unwrap().companion_step, Some(CompanionStep::Doubled));
}

#[test]
fn one_step_is_estimated_at_half_its_step_and_none_asks_for_nothing() {
    // One step has no coarser companion: the estimate comes from companions at half the step.
    let one = run(json!({"duration": 0.01, "dt": 0.01, "bodies": [small_cloth()]}));
    let error = one.stats.error.unwrap();
    assert_eq!(error.companion_step, Some(CompanionStep::Halved));
    assert!(matches!(error.outcome, EstimateOutcome::Estimate { max, .. } if max > 0.0 && max.is_finite()));
    let none =
        run(json!({"duration": 0.01, "dt": 0.001, "error_estimate": "none", "bodies": [small_cloth()]}));
    assert_eq!(none.stats.error, None);
}

/// A scene whose every implicit solve runs far longer than a test waits: a tolerance no residual
/// meets and 2⁴⁰ iterations, far past what a scene may ask for, set on the compiled scene: the
/// solver must stop when asked whatever its settings. Such a solve does end once conjugate
/// gradients' updated residual underflows, which a well-preconditioned chain reaches within the
/// test's wait; the bodies below take many times as long.
fn endless_solve(body: Value, estimate: &str) -> Compiled {
    let scene = json!({"duration": 1.0, "dt": 0.005, "integrator": "implicit_euler",
        "error_estimate": estimate, "bodies": [body]});
    let mut compiled = Scene::from_json(scene.to_string().as_bytes()).unwrap().compile();
    compiled.config.settings.tolerance = 1e-300;
    compiled.config.settings.reduction = 0.0;
    compiled.config.settings.max_iterations = 1 << 40;
    compiled
}

/// Cancels `control` once the run has been inside its first step for a while, and returns how
/// long the run took to end after the cancellation, with its recording. The first solve is still
/// running when the run is cancelled, so a run that ends with no step taken was stopped part-way
/// through it; the deadline only turns a cancellation that never arrives into a failure rather
/// than a hang, and how soon the run ends is printed, not asserted, since a loaded machine can
/// delay it by any amount.
fn cancel_mid_solve(compiled: &Compiled) -> (std::time::Duration, Recording) {
    let control = Control::new();
    std::thread::scope(|s| {
        let run = s.spawn(|| execute(compiled, &control));
        // Far longer than a step of these scenes takes without the endless solve.
        std::thread::sleep(std::time::Duration::from_millis(300));
        assert!(!run.is_finished(), "the first solve is still running");
        assert_eq!(control.steps_done(), 0);
        let cancelled = Instant::now();
        control.cancel();
        let deadline = cancelled + std::time::Duration::from_secs(30);
        while !run.is_finished() {
            assert!(Instant::now() < deadline, "the run did not stop within 30 s of its cancellation");
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        (cancelled.elapsed(), run.join().unwrap())
    })
}

#[test]
fn a_cancellation_stops_a_grid_clothes_linear_solve_part_way() {
    let cloth = json!({"type": "cloth", "resolution": [256, 256], "pin": [[0, 0], [255, 0]]});
    let (stopped_in, r) = cancel_mid_solve(&endless_solve(cloth, "none"));
    assert_eq!((r.stats.status, r.stats.steps), (Status::Cancelled, 0));
    assert_eq!(r.frames.times, [0.0], "the frame at t = 0 and no other");
    eprintln!("stopped {stopped_in:?} after the cancellation");
}

#[test]
fn a_cancellation_stops_a_spring_list_solve_and_the_error_estimates_companions() {
    // A 27,000-particle lattice, whose first solve runs many times the test's wait before its
    // residual underflows, where a chain's aggregation hierarchy solves it almost exactly.
    let lattice = json!({"type": "lattice", "resolution": [30, 30, 30], "pin": [[0, 0, 0]]});
    let (stopped_in, r) = cancel_mid_solve(&endless_solve(lattice, "richardson"));
    assert_eq!((r.stats.status, r.stats.steps), (Status::Cancelled, 0));
    eprintln!("stopped {stopped_in:?} after the cancellation");
}

#[test]
fn an_interrupt_that_is_never_raised_changes_no_bit() {
    let scene = json!({"duration": 0.05, "dt": 0.005, "integrator": "implicit_euler",
        "bodies": [{"type": "cloth", "resolution": [12, 12], "pin": [[0, 0], [11, 0]]}]});
    let compiled = Scene::from_json(scene.to_string().as_bytes()).unwrap().compile();
    let mut plain = Simulation::<f64>::new(&compiled.model, &compiled.config);
    let mut watched = Simulation::<f64>::new(&compiled.model, &compiled.config);
    watched.set_interrupt(crate::solver::Interrupt::new());
    for _ in 0..10 {
        plain.step().unwrap();
        watched.step().unwrap();
    }
    let bits = |s: &Simulation<f64>| {
        s.state().positions.iter().flat_map(|p| p.to_array()).map(f64::to_bits).collect::<Vec<_>>()
    };
    assert_eq!(bits(&plain), bits(&watched));
    let raised = crate::solver::Interrupt::new();
    watched.set_interrupt(raised.clone());
    raised.raise();
    let before = bits(&watched);
    assert_eq!(watched.step(), Err(StepError::Interrupted));
    assert_eq!((watched.steps_taken(), bits(&watched)), (10, before), "an interrupted step changes nothing");
}

#[test]
fn a_run_whose_self_collision_meets_more_pairs_than_its_cap_ends_failed_with_the_reason() {
    // 20 × 20 particles 0.053 m apart in cells of 0.2 m: thousands of candidate pairs at rest.
    let scene = json!({"duration": 0.1, "dt": 1e-3, "error_estimate": "none",
        "bodies": [{"type": "cloth", "resolution": [20, 20], "size": [1, 1]}],
        "self_collision": {"thickness": 0.1}});
    let scene = Scene::from_json(scene.to_string().as_bytes()).unwrap();
    let mut compiled = scene.compile();
    let met = crate::solver::candidate_pairs(&compiled.model, 0.1);
    assert!(met > 5000, "{met} pairs");
    compiled.config.max_self_collision_pairs = 1000;
    for estimate in [ErrorEstimateName::None, ErrorEstimateName::Richardson] {
        compiled.error_estimate = estimate;
        let r = execute(&compiled, &Control::new());
        assert_eq!(r.stats.status, Status::Failed, "{estimate:?}");
        // The step that met them did not complete.
        assert_eq!(r.stats.steps, 0);
        let failure = r.stats.failure.as_deref().unwrap();
        assert!(
            failure.contains(&format!("met {met} candidate pairs")) && failure.contains("the 1000"),
            "{failure}"
        );
        assert!(!r.has_final && r.stats.energy.is_none());
    }
    // With room for them, the run goes on past its first step (a thickness above the spacing
    // throws the cloth apart, so it ends diverged).
    compiled.config.max_self_collision_pairs = 4 * met as usize;
    compiled.error_estimate = ErrorEstimateName::None;
    let r = execute(&compiled, &Control::new());
    assert!(
        r.stats.status != Status::Failed && r.stats.steps > 1,
        "{:?} at {}",
        r.stats.status,
        r.stats.steps
    );
}

#[test]
fn frames_finer_than_the_step_are_kept_once() {
    let r = run(json!({"duration": 0.01, "dt": 1e-3, "bodies": [small_cloth()], "output": {"fps": 1e6}}));
    assert_eq!(r.frames.times.len(), 11);
}

/// The last recorded frame's positions.
fn last_positions(r: &Recording) -> Vec<f64> {
    let all = r.frames.positions.as_ref().unwrap().to_f64();
    all[all.len() - 3 * r.particles..].to_vec()
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn a_cloth_released_from_rest_does_not_stop_before_it_falls() {
    // A cloth hanging from two corners, released still. At 100 frames a second rest is checked
    // every 10 steps: at the first check (t = 0.01 s) every particle is slower than 0.2 m/s
    // (9.81 m/s² × 0.01 s ≈ 0.098 m/s), but each still gains g per second: it has not begun.
    let scene = |stop: Option<f64>| {
        json!({"duration": 10.0, "dt": 1e-3, "integrator": "implicit_euler", "drag": 2.0,
            "stop_at_rest": stop, "bodies": [small_cloth()], "error_estimate": "none",
            "output": {"fps": 100, "fields": ["positions"]}})
    };
    let r = run(scene(Some(0.2)));
    assert_eq!(r.stats.status, Status::Succeeded);
    let t = r.stats.stopped_at_rest.expect("the damped cloth settles within 10 s");
    assert!(t > 0.5, "stopped at {t} s, before the cloth had swung down");
    assert_eq!(*r.frames.times.last().unwrap(), t);
    assert_eq!(r.stats.steps, (t / 1e-3).round() as u64);
    // Settled: where a run to the end puts it, within a few centimetres (its speed is under
    // 0.2 m/s and decaying at the drag's rate), and with little kinetic energy.
    let full = run(scene(None));
    assert_eq!(full.stats.stopped_at_rest, None);
    let off = largest_difference(&last_positions(&r), &last_positions(&full));
    assert!(off < 0.05, "{off} m from where the cloth ends up");
    let energy = r.stats.energy.unwrap();
    // 0.5 kg, every particle under 0.2 m/s: at most ½ · 0.5 · 0.2² = 0.01 J.
    assert!(energy.kinetic < 0.01, "{energy:?}");
}

#[test]
fn a_cloth_falling_onto_the_floor_stops_once_it_lies_there() {
    // Dropped from 0.3 m onto the floor plane (sticking friction): the fall takes
    // √(2 · 0.3 / 9.81) ≈ 0.25 s; the cloth stops once it lies flat and still, well before 5 s.
    let scene = |stop: Option<f64>| {
        json!({"duration": 5.0, "dt": 2e-3, "integrator": "implicit_euler", "stop_at_rest": stop,
            "bodies": [{"type": "cloth", "resolution": [6, 6], "center": [0, 0.3, 0]}],
            "colliders": [{"type": "plane", "friction": 1.0}], "error_estimate": "none",
            "output": {"fps": 50, "fields": ["positions"]}})
    };
    let r = run(scene(Some(1e-3)));
    let t = r.stats.stopped_at_rest.expect("the cloth comes to rest on the floor");
    assert!(t > 0.25 && t < 5.0, "stopped at {t} s");
    let full = run(scene(None));
    let off = largest_difference(&last_positions(&r), &last_positions(&full));
    assert!(off < 1e-3, "{off} m from where the cloth ends up");
    assert!(last_positions(&r).chunks(3).all(|p| p[1].abs() < 1e-9), "the cloth lies on the floor");
}

#[test]
fn a_cloth_held_by_a_collider_is_at_rest() {
    // Flat at rest length on the floor from the start: gravity pushes into the plane and the
    // projection takes that away every step, so no velocity changes and the run stops at its
    // first check (33 steps, a thirtieth of a second), though the force sum on each particle is
    // its weight.
    let r = run(json!({"duration": 1.0, "dt": 1e-3, "stop_at_rest": 1e-3,
        "bodies": [{"type": "cloth", "resolution": [6, 6], "center": [0, 0, 0]}],
        "colliders": [{"type": "plane", "friction": 1.0}], "error_estimate": "none",
        "output": {"frames": "final"}}));
    assert_eq!((r.stats.stopped_at_rest, r.stats.steps), (Some(0.033), 33));
    // Draped over a round table onto the floor (examples/tablecloth.json, run longer): the
    // stretched springs pull and the table pushes back. It stops once settled, where a run to
    // the end leaves it. (The drape over a ball of examples/drape_sphere.json does not settle:
    // it slides off the ball over seconds, at small steps too.)
    let scene = |stop: Option<f64>| {
        let mut scene: Value = serde_json::from_str(include_str!("../../examples/tablecloth.json")).unwrap();
        scene["duration"] = json!(6.0);
        scene["stop_at_rest"] = json!(stop);
        scene["error_estimate"] = json!("none");
        scene
    };
    let r = run(scene(Some(0.01)));
    let t = r.stats.stopped_at_rest.expect("the draped cloth comes to rest");
    assert!(t > 0.5 && t < 6.0, "stopped at {t} s");
    let full = run(scene(None));
    let off = largest_difference(&last_positions(&r), &last_positions(&full));
    assert!(off < 0.02, "{off} m from where the cloth ends up");
}

/// Two particles released at rest on a plane tilted by `degrees` with friction 0.5, stepped by
/// implicit Euler at `dt` for two seconds, checked for rest (`stop_at_rest`) as `drape run` checks.
fn on_a_slope(degrees: f64, dt: f64, stop_at_rest: Option<f64>) -> Recording {
    let (sin, cos) = degrees.to_radians().sin_cos();
    run(json!({"duration": 2.0, "dt": dt, "integrator": "implicit_euler", "stop_at_rest": stop_at_rest,
        "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [0, 0, 0.1], "count": 2}],
        "colliders": [{"type": "plane", "point": [0, 0, 0], "normal": [-sin, cos, 0], "friction": 0.5}],
        "error_estimate": "none", "output": {"frames": "final"}}))
}

#[test]
fn static_friction_holds_a_particle_on_a_slope_at_any_step() {
    // tan 20° < 0.5: Coulomb's law holds the particles. Only the first step, before they stick,
    // slides them, by `dt² g sin 20°` down the slope; from then on each is held to the point where
    // it stuck by its anchor spring, of stiffness `κ m / dt²`, which stretches by `1 / κ` of that
    // slide to balance the pull down the slope (to the solve's tolerance), and they stay put: at
    // rest at the first check (after a thirtieth of a second: 2 steps and 33 steps), by their
    // displacement as by their velocity, and where the anchor spring holds them after 2 s.
    let g = 9.81;
    for (dt, first_check) in [(1.0 / 60.0, 2), (1e-3, 33)] {
        let at_rest = on_a_slope(20.0, dt, Some(0.005));
        let stopped = (at_rest.stats.stopped_at_rest, at_rest.stats.steps);
        assert_eq!(stopped, (Some(first_check as f64 * dt), first_check), "dt {dt}");
        let held = on_a_slope(20.0, dt, None);
        let first_step = dt * dt * g * 20f64.to_radians().sin();
        let expected = first_step * (1.0 + 1.0 / HOLD_STIFFNESS);
        let slid = last_positions(&held)[0].hypot(last_positions(&held)[1]);
        assert!((slid - expected).abs() < 1e-6 * expected, "dt {dt}: slid {slid} m, not {expected}");
    }
}

#[test]
fn a_particle_on_a_slope_steeper_than_friction_slides_at_coulombs_acceleration() {
    // tan 40° > 0.5: the particles slide at a = g (sin 40° - 0.5 cos 40°). From the second step the
    // kinetic friction of the last is carried into the step, so the positions follow that
    // acceleration; the first step slides by g sin 40° alone, `0.5 g cos 40° dt²` further.
    let (g, dt) = (9.81, 1.0 / 60.0);
    let (sin, cos) = 40f64.to_radians().sin_cos();
    let a = g * (sin - 0.5 * cos);
    let slid = on_a_slope(40.0, dt, Some(0.005));
    assert_eq!(slid.stats.stopped_at_rest, None);
    let steps = slid.stats.steps as f64;
    let expected = a * dt * dt * steps * (steps + 1.0) / 2.0 + 0.5 * g * cos * dt * dt;
    let along = last_positions(&slid)[0].hypot(last_positions(&slid)[1]);
    assert!((along - expected).abs() < 1e-9, "slid {along} m down the slope, not {expected}");
}

#[test]
fn a_particle_that_moves_with_no_velocity_is_not_at_rest() {
    // Rest is judged by each particle's displacement over the step as well as its velocity.
    let compiled = Scene::from_json(
        json!({"duration": 1.0, "dt": 0.01, "gravity": [0, 0, 0], "bodies": [{"type": "chain", "count": 2}]})
            .to_string()
            .as_bytes(),
    )
    .expect("a valid scene")
    .compile();
    let simulation = Simulation::<f64>::new(&compiled.model, &compiled.config);
    let rest = Rest::new(&compiled, 0.005, &simulation);
    let mut state = simulation.state().clone();
    let pinned = &compiled.model.pinned;
    assert!(rest.holds(&state, 0.01, pinned));
    // 4 mm/s by its displacement is below the limit, 6 mm/s is not.
    for (speed, holds) in [(0.004, true), (0.006, false)] {
        let moved = simulation.state().positions.get(1) + Vec3::new(speed * 0.01, 0.0, 0.0);
        state.positions.set(1, moved);
        assert_eq!(rest.holds(&state, 0.01, pinned), holds, "{speed} m/s");
    }
}

#[test]
fn a_mesh_collider_is_recorded_with_its_triangles() {
    let r = run(json!({
        "duration": 0.01, "dt": 0.005, "error_estimate": "none",
        "bodies": [{"type": "chain", "count": 2}],
        "colliders": [{"type": "plane"}, {"type": "mesh", "vertices": [0, 0, 0, 1, 0, 0, 0, 0, 1], "triangles": [0, 2, 1]}],
    }));
    assert_eq!(r.colliders.len(), 2);
    assert_eq!(r.colliders[1].name, "collider:1");
    assert_eq!(
        r.colliders[1].shape,
        ColliderShape::Mesh {
            vertices: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            triangles: vec![[0, 2, 1]]
        }
    );
    assert_eq!(r.colliders[1].frames, None);
    assert!(r.stats.stages.contains(&"mesh"), "{:?}", r.stats.stages);
}

#[test]
fn a_moving_collider_carries_its_transform_at_every_frame() {
    let r = run(json!({
        "duration": 1.0, "dt": 0.01, "error_estimate": "none", "output": {"fps": 4},
        "bodies": [{"type": "chain", "count": 2, "start": [0, 5, 0], "end": [1, 5, 0]}],
        "colliders": [
            {"type": "plane"},
            {"type": "sphere", "center": [0, 0, 0], "radius": 0.1,
             "motion": {"keyframes": [{"t": 0, "translation": [0, 0, 0]}, {"t": 0.5, "translation": [2, 0, 0], "rotation": [0, 1, 0, 0]}]}},
        ],
    }));
    assert_eq!(r.colliders[0].frames, None);
    let frames = r.colliders[1].frames.as_ref().unwrap();
    assert_eq!(frames.len(), r.frames.times.len());
    // Frames at 0, 0.25, 0.5, 0.75, 1 s: halfway, then at the last key and held there.
    assert_eq!(r.frames.times, [0.0, 0.25, 0.5, 0.75, 1.0]);
    assert_eq!(frames[0].translation, [0.0, 0.0, 0.0]);
    assert!((frames[1].translation[0] - 1.0).abs() < 1e-15);
    // Half of a half turn about y: a quarter turn.
    let half = std::f64::consts::FRAC_1_SQRT_2;
    let rotation = frames[1].rotation;
    assert!((rotation[1] - half).abs() < 1e-12 && (rotation[3] - half).abs() < 1e-12, "{rotation:?}");
    assert_eq!(frames[4].translation, [2.0, 0.0, 0.0]);
    assert!(r.stats.stages.contains(&"moving_colliders"), "{:?}", r.stats.stages);
}

/// The equilibrium part of a run's error estimate.
fn equilibrium_of(r: &Recording) -> crate::solver::Equilibrium {
    r.stats.error.as_ref().and_then(|e| e.equilibrium).expect("a run at rest reports its equilibrium")
}

#[test]
fn a_hanging_chain_stopped_before_equilibrium_knows_how_far_it_is() {
    // Eleven particles of 0.01 kg hung from the first, links k = 50 N/m: at equilibrium the link
    // above particle j carries the weight of the n - j particles from j down, so it is stretched
    // by (n - j) m g / k. Stopped at rest with a loose threshold the chain is still a little off
    // that shape; the displacement the estimate predicts is the distance to it.
    let (n, mass, k, g) = (11usize, 0.11, 50.0, 9.81);
    let r = run(json!({"duration": 20.0, "dt": 0.01, "integrator": "implicit_euler", "stop_at_rest": 0.02,
        "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [0, -1, 0], "count": n, "pin": [0],
                    "mass": mass, "spring": {"k": k, "damping": 0.05}}],
        "output": {"frames": "final"}}));
    assert!(r.stats.stopped_at_rest.is_some());
    let m = mass / n as f64;
    let mut exact = vec![0.0; n];
    for j in 1..n {
        exact[j] = exact[j - 1] - (0.1 + (n - j) as f64 * m * g / k);
    }
    let last = last_positions(&r);
    let distance = (0..n)
        .map(|j| {
            ((last[3 * j + 1] - exact[j]).powi(2) + last[3 * j].powi(2) + last[3 * j + 2].powi(2)).sqrt()
        })
        .fold(0.0, f64::max);
    let q = equilibrium_of(&r);
    // The chain hangs straight and its links are linear springs: the system is linear along the
    // chain, so one solve with the stiffness lands on the static solution.
    assert!(distance > 1e-5, "the run stopped {distance} m from equilibrium: too close to test");
    let ratio = q.displacement_max / distance;
    assert!((ratio - 1.0).abs() < 1e-3, "predicted {} m, true {distance} m", q.displacement_max);
    // The residual is the stretch still missing times k, on a particle of weight m g.
    let relative = q.residual_relative.unwrap();
    assert!(relative > 0.0 && relative < 0.01 * 2.0, "{q:?}");
}

/// The largest distance between two runs' final particles.
fn final_separation(a: &Recording, b: &Recording) -> f64 {
    let (a, b) = (last_positions(a), last_positions(b));
    a.chunks(3)
        .zip(b.chunks(3))
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

#[test]
fn a_hanging_cloth_stopped_early_predicts_its_distance_from_the_settled_shape() {
    // Hanging from two corners, stopped at rest loosely and tightly: the tight run's own estimate
    // shows it settled to within a small fraction of the loose run's distance, and the loose
    // run's predicted displacement is that distance within a factor 1.5 (the sag is not linear
    // in the positions, and the stiffness is taken at the loose run's state).
    let scene = |stop: f64| {
        json!({"duration": 60.0, "dt": 0.01, "integrator": "implicit_euler", "drag": 1.0,
            "stop_at_rest": stop, "bodies": [{"type": "cloth", "resolution": [9, 9], "pin": [[0, 0], [8, 0]],
            "orientation": "vertical", "springs": {"structural": {"k": 500, "damping": 0.5},
            "shear": {"k": 50, "damping": 0.05}, "bending": {"k": 5, "damping": 0.01}}}],
            "output": {"frames": "final"}})
    };
    let loose = run(scene(0.02));
    let tight = run(scene(1e-6));
    let (q_loose, q_tight) = (equilibrium_of(&loose), equilibrium_of(&tight));
    let distance = final_separation(&loose, &tight);
    assert!(q_tight.displacement_max < 0.01 * distance, "{q_tight:?} against {distance} m");
    let ratio = q_loose.displacement_max / distance;
    assert!((1.0 / 1.5..1.5).contains(&ratio), "predicted {} m, true {distance} m", q_loose.displacement_max);
}

#[test]
fn the_equilibrium_solve_stops_when_its_run_is_interrupted() {
    // A small cloth hung from two corners, as it starts: far from equilibrium, so the solve has
    // iterations to do. An interrupt raised before it ends leaves no estimate rather than a late one.
    let scene =
        Scene::from_json(json!({"duration": 0.1, "bodies": [small_cloth()]}).to_string().as_bytes()).unwrap();
    let compiled = scene.compile();
    let (model, config) = (&compiled.model, &compiled.config);
    let positions = model.positions.clone();
    let free = crate::solver::Interrupt::new();
    let solved = crate::solver::equilibrium(model, config, &positions, 0.0, &free).expect("not interrupted");
    assert!(solved.iterations > 0 && solved.residual_force > 0.0, "{solved:?}");
    let raised = crate::solver::Interrupt::new();
    raised.raise();
    assert_eq!(crate::solver::equilibrium(model, config, &positions, 0.0, &raised), None);
}

/// A 0.5 m cotton cloth of `n × n` hung from its two top corners, run to `until` seconds or, with
/// none, to rest, with the estimate asked for.
fn hanging_material_cloth(n: usize, estimate: &str, orientation: &str, until: Option<f64>) -> Recording {
    run(json!({"duration": until.unwrap_or(30.0), "dt": 0.01, "integrator": "implicit_euler", "drag": 1.0,
        "stop_at_rest": until.is_none().then_some(1e-3), "error_estimate": estimate,
        "bodies": [{"type": "cloth", "size": [0.5, 0.5], "resolution": [n, n], "orientation": orientation,
            "center": [0, 1, 0], "material": "cotton", "pin": [[0, 0], [n - 1, 0]]}],
        "output": {"frames": "final"}}))
}

/// The largest and root-mean-square distance from a run's final particles to a finer run's at the
/// same material points (grids of `2^k + 1`, so the finer run's every `step`-th particle).
fn distance_to_finer(coarse: &Recording, n: usize, finer: &Recording, step: usize) -> (f64, f64) {
    let (a, b) = (last_positions(coarse), last_positions(finer));
    let fine_n = (n - 1) * step + 1;
    let distances: Vec<f64> = (0..n * n)
        .map(|p| {
            let (i, j) = (p % n, p / n);
            let q = j * step * fine_n + i * step;
            (0..3).map(|k| (a[3 * p + k] - b[3 * q + k]).powi(2)).sum::<f64>().sqrt()
        })
        .collect();
    let max = distances.iter().copied().fold(0.0, f64::max);
    let rms = (distances.iter().map(|d| d * d).sum::<f64>() / distances.len() as f64).sqrt();
    (max, rms)
}

/// The spatial estimate and what it estimates: the largest and root-mean-square distance from
/// the run's final particles to those of a reference 4 times as fine, and the estimate's own.
fn spatial_estimate_against_reference(
    n: usize,
    orientation: &str,
    until: Option<f64>,
) -> ((f64, f64), (f64, f64), f64, bool) {
    let reference = hanging_material_cloth(4 * n - 3, "none", orientation, until);
    let r = hanging_material_cloth(n, "resolution", orientation, until);
    if until.is_none() {
        assert!(r.stats.stopped_at_rest.is_some() && reference.stats.stopped_at_rest.is_some());
    }
    let error = r.stats.error.clone().expect("an estimate");
    let EstimateOutcome::Estimate { max, rms, observed_order: Some(order), reliable: Some(reliable) } =
        error.outcome
    else {
        panic!("{error:?}")
    };
    (distance_to_finer(&r, n, &reference, 4), (max, rms), order, reliable)
}

#[test]
fn the_spatial_estimate_of_a_falling_cloth_is_within_a_factor_three_of_its_distance_to_a_finer_one() {
    // Dropped from horizontal, hung from two corners, 0.35 s into its fall: at 9², with
    // companions at 5² and 3², against 33². The three resolutions show an order near 0.9, and the
    // estimate is within a factor 3 of the distance to the reference (itself short of the true
    // error, the reference having its own). At rest this cloth can fold to either side, and
    // which fold a resolution takes changes with the step, so its shape at rest is no test of the
    // estimate (docs/accuracy.md, "Spatial error"); while it falls there is one shape.
    let ((true_max, true_rms), (max, rms), order, reliable) =
        spatial_estimate_against_reference(9, "horizontal", Some(0.35));
    assert!(reliable && (0.6..1.4).contains(&order), "order {order}");
    for (estimate, truth) in [(max, true_max), (rms, true_rms)] {
        assert!((1.0 / 3.0..3.0).contains(&(estimate / truth)), "estimate {estimate} m, distance {truth} m");
    }
}

#[test]
fn a_spatial_estimate_whose_resolutions_are_not_yet_asymptotic_says_so() {
    // Hung from two corners as it starts, vertical: the top edge sags between the corners, and
    // the differences between 17², 9² and 5² grow as the resolution refines (an order below
    // 0), so the estimate is marked unreliable (its value is still near the distance to 65²).
    let ((true_max, _), (max, _), order, reliable) = spatial_estimate_against_reference(17, "vertical", None);
    assert!(!reliable && order < 0.0, "order {order}");
    assert!((0.5..2.0).contains(&(max / true_max)), "estimate {max} m, distance {true_max} m");
}

#[test]
fn the_spatial_estimate_plans_its_companions_work_by_their_share_of_the_particles() {
    let scene = json!({"duration": 1.0, "dt": 0.01, "error_estimate": "resolution",
        "bodies": [{"type": "cloth", "resolution": [17, 17], "material": "cotton"}]});
    let compiled = Scene::from_json(scene.to_string().as_bytes()).unwrap().compile();
    // 100 steps of 289 particles; companions of 81 and 25: 100 · 106 / 289 = 36.7 steps of the run.
    assert_eq!(compiled.steps, 100);
    assert_eq!(planned_companion_steps(&compiled), 37);
}

/// The drapes of `examples/` in contact, with the step each takes: a 20² sheet dropped onto a
/// sphere and the floor, the same onto a sphere given as a mesh, an 18² sheet onto a torus, and
/// a 21² tablecloth onto a round table.
const DRAPES: [(&str, &str, f64); 4] = [
    ("drape_sphere", include_str!("../../examples/drape_sphere.json"), 0.01),
    ("drape_mesh_sphere", include_str!("../../examples/drape_mesh_sphere.json"), 0.01),
    ("drape_torus", include_str!("../../examples/drape_torus.json"), 0.01),
    ("tablecloth", include_str!("../../examples/tablecloth.json"), 0.005),
];

/// The scene `example` (the text of a drape of `examples/`) with `integrator` at `dt` to
/// `duration`, and the estimate asked for.
fn drape(example: &str, integrator: &str, dt: f64, duration: f64, estimate: &str, fps: f64) -> Value {
    let mut scene: Value = serde_json::from_str(example).unwrap();
    scene["integrator"] = json!(integrator);
    scene["dt"] = json!(dt);
    scene["duration"] = json!(duration);
    scene["error_estimate"] = json!(estimate);
    scene["output"] = json!({"frames": "all", "fps": fps, "fields": ["positions"]});
    scene
}

/// A drape by symplectic Euler at 2.5e-6 s, 40 times below its stability bound (docs/accuracy.md
/// checks it against RK4), every quarter second from 0.5 s to its `duration`: each time's
/// positions and their largest distance from the same run at 5e-6 s, which bounds the reference's
/// own error as long as halving the step at least halves it (in contact the error shrinks at first
/// order or stays on a plateau, and on a plateau the distance is about the error itself).
struct DrapeReference {
    frames: Vec<(f64, Vec<f64>, f64)>,
}

impl DrapeReference {
    fn new(example: &str) -> Self {
        let duration = serde_json::from_str::<Value>(example).unwrap()["duration"].as_f64().unwrap();
        let (fine, coarse) = std::thread::scope(|s| {
            let at =
                |dt: f64| s.spawn(move || run(drape(example, "symplectic_euler", dt, duration, "none", 4.0)));
            let (fine, coarse) = (at(2.5e-6), at(5e-6));
            (fine.join().unwrap(), coarse.join().unwrap())
        });
        let frames = Self::times(duration)
            .map(|t| {
                let (a, b) = (frame_at(&fine, t), frame_at(&coarse, t));
                let bound = largest_distance(&a, &b);
                (t, a, bound)
            })
            .collect();
        DrapeReference { frames }
    }

    /// Every quarter second from 0.5 s to `duration`.
    fn times(duration: f64) -> impl Iterator<Item = f64> {
        (2..).map(|k| 0.25 * f64::from(k)).take_while(move |&t| t <= duration + 1e-9)
    }

    /// The reference of the drape onto the sphere, which several tests share.
    fn sphere() -> &'static Self {
        static REFERENCE: std::sync::OnceLock<DrapeReference> = std::sync::OnceLock::new();
        REFERENCE.get_or_init(|| Self::new(DRAPES[0].1))
    }

    /// The reference at `t` and the bound on its error.
    fn at(&self, t: f64) -> (&[f64], f64) {
        let (_, x, bound) = self.frames.iter().find(|(at, ..)| *at == t).expect("a reference time");
        (x, *bound)
    }
}

/// A recording's positions at time `t`.
fn frame_at(r: &Recording, t: f64) -> Vec<f64> {
    let frame = r.frames.times.iter().position(|&at| (at - t).abs() < 1e-9).expect("a frame at t");
    let per_frame = 3 * r.particles;
    r.frames.positions.as_ref().unwrap().to_f64()[frame * per_frame..(frame + 1) * per_frame].to_vec()
}

/// The largest distance between two sets of particles.
fn largest_distance(a: &[f64], b: &[f64]) -> f64 {
    a.chunks(3)
        .zip(b.chunks(3))
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

/// Runs the drape `example` with `integrator` at `dt` to `t` with the default estimate, which in
/// contact runs its companion at half the step: the estimate, the run's distance from the
/// reference (the true error) and the bound on the reference's own error.
fn contact_estimate(
    example: &str,
    reference: &DrapeReference,
    integrator: &str,
    dt: f64,
    t: f64,
) -> (f64, f64, f64) {
    let r = run(drape(example, integrator, dt, t, "richardson", 1.0 / t));
    assert_eq!(r.stats.status, Status::Succeeded);
    assert_eq!(r.stats.error.as_ref().unwrap().companion_step, Some(CompanionStep::Halved));
    let (reference, bound) = reference.at(t);
    let truth = largest_distance(&last_positions(&r), reference);
    (estimate_of(&r).0, truth, bound)
}

/// Whether `estimate` is within `factor` of the true error whichever way the reference's own error
/// leans.
fn within_factor(factor: f64, (estimate, truth, bound): (f64, f64, f64)) -> bool {
    estimate / (truth + bound) > 1.0 / factor && estimate / (truth - bound) < factor
}

#[test]
fn in_contact_an_explicit_run_near_its_stability_limit_has_an_estimate_within_a_factor_three() {
    // At 2e-4 s twice the step diverges; with the cloth landing on the sphere the estimate used
    // to be missing. The halved companion's is within 0.7 to 2.2 of the true error at 0.5 s and 1 s.
    let (sphere, reference) = (DRAPES[0].1, DrapeReference::sphere());
    for integrator in ["symplectic_euler", "rk4"] {
        for t in [0.5, 1.0] {
            let measured = contact_estimate(sphere, reference, integrator, 2e-4, t);
            let (_, truth, bound) = measured;
            assert!(
                bound < 0.25 * truth,
                "the reference is {bound} m from its refinement, the run {truth} m from it"
            );
            assert!(within_factor(3.0, measured), "{integrator} to {t} s: {measured:?}");
        }
    }
}

#[test]
fn in_contact_implicit_eulers_estimate_is_right_on_average_and_within_a_factor_three_at_rest() {
    // Each drape of `examples/` at its own step, every quarter second from 0.5 s to its end, where
    // it has settled. In contact the companion runs at half the step. While a cloth lands and
    // folds, which way a fold goes can differ between the run and its companion, or between both
    // and the reference: the estimate, twice their distance, is then up to three times the true
    // error, or a fraction of it where the two runs fold alike and the reference otherwise. As
    // measured, over the 38 times: 0.19 to 2.88 times the true error, 37 of them within a factor
    // 3, 1.28 times in their geometric mean; settled, 0.46 (the sphere), 2.51 (the mesh sphere),
    // 2.12 (the torus) and 2.02 (the tablecloth). Settled, the run and its companion rest where
    // each one's path left it (static friction holds a range of shapes), so the estimate is not
    // asymptotic there either.
    let mut ratios = Vec::new();
    for (name, example, dt) in DRAPES {
        let reference =
            if name == "drape_sphere" { DrapeReference::sphere() } else { &DrapeReference::new(example) };
        let measured: Vec<(f64, (f64, f64, f64))> = reference
            .frames
            .iter()
            .map(|&(t, ..)| (t, contact_estimate(example, reference, "implicit_euler", dt, t)))
            .collect();
        for &(t, (estimate, truth, bound)) in &measured {
            // The run's distance from the reference is mostly the run's own error.
            assert!(
                bound < truth,
                "{name} at {t} s: the reference is {bound} m from its refinement, the run {truth} m from it"
            );
            ratios.push((name, t, estimate / truth));
        }
        let &(t, (estimate, truth, _)) = measured.last().expect("a settled time");
        assert!(
            (1.0 / 3.0..3.0).contains(&(estimate / truth)),
            "{name} settled at {t} s: estimate {estimate:.3e} m, true error {truth:.3e} m"
        );
    }
    let logs: Vec<f64> = ratios.iter().map(|(.., r)| r.ln()).collect();
    let geometric_mean = (logs.iter().sum::<f64>() / logs.len() as f64).exp();
    assert!((1.0 / 1.5..1.5).contains(&geometric_mean), "{geometric_mean} of {ratios:?}");
    let within_three = logs.iter().filter(|l| l.abs() < 3f64.ln()).count();
    assert!(10 * within_three >= 9 * ratios.len(), "{within_three} of {ratios:?} within a factor 3");
    // The plan counts the halved companion's steps.
    let scene = Scene::from_json(
        drape(DRAPES[0].1, "implicit_euler", 0.01, 1.0, "richardson", 1.0).to_string().as_bytes(),
    );
    assert_eq!(planned_companion_steps(&scene.unwrap().compile()), 200);
}
