//! What the mesh formats need about each body's surface: its triangles re-based to the body's
//! own vertices, one frame's values for the body, and vertex normals when the run recorded none.

use crate::run::{Recording, Samples};
use crate::scene::BodyInfo;

/// The triangles of `body`, indexing its own vertices from 0 (`Recording::triangles` index the
/// global particle array).
pub(super) fn body_triangles(recording: &Recording, body: &BodyInfo) -> Vec<[u32; 3]> {
    let range = body.offset..body.offset + body.count;
    let offset = body.offset as u32;
    recording
        .triangles
        .iter()
        .filter(|t| range.contains(&(t[0] as usize)))
        .map(|t| t.map(|i| i - offset))
        .collect()
}

/// The scalars of `body` in `frame`: its slice of the flat frames × particles × 3 samples.
pub(super) fn body_range(particles: usize, frame: usize, body: &BodyInfo) -> std::ops::Range<usize> {
    let start = 3 * (frame * particles + body.offset);
    start..start + 3 * body.count
}

/// The vectors of `body` in `frame`, widened to `f64` (exact).
pub(super) fn body_vectors(
    samples: &Samples,
    particles: usize,
    frame: usize,
    body: &BodyInfo,
) -> Vec<[f64; 3]> {
    let range = body_range(particles, frame, body);
    let widened: Vec<f64> = match samples {
        Samples::F32(v) => v[range].iter().map(|&x| f64::from(x)).collect(),
        Samples::F64(v) => v[range].to_vec(),
    };
    widened.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// Area-weighted unit vertex normals of a surface: the normalised sum of the cross products of
/// the triangles around each vertex. A vertex on no triangle, or whose triangles cancel, gets
/// the zero vector rather than a NaN.
pub(super) fn vertex_normals(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0; 3]; positions.len()];
    for triangle in triangles {
        let [a, b, c] = triangle.map(|i| positions[i as usize]);
        let (u, v) = (sub(b, a), sub(c, a));
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        for &i in triangle {
            let sum = &mut normals[i as usize];
            sum.iter_mut().zip(n).for_each(|(s, n)| *s += n);
        }
    }
    for n in &mut normals {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        *n = if length > 0.0 && length.is_finite() { n.map(|x| x / length) } else { [0.0; 3] };
    }
    normals
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_weigh_by_area_and_leave_lone_vertices_zero() {
        // A unit square in the x-z plane facing +y, a sliver tilted towards +x sharing vertex 2,
        // and a vertex on no triangle.
        let positions = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [5.0, 5.0, 5.0]];
        let normals = vertex_normals(&positions, &[[0, 1, 2], [2, 1, 3]]);
        for n in &normals[..4] {
            assert_eq!(*n, [0.0, 1.0, 0.0]);
        }
        assert_eq!(normals[4], [0.0; 3]);
        // Two triangles of areas 1/2 and 1/8 meeting at vertex 0, facing +y and +x: the sum is
        // (1/4, 1, 0), normalised.
        let positions = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]];
        let normals = vertex_normals(&positions, &[[0, 1, 2], [0, 3, 4]]);
        let length = (1.0f64 + 1.0 / 16.0).sqrt();
        assert_eq!(normals[0], [0.25 / length, 1.0 / length, 0.0]);
    }
}
