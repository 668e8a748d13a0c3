//! Self-collision: particles of the scene keep at least `2 · thickness` apart unless a spring
//! joins them.
//!
//! Candidates come from a spatial hash of cubic cells of side `2 · thickness`, so two particles
//! close enough to collide are in the same or neighbouring cells. Each pair of neighbouring cells
//! is visited from one of the two only (the cells "after" a cell: the next along `i` in its own
//! column `(j, k)`, and three along `i` in each of the four columns after its own), so a particle
//! looks in 14 cells rather than 27 and meets each pair once.
//!
//! A cell `(i, j, k)` goes to the bucket `hash(j, k) + i` (Fibonacci hashing of the column), so
//! the cells `i - 1 ..= i + 1` of a column are adjacent buckets: a particle's 14 cells are five
//! runs of buckets, not 14 scattered lookups, and the particles along a row of cloth, visited one
//! after the other, read neighbouring buckets. Each step the particles are counting-sorted by
//! bucket into one flat array that also holds each one's cell (a count per bucket, a prefix sum,
//! a scatter), with the table and the array allocated once. A run is read in order, and an entry
//! of another column hashed nearby is passed over on its cell alone, before any position is
//! read. The cost is linear in the particle count for any layout whose cells hold a bounded
//! number of particles, as cloth does.
//!
//! Which pairs a particle meets depends on the cells alone, which are fixed for the sweep, so
//! that search, the costly part, runs in bands of particles on the solver's threads, each band
//! listing its pairs in the sweep's order; the sweep then takes the lists one after the other.
//! The pairs and their order are those of one thread's search, whatever the number of bands. The
//! lists start with room for a pair per particle and keep it from step to step (a 256² cloth
//! draped over a sphere meets a few hundred pairs); only a state more crumpled than that makes a
//! step allocate, once, to make more room. The lists together never hold room for more than the
//! stage's cap on pairs: a band that needs more room takes it from what the cap leaves, and one
//! that finds none counts its remaining pairs without storing them. A search whose pairs come to
//! more than the cap ends the stage with [`PairCapReached`] (which does not depend on the number
//! of bands); one that fits but whose room was held by other bands is searched again in lists
//! made exactly large enough. A thickness far above the particle spacing would otherwise meet
//! every pair of particles, a number quadratic in their count.
//!
//! A pair closer than `2 · thickness` that no spring joins is pushed apart along the line
//! between them until it is exactly that far, shared by inverse mass (a pinned particle is held),
//! and the part of its relative velocity that brings them together is removed, shared the same
//! way: an inelastic collision, which cannot add kinetic energy. Coincident particles have no
//! line between them; they are separated along y. One Gauss-Seidel sweep runs per step, in a
//! fixed order: the particles by index, and each one's cells in the order of [`FORWARD`], a run
//! by bucket and a bucket by particle index. Cells are those of the positions at the start of
//! the sweep; the pair's distance is that of the positions as the sweep has left them.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::Model;
use crate::solver::parallel;
use crate::solver::state::State;

/// A cell's coordinates in cell sides, clamped to `i32` (a particle that far away has diverged;
/// clamping only merges far cells, and the distance test still decides).
type Cell = [i32; 3];

/// A particle in the sorted array, with its cell.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    particle: u32,
    cell: Cell,
}

/// The cells after a particle's own, as runs `[dj, dk, from]` of the cells `i + from ..= i + 1`
/// of column `(j + dj, k + dk)`: its own column from its own cell, and the four columns after
/// its own in `(j, k)` order whole. Every pair of neighbouring cells is one of these from exactly
/// one of its two cells, so each pair of particles is met once.
const FORWARD: [[i64; 3]; 5] = [[0, 0, 0], [0, 1, -1], [1, -1, -1], [1, 0, -1], [1, 1, -1]];

/// Where a position falls: its cell, and the cell's bucket in a table of a power-of-two size.
#[derive(Clone, Copy, Debug)]
struct CellHash {
    /// `1 / cell side`.
    inverse_cell: f64,
    /// Bucket count minus one (a power of two minus one).
    mask: usize,
    /// 64 minus the bucket count's power of two: the shift that keeps a hash's top bits.
    shift: u32,
}

impl CellHash {
    fn cell<T: Real>(&self, x: [T; 3]) -> Cell {
        x.map(|v| (v.to_f64() * self.inverse_cell).floor().clamp(i32::MIN.into(), i32::MAX.into()) as i32)
    }

    /// The bucket of cell `(i, j, k)`: the column `(j, k)` hashed (Fibonacci hashing: the top
    /// bits of the product with 2^64 / φ, which every bit of `j` and `k` reaches), plus `i`, so
    /// that consecutive `i` are consecutive buckets.
    fn bucket_of(&self, i: i64, j: i64, k: i64) -> usize {
        let column = ((j as u64) << 32 ^ (k as u32 as u64)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        ((column >> self.shift) as usize).wrapping_add(i as usize) & self.mask
    }

    fn bucket(&self, [i, j, k]: Cell) -> usize {
        self.bucket_of(i.into(), j.into(), k.into())
    }
}

/// The self-collision stage with its hash and scratch, allocated once.
#[derive(Clone, Debug)]
pub struct SelfCollision<T> {
    /// The distance every unjoined pair keeps: `2 · thickness`.
    distance: T,
    hash: CellHash,
    /// Per bucket: index of its first particle in `sorted`; one extra entry at the end.
    bucket_start: Vec<u32>,
    /// The particles sorted by bucket, each with its cell.
    sorted: Vec<Entry>,
    /// Per particle: its cell and the cell's bucket.
    cells: Vec<Cell>,
    buckets: Vec<u32>,
    /// Per band of particles (one per solver thread for a large state): the candidate pairs its
    /// particles meet, in the sweep's order.
    pairs: Vec<Vec<[u32; 2]>>,
    /// Per band: the pairs it met and could not store for want of room under the cap.
    unstored: Vec<usize>,
    /// The most pairs the lists together may have room for.
    max_pairs: usize,
    /// Spring partners of each particle, sorted: `partners[partner_start[p]..partner_start[p + 1]]`.
    partner_start: Vec<u32>,
    partners: Vec<u32>,
}

/// The self-collision stage met more candidate pairs in one step than its cap allows it to hold.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PairCapReached {
    /// Candidate pairs the step met.
    pub pairs: u64,
    /// The most the stage may hold.
    pub cap: usize,
}

impl std::fmt::Display for PairCapReached {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "self-collision met {} candidate pairs in one step, more than the {} this run may hold: \
             the particles crowded within a few thicknesses of one another",
            self.pairs, self.cap
        )
    }
}

impl<T: Real> SelfCollision<T> {
    /// The stage for a model whose particles keep `2 · thickness` apart (thickness positive),
    /// holding at most `max_pairs` candidate pairs.
    pub fn new(model: &Model, thickness: f64, max_pairs: usize) -> Self {
        let n = model.particle_count();
        // At most a quarter full: a run of three buckets holds under one particle of other
        // columns on average.
        let buckets = (4 * n).max(4).next_power_of_two();
        let mut lists = vec![Vec::new(); n];
        for s in &model.springs {
            lists[s.i as usize].push(s.j);
            lists[s.j as usize].push(s.i);
        }
        let mut partner_start = Vec::with_capacity(n + 1);
        let mut partners = Vec::new();
        for mut list in lists {
            partner_start.push(partners.len() as u32);
            list.sort_unstable();
            list.dedup();
            partners.extend(list);
        }
        partner_start.push(partners.len() as u32);
        Self {
            distance: T::from_f64(2.0 * thickness),
            hash: CellHash {
                inverse_cell: 1.0 / (2.0 * thickness),
                mask: buckets - 1,
                shift: 64 - buckets.trailing_zeros(),
            },
            bucket_start: vec![0; buckets + 1],
            sorted: vec![Entry::default(); n],
            cells: vec![[0; 3]; n],
            buckets: vec![0; n],
            pairs: {
                let bands = parallel::band_count(n, n, 1);
                let room = n.div_ceil(bands).min(max_pairs / bands);
                (0..bands).map(|_| Vec::with_capacity(room)).collect()
            },
            unstored: vec![0; parallel::band_count(n, n, 1)],
            max_pairs,
            partner_start,
            partners,
        }
    }

    fn joined(&self, p: usize, q: u32) -> bool {
        let range = self.partner_start[p] as usize..self.partner_start[p + 1] as usize;
        self.partners[range].binary_search(&q).is_ok()
    }

    /// Counting-sorts the particles into the hash buckets of their cells. Each particle's cell
    /// and bucket depend on its position alone, so a large state finds them in bands on the
    /// solver's threads.
    fn build(&mut self, x: &Vectors<T>) {
        let (hash, n) = (self.hash, self.cells.len());
        let band = n.div_ceil(parallel::band_count(n, n, 1));
        let [x, y, z] = x.axes();
        let outputs = ([&mut self.cells[..]], [&mut self.buckets[..]]);
        parallel::in_bands(outputs, n, 1, band, &|first, _, ([cells], [buckets])| {
            for (p, (cell, bucket)) in (first..).zip(cells.iter_mut().zip(buckets)) {
                *cell = hash.cell([x[p], y[p], z[p]]);
                *bucket = hash.bucket(*cell) as u32;
            }
        });
        // Each bucket's count, then the running sum: where each bucket ends.
        let (ends, total) = self.bucket_start.split_at_mut(hash.mask + 1);
        ends.fill(0);
        for &b in &self.buckets {
            ends[b as usize] += 1;
        }
        let mut end = 0;
        for count in ends.iter_mut() {
            end += *count;
            *count = end;
        }
        total[0] = end;
        // Scatter from the last particle back, each bucket's end its cursor: the buckets fill
        // from their ends down, their particles in increasing order, and each cursor is left at
        // its bucket's start.
        for (p, (&cell, &b)) in self.cells.iter().zip(&self.buckets).enumerate().rev() {
            let cursor = &mut self.bucket_start[b as usize];
            *cursor -= 1;
            self.sorted[*cursor as usize] = Entry { particle: p as u32, cell };
        }
    }

    /// The entries of the buckets from `first` to `last` (at most `mask`).
    fn entries(&self, first: usize, last: usize) -> &[Entry] {
        &self.sorted[self.bucket_start[first] as usize..self.bucket_start[last + 1] as usize]
    }

    /// Pushes apart every unjoined pair closer than `2 · thickness`; returns whether any moved,
    /// or, leaving the state as it was, that the step met more pairs than the cap.
    pub fn resolve(&mut self, state: &mut State<T>, inverse_masses: &[T]) -> Result<bool, PairCapReached> {
        self.build(&state.positions);
        let mut pairs = std::mem::take(&mut self.pairs);
        let mut unstored = std::mem::take(&mut self.unstored);
        let (bands, n) = (pairs.len(), self.cells.len());
        let chunk = n.div_ceil(bands).max(1);
        let held = pairs.iter().map(Vec::capacity).fold(0, usize::saturating_add);
        let room = AtomicUsize::new(self.max_pairs.saturating_sub(held));
        let this = &*self;
        parallel::in_bands(
            ([&mut pairs[..]], [&mut unstored[..]]),
            bands,
            1,
            1,
            &|band, _, ([lists], [cut])| {
                for ((band, list), cut) in (band..).zip(lists).zip(cut) {
                    list.clear();
                    *cut = this.candidates(band * chunk..((band + 1) * chunk).min(n), list, &room);
                }
            },
        );
        let cut = unstored.iter().fold(0, |sum: usize, &c| sum.saturating_add(c));
        if cut > 0 {
            let met = pairs.iter().map(Vec::len).fold(cut, usize::saturating_add);
            if met > self.max_pairs {
                self.pairs = pairs;
                self.unstored = unstored;
                return Err(PairCapReached { pairs: met as u64, cap: self.max_pairs });
            }
            // The pairs fit, but other bands held the room: give each band exactly what it met.
            for (band, (list, cut)) in pairs.iter_mut().zip(unstored.iter_mut()).enumerate() {
                if *cut == 0 {
                    list.shrink_to_fit();
                    continue;
                }
                let needed = list.len() + *cut;
                *list = Vec::new();
                list.reserve_exact(needed);
                *cut = self.candidates(band * chunk..((band + 1) * chunk).min(n), list, &AtomicUsize::new(0));
                debug_assert_eq!(*cut, 0);
            }
        }
        let mut moved = false;
        for &[p, q] in pairs.iter().flatten() {
            moved |= self.separate(p as usize, q as usize, state, inverse_masses);
        }
        self.pairs = pairs;
        self.unstored = unstored;
        Ok(moved)
    }

    /// Appends to `pairs`, in the sweep's order, every pair the particles `particles` meet in
    /// the cells after their own. A full list takes more room from `room` (the room left under
    /// the cap), doubling while it can; once none is left, the pairs still met are counted, not
    /// stored, and their count returned.
    fn candidates(&self, particles: Range<usize>, pairs: &mut Vec<[u32; 2]>, room: &AtomicUsize) -> usize {
        let mut unstored = 0;
        for p in particles {
            let [i, j, k] = self.cells[p].map(i64::from);
            for [dj, dk, from] in FORWARD {
                let (column_j, column_k) = (j + dj, k + dk);
                let first = self.hash.bucket_of(i + from, column_j, column_k);
                let mut meet = |entries: &[Entry]| {
                    for entry in entries {
                        let [ei, ej, ek] = entry.cell.map(i64::from);
                        let q = entry.particle as usize;
                        let beside = (ej == column_j) & (ek == column_k) & (ei - i >= from) & (ei - i <= 1);
                        // In p's own cell, each pair once.
                        let once = (ei != i) | (dj != 0) | (dk != 0) | (q > p);
                        // One branch, rarely taken: most entries are of other columns.
                        if beside & once {
                            if pairs.len() == pairs.capacity() && (unstored > 0 || !grow(pairs, room)) {
                                unstored += 1;
                            } else {
                                pairs.push([p as u32, q as u32]);
                            }
                        }
                    }
                };
                let last = first + (1 - from) as usize;
                if last <= self.hash.mask {
                    meet(self.entries(first, last));
                } else {
                    // The run wraps past the last bucket.
                    let mask = self.hash.mask;
                    (first..=last).for_each(|b| meet(self.entries(b & mask, b & mask)));
                }
            }
        }
        unstored
    }

    /// Pushes the candidate pair `p`, `q` apart if they are closer than `2 · thickness` and no
    /// spring joins them; returns whether they were.
    fn separate(&self, p: usize, q: usize, state: &mut State<T>, inverse_masses: &[T]) -> bool {
        let (x, v) = (&mut state.positions, &mut state.velocities);
        let d = x.get(q) - x.get(p);
        let d2 = d.length_squared();
        let (wp, wq) = (inverse_masses[p], inverse_masses[q]);
        let w = wp + wq;
        if !(d2 < self.distance * self.distance) || w == T::ZERO || self.joined(p, q as u32) {
            return false;
        }
        let length = d2.sqrt();
        let n = if length > T::ZERO { d * (T::ONE / length) } else { Vec3::new(T::ZERO, T::ONE, T::ZERO) };
        let push = n * ((self.distance - length) / w);
        x.sub(p, push * wp);
        x.add(q, push * wq);
        let closing = (v.get(q) - v.get(p)).dot(n);
        if closing < T::ZERO {
            let impulse = n * (closing / w);
            v.add(p, impulse * wp);
            v.sub(q, impulse * wq);
        }
        true
    }
}

/// How many candidate pairs the stage meets in the model's initial layout: for every cell of
/// side `2 · thickness`, the pairs within it and with the 13 cells after it. A cost estimate
/// made without building the stage: one pass over the particles and one over the occupied
/// cells. Motion changes the count (a cloth folding onto itself meets more).
pub fn candidate_pairs(model: &Model, thickness: f64) -> u64 {
    let hash = CellHash { inverse_cell: 1.0 / (2.0 * thickness), mask: 0, shift: 0 };
    let mut counts = std::collections::HashMap::<Cell, u64>::with_capacity(model.particle_count());
    for p in &model.positions {
        *counts.entry(hash.cell(p.to_array())).or_default() += 1;
    }
    let count_at = |i: i64, j: i64, k: i64| -> u64 {
        let inside = |v: i64| i32::try_from(v).ok();
        match (inside(i), inside(j), inside(k)) {
            (Some(i), Some(j), Some(k)) => counts.get(&[i, j, k]).copied().unwrap_or(0),
            _ => 0,
        }
    };
    let mut pairs = 0u64;
    for (&[i, j, k], &own) in &counts {
        let [i, j, k] = [i, j, k].map(i64::from);
        let mut after = 0u64;
        for [dj, dk, from] in FORWARD {
            for di in from..=1 {
                if (dj, dk, di) != (0, 0, 0) {
                    after = after.saturating_add(count_at(i + di, j + dj, k + dk));
                }
            }
        }
        let within = own.saturating_mul(own.saturating_sub(1)) / 2;
        pairs = pairs.saturating_add(within).saturating_add(own.saturating_mul(after));
    }
    pairs
}

/// Makes room in a full list for more pairs, taken from `room`: as many again as it holds (at
/// least 64), or what is left. Returns false when nothing is left.
fn grow(pairs: &mut Vec<[u32; 2]>, room: &AtomicUsize) -> bool {
    let wanted = pairs.capacity().max(64);
    let Ok(left) = room.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |left| {
        (left > 0).then(|| left.saturating_sub(wanted))
    }) else {
        return false;
    };
    pairs.reserve_exact(wanted.min(left));
    true
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::bodies::Chain;
    use crate::solver::model::SpringParams;

    /// Particles on a line, `spacing` apart, with a spring between the first two only.
    fn model(positions: &[f64]) -> Model {
        let mut m = Model::default();
        m.add_particles(positions.iter().map(|&x| DVec3::new(x, 0.0, 0.0)), |_| 1.0, DVec3::ZERO);
        m.connect(
            0,
            1,
            SpringParams { stiffness: 1.0, damping: 0.0 },
            crate::solver::model::SpringKind::Structural,
        );
        m
    }

    fn state(m: &Model, v: &[f64]) -> State<f64> {
        State {
            positions: m.positions.iter().map(|&p| Vec3::from_dvec3(p)).collect(),
            velocities: v.iter().map(|&v| Vec3::new(v, 0.0, 0.0)).collect(),
        }
    }

    #[test]
    fn close_unjoined_pairs_are_pushed_to_twice_the_thickness_and_stop_approaching() {
        // 0-1 are joined and close; 1-2 are not joined and close; 3 is far away.
        let m = model(&[0.0, 0.008, 0.012, 1.0]);
        let mut s = state(&m, &[0.0, 1.0, -1.0, 0.0]);
        let mut stage = SelfCollision::<f64>::new(&m, 0.005, usize::MAX);
        let before = s.positions.clone();
        assert!(stage.resolve(&mut s, &[1.0, 1.0, 1.0, 1.0]).unwrap());
        assert_eq!(s.positions.get(0), before.get(0));
        assert_eq!(s.positions.get(3), before.get(3));
        let gap = s.positions.get(2).x - s.positions.get(1).x;
        assert!((gap - 0.01).abs() < 1e-15, "{gap}");
        // Equal masses: both moved by half and the approach (-2 m/s) is gone, momentum kept.
        assert!((s.velocities.get(1).x - 0.0).abs() < 1e-15 && (s.velocities.get(2).x - 0.0).abs() < 1e-15);
    }

    #[test]
    fn every_close_pair_is_met_across_every_cell_face_edge_and_corner() {
        // Pairs of unjoined particles far apart from one another, each pair along one of the 26
        // directions to a neighbouring cell, at random places in the cells (so that a pair
        // straddles every combination of cell boundaries), near the origin and a million cells
        // away; a close pair at 0.9 of the distance, a far one at 1.1.
        let thickness = 0.005;
        let distance = 2.0 * thickness;
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut positions = Vec::new();
        let directions =
            (0..27).map(|c| DVec3::new((c % 3) as f64 - 1.0, (c / 3 % 3) as f64 - 1.0, (c / 9) as f64 - 1.0));
        for (d, direction) in directions.filter(|d| *d != DVec3::ZERO).enumerate() {
            for trial in 0..32 {
                let far = if trial % 2 == 0 { 0.0 } else { -1e4 };
                let base = DVec3::new(d as f64, trial as f64, far)
                    + DVec3::new(random(), random(), random()) * distance;
                for scale in [0.9, 1.1] {
                    let base = base + DVec3::new(0.0, 0.0, scale);
                    positions.extend([base, base + direction.normalize() * (scale * distance)]);
                }
            }
        }
        let mut m = Model::default();
        m.add_particles(positions.iter().copied(), |_| 1.0, DVec3::ZERO);
        let mut s = state(&m, &vec![0.0; positions.len()]);
        let mut stage = SelfCollision::<f64>::new(&m, thickness, usize::MAX);
        assert!(stage.resolve(&mut s, &vec![1.0; positions.len()]).unwrap());
        for pair in 0..positions.len() / 2 {
            let (p, q) = (2 * pair, 2 * pair + 1);
            let gap = (s.positions.get(q) - s.positions.get(p)).length();
            let was = (positions[q] - positions[p]).length();
            if was < distance {
                assert!((gap - distance).abs() < 1e-9, "pair {p}, {q} was {was} apart and is {gap}");
            } else {
                assert_eq!(s.positions.get(p), Vec3::from_dvec3(positions[p]));
                assert_eq!(s.positions.get(q), Vec3::from_dvec3(positions[q]));
            }
        }
    }

    #[test]
    fn the_sweep_gives_the_same_bits_whatever_the_number_of_bands() {
        // Crumpled so that thousands of pairs are met.
        let (m, velocities, w) = crumpled_cloth();
        let sweeps = |bands: usize| {
            let mut stage = SelfCollision::<f64>::new(&m, 0.004, usize::MAX);
            stage.pairs = vec![Vec::new(); bands];
            stage.unstored = vec![0; bands];
            let mut s = state(&m, &velocities);
            let met = (0..3).map(|_| stage.resolve(&mut s, &w).unwrap()).collect::<Vec<_>>();
            (met, stage.pairs.iter().map(Vec::len).sum::<usize>(), s)
        };
        let (met, pairs, one) = sweeps(1);
        assert_eq!(met, [true; 3]);
        assert!(pairs > 1000, "{pairs} pairs");
        for bands in [2, 3, 7] {
            let (_, _, many) = sweeps(bands);
            assert_eq!(
                (&many.positions, &many.velocities),
                (&one.positions, &one.velocities),
                "{bands} bands"
            );
        }
    }

    /// A 40 × 40 cloth crumpled into a small ball, with its velocities and inverse masses.
    fn crumpled_cloth() -> (Model, Vec<f64>, Vec<f64>) {
        let mut m = Model::default();
        m.add_cloth(&crate::solver::bodies::Cloth::square_metre(
            40,
            SpringParams { stiffness: 1.0, damping: 0.0 },
        ));
        for (p, x) in m.positions.iter_mut().enumerate() {
            let t = p as f64 * 0.37;
            *x = DVec3::new((t * 1.3).sin(), (t * 0.7).cos(), (t * 2.1).sin()) * 0.1;
        }
        let velocities = (0..m.particle_count()).map(|p| (p as f64 * 0.11).sin()).collect();
        let w = (0..m.particle_count()).map(|p| if p % 97 == 0 { 0.0 } else { 1.0 }).collect();
        (m, velocities, w)
    }

    #[test]
    fn a_step_meeting_more_pairs_than_the_cap_fails_and_leaves_the_state_alone() {
        let (m, velocities, w) = crumpled_cloth();
        let mut free = SelfCollision::<f64>::new(&m, 0.004, usize::MAX);
        assert!(free.resolve(&mut state(&m, &velocities), &w).unwrap());
        let met: usize = free.pairs.iter().map(Vec::len).sum();
        assert!(met > 1000, "{met} pairs");

        for bands in [1, 3, 7] {
            let mut capped = SelfCollision::<f64>::new(&m, 0.004, met - 1);
            capped.pairs = vec![Vec::new(); bands];
            capped.unstored = vec![0; bands];
            let mut s = state(&m, &velocities);
            let before = s.clone();
            assert_eq!(
                capped.resolve(&mut s, &w),
                Err(PairCapReached { pairs: met as u64, cap: met - 1 }),
                "{bands} bands"
            );
            assert_eq!((&s.positions, &s.velocities), (&before.positions, &before.velocities));
            let room: usize = capped.pairs.iter().map(Vec::capacity).sum();
            assert!(room < met, "{bands} bands hold room for {room} pairs");
        }
    }

    #[test]
    fn a_step_meeting_exactly_the_cap_runs_as_if_uncapped_whatever_the_bands() {
        let (m, velocities, w) = crumpled_cloth();
        let mut free = SelfCollision::<f64>::new(&m, 0.004, usize::MAX);
        let mut expected = state(&m, &velocities);
        free.resolve(&mut expected, &w).unwrap();
        let met: usize = free.pairs.iter().map(Vec::len).sum();
        for bands in [1, 2, 3, 7] {
            let mut capped = SelfCollision::<f64>::new(&m, 0.004, met);
            capped.pairs = vec![Vec::new(); bands];
            capped.unstored = vec![0; bands];
            let mut s = state(&m, &velocities);
            assert_eq!(capped.resolve(&mut s, &w), Ok(true), "{bands} bands");
            assert_eq!((&s.positions, &s.velocities), (&expected.positions, &expected.velocities));
            let room: usize = capped.pairs.iter().map(Vec::capacity).sum();
            assert!(room <= met, "{bands} bands hold room for {room} of {met} pairs");
        }
    }

    #[test]
    fn the_estimate_of_pairs_is_the_count_the_search_meets() {
        let (m, velocities, w) = crumpled_cloth();
        for thickness in [0.001, 0.004, 0.02, 1.0] {
            let mut stage = SelfCollision::<f64>::new(&m, thickness, usize::MAX);
            stage.resolve(&mut state(&m, &velocities), &w).unwrap();
            let met: usize = stage.pairs.iter().map(Vec::len).sum();
            assert_eq!(candidate_pairs(&m, thickness), met as u64, "thickness {thickness}");
        }
        // Every pair of the 1600 particles when one cell holds them all.
        assert_eq!(candidate_pairs(&m, 10.0), 1600 * 1599 / 2);
    }

    #[test]
    fn a_pinned_particle_is_held_and_coincident_particles_separate_along_y() {
        let m = model(&[0.0, 5.0, 5.0]);
        let mut s = state(&m, &[0.0, 0.0, 0.0]);
        let mut stage = SelfCollision::<f64>::new(&m, 0.01, usize::MAX);
        assert!(stage.resolve(&mut s, &[1.0, 0.0, 1.0]).unwrap());
        assert_eq!(s.positions.get(1), Vec3::new(5.0, 0.0, 0.0));
        assert_eq!(s.positions.get(2), Vec3::new(5.0, 0.02, 0.0));
        assert!(s.positions.iter().all(|p| p.is_finite()));
    }

    #[test]
    fn a_crumpled_chain_keeps_every_unjoined_pair_apart_after_a_few_sweeps() {
        // A chain folded back and forth onto itself in a small box.
        let mut m = Model::default();
        m.add_chain(&Chain {
            start: DVec3::ZERO,
            end: DVec3::new(1.0, 0.0, 0.0),
            count: 200,
            mass: 1.0,
            velocity: DVec3::ZERO,
            spring: SpringParams { stiffness: 1.0, damping: 0.0 },
            rest_length: None,
            pins: vec![],
        });
        for (p, x) in m.positions.iter_mut().enumerate() {
            let t = p as f64 * 0.37;
            *x = DVec3::new((t * 1.3).sin(), (t * 0.7).cos(), (t * 2.1).sin()) * 0.05;
        }
        let mut s = state(&m, &vec![0.0; 200]);
        let mut stage = SelfCollision::<f64>::new(&m, 0.002, usize::MAX);
        let w = vec![1.0; 200];
        for _ in 0..200 {
            stage.resolve(&mut s, &w).unwrap();
        }
        for p in 0..200usize {
            for q in p + 2..200 {
                let d = (s.positions.get(q) - s.positions.get(p)).length();
                assert!(d > 0.002, "{p} and {q} are {d} apart");
            }
        }
    }

    #[test]
    fn self_collision_is_a_stage_only_when_asked_for() {
        use crate::solver::simulation::{Config, Simulation};
        let m = model(&[0.0, 0.5, 1.0]);
        let without = Simulation::<f64>::new(&m, &Config::default());
        assert!(!without.stages().contains(&"self_collision"));
        let with = Simulation::<f64>::new(&m, &Config { self_collision: Some(0.01), ..Config::default() });
        assert_eq!(with.stages(), ["gravity", "springs", "self_collision"]);
    }
}
