//! Self-collision: particles of the scene keep at least `2 · thickness` apart unless a spring
//! joins them.
//!
//! Candidates come from a spatial hash with cubic cells of side `2 · thickness`, so two particles
//! close enough to collide are in the same or neighbouring cells. Each step the particles are
//! counting-sorted by the hash of their cell into one flat array (a count per bucket, a prefix
//! sum, a scatter), with the table, the counts and the order all allocated once; then each
//! particle looks in the 27 cells around it. The cost is linear in the particle count for any
//! layout whose cells hold a bounded number of particles, as cloth does.
//!
//! A pair closer than `2 · thickness` that no spring joins is pushed apart along the line
//! between them until it is exactly that far, shared by inverse mass (a pinned particle is held),
//! and the part of its relative velocity that brings them together is removed, shared the same
//! way: an inelastic collision, which cannot add kinetic energy. Coincident particles have no
//! line between them; they are separated along y. One Gauss-Seidel sweep runs per step.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use super::model::Model;
use super::{Real, State, Vec3, Vectors};

/// The self-collision stage with its hash and scratch, allocated once.
#[derive(Clone, Debug)]
pub struct SelfCollision<T> {
    /// The distance every unjoined pair keeps: `2 · thickness`.
    distance: T,
    /// `1 / cell side`.
    inverse_cell: f64,
    /// Bucket count minus one (a power of two minus one).
    mask: usize,
    /// Per bucket: index of its first particle in `order`; one extra entry at the end.
    bucket_start: Vec<u32>,
    /// Particle indices sorted by bucket.
    order: Vec<u32>,
    /// Per particle: its bucket.
    bucket_of: Vec<u32>,
    /// Spring partners of each particle, sorted: `partners[partner_start[p]..partner_start[p + 1]]`.
    partner_start: Vec<u32>,
    partners: Vec<u32>,
}

impl<T: Real> SelfCollision<T> {
    /// The stage for a model whose particles keep `2 · thickness` apart (thickness positive).
    pub fn new(model: &Model, thickness: f64) -> Self {
        let n = model.particle_count();
        let buckets = (2 * n).max(2).next_power_of_two();
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
            bucket_start: vec![0; buckets + 1],
            order: vec![0; n],
            bucket_of: vec![0; n],
            partner_start,
            partners,
        }
    }

    fn joined(&self, p: usize, q: u32) -> bool {
        let range = self.partner_start[p] as usize..self.partner_start[p + 1] as usize;
        self.partners[range].binary_search(&q).is_ok()
    }

    fn cell(&self, x: Vec3<T>) -> [i64; 3] {
        let c = |v: T| (v.to_f64() * self.inverse_cell).floor() as i64;
        [c(x.x), c(x.y), c(x.z)]
    }

    fn bucket(&self, [i, j, k]: [i64; 3]) -> usize {
        let h = (i.wrapping_mul(73_856_093)) ^ (j.wrapping_mul(19_349_663)) ^ (k.wrapping_mul(83_492_791));
        (h as u64 as usize) & self.mask
    }

    /// Counting-sorts the particles into the hash buckets of their cells.
    fn build(&mut self, x: &Vectors<T>) {
        self.bucket_start.fill(0);
        for (p, position) in x.iter().enumerate() {
            let b = self.bucket(self.cell(position));
            self.bucket_of[p] = b as u32;
            self.bucket_start[b + 1] += 1;
        }
        for b in 1..self.bucket_start.len() {
            self.bucket_start[b] += self.bucket_start[b - 1];
        }
        // Scatter, using each bucket's start as its cursor, then shift the starts back.
        for p in 0..x.len() {
            let b = self.bucket_of[p] as usize;
            self.order[self.bucket_start[b] as usize] = p as u32;
            self.bucket_start[b] += 1;
        }
        for b in (1..self.bucket_start.len()).rev() {
            self.bucket_start[b] = self.bucket_start[b - 1];
        }
        self.bucket_start[0] = 0;
    }

    /// Pushes apart every unjoined pair closer than `2 · thickness`; returns whether any moved.
    #[allow(clippy::needless_range_loop, reason = "each particle updates itself and a partner")]
    pub fn resolve(&mut self, state: &mut State<T>, inverse_masses: &[T]) -> bool {
        self.build(&state.positions);
        let (x, v) = (&mut state.positions, &mut state.velocities);
        let limit2 = self.distance * self.distance;
        let mut moved = false;
        for p in 0..x.len() {
            let [ci, cj, ck] = self.cell(x.get(p));
            for di in -1..=1 {
                for dj in -1..=1 {
                    for dk in -1..=1 {
                        let b = self.bucket([ci + di, cj + dj, ck + dk]);
                        let range = self.bucket_start[b] as usize..self.bucket_start[b + 1] as usize;
                        for slot in range {
                            let q = self.order[slot];
                            if q as usize <= p {
                                continue;
                            }
                            let d = x.get(q as usize) - x.get(p);
                            let d2 = d.length_squared();
                            if !(d2 < limit2) || self.joined(p, q) {
                                continue;
                            }
                            let (wp, wq) = (inverse_masses[p], inverse_masses[q as usize]);
                            let w = wp + wq;
                            if w == T::ZERO {
                                continue;
                            }
                            let length = d2.sqrt();
                            let n = if length > T::ZERO {
                                d * (T::ONE / length)
                            } else {
                                Vec3::new(T::ZERO, T::ONE, T::ZERO)
                            };
                            let push = n * ((self.distance - length) / w);
                            x.sub(p, push * wp);
                            x.add(q as usize, push * wq);
                            let closing = (v.get(q as usize) - v.get(p)).dot(n);
                            if closing < T::ZERO {
                                let impulse = n * (closing / w);
                                v.add(p, impulse * wp);
                                v.sub(q as usize, impulse * wq);
                            }
                            moved = true;
                        }
                    }
                }
            }
        }
        moved
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
