//! Running a sweep in this process, on a fixed number of threads, for `drape sweep`.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::Sweep;
use super::table::{Outcome, Table, compile_for_table};
use crate::run::{Control, Recording, execute};
use crate::scene::{Compiled, Scene};

/// Runs the reference and every variant, `threads` at a time (at least one), and makes the table.
pub fn run_locally(sweep: &Sweep, threads: usize) -> Table {
    run_locally_with(sweep, threads, &|scene| Ok(compile_for_table(scene)), &AtomicUsize::new(0))
}

/// [`run_locally`], each scene compiled by `compile` (which may refuse it, in words); `finished`
/// counts the runs that have ended, for a caller showing progress from another thread.
pub fn run_locally_with(
    sweep: &Sweep,
    threads: usize,
    compile: &(dyn Fn(&Scene) -> Result<Compiled, String> + Sync),
    finished: &AtomicUsize,
) -> Table {
    let scenes: Vec<&Scene> = sweep.reference.iter().chain(sweep.variants.iter().map(|v| &v.scene)).collect();
    let results: Vec<Mutex<Option<Result<Recording, String>>>> =
        scenes.iter().map(|_| Mutex::new(None)).collect();
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1).min(scenes.len().max(1)) {
            scope.spawn(|| {
                loop {
                    let index = next.fetch_add(1, Ordering::Relaxed);
                    let Some(scene) = scenes.get(index) else { break };
                    let outcome = catch_unwind(AssertUnwindSafe(|| {
                        compile(scene).map(|compiled| execute(&compiled, &Control::new()))
                    }))
                    .map_err(|panic| {
                        let message = panic
                            .downcast_ref::<&str>()
                            .map(|s| s.to_string())
                            .or_else(|| panic.downcast_ref::<String>().cloned())
                            .unwrap_or_else(|| "unknown".into());
                        format!("the run failed: {message}")
                    })
                    .and_then(|compiled| compiled);
                    *results[index].lock().unwrap_or_else(|e| e.into_inner()) = Some(outcome);
                    finished.fetch_add(1, Ordering::Relaxed);
                }
            });
        }
    });
    let mut outcomes = results.into_iter().map(|m| match m.into_inner().unwrap_or_else(|e| e.into_inner()) {
        Some(Ok(recording)) => Outcome::Finished(Box::new(recording.into())),
        Some(Err(message)) => Outcome::Pending { status: "failed".into(), detail: Some(message) },
        None => Outcome::Pending { status: "failed".into(), detail: Some("the run did not report".into()) },
    });
    let reference = sweep.reference.as_ref().and_then(|_| outcomes.next());
    let variants: Vec<Outcome> = outcomes.collect();
    Table::assemble(sweep, reference.as_ref(), &variants)
}
