//! Encoders that turn a [`Recording`] into the bytes a client asked for, one file per format,
//! and [`encode`], the one entry point that picks among them.
//!
//! Every encoder writes as it goes into any [`Write`] and never builds a second copy of the
//! frames: formats that need lengths up front (glTF, NPY) compute them from the recording first.
//! Numbers are the recording's own: a format in the run's precision carries the same bits as the
//! JSON result; glTF and PC2 are `f32` by their specifications, so an `f64` run is rounded to
//! the nearest `f32` there. A value that is not finite has one spelling per format: `null` in
//! JSON, `NaN`/`Infinity`/`-Infinity` in OBJ, the IEEE value itself in NPY, NPZ and PC2; glTF
//! allows none, so a GLB leaves out the frames that hold one.

mod format;
mod glb;
mod json;
mod json_read;
mod npy;
mod obj;
mod pc2;
mod surface;

use std::io::{self, BufWriter, Write};

pub use format::{Format, FormatError, check};
pub use json::{stats_json, write_json};
pub use json_read::{ReadError, read_json};

use crate::run::Recording;
use crate::scene::Field;

/// Writes `recording` encoded as `format`.
///
/// `format` should be what [`Format::for_fields`] gives for the scene's fields (its media type is
/// the one to send). A recording holding a field the format cannot carry, or without the frame
/// or positions the format needs, is refused with [`io::ErrorKind::InvalidInput`] rather than
/// encoded with something missing; [`check`] finds such conflicts before the run.
pub fn encode<W: Write>(recording: &Recording, format: Format, writer: W) -> io::Result<()> {
    if let Some(problem) = unencodable(recording, format) {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, problem));
    }
    let mut writer = BufWriter::with_capacity(1 << 16, writer);
    match format {
        Format::Json => write_json(recording, &mut writer)?,
        Format::Glb => glb::write_glb(recording, &mut writer)?,
        Format::Obj => obj::write_obj(recording, &mut writer)?,
        Format::Npy => npy::write_npy(recording, &mut writer)?,
        Format::Npz => npy::write_npz(recording, &mut writer)?,
        Format::Pc2 => pc2::write_pc2(recording, &mut writer)?,
    }
    writer.flush()
}

/// Whether `format` can carry everything `recording` holds; each problem is named by the
/// `output` field of the scene at fault (`/output/fields/1`, `/output/frames`), as [`check`]
/// names them before a run.
pub fn check_recording(format: Format, recording: &Recording) -> Result<(), Vec<crate::scene::FieldError>> {
    let output = crate::scene::Output {
        frames: recording.selection,
        fields: recorded_fields(recording),
        format,
        ..crate::scene::Output::default()
    };
    check(format, &output)?;
    match unencodable(recording, format) {
        None => Ok(()),
        Some(problem) => Err(vec![crate::scene::FieldError::new("/output/frames", problem)]),
    }
}

/// The fields a recording holds, in contract order.
pub fn recorded_fields(recording: &Recording) -> Vec<Field> {
    let f = &recording.frames;
    let held = [
        f.positions.is_some(),
        f.velocities.is_some(),
        f.normals.is_some(),
        f.energy.is_some(),
        f.strain.is_some(),
    ];
    Field::ALL.into_iter().zip(held).filter_map(|(field, held)| held.then_some(field)).collect()
}

fn unencodable(recording: &Recording, format: Format) -> Option<String> {
    let fields = recorded_fields(recording);
    if let Some(field) = fields.iter().find(|&&f| !format.carries(f)) {
        return Some(format!("format {} cannot carry {}", format.name(), field.name()));
    }
    if format.needs_positions() && !fields.contains(&Field::Positions) {
        return Some(format!("format {} needs positions, and the run recorded none", format.name()));
    }
    if format != Format::Json && recording.frames.is_empty() {
        return Some(format!("format {} needs a frame, and the run recorded none", format.name()));
    }
    if format == Format::Glb && glb::shown_frames(recording).is_empty() {
        return Some(
            "format glb needs a frame whose positions are finite in f32, and the run has none".into(),
        );
    }
    None
}
