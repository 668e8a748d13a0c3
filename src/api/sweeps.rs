//! The `/sweeps` endpoints: submit a sweep, list the sweeps, read a sweep's table (JSON or CSV)
//! and plot, cancel it. Any instance on the same store answers for any sweep.

use axum::Json;
use axum::extract::{RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use serde_json::{Value, json};

use super::AppState;
use super::extract::{IdempotencyKey, JsonBody, PageQuery, SweepPath};
use super::problem::AppError;
use super::views::rfc3339;
use crate::assets::has_references;
use crate::jobs::{Idempotency, JobId, Page, SweepState, SweepSummary, SweepTable, fingerprint};
use crate::scene::FieldError;

/// `POST /sweeps`: puts the meshes its base scene names by `"asset"` in place, checks the sweep
/// (pointers, values, variant count, every run's limits) and stores it, one entry whatever its
/// size, with its reference and every variant waiting to run; `202` with the sweep and its
/// `Location`. A repeated `Idempotency-Key` with the same document answers with the same sweep.
pub async fn submit(
    State(state): State<AppState>,
    IdempotencyKey(key): IdempotencyKey,
    JsonBody(mut document): JsonBody,
) -> Result<Response, AppError> {
    // The document as sent, before its meshes are put in, is what a repeat must match.
    let idempotency = key.map(|key| Idempotency { key, fingerprint: fingerprint(&document) });
    // The base scene's `"asset"` references are resolved once, so every variant holds the mesh.
    if let Some(scene) = document.get_mut("scene").filter(|scene| has_references(scene)) {
        state.jobs.resolve_assets(scene, "/scene").await?;
    }
    let submitted = state.jobs.submit_sweep(document, state.config.max_sweep_variants, idempotency).await?;
    let sweep = if submitted.repeated {
        state.jobs.sweep_state(submitted.summary).await?
    } else {
        state.jobs.queued_sweep_state(submitted.summary).await?
    };
    let id = sweep.summary.entry.id.clone();
    let mut response = (StatusCode::ACCEPTED, Json(sweep_view(&sweep))).into_response();
    let location = HeaderValue::from_str(&format!("/sweeps/{id}")).expect("sweep ids are URL-safe");
    response.headers_mut().insert(header::LOCATION, location);
    if submitted.repeated {
        response.headers_mut().insert("idempotent-replayed", HeaderValue::from_static("true"));
    }
    Ok(response)
}

/// `GET /sweeps`: the sweeps, newest first, `offset` and `limit` paged, each with its progress.
pub async fn list(State(state): State<AppState>, page: PageQuery) -> Result<Response, AppError> {
    let sweeps = state.jobs.list_sweeps(Page { offset: page.offset, limit: page.limit }).await?;
    let next = (sweeps.len() as u64 == page.limit)
        .then(|| format!("/sweeps?offset={}&limit={}", page.offset + page.limit, page.limit));
    let views: Vec<_> = sweeps.iter().map(summary_view).collect();
    Ok(Json(json!({"sweeps": views, "offset": page.offset, "limit": page.limit, "next": next}))
        .into_response())
}

/// `GET /sweeps/{id}`: the table as it stands, as JSON, or as CSV with `?format=csv` or
/// `Accept: text/csv`.
pub async fn get(
    State(state): State<AppState>,
    SweepPath(id): SweepPath,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let csv = wants_csv(query.as_deref(), &headers)?;
    let sweep = state_of(&state, &id).await?;
    if csv {
        let bytes = sweep.csv().map_err(|e| AppError::Internal(format!("CSV: {e}")))?;
        return Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], bytes).into_response());
    }
    Ok(Json(sweep_view(&sweep)).into_response())
}

/// `GET /sweeps/{id}/plot.svg`: error against wall time, log-log, one series per integrator.
pub async fn plot(State(state): State<AppState>, SweepPath(id): SweepPath) -> Result<Response, AppError> {
    let sweep = state_of(&state, &id).await?;
    let bytes = sweep.svg(&format!("sweep {id}")).map_err(|e| AppError::Internal(format!("SVG: {e}")))?;
    Ok(([(header::CONTENT_TYPE, "image/svg+xml")], bytes).into_response())
}

/// `DELETE /sweeps/{id}`: cancels the sweep: runs not started end at once, running ones stop;
/// `202` with the sweep.
pub async fn cancel(State(state): State<AppState>, SweepPath(id): SweepPath) -> Result<Response, AppError> {
    let summary =
        state.jobs.cancel_sweep(&id).await?.ok_or_else(|| AppError::SweepNotFound { id: id.to_string() })?;
    let sweep = state.jobs.sweep_state(summary).await?;
    Ok((StatusCode::ACCEPTED, Json(sweep_view(&sweep))).into_response())
}

/// The sweep with this id and its table as they stand.
pub(super) async fn state_of(state: &AppState, id: &JobId) -> Result<SweepState, AppError> {
    let summary =
        state.jobs.sweep(id).await?.ok_or_else(|| AppError::SweepNotFound { id: id.to_string() })?;
    Ok(state.jobs.sweep_state(summary).await?)
}

/// A sweep as the API shows it: the table, with what [`summary_view`] shows.
pub(super) fn sweep_view(sweep: &SweepState) -> SweepView<'_> {
    let mut summary = summary_view(&sweep.summary);
    summary["variants"] = sweep.variants.into();
    // The rows were read after the summary's counts: what they say is the more recent.
    summary["complete"] = sweep.table.is_complete().into();
    summary["progress"]["finished"] = sweep.finished.into();
    SweepView { table: &sweep.table, summary }
}

/// A sweep's table followed by its summary, in one JSON object written straight from the table.
#[derive(Serialize)]
pub(super) struct SweepView<'a> {
    #[serde(flatten)]
    table: &'a SweepTable,
    #[serde(flatten)]
    summary: Value,
}

/// A sweep without its table: id, progress, and links.
pub(super) fn summary_view(summary: &SweepSummary) -> Value {
    let entry = &summary.entry;
    let id = &entry.id;
    json!({
        "id": id.as_str(),
        "created_at": rfc3339(entry.created_ms),
        "variants": entry.runs - u32::from(entry.has_reference),
        "complete": summary.is_complete(),
        "cancel_requested": summary.cancel_requested,
        "progress": {"finished": summary.finished, "running": summary.running, "runs": entry.runs},
        "links": {
            "self": format!("/sweeps/{id}"),
            "csv": format!("/sweeps/{id}?format=csv"),
            "plot": format!("/sweeps/{id}/plot.svg"),
            "events": format!("/sweeps/{id}/events"),
        },
    })
}

/// Whether the table is wanted as CSV: `?format=csv`, or `Accept: text/csv` without `?format=`.
fn wants_csv(query: Option<&str>, headers: &HeaderMap) -> Result<bool, AppError> {
    let format = query
        .unwrap_or("")
        .split('&')
        .filter_map(|pair| pair.split_once('=').or(Some((pair, ""))))
        .find(|(key, _)| *key == "format")
        .map(|(_, value)| value);
    match format {
        Some("csv") => Ok(true),
        Some("json") => Ok(false),
        Some(other) => Err(AppError::BadRequest {
            detail: format!("format `{other}` is not offered for a sweep table: use `json` or `csv`"),
            errors: vec![FieldError::new("/format", "`json` or `csv`")],
        }),
        None => Ok(headers
            .get(header::ACCEPT)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|accept| accept.split(',').any(|t| t.trim().starts_with("text/csv")))),
    }
}
