//! Guards the rule that a simulation step allocates nothing: every integrator, both precisions,
//! on a cloth with every stage a scene can switch on, and on bodies whose springs are not a grid,
//! stepped under an allocator that counts.

// Counting allocations needs a global allocator, which is an unsafe impl; it forwards to the
// system allocator unchanged.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use drape::run::Control;
use drape::scene::Scene;
use drape::solver::{IntegratorKind, Real, Simulation};

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// Every stage a scene can switch on: colliders of each shape, wind of both models with gusts,
/// strain limiting and self-collision.
const ALL_STAGES: [&str; 3] = [
    r#""colliders": [{"type": "plane", "point": [0, 0.9, 0], "normal": [0, 1, 0]},
                     {"type": "sphere", "center": [0, 0.7, 0], "radius": 0.25},
                     {"type": "box", "center": [0.3, 0.8, 0], "half_extents": [0.1, 0.1, 0.1]},
                     {"type": "cylinder", "center": [-0.3, 0.8, 0], "radius": 0.1, "height": 0.2}],
       "wind": {"model": "aerodynamic", "velocity": [2, 0, 1], "gust": {"amplitude": 0.5, "frequency": 1, "wavelength": 1}},
       "strain_limit": 0.1, "self_collision": {"thickness": 0.01}"#,
    r#""wind": {"model": "viscous", "velocity": [2, 0, 1]}"#,
    r#""drag": 0.5"#,
];

/// A cloth, whose springs the stencil pass evaluates.
const CLOTH: &str = r#"[{"type": "cloth", "resolution": [12, 12], "pin": [[0, 0], [11, 0]]}]"#;

/// Bodies whose springs go through the spring-run pass.
const NOT_GRIDS: &str = r#"[{"type": "lattice", "resolution": [5, 4, 3]}, {"type": "chain"},
    {"type": "mesh", "vertices": [0, 1, 0, 0.1, 1, 0, 0.2, 1, 0, 0, 0.9, 0, 0.1, 0.9, 0, 0.2, 0.9, 0.05],
     "triangles": [0, 3, 1, 1, 3, 4, 1, 4, 2, 2, 4, 5]}]"#;

fn allocations_during_steps<T: Real>(integrator: IntegratorKind, stages: &str) -> usize {
    allocations_stepping::<T>(integrator, stages, CLOTH)
}

fn allocations_stepping<T: Real>(integrator: IntegratorKind, stages: &str, bodies: &str) -> usize {
    let scene = Scene::from_json(
        format!(
            r#"{{"duration": 1, "dt": 0.0002, "integrator": "{}", {stages}, "bodies": {bodies}}}"#,
            integrator.name()
        )
        .as_bytes(),
    )
    .unwrap();
    let compiled = scene.compile();
    let mut simulation = Simulation::<T>::new(&compiled.model, &compiled.config);
    if stages == ALL_STAGES[0] {
        for stage in ["wind", "strain_limit", "self_collision", "plane", "sphere", "box", "cylinder"] {
            assert!(simulation.stages().contains(&stage), "{stage} is not among {:?}", simulation.stages());
        }
    }
    simulation.step().unwrap();
    let before = ALLOCATIONS.with(Cell::get);
    for _ in 0..200 {
        simulation.step().unwrap();
    }
    ALLOCATIONS.with(Cell::get) - before
}

#[test]
fn no_stage_of_any_integrator_allocates_in_a_step() {
    for stages in ALL_STAGES {
        for integrator in IntegratorKind::ALL {
            let name = integrator.name();
            assert_eq!(allocations_during_steps::<f64>(integrator, stages), 0, "{name} in f64 with {stages}");
            assert_eq!(allocations_during_steps::<f32>(integrator, stages), 0, "{name} in f32 with {stages}");
        }
    }
    for integrator in IntegratorKind::ALL {
        let name = integrator.name();
        for stages in &ALL_STAGES[1..] {
            assert_eq!(
                allocations_stepping::<f64>(integrator, stages, NOT_GRIDS),
                0,
                "{name} in f64 with {stages}"
            );
            assert_eq!(
                allocations_stepping::<f32>(integrator, stages, NOT_GRIDS),
                0,
                "{name} in f32 with {stages}"
            );
        }
    }
    // The counter does count: a run records frames into growing buffers.
    let before = ALLOCATIONS.with(Cell::get);
    let scene = Scene::from_json(br#"{"duration": 0.01, "bodies": [{"type": "chain"}]}"#).unwrap();
    drape::run::execute(&scene.compile(), &Control::new());
    assert!(ALLOCATIONS.with(Cell::get) > before);
}

/// A cloth large enough that implicit Euler applies its system on several threads: the solve
/// enters the thread pool once per step, and the pool's shared queue allocates one block of 63
/// entries as it fills, so at most one allocation in these 5 steps.
#[test]
fn implicit_euler_on_a_cloth_large_enough_for_threads_allocates_at_most_the_pools_queue_blocks() {
    let scene = Scene::from_json(
        br#"{"duration": 1, "dt": 0.002, "integrator": "implicit_euler",
             "bodies": [{"type": "cloth", "resolution": [128, 128], "pin": [[0, 0], [127, 0]]}]}"#,
    )
    .unwrap();
    let compiled = scene.compile();
    let mut simulation = Simulation::<f32>::new(&compiled.model, &compiled.config);
    simulation.step().unwrap();
    let before = ALLOCATIONS.with(Cell::get);
    for _ in 0..5 {
        simulation.step().unwrap();
    }
    assert!(ALLOCATIONS.with(Cell::get) - before <= 1);
}
