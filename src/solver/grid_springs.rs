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

    /// Adds every spring force of the body to `forces` (`masses` are the particles').
    pub fn add_forces(&mut self, x: &[Vec3<T>], v: &[Vec3<T>], masses: &[T], forces: &mut [Vec3<T>]) {
        self.load(x, v, masses, |_, _| Vec3::ZERO);
        self.add_springs();
        let [fx, fy, fz] = &self.forces;
        for (((f, &x), &y), &z) in forces[self.particles()].iter_mut().zip(fx).zip(fy).zip(fz) {
            *f += Vec3::new(x, y, z);
        }
    }

    /// Copies the body's positions and velocities into the per-axis arrays and starts each
    /// particle's force at `initial(mass, velocity)`.
    pub fn load(
        &mut self,
        x: &[Vec3<T>],
        v: &[Vec3<T>],
        masses: &[T],
        initial: impl Fn(T, Vec3<T>) -> Vec3<T>,
    ) {
        let range = self.particles();
        let n = range.len();
        let (x, v, masses) = (&x[range.clone()], &v[range.clone()], &masses[range]);
        let [px, py, pz, vx, vy, vz] = self.state.each_mut().map(|axis| &mut axis[..n]);
        let [fx, fy, fz] = self.forces.each_mut().map(|axis| &mut axis[..n]);
        for k in 0..n {
            let (position, velocity) = (x[k], v[k]);
            (px[k], py[k], pz[k]) = (position.x, position.y, position.z);
            (vx[k], vy[k], vz[k]) = (velocity.x, velocity.y, velocity.z);
            let f = initial(masses[k], velocity);
            (fx[k], fy[k], fz[k]) = (f.x, f.y, f.z);
        }
    }

    /// Adds every spring force to the loaded forces, row after row.
    pub fn add_springs(&mut self) {
        let nx = self.nx;
        for j in 0..self.ny {
            for family in &self.families {
                let [ai, aj, bi, bj] = family.offsets;
                if j + aj.max(bj) >= self.ny {
                    continue;
                }
                let len = nx - ai.max(bi);
                let (p, q) = ((j + aj) * nx + ai, (j + bj) * nx + bi);
                spring_row(family, &self.state, &mut self.forces, p, q, len);
            }
        }
    }

    /// Symplectic Euler on the body from the loaded state and forces (`v += h f w`, then
    /// `x += h v`), written to `x` and `v`. Returns `Σ m |v|²` and the sum of every position
    /// component, summed in particle order as the stability watch sums them.
    pub fn symplectic_update(
        &self,
        masses: &[T],
        inverse_masses: &[T],
        h: T,
        x: &mut [Vec3<T>],
        v: &mut [Vec3<T>],
    ) -> (T, T) {
        let range = self.particles();
        let n = range.len();
        let (x, v) = (&mut x[range.clone()], &mut v[range.clone()]);
        let (masses, inverse_masses) = (&masses[range.clone()], &inverse_masses[range]);
        let [px, py, pz, vx, vy, vz] = self.state.each_ref().map(|axis| &axis[..n]);
        let [fx, fy, fz] = self.forces.each_ref().map(|axis| &axis[..n]);
        let (mut twice_kinetic, mut position_sum) = (T::ZERO, T::ZERO);
        for k in 0..n {
            let acceleration = Vec3::new(fx[k], fy[k], fz[k]) * inverse_masses[k];
            let velocity = Vec3::new(vx[k], vy[k], vz[k]) + acceleration * h;
            let position = Vec3::new(px[k], py[k], pz[k]) + velocity * h;
            (x[k], v[k]) = (position, velocity);
            twice_kinetic += masses[k] * velocity.length_squared();
            position_sum += position.x + position.y + position.z;
        }
        (twice_kinetic, position_sum)
    }
}

/// Springs evaluated together: the row loop works on fixed-size blocks of this many, copied into
/// local arrays, which the compiler turns into vector instructions without having to prove that
/// the inputs and the output do not overlap. A row's last, partial block is padded with
/// coincident ends, whose force is zero, and only its real springs are kept.
const LANES: usize = 8;

/// Adds the force of `len` springs of one family, from particles `p..p + len` to `q..q + len`,
/// to the first ends' forces and subtracts it from the second ends'. `state` holds the per-axis
/// positions then velocities, `forces` the per-axis forces.
#[inline(never)]
fn spring_row<T: Real>(
    family: &Family<T>,
    state: &[Vec<T>; 6],
    forces: &mut [Vec<T>; 3],
    p: usize,
    q: usize,
    len: usize,
) {
    let mut s = 0;
    while s + LANES <= len {
        let mut ends_a = [[T::ZERO; LANES]; 6];
        let mut ends_b = [[T::ZERO; LANES]; 6];
        for ((a, b), axis) in ends_a.iter_mut().zip(&mut ends_b).zip(state) {
            a.copy_from_slice(&axis[p + s..p + s + LANES]);
            b.copy_from_slice(&axis[q + s..q + s + LANES]);
        }
        let block = spring_block(family, &ends_a, &ends_b);
        for (axis, block) in forces.iter_mut().zip(&block) {
            let first: &mut [T; LANES] = (&mut axis[p + s..p + s + LANES]).try_into().expect("a full block");
            for (f, &b) in first.iter_mut().zip(block) {
                *f += b;
            }
            let second: &mut [T; LANES] = (&mut axis[q + s..q + s + LANES]).try_into().expect("a full block");
            for (f, &b) in second.iter_mut().zip(block) {
                *f -= b;
            }
        }
        s += LANES;
    }
    let width = len - s;
    if width == 0 {
        return;
    }
    let mut ends_a = [[T::ZERO; LANES]; 6];
    let mut ends_b = [[T::ZERO; LANES]; 6];
    for ((a, b), axis) in ends_a.iter_mut().zip(&mut ends_b).zip(state) {
        a[..width].copy_from_slice(&axis[p + s..p + len]);
        b[..width].copy_from_slice(&axis[q + s..q + len]);
    }
    let block = spring_block(family, &ends_a, &ends_b);
    for (axis, block) in forces.iter_mut().zip(&block) {
        for (f, &b) in axis[p + s..p + len].iter_mut().zip(block) {
            *f += b;
        }
        for (f, &b) in axis[q + s..q + len].iter_mut().zip(block) {
            *f -= b;
        }
    }
}

/// The forces on the first ends of a block of springs, per axis.
#[inline(always)]
fn spring_block<T: Real>(family: &Family<T>, a: &[[T; LANES]; 6], b: &[[T; LANES]; 6]) -> [[T; LANES]; 3] {
    let mut block = [[T::ZERO; LANES]; 3];
    for lane in 0..LANES {
        let [fx, fy, fz] = spring_force(family, |k| a[k][lane], |k| b[k][lane]);
        block[0][lane] = fx;
        block[1][lane] = fy;
        block[2][lane] = fz;
    }
    block
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
        grid.add_forces(&x, &v, &vec![1.0; x.len()], &mut by_stencil);
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

    #[test]
    fn fused_symplectic_step_follows_the_spring_list_path() {
        use super::super::{Config, IntegratorKind, Simulation};
        let (mut model, _, _) = moving_cloth();
        model.pin(0);
        let config =
            Config { integrator: IntegratorKind::SymplecticEuler, dt: 2e-4, drag: 0.5, ..Config::default() };
        let mut fused = Simulation::<f64>::new(&model, &config);
        model.grids.clear();
        let mut listed = Simulation::<f64>::new(&model, &config);
        for _ in 0..500 {
            fused.step().expect("stable");
            listed.step().expect("stable");
        }
        let (a, b) = (fused.state(), listed.state());
        assert_eq!(a.positions[0], b.positions[0], "the pin holds");
        let moved = (a.positions[40] - Vec3::from_dvec3(model.positions[40])).length();
        assert!(moved > 1e-3, "the cloth moved {moved} m");
        for (p, q) in a.positions.iter().zip(&b.positions) {
            assert!((*p - *q).length() < 1e-9, "{p:?} against {q:?}");
        }
        assert!((fused.energy().kinetic - listed.energy().kinetic).abs() < 1e-9);
    }

    /// The performance peers' hanging cloth (`/work/shared/bench/peers`): N = 32, 1 s at 1e-4 s.
    /// Their NumPy, Taichi, Warp, Newton and C++ versions all end with the centre particle at
    /// y = 0.53204 and particle (0, 31) at y = 0.17014 (spread 4e-7 among them, in f32).
    fn peers_cloth_after_one_second<T: Real>() -> (f64, f64) {
        use super::super::{Config, IntegratorKind, Simulation};
        let n = 32;
        let springs = SpringParams { stiffness: 5000.0, damping: 0.5 };
        let mut model = Model::default();
        model.add_cloth(&Cloth {
            size: [1.0, 1.0],
            resolution: [n, n],
            center: DVec3::new(0.5, 1.0, 0.5),
            orientation: Orientation::Horizontal,
            mass: 1.0,
            velocity: DVec3::ZERO,
            structural: springs,
            shear: springs,
            bending: springs,
            pins: vec![[0, 0], [n - 1, 0]],
        });
        let config = Config {
            integrator: IntegratorKind::SymplecticEuler,
            dt: 1e-4,
            drag: 0.01 * (n * n) as f64,
            ..Config::default()
        };
        let mut simulation = Simulation::<T>::new(&model, &config);
        for _ in 0..10_000 {
            simulation.step().expect("stable at the peers' step");
        }
        let y = |i: usize, j: usize| simulation.state().positions[j * n + i].y.to_f64();
        (y(n / 2, n / 2), y(0, n - 1))
    }

    #[test]
    fn the_peers_cloth_hangs_where_every_peer_puts_it() {
        for (centre, corner) in [peers_cloth_after_one_second::<f32>(), peers_cloth_after_one_second::<f64>()]
        {
            assert!((centre - 0.5320434).abs() < 3e-6, "centre at y = {centre}");
            assert!((corner - 0.1701399).abs() < 3e-6, "corner at y = {corner}");
        }
    }
}
