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

/// The stiffness block `K_s` of one spring: `∂f_i/∂x_i = -K_s`, `∂f_i/∂x_j = K_s`.
///
/// `K_s = k [n nᵀ + α (I - n nᵀ)]` with `α = max(0, 1 - L/l)`: the transverse term is dropped
/// while the spring is compressed, which keeps `K_s` positive semi-definite (Choi and Ko).
#[inline(always)]
pub(crate) fn stiffness_block<T: Real>(s: &Spring<T>, n: Vec3<T>, l: T) -> Sym3<T> {
    let alpha = (T::ONE - s.rest_length / l).max(T::ZERO);
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
