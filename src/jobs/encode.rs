//! Turning a finished run into the bytes the store keeps and the result endpoint serves.
//!
//! Every result goes through [`encode_result`], the one place that chooses an encoding: the
//! scene's `output.format` (NPY becomes NPZ when the scene records more than positions). A result
//! kept as JSON, drape's canonical and lossless form, can be served later in any other format:
//! [`transcode`] reads it back and encodes it again, with the same numbers.

use bytes::Bytes;

use super::StoredResult;
use crate::output::{Format, check_recording, encode, read_json, recorded_fields};
use crate::run::Recording;
use crate::scene::FieldError;
use crate::scene::Output;

/// Encodes a recording in the format its scene's `output` asks for.
pub fn encode_result(recording: &Recording, output: &Output) -> std::io::Result<StoredResult> {
    let format = output.format.for_fields(&output.fields);
    let mut bytes = Vec::new();
    encode(recording, format, &mut bytes)?;
    Ok(StoredResult { media_type: format.media_type(), bytes: Bytes::from(bytes) })
}

/// Why a stored result cannot be served in another format.
#[derive(Debug, thiserror::Error)]
pub enum TranscodeError {
    /// The result is kept in a binary format, from which no other is made.
    #[error("the result is stored as {stored}")]
    NotCanonical {
        /// Its media type.
        stored: &'static str,
    },
    /// The format cannot carry what the run recorded.
    #[error("{} cannot carry this result", .format.name())]
    CannotCarry {
        /// The format asked for.
        format: Format,
        /// What it cannot carry, by the scene's `output` field.
        errors: Vec<FieldError>,
    },
    /// The stored bytes did not read back or encode.
    #[error("the stored result could not be re-encoded: {0}")]
    Broken(String),
}

/// The stored result in `format`: as it is when it already is, else made from its JSON form.
/// Reading and encoding is CPU work: call it off the async runtime.
pub fn transcode(stored: StoredResult, format: Format) -> Result<StoredResult, TranscodeError> {
    if stored.media_type == format.media_type() {
        return Ok(stored);
    }
    if stored.media_type != Format::Json.media_type() {
        return Err(TranscodeError::NotCanonical { stored: stored.media_type });
    }
    let recording = read_json(&stored.bytes).map_err(|e| TranscodeError::Broken(e.to_string()))?;
    let format = format.for_fields(&recorded_fields(&recording));
    check_recording(format, &recording).map_err(|errors| TranscodeError::CannotCarry { format, errors })?;
    let mut bytes = Vec::new();
    encode(&recording, format, &mut bytes).map_err(|e| TranscodeError::Broken(e.to_string()))?;
    Ok(StoredResult { media_type: format.media_type(), bytes: Bytes::from(bytes) })
}
