//! The springs of a cloth evaluated as row stencils: the fast force pass for grid bodies.
//!
//! A cloth's springs follow a fixed stencil, six families of the form `(i + ai, j + aj)` to
//! `(i + bi, j + bj)`, each with one rest length, stiffness and damping. Along a grid row the
//! first ends of a family are consecutive particles and so are the second ends, so a family's
//! springs on one row are two contiguous runs of particles: no index lists. The pass copies the
//! body's positions and velocities into per-axis arrays once, evaluates every spring once per row
//! and family into a row buffer (a branch-free loop the compiler vectorises), then adds the row to
//! the first ends and subtracts it from the second. Rows are visited in order and every family of
//! a row in turn, so the three rows a stencil reaches stay in the first-level cache.
//!
//! The result is the same force as the general spring-list loop, summed in a different, fixed
//! order: deterministic, and equal to it up to rounding.

use std::ops::Range;

use super::model::{Model, Spring, SpringGrid};
use super::{Real, Vec3};

/// One spring family of a grid: its stencil offsets and its parameters.
#[derive(Clone, Copy, Debug)]
struct Family<T> {
    /// `[ai, aj, bi, bj]`: the spring joins `(i + ai, j + aj)` to `(i + bi, j + bj)`.
    offsets: [usize; 4],
    rest_length: T,
    stiffness: T,
    damping: T,
}

/// A cloth body whose springs are evaluated by stencil, with its per-axis scratch.
#[derive(Clone, Debug)]
pub(crate) struct GridSprings<T> {
    first: usize,
    nx: usize,
    ny: usize,
    springs: Range<usize>,
    families: Vec<Family<T>>,
    /// Per axis: positions x, y, z then velocities x, y, z.
    state: [Vec<T>; 6],
    forces: [Vec<T>; 3],
    row: [Vec<T>; 3],
}

impl<T: Real> GridSprings<T> {
    /// The grid's stencil evaluator, if `springs[grid.springs]` are exactly the springs its stencil
    /// generates (in the builder's order) with one rest length, stiffness and damping per family
    /// in precision `T`; `None` otherwise, and the springs stay on the general path.
    pub fn new(grid: &SpringGrid, springs: &[Spring<T>]) -> Option<Self> {
        let [nx, ny] = grid.resolution;
        let springs = springs.get(grid.springs.clone())?;
        let at = |i: usize, j: usize| (grid.first_particle + j * nx + i) as u32;
        let mut families = Vec::with_capacity(grid.stencil.len());
        let mut next = springs.iter();
        for &offsets in &grid.stencil {
            let [ai, aj, bi, bj] = offsets;
            let (reach_i, reach_j) = (ai.max(bi), aj.max(bj));
            let mut family: Option<Family<T>> = None;
            for j in 0..ny.saturating_sub(reach_j) {
                for i in 0..nx.saturating_sub(reach_i) {
                    let s = next.next()?;
                    if (s.i, s.j) != (at(i + ai, j + aj), at(i + bi, j + bj)) {
                        return None;
                    }
                    let this = Family {
                        offsets,
                        rest_length: s.rest_length,
                        stiffness: s.stiffness,
                        damping: s.damping,
                    };
                    match family {
                        None => family = Some(this),
                        Some(f)
                            if f.rest_length == this.rest_length
                                && f.stiffness == this.stiffness
                                && f.damping == this.damping => {}
                        Some(_) => return None,
                    }
                }
            }
            families.extend(family);
        }
        if next.next().is_some() {
            return None;
        }
        let n = nx * ny;
        Some(Self {
            first: grid.first_particle,
            nx,
            ny,
            springs: grid.springs.clone(),
            families,
            state: std::array::from_fn(|_| vec![T::ZERO; n]),
            forces: std::array::from_fn(|_| vec![T::ZERO; n]),
            row: std::array::from_fn(|_| vec![T::ZERO; nx]),
        })
    }

    /// The particles of the body.
    pub fn particles(&self) -> Range<usize> {
        self.first..self.first + self.nx * self.ny
    }

    /// The springs of the model's list this body evaluates.
    pub fn springs(&self) -> Range<usize> {
        self.springs.clone()
    }

    /// Adds every spring force of the body to `forces`.
    pub fn add_forces(&mut self, x: &[Vec3<T>], v: &[Vec3<T>], forces: &mut [Vec3<T>]) {
        let range = self.particles();
        let (positions, velocities) = self.state.split_at_mut(3);
        split_axes(&x[range.clone()], positions);
        split_axes(&v[range.clone()], velocities);
        for axis in &mut self.forces {
            axis.fill(T::ZERO);
        }
        let nx = self.nx;
        for j in 0..self.ny {
            for family in &self.families {
                let [ai, aj, bi, bj] = family.offsets;
                if j + aj.max(bj) >= self.ny {
                    continue;
                }
                let len = nx - ai.max(bi);
                let (p, q) = ((j + aj) * nx + ai, (j + bj) * nx + bi);
                let [rx, ry, rz] = &mut self.row;
                let [x, y, z, u, v, w] = &self.state;
                let a = [
                    &x[p..p + len],
                    &y[p..p + len],
                    &z[p..p + len],
                    &u[p..p + len],
                    &v[p..p + len],
                    &w[p..p + len],
                ];
                let b = [
                    &x[q..q + len],
                    &y[q..q + len],
                    &z[q..q + len],
                    &u[q..q + len],
                    &v[q..q + len],
                    &w[q..q + len],
                ];
                spring_row(family, a, b, [&mut rx[..len], &mut ry[..len], &mut rz[..len]]);
                for (axis, row) in self.forces.iter_mut().zip(&self.row) {
                    for (f, &r) in axis[p..p + len].iter_mut().zip(&row[..len]) {
                        *f += r;
                    }
                    for (f, &r) in axis[q..q + len].iter_mut().zip(&row[..len]) {
                        *f -= r;
                    }
                }
            }
        }
        let [fx, fy, fz] = &self.forces;
        for (((f, &x), &y), &z) in forces[range].iter_mut().zip(fx).zip(fy).zip(fz) {
            *f += Vec3::new(x, y, z);
        }
    }
}

/// Copies vectors into three per-axis arrays.
fn split_axes<T: Real>(vectors: &[Vec3<T>], axes: &mut [Vec<T>]) {
    let [ax, ay, az] = axes else { unreachable!("three axes") };
    for (((v, x), y), z) in vectors.iter().zip(ax.iter_mut()).zip(ay.iter_mut()).zip(az.iter_mut()) {
        (*x, *y, *z) = (v.x, v.y, v.z);
    }
}

/// Springs evaluated together: the row loop works on fixed-size blocks of this many, copied into
/// local arrays, which the compiler turns into vector instructions without having to prove that
/// the inputs and the output do not overlap.
const LANES: usize = 8;

/// The force on the first end of `row.len()` springs of one family, whose first ends' positions
/// and velocities (per axis) are `a` and second ends' are `b`, written into `row`.
#[inline(never)]
fn spring_row<T: Real>(family: &Family<T>, a: [&[T]; 6], b: [&[T]; 6], row: [&mut [T]; 3]) {
    let len = row[0].len();
    let [rx, ry, rz] = row;
    let mut s = 0;
    while s + LANES <= len {
        let mut ends_a = [[T::ZERO; LANES]; 6];
        let mut ends_b = [[T::ZERO; LANES]; 6];
        for k in 0..6 {
            ends_a[k].copy_from_slice(&a[k][s..s + LANES]);
            ends_b[k].copy_from_slice(&b[k][s..s + LANES]);
        }
        let mut block = [[T::ZERO; LANES]; 3];
        for lane in 0..LANES {
            let [fx, fy, fz] = spring_force(family, |k| ends_a[k][lane], |k| ends_b[k][lane]);
            block[0][lane] = fx;
            block[1][lane] = fy;
            block[2][lane] = fz;
        }
        rx[s..s + LANES].copy_from_slice(&block[0]);
        ry[s..s + LANES].copy_from_slice(&block[1]);
        rz[s..s + LANES].copy_from_slice(&block[2]);
        s += LANES;
    }
    for s in s..len {
        let [fx, fy, fz] = spring_force(family, |k| a[k][s], |k| b[k][s]);
        rx[s] = fx;
        ry[s] = fy;
        rz[s] = fz;
    }
}

/// The force on the first end of one spring, given each end's `[x, y, z, vx, vy, vz]` by
/// component: the spring-list force (see [`springs`](super::springs)), with the coincident-ends
/// case selected away rather than branched around, so that a block of springs vectorises.
#[inline(always)]
fn spring_force<T: Real>(family: &Family<T>, a: impl Fn(usize) -> T, b: impl Fn(usize) -> T) -> [T; 3] {
    let (dx, dy, dz) = (b(0) - a(0), b(1) - a(1), b(2) - a(2));
    let l2 = dx * dx + dy * dy + dz * dz;
    let l = l2.sqrt();
    let inverse = T::ONE / l;
    let (nx, ny, nz) = (dx * inverse, dy * inverse, dz * inverse);
    let (du, dv, dw) = (b(3) - a(3), b(4) - a(4), b(5) - a(5));
    let magnitude =
        family.stiffness * (l - family.rest_length) + family.damping * (du * nx + dv * ny + dw * nz);
    if l2 > T::from_f64(1e-30) { [nx * magnitude, ny * magnitude, nz * magnitude] } else { [T::ZERO; 3] }
}

/// The grid records of a model whose springs this module can evaluate.
pub(crate) fn grids<T: Real>(model: &Model, springs: &[Spring<T>]) -> Vec<GridSprings<T>> {
    model.grids.iter().filter_map(|g| GridSprings::new(g, springs)).collect()
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::super::bodies::{Cloth, Orientation};
    use super::super::model::SpringParams;
    use super::super::springs;
    use super::*;

    /// A 13 × 5 cloth (13 is not a multiple of the block width, so the tail loop runs too) with
    /// springs of three different parameter sets, bent and moving so every spring is loaded.
    fn moving_cloth() -> (Model, Vec<Vec3<f64>>, Vec<Vec3<f64>>) {
        let mut model = Model::default();
        model.add_cloth(&Cloth {
            size: [1.2, 0.4],
            resolution: [13, 5],
            center: DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Vertical,
            mass: 0.3,
            velocity: DVec3::ZERO,
            structural: SpringParams { stiffness: 900.0, damping: 0.3 },
            shear: SpringParams { stiffness: 400.0, damping: 0.1 },
            bending: SpringParams { stiffness: 50.0, damping: 0.05 },
            pins: vec![],
        });
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
        (model, x, v)
    }

    #[test]
    fn stencil_pass_gives_the_spring_list_force() {
        let (model, x, v) = moving_cloth();
        let springs: Vec<Spring<f64>> = model.springs.clone();
        let mut grid = GridSprings::new(&model.grids[0], &springs).expect("a builder's cloth is a grid");
        assert_eq!(grid.springs(), 0..springs.len());
        let mut by_stencil = vec![Vec3::ZERO; x.len()];
        let mut by_list = vec![Vec3::ZERO; x.len()];
        grid.add_forces(&x, &v, &mut by_stencil);
        springs::add_forces(&springs, &x, &v, &mut by_list);
        let largest = by_list.iter().map(|f| f.length()).fold(0.0, f64::max);
        assert!(largest > 1.0, "the springs are loaded: {largest}");
        for (a, b) in by_stencil.iter().zip(&by_list) {
            assert!((*a - *b).length() <= 1e-12 * largest, "{a:?} against {b:?}");
        }
    }

    #[test]
    fn springs_that_differ_from_the_stencil_stay_on_the_list() {
        let (model, _, _) = moving_cloth();
        let mut springs = model.springs.clone();
        springs[7].rest_length *= 1.01;
        assert!(GridSprings::new(&model.grids[0], &springs).is_none());
        let mut springs = model.springs.clone();
        springs.swap(3, 4);
        assert!(GridSprings::new(&model.grids[0], &springs).is_none());
        assert!(GridSprings::new(&model.grids[0], &model.springs[1..]).is_none());
    }
}
