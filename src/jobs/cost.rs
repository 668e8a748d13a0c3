//! The cost model: the work and the memory of a compiled scene, stage by stage, known before
//! anything runs.
//!
//! Work is counted in element-steps: each step costs one for every particle, every spring,
//! every collider test of a particle (colliders × particles), every self-collision candidate
//! pair, every bending element and every wind triangle, RK4's four force evaluations and implicit Euler's passes
//! counted as that many; the error estimate's companions cost their own steps. Memory is an
//! upper bound in bytes on what a run holds at once: the model and the simulation's arrays (per
//! particle and per spring, by integrator and precision), the self-collision hash and its pairs,
//! the recorded frames and the encoded result, and a companion run beside the main one. Each
//! stage names the scene field that switches it on or sets its size, so that a refusal can point
//! at it. The per-element byte counts are measured figures with a margin: the peak resident
//! memory of `drape run` on cloths, lattices and collider sets of several sizes, with each
//! integrator and stage, stays under the estimate plus [`MEMORY_RESERVE`](crate::config::MEMORY_RESERVE).

use crate::run::{MAX_ROW_CROSSINGS_PER_TRIANGLE, MAX_ROWS};
use crate::scene::{
    Body, ClothShape, ColliderSpec, Compiled, Field, FrameSelection, IntegratorName, MeshColliderSpec,
    Precision, Scene,
};
use crate::solver::{WindModel, candidate_pairs};

use super::record::Plan;

/// Force evaluations over every particle and spring that a step of implicit Euler is counted
/// as: its assembly and a few conjugate-gradient iterations on the multigrid preconditioner (the
/// wall-time limit stops a solve that takes many more).
pub const IMPLICIT_PASSES: u64 = 8;

/// Bytes a particle costs in the model a scene compiles to (positions, velocities, masses, pins,
/// body bookkeeping), whatever the precision.
const MODEL_BYTES_PER_PARTICLE: u64 = 128;
/// Bytes a spring costs in the model.
const MODEL_BYTES_PER_SPRING: u64 = 48;
/// Bytes a bending element costs in the model: four indices, four weights, stiffness and
/// damping in `f64`.
const MODEL_BYTES_PER_BENDING_ELEMENT: u64 = 64;
/// Bytes a bending element costs in a running simulation (the same in `f64`, its copy in the
/// implicit grid solver, the fused passes' force array counted per particle with the rest).
const SIMULATION_BYTES_PER_BENDING_ELEMENT: u64 = 128;
/// Bytes a triangle costs in the model.
const MODEL_BYTES_PER_TRIANGLE: u64 = 16;
/// Real numbers a particle costs in a running simulation, by integrator (state, forces,
/// integrator scratch and, for implicit Euler, the operator, the solver's vectors and the
/// multigrid levels, with each level's half-product: the level above coarsened along one axis,
/// 114 numbers a point on half the points above, about 76 a fine particle over all levels).
fn simulation_reals_per_particle(integrator: IntegratorName) -> u64 {
    match integrator {
        IntegratorName::ExplicitEuler | IntegratorName::SymplecticEuler | IntegratorName::Verlet => 40,
        IntegratorName::Rk4 => 64,
        IntegratorName::ImplicitEuler => 240,
    }
}
/// Bytes a spring of a cloth's grid costs in a running simulation (its row stencils, and for
/// implicit Euler its Jacobian blocks).
fn simulation_bytes_per_grid_spring(integrator: IntegratorName) -> u64 {
    match integrator {
        IntegratorName::ImplicitEuler => 160,
        _ => 48,
    }
}
/// Bytes a spring of any other body costs in a running simulation: the spring list, its sorted
/// runs and their bands, and for implicit Euler the Jacobian blocks and the smoothed-aggregation
/// hierarchy of the spring graph. The hierarchy's levels, prolongators and Galerkin products
/// grow with how many neighbours a particle has within two springs, so the figure is the
/// densest graph a scene may give: a lattice, whose springs reach 26 neighbours and bend across
/// two, at the largest size `--max-springs` allows. A mesh with hinges, whose bending widens
/// the graph the same way, stays under it.
fn simulation_bytes_per_listed_spring(integrator: IntegratorName) -> u64 {
    match integrator {
        IntegratorName::ImplicitEuler => 2048,
        _ => 224,
    }
}
/// Bytes a collider costs: its scene document, its parsed and compiled forms and the stage's.
const BYTES_PER_COLLIDER: u64 = 2048;
/// Bytes a mesh collider's triangle costs: its scene numbers (parsed and compiled), its corners
/// and normals in the hierarchy, the hierarchy's nodes, the pseudo-normals of a closed mesh,
/// and the topology's hash maps while it is built.
pub(super) const BYTES_PER_COLLIDER_TRIANGLE: u64 = 768;
/// Bytes a mesh collider's vertex costs: its scene numbers (as JSON values, parsed and compiled),
/// its entry in the map that joins vertices at one position, and its pseudo-normal.
pub(super) const BYTES_PER_COLLIDER_VERTEX: u64 = 256;
/// Bytes a keyframe costs: its scene numbers as JSON values, parsed and compiled.
const BYTES_PER_KEYFRAME: u64 = 512;
/// Bytes a self-collision candidate pair takes in the pair lists.
pub const BYTES_PER_PAIR: u64 = 8;
/// Bytes of the self-collision hash per particle (buckets at most a quarter full, the sorted
/// entries, cells) and per spring (each end's partner list).
const HASH_BYTES_PER_PARTICLE: u64 = 96;
const HASH_BYTES_PER_SPRING: u64 = 8;
/// Bytes a recorded value costs: the value in the run's precision (counted as 8) and its
/// encoding, twice (the encoded result and its compressed copy); JSON writes a double in at most
/// 25 bytes.
const BYTES_PER_RECORDED_VALUE: u64 = 8 + 2 * 25;

/// Bytes the drape coefficient's measurement takes per specimen triangle (its three edges, its
/// place in the sweep order, its span) and per particle (its final position and projection).
const DRAPE_COEFFICIENT_BYTES_PER_TRIANGLE: u64 = 96;
const DRAPE_COEFFICIENT_BYTES_PER_PARTICLE: u64 = 40;

/// What one stage of a run costs.
#[derive(Clone, Debug, PartialEq)]
pub struct StageCost {
    /// The stage, as `stats.stages` names it, or `bodies`, `frames`, `error_estimate`.
    pub stage: &'static str,
    /// The scene field that switches it on or sets its size (a JSON Pointer).
    pub pointer: String,
    /// Element-steps.
    pub work: u64,
    /// Bytes.
    pub memory: u64,
}

/// The work and memory of a run, stage by stage.
#[derive(Clone, Debug, PartialEq)]
pub struct Cost {
    /// Every stage the scene switches on.
    pub stages: Vec<StageCost>,
    /// Self-collision candidate pairs in the initial layout (0 without self-collision).
    pub pairs: u64,
}

impl Cost {
    /// The cost of a compiled scene whose plan is `plan`.
    pub fn of(scene: &Scene, compiled: &Compiled, plan: &Plan) -> Self {
        let particles = plan.particles;
        let springs = plan.springs;
        let triangles = compiled.model.triangles.len() as u64;
        let steps = plan.steps;
        let real = match compiled.precision {
            Precision::F32 => 4,
            Precision::F64 => 8,
        };
        let per_step = |work: u64| work.saturating_mul(steps);
        let mut stages = Vec::new();
        let mut stage = |stage, pointer: String, work, memory| {
            stages.push(StageCost { stage, pointer, work, memory });
        };

        let model_memory = particles
            .saturating_mul(MODEL_BYTES_PER_PARTICLE)
            .saturating_add(springs.saturating_mul(MODEL_BYTES_PER_SPRING))
            .saturating_add(triangles.saturating_mul(MODEL_BYTES_PER_TRIANGLE));
        // A run's simulation beside its model; the error estimate adds a second one.
        let listed = scene
            .bodies
            .iter()
            .filter(|b| !matches!(b, Body::Cloth(c) if c.shape == ClothShape::Rectangle))
            .map(Body::spring_count)
            .fold(0, u64::saturating_add)
            .min(springs);
        let mut simulation_memory = particles
            .saturating_mul(simulation_reals_per_particle(scene.integrator) * real)
            .saturating_add(
                (springs - listed).saturating_mul(simulation_bytes_per_grid_spring(scene.integrator)),
            )
            .saturating_add(listed.saturating_mul(simulation_bytes_per_listed_spring(scene.integrator)));
        let passes = match scene.integrator {
            IntegratorName::Rk4 => 4,
            IntegratorName::ImplicitEuler => IMPLICIT_PASSES,
            _ => 1,
        };
        let elements = particles.saturating_add(springs);
        let mut step_work = elements.saturating_mul(passes);
        stage(
            "bodies",
            largest_body(scene),
            per_step(elements),
            model_memory.saturating_add(simulation_memory),
        );
        if passes > 1 {
            stage("integrator", "/integrator".into(), per_step(elements.saturating_mul(passes - 1)), 0);
        }

        let bending = compiled.model.bending.len() as u64;
        if bending > 0 {
            // Each element once per force evaluation, and again in each implicit product.
            let work = bending.saturating_mul(passes);
            let memory = bending
                .saturating_mul(MODEL_BYTES_PER_BENDING_ELEMENT + SIMULATION_BYTES_PER_BENDING_ELEMENT);
            step_work = step_work.saturating_add(work);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("bending", body_with_material(scene), per_step(work), memory);
        }
        if !scene.colliders.is_empty() {
            let tests = particles.saturating_mul(scene.colliders.len() as u64);
            let memory = particles
                .saturating_mul(3 * real)
                .saturating_add((scene.colliders.len() as u64).saturating_mul(BYTES_PER_COLLIDER));
            step_work = step_work.saturating_add(tests);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("colliders", "/colliders".into(), per_step(tests), memory);
        }
        let carried: u64 = scene
            .bodies
            .iter()
            .filter(|b| b.pin_motion().is_some())
            .map(|b| match b {
                Body::Cloth(c) => c.pin.len(),
                Body::Chain(c) => c.pin.len(),
                Body::Lattice(l) => l.pin.len(),
                Body::Mesh(m) => m.pin.len(),
            } as u64)
            .fold(0, u64::saturating_add);
        if carried > 0 {
            // Each pin placed every step; its rest offset kept.
            let memory = carried.saturating_mul(32);
            step_work = step_work.saturating_add(carried);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("pin_motion", "/bodies".into(), per_step(carried), memory);
        }
        let moving: Vec<u64> = scene
            .colliders
            .iter()
            .filter_map(|c| c.motion())
            .map(|m| m.keyframes.as_ref().map_or(1, |keys| keys.len() as u64))
            .collect();
        if !moving.is_empty() {
            // Each particle is seen from a moving collider's frame, twice, before its tests.
            let work = particles.saturating_mul(2 * moving.len() as u64);
            let memory = moving
                .iter()
                .fold(0, |sum: u64, &keys| sum.saturating_add(keys.saturating_mul(BYTES_PER_KEYFRAME)));
            step_work = step_work.saturating_add(work);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("moving_colliders", "/colliders".into(), per_step(work), memory);
        }
        for (index, collider) in scene.colliders.iter().enumerate() {
            let ColliderSpec::Mesh(mesh) = collider else { continue };
            let (work, memory) = mesh_collider(mesh, particles);
            step_work = step_work.saturating_add(work);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("mesh", format!("/colliders/{index}/triangles"), per_step(work), memory);
        }
        if let Some(wind) = &compiled.config.wind {
            let work = match wind.model {
                WindModel::Viscous => triangles.saturating_add(particles),
                WindModel::Aerodynamic => triangles,
            };
            let memory =
                particles.saturating_mul(3 * real).saturating_add(triangles.saturating_mul(4 * real));
            step_work = step_work.saturating_add(work);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("wind", "/wind".into(), per_step(work), memory);
        }
        if compiled.config.strain_limit.is_some() {
            let memory = particles.saturating_mul(3 * real);
            step_work = step_work.saturating_add(springs);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("strain_limit", "/strain_limit".into(), per_step(springs), memory);
        }
        let mut pairs = 0;
        if let Some(thickness) = compiled.config.self_collision {
            pairs = candidate_pairs(&compiled.model, thickness);
            // The lists start with room for a pair per particle.
            let held = pairs.max(particles);
            let work = particles.saturating_add(pairs);
            let memory = particles
                .saturating_mul(HASH_BYTES_PER_PARTICLE)
                .saturating_add(springs.saturating_mul(HASH_BYTES_PER_SPRING))
                .saturating_add(held.saturating_mul(BYTES_PER_PAIR));
            step_work = step_work.saturating_add(work);
            simulation_memory = simulation_memory.saturating_add(memory);
            stage("self_collision", "/self_collision/thickness".into(), per_step(work), memory);
        }

        if let Some(tester) = &compiled.drape_tester {
            // Measured once, at the end: at most the row crossings and rows the measurement
            // allows itself before it starts, and the outline's edges.
            let triangles = tester.triangles.len() as u64;
            let crossings = triangles.saturating_mul(MAX_ROW_CROSSINGS_PER_TRIANGLE).max(MAX_ROWS);
            let work = crossings.saturating_add(MAX_ROWS).saturating_add(triangles.saturating_mul(3));
            let memory = triangles
                .saturating_mul(DRAPE_COEFFICIENT_BYTES_PER_TRIANGLE)
                .saturating_add(particles.saturating_mul(DRAPE_COEFFICIENT_BYTES_PER_PARTICLE));
            let specimen = scene
                .bodies
                .iter()
                .position(|b| matches!(b, Body::Cloth(c) if c.shape == ClothShape::Disk))
                .unwrap_or(0);
            stage("drape_coefficient", format!("/bodies/{specimen}/shape"), work, memory);
        }
        let (frames, values) = recorded(compiled, plan);
        if values > 0 {
            let pointer =
                if compiled.output.frames == FrameSelection::All { "/output/fps" } else { "/output/fields" };
            let memory = values
                .saturating_mul(BYTES_PER_RECORDED_VALUE)
                .saturating_add(frames.min(steps.saturating_add(2)).saturating_mul(16));
            stage("frames", pointer.into(), 0, memory);
        }
        if plan.companion_steps > 0 {
            // Companions run one at a time beside the main run, each with a simulation of its own.
            stage(
                "error_estimate",
                "/error_estimate".into(),
                step_work.saturating_mul(plan.companion_steps),
                simulation_memory,
            );
        }
        Self { stages, pairs }
    }

    /// Element-steps of the whole run, companions included.
    pub fn work(&self) -> u64 {
        self.stages.iter().map(|s| s.work).fold(0, u64::saturating_add)
    }

    /// Bytes the run holds at most, companions included.
    pub fn memory(&self) -> u64 {
        self.stages.iter().map(|s| s.memory).fold(0, u64::saturating_add)
    }

    /// Runs holding self-collision pairs at once: the main run and a companion beside it.
    pub fn concurrent_runs(&self) -> u64 {
        if self.stages.iter().any(|s| s.stage == "error_estimate") { 2 } else { 1 }
    }

    /// The stage that costs the most of `measure`.
    pub fn largest(&self, measure: fn(&StageCost) -> u64) -> Option<&StageCost> {
        self.stages.iter().max_by_key(|s| measure(s))
    }
}

/// A mesh collider's work per step and memory: each particle walks the hierarchy twice (its
/// path, then its nearest triangle), each walk counted as the tree's depth in node tests plus a
/// leaf of triangles; the memory is the hierarchy and what building it holds.
fn mesh_collider(mesh: &MeshColliderSpec, particles: u64) -> (u64, u64) {
    let triangles = (mesh.triangles.len() / 3) as u64;
    let depth = u64::from(triangles.max(1).ilog2()) + 1;
    let per_particle = 2 * (depth + crate::solver::BVH_LEAF_SIZE as u64);
    let memory = triangles
        .saturating_mul(BYTES_PER_COLLIDER_TRIANGLE)
        .saturating_add(((mesh.vertices.len() / 3) as u64).saturating_mul(BYTES_PER_COLLIDER_VERTEX));
    (particles.saturating_mul(per_particle), memory)
}

/// The size field of the body with the most particles.
fn largest_body(scene: &Scene) -> String {
    let (at, body) = scene
        .bodies
        .iter()
        .enumerate()
        .max_by_key(|(_, b)| b.particle_count())
        .expect("a valid scene has a body");
    format!("/bodies/{at}{}", size_field(body))
}

/// The `material` of the largest body that has one: what switches the bending elements on.
fn body_with_material(scene: &Scene) -> String {
    let material = |b: &Body| match b {
        Body::Cloth(c) => c.material.is_some(),
        Body::Mesh(m) => m.material.is_some(),
        Body::Chain(_) | Body::Lattice(_) => false,
    };
    scene
        .bodies
        .iter()
        .enumerate()
        .filter(|(_, b)| material(b))
        .max_by_key(|(_, b)| b.particle_count())
        .map_or_else(|| "/bodies".to_string(), |(at, _)| format!("/bodies/{at}/material"))
}

/// The field that sets a body's size.
pub fn size_field(body: &Body) -> &'static str {
    match body {
        Body::Cloth(_) | Body::Lattice(_) => "/resolution",
        Body::Chain(_) => "/count",
        Body::Mesh(_) => "/vertices",
    }
}

/// An upper bound on the frames a run records and on the values they hold: frames ×
/// (3 × particles per vector field + springs for strain + 3 for energy).
pub fn recorded(compiled: &Compiled, plan: &Plan) -> (u64, u64) {
    let output = &compiled.output;
    let frames = match output.frames {
        FrameSelection::All => ((plan.duration * output.fps).floor() as u64).saturating_add(2),
        FrameSelection::Final => 1,
        FrameSelection::None => 0,
    };
    let per_frame = output
        .fields
        .iter()
        .map(|field| match field {
            Field::Positions | Field::Velocities | Field::Normals => plan.particles.saturating_mul(3),
            Field::Energy => 3,
            Field::Strain => plan.springs,
        })
        .fold(0, u64::saturating_add);
    (frames, frames.saturating_mul(per_frame))
}

/// Steps of the error estimate's companions, as planned before they run
/// ([`crate::run::planned_companion_steps`]): at twice the step (and four times, for `richardson3`), or
/// at half (and a quarter) when the doubled step would not be stable or the scene has contacts;
/// for `resolution`, the coarser companions' steps counted in steps of the run by their share
/// of its particles.
pub fn companion_steps(compiled: &Compiled) -> u64 {
    crate::run::planned_companion_steps(compiled)
}
