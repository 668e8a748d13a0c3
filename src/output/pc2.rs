//! PC2, the point cache of 3ds Max and Blender's Mesh Cache modifier: a 32-byte little-endian
//! header (the signature `POINTCACHE2\0`, `i32` version 1, `i32` point count, `f32` start
//! frame, `f32` sample rate, `i32` sample count), then for each sample every point's `f32` x,
//! y, z.
//!
//! One sample per recorded frame, every particle of every body in order. The start frame is 0
//! and the sample rate 1: sample k is the k-th frame of the result, `1/fps` seconds apart (the
//! last one may be closer when the run stopped at rest). PC2 is `f32` by its definition, so an
//! `f64` run is rounded to the nearest `f32`.

use std::io::{self, Write};

use super::Selected;
use crate::run::{Recording, Samples};

/// The signature that opens every PC2 file.
const SIGNATURE: &[u8; 12] = b"POINTCACHE2\0";
const VERSION: i32 = 1;

/// Writes the positions of `recording` as a PC2 point cache.
pub(super) fn write_pc2<W: Write>(recording: &Recording, selected: &Selected, w: &mut W) -> io::Result<()> {
    let positions = selected.positions.expect("checked by encode");
    let count = |n: usize, what: &str| {
        i32::try_from(n)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, format!("too many {what} for PC2: {n}")))
    };
    w.write_all(SIGNATURE)?;
    w.write_all(&VERSION.to_le_bytes())?;
    w.write_all(&count(recording.particles, "points")?.to_le_bytes())?;
    w.write_all(&0.0f32.to_le_bytes())?;
    w.write_all(&1.0f32.to_le_bytes())?;
    w.write_all(&count(recording.frames.len(), "samples")?.to_le_bytes())?;
    let per_frame = 3 * recording.particles;
    let mut buffer = Vec::with_capacity(4 * per_frame);
    for k in 0..recording.frames.len() {
        buffer.clear();
        let scalars = k * per_frame..(k + 1) * per_frame;
        match positions {
            Samples::F32(v) => v[scalars].iter().for_each(|x| buffer.extend_from_slice(&x.to_le_bytes())),
            Samples::F64(v) => {
                v[scalars].iter().for_each(|&x| buffer.extend_from_slice(&(x as f32).to_le_bytes()))
            }
        }
        w.write_all(&buffer)?;
    }
    Ok(())
}
