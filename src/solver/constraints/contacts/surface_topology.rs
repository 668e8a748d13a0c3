//! What a mesh collider learns once from its triangles: which triangles have a surface, whether
//! the mesh is closed, which way is out, and the pseudo-normals that tell inside from outside.
//!
//! Vertices at the same position are one vertex (files often split them along seams). A
//! triangle of zero area has no surface and is left out. The mesh is **closed** when every edge
//! of the remaining triangles is shared by exactly two of them, traversed once in each direction
//! (a consistently oriented, watertight surface); a closed mesh wound inwards (negative signed
//! volume) is turned outwards. Any other mesh is an open, two-sided sheet.
//!
//! For a closed mesh, the side of a point is the sign of `(p - q) · n`, where `q` is the point of
//! the surface nearest to `p` and `n` the angle-weighted pseudo-normal of the feature `q` lies on:
//! the face's normal, the sum of the two face normals at an edge, or the sum of the face normals
//! at a vertex weighted by the faces' angles there (Bærentzen and Aanæs, *Signed distance
//! computation using the angle weighted pseudonormal*, IEEE TVCG 11(3), 2005), which is exact
//! for any closed, oriented surface.

use std::collections::HashMap;

use glam::DVec3;

use crate::solver::constraints::contacts::TriangleSurface;

/// The triangles that have a surface, with their outward normals, and the pseudo-normals of a
/// closed mesh.
pub(super) struct Topology {
    /// Corners of each triangle kept, in the order given.
    pub corners: Vec<[DVec3; 3]>,
    /// Unit normals, outward for a closed mesh.
    pub normals: Vec<DVec3>,
    /// For a closed mesh, per triangle: the pseudo-normals of its edges (edge `k` from corner
    /// `k` to corner `k + 1`) and of its corners.
    pub pseudo_normals: Option<Vec<[[DVec3; 3]; 2]>>,
}

impl Topology {
    pub fn of(surface: &TriangleSurface) -> Self {
        let mut welded: HashMap<[u64; 3], u32> = HashMap::with_capacity(surface.vertices.len());
        // `+ 0.0` makes -0.0 and 0.0 the same position.
        let key = |p: DVec3| [(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits(), (p.z + 0.0).to_bits()];
        let canonical: Vec<u32> = surface
            .vertices
            .iter()
            .enumerate()
            .map(|(i, &p)| *welded.entry(key(p)).or_insert(i as u32))
            .collect();
        let mut triangles = Vec::with_capacity(surface.triangles.len());
        let mut corners = Vec::with_capacity(surface.triangles.len());
        let mut normals = Vec::with_capacity(surface.triangles.len());
        for tri in &surface.triangles {
            let [a, b, c] = tri.map(|i| surface.vertices[i as usize]);
            let Some(normal) = (b - a).cross(c - a).try_normalize() else { continue };
            triangles.push(tri.map(|i| canonical[i as usize]));
            corners.push([a, b, c]);
            normals.push(normal);
        }
        let mut topology = Self { corners, normals, pseudo_normals: None };
        if let Some(neighbours) = closed_neighbours(&triangles) {
            topology.close(&triangles, &neighbours);
        }
        topology
    }

    /// Orients a closed mesh outwards and computes its pseudo-normals.
    fn close(&mut self, triangles: &[[u32; 3]], neighbours: &[[u32; 3]]) {
        let volume: f64 = self.corners.iter().map(|[a, b, c]| a.dot(b.cross(*c))).sum();
        if volume < 0.0 {
            self.normals.iter_mut().for_each(|n| *n = -*n);
        }
        let vertices = triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
        let mut at_vertex = vec![DVec3::ZERO; vertices];
        for (t, tri) in triangles.iter().enumerate() {
            let corners = self.corners[t];
            for k in 0..3 {
                let (before, after) = (corners[(k + 2) % 3] - corners[k], corners[(k + 1) % 3] - corners[k]);
                at_vertex[tri[k] as usize] += self.normals[t] * before.angle_between(after);
            }
        }
        let pseudo = triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                let edges =
                    std::array::from_fn(|k| self.normals[t] + self.normals[neighbours[t][k] as usize]);
                [edges, tri.map(|v| at_vertex[v as usize])]
            })
            .collect();
        self.pseudo_normals = Some(pseudo);
    }
}

/// For a closed mesh, the triangle across each edge of each triangle; `None` when some edge is
/// not shared by exactly two triangles traversing it in opposite directions.
fn closed_neighbours(triangles: &[[u32; 3]]) -> Option<Vec<[u32; 3]>> {
    if triangles.is_empty() {
        return None;
    }
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            if directed.insert((tri[k], tri[(k + 1) % 3]), t as u32).is_some() {
                return None;
            }
        }
    }
    triangles
        .iter()
        .map(|tri| {
            let across = |k: usize| directed.get(&(tri[(k + 1) % 3], tri[k])).copied();
            Some([across(0)?, across(1)?, across(2)?])
        })
        .collect()
}
