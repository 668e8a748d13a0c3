//! Fabrics in physical units: the bending elements' energy against the closed form of a bent
//! sheet, the membrane's stress under uniaxial stretch, the convergence of a drape with the
//! resolution, the cantilever against the heavy elastica, zero-length springs, and the named
//! presets a material can be given by.

mod elastica;

use drape::scene::{Body, DEFAULT_DAMPING_TIME, FABRIC_PRESETS, FabricSpec, Scene};
use drape::solver::{
    Chain, Cloth, Config, Dynamics, Fabric, IntegratorKind, Model, Orientation, Simulation, SpringParams,
    Vectors,
};
use elastica::elastica_chord_angle;
use glam::DVec3;

const COTTONISH: Fabric =
    Fabric { density: 0.15, stretch: 2000.0, shear: 100.0, bending: 1e-5, damping_time: 1e-3 };

/// An `n × n` grid cloth of `fabric` on the unit square in the x-z plane, nothing pinned.
fn sheet(n: usize, fabric: &Fabric) -> Model {
    let mut model = Model::default();
    let springs = SpringParams { stiffness: 1.0, damping: 0.0 };
    let cloth = Cloth { center: DVec3::new(0.5, 0.0, 0.5), ..Cloth::square_metre(n, springs) };
    model.add_fabric_cloth(&cloth, fabric);
    model
}

/// The elastic energy of the model's bending elements alone with its particles at `positions`.
fn bending_energy(model: &Model, positions: &[DVec3]) -> f64 {
    let bare = Model {
        positions: positions.to_vec(),
        velocities: vec![DVec3::ZERO; positions.len()],
        masses: model.masses.clone(),
        pinned: model.pinned.clone(),
        triangles: model.triangles.clone(),
        bending: model.bending.clone(),
        ..Model::default()
    };
    Simulation::<f64>::new(&bare, &Config { gravity: DVec3::ZERO, ..Config::default() }).energy().spring
}

/// The sheet's rest positions wrapped isometrically onto a cylinder of curvature `kappa`
/// whose axis lies along `axis` (a unit vector in the x-z plane).
fn wrapped(rest: &[DVec3], kappa: f64, axis: DVec3) -> Vec<DVec3> {
    let across = DVec3::Y.cross(axis);
    rest.iter()
        .map(|p| {
            let (s, u) = (p.dot(across), p.dot(axis));
            across * ((kappa * s).sin() / kappa) + axis * u + DVec3::Y * ((1.0 - (kappa * s).cos()) / kappa)
        })
        .collect()
}

#[test]
fn bending_elements_of_a_sheet_bent_to_a_cylinder_store_half_b_kappa_squared_per_area() {
    // A sheet wrapped onto a cylinder of curvature κ stores ½ B κ² per unit area, whatever the
    // direction of the cylinder's axis, so its bending moment per unit width is B κ. The first
    // and last particles along a row or column have no second difference, so the discrete
    // energy falls short by a strip along the border: a relative error of first order in the
    // spacing.
    let kappa = 2.0;
    let exact = 0.5 * COTTONISH.bending * kappa * kappa;
    let axes = [DVec3::Z, DVec3::X, DVec3::new(1.0, 0.0, 1.0).normalize()];
    for axis in axes {
        let errors: Vec<f64> = [20, 40, 80]
            .into_iter()
            .map(|n| {
                let model = sheet(n, &COTTONISH);
                let energy = bending_energy(&model, &wrapped(&model.positions, kappa, axis));
                (energy - exact) / exact
            })
            .collect();
        for pair in errors.windows(2) {
            let order = (pair[0].abs() / pair[1].abs()).log2();
            assert!((0.8..1.3).contains(&order), "axis {axis}: errors {errors:?}, order {order}");
        }
        assert!(errors[2].abs() < 0.03, "axis {axis}: errors {errors:?}");
    }
}

#[test]
fn bending_energy_is_quadratic_in_the_curvature_and_blind_to_rigid_motion() {
    let model = sheet(21, &COTTONISH);
    let rest = &model.positions;
    let e1 = bending_energy(&model, &wrapped(rest, 1.0, DVec3::Z));
    let e2 = bending_energy(&model, &wrapped(rest, 0.5, DVec3::Z));
    // Wrapping is exactly isometric, and a wrapped row's second difference is 4 sin²(a κ / 2) / κ
    // long: quadratic in κ up to the (a κ)⁴ term of the sine.
    assert!((e1 / e2 - 4.0).abs() < 4.0 * 1e-3, "{e1} against {e2}");
    let turned = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let moved: Vec<DVec3> = rest.iter().map(|&p| turned * p + DVec3::new(3.0, -1.0, 2.0)).collect();
    assert!(bending_energy(&model, &moved) < 1e-20);
}

#[test]
fn bending_forces_are_the_gradient_of_their_energy() {
    let model = sheet(6, &COTTONISH);
    let bent: Vec<DVec3> = wrapped(&model.positions, 3.0, DVec3::new(0.6, 0.0, 0.8))
        .iter()
        .enumerate()
        .map(|(p, x)| *x + DVec3::new(0.0, 1e-3 * ((p * 7) % 5) as f64, 0.0))
        .collect();
    let bare = Model { springs: Vec::new(), grids: Vec::new(), ..model.clone() };
    let mut dynamics = Dynamics::<f64>::new(&bare, DVec3::ZERO, 0.0);
    let x: Vectors<f64> = bent.iter().map(|&p| drape::solver::Vec3::from_dvec3(p)).collect();
    let v = Vectors::zeros(bent.len());
    let mut forces = Vectors::zeros(bent.len());
    dynamics.forces(&x, &v, 0.0, &mut forces);
    let step = 1e-6;
    for p in [0, 7, 14, 20, 35] {
        for axis in 0..3 {
            let mut nudged = bent.clone();
            nudged[p][axis] += step;
            let up = bending_energy(&bare, &nudged);
            nudged[p][axis] -= 2.0 * step;
            let down = bending_energy(&bare, &nudged);
            let gradient = (up - down) / (2.0 * step);
            let force = forces.get(p).to_dvec3()[axis];
            assert!(
                (force + gradient).abs() <= 1e-6 * (1.0 + gradient.abs()),
                "{p}/{axis}: {force} {gradient}"
            );
        }
    }
}

#[test]
fn uniaxial_stretch_of_a_square_patch_gives_stretch_times_strain() {
    // Stretched by ε along x with z held, the force through the last column over the patch's
    // width is S ε inside the patch; each edge row's springs stand for a whole row of cells where
    // half a row of material lies, which adds (S - G) ε / (n - 1): the stiffness per unit of
    // material is the same at every resolution, the border's share falls as 1/n.
    let strain = 1e-7;
    for n in [24, 48, 96] {
        let model = sheet(n, &COTTONISH);
        let stretched: Vectors<f64> = model
            .positions
            .iter()
            .map(|p| drape::solver::Vec3::from_dvec3(DVec3::new(p.x * (1.0 + strain), p.y, p.z)))
            .collect();
        let mut dynamics = Dynamics::<f64>::new(&model, DVec3::ZERO, 0.0);
        let mut forces = Vectors::zeros(model.particle_count());
        dynamics.forces(&stretched, &Vectors::zeros(model.particle_count()), 0.0, &mut forces);
        let pull: f64 = (0..n).map(|j| -forces.get(j * n + n - 1).x).sum();
        let stress = pull / 1.0;
        let (s, g) = (COTTONISH.stretch, COTTONISH.shear);
        let expected = s * strain + (s - g) * strain / (n - 1) as f64;
        assert!((stress - expected).abs() < 1e-5 * expected, "n = {n}: {stress} against {expected}");
    }
}

/// The resting shape of a plate of `fabric`, `n` particles along x and `n / 4` across, clamped
/// horizontally by its first two columns: implicit Euler to rest.
fn rest_plate(n: usize, fabric: &Fabric, length: f64) -> (Model, Simulation<f64>) {
    let across = n / 4;
    let mut model = Model::default();
    let springs = SpringParams { stiffness: 1.0, damping: 0.0 };
    let pins = (0..across).flat_map(|j| [[0, j], [1, j]]).collect();
    let cloth = Cloth {
        size: [length, 0.25 * length],
        resolution: [n, across],
        center: DVec3::new(0.5 * length, 0.0, 0.0),
        orientation: Orientation::Horizontal,
        pins,
        ..Cloth::square_metre(n, springs)
    };
    model.add_fabric_cloth(&cloth, fabric);
    let config =
        Config { integrator: IntegratorKind::ImplicitEuler, dt: 2e-3, drag: 4.0, ..Config::default() };
    let mut sim = Simulation::<f64>::new(&model, &config);
    run_to_rest(&mut sim, 1e-5, 20_000);
    (model, sim)
}

/// Steps until every particle has been slower than `speed` (m/s) for 250 steps in a row (a
/// swing's turning point is slow for a moment only); panics past `max_steps`.
fn run_to_rest(sim: &mut Simulation<f64>, speed: f64, max_steps: u64) {
    let (mut steps, mut slow) = (0, 0);
    loop {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        steps += 1;
        let fastest = sim.state().velocities.iter().map(|v| v.to_dvec3().length()).fold(0.0, f64::max);
        slow = if fastest < speed { slow + 1 } else { 0 };
        if slow == 250 {
            return;
        }
        assert!(steps < max_steps, "not at rest after {steps} steps: {fastest} m/s");
    }
}

#[test]
fn a_drape_converges_with_the_resolution() {
    // The same fabric at 24, 48 and 96 particles along: the free corners' resting positions (the
    // material points all three grids share) approach each other, the gap halving or better with
    // each halving of the spacing.
    let length = 0.3;
    let tips: Vec<DVec3> = [24, 48, 96]
        .into_iter()
        .map(|n| {
            let (model, sim) = rest_plate(n, &COTTONISH, length);
            let across = n / 4;
            let corners = [n - 1, across * n - 1];
            let _ = model;
            corners.iter().map(|&p| sim.state().positions.get(p).to_dvec3()).sum::<DVec3>() / 2.0
        })
        .collect();
    let (coarse, fine) = ((tips[0] - tips[1]).length(), (tips[1] - tips[2]).length());
    let order = (coarse / fine).log2();
    eprintln!("tips {tips:?}: gaps {coarse:.3e} m, {fine:.3e} m, observed order {order:.2}");
    assert!(tips[2].y < -0.01 * length, "the plate sags: {tips:?}");
    assert!(order > 0.8, "gaps {coarse:.3e} m then {fine:.3e} m: order {order:.2}");
}

#[test]
fn the_elastica_shooting_solve_meets_the_small_deflection_beam() {
    // For small λ the cantilever is a linear beam: tip deflection w l⁴ / (8 B), chord angle λ/8.
    for lambda in [1e-3, 1e-2] {
        let angle = elastica_chord_angle(lambda);
        assert!((angle / (lambda / 8.0) - 1.0).abs() < 1e-2, "λ = {lambda}: {angle}");
    }
    // Peirce's cantilever: a chord angle of 41.5° at about λ = 8 (his approximation gives 7.6).
    let peirce = elastica_chord_angle(8.0).to_degrees();
    assert!((40.0..44.0).contains(&peirce), "{peirce}°");
}

/// The scene of a cantilever of λ = `lambda`: a strip 42 particles long and 4 wide, clamped by
/// its first two columns, with the fabric's bending rigidity set from λ. Holding both columns
/// holds the slope between them: the clamp's edge is midway between them, which leaves a free
/// length of 40.5 spacings, 0.2 m.
fn cantilever(lambda: f64) -> String {
    let (free, density, g) = (0.2, 0.2, 9.81);
    let bending = density * g * free * free * free / lambda;
    let spacing = free / 40.5;
    let pins: Vec<String> = (0..4).flat_map(|j| [format!("[0, {j}]"), format!("[1, {j}]")]).collect();
    format!(
        r#"{{
  "duration": 30, "integrator": "implicit_euler", "dt": 0.002, "drag": 4, "stop_at_rest": 1e-5,
  "error_estimate": "none", "output": {{"frames": "final"}},
  "bodies": [{{
    "type": "cloth", "size": [{length}, {width}], "resolution": [42, 4], "center": [{center}, 0, 0],
    "material": {{"density": {density}, "stretch": 5000, "shear": 500, "bending": {bending}}},
    "pin": [{pins}]
  }}]
}}"#,
        length = 41.0 * spacing,
        width = 3.0 * spacing,
        center = 41.0 * spacing / 2.0 - 0.5 * spacing,
        pins = pins.join(", ")
    )
}

#[test]
fn a_cantilever_rests_at_the_heavy_elasticas_chord_angle() {
    for lambda in [2.0, 5.0, 10.0, 20.0] {
        let scene = Scene::from_json(cantilever(lambda).as_bytes()).expect("a valid scene");
        let compiled = scene.compile();
        let mut sim = Simulation::<f64>::new(&compiled.model, &compiled.config);
        run_to_rest(&mut sim, 1e-5, 15_000);
        let x = |p: usize| sim.state().positions.get(p).to_dvec3();
        // From the clamp's edge, midway between columns 0 and 1, to the tip, column 41; the
        // strip's rows move alike.
        let chords: Vec<f64> = (0..4)
            .map(|j| {
                let d = x(j * 42 + 41) - 0.5 * (x(j * 42) + x(j * 42 + 1));
                (-d.y).atan2(d.x)
            })
            .collect();
        let simulated = chords.iter().sum::<f64>() / 4.0;
        let exact = elastica_chord_angle(lambda);
        eprintln!("λ = {lambda}: {:.2}° against {:.2}°", simulated.to_degrees(), exact.to_degrees());
        assert!(
            (simulated - exact).abs().to_degrees() < 1.5,
            "λ = {lambda}: {:.2}° against the elastica's {:.2}°",
            simulated.to_degrees(),
            exact.to_degrees()
        );
    }
}

#[test]
fn coincident_ends_of_a_zero_length_spring_stay_finite() {
    let mut model = Model::default();
    let spring = SpringParams { stiffness: 50.0, damping: 0.3 };
    let chain = Chain {
        start: DVec3::ZERO,
        end: DVec3::ZERO,
        count: 2,
        mass: 0.2,
        velocity: DVec3::ZERO,
        spring,
        rest_length: Some(0.0),
        pins: vec![],
    };
    model.add_chain(&chain);
    for integrator in [IntegratorKind::SymplecticEuler, IntegratorKind::Rk4, IntegratorKind::ImplicitEuler] {
        let config = Config { integrator, gravity: DVec3::ZERO, ..Config::default() };
        let mut sim = Simulation::<f64>::new(&model, &config);
        for _ in 0..100 {
            sim.step().expect("finite");
        }
        assert!(sim.state().positions.iter().all(|p| p.to_dvec3() == DVec3::ZERO), "{integrator:?}");
    }
}

#[test]
fn a_stretched_zero_length_spring_oscillates_at_its_analytic_frequency() {
    // Two particles of mass m on a spring of rest length 0: f = -k (q - p) in every direction, so
    // the separation oscillates at ω = √(2k/m) (reduced mass m/2) about 0, through it.
    let (k, m, start): (f64, f64, f64) = (50.0, 0.1, 0.3);
    let text = format!(
        r#"{{"duration": 1, "dt": 1e-5, "gravity": [0, 0, 0], "error_estimate": "none",
            "bodies": [{{"type": "chain", "start": [0, 0, 0], "end": [{start}, 0, 0], "count": 2,
                         "mass": {}, "spring": {{"k": {k}, "rest_length": 0}}}}]}}"#,
        2.0 * m
    );
    let compiled = Scene::from_json(text.as_bytes()).expect("rest_length 0 is valid").compile();
    let mut sim = Simulation::<f64>::new(&compiled.model, &compiled.config);
    let omega = (2.0 * k / m).sqrt();
    for _ in 0..compiled.steps {
        sim.step().expect("finite");
        let d = sim.state().positions.get(1).to_dvec3() - sim.state().positions.get(0).to_dvec3();
        let expected = start * (omega * sim.time()).cos();
        assert!((d.x - expected).abs() < 1e-3 * start, "t = {}: {} against {expected}", sim.time(), d.x);
    }
}

/// The pointers of a scene's problems, or none when it is valid.
fn problems(text: &str) -> Vec<String> {
    match Scene::from_json(text.as_bytes()) {
        Ok(_) => Vec::new(),
        Err(e) => e.field_errors().iter().map(|f| f.pointer.clone()).collect(),
    }
}

fn cloth_with(fields: &str) -> String {
    format!(r#"{{"duration": 1, "bodies": [{{"type": "cloth", "resolution": [4, 4] {fields}}}]}}"#)
}

#[test]
fn a_material_excludes_springs_and_mass_and_checks_its_values() {
    let material = r#""material": {"density": 0.2, "stretch": 1000, "shear": 50, "bending": 1e-5}"#;
    assert_eq!(problems(&cloth_with(&format!(", {material}"))), Vec::<String>::new());
    assert_eq!(problems(&cloth_with(&format!(r#", {material}, "springs": {{}}"#))), ["/bodies/0/springs"]);
    assert_eq!(problems(&cloth_with(&format!(r#", {material}, "mass": 1"#))), ["/bodies/0/mass"]);
    assert_eq!(
        problems(&cloth_with(
            r#", "material": {"density": 0.2, "stretch": 100, "shear": 100, "bending": 1e-5}"#
        )),
        ["/bodies/0/material/shear"]
    );
    assert_eq!(
        problems(&cloth_with(r#", "material": {"density": -1, "stretch": 1000, "shear": 50, "bending": 0}"#)),
        ["/bodies/0/material/density", "/bodies/0/material/bending"]
    );
    assert_eq!(problems(&cloth_with(r#", "material": "linen""#)), ["/bodies/0/material"]);
    assert_eq!(
        problems(&cloth_with(
            r#", "material": {"density": 1, "stretch": 1000, "shear": 50, "bending": 1e-5, "thickness": 1}"#
        )),
        ["/bodies/0/material/thickness"]
    );
    // A grid so fine that its springs would pass 1e30 N/m.
    assert_eq!(
        problems(&format!(
            r#"{{"duration": 1, "bodies": [{{"type": "cloth", "size": [1e-29, 1e5], "resolution": [4, 4], {material}}}]}}"#
        )),
        ["/bodies/0/material"]
    );
}

#[test]
fn a_cloth_of_a_material_weighs_its_density_times_its_area() {
    let text = r#"{"duration": 1, "bodies": [{"type": "cloth", "size": [0.6, 0.4], "resolution": [7, 5],
        "material": {"density": 0.25, "stretch": 1000, "shear": 50, "bending": 1e-5}}]}"#;
    let compiled = Scene::from_json(text.as_bytes()).expect("valid").compile();
    assert!((compiled.model.total_mass() - 0.25 * 0.6 * 0.4).abs() < 1e-15);
    // A corner carries a quarter cell, an edge particle half a cell, an inner one a whole cell.
    let cell = 0.25 * 0.1 * 0.1;
    assert!((compiled.model.masses[0] - cell / 4.0).abs() < 1e-18);
    assert!((compiled.model.masses[1] - cell / 2.0).abs() < 1e-18);
    assert!((compiled.model.masses[8] - cell).abs() < 1e-18);
    // No springs two apart: structural and shear only, and bending elements.
    assert_eq!(compiled.model.springs.len(), 6 * 5 + 7 * 4 + 2 * 6 * 4);
    assert_eq!(compiled.model.bending.len(), 5 * 5 + 7 * 3 + 6 * 4);
    assert_eq!(scene_springs(text), compiled.model.springs.len() as u64);
}

fn scene_springs(text: &str) -> u64 {
    Scene::from_json(text.as_bytes()).expect("valid").bodies[0].spring_count()
}

#[test]
fn bending_model_must_match_the_bodys_stiffness() {
    let material = r#""material": {"density": 0.2, "stretch": 1000, "shear": 50, "bending": 1e-5}"#;
    assert_eq!(
        problems(&cloth_with(&format!(r#", {material}, "bending_model": "dihedral""#))),
        Vec::<String>::new()
    );
    assert_eq!(
        problems(&cloth_with(&format!(r#", {material}, "bending_model": "springs""#))),
        ["/bodies/0/bending_model"]
    );
    assert_eq!(problems(&cloth_with(r#", "bending_model": "dihedral""#)), ["/bodies/0/bending_model"]);
    assert_eq!(problems(&cloth_with(r#", "bending_model": "springs""#)), Vec::<String>::new());
}

#[test]
fn a_mesh_of_a_material_bends_by_hinges_and_weighs_its_area() {
    let text = r#"{"duration": 1, "bodies": [{"type": "mesh",
        "vertices": [0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1], "triangles": [0, 2, 1, 1, 2, 3],
        "material": {"density": 0.3, "stretch": 900, "shear": 100, "bending": 2e-5}}]}"#;
    let compiled = Scene::from_json(text.as_bytes()).expect("valid").compile();
    assert!((compiled.model.total_mass() - 0.3).abs() < 1e-15);
    // One interior edge, one hinge: c = B / (A0 + A1).
    assert_eq!(compiled.model.bending.len(), 1);
    assert!((compiled.model.bending[0].stiffness - 2e-5).abs() < 1e-18);
    // Van Gelder: an edge of one right triangle of area ½ and length 1 has k = (8/9) 900 · ½.
    let leg = compiled.model.springs.iter().find(|s| (s.i, s.j) == (0, 1)).expect("the edge 0-1");
    assert!((leg.stiffness - 400.0).abs() < 1e-9, "{}", leg.stiffness);
}

#[test]
fn a_mesh_whose_material_would_overflow_on_its_slivers_is_refused() {
    let text = |stretch: f64| {
        format!(
            r#"{{"duration": 1, "bodies": [{{"type": "mesh",
                "vertices": [0, 0, 0, 1e-6, 0, 0, 0, 0, 1e6], "triangles": [0, 2, 1],
                "material": {{"density": 0.3, "stretch": {stretch:e}, "shear": 1, "bending": 1e-5}}}}]}}"#
        )
    };
    // The short edge's k = (8/9) S A / |e|² = (8/9) S 0.5 / 1e-12.
    assert_eq!(problems(&text(1e3)), Vec::<String>::new());
    assert_eq!(problems(&text(1e20)), ["/bodies/0/material"]);
}

/// The material of the first body of a scene whose cloth has `material`, or the scene's problems
/// as `pointer: detail`.
fn material_of(material: &str) -> Result<FabricSpec, Vec<String>> {
    match Scene::from_json(cloth_with(&format!(r#", "material": {material}"#)).as_bytes()) {
        Ok(scene) => match &scene.bodies[0] {
            Body::Cloth(cloth) => Ok(cloth.material.expect("a material")),
            _ => panic!("a cloth"),
        },
        Err(e) => Err(e.field_errors().iter().map(|f| format!("{}: {}", f.pointer, f.detail)).collect()),
    }
}

#[test]
fn a_material_is_a_preset_by_name_or_a_preset_with_values_replaced() {
    assert!(FABRIC_PRESETS.len() >= 5);
    for (name, preset) in FABRIC_PRESETS {
        // Every preset is a valid material, with the default damping.
        assert_eq!(material_of(&format!(r#""{name}""#)), Ok(preset), "{name}");
        assert_eq!(material_of(&format!(r#"{{"preset": "{name}"}}"#)), Ok(preset), "{name}");
        assert!(preset.shear < preset.stretch && preset.damping == DEFAULT_DAMPING_TIME, "{name}");
        // A field beside the preset replaces the preset's value and only it.
        let damped = material_of(&format!(r#"{{"preset": "{name}", "damping": 0.002}}"#));
        assert_eq!(damped, Ok(FabricSpec { damping: 0.002, ..preset }), "{name}");
        let heavier = material_of(&format!(r#"{{"preset": "{name}", "density": 1.5}}"#));
        assert_eq!(heavier, Ok(FabricSpec { density: 1.5, ..preset }), "{name}");
    }
    for required in ["cotton", "denim", "silk", "wool", "polyester"] {
        assert!(FABRIC_PRESETS.iter().any(|(name, _)| *name == required), "{required}");
    }
    // An unknown name is refused at the material, with every known name in the reason.
    let refused = material_of(r#""linen""#).unwrap_err();
    assert_eq!(refused.len(), 1);
    assert!(refused[0].starts_with("/bodies/0/material: unknown preset `linen`"), "{refused:?}");
    for (name, _) in FABRIC_PRESETS {
        assert!(refused[0].contains(&format!("`{name}`")), "{name} in {refused:?}");
    }
    assert!(material_of(r#"{"preset": "linen", "damping": 0}"#).unwrap_err()[0].contains("`denim`"));
    // Without a preset every value but the damping is needed; a replaced value is checked.
    let missing = material_of(r#"{"stretch": 1000, "shear": 50, "bending": 1e-5}"#).unwrap_err();
    assert!(missing[0].starts_with("/bodies/0/material/density: missing field"), "{missing:?}");
    let negative = material_of(r#"{"preset": "silk", "bending": -1}"#).unwrap_err();
    assert_eq!(negative.len(), 1);
    assert!(negative[0].starts_with("/bodies/0/material/bending"), "{negative:?}");
    assert!(material_of("3").unwrap_err()[0].contains("preset"));
}

#[test]
fn a_preset_drapes_the_same_by_name_as_by_its_values() {
    let (_, denim) = FABRIC_PRESETS.iter().find(|(name, _)| *name == "denim").expect("denim");
    let by_values = format!(
        r#"{{"density": {}, "stretch": {}, "shear": {}, "bending": {}}}"#,
        denim.density, denim.stretch, denim.shear, denim.bending
    );
    let compile = |material: &str| {
        Scene::from_json(cloth_with(&format!(r#", "material": {material}"#)).as_bytes())
            .expect("valid")
            .compile()
    };
    let (named, valued) = (compile(r#""denim""#), compile(&by_values));
    assert_eq!(named.model.masses, valued.model.masses);
    assert_eq!(named.model.springs, valued.model.springs);
    assert_eq!(named.model.bending, valued.model.bending);
}
