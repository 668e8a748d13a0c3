//! The solver's threads: one pool with a thread per core, and the rule for when a scene uses it.
//!
//! A large cloth's force pass is cut into bands of rows that threads of [`pool`] run side by side
//! (see [`grid`](crate::solver::forces::grid)), and the other springs into bands of particles
//! (see [`spring_runs`](crate::solver::forces::spring_runs)). Each band recomputes the few rows of
//! springs it shares with its neighbours instead of exchanging partial sums, so every particle's
//! force is summed in the same order whatever the number of bands: a result does not depend on
//! how many threads computed it. A scene too small to pay for the hand-off stays in one band; a cloth
//! somewhat larger runs in bands only while another thread takes one ([`join_side_by_side`]
//! tells). Passes that compute each row alone (the implicit solver's) cut their row-major arrays
//! with [`in_bands`].
//!
//! A run should execute inside the pool ([`install`]), so that handing a band to the other
//! threads is a push onto a work-stealing deque rather than a wake-up. When every pool thread is
//! busy with a run of its own (a service filling the cores with jobs), a run's bands are simply
//! executed one after another by its own thread: the cores are never oversubscribed. The halves
//! of a pass are [`join`]ed so that both threads leave it at once and awake, ready for the next
//! pass of the step; a thread spins only while another runs a band of the same pass, and never
//! for longer than its own share took.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::time::{Duration, Instant};

/// The fewest particles a band is given: below about this many a band's work is not much larger
/// than the cost of handing it to another thread.
pub const MIN_PARTICLES_PER_BAND: usize = 2048;

/// The environment variable that sets the pool's size (a positive integer); by default the pool
/// has one thread per available core.
pub const THREADS_VARIABLE: &str = "DRAPE_SOLVER_THREADS";

/// The solver's thread pool: [`THREADS_VARIABLE`] threads, or one per available core.
pub fn pool() -> &'static rayon::ThreadPool {
    static POOL: OnceLock<rayon::ThreadPool> = OnceLock::new();
    POOL.get_or_init(|| {
        let configured = std::env::var(THREADS_VARIABLE).ok().and_then(|v| v.trim().parse::<usize>().ok());
        let threads = configured
            .filter(|&n| n > 0)
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("drape-solver-{i}"))
            .build()
            .expect("the solver's threads can be started")
    })
}

/// Runs `work` on a thread of the solver's pool and returns its result.
pub fn install<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    pool().install(work)
}

/// `rayon::join` for the two halves of one pass of a step, ending with both threads awake: a half
/// that finishes while the other runs on another thread waits for it, spinning, for at most as
/// long as it took itself.
///
/// A pass is short, and a pool thread that finds no work soon goes to sleep; on a virtual machine
/// waking it can take as long as the pass. Without the wait, the thread that finishes first falls
/// asleep, the pass ends only once it is woken, and the next pass starts with its other thread
/// asleep: two wake-ups a step, a large share of a step (`docs/decisions.md`). A half that no
/// other thread has taken is run by the caller after the first, as `rayon::join` does, and
/// nothing waits for it. Only a step's passes join this way; work that runs for long (a run
/// beside its companions) uses `rayon::join`.
pub fn join<A: Send, B: Send>(left: impl FnOnce() -> A + Send, right: impl FnOnce() -> B + Send) -> (A, B) {
    join_side_by_side(left, right).0
}

/// [`join`], also telling whether the two halves ran side by side, the right one taken by
/// another thread.
pub(crate) fn join_side_by_side<A: Send, B: Send>(
    left: impl FnOnce() -> A + Send,
    right: impl FnOnce() -> B + Send,
) -> ((A, B), bool) {
    const NOT_TAKEN: u8 = 0;
    const RUNNING: u8 = 1;
    const DONE: u8 = 2;
    // The flags only decide how long a thread spins; the join itself publishes the halves' data.
    let right_state = AtomicU8::new(NOT_TAKEN);
    let left_done = AtomicBool::new(false);
    let (left, (right, taken)) = rayon::join_context(
        |_| {
            let start = Instant::now();
            let left = left();
            left_done.store(true, Ordering::Relaxed);
            spin_while(start.elapsed(), || right_state.load(Ordering::Relaxed) == RUNNING);
            left
        },
        |context| {
            if !context.migrated() {
                return (right(), false);
            }
            right_state.store(RUNNING, Ordering::Relaxed);
            let start = Instant::now();
            let right = right();
            right_state.store(DONE, Ordering::Relaxed);
            spin_while(start.elapsed(), || !left_done.load(Ordering::Relaxed));
            (right, true)
        },
    );
    ((left, right), taken)
}

/// Spins while `busy()` holds, for at most `budget`.
fn spin_while(budget: Duration, busy: impl Fn() -> bool) {
    let deadline = Instant::now() + budget;
    while busy() && Instant::now() < deadline {
        for _ in 0..32 {
            std::hint::spin_loop();
        }
    }
}

/// How many bands of rows a grid of `rows` rows and `particles` particles is cut into: one per
/// pool thread, as long as each band keeps at least [`MIN_PARTICLES_PER_BAND`] particles and
/// `min_rows` rows.
pub fn band_count(rows: usize, particles: usize, min_rows: usize) -> usize {
    band_count_of_at_least(rows, particles, min_rows, MIN_PARTICLES_PER_BAND)
}

/// [`band_count`] with bands of at least `min_particles` particles.
pub(crate) fn band_count_of_at_least(
    rows: usize,
    particles: usize,
    min_rows: usize,
    min_particles: usize,
) -> usize {
    let threads = pool().current_num_threads();
    let by_size = particles / min_particles.max(1);
    let by_rows = rows / min_rows.max(1);
    threads.min(by_size).min(by_rows).max(1)
}

/// Mutable row-major arrays of one grid's rows (each a slice, or a pair of such), which can be
/// cut between rows.
pub(crate) trait Rows: Send + Sized {
    /// The first `at` elements of each array, and the rest.
    fn split_at(self, at: usize) -> (Self, Self);
}

impl<T: Send, const K: usize> Rows for [&mut [T]; K] {
    fn split_at(self, at: usize) -> (Self, Self) {
        let mut halves = self.map(|a| a.split_at_mut(at));
        let front = halves.each_mut().map(|(front, _)| std::mem::take(front));
        (front, halves.map(|(_, back)| back))
    }
}

impl<R: Rows> Rows for Option<R> {
    fn split_at(self, at: usize) -> (Self, Self) {
        match self {
            Some(rows) => {
                let (front, back) = rows.split_at(at);
                (Some(front), Some(back))
            }
            None => (None, None),
        }
    }
}

impl<A: Rows, B: Rows> Rows for (A, B) {
    fn split_at(self, at: usize) -> (Self, Self) {
        let ((a0, a1), (b0, b1)) = (self.0.split_at(at), self.1.split_at(at));
        ((a0, b0), (a1, b1))
    }
}

/// Calls `work(first, count, rows)` on bands of at most `band` rows of `rows` (`n_rows` rows of
/// `width`), halving the rows between the pool's threads until a band is that small.
pub(crate) fn in_bands<R: Rows>(
    rows: R,
    n_rows: usize,
    width: usize,
    band: usize,
    work: &(impl Fn(usize, usize, R) + Sync),
) {
    fn split<R: Rows>(
        rows: R,
        first: usize,
        count: usize,
        width: usize,
        band: usize,
        work: &(impl Fn(usize, usize, R) + Sync),
    ) {
        if count <= band {
            work(first, count, rows);
            return;
        }
        let half = count / 2;
        let (front, back) = rows.split_at(half * width);
        join(
            || split(front, first, half, width, band, work),
            || split(back, first + half, count - half, width, band, work),
        );
    }
    split(rows, 0, n_rows, width, band, work);
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::{in_bands, join};

    /// The sum of `range`, by joining halves down to single numbers, counting the leaves run.
    fn joined_sum(range: std::ops::Range<u64>, leaves: &AtomicUsize) -> u64 {
        if range.end - range.start == 1 {
            leaves.fetch_add(1, Ordering::Relaxed);
            return range.start;
        }
        let middle = range.start + (range.end - range.start) / 2;
        let (low, high) =
            join(|| joined_sum(range.start..middle, leaves), || joined_sum(middle..range.end, leaves));
        low + high
    }

    #[test]
    fn bands_cover_every_row_once_whatever_their_size() {
        let input: Vec<f64> = (0..37).map(|k| k as f64 * 0.5).collect();
        for band in [1, 3, 8, 36, 37, 100] {
            let (mut output, mut rows) = (vec![1.0; 37], vec![0; 37]);
            in_bands(([&mut output[..]], [&mut rows[..]]), 37, 1, band, &|first, count, ([out], [rows])| {
                for k in 0..count {
                    out[k] += 2.0 * input[first + k];
                    rows[k] += first + k;
                }
            });
            let expected: Vec<f64> = input.iter().map(|i| 1.0 + 2.0 * i).collect();
            assert_eq!(output, expected, "bands of {band}");
            assert_eq!(rows, (0..37).collect::<Vec<_>>(), "bands of {band}");
        }
    }

    #[test]
    fn join_runs_each_half_once_and_returns_both_results_on_any_pool() {
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let leaves = AtomicUsize::new(0);
            let sum = pool.install(|| joined_sum(1..1001, &leaves));
            assert_eq!(sum, 500_500, "{threads} threads");
            assert_eq!(leaves.load(Ordering::Relaxed), 1000, "{threads} threads");
        }
        // Outside any pool, as `rayon::join` does, on the global pool.
        let leaves = AtomicUsize::new(0);
        assert_eq!(joined_sum(1..65, &leaves), 2080);
        assert_eq!(leaves.load(Ordering::Relaxed), 64);
    }
}
