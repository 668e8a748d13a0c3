//! Turning a finished run into the bytes the store keeps and the result endpoint serves.
//!
//! Every result goes through [`encode_result`], the one place that chooses an encoding: the
//! scene's `output.format` (NPY becomes NPZ when the scene records more than positions).

use bytes::Bytes;

use super::StoredResult;
use crate::output::encode;
use crate::run::Recording;
use crate::scene::Output;

/// Encodes a recording in the format its scene's `output` asks for.
pub fn encode_result(recording: &Recording, output: &Output) -> std::io::Result<StoredResult> {
    let format = output.format.for_fields(&output.fields);
    let mut bytes = Vec::new();
    encode(recording, format, &mut bytes)?;
    Ok(StoredResult { media_type: format.media_type(), bytes: Bytes::from(bytes) })
}
