//! Vertex normals of a triangle surface, area-weighted.

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;

/// Writes the unit normal of every vertex: the normalised sum of the cross products of the
/// triangles around it (so larger triangles weigh more). A vertex on no triangle, or whose
/// triangles cancel or collapse, gets the zero vector rather than a NaN.
pub fn vertex_normals<T: Real>(triangles: &[[u32; 3]], x: &Vectors<T>, normals: &mut [Vec3<T>]) {
    normals.fill(Vec3::ZERO);
    for &[a, b, c] in triangles {
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let xa = x.get(a);
        let n = (x.get(b) - xa).cross(x.get(c) - xa);
        normals[a] += n;
        normals[b] += n;
        normals[c] += n;
    }
    for n in normals.iter_mut() {
        let l2 = n.length_squared();
        *n = if l2 > T::ZERO && l2.is_finite() { *n * (T::ONE / l2.sqrt()) } else { Vec3::ZERO };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_square_faces_up_and_lone_vertex_gets_zero() {
        let x: Vectors<f64> = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(5.0, 5.0, 5.0),
        ]
        .into_iter()
        .collect();
        let triangles = [[0, 1, 2], [2, 1, 3]];
        let mut normals = [Vec3::ZERO; 5];
        vertex_normals(&triangles, &x, &mut normals);
        for n in &normals[..4] {
            assert_eq!(*n, Vec3::new(0.0f64, 1.0, 0.0));
        }
        assert_eq!(normals[4], Vec3::ZERO);
    }
}
