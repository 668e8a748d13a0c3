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
//! are summed the same way every time.

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

    /// Subtracts `Kₖ g[axis]` from particle `k` of hinge `h`.
    #[inline]
    fn spread(&self, h: usize, g: [T; 3], out: &mut [&mut [T]; 3]) {
        for k in 0..4 {
            let (v, w) = (self.vertices[k][h] as usize, self.weights[k][h]);
            for axis in 0..3 {
                out[axis][v] -= w * g[axis];
            }
        }
    }

    /// Adds every hinge's elastic and damping force at `(x, v)` to `forces`.
    pub fn add_forces(&self, x: &Vectors<T>, v: &Vectors<T>, forces: &mut Vectors<T>) {
        let (x, v) = (x.axes(), v.axes());
        let mut out = forces.axes_mut();
        for h in 0..self.len() {
            let (bend, rate) = (self.moment(h, x), self.moment(h, v));
            let (c, d) = (self.stiffness[h], self.damping[h]);
            let g = std::array::from_fn(|axis| c * bend[axis] + d * rate[axis]);
            self.spread(h, g, &mut out);
        }
    }

    /// Adds `(a C + b D) p` to `y`, where `C = Σ c K Kᵀ` and `D = Σ d K Kᵀ` are the hinges'
    /// stiffness and damping matrices (per axis): implicit Euler's product with `a = h²`,
    /// `b = h`.
    pub fn add_product(&self, a: T, b: T, p: [&[T]; 3], y: [&mut [T]; 3]) {
        let mut y = y;
        for h in 0..self.len() {
            let s = self.moment(h, p);
            let scale = a * self.stiffness[h] + b * self.damping[h];
            // `spread` subtracts: hand it the negated moment.
            let g = s.map(|s| T::ZERO - scale * s);
            self.spread(h, g, &mut y);
        }
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

    /// `-h² C v`, the stiffness term implicit Euler adds to its right-hand side (`h f` already
    /// holds the forces), added to `rhs`.
    pub fn add_velocity_term(&self, h: T, v: [&[T]; 3], rhs: [&mut [T]; 3]) {
        let mut rhs = rhs;
        for k in 0..self.len() {
            let s = self.moment(k, v);
            let scale = h * h * self.stiffness[k];
            self.spread(k, s.map(|s| scale * s), &mut rhs);
        }
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
