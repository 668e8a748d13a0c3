//! Where a coarser cloth's particles lie on a finer one: for each particle of a scene at a
//! coarser resolution ([`Scene::coarsened`]), the particles and weights of the finer scene that
//! give the finer cloth at the same material point, so that the two can be compared there.
//!
//! A grid cloth's particle `(i, j)` of `n × m` is the material point `(i / (n - 1), j / (m - 1))`,
//! read on the finer grid bilinearly in the cell that holds it: for grids of `2^k + 1` that is
//! the shared particle itself, with weight 1. A disk's particle is its point in the unit disk's
//! layout ([`solver::disk_layout`]), read linearly in the finer layout's triangle that holds it.
//! Each disk's rings are turned by half their spacing, so no particle but the centre is shared,
//! and a particle on the coarser rim, on the circle, lies just outside the finer disk's
//! inscribed polygon: it is read by extending the triangle it is least outside of. Reading the
//! finer cloth at the coarser one's points, rather than the reverse, keeps the interpolation's
//! own error to the order of the finer spacing squared.

use glam::{DVec2, DVec3};

use super::types::{Body, ClothShape, ClothSpec, Scene};
use crate::solver;

/// For each particle of a coarser scene, the finer scene's particles and weights at its material
/// point (unused entries have weight 0).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialPoints {
    weights: Vec<[(u32, f64); 4]>,
    /// The coarser spacing over the finer, `H / h`, of the first body: exactly 2 for grids of
    /// `2^k + 1` particles and disks of an even number of rings (a rectangle's is the geometric
    /// mean of its two sides').
    pub spacing_ratio: f64,
}

impl MaterialPoints {
    /// The particles of `coarse` as points of `fine`, two scenes whose bodies are the same
    /// cloths at two resolutions.
    pub fn between(coarse: &Scene, fine: &Scene) -> Self {
        let mut weights = Vec::new();
        let mut offset = 0;
        let mut spacing_ratio = None;
        for (coarse, fine) in coarse.bodies.iter().zip(&fine.bodies) {
            if let (Body::Cloth(coarse), Body::Cloth(fine)) = (coarse, fine) {
                spacing_ratio.get_or_insert_with(|| ratio(coarse, fine));
                let shift = |w: [(usize, f64); 4]| w.map(|(p, weight)| ((offset + p) as u32, weight));
                match fine.shape {
                    ClothShape::Rectangle => weights.extend(grid_points(coarse, fine).into_iter().map(shift)),
                    ClothShape::Disk => weights.extend(disk_points(coarse, fine).into_iter().map(shift)),
                }
            }
            offset += fine.particle_count() as usize;
        }
        Self { weights, spacing_ratio: spacing_ratio.unwrap_or(1.0) }
    }

    /// The number of points: the coarser scene's particles.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// The finer scene's `positions` at each point.
    pub fn read<'a>(&'a self, positions: &'a [DVec3]) -> impl Iterator<Item = DVec3> + 'a {
        self.weights.iter().map(|w| w.iter().map(|&(p, weight)| weight * positions[p as usize]).sum())
    }
}

/// `H / h` of two resolutions of a cloth.
fn ratio(coarse: &ClothSpec, fine: &ClothSpec) -> f64 {
    let intervals = |n: usize| n.saturating_sub(1).max(1) as f64;
    match fine.shape {
        ClothShape::Rectangle => {
            let along = |axis: usize| intervals(fine.resolution[axis]) / intervals(coarse.resolution[axis]);
            (along(0) * along(1)).sqrt()
        }
        ClothShape::Disk => fine.disk_rings().max(1) as f64 / coarse.disk_rings().max(1) as f64,
    }
}

/// A rectangle's particles, row by row, bilinearly on the finer grid.
fn grid_points(coarse: &ClothSpec, fine: &ClothSpec) -> Vec<[(usize, f64); 4]> {
    let [n, m] = coarse.resolution;
    let [nx, ny] = fine.resolution;
    // The finer cell and the fraction across it of coarse index `c` of `count`, along a side of
    // `fine_count` particles. `c (fine_count - 1)` and the division are exact when the grids
    // share the point, so a shared particle gets weight exactly 1.
    let cell = |c: usize, count: usize, fine_count: usize| {
        let at = (c * (fine_count - 1)) as f64 / (count - 1) as f64;
        let lower = (at.floor() as usize).min(fine_count - 2);
        (lower, at - lower as f64)
    };
    let mut points = Vec::with_capacity(n * m);
    for j in 0..m {
        let (row, t) = cell(j, m, ny);
        for i in 0..n {
            let (column, s) = cell(i, n, nx);
            let index = |di: usize, dj: usize| (row + dj) * nx + column + di;
            points.push([
                (index(0, 0), (1.0 - s) * (1.0 - t)),
                (index(1, 0), s * (1.0 - t)),
                (index(0, 1), (1.0 - s) * t),
                (index(1, 1), s * t),
            ]);
        }
    }
    points
}

/// A disk's particles, each linearly in the finer layout's triangle that holds it.
fn disk_points(coarse: &ClothSpec, fine: &ClothSpec) -> Vec<[(usize, f64); 4]> {
    let (coarse_points, _) = solver::disk_layout(coarse.disk_rings());
    let rings = fine.disk_rings();
    let (points, triangles) = solver::disk_layout(rings);
    let point = |p: usize| DVec2::from_array(points[p]);
    coarse_points
        .iter()
        .map(|&x| {
            let x = DVec2::from_array(x);
            // The layout's triangles go ring by ring, 6 r² before the band between rings r and
            // r + 1; a band's chords lie inside its outer ring, so the point is in the band of its
            // radius or in one next to it.
            let band = (x.length() * rings as f64).floor() as usize;
            let first = band.saturating_sub(1);
            let last = (band + 1).min(rings - 1);
            let (triangle, coordinates) = (6 * first * first..6 * (last + 1) * (last + 1))
                .map(|t| {
                    let [a, b, c] = triangles[t];
                    (triangles[t], barycentric(x, [point(a), point(b), point(c)]))
                })
                .max_by(|(_, u), (_, v)| smallest(u).total_cmp(&smallest(v)))
                .expect("a disk has a triangle in every band");
            let [a, b, c] = triangle;
            [(a, coordinates[0]), (b, coordinates[1]), (c, coordinates[2]), (0, 0.0)]
        })
        .collect()
}

fn smallest(coordinates: &[f64; 3]) -> f64 {
    coordinates[0].min(coordinates[1]).min(coordinates[2])
}

/// The barycentric coordinates of `x` in the triangle `[a, b, c]` (a layout's triangles are
/// never degenerate).
fn barycentric(x: DVec2, [a, b, c]: [DVec2; 3]) -> [f64; 3] {
    let area = (b - a).perp_dot(c - a);
    let u = (b - x).perp_dot(c - x) / area;
    let v = (c - x).perp_dot(a - x) / area;
    [u, v, 1.0 - u - v]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ErrorEstimateName;

    fn scene(body: serde_json::Value) -> Scene {
        let json = serde_json::json!({"duration": 1, "error_estimate": "none", "bodies": [body]});
        Scene::from_json(json.to_string().as_bytes()).unwrap()
    }

    /// A smooth field on the material coordinates `(u, v)` of a body's particles.
    fn field(positions: &[DVec3]) -> Vec<DVec3> {
        positions.iter().map(|p| DVec3::new(p.x * p.z, (3.0 * p.x).sin(), p.z * p.z)).collect()
    }

    #[test]
    fn a_grid_of_two_to_the_k_plus_one_is_read_at_its_shared_particles_exactly() {
        let fine = scene(serde_json::json!({"type": "cloth", "resolution": [17, 9], "material": "cotton"}));
        let coarse = fine.coarsened().unwrap();
        assert_eq!(coarse.error_estimate, ErrorEstimateName::None);
        let points = MaterialPoints::between(&coarse, &fine);
        assert_eq!(points.len(), 9 * 5);
        let (fine_model, coarse_model) = (fine.compile().model, coarse.compile().model);
        let read: Vec<DVec3> = points.read(&fine_model.positions).collect();
        assert_eq!(read, coarse_model.positions, "shared particles are read bit for bit");
    }

    #[test]
    fn any_grid_is_read_to_the_order_of_the_finer_spacing_squared() {
        // A quadratic field read bilinearly: the error falls by 4 when both grids are refined.
        let error = |n: usize| {
            let fine =
                scene(serde_json::json!({"type": "cloth", "resolution": [n, n], "material": "cotton"}));
            let coarse = fine.coarsened().unwrap();
            let points = MaterialPoints::between(&coarse, &fine);
            let read: Vec<DVec3> = points.read(&field(&fine.compile().model.positions)).collect();
            let exact = field(&coarse.compile().model.positions);
            read.iter().zip(&exact).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max)
        };
        let (coarse, fine) = (error(20), error(40));
        assert!(coarse > 1e-4, "{coarse}");
        let order = (coarse / fine).log2();
        assert!((1.8..2.2).contains(&order), "order {order}: {coarse} then {fine}");
    }

    #[test]
    fn a_disk_is_read_in_the_finer_triangles_to_the_order_of_the_spacing_squared() {
        // The centre is shared exactly; elsewhere the smooth field is read with an error that
        // falls by about 4 when the rings double. The rim's points, outside the finer polygon,
        // are read by extension.
        let error = |n: usize| {
            let fine = scene(serde_json::json!({"type": "cloth", "shape": "disk", "resolution": [n, n],
                "material": "cotton"}));
            let coarse = fine.coarsened().unwrap();
            let points = MaterialPoints::between(&coarse, &fine);
            assert_eq!(points.len(), coarse.bodies[0].particle_count() as usize);
            let read: Vec<DVec3> = points.read(&field(&fine.compile().model.positions)).collect();
            let exact = field(&coarse.compile().model.positions);
            assert_eq!(read[0], exact[0]);
            read.iter().zip(&exact).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max)
        };
        let (coarse, fine) = (error(16), error(32));
        assert!(coarse > 1e-5, "{coarse}");
        let order = (coarse / fine).log2();
        assert!((1.6..2.4).contains(&order), "order {order}: {coarse} then {fine}");
    }
}
