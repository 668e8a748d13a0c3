//! Guards the rule that a simulation step allocates nothing: every integrator, both precisions,
//! on a cloth with gravity, drag and all three spring families, stepped under an allocator that
//! counts.

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

fn allocations_during_steps<T: Real>(integrator: IntegratorKind) -> usize {
    let scene = Scene::from_json(
        format!(
            r#"{{"duration": 1, "dt": 0.0002, "drag": 0.5, "integrator": "{}",
                "bodies": [{{"type": "cloth", "resolution": [12, 12], "pin": [[0, 0], [11, 0]]}}]}}"#,
            integrator.name()
        )
        .as_bytes(),
    )
    .unwrap();
    let compiled = scene.compile();
    let mut simulation = Simulation::<T>::new(&compiled.model, &compiled.config);
    simulation.step().unwrap();
    let before = ALLOCATIONS.with(Cell::get);
    for _ in 0..200 {
        simulation.step().unwrap();
    }
    ALLOCATIONS.with(Cell::get) - before
}

#[test]
fn no_integrator_allocates_in_a_step() {
    for integrator in IntegratorKind::ALL {
        assert_eq!(allocations_during_steps::<f64>(integrator), 0, "{} in f64", integrator.name());
        assert_eq!(allocations_during_steps::<f32>(integrator), 0, "{} in f32", integrator.name());
    }
    // The counter does count: a run records frames into growing buffers.
    let before = ALLOCATIONS.with(Cell::get);
    let scene = Scene::from_json(br#"{"duration": 0.01, "bodies": [{"type": "chain"}]}"#).unwrap();
    drape::run::execute(&scene.compile(), &Control::new());
    assert!(ALLOCATIONS.with(Cell::get) > before);
}
