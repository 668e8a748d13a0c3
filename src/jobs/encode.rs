//! Turning a finished run into the bytes the store keeps and the result endpoint serves.
//!
//! Every result goes through [`encode_result`], the one place that chooses an encoding: the
//! scene's `output.format` (NPY becomes NPZ when the scene records more than positions). A result
//! kept as JSON, drape's canonical and lossless form, can be served later in any other format:
//! [`transcode`] reads it back and encodes it again, with the same numbers: the fields the
//! caller selects, or by default every recorded field the format carries, naming those it left
//! out.
//!
//! Encoding a large recording takes a while, so it can be stopped like the run: the bytes go
//! through [`UnlessStopped`], which fails the next write once its caller's `stop` says so (the
//! encoders write through a buffer, so it looks once per buffer's worth).

use std::io::{self, Write};

use bytes::Bytes;

use super::store::StoredResult;
use crate::output::{Format, carried, check_fields, encode, encode_fields, read_json, recorded_fields};
use crate::run::Recording;
use crate::scene::Output;
use crate::scene::{Field, FieldError};

/// Encodes a recording in the format its scene's `output` asks for, unless `stop` turns true
/// meanwhile: then the error is [`EncodingCancelled`].
pub fn encode_result(
    recording: &Recording,
    output: &Output,
    stop: &dyn Fn() -> bool,
) -> io::Result<StoredResult> {
    let format = output.format.for_fields(&output.fields);
    let mut bytes = Vec::new();
    encode(recording, format, UnlessStopped { inner: &mut bytes, stop })?;
    Ok(StoredResult { media_type: format.media_type(), bytes: Bytes::from(bytes) })
}

/// Why [`encode_result`] stopped: its job was cancelled (by a client, its wall time or a
/// shutdown) while it encoded.
#[derive(Debug, thiserror::Error)]
#[error("the job was stopped while its result was being encoded")]
pub struct EncodingCancelled;

impl EncodingCancelled {
    /// Whether an encoder's error is this one.
    pub fn is(error: &io::Error) -> bool {
        error.get_ref().is_some_and(|inner| inner.is::<Self>())
    }
}

/// A writer that fails once `stop` is true. Its error is not `ErrorKind::Interrupted`, which
/// `write_all` would retry for ever.
struct UnlessStopped<'a, W> {
    inner: W,
    stop: &'a dyn Fn() -> bool,
}

impl<W: Write> UnlessStopped<'_, W> {
    fn check(&self) -> io::Result<()> {
        if (self.stop)() { Err(io::Error::other(EncodingCancelled)) } else { Ok(()) }
    }
}

impl<W: Write> Write for UnlessStopped<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.check()?;
        self.inner.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.check()?;
        self.inner.write_all(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
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
    /// A field selected by name is not one the run recorded.
    #[error("the run did not record {}", .field.name())]
    NotRecorded {
        /// The field.
        field: Field,
    },
    /// The format cannot carry a field selected by name, or what is selected lacks what the
    /// format needs (positions, a frame).
    #[error("{} cannot carry this result", .format.name())]
    CannotCarry {
        /// The format asked for.
        format: Format,
        /// What it cannot carry: by the scene's `output` field (`/output/fields/1`), a field
        /// selected by name by its index in the selection, or `/output/frames`.
        errors: Vec<FieldError>,
    },
    /// The stored bytes did not read back or encode.
    #[error("the stored result could not be re-encoded: {0}")]
    Broken(String),
}

/// A stored result as served: its bytes, and the recorded fields the format asked for could not
/// carry and so left out.
#[derive(Debug)]
pub struct Transcoded {
    /// The result.
    pub result: StoredResult,
    /// The fields left out, in contract order; empty when nothing was.
    pub omitted: Vec<Field>,
}

/// The stored result in `format` (else the one it is stored in) with `fields` (else every field
/// the format carries): as it is when it already is, else made from its JSON form. Fields the
/// format cannot carry are left out and named in [`Transcoded::omitted`] unless `fields` named
/// them, which is [`TranscodeError::CannotCarry`]. Reading and encoding is CPU work: call it off
/// the async runtime.
pub fn transcode(
    stored: StoredResult,
    format: Option<Format>,
    fields: Option<&[Field]>,
) -> Result<Transcoded, TranscodeError> {
    let format = format.or_else(|| Format::from_media_type(stored.media_type)).unwrap_or(Format::Json);
    if stored.media_type == format.media_type() && fields.is_none() {
        return Ok(Transcoded { result: stored, omitted: Vec::new() });
    }
    if stored.media_type != Format::Json.media_type() {
        return Err(TranscodeError::NotCanonical { stored: stored.media_type });
    }
    let recording = read_json(&stored.bytes).map_err(|e| TranscodeError::Broken(e.to_string()))?;
    let recorded = recorded_fields(&recording);
    let (format, fields, omitted) = match fields {
        Some(fields) => {
            if let Some(&field) = fields.iter().find(|f| !recorded.contains(f)) {
                return Err(TranscodeError::NotRecorded { field });
            }
            (format.for_fields(fields), fields.to_vec(), Vec::new())
        }
        None => {
            let carried = carried(format, &recorded);
            (carried.format, carried.fields, carried.omitted)
        }
    };
    check_fields(format, &recording, &fields)
        .map_err(|errors| TranscodeError::CannotCarry { format, errors })?;
    let mut bytes = Vec::new();
    encode_fields(&recording, &fields, format, &mut bytes)
        .map_err(|e| TranscodeError::Broken(e.to_string()))?;
    Ok(Transcoded {
        result: StoredResult { media_type: format.media_type(), bytes: Bytes::from(bytes) },
        omitted,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_fails_the_next_write_and_nothing_more_is_written() {
        let stopped = std::sync::atomic::AtomicBool::new(false);
        let stop = || stopped.load(std::sync::atomic::Ordering::Relaxed);
        let mut bytes = Vec::new();
        let mut writer = UnlessStopped { inner: &mut bytes, stop: &stop };
        writer.write_all(b"abc").unwrap();
        stopped.store(true, std::sync::atomic::Ordering::Relaxed);
        let error = writer.write_all(b"def").unwrap_err();
        assert!(EncodingCancelled::is(&error), "{error}");
        assert_ne!(error.kind(), io::ErrorKind::Interrupted);
        assert!(writer.write(b"g").is_err_and(|e| EncodingCancelled::is(&e)));
        assert_eq!(bytes, b"abc");
    }

    #[test]
    fn a_stop_inside_a_json_encoding_is_found_through_serde_jsons_error() {
        let recording = crate::scene::Scene::from_json(
            br#"{"duration": 0.1, "dt": 0.01, "bodies": [{"type": "chain", "count": 3000}]}"#,
        )
        .map(|scene| crate::run::execute(&scene.compile(), &crate::run::Control::new()))
        .unwrap();
        let error = encode_result(&recording, &Output::default(), &|| true).unwrap_err();
        assert!(EncodingCancelled::is(&error), "{error}");
        assert!(encode_result(&recording, &Output::default(), &|| false).is_ok());
    }

    #[test]
    fn is_only_true_of_the_cancellation() {
        assert!(!EncodingCancelled::is(&io::Error::other("disk full")));
        assert!(!EncodingCancelled::is(&io::Error::from(io::ErrorKind::WriteZero)));
    }
}
