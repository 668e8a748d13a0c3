//! Colliders as closed triangle meshes, for the formats that draw them: a sphere as a UV
//! sphere, a box as six faces with their own normals, a cylinder as its side and two caps, a
//! plane as a square of a given half-size centred on its point, and a mesh as it is. Triangles
//! wind counter-clockwise seen from outside, and every normal is unit.

use std::f64::consts::PI;

use super::surface::vertex_normals;
use crate::run::ColliderShape;

/// Segments around a sphere or cylinder.
const SEGMENTS: u32 = 48;
/// Rings from pole to pole of a sphere.
const RINGS: u32 = 24;

/// A surface to draw: positions, unit normals (zero where a mesh vertex has no surface) and
/// triangles.
#[derive(Debug, Default)]
pub(super) struct Tessellation {
    pub positions: Vec<[f64; 3]>,
    pub normals: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

impl Tessellation {
    fn vertex(&mut self, position: [f64; 3], normal: [f64; 3]) -> u32 {
        self.positions.push(position);
        self.normals.push(normal);
        (self.positions.len() - 1) as u32
    }
}

/// `shape` as triangles; a plane is a square reaching `plane_half_size` from its point along
/// each of its two axes.
pub(super) fn tessellate(shape: &ColliderShape, plane_half_size: f64) -> Tessellation {
    match shape {
        ColliderShape::Plane { point, normal } => plane(*point, *normal, plane_half_size),
        ColliderShape::Sphere { center, radius } => sphere(*center, *radius),
        ColliderShape::Box { center, half_extents } => cuboid(*center, *half_extents),
        ColliderShape::Cylinder { center, radius, height } => cylinder(*center, *radius, *height),
        ColliderShape::Mesh { vertices, triangles } => {
            let positions: Vec<[f64; 3]> = vertices.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect();
            let normals = vertex_normals(&positions, triangles);
            Tessellation { positions, normals, triangles: triangles.clone() }
        }
    }
}

fn plane(point: [f64; 3], normal: [f64; 3], half: f64) -> Tessellation {
    let length = dot(normal, normal).sqrt();
    // The scene refuses a zero normal; a result read back could still hold one.
    let n = if length > 0.0 && length.is_finite() { normal.map(|x| x / length) } else { [0.0, 1.0, 0.0] };
    // The axis least along n is never parallel to it, so the cross product is not zero.
    let least = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
    let mut axis = [0.0; 3];
    axis[least] = 1.0;
    let u = unit(cross(n, axis));
    let v = cross(n, u);
    let mut t = Tessellation::default();
    for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        t.vertex([0, 1, 2].map(|k| point[k] + half * (a * u[k] + b * v[k])), n);
    }
    // u × v = n, so the square's corners in order wind counter-clockwise seen from n.
    t.triangles = vec![[0, 1, 2], [0, 2, 3]];
    t
}

fn sphere(center: [f64; 3], radius: f64) -> Tessellation {
    let mut t = Tessellation::default();
    let columns = SEGMENTS + 1;
    for ring in 0..=RINGS {
        let theta = PI * f64::from(ring) / f64::from(RINGS);
        for segment in 0..=SEGMENTS {
            let phi = 2.0 * PI * f64::from(segment) / f64::from(SEGMENTS);
            let d = [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()];
            t.vertex([0, 1, 2].map(|k| center[k] + radius * d[k]), d);
        }
    }
    let at = |ring: u32, segment: u32| ring * columns + segment;
    for ring in 0..RINGS {
        for s in 0..SEGMENTS {
            // The rings at the poles are single points: one triangle per segment there.
            if ring > 0 {
                t.triangles.push([at(ring, s), at(ring, s + 1), at(ring + 1, s)]);
            }
            if ring + 1 < RINGS {
                t.triangles.push([at(ring, s + 1), at(ring + 1, s + 1), at(ring + 1, s)]);
            }
        }
    }
    t
}

fn cuboid(center: [f64; 3], half: [f64; 3]) -> Tessellation {
    let mut t = Tessellation::default();
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let (mut u, mut v) = ((axis + 1) % 3, (axis + 2) % 3);
            if sign < 0.0 {
                // Keeps u × v along the face's outward normal.
                std::mem::swap(&mut u, &mut v);
            }
            let mut normal = [0.0; 3];
            normal[axis] = sign;
            let first = t.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = center;
                p[axis] += sign * half[axis];
                p[u] += a * half[u];
                p[v] += b * half[v];
                t.vertex(p, normal);
            }
            t.triangles.push([first, first + 1, first + 2]);
            t.triangles.push([first, first + 2, first + 3]);
        }
    }
    t
}

fn cylinder(center: [f64; 3], radius: f64, height: f64) -> Tessellation {
    let mut t = Tessellation::default();
    let (bottom, top) = (center[1] - 0.5 * height, center[1] + 0.5 * height);
    let around = |s: u32| {
        let phi = 2.0 * PI * f64::from(s) / f64::from(SEGMENTS);
        [phi.cos(), 0.0, phi.sin()]
    };
    let at = |d: [f64; 3], y: f64| [center[0] + radius * d[0], y, center[2] + radius * d[2]];
    let side = t.positions.len() as u32;
    for s in 0..=SEGMENTS {
        let d = around(s);
        t.vertex(at(d, bottom), d);
        t.vertex(at(d, top), d);
    }
    for s in 0..SEGMENTS {
        let (b, tp, b1, t1) = (side + 2 * s, side + 2 * s + 1, side + 2 * s + 2, side + 2 * s + 3);
        t.triangles.push([b, tp, b1]);
        t.triangles.push([b1, tp, t1]);
    }
    for (y, up) in [(top, 1.0), (bottom, -1.0)] {
        let normal = [0.0, up, 0.0];
        let middle = t.vertex([center[0], y, center[2]], normal);
        for s in 0..SEGMENTS {
            t.vertex(at(around(s), y), normal);
        }
        for s in 0..SEGMENTS {
            let (k, k1) = (middle + 1 + s, middle + 1 + (s + 1) % SEGMENTS);
            t.triangles.push(if up > 0.0 { [middle, k1, k] } else { [middle, k, k1] });
        }
    }
    t
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// `a` scaled to unit length; only called on vectors that are not zero.
fn unit(a: [f64; 3]) -> [f64; 3] {
    let length = dot(a, a).sqrt();
    a.map(|x| x / length)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle faces away from `inside`, and every normal is unit: the mesh is drawn
    /// from outside.
    fn faces_outward(t: &Tessellation, inside: [f64; 3]) {
        for n in &t.normals {
            assert!((dot(*n, *n).sqrt() - 1.0).abs() < 1e-12, "normal {n:?}");
        }
        for tri in &t.triangles {
            let [a, b, c] = tri.map(|i| t.positions[i as usize]);
            let sub = |p: [f64; 3], q: [f64; 3]| [0, 1, 2].map(|k| p[k] - q[k]);
            let face = cross(sub(b, a), sub(c, a));
            assert!(dot(face, face) > 0.0, "degenerate triangle {tri:?}");
            let centroid = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
            assert!(dot(face, sub(centroid, inside)) > 0.0, "triangle {tri:?} faces inward");
        }
    }

    #[test]
    fn closed_shapes_wind_outward_with_unit_normals() {
        let center = [0.5, 1.0, -2.0];
        faces_outward(&sphere(center, 0.3), center);
        faces_outward(&cuboid(center, [0.1, 0.2, 0.3]), center);
        faces_outward(&cylinder(center, 0.4, 0.1), center);
    }

    #[test]
    fn sphere_vertices_lie_on_it_and_reach_its_poles() {
        let t = sphere([1.0, 2.0, 3.0], 0.25);
        for p in &t.positions {
            let r = dot([p[0] - 1.0, p[1] - 2.0, p[2] - 3.0], [p[0] - 1.0, p[1] - 2.0, p[2] - 3.0]).sqrt();
            assert!((r - 0.25).abs() < 1e-14, "{p:?} at {r}");
        }
        let heights: Vec<f64> = t.positions.iter().map(|p| p[1]).collect();
        assert_eq!(heights.iter().copied().fold(f64::INFINITY, f64::min), 1.75);
        assert_eq!(heights.iter().copied().fold(f64::NEG_INFINITY, f64::max), 2.25);
    }

    #[test]
    fn a_plane_is_a_square_in_it_facing_its_normal() {
        let (point, normal) = ([0.0, 1.0, 0.0], [0.0, 0.0, 2.0]);
        let t = plane(point, normal, 5.0);
        for (p, n) in t.positions.iter().zip(&t.normals) {
            assert_eq!(p[2], 0.0);
            assert_eq!(*n, [0.0, 0.0, 1.0]);
            assert_eq!(p[0].abs().max((p[1] - 1.0).abs()), 5.0);
        }
        faces_outward(&t, [0.0, 1.0, -1.0]);
    }
}
