//! Bending in physical units: elements whose energy is quadratic in the positions, each
//! `E = ½ c |Σₖ Kₖ xₖ|²` over up to four particles with constant weights `K` (summing to zero),
//! stiffness `c` and damping `d`.
//!
//! `Σ Kₖ xₖ` turns with the particles, so every element is blind to rigid motions, and it is
//! zero on the flat rest shape. The force `-c K (K·x)` is linear in the positions, so its
//! Jacobian `-c K Kᵀ ⊗ I₃` is constant: implicit Euler adds it to its system exactly, at any step.
//! Damping is stiffness-proportional (Rayleigh): `-d K (K·v)` with `d = τ c` for the material's
//! time constant `τ`. The bending rigidity `B` is per unit width (N·m): a sheet bent to
//! curvature `κ` stores `½ B κ²` per unit area, and its bending moment per unit width is `B κ`.
//!
//! **A grid cloth** (spacings `a` along `i`, `b` along `j`) has the energy density
//! `½ B (κᵢᵢ² + κⱼⱼ² + 2 κᵢⱼ²)`, the squared second fundamental form: the same for a bend in any
//! direction, with no coupling of the two directions (Poisson ratio 0, as warp and weft bend
//! independently). Three families of elements discretise it, each second order in the spacing:
//! - each particle inside a row with its two neighbours, `K = (1, -2, 1)`: `Σ K x ≈ a² κᵢᵢ n`, so
//!   `c = B b / a³` (half that on the first and last rows, which hold half a row of material);
//! - the same down each column, `c = B a / b³`;
//! - each cell's corners, `K = (1, -1, -1, 1)`: `Σ K x ≈ a b κᵢⱼ n`, `c = 2 B / (a b)`.
//!
//! **A mesh** has one element per interior edge, the quadratic bending of Bergou, Wardetzky,
//! Harmon, Zorin and Grinspun (2006), "A quadratic bending model for inextensible surfaces": for
//! the edge `x0 x1` shared by the triangles `(x0, x1, x2)` and `(x1, x0, x3)`,
//! `K = (c03 + c04, c01 + c02, -c01 - c03, -c02 - c04)` of the rest angles' cotangents (`c0j` at
//! `x0` between the edge and `xj`, `c1j` at `x1`). Bent by a small dihedral angle `θ`, `|Σ K x|`
//! is `|e| θ`, and with `c = B / (A0 + A1)` (the two triangles' rest areas) a mesh of
//! well-shaped triangles bent to a cylinder stores `½ B κ² A`. The edge form depends on the
//! triangles' shapes: right triangles bent across their hypotenuses store several times that,
//! which is why a grid cloth uses its own elements.
//!
//! The elements are stored as structure of arrays and evaluated in one fixed order, so the forces
//! are summed the same way every time. The forces and the implicit solve's products go by runs:
//! consecutive elements whose particles each advance by one and whose weights and constants are
//! equal, as a grid's rows, columns and cells give them (an `n × n` grid's elements make
//! `4 (n − 1)` runs). A run reads and writes each of its four particle sequences contiguously, a
//! stretch at a time, so its loops compile to vector instructions; a mesh's hinges are mostly
//! runs of one, taken one element at a time.

use std::collections::HashMap;

use glam::DVec3;

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::BendingElement;

/// The hinges of a triangulated body at rest, for a bending rigidity `rigidity` (N·m) and a
/// damping time constant `damping_time` (s). `triangles` index `positions`; a hinge is made for
/// every edge shared by exactly two triangles of non-zero area with distinct far vertices, in
/// the order the edges first appear.
pub fn isometric_hinges(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    rigidity: f64,
    damping_time: f64,
) -> Vec<BendingElement> {
    let mut edges: Vec<([u32; 2], Vec<u32>)> = Vec::new();
    let mut edge_index: HashMap<[u32; 2], usize> = HashMap::new();
    for &[a, b, c] in triangles {
        for (p, q, far) in [(a, b, c), (b, c, a), (c, a, b)] {
            let key = [p.min(q), p.max(q)];
            let slot = *edge_index.entry(key).or_insert_with(|| {
                edges.push((key, Vec::new()));
                edges.len() - 1
            });
            edges[slot].1.push(far);
        }
    }
    edges
        .iter()
        .filter_map(|(edge, far)| match far[..] {
            [f, g] if f != g => hinge([edge[0], edge[1], f, g], positions, rigidity, damping_time),
            _ => None,
        })
        .collect()
}

/// The element on `vertices` (the edge, then the far vertices), or `None` when a triangle is
/// degenerate.
fn hinge(
    vertices: [u32; 4],
    positions: &[DVec3],
    rigidity: f64,
    damping_time: f64,
) -> Option<BendingElement> {
    let [x0, x1, x2, x3] = vertices.map(|v| positions[v as usize]);
    let (e0, e1, e2, e3, e4) = (x1 - x0, x2 - x0, x3 - x0, x2 - x1, x3 - x1);
    let cot = |a: DVec3, b: DVec3| {
        let sine = a.cross(b).length();
        (sine > 0.0).then(|| a.dot(b) / sine)
    };
    let (c01, c02, c03, c04) = (cot(e0, e1)?, cot(e0, e2)?, cot(-e0, e3)?, cot(-e0, e4)?);
    let area = 0.5 * (e0.cross(e1).length() + e0.cross(e2).length());
    let weights = [c03 + c04, c01 + c02, -c01 - c03, -c02 - c04];
    let stiffness = rigidity / area;
    (stiffness.is_finite() && weights.iter().all(|w| w.is_finite())).then_some(BendingElement {
        vertices,
        weights,
        stiffness,
        damping: damping_time * stiffness,
    })
}

/// The bending elements of an `nx × ny` grid cloth whose particle `(i, j)` is
/// `first + j * nx + i`, of spacings `[a, b]`, rigidity `rigidity` (N·m) and damping time
/// constant `damping_time` (s): rows, then columns, then cells (see the module's documentation).
pub fn grid_bending(
    first: usize,
    [nx, ny]: [usize; 2],
    [a, b]: [f64; 2],
    rigidity: f64,
    damping_time: f64,
) -> Vec<BendingElement> {
    let at = |i: usize, j: usize| (first + j * nx + i) as u32;
    // The first and last row (column) stand for half a row (column) of material.
    let share = |k: usize, n: usize| if k == 0 || k == n - 1 { 0.5 } else { 1.0 };
    let element = |vertices: [u32; 4], weights: [f64; 4], stiffness: f64| BendingElement {
        vertices,
        weights,
        stiffness,
        damping: damping_time * stiffness,
    };
    let mut elements = Vec::new();
    for j in 0..ny {
        for i in 1..nx - 1 {
            let stiffness = rigidity * share(j, ny) * b / (a * a * a);
            let vertices = [at(i - 1, j), at(i, j), at(i + 1, j), at(i, j)];
            elements.push(element(vertices, [1.0, -2.0, 1.0, 0.0], stiffness));
        }
    }
    for j in 1..ny - 1 {
        for i in 0..nx {
            let stiffness = rigidity * share(i, nx) * a / (b * b * b);
            let vertices = [at(i, j - 1), at(i, j), at(i, j + 1), at(i, j)];
            elements.push(element(vertices, [1.0, -2.0, 1.0, 0.0], stiffness));
        }
    }
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let vertices = [at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)];
            elements.push(element(vertices, [1.0, -1.0, -1.0, 1.0], 2.0 * rigidity / (a * b)));
        }
    }
    elements
}

/// The bending elements of a simulation in precision `T`, one array per field.
#[derive(Clone, Debug)]
pub(crate) struct BendingElements<T> {
    vertices: [Vec<u32>; 4],
    weights: [Vec<T>; 4],
    stiffness: Vec<T>,
    damping: Vec<T>,
    /// `(first element, length)` of each run: element `first + t` of a run has particles
    /// `vertices[k][first] + t` and the first element's weights and constants.
    runs: Vec<(usize, usize)>,
}

/// How many elements of a run are evaluated at once (their forces held on the stack).
const STRETCH: usize = 64;

/// Whether element `next` continues the run of element `previous`: each particle one further on,
/// the same weights and constants.
fn continues(previous: &BendingElement, next: &BendingElement) -> bool {
    (0..4).all(|k| previous.vertices[k].checked_add(1) == Some(next.vertices[k]))
        && previous.weights == next.weights
        && previous.stiffness == next.stiffness
        && previous.damping == next.damping
}

impl<T: Real> BendingElements<T> {
    /// The model's hinges, or `None` when it has none.
    pub fn new(hinges: &[BendingElement]) -> Option<Self> {
        if hinges.is_empty() {
            return None;
        }
        Some(Self {
            vertices: std::array::from_fn(|k| hinges.iter().map(|h| h.vertices[k]).collect()),
            weights: std::array::from_fn(|k| hinges.iter().map(|h| T::from_f64(h.weights[k])).collect()),
            stiffness: hinges.iter().map(|h| T::from_f64(h.stiffness)).collect(),
            damping: hinges.iter().map(|h| T::from_f64(h.damping)).collect(),
            runs: hinges.iter().enumerate().fold(Vec::new(), |mut runs, (h, hinge)| {
                match runs.last_mut() {
                    Some((_, length)) if continues(&hinges[h - 1], hinge) => *length += 1,
                    _ => runs.push((h, 1)),
                }
                runs
            }),
        })
    }

    /// The number of hinges.
    pub fn len(&self) -> usize {
        self.stiffness.len()
    }

    /// `Σₖ Kₖ pₖ` of hinge `h` for each axis of `p`.
    #[inline]
    fn moment(&self, h: usize, p: [&[T]; 3]) -> [T; 3] {
        let mut sum = [T::ZERO; 3];
        for k in 0..4 {
            let (v, w) = (self.vertices[k][h] as usize, self.weights[k][h]);
            for axis in 0..3 {
                sum[axis] += w * p[axis][v];
            }
        }
        sum
    }

    /// Adds every hinge's elastic and damping force at `(x, v)` to `forces`.
    pub fn add_forces(&self, x: &Vectors<T>, v: &Vectors<T>, forces: &mut Vectors<T>) {
        self.subtract_by_runs(x.axes(), v.axes(), |c, d| (c, d), forces.axes_mut());
    }

    /// Subtracts `Kₖ (α K·p + β K·q)` from each element's particle `k` in `out`, with
    /// `(α, β) = constants(c, d)` of the element's stiffness and damping, run by run: for a
    /// stretch of a run, first each element's sum per axis, then its share to each of the four
    /// particle sequences in turn.
    fn subtract_by_runs(
        &self,
        p: [&[T]; 3],
        q: [&[T]; 3],
        constants: impl Fn(T, T) -> (T, T),
        out: [&mut [T]; 3],
    ) {
        for &(first, length) in &self.runs {
            let particles: [usize; 4] = std::array::from_fn(|k| self.vertices[k][first] as usize);
            let weights: [T; 4] = std::array::from_fn(|k| self.weights[k][first]);
            let (alpha, beta) = constants(self.stiffness[first], self.damping[first]);
            if length == 1 {
                for axis in 0..3 {
                    let g = particles
                        .iter()
                        .zip(&weights)
                        .fold(T::ZERO, |g, (&at, &w)| g + w * (alpha * p[axis][at] + beta * q[axis][at]));
                    for (&at, &w) in particles.iter().zip(&weights) {
                        out[axis][at] -= w * g;
                    }
                }
                continue;
            }
            for start in (0..length).step_by(STRETCH) {
                let n = STRETCH.min(length - start);
                for axis in 0..3 {
                    let mut g = [T::ZERO; STRETCH];
                    for (&at, &w) in particles.iter().zip(&weights) {
                        let (ps, qs) = (&p[axis][at + start..][..n], &q[axis][at + start..][..n]);
                        for ((g, &p), &q) in g.iter_mut().zip(ps).zip(qs) {
                            *g += w * (alpha * p + beta * q);
                        }
                    }
                    for (&at, &w) in particles.iter().zip(&weights) {
                        for (f, &g) in out[axis][at + start..][..n].iter_mut().zip(&g) {
                            *f -= w * g;
                        }
                    }
                }
            }
        }
    }

    /// Subtracts `Kₖ s (K·p)` from each element's particle `k` in `out`, with `s = scale(c, d)`
    /// of the element's stiffness and damping, run by run as
    /// [`subtract_by_runs`](Self::subtract_by_runs) does, but with one constant and without the
    /// particles of zero weight (a row's or column's element has three): the implicit solve's
    /// products.
    fn subtract_scaled_by_runs(&self, p: [&[T]; 3], scale: impl Fn(T, T) -> T, out: [&mut [T]; 3]) {
        for &(first, length) in &self.runs {
            let s = scale(self.stiffness[first], self.damping[first]);
            let mut weighted = [(0, T::ZERO, T::ZERO); 4];
            let mut count = 0;
            for k in 0..4 {
                let w = self.weights[k][first];
                if w != T::ZERO {
                    weighted[count] = (self.vertices[k][first] as usize, w, w * s);
                    count += 1;
                }
            }
            let weighted = &weighted[..count];
            for start in (0..length).step_by(STRETCH) {
                let n = STRETCH.min(length - start);
                for axis in 0..3 {
                    let mut g = [T::ZERO; STRETCH];
                    for &(at, _, ws) in weighted {
                        for (g, &p) in g[..n].iter_mut().zip(&p[axis][at + start..][..n]) {
                            *g += ws * p;
                        }
                    }
                    for &(at, w, _) in weighted {
                        for (f, &g) in out[axis][at + start..][..n].iter_mut().zip(&g[..n]) {
                            *f -= w * g;
                        }
                    }
                }
            }
        }
    }

    /// Adds `(a C + b D) p` to `y`, where `C = Σ c K Kᵀ` and `D = Σ d K Kᵀ` are the hinges'
    /// stiffness and damping matrices (per axis): implicit Euler's product with `a = h²`,
    /// `b = h`.
    pub fn add_product(&self, a: T, b: T, p: [&[T]; 3], y: [&mut [T]; 3]) {
        // Subtracting `K (-(a c + b d) K·p)` adds the product.
        self.subtract_scaled_by_runs(p, |c, d| T::ZERO - (a * c + b * d), y);
    }

    /// Adds the diagonal of `a C + b D` (the same on each axis) to `diagonal`.
    pub fn add_diagonal(&self, a: T, b: T, diagonal: &mut [T]) {
        for h in 0..self.len() {
            let scale = a * self.stiffness[h] + b * self.damping[h];
            for k in 0..4 {
                let w = self.weights[k][h];
                diagonal[self.vertices[k][h] as usize] += scale * w * w;
            }
        }
    }

    /// Calls `entry(p, q, c Kₚ K_q, d Kₚ K_q)` for every ordered pair of particles `(p, q)` of
    /// every hinge with non-zero weights, `p == q` included: the entries whose sums are `C` and
    /// `D` (per axis), for a preconditioner that stores them in its own form.
    pub fn for_each_entry(&self, mut entry: impl FnMut(usize, usize, f64, f64)) {
        for h in 0..self.len() {
            let (c, d) = (self.stiffness[h].to_f64(), self.damping[h].to_f64());
            let corners = (0..4).map(|k| (self.vertices[k][h] as usize, self.weights[k][h].to_f64()));
            for (p, wp) in corners.clone().filter(|&(_, w)| w != 0.0) {
                for (q, wq) in corners.clone().filter(|&(_, w)| w != 0.0) {
                    entry(p, q, c * wp * wq, d * wp * wq);
                }
            }
        }
    }

    /// `-h² C v`, the stiffness term implicit Euler adds to its right-hand side (`h f` already
    /// holds the forces), added to `rhs`.
    pub fn add_velocity_term(&self, h: T, v: [&[T]; 3], rhs: [&mut [T]; 3]) {
        self.subtract_scaled_by_runs(v, |c, _| h * h * c, rhs);
    }

    /// [`add_product`](Self::add_product) for points stored as vectors: the spring-list solver's
    /// layout. With `a = 0`, `b = h²` and `p = v` on the stiffness alone it is the right-hand
    /// side's term, so `velocity_term` selects `D` out: `y += (a C + b D) p` or, with it,
    /// `y -= b C p`.
    pub fn add_product_points(&self, a: T, b: T, p: &[Vec3<T>], y: &mut [Vec3<T>], velocity_term: bool) {
        for h in 0..self.len() {
            let mut s = Vec3::ZERO;
            for k in 0..4 {
                s += p[self.vertices[k][h] as usize] * self.weights[k][h];
            }
            let scale = if velocity_term {
                T::ZERO - b * self.stiffness[h]
            } else {
                a * self.stiffness[h] + b * self.damping[h]
            };
            for k in 0..4 {
                y[self.vertices[k][h] as usize] += s * (scale * self.weights[k][h]);
            }
        }
    }

    /// The hinges' elastic energy `½ Σ c |K·x|²`, in joules.
    pub fn energy(&self, x: &Vectors<T>) -> f64 {
        let x = x.axes();
        (0..self.len())
            .map(|h| {
                let s = self.moment(h, x);
                0.5 * self.stiffness[h].to_f64() * s.iter().map(|s| s.to_f64() * s.to_f64()).sum::<f64>()
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The forces by the element-by-element definition, `-Kₖ (c K·x + d K·v)` on each particle.
    fn forces_by_elements(elements: &[BendingElement], x: &[DVec3], v: &[DVec3]) -> Vec<DVec3> {
        let mut forces = vec![DVec3::ZERO; x.len()];
        for e in elements {
            let sum = |p: &[DVec3]| (0..4).map(|k| p[e.vertices[k] as usize] * e.weights[k]).sum::<DVec3>();
            let g = e.stiffness * sum(x) + e.damping * sum(v);
            for k in 0..4 {
                forces[e.vertices[k] as usize] -= e.weights[k] * g;
            }
        }
        forces
    }

    /// A grid's elements (long runs, after three other particles) and a mesh's hinges (runs of
    /// one) give the forces and the implicit product of their definition, at a state of no
    /// symmetry.
    #[test]
    fn forces_by_runs_are_the_forces_of_the_elements() {
        let (nx, ny) = (9, 7);
        let grid = grid_bending(3, [nx, ny], [0.1, 0.12], 2e-3, 1e-2);
        let flat: Vec<DVec3> = (0..16).map(|p| DVec3::new((p % 4) as f64, 0.0, (p / 4) as f64)).collect();
        let triangles: Vec<[u32; 3]> = (0..9u32)
            .flat_map(|c| {
                let p = c + c / 3;
                [[p, p + 4, p + 1], [p + 1, p + 4, p + 5]]
            })
            .collect();
        let mesh = isometric_hinges(&flat, &triangles, 2e-3, 1e-2);
        for (elements, n) in [(grid, 3 + nx * ny), (mesh, 16)] {
            let wobble = |p: usize, f: f64| {
                DVec3::new((f * p as f64).sin(), (1.7 * f * p as f64).cos(), 0.3 * p as f64)
            };
            let x: Vec<DVec3> = (0..n).map(|p| wobble(p, 1.3)).collect();
            let v: Vec<DVec3> = (0..n).map(|p| wobble(p, 0.7)).collect();
            let bending = BendingElements::<f64>::new(&elements).unwrap();
            let as_vectors = |p: &[DVec3]| p.iter().map(|&p| Vec3::from_dvec3(p)).collect::<Vectors<f64>>();
            let mut forces = Vectors::zeros(n);
            bending.add_forces(&as_vectors(&x), &as_vectors(&v), &mut forces);
            let expected = forces_by_elements(&elements, &x, &v);
            let scale = expected.iter().map(|f| f.length()).fold(0.0, f64::max);
            for (p, want) in expected.iter().enumerate() {
                let got = forces.get(p).to_dvec3();
                assert!((got - *want).length() <= 1e-13 * scale, "particle {p}: {got} against {want}");
            }
            // The implicit solve's product `(a C + b D) p` is the force of elements of stiffness
            // `-(a c + b d)` at `p`, with no damping.
            let (a, b) = (0.3, 0.7);
            let scaled: Vec<BendingElement> = elements
                .iter()
                .map(|e| BendingElement { stiffness: -(a * e.stiffness + b * e.damping), damping: 0.0, ..*e })
                .collect();
            let expected = forces_by_elements(&scaled, &x, &v);
            let (points, mut product) = (as_vectors(&x), Vectors::zeros(n));
            bending.add_product(a, b, points.axes(), product.axes_mut());
            for (p, want) in expected.iter().enumerate() {
                let got = product.get(p).to_dvec3();
                assert!((got - *want).length() <= 1e-13 * scale, "particle {p}: {got} against {want}");
            }
        }
        let square =
            BendingElements::<f32>::new(&grid_bending(0, [128, 128], [0.01, 0.01], 1e-5, 1e-4)).unwrap();
        assert_eq!((square.len(), square.runs.len()), (2 * 126 * 128 + 127 * 127, 4 * 127));
    }
}
