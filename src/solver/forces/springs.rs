//! Damped springs: forces, their derivatives for the implicit integrator, energy and strain.
//!
//! A spring between `i` and `j` with `d = x_j - x_i`, `l = |d|`, `n = d / l` pulls `i` with
//! `f_i = [k (l - L) + c (v_j - v_i)·n] n` and `j` with `-f_i`. When `l` is zero the direction is
//! undefined and the spring exerts no force, so coincident particles stay finite.

use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::Spring;

/// The unit direction from `i` to `j` and the distance, or `None` when they coincide.
#[inline(always)]
pub(crate) fn direction<T: Real>(d: Vec3<T>) -> Option<(Vec3<T>, T)> {
    let l2 = d.length_squared();
    // Below this the direction is numerically meaningless; above it `1 / l` cannot overflow.
    if l2 > T::from_f64(1e-30) {
        let l = l2.sqrt();
        Some((d * (T::ONE / l), l))
    } else {
        None
    }
}

/// Adds every spring's force to `forces`, one spring at a time in list order: the definition
/// that the solver's fast passes ([`grid`](super::grid), [`spring_runs`](super::spring_runs)) are
/// checked against.
#[cfg(test)]
pub fn add_forces<T: Real>(springs: &[Spring<T>], x: &Vectors<T>, v: &Vectors<T>, forces: &mut Vectors<T>) {
    for s in springs {
        let (i, j) = (s.i as usize, s.j as usize);
        let Some((n, l)) = direction(x.get(j) - x.get(i)) else { continue };
        let magnitude = s.stiffness * (l - s.rest_length) + s.damping * (v.get(j) - v.get(i)).dot(n);
        let f = n * magnitude;
        forces.add(i, f);
        forces.sub(j, f);
    }
}

/// The force on the first end of a spring of stiffness `k`, rest length `rest` and damping `c`,
/// given the second end's position and velocity relative to the first
/// (`[dx, dy, dz, du, dv, dw]`): the force [`add_forces`] applies, with the coincident-ends case
/// selected away rather than branched around, so that a block of springs evaluated lane by lane
/// compiles to vector instructions.
#[inline(always)]
pub(crate) fn branch_free_force<T: Real>(k: T, rest: T, c: T, [dx, dy, dz, du, dv, dw]: [T; 6]) -> [T; 3] {
    // `f = [k (l - L) + c (Δv·d) / l] d / l`: scaling `d` once by the magnitude over `l`, rather
    // than normalising it first, and fusing the dot products' multiply-adds, keeps the vector
    // loop to a third fewer instructions. `mul_add` rounds once on every target, so the result
    // is the same bits with or without hardware FMA.
    let l2 = dx.mul_add(dx, dy.mul_add(dy, dz * dz));
    let l = l2.sqrt();
    let inverse = T::ONE / l;
    let closing = du.mul_add(dx, dv.mul_add(dy, dw * dz));
    let magnitude = k.mul_add(l - rest, c * closing * inverse);
    let scale = if l2 > T::from_f64(1e-30) { magnitude * inverse } else { T::ZERO };
    [dx * scale, dy * scale, dz * scale]
}

/// The stiffness block `K_s` of one spring as implicit Euler's step takes it:
/// `∂f_i/∂x_i ≈ -K_s`, `∂f_i/∂x_j ≈ K_s`.
///
/// `K_s = k [n nᵀ + α (I - n nᵀ)]` with `α = max(0, 1 - L/l)`: the positive semi-definite part
/// of the exact stiffness (Choi and Ko). The exact transverse factor `1 - L/l` is negative while
/// the spring is compressed: the spring pushes a particle that leaves its line further out
/// (buckling). That push is left out of the step's matrix, so the step takes it explicitly, as
/// the force has it. Taking it by its absolute value instead also keeps `K_s` definite, but adds a
/// drag `h k |1 - L/l|` across every fold that the force does not have, and a fold then settles
/// in about as many steps whatever the step, which at the frame interval keeps a drape from
/// coming to rest (`docs/decisions.md`, "A compressed spring's push across it left explicit").
/// The contacts held in the solve keep the folds lying on a collider on it. Only the step's
/// Jacobian is approximated, never the force, so the states at rest do not depend on it. It is
/// also the softest definite stiffness, the one the distance from equilibrium
/// ([`crate::solver::equilibrium`]) solves with.
#[inline(always)]
pub(crate) fn stiffness_block<T: Real>(s: &Spring<T>, n: Vec3<T>, l: T) -> Sym3<T> {
    block(s, n, step_transverse_factor(s.rest_length / l))
}

/// The step's transverse factor `α = max(0, 1 - L/l)` of [`stiffness_block`], from `L/l`; the
/// grid stencil's branch-free rows take it too. It is below 1 for any positive `L/l`, so the
/// axial factor `1 - α` stays positive.
#[inline(always)]
pub(crate) fn step_transverse_factor<T: Real>(rest_over_length: T) -> T {
    (T::ONE - rest_over_length).max(T::ZERO)
}

/// `k [n nᵀ + α (I - n nᵀ)]`, as a rank-one term plus a multiple of the identity.
#[inline(always)]
fn block<T: Real>(s: &Spring<T>, n: Vec3<T>, alpha: T) -> Sym3<T> {
    Sym3::outer(n) * (s.stiffness * (T::ONE - alpha)) + Sym3::identity() * (s.stiffness * alpha)
}

/// Elastic energy stored in the springs, in joules.
pub fn energy<T: Real>(springs: &[Spring<T>], x: &Vectors<T>) -> f64 {
    springs
        .iter()
        .map(|s| {
            let l = (x.get(s.j as usize) - x.get(s.i as usize)).to_dvec3().length();
            let stretch = l - s.rest_length.to_f64();
            0.5 * s.stiffness.to_f64() * stretch * stretch
        })
        .sum()
}

/// Engineering strain `(l - L) / L` of one spring; zero for a spring of zero rest length.
#[inline]
pub fn strain<T: Real>(s: &Spring<T>, x: &Vectors<T>) -> f64 {
    let rest = s.rest_length.to_f64();
    if rest <= 0.0 {
        return 0.0;
    }
    let l = (x.get(s.j as usize) - x.get(s.i as usize)).to_dvec3().length();
    (l - rest) / rest
}

/// The largest strain over all springs (negative if every spring is compressed), or 0 with none.
pub fn max_strain<T: Real>(springs: &[Spring<T>], x: &Vectors<T>) -> f64 {
    springs.iter().map(|s| strain(s, x)).reduce(f64::max).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::model::SpringKind;

    /// `K n` along the spring and `K t` across it, for a spring of rest length 1 and `k` 100 at
    /// length `l` along x, by each block.
    fn along_and_across(
        block: fn(&Spring<f64>, Vec3<f64>, f64) -> Sym3<f64>,
        l: f64,
    ) -> (Vec3<f64>, Vec3<f64>) {
        let spring = Spring {
            i: 0,
            j: 1,
            rest_length: 1.0,
            stiffness: 100.0,
            damping: 0.0,
            kind: SpringKind::Structural,
        };
        let (n, t) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.6, 0.8));
        let k = block(&spring, n, l);
        (k.apply(n), k.apply(t))
    }

    #[test]
    fn a_stretched_springs_block_is_the_exact_stiffness() {
        // At l = 1.25: k along the spring, k (1 - L/l) = 20 across it.
        let (along, across) = along_and_across(stiffness_block, 1.25);
        assert!((along - Vec3::new(100.0, 0.0, 0.0)).length() < 1e-12, "{along:?}");
        assert!((across - Vec3::new(0.0, 12.0, 16.0)).length() < 1e-12, "{across:?}");
    }

    #[test]
    fn a_compressed_springs_push_across_is_left_out_of_the_step() {
        // At l = 0.8 the exact factor across is 1 - 1/0.8 = -0.25: the block takes 0 across and
        // keeps k along the spring, at any compression.
        for l in [0.8, 0.25] {
            let (along, across) = along_and_across(stiffness_block, l);
            assert!((along - Vec3::new(100.0, 0.0, 0.0)).length() < 1e-12, "{along:?}");
            assert!(across.length() < 1e-12, "{across:?}");
        }
    }
}
