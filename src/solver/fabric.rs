//! Fabrics in physical units: a membrane, a bending rigidity and an areal density turned into
//! the constants of a body's springs, hinges and particles, so that the same fabric behaves the
//! same at any resolution.
//!
//! A [`Fabric`] has the density `ρ` (kg/m²), the stretch stiffness `S` and shear stiffness `G`
//! of its membrane (N/m), its bending rigidity per unit width `B` (N·m, the textile `B`) and a
//! damping time constant `τ` (s): every element's damping is `τ` times its stiffness
//! (stiffness-proportional Rayleigh damping), so a deformation mode of angular frequency `ω` is
//! damped at the rate `½ τ ω²`, whatever the resolution.
//!
//! **A grid cloth** with spacings `a` along `i` and `b` along `j` and `d² = a² + b²` gets, for a
//! strain field `ε`, the energy density of its springs (each cell has one spring of each
//! structural family and both diagonals)
//! `W = ½ kᵢ (a/b) εᵢᵢ² + ½ kⱼ (b/a) εⱼⱼ² + (k_d / (a b d²)) [(a² εᵢᵢ + b² εⱼⱼ)² + 4 a² b² εᵢⱼ²]`.
//! With `k_d = G d² / (2 a b)` the diagonals give the shear modulus `∂²W/∂γ² = G` (`γ = 2εᵢⱼ`);
//! with `kᵢ = (S − G) b / a` and `kⱼ = (S − G) a / b` a uniaxial stretch with the other direction
//! held gives `σ = S ε` along either axis. None of the constants depends on the number of cells
//! but through the cell's aspect ratio: refining the grid keeps the material. This asks `G < S`,
//! which woven fabrics meet by two orders of magnitude. A particle carries the area of its
//! quarter cells times `ρ`.
//!
//! **A mesh** gets Van Gelder's (1998) spring constants: an edge `e` of the triangles of rest
//! areas `A_t` has `k_e = E Σ_t A_t / |e|²`, which makes a mesh of equilateral triangles an
//! isotropic membrane of Young's modulus `E` and Poisson ratio 1/3 exactly (other meshes
//! approximately). A triangle spring network has that one Poisson ratio, so its shear modulus is
//! `3E/8` and not free: a mesh takes `E = 8S/9`, for which the held uniaxial stretch gives
//! `σ = E/(1 − ν²) ε = S ε`, and does not read `G`. A vertex carries a third of the area of its
//! triangles times `ρ`.
//!
//! A grid cloth bends by the second differences of its rows and columns and the cross
//! differences of its cells, a mesh by hinges on its interior edges, both of rigidity `B` (see
//! [`bending`](crate::solver::forces::bending)).

use std::ops::Range;

use crate::solver::bodies::{CLOTH_STENCIL, Cloth, ClothMass, Mesh, vertex_areas};
use crate::solver::forces::bending::{grid_bending, isometric_hinges};
use crate::solver::model::{Model, SpringKind, SpringParams};

/// A fabric in physical units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fabric {
    /// Mass per area, in kg/m².
    pub density: f64,
    /// Membrane stiffness in uniaxial stretch with the other direction held, in N/m.
    pub stretch: f64,
    /// Membrane shear stiffness (shear force per width per radian), in N/m.
    pub shear: f64,
    /// Bending rigidity per unit width, in N·m.
    pub bending: f64,
    /// Every element's damping over its stiffness, in seconds.
    pub damping_time: f64,
}

impl Fabric {
    /// The stiffness of the springs along `i`, along `j` and across the diagonals of a grid of
    /// spacings `a` along `i` and `b` along `j` (see the module's documentation).
    pub fn grid_stiffness(&self, a: f64, b: f64) -> [f64; 3] {
        let axial = self.stretch - self.shear;
        [axial * b / a, axial * a / b, self.shear * (a * a + b * b) / (2.0 * a * b)]
    }

    /// Young's modulus a triangle spring network takes so that a held uniaxial stretch gives
    /// `σ = S ε` (see the module's documentation), in N/m.
    pub fn mesh_young_modulus(&self) -> f64 {
        8.0 / 9.0 * self.stretch
    }

    fn params(&self, stiffness: f64) -> SpringParams {
        SpringParams { stiffness, damping: self.damping_time * stiffness }
    }
}

impl Model {
    /// Adds a cloth of `fabric`, its grid as [`add_cloth`](Self::add_cloth) lays it out, with
    /// structural and shear springs and hinges on every interior edge; the cloth's spring
    /// parameters and mass are not read.
    pub fn add_fabric_cloth(&mut self, cloth: &Cloth, fabric: &Fabric) -> Range<usize> {
        let [nx, ny] = cloth.resolution;
        let (a, b) = (cloth.size[0] / (nx - 1) as f64, cloth.size[1] / (ny - 1) as f64);
        let [along_i, along_j, diagonal] = fabric.grid_stiffness(a, b);
        let [(_, [structural_i, structural_j]), (_, [shear_a, shear_b]), _] = CLOTH_STENCIL;
        let families = [
            (SpringKind::Structural, structural_i, fabric.params(along_i)),
            (SpringKind::Structural, structural_j, fabric.params(along_j)),
            (SpringKind::Shear, shear_a, fabric.params(diagonal)),
            (SpringKind::Shear, shear_b, fabric.params(diagonal)),
        ];
        let range = self.add_grid_cloth(cloth, ClothMass::ByArea(fabric.density), &families);
        let elements = grid_bending(range.start, [nx, ny], [a, b], fabric.bending, fabric.damping_time);
        self.bending.extend(elements);
        range
    }

    /// Adds a mesh of `fabric`: Van Gelder springs on its edges and hinges on its interior
    /// edges; the mesh's spring parameters and mass are not read.
    pub fn add_fabric_mesh(&mut self, mesh: &Mesh, fabric: &Fabric) -> Range<usize> {
        let areas = vertex_areas(&mesh.vertices, &mesh.triangles);
        let range =
            self.add_particles(mesh.vertices.iter().copied(), |v| fabric.density * areas[v], mesh.velocity);
        let at = |v: usize| range.start + v;
        // Each undirected edge, in first-seen order, with the rest area of its triangles.
        let mut edges: Vec<([usize; 2], f64)> = Vec::new();
        let mut edge_index = std::collections::HashMap::new();
        let first_triangle = self.triangles.len();
        for &[a, b, c] in &mesh.triangles {
            let [pa, pb, pc] = [a, b, c].map(|v| mesh.vertices[v]);
            let area = 0.5 * (pb - pa).cross(pc - pa).length();
            for (p, q) in [(a, b), (b, c), (c, a)] {
                let key = [p.min(q), p.max(q)];
                let slot = *edge_index.entry(key).or_insert_with(|| {
                    edges.push((key, 0.0));
                    edges.len() - 1
                });
                edges[slot].1 += area;
            }
            self.triangles.push([at(a) as u32, at(b) as u32, at(c) as u32]);
        }
        let young = fabric.mesh_young_modulus();
        for &([p, q], area) in &edges {
            let length_squared = mesh.vertices[p].distance_squared(mesh.vertices[q]);
            if length_squared > 0.0 {
                let params = fabric.params(young * area / length_squared);
                self.connect(at(p), at(q), params, SpringKind::Structural);
            }
        }
        self.add_hinges(first_triangle, fabric);
        for &v in &mesh.pins {
            self.pin(at(v));
        }
        range
    }

    /// Adds a hinge of `fabric`'s rigidity on every interior edge of the triangles from
    /// `first_triangle` on (one body's).
    fn add_hinges(&mut self, first_triangle: usize, fabric: &Fabric) {
        let hinges = isometric_hinges(
            &self.positions,
            &self.triangles[first_triangle..],
            fabric.bending,
            fabric.damping_time,
        );
        self.bending.extend(hinges);
    }
}
