//! What `drape run` and `drape sweep` show on standard error while they work, here or on a
//! server: a progress bar (steps or runs done, simulated time, rate, time left). It is drawn only
//! when standard error is a terminal and the caller did not ask for quiet, so logs, pipes and CI
//! output stay clean.
//!
//! The work runs on a scoped thread while this thread redraws the bar from the counters the work
//! publishes ([`Control::steps_done`] for a run, a count of ended runs for a sweep, the last
//! event of a job on a server), so the bar costs the work nothing.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

use crate::run::Control;

/// How often the bar is redrawn.
const REDRAW: Duration = Duration::from_millis(100);

/// Whether to draw progress: standard error is a terminal and quiet was not asked for.
pub fn wanted(quiet: bool) -> bool {
    !quiet && std::io::stderr().is_terminal()
}

/// Runs `work`, a run of `steps` steps of `dt` seconds that publishes its progress through
/// `control`, and, if `show`, draws its progress until it returns.
pub fn follow_run<R: Send>(
    show: bool,
    control: &Control,
    steps: u64,
    dt: f64,
    work: impl FnOnce() -> R + Send,
) -> R {
    follow_steps(
        show,
        steps,
        || {
            let done = control.steps_done();
            (done, done as f64 * dt)
        },
        work,
    )
}

/// Runs `work`, a run of `steps` steps whose steps done and simulated time `read` gives (a run
/// on a server, followed through its events), and, if `show`, draws its progress until it returns.
pub fn follow_steps<R: Send>(
    show: bool,
    steps: u64,
    read: impl Fn() -> (u64, f64),
    work: impl FnOnce() -> R + Send,
) -> R {
    follow(
        show,
        steps,
        "{bar:30} {pos}/{len} steps  t = {msg}  {per_sec}  {eta} left",
        || {
            let (done, t) = read();
            (done, format!("{t:.3} s"))
        },
        work,
    )
}

/// Runs `work`, a sweep of `runs` runs that counts the ended ones in `finished`, and, if `show`,
/// draws its progress until it returns.
pub fn follow_sweep<R: Send>(
    show: bool,
    finished: &AtomicUsize,
    runs: usize,
    work: impl FnOnce() -> R + Send,
) -> R {
    follow(
        show,
        runs as u64,
        "{bar:30} {pos}/{len} runs  {per_sec}  {eta} left",
        || (finished.load(Ordering::Relaxed) as u64, String::new()),
        work,
    )
}

fn follow<R: Send>(
    show: bool,
    length: u64,
    template: &str,
    read: impl Fn() -> (u64, String),
    work: impl FnOnce() -> R + Send,
) -> R {
    if !show {
        return work();
    }
    let style = ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar());
    let bar = ProgressBar::new(length).with_style(style);
    std::thread::scope(|scope| {
        let worker = scope.spawn(work);
        while !worker.is_finished() {
            let (position, message) = read();
            bar.set_message(message);
            bar.set_position(position);
            std::thread::sleep(REDRAW);
        }
        bar.finish_and_clear();
        worker.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    })
}
