//! Blocks of [`LANES`] springs evaluated side by side: the vector kernel of the fast force passes.
//!
//! The grid pass ([`grid`](super::grid)) and the run pass ([`spring_runs`](super::spring_runs))
//! both evaluate springs whose first ends are consecutive particles and whose second ends are
//! too. They read a block's ends straight from the state's axes into fixed-size arrays, compute
//! the block's forces lane by lane with the branch-free formula of [`springs`](super::springs),
//! and add them into force accumulators: code the compiler turns into full-width vector
//! instructions, with no index lists and no remainder loop.
//!
//! A block's second ends take their forces before its first ends. When both ends lie on the
//! same axis, `s > 0` particles apart, a particle `k` then always receives `-f[k - s]` before
//! `+f[k]`, however the springs are cut into blocks: the order in which forces are summed does
//! not depend on where a block starts.

use super::springs;
use crate::solver::math::real::Real;

/// Springs evaluated side by side: eight `f32` fill a 256-bit vector register.
pub(crate) const LANES: usize = 8;

/// The positions then velocities of a block's ends, per component.
pub(crate) type Ends<'a, T> = [&'a [T; LANES]; 6];

/// The forces on a block's first ends, per axis.
pub(crate) type Forces<T> = [[T; LANES]; 3];

/// The positions then velocities of the `LANES` consecutive particles from `first`, per
/// component, read in place.
#[inline(always)]
pub(crate) fn whole<'a, T: Real>(x: [&'a [T]; 3], v: [&'a [T]; 3], first: usize) -> Ends<'a, T> {
    let ([x0, x1, x2], [v0, v1, v2]) = (axes(x, first), axes(v, first));
    [x0, x1, x2, v0, v1, v2]
}

/// The `LANES` consecutive values from `first` of each of three axes, read in place.
#[inline(always)]
pub(crate) fn axes<T: Real>(axes: [&[T]; 3], first: usize) -> [&[T; LANES]; 3] {
    axes.map(|axis| <&[T; LANES]>::try_from(&axis[first..first + LANES]).expect("a whole block"))
}

/// The positions then velocities of `count < LANES` consecutive particles from `first`, per
/// component, padded with zeros: a padded lane's two ends coincide, so its force is zero.
#[inline(always)]
pub(crate) fn padded<T: Real>(x: [&[T]; 3], v: [&[T]; 3], first: usize, count: usize) -> [[T; LANES]; 6] {
    let mut block = [[T::ZERO; LANES]; 6];
    for (lanes, axis) in block.iter_mut().zip(x.into_iter().chain(v)) {
        lanes[..count].copy_from_slice(&axis[first..first + count]);
    }
    block
}

/// The forces on the first ends of a block of springs of stiffness `k`, damping `c` and rest
/// lengths `rest`, from the ends `a` to the ends `b` (see [`springs::branch_free_force`]).
#[inline(always)]
pub(crate) fn forces<T: Real>(k: T, c: T, rest: &[T; LANES], a: Ends<T>, b: Ends<T>) -> Forces<T> {
    let mut block = [[T::ZERO; LANES]; 3];
    for lane in 0..LANES {
        let d = std::array::from_fn(|axis| b[axis][lane] - a[axis][lane]);
        let [fx, fy, fz] = springs::branch_free_force(k, rest[lane], c, d);
        (block[0][lane], block[1][lane], block[2][lane]) = (fx, fy, fz);
    }
    block
}

/// Adds the first `count` lanes of `block` to `out` from `start`.
#[inline(always)]
pub(crate) fn add<T: Real>(out: [&mut [T]; 3], start: usize, count: usize, block: &Forces<T>) {
    for (axis, lanes) in out.into_iter().zip(block) {
        if count == LANES {
            let axis: &mut [T; LANES] = (&mut axis[start..start + LANES]).try_into().expect("a whole block");
            for lane in 0..LANES {
                axis[lane] += lanes[lane];
            }
        } else {
            for (f, &g) in axis[start..start + count].iter_mut().zip(lanes) {
                *f += g;
            }
        }
    }
}

/// Subtracts the first `count` lanes of `block` from `out` from `start`.
#[inline(always)]
pub(crate) fn subtract<T: Real>(out: [&mut [T]; 3], start: usize, count: usize, block: &Forces<T>) {
    for (axis, lanes) in out.into_iter().zip(block) {
        if count == LANES {
            let axis: &mut [T; LANES] = (&mut axis[start..start + LANES]).try_into().expect("a whole block");
            for lane in 0..LANES {
                axis[lane] -= lanes[lane];
            }
        } else {
            for (f, &g) in axis[start..start + count].iter_mut().zip(lanes) {
                *f -= g;
            }
        }
    }
}
