//! Builders for the body types a scene can hold: cloth, chain, lattice and triangle mesh.
//!
//! Each builder appends its particles, springs and triangles to a [`Model`] and returns the range
//! of particle indices it used, so that several bodies share one model. Inputs are assumed valid
//! (the scene layer checks them); builders never panic on valid input.

use std::collections::HashMap;
use std::ops::Range;

use glam::DVec3;

use crate::solver::model::{Model, SpringGrid, SpringKind, SpringParams};

/// Whether a cloth starts flat in the x-z plane or hangs in the x-y plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Orientation {
    /// In the x-z plane: `i` along x, `j` along z.
    Horizontal,
    /// In the x-y plane: `i` along x, `j` downwards from the top row `j = 0`.
    Vertical,
}

/// A rectangular cloth: an `nx × ny` grid with structural, shear and bending springs.
#[derive(Clone, Debug)]
pub struct Cloth {
    /// Extent along `i` and `j`, in metres.
    pub size: [f64; 2],
    /// Particles along `i` and `j` (each at least 2).
    pub resolution: [usize; 2],
    /// The centre of the sheet.
    pub center: DVec3,
    /// Plane of the sheet.
    pub orientation: Orientation,
    /// Total mass, spread evenly over the particles, in kg.
    pub mass: f64,
    /// Initial velocity of every free particle.
    pub velocity: DVec3,
    /// Grid neighbours.
    pub structural: SpringParams,
    /// Cell diagonals.
    pub shear: SpringParams,
    /// Particles two apart along the grid.
    pub bending: SpringParams,
    /// Pinned particles as grid coordinates `[i, j]`.
    pub pins: Vec<[usize; 2]>,
}

impl Cloth {
    /// A square metre of cloth, `n × n` particles, 1 kg, held horizontal at rest and centred on
    /// `(0.5, 1, 0.5)`, every spring family with `springs`, nothing pinned: with k = 5000 N/m and
    /// damping 0.5 N·s/m, the hanging cloth the performance peers and the benches step. Change
    /// fields with struct update syntax: `Cloth { pins, ..Cloth::square_metre(n, springs) }`.
    pub fn square_metre(n: usize, springs: SpringParams) -> Self {
        Self {
            size: [1.0, 1.0],
            resolution: [n, n],
            center: DVec3::new(0.5, 1.0, 0.5),
            orientation: Orientation::Horizontal,
            mass: 1.0,
            velocity: DVec3::ZERO,
            structural: springs,
            shear: springs,
            bending: springs,
            pins: Vec::new(),
        }
    }
}

/// A chain: `count` particles evenly spaced from `start` to `end`, joined in sequence.
#[derive(Clone, Debug)]
pub struct Chain {
    /// Position of the first particle.
    pub start: DVec3,
    /// Position of the last particle.
    pub end: DVec3,
    /// Number of particles (at least 2; two make a single spring).
    pub count: usize,
    /// Total mass, spread evenly, in kg.
    pub mass: f64,
    /// Initial velocity of every free particle.
    pub velocity: DVec3,
    /// The links' stiffness and damping.
    pub spring: SpringParams,
    /// Rest length of every link; `None` takes the initial spacing.
    pub rest_length: Option<f64>,
    /// Pinned particle indices within the chain.
    pub pins: Vec<usize>,
}

/// A 3-D block of particles (a jelly): an `nx × ny × nz` lattice.
#[derive(Clone, Debug)]
pub struct Lattice {
    /// Extent along x, y and z, in metres.
    pub size: [f64; 3],
    /// Particles along x, y and z (each at least 2).
    pub resolution: [usize; 3],
    /// The centre of the block.
    pub center: DVec3,
    /// Total mass, spread evenly, in kg.
    pub mass: f64,
    /// Initial velocity of every free particle.
    pub velocity: DVec3,
    /// Axis neighbours.
    pub structural: SpringParams,
    /// Face and body diagonals.
    pub shear: SpringParams,
    /// Particles two apart along an axis.
    pub bending: SpringParams,
    /// Pinned particles as lattice coordinates `[i, j, k]`.
    pub pins: Vec<[usize; 3]>,
}

/// A triangle mesh: edges become structural springs, and the two far vertices of every pair of
/// triangles sharing an edge are joined by a bending spring.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// Vertex positions.
    pub vertices: Vec<DVec3>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[usize; 3]>,
    /// Total mass, spread over the vertices by the area of their triangles, in kg.
    pub mass: f64,
    /// Initial velocity of every free vertex.
    pub velocity: DVec3,
    /// Edge springs.
    pub structural: SpringParams,
    /// Springs across shared edges.
    pub bending: SpringParams,
    /// Pinned vertex indices.
    pub pins: Vec<usize>,
}

/// How a grid cloth's mass is spread over its particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ClothMass {
    /// This total, the same for every particle.
    Even(f64),
    /// This density, in kg/m², each particle carrying the area of its quarter cells.
    ByArea(f64),
}

/// Each spring family of a cloth as the pairs of grid offsets `[ai, aj, bi, bj]` it joins:
/// particle `(i + ai, j + aj)` to `(i + bi, j + bj)`.
pub(crate) const CLOTH_STENCIL: [(SpringKind, [[usize; 4]; 2]); 3] = [
    (SpringKind::Structural, [[0, 0, 1, 0], [0, 0, 0, 1]]),
    (SpringKind::Shear, [[0, 0, 1, 1], [1, 0, 0, 1]]),
    (SpringKind::Bending, [[0, 0, 2, 0], [0, 0, 0, 2]]),
];

/// The area a mesh assigns to each vertex: a third of each triangle it belongs to.
pub fn vertex_areas(vertices: &[DVec3], triangles: &[[usize; 3]]) -> Vec<f64> {
    let mut areas = vec![0.0; vertices.len()];
    for &[a, b, c] in triangles {
        let area = 0.5 * (vertices[b] - vertices[a]).cross(vertices[c] - vertices[a]).length();
        for v in [a, b, c] {
            areas[v] += area / 3.0;
        }
    }
    areas
}

impl Model {
    /// Adds a cloth; particle `(i, j)` gets index `offset + j * nx + i`.
    pub fn add_cloth(&mut self, cloth: &Cloth) -> Range<usize> {
        let families = CLOTH_STENCIL.iter().flat_map(|&(kind, offsets)| {
            let params = match kind {
                SpringKind::Structural => cloth.structural,
                SpringKind::Shear => cloth.shear,
                SpringKind::Bending => cloth.bending,
            };
            offsets.map(|offset| (kind, offset, params))
        });
        self.add_grid_cloth(cloth, ClothMass::Even(cloth.mass), &families.collect::<Vec<_>>())
    }

    /// Adds a cloth of mass `mass` whose springs are `families`, each a kind, its stencil
    /// offsets `[ai, aj, bi, bj]` and its parameters; the cloth's own spring parameters and mass
    /// are not read.
    pub(crate) fn add_grid_cloth(
        &mut self,
        cloth: &Cloth,
        mass: ClothMass,
        families: &[(SpringKind, [usize; 4], SpringParams)],
    ) -> Range<usize> {
        let [nx, ny] = cloth.resolution;
        let [sx, sy] = cloth.size;
        let (di, dj) = (sx / (nx - 1) as f64, sy / (ny - 1) as f64);
        let place = |i: usize, j: usize| {
            let u = -0.5 * sx + i as f64 * di;
            let w = -0.5 * sy + j as f64 * dj;
            cloth.center
                + match cloth.orientation {
                    Orientation::Horizontal => DVec3::new(u, 0.0, w),
                    Orientation::Vertical => DVec3::new(u, -w, 0.0),
                }
        };
        let positions = (0..ny).flat_map(|j| (0..nx).map(move |i| (i, j))).map(|(i, j)| place(i, j));
        let mass_of = |p: usize| match mass {
            ClothMass::Even(total) => total / (nx * ny) as f64,
            ClothMass::ByArea(density) => {
                // A particle carries the quarter of each grid cell it is a corner of.
                let edge = |k: usize, n: usize| if k == 0 || k == n - 1 { 0.5 } else { 1.0 };
                density * di * dj * edge(p % nx, nx) * edge(p / nx, ny)
            }
        };
        let range = self.add_particles(positions, mass_of, cloth.velocity);
        let at = |i: usize, j: usize| range.start + j * nx + i;

        let first_spring = self.springs.len();
        for &(kind, [ai, aj, bi, bj], params) in families {
            let (reach_i, reach_j) = (ai.max(bi), aj.max(bj));
            // One rest length per family, so that the stencil pass can share it: the grid is
            // affine, so every spring of a family has this length up to rounding.
            let rest = place(ai, aj).distance(place(bi, bj));
            for j in 0..ny.saturating_sub(reach_j) {
                for i in 0..nx.saturating_sub(reach_i) {
                    self.connect_with_rest(at(i + ai, j + aj), at(i + bi, j + bj), rest, params, kind);
                }
            }
        }
        self.grids.push(SpringGrid {
            first_particle: range.start,
            resolution: [nx, ny],
            stencil: families.iter().map(|&(_, offsets, _)| offsets).collect(),
            springs: first_spring..self.springs.len(),
        });
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let (p00, p10, p01, p11) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
                self.triangles.push([p00 as u32, p01 as u32, p10 as u32]);
                self.triangles.push([p10 as u32, p01 as u32, p11 as u32]);
            }
        }
        for &[i, j] in &cloth.pins {
            self.pin(at(i, j));
        }
        range
    }

    /// Adds a chain; its particles keep their order.
    pub fn add_chain(&mut self, chain: &Chain) -> Range<usize> {
        let n = chain.count;
        let positions = (0..n).map(|p| chain.start.lerp(chain.end, p as f64 / (n - 1) as f64));
        let per_particle = chain.mass / n as f64;
        let range = self.add_particles(positions, |_| per_particle, chain.velocity);
        for p in range.start..range.end - 1 {
            match chain.rest_length {
                Some(rest) => self.connect_with_rest(p, p + 1, rest, chain.spring, SpringKind::Structural),
                None => self.connect(p, p + 1, chain.spring, SpringKind::Structural),
            }
        }
        for &p in &chain.pins {
            self.pin(range.start + p);
        }
        range
    }

    /// Adds a lattice; particle `(i, j, k)` gets index `offset + (k * ny + j) * nx + i`.
    pub fn add_lattice(&mut self, lattice: &Lattice) -> Range<usize> {
        let [nx, ny, nz] = lattice.resolution;
        let size = DVec3::from_array(lattice.size);
        let spacing = size / DVec3::new((nx - 1) as f64, (ny - 1) as f64, (nz - 1) as f64);
        let origin = lattice.center - 0.5 * size;
        let positions = (0..nz).flat_map(|k| {
            (0..ny).flat_map(move |j| {
                (0..nx).map(move |i| origin + spacing * DVec3::new(i as f64, j as f64, k as f64))
            })
        });
        let per_particle = lattice.mass / (nx * ny * nz) as f64;
        let range = self.add_particles(positions, |_| per_particle, lattice.velocity);
        let at = |i: usize, j: usize, k: usize| range.start + (k * ny + j) * nx + i;
        let inside = |i: isize, j: isize, k: isize| {
            (0..nx as isize).contains(&i) && (0..ny as isize).contains(&j) && (0..nz as isize).contains(&k)
        };

        // Each offset is listed once (lexicographically positive), so each pair is joined once.
        let mut offsets: Vec<([isize; 3], SpringKind, SpringParams)> = Vec::new();
        for dk in -1..=1isize {
            for dj in -1..=1isize {
                for di in -1..=1isize {
                    let positive = (dk, dj, di) > (0, 0, 0);
                    if !positive {
                        continue;
                    }
                    let axes = [di, dj, dk].iter().filter(|d| **d != 0).count();
                    let (kind, params) = if axes == 1 {
                        (SpringKind::Structural, lattice.structural)
                    } else {
                        (SpringKind::Shear, lattice.shear)
                    };
                    offsets.push(([di, dj, dk], kind, params));
                }
            }
        }
        for axis in 0..3 {
            let mut d = [0isize; 3];
            d[axis] = 2;
            offsets.push((d, SpringKind::Bending, lattice.bending));
        }
        for ([di, dj, dk], kind, params) in offsets {
            for k in 0..nz {
                for j in 0..ny {
                    for i in 0..nx {
                        let (bi, bj, bk) = (i as isize + di, j as isize + dj, k as isize + dk);
                        if inside(bi, bj, bk) {
                            let b = at(bi as usize, bj as usize, bk as usize);
                            self.connect(at(i, j, k), b, params, kind);
                        }
                    }
                }
            }
        }
        self.add_lattice_surface(lattice.resolution, &at);
        for &[i, j, k] in &lattice.pins {
            self.pin(at(i, j, k));
        }
        range
    }

    /// Triangulates the six faces of a lattice, wound so that normals point outwards.
    fn add_lattice_surface(&mut self, [nx, ny, nz]: [usize; 3], at: &dyn Fn(usize, usize, usize) -> usize) {
        // For each face: the fixed axis, its value, and the two in-face axes ordered so that
        // (u × v) points outwards.
        let faces: [(usize, usize, usize, usize); 6] = [
            (0, 0, 2, 1),      // x = 0: z × y = -x
            (0, nx - 1, 1, 2), // x = max: y × z = +x
            (1, 0, 0, 2),      // y = 0: x × z = -y
            (1, ny - 1, 2, 0), // y = max: z × x = +y
            (2, 0, 1, 0),      // z = 0: y × x = -z
            (2, nz - 1, 0, 1), // z = max: x × y = +z
        ];
        let extent = [nx, ny, nz];
        for (fixed, value, u_axis, v_axis) in faces {
            let point = |u: usize, v: usize| {
                let mut c = [0usize; 3];
                c[fixed] = value;
                c[u_axis] = u;
                c[v_axis] = v;
                at(c[0], c[1], c[2]) as u32
            };
            for v in 0..extent[v_axis] - 1 {
                for u in 0..extent[u_axis] - 1 {
                    let (p00, p10, p01, p11) =
                        (point(u, v), point(u + 1, v), point(u, v + 1), point(u + 1, v + 1));
                    self.triangles.push([p00, p10, p11]);
                    self.triangles.push([p00, p11, p01]);
                }
            }
        }
    }

    /// Adds a triangle mesh; its vertices keep their order.
    pub fn add_mesh(&mut self, mesh: &Mesh) -> Range<usize> {
        let areas = vertex_areas(&mesh.vertices, &mesh.triangles);
        let total_area: f64 = areas.iter().sum();
        let range = self.add_particles(
            mesh.vertices.iter().copied(),
            |v| mesh.mass * areas[v] / total_area,
            mesh.velocity,
        );
        let at = |v: usize| range.start + v;

        // Each undirected edge, in first-seen order, with the far vertices of its triangles.
        let mut edges: Vec<((usize, usize), Vec<usize>)> = Vec::new();
        let mut edge_index: HashMap<(usize, usize), usize> = HashMap::new();
        for &[a, b, c] in &mesh.triangles {
            for (p, q, far) in [(a, b, c), (b, c, a), (c, a, b)] {
                let key = (p.min(q), p.max(q));
                let slot = *edge_index.entry(key).or_insert_with(|| {
                    edges.push((key, Vec::new()));
                    edges.len() - 1
                });
                edges[slot].1.push(far);
            }
            self.triangles.push([at(a) as u32, at(b) as u32, at(c) as u32]);
        }
        for ((p, q), _) in &edges {
            self.connect(at(*p), at(*q), mesh.structural, SpringKind::Structural);
        }
        for (_, far) in &edges {
            if let [f, g] = far[..]
                && f != g
            {
                self.connect(at(f), at(g), mesh.bending, SpringKind::Bending);
            }
        }
        for &v in &mesh.pins {
            self.pin(at(v));
        }
        range
    }
}
