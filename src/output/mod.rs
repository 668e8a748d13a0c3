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

mod collider_mesh;
mod format;
mod glb;
mod json;
mod json_read;
mod npy;
mod obj;
mod pc2;
mod surface;

use std::io::{self, BufWriter, Write};

pub use format::{Carried, Format, FormatError, carried, check};
pub use json::{stats_json, write_json};
pub use json_read::{ReadError, read_json, read_json_final};

use crate::run::{Recording, Samples};
use crate::scene::{Field, FieldError};
use crate::solver::Energy;

/// Writes `recording` encoded as `format`, with every field it recorded.
///
/// `format` should be what [`Format::for_fields`] gives for the scene's fields (its media type is
/// the one to send). A recording holding a field the format cannot carry, or without the frame
/// or positions the format needs, is refused with [`io::ErrorKind::InvalidInput`] rather than
/// encoded with something missing; [`check`] finds such conflicts before the run. To leave
/// fields out, name the others with [`encode_fields`].
pub fn encode<W: Write>(recording: &Recording, format: Format, writer: W) -> io::Result<()> {
    encode_fields(recording, &recorded_fields(recording), format, writer)
}

/// Writes `fields` of `recording` encoded as `format`, as if the run had recorded those alone:
/// the other fields are left out, read in place like the rest (nothing is copied). Each field
/// must be one the run recorded and `format` carries, and the format must have the positions
/// and frame it needs, else [`io::ErrorKind::InvalidInput`]; [`carried`] says which fields a
/// format carries.
pub fn encode_fields<W: Write>(
    recording: &Recording,
    fields: &[Field],
    format: Format,
    writer: W,
) -> io::Result<()> {
    let selected = Selected::of(recording, fields)
        .map_err(|field| io::Error::new(io::ErrorKind::InvalidInput, not_recorded(field)))?;
    if let Some(problem) = unencodable(recording, &selected, format) {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, problem));
    }
    let mut writer = BufWriter::with_capacity(1 << 16, writer);
    match format {
        Format::Json => json::write_json_fields(recording, &selected, &mut writer)?,
        Format::Glb => glb::write_glb(recording, &selected, &mut writer)?,
        Format::Obj => obj::write_obj(recording, &selected, &mut writer)?,
        Format::Npy => npy::write_npy(recording, &selected, &mut writer)?,
        Format::Npz => npy::write_npz(recording, &selected, &mut writer)?,
        Format::Pc2 => pc2::write_pc2(recording, &selected, &mut writer)?,
    }
    writer.flush()
}

/// Whether `format` can carry everything `recording` holds; each problem is named by the
/// `output` field of the scene at fault (`/output/fields/1`, `/output/frames`), as [`check`]
/// names them before a run.
pub fn check_recording(format: Format, recording: &Recording) -> Result<(), Vec<FieldError>> {
    check_fields(format, recording, &recorded_fields(recording))
}

/// Whether `format` can carry `fields` of `recording` ([`encode_fields`]); each problem is named
/// as by [`check_recording`], a field by its index in `fields` (`/output/fields/1`).
pub fn check_fields(format: Format, recording: &Recording, fields: &[Field]) -> Result<(), Vec<FieldError>> {
    let selected = match Selected::of(recording, fields) {
        Ok(selected) => selected,
        Err(field) => {
            let index = fields.iter().position(|&f| f == field).unwrap_or_default();
            return Err(vec![FieldError::new(format!("/output/fields/{index}"), not_recorded(field))]);
        }
    };
    let output = crate::scene::Output {
        frames: recording.selection,
        fields: fields.to_vec(),
        format,
        ..crate::scene::Output::default()
    };
    check(format, &output)?;
    match unencodable(recording, &selected, format) {
        None => Ok(()),
        Some(problem) => Err(vec![FieldError::new("/output/frames", problem)]),
    }
}

/// The fields a recording holds, in contract order.
pub fn recorded_fields(recording: &Recording) -> Vec<Field> {
    Selected::all(recording).fields()
}

fn not_recorded(field: Field) -> String {
    format!("the run did not record {}", field.name())
}

/// The fields an encoding writes, borrowed from a recording's frames; a field left out (or not
/// recorded) is `None`. Encoders read the fields from here and nowhere else, and everything
/// else (mesh, times, statistics) from the recording.
#[derive(Clone, Copy, Debug, Default)]
struct Selected<'a> {
    positions: Option<&'a Samples>,
    velocities: Option<&'a Samples>,
    normals: Option<&'a Samples>,
    energy: Option<&'a [Energy]>,
    strain: Option<&'a [f64]>,
}

impl<'a> Selected<'a> {
    /// Every field `recording` holds.
    fn all(recording: &'a Recording) -> Self {
        let f = &recording.frames;
        Self {
            positions: f.positions.as_ref(),
            velocities: f.velocities.as_ref(),
            normals: f.normals.as_ref(),
            energy: f.energy.as_deref(),
            strain: f.strain.as_deref(),
        }
    }

    /// `fields` of `recording`; the first it did not record is the error.
    fn of(recording: &'a Recording, fields: &[Field]) -> Result<Self, Field> {
        let all = Self::all(recording);
        let mut selected = Self::default();
        for &field in fields {
            let held = match field {
                Field::Positions => {
                    selected.positions = all.positions;
                    all.positions.is_some()
                }
                Field::Velocities => {
                    selected.velocities = all.velocities;
                    all.velocities.is_some()
                }
                Field::Normals => {
                    selected.normals = all.normals;
                    all.normals.is_some()
                }
                Field::Energy => {
                    selected.energy = all.energy;
                    all.energy.is_some()
                }
                Field::Strain => {
                    selected.strain = all.strain;
                    all.strain.is_some()
                }
            };
            if !held {
                return Err(field);
            }
        }
        Ok(selected)
    }

    /// The fields selected, in contract order.
    fn fields(&self) -> Vec<Field> {
        let held = [
            self.positions.is_some(),
            self.velocities.is_some(),
            self.normals.is_some(),
            self.energy.is_some(),
            self.strain.is_some(),
        ];
        Field::ALL.into_iter().zip(held).filter_map(|(field, held)| held.then_some(field)).collect()
    }
}

fn unencodable(recording: &Recording, selected: &Selected, format: Format) -> Option<String> {
    let fields = selected.fields();
    if let Some(field) = fields.iter().find(|&&f| !format.carries(f)) {
        return Some(format!("format {} cannot carry {}", format.name(), field.name()));
    }
    if format.needs_positions() && !fields.contains(&Field::Positions) {
        return Some(format!("format {} needs positions, and the run recorded none", format.name()));
    }
    if format != Format::Json && recording.frames.is_empty() {
        return Some(format!("format {} needs a frame, and the run recorded none", format.name()));
    }
    if format == Format::Glb && glb::shown_frames(recording, selected).is_empty() {
        return Some(
            "format glb needs a frame whose positions are finite in f32, and the run has none".into(),
        );
    }
    None
}
