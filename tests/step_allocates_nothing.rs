//! Guards the rule that a simulation step allocates nothing, on any thread: every integrator,
//! both precisions, on a cloth with every stage a scene can switch on, on bodies whose springs
//! are not a grid, and on cloths large enough that the solver's pool runs bands of a pass on its
//! worker threads — all stepped under an allocator that counts every allocation in the process.
//!
//! The count is process-wide, so this binary holds a single test: another test running beside it
//! (the harness runs tests on threads of their own) would add its allocations to the count.

// Counting allocations needs a global allocator, which is an unsafe impl; it forwards to the
// system allocator unchanged.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use drape::run::Control;
use drape::scene::Scene;
use drape::solver::{IntegratorKind, Real, Simulation, parallel};

/// Counts allocations and reallocations made by any thread of the process.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// Allocations made so far by every thread.
fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::SeqCst)
}

/// Every stage a scene can switch on: colliders of each shape, fixed and moving, wind of both
/// models with gusts, strain limiting and self-collision.
const ALL_STAGES: [&str; 3] = [
    r#""colliders": [{"type": "plane", "point": [0, 0.9, 0], "normal": [0, 1, 0]},
                     {"type": "sphere", "center": [0, 0.7, 0], "radius": 0.25},
                     {"type": "box", "center": [0.3, 0.8, 0], "half_extents": [0.1, 0.1, 0.1]},
                     {"type": "cylinder", "center": [-0.3, 0.8, 0], "radius": 0.1, "height": 0.2},
                     {"type": "mesh", "vertices": [-1, 0.85, -1, 1, 0.85, -1, 1, 0.85, 1, -1, 0.85, 1], "triangles": [0, 2, 1, 0, 3, 2],
                      "motion": {"velocity": [0, 0.1, 0], "angular_velocity": [0, 0.5, 0]}},
                     {"type": "sphere", "center": [0, 0, 0], "radius": 0.1,
                      "motion": {"keyframes": [{"t": 0, "translation": [0.2, 0.9, 0]}, {"t": 1, "translation": [-0.2, 0.9, 0]}]}}],
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

/// A cloth of 128 × 128 particles: 16,384, eight bands' worth of
/// [`parallel::MIN_PARTICLES_PER_BAND`], so its passes run in bands on the pool's threads.
const LARGE_CLOTH: &str = r#"[{"type": "cloth", "resolution": [128, 128], "pin": [[0, 0], [127, 0]]}]"#;

/// The time step of the small scenes.
const SMALL_SCENES_DT: &str = r#""dt": 0.0002,"#;

/// The time step of the large cloth: its particles are about ten times closer and a hundred
/// times lighter than the small cloth's, so the explicit integrators need a step about ten times
/// shorter (the stable step scales as √(m/k)).
const LARGE_CLOTH_DT: &str = r#""dt": 0.00002,"#;

/// Allocations, on any thread, during `steps` steps of `bodies` with `stages` after a first step
/// (which may set up what later steps reuse), stepped on the solver's pool as a run is. `dt` is
/// a scene member (`"dt": ...,`) or empty.
fn allocations_stepping<T: Real>(
    integrator: IntegratorKind,
    stages: &str,
    bodies: &str,
    dt: &str,
    steps: usize,
) -> usize {
    let scene = Scene::from_json(
        format!(
            r#"{{"duration": 1, {dt} "integrator": "{}", {stages}, "bodies": {bodies}}}"#,
            integrator.name()
        )
        .as_bytes(),
    )
    .unwrap();
    let compiled = scene.compile();
    let mut simulation = Simulation::<T>::new(&compiled.model, &compiled.config);
    if stages == ALL_STAGES[0] {
        for stage in [
            "wind",
            "strain_limit",
            "self_collision",
            "plane",
            "sphere",
            "box",
            "cylinder",
            "mesh",
            "moving_colliders",
        ] {
            assert!(simulation.stages().contains(&stage), "{stage} is not among {:?}", simulation.stages());
        }
    }
    parallel::install(|| {
        simulation.step().unwrap();
        let before = allocations();
        for _ in 0..steps {
            simulation.step().unwrap();
        }
        allocations() - before
    })
}

#[test]
fn no_step_allocates_on_any_thread() {
    // The counter does count: a run records frames into growing buffers.
    let before = allocations();
    let scene = Scene::from_json(br#"{"duration": 0.01, "bodies": [{"type": "chain"}]}"#).unwrap();
    drape::run::execute(&scene.compile(), &Control::new());
    assert!(allocations() > before);

    // Warm-up: the pool's threads allocate as they start (their names, their queues), which the
    // pool's creation does not wait for; a job run on every one of them has waited for that.
    parallel::pool().broadcast(|_| ());

    // It counts on every thread: one allocation on each of the pool's threads shows.
    let threads = parallel::pool().current_num_threads();
    let before = allocations();
    parallel::pool().broadcast(|_| drop(std::hint::black_box(Box::new(1u64))));
    assert!(allocations() - before >= threads, "{threads} threads");

    for stages in ALL_STAGES {
        for integrator in IntegratorKind::ALL {
            let name = integrator.name();
            assert_eq!(
                allocations_stepping::<f64>(integrator, stages, CLOTH, SMALL_SCENES_DT, 200),
                0,
                "{name} in f64 with {stages}"
            );
            assert_eq!(
                allocations_stepping::<f32>(integrator, stages, CLOTH, SMALL_SCENES_DT, 200),
                0,
                "{name} in f32 with {stages}"
            );
        }
    }
    for integrator in IntegratorKind::ALL {
        let name = integrator.name();
        for stages in &ALL_STAGES[1..] {
            assert_eq!(
                allocations_stepping::<f64>(integrator, stages, NOT_GRIDS, SMALL_SCENES_DT, 200),
                0,
                "{name} in f64 with {stages}"
            );
            assert_eq!(
                allocations_stepping::<f32>(integrator, stages, NOT_GRIDS, SMALL_SCENES_DT, 200),
                0,
                "{name} in f32 with {stages}"
            );
        }
    }
    for integrator in IntegratorKind::ALL {
        let name = integrator.name();
        for stages in &ALL_STAGES[1..] {
            assert_eq!(
                allocations_stepping::<f32>(integrator, stages, LARGE_CLOTH, LARGE_CLOTH_DT, 5),
                0,
                "{name} in f32 with {stages} on the large cloth"
            );
        }
    }
}
