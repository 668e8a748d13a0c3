//! Turning a finished run into the bytes the store keeps and the result endpoint serves.
//!
//! Every result goes through [`encode_result`], the one place that chooses an encoding.

use bytes::Bytes;

use super::StoredResult;
use crate::run::Recording;

/// Encodes a recording as the JSON result.
pub fn encode_result(recording: &Recording) -> std::io::Result<StoredResult> {
    let mut bytes = Vec::new();
    crate::output::write_json(recording, &mut bytes)?;
    Ok(StoredResult { media_type: "application/json", bytes: Bytes::from(bytes) })
}
