//! The springs no grid covers (meshes, chains, lattices), evaluated in runs: the fast force pass
//! for any spring list.
//!
//! At construction the springs are sorted into runs: `len` springs joining particles `p + k` and
//! `q + k` for `k = 0..len`, with one stiffness and damping and a rest length per spring. Along a
//! run both ends are contiguous ranges of each axis of the state, so a run is evaluated like a
//! row of a grid stencil: in blocks of [`LANES`] springs copied into local arrays, which compile
//! to full-width vector instructions, without index lists. Bodies whose particles are numbered
//! along a grid (a row-major mesh, a chain, a lattice) give long runs; whatever does not fit a
//! run of at least [`MIN_RUN`] springs is evaluated one spring at a time.
//!
//! A spring's direction does not change its force (swapping its ends negates `d` and `n`
//! exactly), so every spring is stored with its lower particle first: a run's second ends lie
//! `q - p > 0` particles after its first ends. Within a block the second ends receive their
//! forces before the first ends, so a particle always receives a run's contribution as a second
//! end (spring `k - (q - p)`) before its contribution as a first end (spring `k`), however the
//! run is cut into blocks. Every particle therefore sums its forces in one fixed order: run after
//! run (sorted by first particle), then the remaining springs in list order.
//!
//! Large scenes are cut into bands of particles run by the solver's threads
//! ([`parallel`](crate::solver::parallel)). A band owns its particles' forces: it evaluates every
//! spring with an end inside it, recomputing those that cross its border, and keeps only the
//! contributions to its own particles. The order in which a particle sums its forces is the one
//! above whatever the band count, so results do not depend on the number of threads. The result
//! is the spring-list force of [`springs`](super::springs) summed in a different, fixed order:
//! equal to it up to rounding.

use std::ops::Range;

use super::spring_blocks::{self as blocks, LANES};
use super::springs::direction;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::Spring;
use crate::solver::parallel;

/// The shortest run worth a vector block; shorter ones are evaluated one spring at a time.
const MIN_RUN: usize = 4;

/// The longest run: longer ones are split so that, with runs sorted by first particle, the pass
/// sweeps the particles once in order rather than once per long run, and the forces it adds to
/// stay in cache.
const MAX_RUN: usize = 512;

/// The most bands a scene is cut into.
const MAX_BANDS: usize = 64;

/// `len` springs from particles `first + k` to `second + k`, `second > first`.
#[derive(Clone, Copy, Debug)]
struct Run<T> {
    first: usize,
    second: usize,
    len: usize,
    /// Where the run's rest lengths start in [`SpringRuns::rest_lengths`].
    rest_lengths: usize,
    stiffness: T,
    damping: T,
}

/// A band of particles and the springs outside runs that touch it.
#[derive(Clone, Debug)]
struct Band<T> {
    particles: Range<usize>,
    /// The springs outside runs with an end in the band, in list order.
    singles: Vec<Spring<T>>,
}

/// Numbers of springs in runs and outside them.
#[cfg(test)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunStats {
    /// Runs.
    pub runs: usize,
    /// Springs in runs.
    pub springs_in_runs: usize,
    /// Springs evaluated one at a time.
    pub single_springs: usize,
}

/// A spring list sorted into runs, with its bands.
#[derive(Clone, Debug)]
pub(crate) struct SpringRuns<T> {
    runs: Vec<Run<T>>,
    rest_lengths: Vec<T>,
    single_springs: usize,
    /// Particles per band (the last band may have fewer).
    band_particles: usize,
    bands: Vec<Band<T>>,
}

impl<T: Real> SpringRuns<T> {
    /// Sorts `springs` between `particles` particles into runs, cut into as many bands as the
    /// solver's threads can use.
    pub fn new(springs: &[Spring<T>], particles: usize) -> Self {
        let (runs, rest_lengths, singles) = sort_into_runs(springs);
        let widest = runs.iter().map(|r| r.second - r.first).max().unwrap_or(1);
        let count =
            if springs.is_empty() { 1 } else { parallel::band_count(particles, particles, 4 * widest) };
        Self::with_bands(runs, rest_lengths, &singles, particles, count)
    }

    /// The runs and single springs cut into `count` bands of particles.
    fn with_bands(
        runs: Vec<Run<T>>,
        rest_lengths: Vec<T>,
        singles: &[Spring<T>],
        particles: usize,
        count: usize,
    ) -> Self {
        let total = particles.max(1);
        let band_particles = total.div_ceil(count.clamp(1, total.min(MAX_BANDS)));
        let bands = (0..total.div_ceil(band_particles))
            .map(|b| {
                let owned = b * band_particles..((b + 1) * band_particles).min(particles);
                let singles = singles
                    .iter()
                    .filter(|s| owned.contains(&(s.i as usize)) || owned.contains(&(s.j as usize)))
                    .copied()
                    .collect();
                Band { particles: owned, singles }
            })
            .collect();
        Self { runs, rest_lengths, single_springs: singles.len(), band_particles, bands }
    }

    /// Whether there are no springs.
    pub fn is_empty(&self) -> bool {
        self.runs.is_empty() && self.single_springs == 0
    }

    /// How the springs were sorted.
    #[cfg(test)]
    pub fn stats(&self) -> RunStats {
        RunStats {
            runs: self.runs.len(),
            springs_in_runs: self.rest_lengths.len(),
            single_springs: self.single_springs,
        }
    }

    /// Adds every spring's force to `forces`.
    pub fn add_forces(&self, x: &Vectors<T>, v: &Vectors<T>, forces: &mut Vectors<T>) {
        if self.is_empty() {
            return;
        }
        let (x, v) = (x.axes(), v.axes());
        let [fx, fy, fz] = forces.axes_mut();
        if let [band] = self.bands.as_slice() {
            self.sweep(band, x, v, [fx, fy, fz]);
            return;
        }
        let (bands, width) = (self.bands.len(), self.band_particles);
        parallel::in_bands([fx, fy, fz], bands, width, 1, &|band, _, forces| {
            self.sweep(&self.bands[band], x, v, forces);
        });
    }

    /// Adds the force of every spring with an end in `band` to the band's particles, whose
    /// forces are `out` (indexed from the band's first particle).
    fn sweep(&self, band: &Band<T>, x: [&[T]; 3], v: [&[T]; 3], mut out: [&mut [T]; 3]) {
        let Range { start: low, end: high } = band.particles;
        for run in &self.runs {
            if run.first >= high {
                // Runs are sorted by first particle: no later run reaches the band.
                break;
            }
            // Springs whose second end is in the band, and those whose first end is.
            let seconds = span(low, high, run.second, run.len);
            let firsts = span(low, high, run.first, run.len);
            let rest = &self.rest_lengths[run.rest_lengths..run.rest_lengths + run.len];
            let mut evaluate = |springs: Range<usize>, ends: Ends| {
                if !springs.is_empty() {
                    run_springs(run, rest, x, v, springs, ends, low, &mut out);
                }
            };
            // `seconds` starts and ends no later than `firsts` (`second > first`): walk k upwards.
            let both = firsts.start.max(seconds.start)..seconds.end.min(firsts.end);
            evaluate(seconds.start..seconds.end.min(firsts.start), Ends::Second);
            evaluate(both.clone(), Ends::Both);
            evaluate(firsts.start.max(seconds.end)..firsts.end, Ends::First);
        }
        let owned = |p: usize| (low..high).contains(&p);
        for s in &band.singles {
            let (i, j) = (s.i as usize, s.j as usize);
            let xi = [x[0][i], x[1][i], x[2][i]];
            let xj = [x[0][j], x[1][j], x[2][j]];
            let d = Vec3::new(xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]);
            let Some((n, l)) = direction(d) else { continue };
            let dv = Vec3::new(v[0][j] - v[0][i], v[1][j] - v[1][i], v[2][j] - v[2][i]);
            let f = (n * (s.stiffness * (l - s.rest_length) + s.damping * dv.dot(n))).to_array();
            if owned(i) {
                for (axis, f) in out.iter_mut().zip(f) {
                    axis[i - low] += f;
                }
            }
            if owned(j) {
                for (axis, f) in out.iter_mut().zip(f) {
                    axis[j - low] -= f;
                }
            }
        }
    }
}

/// The springs `k` of a run of `len` whose end `start + k` lies in `low..high`.
#[inline]
fn span(low: usize, high: usize, start: usize, len: usize) -> Range<usize> {
    let from = low.saturating_sub(start).min(len);
    let to = high.saturating_sub(start).min(len);
    from..to
}

/// Which ends of a stretch of springs are in the band and receive their forces.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Ends {
    First,
    Second,
    Both,
}

/// Evaluates springs `springs` of `run` block by block and adds their forces to the ends that
/// `ends` names, in `out`, whose first entry is particle `low`.
#[allow(clippy::too_many_arguments)]
#[inline]
fn run_springs<T: Real>(
    run: &Run<T>,
    rest: &[T],
    x: [&[T]; 3],
    v: [&[T]; 3],
    springs: Range<usize>,
    ends: Ends,
    low: usize,
    out: &mut [&mut [T]; 3],
) {
    let mut k = springs.start;
    while k + LANES <= springs.end {
        let ends_a = blocks::whole(x, v, run.first + k);
        let ends_b = blocks::whole(x, v, run.second + k);
        let rest: &[T; LANES] = rest[k..k + LANES].try_into().expect("a whole block");
        let block = blocks::forces(run.stiffness, run.damping, rest, ends_a, ends_b);
        put(out, run, k, LANES, low, ends, &block);
        k += LANES;
    }
    if k < springs.end {
        let count = springs.end - k;
        let ends_a = blocks::padded(x, v, run.first + k, count);
        let ends_b = blocks::padded(x, v, run.second + k, count);
        let mut rest_block = [T::ZERO; LANES];
        rest_block[..count].copy_from_slice(&rest[k..k + count]);
        let block =
            blocks::forces(run.stiffness, run.damping, &rest_block, ends_a.each_ref(), ends_b.each_ref());
        put(out, run, k, count, low, ends, &block);
    }
}

/// Hands springs `k..k + count` of `run` to the ends `ends` names; second ends first (see the
/// module's notes on summation order).
#[inline(always)]
fn put<T: Real>(
    out: &mut [&mut [T]; 3],
    run: &Run<T>,
    k: usize,
    count: usize,
    low: usize,
    ends: Ends,
    block: &blocks::Forces<T>,
) {
    if ends != Ends::First {
        blocks::subtract(out.each_mut().map(|axis| &mut **axis), run.second + k - low, count, block);
    }
    if ends != Ends::Second {
        blocks::add(out.each_mut().map(|axis| &mut **axis), run.first + k - low, count, block);
    }
}

/// Sorts springs into runs of at least [`MIN_RUN`] and at most [`MAX_RUN`] springs, sorted by
/// first particle, with their rest lengths; returns the runs, the rest lengths and the springs
/// left over, in list order.
fn sort_into_runs<T: Real>(springs: &[Spring<T>]) -> (Vec<Run<T>>, Vec<T>, Vec<Spring<T>>) {
    // Every spring with its lower particle first; the force is the same.
    let ordered: Vec<Spring<T>> =
        springs.iter().map(|s| if s.i <= s.j { *s } else { Spring { i: s.j, j: s.i, ..*s } }).collect();
    let key = |s: &Spring<T>| (s.j - s.i, s.stiffness.to_f64().to_bits(), s.damping.to_f64().to_bits(), s.i);
    let mut order: Vec<usize> = (0..ordered.len()).filter(|&k| ordered[k].i < ordered[k].j).collect();
    order.sort_by_key(|&k| (key(&ordered[k]), k));

    let mut in_run = vec![false; ordered.len()];
    let mut runs: Vec<(Run<T>, Vec<usize>)> = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let first = &ordered[order[start]];
        let mut end = start + 1;
        while end < order.len() && end - start < MAX_RUN {
            let (previous, next) = (&ordered[order[end - 1]], &ordered[order[end]]);
            let continues = next.i == previous.i + 1
                && next.j == previous.j + 1
                && next.stiffness.to_f64().to_bits() == first.stiffness.to_f64().to_bits()
                && next.damping.to_f64().to_bits() == first.damping.to_f64().to_bits();
            if !continues {
                break;
            }
            end += 1;
        }
        if end - start >= MIN_RUN {
            let members = order[start..end].to_vec();
            for &k in &members {
                in_run[k] = true;
            }
            let run = Run {
                first: first.i as usize,
                second: first.j as usize,
                len: end - start,
                rest_lengths: 0,
                stiffness: first.stiffness,
                damping: first.damping,
            };
            runs.push((run, members));
        }
        start = end;
    }
    runs.sort_by_key(|(run, _)| (run.first, run.second));
    let mut rest_lengths = Vec::with_capacity(runs.iter().map(|(r, _)| r.len).sum());
    let runs = runs
        .into_iter()
        .map(|(mut run, members)| {
            run.rest_lengths = rest_lengths.len();
            rest_lengths.extend(members.iter().map(|&k| ordered[k].rest_length));
            run
        })
        .collect();
    let singles = (0..ordered.len()).filter(|&k| !in_run[k]).map(|k| ordered[k]).collect();
    (runs, rest_lengths, singles)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::bodies::{Chain, Cloth, Lattice, Mesh, Orientation};
    use crate::solver::forces::springs;
    use crate::solver::model::{Model, SpringParams};

    const STIFF: SpringParams = SpringParams { stiffness: 900.0, damping: 0.3 };
    const SOFT: SpringParams = SpringParams { stiffness: 50.0, damping: 0.05 };

    /// A 13 × 7 cloth given as a mesh (13 is not a multiple of the vector width, so partial
    /// blocks run too).
    fn mesh() -> Model {
        let mut grid = Model::default();
        grid.add_cloth(&Cloth {
            size: [1.2, 0.4],
            resolution: [13, 7],
            center: DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Vertical,
            mass: 0.3,
            velocity: DVec3::ZERO,
            structural: STIFF,
            shear: STIFF,
            bending: SOFT,
            pins: vec![],
        });
        let mut model = Model::default();
        model.add_mesh(&Mesh {
            vertices: grid.positions,
            triangles: grid.triangles.iter().map(|t| t.map(|v| v as usize)).collect(),
            mass: 0.3,
            velocity: DVec3::ZERO,
            structural: STIFF,
            bending: SOFT,
            pins: vec![],
        });
        model
    }

    fn chain() -> Model {
        let mut model = Model::default();
        model.add_chain(&Chain {
            start: DVec3::new(0.0, 1.0, 0.0),
            end: DVec3::new(1.0, 0.5, 0.2),
            count: 37,
            mass: 0.5,
            velocity: DVec3::ZERO,
            spring: STIFF,
            rest_length: None,
            pins: vec![],
        });
        model
    }

    fn lattice() -> Model {
        let mut model = Model::default();
        model.add_lattice(&Lattice {
            size: [0.5, 0.3, 0.4],
            resolution: [11, 5, 4],
            center: DVec3::new(0.0, 1.0, 0.0),
            mass: 2.0,
            velocity: DVec3::ZERO,
            structural: STIFF,
            shear: SpringParams { stiffness: 400.0, damping: 0.1 },
            bending: SOFT,
            pins: vec![],
        });
        model
    }

    /// The model's positions displaced and its particles moving, so that every spring is loaded.
    fn moving(model: &Model) -> (Vectors<f64>, Vectors<f64>) {
        let wave = |p: usize, a: f64| {
            DVec3::new((a * p as f64).sin(), (1.3 * a * p as f64).cos(), (0.7 * p as f64).sin())
        };
        let x = model
            .positions
            .iter()
            .enumerate()
            .map(|(p, &x)| Vec3::from_dvec3(x + wave(p, 0.37) * 0.01))
            .collect();
        let v = (0..model.particle_count()).map(|p| Vec3::from_dvec3(wave(p, 0.91))).collect();
        (x, v)
    }

    /// Forces start from a non-zero value, as they do after gravity and drag.
    fn start(n: usize) -> Vectors<f64> {
        (0..n).map(|p| Vec3::new(p as f64 * 0.01, -1.0, 0.5)).collect()
    }

    fn runs_in_bands(model: &Model, count: usize) -> SpringRuns<f64> {
        let (runs, rest_lengths, singles) = sort_into_runs(&model.springs);
        SpringRuns::with_bands(runs, rest_lengths, &singles, model.particle_count(), count)
    }

    fn gives_the_spring_list_force(model: &Model) -> RunStats {
        let (x, v) = moving(model);
        let n = x.len();
        let mut by_list = start(n);
        springs::add_forces(&model.springs, &x, &v, &mut by_list);
        let largest = by_list.iter().map(|f| f.length()).fold(0.0, f64::max);
        assert!(largest > 1.0, "the springs are loaded: {largest}");
        let one_band = {
            let runs = runs_in_bands(model, 1);
            let mut forces = start(n);
            runs.add_forces(&x, &v, &mut forces);
            for (a, b) in forces.iter().zip(by_list.iter()) {
                assert!((a - b).length() <= 1e-12 * largest, "{a:?} against {b:?}");
            }
            forces
        };
        for count in [2, 3, 5, 8] {
            let runs = runs_in_bands(model, count);
            assert_eq!(runs.bands.len(), count, "{n} particles in {count} bands");
            let mut forces = start(n);
            runs.add_forces(&x, &v, &mut forces);
            assert_eq!(forces, one_band, "{count} bands sum in the same order as one");
        }
        let stats = SpringRuns::new(&model.springs, n).stats();
        assert_eq!(stats.springs_in_runs + stats.single_springs, model.springs.len());
        stats
    }

    #[test]
    fn run_pass_gives_the_spring_list_force_on_a_mesh() {
        let model = mesh();
        let stats = gives_the_spring_list_force(&model);
        // In row-major order every family of edges and of springs across edges runs along a row
        // (the columns' springs in one run): nothing is left over.
        assert_eq!(stats.single_springs, 0, "{stats:?}");
    }

    #[test]
    fn run_pass_gives_the_spring_list_force_on_a_chain() {
        let model = chain();
        let stats = gives_the_spring_list_force(&model);
        assert_eq!(stats, RunStats { runs: 1, springs_in_runs: 36, single_springs: 0 });
    }

    #[test]
    fn run_pass_gives_the_spring_list_force_on_a_lattice() {
        let model = lattice();
        let stats = gives_the_spring_list_force(&model);
        assert!(stats.springs_in_runs > stats.single_springs, "{stats:?}");
    }

    #[test]
    fn springs_in_any_order_and_direction_give_the_spring_list_force() {
        let mut model = mesh();
        model.springs.reverse();
        for s in model.springs.iter_mut().step_by(3) {
            (s.i, s.j) = (s.j, s.i);
        }
        // Scattered springs and a spring joining a particle to itself.
        model.springs.swap(5, 70);
        model.springs.push(Spring { i: 4, j: 4, ..model.springs[0] });
        let stats = gives_the_spring_list_force(&model);
        assert!(stats.single_springs > 0, "{stats:?}");
    }

    #[test]
    fn run_statistics_of_a_row_major_mesh_follow_from_its_grid() {
        let (nx, ny) = (13, 7);
        let stats = SpringRuns::new(&mesh().springs, nx * ny).stats();
        // Edges: along rows, down columns, across cells; springs across the cell diagonals, across
        // the inner row edges and across the inner column edges.
        let edges = (nx - 1) * ny + nx * (ny - 1) + (nx - 1) * (ny - 1);
        let across = (nx - 1) * (ny - 1) + (nx - 1) * (ny - 2) + (nx - 2) * (ny - 1);
        // A run per row for every family but the columns' edges, which are one run (split
        // every MAX_RUN springs), and the springs across row edges, which skip the first row.
        let runs = ny + (nx * (ny - 1)).div_ceil(MAX_RUN) + 3 * (ny - 1) + (ny - 2);
        assert_eq!(stats, RunStats { runs, springs_in_runs: edges + across, single_springs: 0 });
    }
}
