//! A round cloth: a disk triangulated in concentric rings, built as a triangle mesh.
//!
//! Ring `r` (for `r` from 1 to `rings`) lies at radius `r · h`, `h = radius / rings`, and holds
//! `6r` particles evenly spaced, the first half a spacing past angle 0 (`π / 6r`); ring 0 is the
//! centre. Each ring's spacing is then `2πr·h / 6r ≈ 1.05 h`, so every triangle is close to
//! equilateral at every radius, and the outer ring lies on the circle: the outline is a regular
//! `6·rings`-gon inscribed in it. The half-spacing turn keeps particles of neighbouring rings off
//! a common ray, where they would make triangles of 30° and 120°; with it every angle lies
//! between 42° and 91° at any resolution. Two
//! neighbouring rings (`6r` and `6r + 6` particles) are stitched by walking both in angle and
//! always advancing the ring whose next particle comes first, which gives `12r + 6` triangles
//! between them and `6 rings²` in all. A square grid clipped to the circle would need its
//! boundary snapped, which leaves slivers where the circle passes close to a grid point; the
//! rings have none.
//!
//! The disk is then an ordinary [`Mesh`]: its edges are structural springs, the far vertices of
//! every two triangles sharing an edge a bending spring, mass is spread by area, and it runs
//! through the spring-list path. A net of triangles resists shear with its edge springs (a
//! square of springs does not, which is why a rectangular cloth needs its diagonal family), so
//! a disk has no separate shear family.

use std::f64::consts::TAU;
use std::ops::Range;

use glam::DVec3;

use crate::solver::bodies::{Mesh, Orientation};
use crate::solver::model::{Model, SpringParams};

/// A horizontal or vertical disk of cloth.
#[derive(Clone, Debug)]
pub struct Disk {
    /// Diameter, in metres.
    pub diameter: f64,
    /// Rings around the centre particle (at least 1).
    pub rings: usize,
    /// The centre of the disk.
    pub center: DVec3,
    /// Plane of the disk: horizontal is the x-z plane (front +y), vertical the x-y plane (front
    /// +z).
    pub orientation: Orientation,
    /// Total mass, spread by area, in kg.
    pub mass: f64,
    /// Initial velocity of every free particle.
    pub velocity: DVec3,
    /// Edge springs.
    pub structural: SpringParams,
    /// Springs across shared edges.
    pub bending: SpringParams,
    /// Pinned particles as `[ring, k]`: the `k`-th particle of ring `ring` ([`disk_index`]).
    pub pins: Vec<[usize; 2]>,
}

/// The particles of a disk of `rings` rings: `1 + 3 rings (rings + 1)`.
pub fn disk_particle_count(rings: usize) -> usize {
    1 + 3 * rings * (rings + 1)
}

/// The particles in ring `ring`: 1 at the centre, `6 ring` beyond.
pub fn disk_ring_size(ring: usize) -> usize {
    if ring == 0 { 1 } else { 6 * ring }
}

/// The index within its disk of particle `k` of ring `ring` (`k < disk_ring_size(ring)`): rings
/// are numbered outwards, and a ring's particles counter-clockwise seen from the front, from the
/// one just past the +x axis.
pub fn disk_index(ring: usize, k: usize) -> usize {
    if ring == 0 { 0 } else { 1 + 3 * ring * (ring - 1) + k }
}

/// The unit disk's layout: points `(u, v)` with the outer ring on the unit circle, and
/// triangles counter-clockwise in `(u, v)`.
pub fn disk_layout(rings: usize) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let mut points = Vec::with_capacity(disk_particle_count(rings));
    points.push([0.0, 0.0]);
    for ring in 1..=rings {
        let n = disk_ring_size(ring);
        let radius = ring as f64 / rings as f64;
        points.extend((0..n).map(|k| {
            let angle = TAU * (k as f64 + 0.5) / n as f64;
            [radius * angle.cos(), radius * angle.sin()]
        }));
    }
    let mut triangles = Vec::with_capacity(6 * rings * rings);
    for ring in 0..rings {
        let (inner, outer) = (disk_ring_size(ring), disk_ring_size(ring + 1));
        let at_inner = |k: usize| disk_index(ring, k % inner);
        let at_outer = |k: usize| disk_index(ring + 1, k % outer);
        let (mut a, mut b) = (0, 0);
        // Each triangle advances one ring by one particle; the next particle in angle goes
        // first (angles (a + 1.5)/inner against (b + 1.5)/outer, compared in integers). The
        // centre "ring" has one particle and never advances.
        while b < outer || (ring > 0 && a < inner) {
            let advance_inner = ring > 0 && (b == outer || (2 * a + 3) * outer < (2 * b + 3) * inner);
            if advance_inner {
                triangles.push([at_inner(a), at_outer(b), at_inner(a + 1)]);
                a += 1;
            } else {
                triangles.push([at_inner(a), at_outer(b), at_outer(b + 1)]);
                b += 1;
            }
        }
    }
    (points, triangles)
}

impl Disk {
    /// The disk as the triangle mesh it is built as, its vertices numbered as [`disk_index`]
    /// says; any builder of meshes builds it.
    pub fn mesh(&self) -> Mesh {
        let disk = self;
        let (points, triangles) = disk_layout(disk.rings);
        let radius = 0.5 * disk.diameter;
        let vertices = points
            .iter()
            .map(|&[u, v]| {
                let (u, v) = (radius * u, radius * v);
                disk.center
                    + match disk.orientation {
                        // (u, v) → (x, -z) keeps counter-clockwise triangles facing +y.
                        Orientation::Horizontal => DVec3::new(u, 0.0, -v),
                        Orientation::Vertical => DVec3::new(u, v, 0.0),
                    }
            })
            .collect();
        Mesh {
            vertices,
            triangles,
            mass: disk.mass,
            velocity: disk.velocity,
            structural: disk.structural,
            bending: disk.bending,
            pins: disk.pins.iter().map(|&[ring, k]| disk_index(ring, k)).collect(),
        }
    }
}

impl Model {
    /// Adds a disk; its particles are numbered as [`disk_index`] says.
    pub fn add_disk(&mut self, disk: &Disk) -> Range<usize> {
        self.add_mesh(&disk.mesh())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::model::SpringKind;

    fn disk(rings: usize) -> Disk {
        let springs = SpringParams { stiffness: 100.0, damping: 0.0 };
        Disk {
            diameter: 0.3,
            rings,
            center: DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Horizontal,
            mass: 0.2,
            velocity: DVec3::ZERO,
            structural: springs,
            bending: springs,
            pins: Vec::new(),
        }
    }

    fn triangle_area(model: &Model, [a, b, c]: [u32; 3]) -> DVec3 {
        let p = |i: u32| model.positions[i as usize];
        0.5 * (p(b) - p(a)).cross(p(c) - p(a))
    }

    /// Counts from Euler's formula for a triangulated disk: `F = 6R²` triangles, `V = 1 + 3R(R+1)`
    /// vertices, so `E = V + F - 1 = 9R² + 3R` edges, `6R` of them on the boundary, and a bending
    /// spring across each of the `9R² - 3R` interior ones.
    #[test]
    fn has_the_counts_of_a_triangulated_disk() {
        for rings in [1, 2, 5, 12] {
            let mut model = Model::default();
            model.add_disk(&disk(rings));
            let r = rings;
            assert_eq!(model.particle_count(), 1 + 3 * r * (r + 1));
            assert_eq!(model.triangles.len(), 6 * r * r);
            let count = |kind| model.springs.iter().filter(|s| s.kind == kind).count();
            assert_eq!(count(SpringKind::Structural), 9 * r * r + 3 * r);
            assert_eq!(count(SpringKind::Bending), 9 * r * r - 3 * r);
            assert_eq!(count(SpringKind::Shear), 0);
        }
    }

    /// The triangles tile the inscribed `6R`-gon exactly once, all facing +y: their signed areas
    /// sum to the polygon's area `3R sin(2π/6R) ρ²`, and none is flipped.
    #[test]
    fn tiles_the_inscribed_polygon_facing_up() {
        for rings in [1, 3, 8, 20] {
            let mut model = Model::default();
            model.add_disk(&disk(rings));
            let areas: Vec<DVec3> = model.triangles.iter().map(|&t| triangle_area(&model, t)).collect();
            assert!(areas.iter().all(|a| a.y > 0.0 && a.x.abs() < 1e-15 && a.z.abs() < 1e-15));
            let sum: f64 = areas.iter().map(|a| a.y).sum();
            let sides = 6 * rings;
            let polygon = 0.5 * sides as f64 * 0.15f64.powi(2) * (TAU / sides as f64).sin();
            assert!((sum - polygon).abs() < 1e-14, "{sum} against {polygon}");
            let mass: f64 = model.masses.iter().sum();
            assert!((mass - 0.2).abs() < 1e-15);
        }
    }

    /// Near-uniform triangles: every angle of every triangle lies within [42°, 91°] at every
    /// resolution (an equilateral triangle has 60°), and the edges within a factor 1.5 of each
    /// other across the whole disk.
    #[test]
    fn triangles_are_well_shaped() {
        for rings in [1, 2, 4, 10, 40] {
            let mut model = Model::default();
            model.add_disk(&disk(rings));
            let p = |i: u32| model.positions[i as usize];
            let (mut smallest, mut largest) = (180.0f64, 0.0f64);
            let (mut shortest, mut longest) = (f64::MAX, 0.0f64);
            for &[a, b, c] in &model.triangles {
                for (o, q, r) in [(a, b, c), (b, c, a), (c, a, b)] {
                    let angle = (p(q) - p(o)).angle_between(p(r) - p(o)).to_degrees();
                    smallest = smallest.min(angle);
                    largest = largest.max(angle);
                    let edge = p(q).distance(p(o));
                    shortest = shortest.min(edge);
                    longest = longest.max(edge);
                }
            }
            assert!(smallest > 42.0 && largest < 91.0, "{rings} rings: angles {smallest}..{largest}");
            assert!(longest / shortest < 1.5, "{rings} rings: edges {shortest}..{longest}");
        }
    }

    #[test]
    fn numbers_rings_outwards_and_pins_by_ring() {
        let mut model = Model::default();
        let range = model.add_disk(&Disk { pins: vec![[0, 0], [3, 17]], ..disk(3) });
        assert_eq!(range, 0..37);
        let radius = |i: usize| (model.positions[i] - DVec3::new(0.0, 1.0, 0.0)).length();
        assert!((radius(disk_index(3, 0)) - 0.15).abs() < 1e-15);
        assert!((radius(disk_index(2, 11)) - 0.10).abs() < 1e-15);
        assert_eq!(disk_index(3, 17), 36);
        let pinned: Vec<usize> = (0..37).filter(|&i| model.pinned[i]).collect();
        assert_eq!(pinned, [0, 36]);
    }
}
