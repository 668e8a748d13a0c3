//! The `/jobs` endpoints: submit, list, look up, fetch the result of, and cancel jobs.

use axum::Json;
use axum::extract::State;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::AppState;
use super::extract::{
    FieldsChoice, FormatChoice, IdempotencyKey, JobPath, PageQuery, SceneBody, names, selection_problems,
};
use super::problem::AppError;
use super::views::job_view;
use crate::jobs::{Cancelled, JobRecord, Page, StoredResult, Submission, TranscodeError, transcode};
use crate::output::Format;
use crate::scene::{Field, FieldError};

/// `POST /jobs`: queues a scene; `202` with the job and its `Location`. A repeated
/// `Idempotency-Key` with the same body answers with the same job. `?format=` sets the format
/// the result is stored in (default: the scene's `output.format`).
pub async fn submit(
    State(state): State<AppState>,
    IdempotencyKey(key): IdempotencyKey,
    FormatChoice(format): FormatChoice<false>,
    body: SceneBody,
) -> Result<Response, AppError> {
    let body = body.with_format(format)?;
    let submitted = state
        .jobs
        .submit(Submission {
            scene: body.scene,
            document: body.document,
            fingerprint: body.fingerprint,
            idempotency_key: key,
            max_work: None,
        })
        .await?;
    let job = if submitted.repeated {
        state.jobs.get(&submitted.job.id).await?.unwrap_or(submitted.job)
    } else {
        submitted.job
    };
    let mut response = (StatusCode::ACCEPTED, Json(job_view(&job))).into_response();
    let location = HeaderValue::from_str(&format!("/jobs/{}", job.id)).expect("job ids are URL-safe");
    response.headers_mut().insert(header::LOCATION, location);
    if submitted.repeated {
        response.headers_mut().insert("idempotent-replayed", HeaderValue::from_static("true"));
    }
    Ok(response)
}

/// `GET /jobs`: recent jobs, newest first, `offset` and `limit` paged.
pub async fn list(State(state): State<AppState>, page: PageQuery) -> Result<Response, AppError> {
    let jobs = state.jobs.list(Page { offset: page.offset, limit: page.limit }).await?;
    let next = (jobs.len() as u64 == page.limit)
        .then(|| format!("/jobs?offset={}&limit={}", page.offset + page.limit, page.limit));
    let views: Vec<_> = jobs.iter().map(job_view).collect();
    Ok(Json(json!({"jobs": views, "offset": page.offset, "limit": page.limit, "next": next})).into_response())
}

/// `GET /jobs/{id}`: the job's status, progress and, once ended, its stats.
pub async fn get(State(state): State<AppState>, JobPath(id): JobPath) -> Result<Response, AppError> {
    let job = state.jobs.get(&id).await?.ok_or_else(|| AppError::JobNotFound { id: id.to_string() })?;
    Ok(Json(job_view(&job)).into_response())
}

/// `GET /jobs/{id}/result`: the result of an ended job, in the format asked for (`?format=`,
/// `Accept`), else the one it was stored in, with the fields asked for (`?fields=`), else every
/// recorded field the format carries. A result stored as JSON (the default) is made into any
/// other format on request, leaving out the fields the format cannot carry and naming them in
/// `Drape-Omitted-Fields`; one stored in a binary format is served only as that, and asking for
/// another (or for fields) is a `406` that says which it is. A field asked for by name that the
/// run did not record, or that the format cannot carry, is a `422` at `/fields`.
pub async fn result(
    State(state): State<AppState>,
    JobPath(id): JobPath,
    FormatChoice(format): FormatChoice<true>,
    FieldsChoice(fields): FieldsChoice,
) -> Result<Response, AppError> {
    let job = state.jobs.get(&id).await?.ok_or_else(|| AppError::JobNotFound { id: id.to_string() })?;
    let result = match state.jobs.result(&id).await? {
        Some(result) if job.status.is_final() => result,
        _ => return Err(AppError::NoResult { id: job.id, status: job.status, message: job.message }),
    };
    if format.is_none() && fields.is_none() {
        return Ok(result_response(&job, result, &[]));
    }
    let stored = result.media_type;
    let wanted = format.or_else(|| Format::from_media_type(stored)).unwrap_or(Format::Json);
    let explicit = fields.is_some();
    let transcoded = tokio::task::spawn_blocking(move || transcode(result, format, fields.as_deref()))
        .await
        .map_err(|e| AppError::Internal(format!("transcoding job {id} failed: {e}")))?;
    match transcoded {
        Ok(served) => Ok(result_response(&job, served.result, &served.omitted)),
        Err(TranscodeError::NotCanonical { .. }) if format.is_none() || stored == wanted.media_type() => {
            Err(AppError::NotAcceptable {
                detail: format!(
                    "job {id}'s result is stored as {stored}, from which no fields are selected; to select \
                     them, keep the default json (or submit with ?format=json) and fetch with ?fields="
                ),
            })
        }
        Err(TranscodeError::NotCanonical { .. }) => Err(AppError::NotAcceptable {
            detail: format!(
                "job {id}'s result is stored as {stored}, from which no other format is made; to get {} ({}), \
                 submit the scene with ?format={} or output.format `{}`, or keep the default json",
                wanted.name(),
                wanted.media_type(),
                wanted.name(),
                wanted.name()
            ),
        }),
        Err(TranscodeError::NotRecorded { field }) => Err(AppError::NotRecorded(vec![FieldError::new(
            "/fields",
            format!("job {id} did not record {}", field.name()),
        )])),
        Err(TranscodeError::CannotCarry { format, errors }) if explicit => {
            Err(AppError::CannotCarry { format: format.name(), errors: selection_problems(errors) })
        }
        Err(TranscodeError::CannotCarry { format, errors }) => {
            Err(AppError::CannotCarry { format: format.name(), errors })
        }
        Err(TranscodeError::Broken(message)) => Err(AppError::Internal(message)),
    }
}

/// A stored result as a response; the one place that turns a result into HTTP. `omitted` are
/// the recorded fields its format could not carry, named in `Drape-Omitted-Fields`.
pub fn result_response(job: &JobRecord, result: StoredResult, omitted: &[Field]) -> Response {
    let mut response = ([(header::CONTENT_TYPE, result.media_type)], result.bytes).into_response();
    let headers = response.headers_mut();
    headers.insert("drape-job-id", HeaderValue::from_str(job.id.as_str()).expect("job ids are header-safe"));
    headers.insert("drape-job-status", HeaderValue::from_static(job.status.name()));
    if !omitted.is_empty() {
        let names = HeaderValue::from_str(&names(omitted)).expect("field names are header-safe");
        headers.insert("drape-omitted-fields", names);
    }
    response
}

/// `DELETE /jobs/{id}`: cancels a job. A queued job is dropped (`200`, status `cancelled`); a
/// running one stops within a step or a solver iteration (`202`); an ended one is a `409`.
pub async fn cancel(State(state): State<AppState>, JobPath(id): JobPath) -> Result<Response, AppError> {
    match state.jobs.cancel(&id).await? {
        None => Err(AppError::JobNotFound { id: id.to_string() }),
        Some(Cancelled::Dropped(job)) => Ok((StatusCode::OK, Json(job_view(&job))).into_response()),
        Some(Cancelled::Stopping(job)) => Ok((StatusCode::ACCEPTED, Json(job_view(&job))).into_response()),
        Some(Cancelled::AlreadyEnded(job)) => Err(AppError::AlreadyEnded { id: job.id, status: job.status }),
    }
}
