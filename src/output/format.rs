//! Choosing a result's encoding: each [`Format`]'s media type, its name in `?format=` and
//! `--format`, content negotiation from an HTTP `Accept` header (RFC 9110 §12.5.1), and the check
//! that a format can carry the fields a scene asks for.
//!
//! | format | media type | fields it carries |
//! | --- | --- | --- |
//! | `json` | `application/json` | all |
//! | `glb` | `model/gltf-binary` | positions (required), normals |
//! | `obj` | `model/obj` | positions (required), normals; the last frame only |
//! | `npy` | `application/x-npy` | positions (required); with more fields it is sent as `npz` |
//! | `npz` | `application/x-npz` | all, one array each, plus `times` |
//! | `pc2` | `application/x-pc2` | positions (required) |

use thiserror::Error;

pub use crate::scene::Format;
use crate::scene::{Field, FieldError, Output};

/// Why a client's choice of format cannot be honoured.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum FormatError {
    /// `?format=` or `--format` named no known format (a 400 over HTTP).
    #[error("unknown format {0:?}; known formats: json, glb, obj, npy, npz, pc2")]
    Unknown(String),
    /// The `Accept` header allows none of our media types (a 406 over HTTP).
    #[error("none of the accepted media types can be produced; available: {}", media_types())]
    NotAcceptable,
}

fn media_types() -> String {
    Format::ALL.iter().map(|f| f.media_type()).collect::<Vec<_>>().join(", ")
}

impl Format {
    /// The media type of the encoded bytes (for `Content-Type`).
    pub fn media_type(self) -> &'static str {
        match self {
            Self::Json => "application/json",
            Self::Glb => "model/gltf-binary",
            Self::Obj => "model/obj",
            Self::Npy => "application/x-npy",
            Self::Npz => "application/x-npz",
            Self::Pc2 => "application/x-pc2",
        }
    }

    /// The format whose media type is exactly `media_type`.
    pub fn from_media_type(media_type: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.media_type() == media_type)
    }

    /// The format named `name` (`?format=glb`, `--format glb`).
    pub fn from_name(name: &str) -> Result<Format, FormatError> {
        Format::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| FormatError::Unknown(name.to_string()))
    }

    /// The format an `Accept` header asks for: the media range with the highest `q` that names one
    /// of ours, the earlier one on a tie. `Ok(None)` when the header leaves the choice open (it is
    /// empty, or only `*/*` matches best), so the scene's own format applies.
    pub fn from_accept(header: &str) -> Result<Option<Format>, FormatError> {
        let mut best: Option<(f64, Option<Format>)> = None;
        for range in header.split(',').map(str::trim).filter(|r| !r.is_empty()) {
            let mut parts = range.split(';').map(str::trim);
            let media = parts.next().unwrap_or_default().to_ascii_lowercase();
            let q = parts
                .filter_map(|p| p.split_once('='))
                .find(|(k, _)| k.trim().eq_ignore_ascii_case("q"))
                .map_or(Some(1.0), |(_, v)| v.trim().parse::<f64>().ok().filter(|q| (0.0..=1.0).contains(q)));
            let Some(q) = q.filter(|&q| q > 0.0) else { continue };
            let choice = match media.split_once('/') {
                Some(("*", "*")) => None,
                Some((kind, "*")) => {
                    match Format::ALL.into_iter().find(|f| f.media_type().starts_with(&format!("{kind}/"))) {
                        Some(format) => Some(format),
                        None => continue,
                    }
                }
                _ => match Format::ALL.into_iter().find(|f| f.media_type() == media) {
                    Some(format) => Some(format),
                    None => continue,
                },
            };
            if best.is_none_or(|(best_q, _)| q > best_q) {
                best = Some((q, choice));
            }
        }
        match best {
            Some((_, choice)) => Ok(choice),
            None if header.trim().is_empty() => Ok(None),
            None => Err(FormatError::NotAcceptable),
        }
    }
}

impl std::str::FromStr for Format {
    type Err = FormatError;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Format::from_name(name)
    }
}

/// What a format sends of a run's fields when the caller names none: the format actually sent,
/// the fields it carries and those it leaves out, each in contract order ([`Field::ALL`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Carried {
    /// The format sent: NPY becomes NPZ for more than positions ([`Format::for_fields`]).
    pub format: Format,
    /// The fields it carries.
    pub fields: Vec<Field>,
    /// The fields it leaves out, empty when it carries them all.
    pub omitted: Vec<Field>,
}

/// What `format` carries of `fields` (those a run recorded). Whether what is left is enough to
/// encode (a mesh format needs positions) is [`check`]'s question.
pub fn carried(format: Format, fields: &[Field]) -> Carried {
    let format = format.for_fields(fields);
    let (fields, omitted) = Field::ALL
        .into_iter()
        .filter(|field| fields.contains(field))
        .partition(|&field| format.carries(field));
    Carried { format, fields, omitted }
}

/// Checks that `format` can encode what `output` asks for. Each problem names its field by JSON
/// Pointer into the scene (`/output/fields/2` for a field the format cannot carry), so that a
/// request whose chosen format conflicts with its scene gets a 422 that says where.
pub fn check(format: Format, output: &Output) -> Result<(), Vec<FieldError>> {
    let problems = output.format_problems(format);
    if problems.is_empty() { Ok(()) } else { Err(problems) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::FrameSelection;

    #[test]
    fn names_and_media_types_round_trip() {
        for format in Format::ALL {
            assert_eq!(Format::from_name(format.name()), Ok(format));
            assert_eq!(Format::from_accept(format.media_type()), Ok(Some(format)));
        }
        assert_eq!(Format::from_name("gltf"), Err(FormatError::Unknown("gltf".into())));
    }

    #[test]
    fn accept_picks_the_highest_quality_we_can_produce() {
        let accept = "text/html, model/obj;q=0.5, model/gltf-binary;q=0.9, */*;q=0.1";
        assert_eq!(Format::from_accept(accept), Ok(Some(Format::Glb)));
        assert_eq!(
            Format::from_accept("application/x-npz;q=0.3, application/json;q=0.3"),
            Ok(Some(Format::Npz))
        );
        assert_eq!(Format::from_accept("model/*"), Ok(Some(Format::Glb)));
        assert_eq!(Format::from_accept("*/*"), Ok(None));
        assert_eq!(Format::from_accept(""), Ok(None));
        assert_eq!(Format::from_accept("application/json;q=0, model/obj"), Ok(Some(Format::Obj)));
        assert_eq!(Format::from_accept("text/html, image/png"), Err(FormatError::NotAcceptable));
        assert_eq!(Format::from_accept("application/json;q=0"), Err(FormatError::NotAcceptable));
    }

    fn output(fields: &[Field], frames: FrameSelection) -> Output {
        Output { fields: fields.to_vec(), frames, ..Output::default() }
    }

    #[test]
    fn a_field_the_format_cannot_carry_is_named_by_pointer() {
        let asked = output(&[Field::Positions, Field::Normals, Field::Energy], FrameSelection::All);
        let problems = check(Format::Glb, &asked).unwrap_err();
        assert_eq!(problems.len(), 1);
        assert_eq!(problems[0].pointer, "/output/fields/2");
        assert!(problems[0].detail.contains("energy"), "{}", problems[0].detail);
        assert_eq!(check(Format::Pc2, &asked).unwrap_err().len(), 2);
        assert_eq!(check(Format::Json, &asked), Ok(()));
        assert_eq!(check(Format::Npz, &asked), Ok(()));
        // NPY with more than positions is sent as NPZ, which carries them all.
        assert_eq!(check(Format::Npy, &asked), Ok(()));
        assert_eq!(Format::Npy.for_fields(&asked.fields), Format::Npz);
        assert_eq!(Format::Npy.for_fields(&[Field::Positions]), Format::Npy);
    }

    #[test]
    fn a_format_carries_what_it_can_and_names_the_rest() {
        let recorded = [Field::Positions, Field::Velocities, Field::Normals, Field::Energy];
        let glb = carried(Format::Glb, &recorded);
        assert_eq!(glb.format, Format::Glb);
        assert_eq!(glb.fields, [Field::Positions, Field::Normals]);
        assert_eq!(glb.omitted, [Field::Velocities, Field::Energy]);
        let pc2 = carried(Format::Pc2, &[Field::Energy, Field::Positions, Field::Velocities, Field::Normals]);
        assert_eq!(pc2.omitted, [Field::Velocities, Field::Normals, Field::Energy]);
        assert_eq!((pc2.fields.as_slice(), pc2.omitted.len()), ([Field::Positions].as_slice(), 3));
        // NPY with more than positions is sent as NPZ, which leaves nothing out.
        let npy = carried(Format::Npy, &recorded);
        assert_eq!((npy.format, npy.fields.len(), npy.omitted.len()), (Format::Npz, 4, 0));
        assert_eq!(carried(Format::Json, &recorded).omitted, []);
        // What is left may still not be enough: that is check's to say.
        assert_eq!(carried(Format::Obj, &[Field::Energy]).fields, []);
    }

    #[test]
    fn mesh_formats_need_positions_and_a_frame() {
        let no_positions = output(&[Field::Normals], FrameSelection::Final);
        let problems = check(Format::Obj, &no_positions).unwrap_err();
        assert_eq!(problems.iter().map(|p| p.pointer.as_str()).collect::<Vec<_>>(), ["/output/fields"]);
        let no_frames = output(&[Field::Positions], FrameSelection::None);
        assert_eq!(check(Format::Pc2, &no_frames).unwrap_err()[0].pointer, "/output/frames");
        assert_eq!(check(Format::Json, &no_frames), Ok(()));
    }
}
