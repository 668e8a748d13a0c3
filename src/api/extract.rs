//! Extractors whose rejections are [`AppError`]s, so a bad request body, header or query gets
//! the same problem body as every other error.

use std::collections::HashMap;

use axum::body::Bytes;
use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::request::Parts;
use axum::http::{StatusCode, header};
use serde_json::Value;

use super::AppState;
use super::problem::AppError;
use crate::assets::has_references;
use crate::jobs::{JobId, fingerprint};
use crate::output::Format;
use crate::output::carried;
use crate::scene::{Field, FieldError, Scene};

/// A scene from a JSON body, validated, with the fingerprint of the document.
pub struct SceneBody {
    /// The scene.
    pub scene: Scene,
    /// [`fingerprint`] of the document, for idempotency.
    pub fingerprint: u64,
    /// The document, as the job store keeps it.
    pub document: Value,
}

impl SceneBody {
    /// The scene with its result format set to `choice`, if the client chose one, checked
    /// against the fields the scene records. The choice is part of the fingerprint.
    pub fn with_format(mut self, choice: Option<Format>) -> Result<Self, AppError> {
        let Some(format) = choice else { return Ok(self) };
        crate::output::check(format, &self.scene.output).map_err(AppError::InvalidScene)?;
        self.scene.output.format = format;
        // The stored document is what a worker runs, on any instance: it carries the choice too.
        if let Some(scene) = self.document.as_object_mut() {
            let output = scene.entry("output").or_insert_with(|| serde_json::json!({}));
            if let Some(output) = output.as_object_mut() {
                output.insert("format".into(), format.name().into());
            }
        }
        self.fingerprint = fingerprint(&serde_json::json!([self.fingerprint, format.name()]));
        Ok(self)
    }
}

impl SceneBody {
    /// The scene set to record what a one-shot result in `format` with `fields` sends (see
    /// [`FieldsChoice`]), with the fields left out because the format cannot carry them. Without
    /// either choice the scene is as sent. Each field selected must be one the scene records and
    /// the format carries (`422` at `/fields`); what remains must be enough for the format
    /// (positions for a mesh format, a frame), else a `422` at the scene's field. The choices
    /// are part of the fingerprint.
    pub fn for_result(
        mut self,
        format: Option<Format>,
        fields: Option<Vec<Field>>,
    ) -> Result<(Self, Vec<Field>), AppError> {
        if format.is_none() && fields.is_none() {
            return Ok((self, Vec::new()));
        }
        let wanted = format.unwrap_or(self.scene.output.format);
        let recorded = &self.scene.output.fields;
        let explicit = fields.is_some();
        let (sent, kept, omitted) = match fields {
            Some(fields) => {
                if let Some(field) = fields.iter().find(|f| !recorded.contains(f)) {
                    return Err(AppError::NotRecorded(vec![FieldError::new(
                        "/fields",
                        format!("the scene does not record {}; it records {}", field.name(), names(recorded)),
                    )]));
                }
                let sent = wanted.for_fields(&fields);
                if let Some(field) = fields.iter().find(|&&f| !sent.carries(f)) {
                    return Err(AppError::CannotCarry {
                        format: sent.name(),
                        errors: vec![cannot_carry_selected(sent, *field)],
                    });
                }
                (sent, fields, Vec::new())
            }
            None => {
                let carried = carried(wanted, recorded);
                (carried.format, carried.fields, carried.omitted)
            }
        };
        self.scene.output.fields = kept;
        if let Err(problems) = crate::output::check(sent, &self.scene.output) {
            return Err(if explicit {
                AppError::CannotCarry { format: sent.name(), errors: selection_problems(problems) }
            } else {
                AppError::InvalidScene(problems)
            });
        }
        self.scene.output.format = sent;
        // The stored document is what a worker runs, on any instance: it carries the choice too.
        let names: Vec<&str> = self.scene.output.fields.iter().map(|f| f.name()).collect();
        if let Some(scene) = self.document.as_object_mut() {
            let output = scene.entry("output").or_insert_with(|| serde_json::json!({}));
            if let Some(output) = output.as_object_mut() {
                output.insert("format".into(), sent.name().into());
                output.insert("fields".into(), names.clone().into());
            }
        }
        self.fingerprint = fingerprint(&serde_json::json!([self.fingerprint, sent.name(), names]));
        Ok((self, omitted))
    }
}

/// Problems with an `output` of fields selected by name (`?fields=`), a field named by the
/// selection (`/fields`) rather than the scene's `output.fields`.
pub fn selection_problems(problems: Vec<FieldError>) -> Vec<FieldError> {
    problems
        .into_iter()
        .map(
            |p| {
                if p.pointer.starts_with("/output/fields") { FieldError::new("/fields", p.detail) } else { p }
            },
        )
        .collect()
}

/// Fields as a list for a message: `positions, energy`.
pub fn names(fields: &[Field]) -> String {
    fields.iter().map(|f| f.name()).collect::<Vec<_>>().join(", ")
}

/// The problem of a field selected by name (`?fields=`) that `format` cannot carry.
pub fn cannot_carry_selected(format: Format, field: Field) -> FieldError {
    let carriers: Vec<&str> = Format::ALL.iter().filter(|f| f.carries(field)).map(|f| f.name()).collect();
    FieldError::new(
        "/fields",
        format!("format {} cannot carry {}; {} can", format.name(), field.name(), carriers.join(", ")),
    )
}

impl FromRequest<AppState> for SceneBody {
    type Rejection = AppError;

    /// Reads the scene with the meshes its `"asset"` references name put in their place; the
    /// fingerprint is of the document as sent (an asset id is the hash of its bytes), the
    /// stored document the one resolved.
    async fn from_request(request: Request, state: &AppState) -> Result<Self, AppError> {
        let JsonBody(mut document) = JsonBody::from_request(request, state).await?;
        let fingerprint = fingerprint(&document);
        if has_references(&document) {
            state.jobs.resolve_assets(&mut document, "").await?;
        }
        let scene = Scene::from_value(document.clone())?;
        Ok(Self { scene, fingerprint, document })
    }
}

/// The request's `Content-Type`, as text.
pub(super) fn content_type(request: &Request) -> Option<String> {
    request.headers().get(header::CONTENT_TYPE).map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned())
}

/// The whole body (the body-limit layer has bounded it: past the limit is a 413).
pub(super) async fn body_bytes<S: Send + Sync>(request: Request, state: &S) -> Result<Bytes, AppError> {
    Bytes::from_request(request, state).await.map_err(|rejection| {
        if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
            AppError::BodyTooLarge
        } else {
            AppError::BadRequest {
                detail: format!("the body could not be read: {rejection}"),
                errors: vec![],
            }
        }
    })
}

/// A JSON document from a body declared as JSON.
pub struct JsonBody(pub Value);

impl<S: Send + Sync> FromRequest<S> for JsonBody {
    type Rejection = AppError;

    async fn from_request(request: Request, state: &S) -> Result<Self, AppError> {
        let content_type = content_type(&request);
        if !content_type.as_deref().is_some_and(is_json) {
            return Err(AppError::UnsupportedMediaType { found: content_type });
        }
        let bytes = body_bytes(request, state).await?;
        let document: Value = serde_json::from_slice(&bytes).map_err(|e| AppError::MalformedJson {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        Ok(Self(document))
    }
}

/// Whether a `Content-Type` declares JSON: `application/json` or a `+json` type, any parameters.
fn is_json(content_type: &str) -> bool {
    let essence = content_type.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
    essence == "application/json" || (essence.starts_with("application/") && essence.ends_with("+json"))
}

/// The `Idempotency-Key` header, if sent: 1 to 255 visible ASCII characters.
pub struct IdempotencyKey(pub Option<String>);

impl<S: Send + Sync> FromRequestParts<S> for IdempotencyKey {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, AppError> {
        let Some(value) = parts.headers.get("idempotency-key") else { return Ok(Self(None)) };
        let key = value
            .to_str()
            .ok()
            .filter(|k| (1..=255).contains(&k.len()) && k.bytes().all(|b| b.is_ascii_graphic()));
        match key {
            Some(key) => Ok(Self(Some(key.to_string()))),
            None => Err(AppError::BadRequest {
                detail: "Idempotency-Key must be 1 to 255 visible ASCII characters".into(),
                errors: vec![FieldError::new(
                    "/headers/idempotency-key",
                    "1 to 255 visible ASCII characters",
                )],
            }),
        }
    }
}

/// A sweep id from the path; a malformed id is an unknown sweep.
pub struct SweepPath(pub JobId);

impl<S: Send + Sync> FromRequestParts<S> for SweepPath {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        let axum::extract::Path(raw) = axum::extract::Path::<String>::from_request_parts(parts, state)
            .await
            .map_err(|e| AppError::Internal(format!("sweep route without an id: {e}")))?;
        JobId::parse(&raw).map(Self).ok_or(AppError::SweepNotFound { id: raw })
    }
}

/// A job id from the path; a malformed id is an unknown job.
pub struct JobPath(pub JobId);

impl<S: Send + Sync> FromRequestParts<S> for JobPath {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        let axum::extract::Path(raw) = axum::extract::Path::<String>::from_request_parts(parts, state)
            .await
            .map_err(|e| AppError::Internal(format!("job route without an id: {e}")))?;
        JobId::parse(&raw).map(Self).ok_or(AppError::JobNotFound { id: raw })
    }
}

/// The query of `GET /jobs`: `offset` and `limit`.
pub struct PageQuery {
    /// Jobs to skip (default 0).
    pub offset: u64,
    /// Jobs to return, 1 to [`PageQuery::MAX_LIMIT`] (default 20).
    pub limit: u64,
}

/// The query string as name-value pairs; a malformed one is a 400.
async fn query_parameters<S: Send + Sync>(
    parts: &mut Parts,
    state: &S,
) -> Result<HashMap<String, String>, AppError> {
    let axum::extract::Query(params) =
        axum::extract::Query::<HashMap<String, String>>::from_request_parts(parts, state).await.map_err(
            |e| AppError::BadRequest {
                detail: format!("the query string is malformed: {e}"),
                errors: vec![],
            },
        )?;
    Ok(params)
}

impl PageQuery {
    /// The largest page.
    pub const MAX_LIMIT: u64 = 100;
}

impl<S: Send + Sync> FromRequestParts<S> for PageQuery {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        let params = query_parameters(parts, state).await?;
        let mut errors = Vec::new();
        let mut number =
            |name: &str, default: u64, range: std::ops::RangeInclusive<u64>| match params.get(name) {
                None => default,
                Some(text) => match text.parse::<u64>() {
                    Ok(n) if range.contains(&n) => n,
                    _ => {
                        errors.push(FieldError::new(
                            format!("/{name}"),
                            format!(
                                "must be a whole number from {} to {}, not `{text}`",
                                range.start(),
                                range.end()
                            ),
                        ));
                        default
                    }
                },
            };
        let offset = number("offset", 0, 0..=u64::from(u32::MAX));
        let limit = number("limit", 20, 1..=Self::MAX_LIMIT);
        for unknown in params.keys().filter(|k| !matches!(k.as_str(), "offset" | "limit")) {
            errors.push(FieldError::new(
                format!("/{unknown}"),
                "unknown query parameter: expected `offset` or `limit`",
            ));
        }
        if errors.is_empty() {
            Ok(Self { offset, limit })
        } else {
            Err(AppError::BadRequest { detail: "invalid query parameters; see `errors`".into(), errors })
        }
    }
}

/// The result format a client asks for: `?format=` (a name), else, when `ACCEPT` is true, the
/// `Accept` header (media types). `None` leaves the choice to the scene's `output.format`.
pub struct FormatChoice<const ACCEPT: bool>(pub Option<Format>);

impl<S: Send + Sync, const ACCEPT: bool> FromRequestParts<S> for FormatChoice<ACCEPT> {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        let params = query_parameters(parts, state).await?;
        if let Some(name) = params.get("format") {
            return Format::from_name(name).map(|f| Self(Some(f))).map_err(|e| AppError::BadRequest {
                detail: e.to_string(),
                errors: vec![FieldError::new("/format", e.to_string())],
            });
        }
        let accept =
            parts.headers.get(header::ACCEPT).map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
        match accept {
            Some(accept) if ACCEPT => Format::from_accept(&accept)
                .map(Self)
                .map_err(|e| AppError::NotAcceptable { detail: e.to_string() }),
            _ => Ok(Self(None)),
        }
    }
}

/// The fields a client selects for a result: `?fields=positions,normals` (names, comma-separated;
/// one named twice counts once). `None` leaves the choice to the format: every recorded field it
/// carries.
pub struct FieldsChoice(pub Option<Vec<Field>>);

impl<S: Send + Sync> FromRequestParts<S> for FieldsChoice {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        let params = query_parameters(parts, state).await?;
        let Some(list) = params.get("fields") else { return Ok(Self(None)) };
        let mut fields = Vec::new();
        for name in list.split(',') {
            match Field::ALL.into_iter().find(|f| f.name() == name) {
                Some(field) if fields.contains(&field) => {}
                Some(field) => fields.push(field),
                None => {
                    let detail = format!(
                        "unknown field `{name}`: expected a comma-separated list of {}",
                        names(&Field::ALL).replace(' ', "")
                    );
                    return Err(AppError::BadRequest {
                        detail: detail.clone(),
                        errors: vec![FieldError::new("/fields", detail)],
                    });
                }
            }
        }
        Ok(Self(Some(fields)))
    }
}

#[cfg(test)]
mod tests {
    use super::is_json;

    #[test]
    fn json_content_types() {
        for yes in [
            "application/json",
            "application/json; charset=utf-8",
            "Application/JSON",
            "application/scene+json",
        ] {
            assert!(is_json(yes), "{yes}");
        }
        for no in ["text/plain", "application/x-www-form-urlencoded", "text/json", "", "application/jsonx"] {
            assert!(!is_json(no), "{no}");
        }
    }
}
