//! Every error the API answers with, as an RFC 9457 `application/problem+json` body.
//!
//! Handlers, extractors and layers all fail with [`AppError`], so a malformed body, an unknown
//! route and a full queue look alike to a client: `type`, `title`, `status`, `detail`, and for
//! problems with the request's content, `errors: [{pointer, detail}]` with a JSON Pointer to
//! each field at fault. A 500 logs its cause and tells the client nothing more.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::access::Refusal;
use crate::assets::ReadError;
use crate::jobs::{
    AssetError, JobId, JobStatus, ResolveError, StoreError, SubmitError, SweepDocumentError, SweepSubmitError,
};
use crate::scene::{FieldError, SceneError};

/// The media type of a problem body.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// An error answered to a client.
#[derive(Debug)]
pub enum AppError {
    /// 400: the body is not JSON.
    MalformedJson {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser expected.
        message: String,
    },
    /// 400: a query parameter or header is invalid; the pointer names it (`/limit`).
    BadRequest {
        /// What is wrong.
        detail: String,
        /// The parameters at fault.
        errors: Vec<FieldError>,
    },
    /// 401: tokens are required and the request carries none this server accepts.
    Unauthorized {
        /// What was wrong with the request's `Authorization`.
        reason: Refusal,
    },
    /// 404: no route has this path.
    NoRoute {
        /// The path asked for.
        path: String,
    },
    /// 404: no job has this id.
    JobNotFound {
        /// The id asked for.
        id: String,
    },
    /// 404: no sweep has this id.
    SweepNotFound {
        /// The id asked for.
        id: String,
    },
    /// 405: the route exists but not with this method.
    MethodNotAllowed {
        /// The method used.
        method: String,
        /// The path asked for.
        path: String,
    },
    /// 406: the result cannot be produced in any media type the client accepts.
    NotAcceptable {
        /// What was asked and what is available.
        detail: String,
    },
    /// 408: the request took longer than the server's request timeout.
    Timeout,
    /// 409: the job has no result to serve (yet, or ever).
    NoResult {
        /// The job.
        id: JobId,
        /// Its status.
        status: JobStatus,
        /// Why it failed or was cancelled.
        message: Option<String>,
    },
    /// 409: the job has already ended and cannot be cancelled.
    AlreadyEnded {
        /// The job.
        id: JobId,
        /// How it ended.
        status: JobStatus,
    },
    /// 409: the job run by `POST /simulate` was cancelled before it finished.
    JobCancelled {
        /// The job.
        id: JobId,
        /// Why.
        message: Option<String>,
    },
    /// 413: the request body is larger than the server accepts.
    BodyTooLarge,
    /// 413: the run is too large for `POST /simulate`; `POST /jobs` takes it.
    OverBudget {
        /// Element-steps of the run.
        work: u64,
        /// The budget of `POST /simulate`.
        budget: u64,
        /// The field of the stage that costs the most, with why.
        errors: Vec<FieldError>,
    },
    /// 414: the request target is longer than the server reads.
    UriTooLong {
        /// Its length, in bytes.
        length: usize,
        /// The longest accepted.
        limit: usize,
    },
    /// 415: the body is compressed in an encoding the server cannot read.
    UnsupportedEncoding {
        /// The `Content-Encoding` sent.
        found: String,
    },
    /// 415: the body is not declared as JSON.
    UnsupportedMediaType {
        /// The `Content-Type` sent, if any.
        found: Option<String>,
    },
    /// 421: the request is addressed to a host name this server does not answer to.
    HostNotAllowed {
        /// The `Host` sent, if any.
        host: Option<String>,
    },
    /// 422: the document is JSON but not a valid scene.
    InvalidScene(Vec<FieldError>),
    /// 422: the result cannot be given in the format asked for: the run recorded something the
    /// format cannot carry (named by the scene's `output` field).
    CannotCarry {
        /// The format asked for.
        format: &'static str,
        /// What it cannot carry.
        errors: Vec<FieldError>,
    },
    /// 422: a field selected by name (`?fields=`) is not one the run records.
    NotRecorded(Vec<FieldError>),
    /// 422: the scene is valid but larger than this server's limits.
    OverLimit(Vec<FieldError>),
    /// 422: the sweep document is invalid, makes too many variants, or a run exceeds this
    /// server's limits; each problem is at a pointer into the sweep document.
    InvalidSweep(Vec<FieldError>),
    /// 422: the `Idempotency-Key` was already used with a different body.
    KeyReused {
        /// The key.
        key: String,
        /// What holds it: `job <id>` or `sweep <id>`.
        holder: String,
    },
    /// 429: the job queue is full; try again after `Retry-After` seconds.
    QueueFull {
        /// Seconds to wait.
        retry_after: u64,
    },
    /// 431: the request's header section is larger than the server reads.
    HeadersTooLarge {
        /// What is too large.
        detail: String,
    },
    /// 503: the server is shutting down.
    ShuttingDown,
    /// 503: the server is handling as many requests as it can.
    Overloaded,
    /// 422: the run took longer than the job wall-time limit; the scene asks too much of this
    /// server.
    TooSlow {
        /// The job.
        id: JobId,
        /// What happened.
        message: String,
    },
    /// 500: the job failed for a reason other than its wall time (a panic); the message says which.
    JobFailed {
        /// The job.
        id: JobId,
        /// What happened.
        message: String,
    },
    /// 404: no asset has this id.
    AssetNotFound {
        /// The id asked for.
        id: String,
    },
    /// 413: the mesh file is larger than an upload may be, or the store holds as many assets
    /// as it may; the detail names the limit.
    AssetOverLimit {
        /// Which limit, and by how much.
        detail: String,
    },
    /// 415: the body of `POST /assets` is not of a mesh media type.
    NotAMeshType {
        /// The `Content-Type` sent, if any.
        found: Option<String>,
    },
    /// 422: the uploaded file is not a mesh this server reads; the reason names the OBJ line or
    /// the GLB accessor (or chunk).
    InvalidMesh(ReadError),
    /// 500: something broke on the server; the cause is logged, not sent.
    Internal(String),
}

impl AppError {
    /// The HTTP status of the error.
    pub fn status(&self) -> StatusCode {
        match self {
            Self::MalformedJson { .. } | Self::BadRequest { .. } => StatusCode::BAD_REQUEST,
            Self::Unauthorized { .. } => StatusCode::UNAUTHORIZED,
            Self::UriTooLong { .. } => StatusCode::URI_TOO_LONG,
            Self::UnsupportedEncoding { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            Self::HostNotAllowed { .. } => StatusCode::MISDIRECTED_REQUEST,
            Self::HeadersTooLarge { .. } => StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            Self::NoRoute { .. }
            | Self::JobNotFound { .. }
            | Self::SweepNotFound { .. }
            | Self::AssetNotFound { .. } => StatusCode::NOT_FOUND,
            Self::MethodNotAllowed { .. } => StatusCode::METHOD_NOT_ALLOWED,
            Self::NotAcceptable { .. } => StatusCode::NOT_ACCEPTABLE,
            Self::Timeout => StatusCode::REQUEST_TIMEOUT,
            Self::NoResult { .. } | Self::AlreadyEnded { .. } | Self::JobCancelled { .. } => {
                StatusCode::CONFLICT
            }
            Self::BodyTooLarge | Self::OverBudget { .. } | Self::AssetOverLimit { .. } => {
                StatusCode::PAYLOAD_TOO_LARGE
            }
            Self::UnsupportedMediaType { .. } | Self::NotAMeshType { .. } => {
                StatusCode::UNSUPPORTED_MEDIA_TYPE
            }
            Self::InvalidMesh(_)
            | Self::InvalidScene(_)
            | Self::CannotCarry { .. }
            | Self::NotRecorded(_)
            | Self::InvalidSweep(_)
            | Self::OverLimit(_)
            | Self::KeyReused { .. }
            | Self::TooSlow { .. } => StatusCode::UNPROCESSABLE_ENTITY,
            Self::QueueFull { .. } => StatusCode::TOO_MANY_REQUESTS,
            Self::ShuttingDown | Self::Overloaded => StatusCode::SERVICE_UNAVAILABLE,
            Self::JobFailed { .. } | Self::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The `type` slug, `title` and `detail` of the problem.
    fn describe(&self) -> (&'static str, &'static str, String) {
        match self {
            Self::MalformedJson { line, column, message } => (
                "malformed-json",
                "The body is not valid JSON",
                format!("line {line}, column {column}: {message}"),
            ),
            Self::BadRequest { detail, .. } => ("bad-request", "The request is invalid", detail.clone()),
            Self::Unauthorized { reason } => (
                "unauthorized",
                "A bearer token is required",
                match reason {
                    Refusal::NoToken => "send `Authorization: Bearer <token>` with a token this server accepts (--auth-token)",
                    Refusal::NotBearer => "the Authorization header must be `Bearer <token>`",
                    Refusal::UnknownToken => "the bearer token is not one this server accepts",
                }
                .into(),
            ),
            Self::UriTooLong { length, limit } => (
                "uri-too-long",
                "The request target is too long",
                format!("the path and query are {length} bytes long, over the {limit} this server reads"),
            ),
            Self::UnsupportedEncoding { found } => (
                "unsupported-content-encoding",
                "The body's encoding is not supported",
                format!("Content-Encoding is `{found}`; send the body as it is or as `gzip`"),
            ),
            Self::HostNotAllowed { host } => (
                "host-not-allowed",
                "The request is addressed to another host",
                match host {
                    Some(host) => format!("this server does not answer to the Host `{host}` (--allowed-hosts)"),
                    None => "the request names no Host, and this server answers only to the names of --allowed-hosts".into(),
                },
            ),
            Self::HeadersTooLarge { detail } => {
                ("header-fields-too-large", "The request's header fields are too large", detail.clone())
            }
            Self::NoRoute { path } => {
                ("not-found", "No such resource", format!("nothing is served at {path}"))
            }
            Self::JobNotFound { id } => {
                ("job-not-found", "No such job", format!("there is no job with id `{id}`"))
            }
            Self::SweepNotFound { id } => {
                ("sweep-not-found", "No such sweep", format!("there is no sweep with id `{id}`"))
            }
            Self::MethodNotAllowed { method, path } => (
                "method-not-allowed",
                "Method not allowed",
                format!("{path} does not accept {method}; see /openapi.json for its methods"),
            ),
            Self::NotAcceptable { detail } => ("not-acceptable", "Not acceptable", detail.clone()),
            Self::Timeout => {
                ("timeout", "Request timed out", "the request took longer than the server allows".into())
            }
            Self::NoResult { id, status, message } => (
                "no-result",
                "The job has no result",
                match (status.is_final(), message) {
                    (false, _) => format!(
                        "job {id} is {}; follow /jobs/{id}/events or poll /jobs/{id} until it ends",
                        status.name()
                    ),
                    (true, Some(m)) => format!("job {id} ended {} without a result: {m}", status.name()),
                    (true, None) => format!("job {id} ended {} without a result", status.name()),
                },
            ),
            Self::AlreadyEnded { id, status } => (
                "already-ended",
                "The job has already ended",
                format!("job {id} already ended {}", status.name()),
            ),
            Self::JobCancelled { id, message } => (
                "job-cancelled",
                "The job was cancelled",
                format!("job {id} was cancelled: {}", message.as_deref().unwrap_or("no reason given")),
            ),
            Self::BodyTooLarge => (
                "body-too-large",
                "The body is too large",
                "the request body exceeds the server's limit (--body-limit)".into(),
            ),
            Self::OverBudget { work, budget, .. } => (
                "over-simulate-budget",
                "Too large to run synchronously",
                format!(
                    "the run needs {work} element-steps of work (particles, springs, collider tests, self-collision pairs and wind triangles, each per step, error-estimate companions included), over the {budget} that POST /simulate \
                     runs while you wait; submit it to POST /jobs instead and fetch /jobs/{{id}}/result"
                ),
            ),
            Self::UnsupportedMediaType { found } => (
                "unsupported-media-type",
                "The body must be JSON",
                match found {
                    Some(t) => format!("Content-Type is `{t}`; send the scene as `application/json`"),
                    None => "no Content-Type header; send the scene as `application/json`".into(),
                },
            ),
            Self::InvalidScene(errors) => ("invalid-scene", "The scene is invalid", summary(errors)),
            Self::CannotCarry { format, errors } => (
                "format-cannot-carry",
                "The format cannot carry this result",
                format!("{format} cannot carry what the run recorded: {}", summary(errors)),
            ),
            Self::NotRecorded(errors) => {
                ("field-not-recorded", "The run does not record this field", summary(errors))
            }
            Self::InvalidSweep(errors) => ("invalid-sweep", "The sweep cannot run", summary(errors)),
            Self::OverLimit(errors) => (
                "over-limit",
                "The scene exceeds this server's limits",
                errors.iter().map(|e| e.detail.as_str()).collect::<Vec<_>>().join("; "),
            ),
            Self::KeyReused { key, holder } => (
                "idempotency-key-reused",
                "Idempotency-Key reused with a different body",
                format!(
                    "the Idempotency-Key `{key}` was first used for {holder} with a different body; use a new key"
                ),
            ),
            Self::QueueFull { retry_after } => (
                "queue-full",
                "The job queue is full",
                format!("every place in the queue is taken; retry in {retry_after} s"),
            ),
            Self::ShuttingDown => (
                "shutting-down",
                "The server is shutting down",
                "the server takes no new jobs while it stops".into(),
            ),
            Self::Overloaded => {
                ("overloaded", "The server is overloaded", "too many requests at once; retry shortly".into())
            }
            Self::TooSlow { id, message } => (
                "wall-time-exceeded",
                "The run exceeded the wall-time limit",
                format!(
                    "job {id} failed: {message}; shorten the run (duration, resolution) or ask for a larger --job-wall-time"
                ),
            ),
            Self::JobFailed { id, message } => {
                ("job-failed", "The job failed", format!("job {id} failed: {message}"))
            }
            Self::AssetNotFound { id } => {
                ("asset-not-found", "No such asset", format!("there is no asset with id `{id}`"))
            }
            Self::AssetOverLimit { detail } => {
                ("asset-over-limit", "The asset exceeds this server's limits", detail.clone())
            }
            Self::NotAMeshType { found } => (
                "unsupported-media-type",
                "The body must be a mesh file",
                format!(
                    "Content-Type is {}; send an OBJ as `model/obj` (or `text/plain`) or a GLB as `model/gltf-binary`",
                    found.as_deref().map_or("missing".into(), |t| format!("`{t}`"))
                ),
            ),
            Self::InvalidMesh(e) => ("invalid-mesh", "The file is not a mesh this server reads", e.to_string()),
            Self::Internal(_) => {
                ("internal", "Internal server error", "the server failed; the cause is logged".into())
            }
        }
    }

    fn errors(&self) -> Option<&[FieldError]> {
        match self {
            Self::InvalidScene(errors)
            | Self::CannotCarry { errors, .. }
            | Self::NotRecorded(errors)
            | Self::InvalidSweep(errors)
            | Self::OverLimit(errors)
            | Self::OverBudget { errors, .. }
            | Self::BadRequest { errors, .. } => Some(errors),
            _ => None,
        }
    }

    /// A problem for a bare status from a layer that answered without a body.
    pub fn for_status(status: StatusCode, method: &str, path: &str) -> Self {
        match status {
            StatusCode::NOT_FOUND => Self::NoRoute { path: path.into() },
            StatusCode::METHOD_NOT_ALLOWED => {
                Self::MethodNotAllowed { method: method.into(), path: path.into() }
            }
            StatusCode::PAYLOAD_TOO_LARGE => Self::BodyTooLarge,
            StatusCode::REQUEST_TIMEOUT => Self::Timeout,
            StatusCode::SERVICE_UNAVAILABLE => Self::Overloaded,
            StatusCode::UNSUPPORTED_MEDIA_TYPE => Self::UnsupportedMediaType { found: None },
            s if s.is_server_error() => Self::Internal(format!("a layer answered {s}")),
            s => Self::BadRequest {
                detail: s.canonical_reason().unwrap_or("bad request").into(),
                errors: vec![],
            },
        }
    }
}

impl IntoResponse for AppError {
    fn into_response(self) -> Response {
        let status = self.status();
        if let Self::Internal(cause) = &self {
            tracing::error!(%cause, "internal error");
        }
        let (slug, title, detail) = self.describe();
        let detail = detail.as_str();
        let mut body = json!({
            "type": format!("/problems/{slug}"),
            "title": title,
            "status": status.as_u16(),
            "detail": detail,
        });
        if let Some(errors) = self.errors() {
            body["errors"] =
                errors.iter().map(|e| json!({"pointer": e.pointer, "detail": e.detail})).collect();
        } else if let Self::MalformedJson { .. } = self {
            // The whole document is at fault.
            body["errors"] = json!([{"pointer": "", "detail": detail}]);
        }
        match &self {
            Self::InvalidMesh(ReadError::Obj(e)) => body["line"] = e.line.into(),
            Self::InvalidMesh(ReadError::Glb(e)) => body["at"] = e.place.to_string().into(),
            _ => {}
        }
        let mut response = (status, [(header::CONTENT_TYPE, PROBLEM_JSON)], body.to_string()).into_response();
        match self {
            Self::QueueFull { retry_after } => {
                response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(retry_after));
            }
            Self::Unauthorized { reason } => {
                let challenge = match reason {
                    Refusal::NoToken => "Bearer",
                    Refusal::NotBearer => "Bearer error=\"invalid_request\"",
                    Refusal::UnknownToken => "Bearer error=\"invalid_token\"",
                };
                response.headers_mut().insert(header::WWW_AUTHENTICATE, HeaderValue::from_static(challenge));
            }
            _ => {}
        }
        response
    }
}

impl From<SceneError> for AppError {
    fn from(e: SceneError) -> Self {
        match e {
            SceneError::Syntax { line, column, message } => Self::MalformedJson { line, column, message },
            SceneError::Invalid(errors) => Self::InvalidScene(errors),
        }
    }
}

impl From<StoreError> for AppError {
    fn from(e: StoreError) -> Self {
        match e {
            StoreError::NotFound(id) => Self::JobNotFound { id: id.to_string() },
            StoreError::Backend(cause) => Self::Internal(cause),
        }
    }
}

impl From<SubmitError> for AppError {
    fn from(e: SubmitError) -> Self {
        match e {
            SubmitError::OverLimit(errors) => Self::OverLimit(errors),
            SubmitError::OverBudget { work, budget, pointer, stage, stage_work } => Self::OverBudget {
                work,
                budget,
                errors: vec![FieldError::new(
                    pointer,
                    format!("{stage} costs {stage_work} of the run's {work} element-steps"),
                )],
            },
            SubmitError::KeyReused { key, job } => Self::KeyReused { key, holder: format!("job {job}") },
            SubmitError::QueueFull => Self::QueueFull { retry_after: 1 },
            SubmitError::ShuttingDown => Self::ShuttingDown,
            SubmitError::Store(e) => e.into(),
        }
    }
}

impl From<AssetError> for AppError {
    fn from(e: AssetError) -> Self {
        match e {
            e @ (AssetError::TooLarge { .. } | AssetError::StoreFull(_)) => {
                Self::AssetOverLimit { detail: e.to_string() }
            }
            AssetError::Unreadable(e) => Self::InvalidMesh(e),
            AssetError::Store(e) => e.into(),
        }
    }
}

impl From<ResolveError> for AppError {
    fn from(e: ResolveError) -> Self {
        match e {
            ResolveError::Invalid(errors) => Self::InvalidScene(errors),
            ResolveError::Store(e) => e.into(),
        }
    }
}

/// The first few field problems in one line.
fn summary(errors: &[FieldError]) -> String {
    const SHOWN: usize = 3;
    let mut text = errors.iter().take(SHOWN).map(ToString::to_string).collect::<Vec<_>>().join("; ");
    if errors.len() > SHOWN {
        text.push_str(&format!("; and {} more (see `errors`)", errors.len() - SHOWN));
    }
    text
}

impl From<SweepSubmitError> for AppError {
    fn from(e: SweepSubmitError) -> Self {
        match e {
            SweepSubmitError::Invalid(SweepDocumentError::Syntax { line, column, message }) => {
                Self::MalformedJson { line, column, message }
            }
            SweepSubmitError::Invalid(SweepDocumentError::Invalid(errors)) => Self::InvalidSweep(errors),
            SweepSubmitError::Invalid(e @ SweepDocumentError::TooManyVariants { .. }) => {
                Self::InvalidSweep(vec![FieldError::new("/vary", format!("{e} (--max-sweep-variants)"))])
            }
            SweepSubmitError::OverLimit(errors) => Self::InvalidSweep(errors),
            SweepSubmitError::KeyReused { key, sweep } => {
                Self::KeyReused { key, holder: format!("sweep {sweep}") }
            }
            SweepSubmitError::Submit(e) => e.into(),
            SweepSubmitError::Store(e) => e.into(),
        }
    }
}
