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
//! A pair closer than `2 · thickness` that no spring joins is pushed apart along the line
//! between them until it is exactly that far, shared by inverse mass (a pinned particle is held),
//! and the part of its relative velocity that brings them together is removed, shared the same
//! way: an inelastic collision, which cannot add kinetic energy. Coincident particles have no
//! line between them; they are separated along y. One Gauss-Seidel sweep runs per step, in a
//! fixed order: the particles by index, and each one's cells in the order of [`FORWARD`], a run
//! by bucket and a bucket by particle index. Cells are those of the positions at the start of
//! the sweep; the pair's distance is that of the positions as the sweep has left them.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use super::model::Model;
use super::{Real, State, Vec3, Vectors};

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

/// The self-collision stage with its hash and scratch, allocated once.
#[derive(Clone, Debug)]
pub struct SelfCollision<T> {
    /// The distance every unjoined pair keeps: `2 · thickness`.
    distance: T,
    /// `1 / cell side`.
    inverse_cell: f64,
    /// Bucket count minus one (a power of two minus one).
    mask: usize,
    /// 64 minus the bucket count's power of two: the shift that keeps a hash's top bits.
    shift: u32,
    /// Per bucket: index of its first particle in `sorted`; one extra entry at the end.
    bucket_start: Vec<u32>,
    /// The particles sorted by bucket, each with its cell.
    sorted: Vec<Entry>,
    /// Per particle: its cell.
    cells: Vec<Cell>,
    /// Spring partners of each particle, sorted: `partners[partner_start[p]..partner_start[p + 1]]`.
    partner_start: Vec<u32>,
    partners: Vec<u32>,
}

impl<T: Real> SelfCollision<T> {
    /// The stage for a model whose particles keep `2 · thickness` apart (thickness positive).
    pub fn new(model: &Model, thickness: f64) -> Self {
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
            inverse_cell: 1.0 / (2.0 * thickness),
            mask: buckets - 1,
            shift: 64 - buckets.trailing_zeros(),
            bucket_start: vec![0; buckets + 1],
            sorted: vec![Entry::default(); n],
            cells: vec![[0; 3]; n],
            partner_start,
            partners,
        }
    }

    fn joined(&self, p: usize, q: u32) -> bool {
        let range = self.partner_start[p] as usize..self.partner_start[p + 1] as usize;
        self.partners[range].binary_search(&q).is_ok()
    }

    fn cell(&self, x: Vec3<T>) -> Cell {
        let c =
            |v: T| (v.to_f64() * self.inverse_cell).floor().clamp(i32::MIN.into(), i32::MAX.into()) as i32;
        [c(x.x), c(x.y), c(x.z)]
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

    /// Counting-sorts the particles into the hash buckets of their cells.
    fn build(&mut self, x: &Vectors<T>) {
        self.bucket_start.fill(0);
        for (p, position) in x.iter().enumerate() {
            let cell = self.cell(position);
            self.cells[p] = cell;
            let b = self.bucket(cell);
            self.bucket_start[b + 1] += 1;
        }
        for b in 1..self.bucket_start.len() {
            self.bucket_start[b] += self.bucket_start[b - 1];
        }
        // Scatter, using each bucket's start as its cursor, then shift the starts back.
        for (p, &cell) in self.cells.iter().enumerate() {
            let b = self.bucket(cell);
            self.sorted[self.bucket_start[b] as usize] = Entry { particle: p as u32, cell };
            self.bucket_start[b] += 1;
        }
        for b in (1..self.bucket_start.len()).rev() {
            self.bucket_start[b] = self.bucket_start[b - 1];
        }
        self.bucket_start[0] = 0;
    }

    /// The entries of the buckets from `first` to `last` (at most `mask`).
    fn buckets(&self, first: usize, last: usize) -> &[Entry] {
        &self.sorted[self.bucket_start[first] as usize..self.bucket_start[last + 1] as usize]
    }

    /// Pushes apart every unjoined pair closer than `2 · thickness`; returns whether any moved.
    pub fn resolve(&mut self, state: &mut State<T>, inverse_masses: &[T]) -> bool {
        self.build(&state.positions);
        let mut moved = false;
        for (p, &[ci, cj, ck]) in self.cells.iter().enumerate() {
            let (i, j, k) = (i64::from(ci), i64::from(cj), i64::from(ck));
            for [dj, dk, from] in FORWARD {
                let (column_j, column_k) = (j + dj, k + dk);
                let first = self.bucket_of(i + from, column_j, column_k);
                let mut meet = |entries: &[Entry]| {
                    for entry in entries {
                        let [ei, ej, ek] = entry.cell.map(i64::from);
                        let q = entry.particle as usize;
                        let beside = (ej == column_j) & (ek == column_k) & (ei - i >= from) & (ei - i <= 1);
                        // In p's own cell, each pair once.
                        let once = (ei != i) | (dj != 0) | (dk != 0) | (q > p);
                        // One branch, rarely taken: most entries are of other columns.
                        if beside & once {
                            moved |= self.separate(p, q, state, inverse_masses);
                        }
                    }
                };
                let last = first + (1 - from) as usize;
                if last <= self.mask {
                    meet(self.buckets(first, last));
                } else {
                    // The run wraps past the last bucket.
                    (first..=last).for_each(|b| meet(self.buckets(b & self.mask, b & self.mask)));
                }
            }
        }
        moved
    }

    /// Pushes `p` and `q` apart if they are closer than `2 · thickness` and no spring joins them;
    /// returns whether they were.
    #[inline(never)]
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

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::{Chain, SpringParams};

    /// Particles on a line, `spacing` apart, with a spring between the first two only.
    fn model(positions: &[f64]) -> Model {
        let mut m = Model::default();
        m.add_particles(positions.iter().map(|&x| DVec3::new(x, 0.0, 0.0)), |_| 1.0, DVec3::ZERO);
        m.connect(0, 1, SpringParams { stiffness: 1.0, damping: 0.0 }, crate::solver::SpringKind::Structural);
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
        let mut stage = SelfCollision::<f64>::new(&m, 0.005);
        let before = s.positions.clone();
        assert!(stage.resolve(&mut s, &[1.0, 1.0, 1.0, 1.0]));
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
        let mut stage = SelfCollision::<f64>::new(&m, thickness);
        assert!(stage.resolve(&mut s, &vec![1.0; positions.len()]));
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
    fn a_pinned_particle_is_held_and_coincident_particles_separate_along_y() {
        let m = model(&[0.0, 5.0, 5.0]);
        let mut s = state(&m, &[0.0, 0.0, 0.0]);
        let mut stage = SelfCollision::<f64>::new(&m, 0.01);
        assert!(stage.resolve(&mut s, &[1.0, 0.0, 1.0]));
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
        let mut stage = SelfCollision::<f64>::new(&m, 0.002);
        let w = vec![1.0; 200];
        for _ in 0..200 {
            stage.resolve(&mut s, &w);
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
        use crate::solver::{Config, Simulation};
        let m = model(&[0.0, 0.5, 1.0]);
        let without = Simulation::<f64>::new(&m, &Config::default());
        assert!(!without.stages().contains(&"self_collision"));
        let with = Simulation::<f64>::new(&m, &Config { self_collision: Some(0.01), ..Config::default() });
        assert_eq!(with.stages(), ["gravity", "springs", "self_collision"]);
    }
}
