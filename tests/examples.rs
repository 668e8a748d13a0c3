//! Every scene in `examples/` runs as `drape run` would run it, and shows the physics it is
//! there to show: oscillation periods against theory, no particle inside a collider after any
//! step, a symmetric tablecloth, a flag blown downwind, a jelly cube at rest on the ground,
//! self-collision distances and the strain limit.

mod elastica;

use std::path::Path;

use drape::run::{self, Control, Status};
use drape::scene::{Compiled, Scene};
use drape::solver::{Shape, Simulation, Vec3};
use glam::DVec3;

fn scene(name: &str) -> Scene {
    Scene::from_json(&example_text(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The text of `examples/{name}`.
fn example_text(name: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples").join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Steps a compiled scene to its end, checking after every step that no free particle is inside
/// a fixed collider by more than 1e-6 m; returns the simulation at the end.
fn run_checked(compiled: &Compiled, mut after_step: impl FnMut(&Simulation<f64>)) -> Simulation<f64> {
    let mut sim = Simulation::<f64>::new(&compiled.model, &compiled.config);
    for _ in 0..compiled.steps {
        sim.step().unwrap_or_else(|d| panic!("diverged: {d:?}"));
        assert_outside_colliders(compiled, &sim);
        after_step(&sim);
    }
    sim
}

fn assert_outside_colliders(compiled: &Compiled, sim: &Simulation<f64>) {
    // A moving collider's shape is in its own frame; its example checks it where it is.
    for collider in compiled.config.colliders.iter().filter(|c| c.motion.is_none()) {
        for (p, x) in sim.state().positions.iter().enumerate() {
            if compiled.model.pinned[p] {
                continue;
            }
            let depth = collider.shape.signed_distance(x.to_dvec3());
            assert!(
                depth >= -1e-6,
                "step {}: particle {p} is {:.3e} m inside the {}",
                sim.steps_taken(),
                -depth,
                collider.shape.name()
            );
        }
    }
}

fn positions(sim: &Simulation<f64>) -> Vec<DVec3> {
    sim.state().positions.iter().map(|p| p.to_dvec3()).collect()
}

fn mean(points: &[DVec3]) -> DVec3 {
    points.iter().sum::<DVec3>() / points.len() as f64
}

fn max_speed(sim: &Simulation<f64>) -> f64 {
    sim.state().velocities.iter().map(|v: Vec3<f64>| v.to_dvec3().length()).fold(0.0, f64::max)
}

/// The period of a sampled signal from its upward crossings of the middle of its range.
fn period(samples: &[f64], dt: f64) -> f64 {
    let (lo, hi) = samples.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &s| (l.min(s), h.max(s)));
    let middle = 0.5 * (lo + hi);
    let crossings: Vec<f64> = samples
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < middle && w[1] >= middle)
        .map(|(k, w)| (k as f64 + (middle - w[0]) / (w[1] - w[0])) * dt)
        .collect();
    assert!(crossings.len() >= 3, "too few oscillations: {}", crossings.len());
    (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64
}

#[test]
fn every_example_runs_as_drape_run_runs_it() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".json"))
        .collect();
    names.sort();
    for name in [
        "single_spring.json",
        "chain.json",
        "hanging_cloth.json",
        "drape_sphere.json",
        "drape_sphere_explicit.json",
        "tablecloth.json",
        "flag.json",
        "jelly_cube.json",
        "self_collision.json",
        "strain_limited.json",
        "drape_tester.json",
        "cantilever.json",
        "drape_mesh_sphere.json",
        "fast_particle_sheet.json",
        "swept_ball.json",
        "tablecloth_pull.json",
        "drape_torus.json",
    ] {
        assert!(names.iter().any(|n| n == name), "examples/{name} is missing");
    }
    for name in &names {
        let compiled = scene(name).compile();
        let recording = run::execute(&compiled, &Control::new());
        assert_eq!(recording.stats.status, Status::Succeeded, "{name}: {:?}", recording.stats.diverged);
        assert!(recording.stats.energy.is_some_and(|e| e.total().is_finite()), "{name}");
        let stages = &recording.stats.stages;
        for collider in &compiled.config.colliders {
            assert!(stages.contains(&collider.shape.name()), "{name}: {stages:?}");
        }
        let expected: &[&str] = match name.as_str() {
            "single_spring.json" | "chain.json" => &["gravity", "springs"],
            "hanging_cloth.json" => &["gravity", "drag", "springs"],
            "drape_sphere.json" | "drape_sphere_explicit.json" => {
                &["gravity", "drag", "springs", "sphere", "plane"]
            }
            "tablecloth.json" => &["gravity", "drag", "springs", "cylinder", "plane"],
            "drape_tester.json" => &["gravity", "drag", "springs", "bending", "cylinder"],
            // Aerodynamic wind needs no vertex normals; the output's `normals` field does.
            "flag.json" => &["gravity", "drag", "springs", "wind", "normals"],
            "jelly_cube.json" => &["gravity", "drag", "springs", "plane"],
            "self_collision.json" => &["gravity", "drag", "springs", "self_collision", "plane"],
            "strain_limited.json" => &["gravity", "drag", "springs", "strain_limit", "sphere"],
            "cantilever.json" => &["gravity", "drag", "springs", "bending"],
            "drape_mesh_sphere.json" => &["gravity", "drag", "springs", "mesh", "plane"],
            "fast_particle_sheet.json" => &["gravity", "springs", "mesh"],
            "swept_ball.json" => &["gravity", "drag", "springs", "sphere", "moving_colliders"],
            "tablecloth_pull.json" => &["gravity", "drag", "springs", "pin_motion", "box", "plane"],
            "drape_torus.json" => &["gravity", "drag", "springs", "mesh", "plane"],
            _ => continue,
        };
        assert_eq!(stages, expected, "{name}");
    }
}

#[test]
fn single_spring_oscillates_with_period_two_pi_root_m_over_k() {
    let compiled = scene("single_spring.json").compile();
    let mut heights = Vec::new();
    run_checked(&compiled, |sim| heights.push(sim.state().positions.get(1).y));
    // The free particle carries half the 0.2 kg; k = 40 N/m.
    let expected = std::f64::consts::TAU * (0.1f64 / 40.0).sqrt();
    let measured = period(&heights, compiled.config.dt);
    assert!((measured - expected).abs() < 1e-3 * expected, "period {measured}, expected {expected}");
}

#[test]
fn chain_fundamental_mode_has_the_period_of_a_fixed_free_chain() {
    // Five free masses m = 0.1 kg below a pin, six springs of k = 50 N/m... five springs: the
    // modes of a fixed-free chain of N masses are sin(i θ_j), θ_j = (2j - 1) π / (2N + 1), with
    // ω_j = 2 √(k/m) sin(θ_j / 2). Gravity along the chain only shifts the equilibrium.
    let compiled = scene("chain.json").compile();
    let (n, k, m) = (5usize, 50.0f64, 0.1f64);
    let theta = std::f64::consts::PI / (2 * n + 1) as f64;
    let shape: Vec<f64> = (1..=n).map(|i| (i as f64 * theta).sin()).collect();
    let mut amplitude = Vec::new();
    run_checked(&compiled, |sim| {
        let y = &sim.state().positions;
        amplitude.push((1..=n).map(|i| shape[i - 1] * y.get(i).y).sum());
    });
    let omega = 2.0 * (k / m).sqrt() * (theta / 2.0).sin();
    let expected = std::f64::consts::TAU / omega;
    let measured = period(&amplitude, compiled.config.dt);
    assert!((measured - expected).abs() < 1e-3 * expected, "period {measured}, expected {expected}");
}

/// The particle of `(i, j)` mirrored across the cloth's centre line along `i`.
fn mirror_error(x: &[DVec3], nx: usize, ny: usize, centre: DVec3) -> f64 {
    let mut worst: f64 = 0.0;
    for j in 0..ny {
        for i in 0..nx {
            let a = x[j * nx + i] - centre;
            let b = x[j * nx + (nx - 1 - i)] - centre;
            worst = worst.max((a - DVec3::new(-b.x, b.y, b.z)).length());
        }
    }
    worst
}

#[test]
fn hanging_cloth_holds_its_two_corners_and_hangs_symmetrically_below_them() {
    let compiled = scene("hanging_cloth.json").compile();
    let start = compiled.model.positions.clone();
    let sim = run_checked(&compiled, |_| {});
    let x = positions(&sim);
    let (nx, ny) = (20, 20);
    for corner in [0, nx - 1] {
        assert_eq!(x[corner], start[corner], "pinned corner {corner} moved");
    }
    assert!(x.iter().all(|p| p.y <= start[0].y + 1e-9));
    assert!(mean(&x).y < start[0].y - 0.3, "the cloth does not hang: {:?}", mean(&x));
    let asymmetry = mirror_error(&x, nx, ny, DVec3::ZERO);
    assert!(asymmetry < 1e-3, "asymmetric by {asymmetry} m");
}

#[test]
fn cloth_drapes_over_the_sphere_without_entering_it() {
    let compiled = scene("drape_sphere.json").compile();
    let sim = run_checked(&compiled, |_| {});
    let x = positions(&sim);
    // Particle (10, 10) is next to the middle: it rests on top of the ball (top at y = 0.8, the
    // scene's centre height 0.5 plus radius 0.3).
    let top = x.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    assert!((top - 0.8).abs() < 0.02, "highest point {top}");
    let corner = x[0];
    assert!(corner.y < 0.5, "corner still at {corner:?}");
}

#[test]
fn the_sphere_drape_at_the_default_step_keeps_its_folds_on_the_ball() {
    // drape_sphere.json at 64 × 64 particles without its `dt`: implicit Euler in contact takes
    // half the frame interval, 1/60 s at the example's 30 frames a second. The sheet is compressed
    // where it wraps the ball, and a compressed spring's transverse stiffness `k (1 - L/l)` is
    // negative: left out of the step's matrix, so explicit in the step, it lifted the folds on
    // the ball's top off it and back at about 1 m/s from 1.25 s on while the contacts were only
    // projected after the solve. With the contacts held in the solve the folds stay on the ball,
    // the sheet settles where small steps put it (lowest point 0.258 m as measured, 0.261 m at
    // small steps, against 0.221 m with the projection alone), and from 4.5 s on no particle is
    // faster than 16 mm/s.
    let mut json: serde_json::Value = serde_json::from_slice(&example_text("drape_sphere.json")).unwrap();
    json["bodies"][0]["resolution"] = serde_json::json!([64, 64]);
    json.as_object_mut().unwrap().remove("dt");
    json["duration"] = serde_json::json!(5.0);
    let compiled = Scene::from_json(json.to_string().as_bytes()).unwrap().compile();
    assert_eq!(compiled.config.dt, 1.0 / 60.0);
    let mut fastest_late = 0.0_f64;
    let sim = run_checked(&compiled, |sim| {
        if sim.time() > 4.5 {
            fastest_late = fastest_late.max(max_speed(sim));
        }
    });
    assert!(fastest_late < 0.02, "a particle moves at {fastest_late} m/s between 4.5 and 5 s");
    let lowest = positions(&sim).iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    assert!((0.25..0.27).contains(&lowest), "lowest point {lowest} m");
}

#[test]
fn cloth_drapes_over_a_mesh_sphere_as_over_the_analytic_sphere() {
    // The same scene with the ball as a closed icosphere of 1,280 triangles whose faces lie at
    // the ball's radius on average (vertices 0.4 % out), 1 mm thick.
    let over_mesh = positions(&run_checked(&scene("drape_mesh_sphere.json").compile(), |_| {}));
    let over_ball = positions(&run_checked(&scene("drape_sphere.json").compile(), |_| {}));
    let distances: Vec<f64> = over_mesh.iter().zip(&over_ball).map(|(a, b)| (*a - *b).length()).collect();
    let mean = distances.iter().sum::<f64>() / distances.len() as f64;
    let largest = distances.iter().copied().fold(0.0, f64::max);
    // The cloth's particles are 5 cm apart: the two drapes agree to a fraction of that (2.2 mm
    // on average and 3.8 mm at most as measured; static friction keeps small differences in
    // where the folds landed).
    assert!(mean < 0.01 && largest < 0.035, "mean distance {mean} m, largest {largest} m");
}

#[test]
fn pellets_at_100_m_s_stop_at_a_sheet_of_two_triangles() {
    let compiled = scene("fast_particle_sheet.json").compile();
    // 1.67 m a step: the first step takes them from 1 m above the sheet to 0.67 m below it.
    let sim = run_checked(&compiled, |sim| {
        for x in sim.state().positions.iter() {
            assert!(x.y >= 0.005 - 1e-12, "step {}: a pellet at y = {}", sim.steps_taken(), x.y);
        }
    });
    for x in sim.state().positions.iter() {
        assert!((x.y - 0.005).abs() < 1e-9, "a pellet ends at y = {}", x.y);
    }
}

#[test]
fn a_ball_swept_through_a_hanging_cloth_carries_it_and_never_holds_a_particle_inside() {
    let compiled = scene("swept_ball.json").compile();
    let ball = &compiled.config.colliders[0];
    let motion = ball.motion.as_ref().expect("the ball moves");
    let mut furthest: f64 = 0.0;
    let sim = run_checked(&compiled, |sim| {
        // The ball where the step left it: no free particle inside.
        let at = motion.at(sim.time());
        for (p, x) in sim.state().positions.iter().enumerate() {
            let local = at.inverse_point(x.to_dvec3());
            if !compiled.model.pinned[p] {
                let depth = ball.shape.signed_distance(local);
                assert!(depth >= -1e-6, "step {}: particle {p} {depth} m inside the ball", sim.steps_taken());
            }
            furthest = furthest.max(x.z);
        }
    });
    // The ball passes through the curtain's plane (z = 0) at 2 m/s, 0.2 m below its pins, and
    // pushes the cloth ahead of it: the cloth is carried well past where it hung.
    assert!(furthest > 0.2, "the cloth reached only z = {furthest}");
    assert!(sim.state().positions.iter().all(|x| x.is_finite()));
}

#[test]
fn a_tablecloth_pulled_by_two_pins_leaves_the_table() {
    let compiled = scene("tablecloth_pull.json").compile();
    let rest = compiled.model.positions.clone();
    let sim = run_checked(&compiled, |_| {});
    let x = positions(&sim);
    // The pins (the middle of the edge at x = 0.5) went 2 m along +x, and are held there.
    for p in [7 * 16 + 15, 8 * 16 + 15] {
        assert!((x[p] - (rest[p] + DVec3::new(2.0, 0.0, 0.0))).length() < 1e-9, "pin {p} at {}", x[p]);
    }
    // The cloth followed them off the table (its top spans x from -0.5 to 0.5).
    let centre = mean(&x);
    assert!(centre.x > 0.9, "the cloth's centre is still at {centre}");
    assert!(x.iter().all(|p| p.x > 0.5), "a particle is still over the table");
}

#[test]
fn cloth_drapes_onto_a_closed_torus_with_no_particle_inside_after_any_step() {
    // The torus of `examples/assets/torus.obj`, inlined: closed, and not convex (its hole).
    let compiled = scene("drape_torus.json").compile();
    let Shape::Mesh { surface, .. } = &compiled.config.colliders[0].shape else { panic!("not a mesh") };
    assert!(surface.is_closed());
    // After every step, every free particle is outside the torus, by the exact distance to a
    // torus (ring radius 0.3 m, tube 0.1 m, centre height 0.1 m), less the facets' chord error
    // (a tube of 12 sides is inside its circle by up to 0.1 (1 - cos 15°) = 3.4 mm).
    let torus_depth = |x: DVec3| {
        let ring = (x.x * x.x + x.z * x.z).sqrt() - 0.3;
        (ring * ring + (x.y - 0.1) * (x.y - 0.1)).sqrt() - 0.1
    };
    let sim = run_checked(&compiled, |sim| {
        for (p, x) in sim.state().positions.iter().enumerate() {
            let depth = torus_depth(x.to_dvec3());
            assert!(depth > -0.0035, "step {}: particle {p} {depth} m into the torus", sim.steps_taken());
        }
    });
    // It came to lie on the torus: its highest point near the tube's top (0.2 m and the thickness).
    let top = positions(&sim).iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    assert!((top - 0.205).abs() < 0.02, "highest point {top}");
}

#[test]
fn explicit_euler_with_small_steps_agrees_with_implicit_euler_at_large_steps() {
    let explicit = scene("drape_sphere_explicit.json").compile();
    let implicit = scene("drape_sphere.json").compile();
    assert!(explicit.steps >= 40 * implicit.steps);
    let a = positions(&run_checked(&explicit, |_| {}));
    let b = positions(&run_checked(&implicit, |_| {}));
    let (ca, cb) = (mean(&a), mean(&b));
    assert!((ca - cb).length() < 0.02, "centres {ca:?} and {cb:?}");
    let mean_gap = a.iter().zip(&b).map(|(p, q)| p.distance(*q)).sum::<f64>() / a.len() as f64;
    assert!(mean_gap < 0.03, "the drapes differ by {mean_gap} m on average");
}

/// The folds over the table's edge are symmetric bifurcations, which amplify any asymmetric
/// error, and static friction keeps what the landing made of it: with each step's solve stopped
/// at a hundredth of its starting residual (the default `reduction`) the linear solves' own
/// errors leave a mirror error of 1.3e-2 m, solved to the tolerance 1e-6 of 4e-6 m, and to 1e-8
/// of 2e-8 m, so the scene solves every step to 1e-8.
#[test]
fn tablecloth_comes_to_rest_symmetric_about_the_table_axis() {
    let compiled = scene("tablecloth.json").compile();
    let sim = run_checked(&compiled, |_| {});
    let x = positions(&sim);
    let n = 21;
    let centre = mean(&x);
    assert!(centre.x.abs() < 1e-3 && centre.z.abs() < 1e-3, "centre {centre:?}");
    assert!(mirror_error(&x, n, n, DVec3::ZERO) < 1e-3, "{}", mirror_error(&x, n, n, DVec3::ZERO));
    // Mirrored across x = 0 by rows too: (i, j) against (i, n - 1 - j).
    let swapped: Vec<DVec3> = (0..n * n).map(|p| x[(n - 1 - p / n) * n + p % n]).collect();
    let rows =
        x.iter().zip(&swapped).map(|(a, b)| (*a - DVec3::new(b.x, b.y, -b.z)).length()).fold(0.0, f64::max);
    assert!(rows < 1e-3, "{rows}");
    // On the table: the middle particle rests on the top at 0.7 m (the scene's cylinder, centred
    // at 0.35 m and 0.7 m high); the edges hang down.
    assert!((x[n * n / 2].y - 0.7).abs() < 1e-3, "{:?}", x[n * n / 2]);
    assert!(x[0].y < 0.5, "corner at {:?}", x[0]);
    assert!(max_speed(&sim) < 0.05, "still moving at {} m/s", max_speed(&sim));
}

#[test]
fn flag_moves_downwind_and_hangs_straight_down_without_wind() {
    let windy = scene("flag.json");
    let compiled = windy.compile();
    let start = mean(&compiled.model.positions);
    let blown = mean(&positions(&run_checked(&compiled, |_| {})));
    assert!(blown.z > start.z + 0.1, "mean moved only to {blown:?} from {start:?}");

    let mut calm = windy.clone();
    calm.wind = None;
    let calm = calm.compile();
    let sim = run_checked(&calm, |_| {});
    assert!(!sim.stages().contains(&"wind"));
    for (p, (x, x0)) in positions(&sim).iter().zip(&calm.model.positions).enumerate() {
        assert!(x.z.abs() < 1e-9, "particle {p} left the plane: {x:?}");
        assert!((x.x - x0.x).abs() < 5e-3, "particle {p} is not below where it started: {x:?}, {x0:?}");
    }
}

#[test]
fn jelly_cube_lands_and_rests_on_the_ground_keeping_its_shape() {
    let compiled = scene("jelly_cube.json").compile();
    let sim = run_checked(&compiled, |_| {});
    let x = positions(&sim);
    let (low, high) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.y), h.max(p.y)));
    assert!(low.abs() < 1e-3, "lowest particle at {low}");
    // The scene's cube is 0.2 m on a side: resting, it keeps that height within 10 %.
    assert!((high - low - 0.2).abs() < 0.02, "height {}", high - low);
    assert!(max_speed(&sim) < 0.05, "still moving at {} m/s", max_speed(&sim));
}

#[test]
fn cloth_folding_onto_itself_keeps_unjoined_particles_apart() {
    let scene = scene("self_collision.json");
    let thickness = scene.self_collision.unwrap().thickness;
    let compiled = scene.compile();
    let sim = run_checked(&compiled, |_| {});
    assert!(sim.stages().contains(&"self_collision"));
    let x = positions(&sim);
    let mut joined = std::collections::HashSet::new();
    for s in &compiled.model.springs {
        joined.insert((s.i.min(s.j), s.i.max(s.j)));
    }
    let mut closest = f64::INFINITY;
    for p in 0..x.len() {
        for q in p + 1..x.len() {
            if !joined.contains(&(p as u32, q as u32)) {
                closest = closest.min(x[p].distance(x[q]));
            }
        }
    }
    assert!(closest > thickness, "two unjoined particles are {closest} m apart");
    // It did fold: some particles are stacked above others.
    let top = x.iter().map(|p| p.y).fold(0.0, f64::max);
    assert!(top > 2.0 * thickness && top < 0.3, "top at {top}");
}

#[test]
fn strain_limit_holds_the_cloth_over_the_sphere_to_ten_percent() {
    let limited = scene("strain_limited.json");
    let compiled = limited.compile();
    let mut worst: f64 = 0.0;
    let sim = run_checked(&compiled, |sim| worst = worst.max(sim.max_strain()));
    assert!(sim.stages().contains(&"strain_limit"));
    // The pass keeps particles out of the sphere while it shortens springs, so both hold.
    assert!(worst <= 0.1 * (1.0 + 1e-6), "strain reached {worst}");

    let mut free = limited.clone();
    free.strain_limit = None;
    let mut worst_free: f64 = 0.0;
    run_checked(&free.compile(), |sim| worst_free = worst_free.max(sim.max_strain()));
    assert!(worst_free > 0.15, "without the limit the soft cloth should stretch more: {worst_free}");
}

/// The area of the union of `triangles` over `points` (`[x, z]`) and a disk, counted the plain
/// way: the cells of a square bitmap of side `cell` whose centres lie in a triangle (by the signs
/// of three cross products) or in the disk. An estimate independent of the run's scanline
/// measurement, off by at most the cells the outline of length `outline` crosses:
/// `2 (outline / cell + 4) cell²`.
fn bitmap_area(points: &[[f64; 2]], triangles: &[[u32; 3]], disk: ([f64; 2], f64), cell: f64) -> f64 {
    let (low, high) = points.iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
    });
    let (nx, nz) =
        (((high[0] - low[0]) / cell).ceil() as usize + 1, ((high[1] - low[1]) / cell).ceil() as usize + 1);
    let mut covered = vec![false; nx * nz];
    let centre = |i: usize, k: usize| [low[0] + (i as f64 + 0.5) * cell, low[1] + (k as f64 + 0.5) * cell];
    let cross =
        |a: [f64; 2], b: [f64; 2], c: [f64; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    for t in triangles {
        let [a, b, c] = t.map(|i| points[i as usize]);
        let cell_of =
            |x: f64, origin: f64, n: usize| (((x - origin) / cell).floor().max(0.0) as usize).min(n - 1);
        let (i0, i1) =
            (cell_of(a[0].min(b[0]).min(c[0]), low[0], nx), cell_of(a[0].max(b[0]).max(c[0]), low[0], nx));
        let (k0, k1) =
            (cell_of(a[1].min(b[1]).min(c[1]), low[1], nz), cell_of(a[1].max(b[1]).max(c[1]), low[1], nz));
        for k in k0..=k1 {
            for i in i0..=i1 {
                let q = centre(i, k);
                let s = [cross(a, b, q), cross(b, c, q), cross(c, a, q)];
                if s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0) {
                    covered[k * nx + i] = true;
                }
            }
        }
    }
    let ([cx, cz], r) = disk;
    let count = (0..nz)
        .flat_map(|k| (0..nx).map(move |i| (i, k)))
        .filter(|&(i, k)| {
            let q = centre(i, k);
            covered[k * nx + i] || (q[0] - cx).hypot(q[1] - cz) <= r
        })
        .count();
    count as f64 * cell * cell
}

/// The drape tester: an 18 cm support under a 30 cm specimen. The specimen drapes (its
/// coefficient between 0 and 1, with the six folds its rings' symmetry gives), its shape is
/// steady over the last second, and the reported coefficient agrees with an independent count of
/// the shadow's bitmap cells within that count's own error.
#[test]
fn drape_tester_reports_the_coefficient_of_its_shadow() {
    let compiled = scene("drape_tester.json").compile();
    let tester = compiled.drape_tester.clone().expect("the example is a drape tester");
    let recording = run::execute(&compiled, &Control::new());
    assert_eq!(recording.stats.status, Status::Succeeded);
    let reported = recording.stats.drape_coefficient.expect("a coefficient");
    assert!(reported > 0.0 && reported < 1.0, "{reported}");

    let frames = recording.frames.positions.as_ref().unwrap().to_f64();
    let n = recording.particles;
    let frame = |f: usize| -> Vec<DVec3> {
        frames[3 * n * f..3 * n * (f + 1)].chunks(3).map(DVec3::from_slice).collect()
    };
    let count = recording.frames.len();
    let last = frame(count - 1);
    assert_eq!(run::drape_coefficient(&tester, &last, &recording.triangles), Some(reported));
    let a_second_before = run::drape_coefficient(&tester, &frame(count - 31), &recording.triangles).unwrap();
    assert!((a_second_before - reported).abs() < 2e-3, "{a_second_before} then {reported}");

    let points: Vec<[f64; 2]> = last.iter().map(|p| [p.x, p.z]).collect();
    let cell = 2.5e-4;
    let shadow =
        bitmap_area(&points, &recording.triangles, (tester.support_center, tester.support_radius), cell);
    let annulus = tester.specimen_area - tester.support_area();
    let independent = (shadow - tester.support_area()) / annulus;
    // The outline of six folds is well under 3 m (ten times the specimen's circumference).
    let bitmap_error = 2.0 * (3.0 / cell + 4.0) * cell * cell / annulus;
    assert!(
        (independent - reported).abs() <= bitmap_error + run::RASTER_ERROR_BOUND,
        "bitmap {independent}, reported {reported}, bound {bitmap_error}"
    );

    // Six folds: the outer ring's projected radius has six maxima around the axis.
    let rings = 15;
    let first = 1 + 3 * rings * (rings - 1);
    let radius: Vec<f64> = last[first..].iter().map(|p| p.x.hypot(p.z)).collect();
    let m = radius.len();
    let smooth: Vec<f64> =
        (0..m).map(|i| (0..5).map(|k| radius[(i + m + k - 2) % m]).sum::<f64>() / 5.0).collect();
    let folds =
        (0..m).filter(|&i| smooth[i] > smooth[(i + m - 1) % m] && smooth[i] >= smooth[(i + 1) % m]).count();
    assert_eq!(folds, 6);
}

/// The drape tester's cotton at two resolutions: 15 rings (the example) and 10. Each comes to
/// rest, the two coefficients agree to 0.03, and each lies between flat and the shadow of a strip
/// of the overhang clamped at the support's rim: the annulus droops less than such a strip,
/// because its hoops must shorten for it to droop, and the heavy elastica gives the strip's reach
/// for `λ = w l³ / B`.
#[test]
fn drape_tester_gives_one_coefficient_at_two_resolutions() {
    let example = scene("drape_tester.json");
    let drape::scene::Body::Cloth(specimen) = &example.bodies[0] else { panic!("a cloth") };
    let fabric = specimen.material.expect("a preset fabric");
    // The coefficient at `rings` rings, and the strip's against that specimen's area.
    let coefficient = |rings: usize| {
        let mut scene = example.clone();
        let drape::scene::Body::Cloth(cloth) = &mut scene.bodies[0] else { unreachable!() };
        cloth.resolution = [2 * rings + 1; 2];
        let compiled = scene.compile();
        let recording = run::execute(&compiled, &Control::new());
        assert_eq!(recording.stats.status, Status::Succeeded);
        assert!(recording.stats.stopped_at_rest.is_some(), "{rings} rings come to rest");
        let tester = compiled.drape_tester.expect("a drape tester");
        let overhang = 0.5 * specimen.disk_diameter() - tester.support_radius;
        let lambda = fabric.density * 9.81 * overhang.powi(3) / fabric.bending;
        let [reach, _] = elastica::elastica_tip(lambda);
        let strip_shadow = std::f64::consts::PI * (tester.support_radius + reach * overhang).powi(2);
        let annulus = tester.specimen_area - tester.support_area();
        let strip = (strip_shadow - tester.support_area()) / annulus;
        let d = recording.stats.drape_coefficient.expect("a coefficient");
        assert!(d > strip && d < 0.99, "{rings} rings: {d}, the strip's {strip}");
        d
    };
    let (fine, coarse) = (coefficient(15), coefficient(10));
    assert!((fine - coarse).abs() <= 0.03, "15 rings {fine}, 10 rings {coarse}");
}

#[test]
fn cantilever_strip_rests_at_the_heavy_elasticas_chord_angle() {
    // A strip clamped by its first two columns (the clamp's edge midway between them) over a free
    // length l of 40.5 spacings, weight w = ρ g per area, rigidity B: at rest, its tip chord
    // falls by the heavy elastica's angle for λ = w l³ / B, which the example sets to 8, twice
    // the bending length c = (B/w)^(1/3) (Peirce's 41.5° cantilever).
    let scene = scene("cantilever.json");
    let compiled = scene.compile();
    let drape::scene::Body::Cloth(cloth) = &scene.bodies[0] else { panic!("a cloth") };
    let fabric = cloth.material.expect("a material");
    let [nx, ny] = cloth.resolution;
    let free = cloth.size[0] * (nx as f64 - 1.5) / (nx - 1) as f64;
    let weight = fabric.density * 9.81;
    let lambda = weight * free.powi(3) / fabric.bending;
    assert!((lambda - 8.0).abs() < 1e-2, "λ = {lambda}");
    assert!((fabric.bending_length(9.81) - free / 2.0).abs() < 1e-3 * free);
    let mut sim = Simulation::<f64>::new(&compiled.model, &compiled.config);
    let rest = compiled.stop_at_rest.expect("the example stops at rest");
    while sim.steps_taken() < compiled.steps {
        sim.step().expect("stable");
        if max_speed(&sim) < rest {
            break;
        }
    }
    assert!(sim.steps_taken() < compiled.steps, "the strip comes to rest");
    let x = |p: usize| sim.state().positions.get(p).to_dvec3();
    let simulated = (0..ny)
        .map(|j| {
            let d = x(j * nx + nx - 1) - 0.5 * (x(j * nx) + x(j * nx + 1));
            (-d.y).atan2(d.x)
        })
        .sum::<f64>()
        / ny as f64;
    let exact = elastica::elastica_chord_angle(lambda);
    assert!(
        (simulated - exact).abs().to_degrees() < 1.5,
        "{:.2}° against the elastica's {:.2}°",
        simulated.to_degrees(),
        exact.to_degrees()
    );
}
