//! Wavefront OBJ, as Wavefront's "Object Files (.obj)" appendix to the Advanced Visualizer
//! manual defines it: the last recorded frame as text, one `o` object per body named after it,
//! with `v` positions, `vn` normals and `f v//vn` faces (1-based, counted over the whole file),
//! or `l` for a chain, which has no faces.
//!
//! Numbers are written in the run's precision, as the shortest decimal that reads back as the
//! same value: the same numbers as the JSON result's. A value that is not finite is written
//! `NaN`, `Infinity` or `-Infinity`, the spellings that C's `strtod`, Rust's and Python's float
//! parsing and JavaScript's `parseFloat` all read back as that value. Normals are the
//! recording's when the run recorded them, otherwise computed here from the triangles (zero for
//! a vertex on no triangle).

use std::io::{self, Write};

use super::Selected;
use super::surface::{body_range, body_triangles, body_vectors, vertex_normals};
use crate::run::{Recording, Samples};

/// Writes the last recorded frame of `recording` as OBJ text. It needs positions and a frame.
pub(super) fn write_obj<W: Write>(recording: &Recording, selected: &Selected, w: &mut W) -> io::Result<()> {
    let positions = selected.positions.expect("checked by encode");
    let last = recording.frames.len() - 1;
    writeln!(
        w,
        "# drape {}: {} particles, t = {} s",
        env!("CARGO_PKG_VERSION"),
        recording.particles,
        recording.frames.times[last]
    )?;
    // `f v//vn` indices count over the whole file; chains have vertices but no normals.
    let mut normals_written = 0;
    for body in &recording.bodies {
        writeln!(w, "o {}", body.name.replace(char::is_whitespace, "_"))?;
        let range = body_range(recording.particles, last, body);
        write_vectors(w, "v", positions, range.clone())?;
        let triangles = body_triangles(recording, body);
        let first = body.offset + 1;
        if triangles.is_empty() {
            let indices: Vec<String> = (first..first + body.count).map(|i| i.to_string()).collect();
            writeln!(w, "l {}", indices.join(" "))?;
            continue;
        }
        match selected.normals {
            Some(normals) => write_vectors(w, "vn", normals, range)?,
            None => {
                let computed =
                    vertex_normals(&body_vectors(positions, recording.particles, last, body), &triangles);
                for n in computed {
                    match positions {
                        Samples::F32(_) => write_vector(w, "vn", n.map(|x| x as f32))?,
                        Samples::F64(_) => write_vector(w, "vn", n)?,
                    }
                }
            }
        }
        for triangle in triangles {
            let [a, b, c] = triangle.map(|i| i as usize + first);
            let [na, nb, nc] = triangle.map(|i| i as usize + normals_written + 1);
            writeln!(w, "f {a}//{na} {b}//{nb} {c}//{nc}")?;
        }
        normals_written += body.count;
    }
    Ok(())
}

/// One `tag x y z` line per vector in `range`, in the samples' precision.
fn write_vectors<W: Write>(
    w: &mut W,
    tag: &str,
    samples: &Samples,
    range: std::ops::Range<usize>,
) -> io::Result<()> {
    match samples {
        Samples::F32(v) => {
            v[range].chunks_exact(3).try_for_each(|c| write_vector(w, tag, [c[0], c[1], c[2]]))
        }
        Samples::F64(v) => {
            v[range].chunks_exact(3).try_for_each(|c| write_vector(w, tag, [c[0], c[1], c[2]]))
        }
    }
}

/// One `tag x y z` line. Rust's `Display` for a finite float prints the shortest decimal that
/// reads back as the same value, never an exponent; its `inf` is not what every reader takes.
fn write_vector<W: Write, T: Copy + Into<f64> + std::fmt::Display>(
    w: &mut W,
    tag: &str,
    v: [T; 3],
) -> io::Result<()> {
    write!(w, "{tag}")?;
    for x in v {
        let wide: f64 = x.into();
        match wide {
            _ if wide.is_finite() => write!(w, " {x}")?,
            _ if wide.is_nan() => write!(w, " NaN")?,
            _ if wide > 0.0 => write!(w, " Infinity")?,
            _ => write!(w, " -Infinity")?,
        }
    }
    writeln!(w)
}
