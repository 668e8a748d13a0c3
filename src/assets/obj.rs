//! The Wavefront OBJ reader: `v` and `f` statements, everything else ignored.
//!
//! A face's corners may be written `v`, `v/vt`, `v//vn` or `v/vt/vn`; only the vertex index is
//! used. Indices are 1-based, or negative to count back from the last vertex defined so far; a
//! face may use only vertices defined above it. A face of more than three corners is split into
//! a fan of triangles around its first corner. Coordinates must be finite and within ±1e6 (the
//! scene's range for coordinates); a fourth (`w`) value of a vertex is ignored.

use thiserror::Error;

use super::mesh::{Mesh, MeshLimits};

/// A bad OBJ file: the 1-based line and what is wrong there.
#[derive(Debug, Error, PartialEq, Eq)]
#[error("OBJ line {line}: {reason}")]
pub struct ObjError {
    /// 1-based line number (0 for the file as a whole).
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

/// The largest magnitude of a coordinate, as in the scene contract.
const MAX_COORDINATE: f64 = 1e6;

/// Reads the triangles of an OBJ file within `limits`.
pub fn read_obj(bytes: &[u8], limits: MeshLimits) -> Result<Mesh, ObjError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        ObjError { line, reason: "the text is not UTF-8".into() }
    })?;
    let mut vertices: Vec<f64> = Vec::new();
    let mut triangles: Vec<u32> = Vec::new();
    let mut corners: Vec<u32> = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let line_number = number + 1;
        let fail = |reason: String| ObjError { line: line_number, reason };
        let statement = line.split('#').next().unwrap_or("");
        let mut words = statement.split_whitespace();
        match words.next() {
            Some("v") => {
                if (vertices.len() / 3) as u64 >= limits.max_vertices {
                    return Err(fail(format!(
                        "more than {} vertices, the most this server takes (--max-particles)",
                        limits.max_vertices
                    )));
                }
                for axis in ["x", "y", "z"] {
                    let word = words
                        .next()
                        .ok_or_else(|| fail(format!("a vertex needs x, y and z; {axis} is missing")))?;
                    let value: f64 =
                        word.parse().map_err(|_| fail(format!("vertex {axis} `{word}` is not a number")))?;
                    if !value.is_finite() || value.abs() > MAX_COORDINATE {
                        return Err(fail(format!("vertex {axis} {word} is not finite within ±1e6")));
                    }
                    vertices.push(value);
                }
            }
            Some("f") => {
                corners.clear();
                let defined = vertices.len() / 3;
                for word in words {
                    corners.push(corner(word, defined).map_err(fail)?);
                }
                if corners.len() < 3 {
                    return Err(fail(format!("a face needs at least 3 corners; it has {}", corners.len())));
                }
                let new_triangles = (corners.len() - 2) as u64;
                if (triangles.len() / 3) as u64 + new_triangles > limits.max_triangles {
                    return Err(fail(format!(
                        "more than {} triangles, the most this server takes (--max-asset-triangles)",
                        limits.max_triangles
                    )));
                }
                for k in 1..corners.len() - 1 {
                    let triangle = [corners[0], corners[k], corners[k + 1]];
                    if triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]
                    {
                        return Err(fail(format!(
                            "the face repeats a vertex (triangle of vertices {}, {}, {})",
                            triangle[0] + 1,
                            triangle[1] + 1,
                            triangle[2] + 1
                        )));
                    }
                    triangles.extend_from_slice(&triangle);
                }
            }
            _ => {}
        }
    }
    if triangles.is_empty() {
        return Err(ObjError { line: 0, reason: "the file has no faces (`f` lines)".into() });
    }
    Ok(Mesh { vertices, triangles }.without_unused_vertices())
}

/// The 0-based vertex of a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`, with `defined`
/// vertices read so far.
fn corner(word: &str, defined: usize) -> Result<u32, String> {
    let index = word.split('/').next().unwrap_or("");
    let value: i64 =
        index.parse().map_err(|_| format!("face corner `{word}` does not start with a vertex index"))?;
    let resolved = if value > 0 {
        value - 1
    } else if value < 0 {
        defined as i64 + value
    } else {
        return Err(format!("face corner `{word}`: vertex indices start at 1"));
    };
    if resolved < 0 || resolved >= defined as i64 {
        return Err(format!("face corner `{word}` names a vertex not defined above ({defined} are)"));
    }
    Ok(resolved as u32)
}
