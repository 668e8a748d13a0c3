//! How far a state at rest is from static equilibrium: the force left unbalanced on each free
//! particle, and the displacement that force implies.
//!
//! The residual `r_i` is the net static force on a particle that nothing holds: springs, bending,
//! gravity and wind at zero velocity (so damping and drag drop out). Pinned particles are held,
//! and so are particles lying on a collider (within a small gap of its surface): a run at rest
//! has found them still there, the contact stage taking whatever force they feel (a projection
//! in positions with velocity-level friction, which a large step can make hold more than a
//! static Coulomb cone would), so their residual is taken as zero and the estimate is the
//! distance to the equilibrium of the free particles with the contact set where it lies.
//!
//! The displacement solves one linear system with the stiffness, `K δx = r` (`K = -∂f/∂x`, the
//! springs' blocks with compressed springs' transverse part dropped, the softest definite
//! stiffness, and the bending elements' constant matrix), by conjugate gradients with the held
//! particles filtered out (Baraff and Witkin). To first order `x + δx` is the static solution, so
//! `|δx|` is how far the state is from the shape it would settle to. The solve looks at the run's
//! [`Interrupt`] at every iteration, so a cancelled or timed-out run does not wait for it.

use glam::DVec3;

use crate::solver::constraints::contacts::{Collider, Shape};
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::forces::springs::{direction, stiffness_block};
use crate::solver::interrupt::Interrupt;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::Model;
use crate::solver::simulation::Config;

/// A particle counts as lying on a collider when it is within this gap of the surface, in metres.
const CONTACT_GAP: f64 = 1e-6;

/// The linear solve stops when its residual is this fraction of `|r|`.
const TOLERANCE: f64 = 1e-8;

/// The linear solve stops after at most this many iterations (three per particle below it), so
/// that the estimate costs a bounded fraction of a run on the largest cloths.
const MAX_ITERATIONS: usize = 2000;

/// How far a state is from static equilibrium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equilibrium {
    /// The largest unbalanced force on a free particle, in newtons.
    pub residual_force: f64,
    /// The largest unbalanced force on a free particle over its weight `m_i |g|` (`None` without
    /// gravity).
    pub residual_relative: Option<f64>,
    /// The largest displacement `|δx_i|` the residual implies, in metres.
    pub displacement_max: f64,
    /// The root-mean-square displacement over all particles, in metres.
    pub displacement_rms: f64,
    /// Conjugate-gradient iterations the solve took.
    pub iterations: usize,
}

/// Zeroes what a held particle would move.
fn filter(held: bool, v: DVec3) -> DVec3 {
    if held { DVec3::ZERO } else { v }
}

/// The residual of `positions` (time `t`, for moving colliders and wind) and the displacement it
/// implies, for the model and configuration the state was simulated with; `None` when
/// `interrupt` is raised before the solve ends.
pub fn equilibrium(
    model: &Model,
    config: &Config,
    positions: &[DVec3],
    t: f64,
    interrupt: &Interrupt,
) -> Option<Equilibrium> {
    let n = positions.len();
    let mut dynamics = Dynamics::<f64>::new(model, config.gravity, 0.0);
    if let Some(wind) = &config.wind {
        dynamics = dynamics.with_wind(model, wind);
    }
    let mut x = Vectors::zeros(n);
    for (p, &position) in positions.iter().enumerate() {
        x.set(p, Vec3::from_dvec3(position));
    }
    let mut forces = Vectors::zeros(n);
    // Springs' and bending's damping act on velocity only: at zero velocity the static force.
    dynamics.forces(&x, &Vectors::zeros(n), t, &mut forces);

    let held: Vec<bool> = (0..n)
        .map(|p| model.pinned[p] || config.colliders.iter().any(|c| lies_on(c, positions[p], t)))
        .collect();
    let residual: Vec<DVec3> = (0..n).map(|p| filter(held[p], forces.get(p).to_dvec3())).collect();
    let weight = config.gravity.length();
    let residual_force = residual.iter().map(|r| r.length()).fold(0.0, f64::max);
    let residual_relative = (weight > 0.0).then(|| {
        residual.iter().zip(&model.masses).map(|(r, m)| r.length() / (m * weight)).fold(0.0, f64::max)
    });

    let stiffness = Stiffness::new(&dynamics, positions, &held);
    let (displacement, iterations) = stiffness.solve(&residual, interrupt)?;
    let displacement_max = displacement.iter().map(|d| d.length()).fold(0.0, f64::max);
    let displacement_rms = if n == 0 {
        0.0
    } else {
        (displacement.iter().map(|d| d.length_squared()).sum::<f64>() / n as f64).sqrt()
    };
    Some(Equilibrium { residual_force, residual_relative, displacement_max, displacement_rms, iterations })
}

/// Whether `x` lies on the collider's surface (or inside) at time `t`.
fn lies_on(collider: &Collider, x: DVec3, t: f64) -> bool {
    let local = collider.motion.as_ref().map_or(x, |m| m.at(t).inverse_point(x));
    let thickness = match &collider.shape {
        Shape::Mesh { thickness, .. } => *thickness,
        _ => 0.0,
    };
    collider.shape.signed_distance(local) - thickness <= CONTACT_GAP
}

/// `K` of the springs and bending elements at a state, with the particles it holds still.
struct Stiffness<'a> {
    dynamics: &'a Dynamics<f64>,
    springs: Vec<Sym3<f64>>,
    /// Per particle: one over the mean of its diagonal block (the preconditioner).
    diagonal: Vec<f64>,
    held: &'a [bool],
}

impl<'a> Stiffness<'a> {
    fn new(dynamics: &'a Dynamics<f64>, x: &[DVec3], held: &'a [bool]) -> Self {
        let mut diagonal = vec![0.0; x.len()];
        let springs = dynamics
            .springs
            .iter()
            .map(|s| {
                let (i, j) = (s.i as usize, s.j as usize);
                let Some((n, l)) = direction(Vec3::from_dvec3(x[j] - x[i])) else { return Sym3::ZERO };
                let block = stiffness_block(s, n, l);
                let [xx, yy, zz, ..] = block.entries();
                diagonal[i] += (xx + yy + zz) / 3.0;
                diagonal[j] += (xx + yy + zz) / 3.0;
                block
            })
            .collect();
        if let Some(hinges) = &dynamics.bending {
            hinges.add_diagonal(1.0, 0.0, &mut diagonal);
        }
        for d in &mut diagonal {
            *d = if *d > 0.0 { 1.0 / *d } else { 0.0 };
        }
        Self { dynamics, springs, diagonal, held }
    }

    /// `y = K S p`, with `S` zeroing the held particles.
    fn apply(&self, p: &[DVec3], y: &mut [Vec3<f64>]) {
        y.fill(Vec3::ZERO);
        for (s, block) in self.dynamics.springs.iter().zip(&self.springs) {
            let (i, j) = (s.i as usize, s.j as usize);
            let pi = filter(self.held[i], p[i]);
            let pj = filter(self.held[j], p[j]);
            let d = block.apply(Vec3::from_dvec3(pi - pj));
            y[i] += d;
            y[j] -= d;
        }
        if let Some(hinges) = &self.dynamics.bending {
            let filtered: Vec<Vec3<f64>> =
                p.iter().zip(self.held).map(|(&v, &held)| Vec3::from_dvec3(filter(held, v))).collect();
            hinges.add_product_points(1.0, 0.0, &filtered, y, false);
        }
    }

    /// `δx` with `S K S δx = S r`, by preconditioned conjugate gradients, and the iterations;
    /// `None` if `interrupt` is raised first.
    fn solve(&self, residual: &[DVec3], interrupt: &Interrupt) -> Option<(Vec<DVec3>, usize)> {
        let n = residual.len();
        let filter_all = |v: &mut [DVec3]| v.iter_mut().zip(self.held).for_each(|(v, &h)| *v = filter(h, *v));
        let precondition = |r: &[DVec3], z: &mut [DVec3]| {
            for ((z, r), (d, &h)) in z.iter_mut().zip(r).zip(self.diagonal.iter().zip(self.held)) {
                *z = filter(h, *r * *d);
            }
        };
        let dot = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum::<f64>();
        let mut x = vec![DVec3::ZERO; n];
        let mut r = residual.to_vec();
        filter_all(&mut r);
        let target = TOLERANCE * dot(&r, &r).sqrt();
        let mut z = vec![DVec3::ZERO; n];
        precondition(&r, &mut z);
        let mut search = z.clone();
        let mut product = vec![Vec3::ZERO; n];
        let mut q = vec![DVec3::ZERO; n];
        let mut rz = dot(&r, &z);
        let max_iterations = (3 * n).clamp(100, MAX_ITERATIONS);
        let mut iterations = 0;
        while dot(&r, &r).sqrt() > target && iterations < max_iterations {
            if interrupt.is_raised() {
                return None;
            }
            self.apply(&search, &mut product);
            for ((q, v), &h) in q.iter_mut().zip(&product).zip(self.held) {
                *q = filter(h, v.to_dvec3());
            }
            let curvature = dot(&search, &q);
            if !(curvature > 0.0 && curvature.is_finite()) {
                break;
            }
            let alpha = rz / curvature;
            for p in 0..n {
                x[p] += search[p] * alpha;
                r[p] -= q[p] * alpha;
            }
            precondition(&r, &mut z);
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for (s, &z) in search.iter_mut().zip(&z) {
                *s = z + *s * beta;
            }
            iterations += 1;
        }
        filter_all(&mut x);
        Some((x, iterations))
    }
}
