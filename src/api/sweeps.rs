//! The `/sweeps` endpoints: submit a sweep as jobs, read its table (JSON or CSV) and plot, cancel it.

use axum::Json;
use axum::extract::{RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

use super::AppState;
use super::extract::{JsonBody, SweepPath};
use super::problem::AppError;
use super::views::rfc3339;
use crate::assets::has_references;
use crate::jobs::{SweepRecord, SweepState};
use crate::scene::FieldError;

/// `POST /sweeps`: puts the meshes its base scene names by `"asset"` in place, checks the sweep (pointers, values, variant count, every run's limits) and
/// queues its reference and every variant as jobs; `202` with the sweep and its `Location`.
pub async fn submit(
    State(state): State<AppState>,
    JsonBody(mut document): JsonBody,
) -> Result<Response, AppError> {
    // The base scene's `"asset"` references are resolved once, so every variant holds the mesh.
    if let Some(scene) = document.get_mut("scene").filter(|scene| has_references(scene)) {
        state.jobs.resolve_assets(scene, "/scene").await?;
    }
    let record = state.sweeps.submit(&state.jobs, document, state.config.max_sweep_variants).await?;
    let sweep = state.sweeps.state(&state.jobs, &record).await?;
    let mut response = (StatusCode::ACCEPTED, Json(sweep_view(&record, &sweep))).into_response();
    let location = HeaderValue::from_str(&format!("/sweeps/{}", record.id)).expect("sweep ids are URL-safe");
    response.headers_mut().insert(header::LOCATION, location);
    Ok(response)
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
    let record = state.sweeps.get(&id).ok_or_else(|| AppError::SweepNotFound { id: id.to_string() })?;
    let sweep = state.sweeps.state(&state.jobs, &record).await?;
    if csv {
        let bytes = sweep.csv().map_err(|e| AppError::Internal(format!("CSV: {e}")))?;
        return Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], bytes).into_response());
    }
    Ok(Json(sweep_view(&record, &sweep)).into_response())
}

/// `GET /sweeps/{id}/plot.svg`: error against wall time, log-log, one series per integrator.
pub async fn plot(State(state): State<AppState>, SweepPath(id): SweepPath) -> Result<Response, AppError> {
    let record = state.sweeps.get(&id).ok_or_else(|| AppError::SweepNotFound { id: id.to_string() })?;
    let sweep = state.sweeps.state(&state.jobs, &record).await?;
    let bytes = sweep.svg(&format!("sweep {id}")).map_err(|e| AppError::Internal(format!("SVG: {e}")))?;
    Ok(([(header::CONTENT_TYPE, "image/svg+xml")], bytes).into_response())
}

/// `DELETE /sweeps/{id}`: cancels every job of the sweep not yet ended; `202` with the sweep.
pub async fn cancel(State(state): State<AppState>, SweepPath(id): SweepPath) -> Result<Response, AppError> {
    let record = state.sweeps.get(&id).ok_or_else(|| AppError::SweepNotFound { id: id.to_string() })?;
    state.sweeps.cancel(&state.jobs, &record).await?;
    let sweep = state.sweeps.state(&state.jobs, &record).await?;
    Ok((StatusCode::ACCEPTED, Json(sweep_view(&record, &sweep))).into_response())
}

/// A sweep as the API shows it: the table, with its id, jobs and progress.
fn sweep_view(record: &SweepRecord, sweep: &SweepState) -> Value {
    let id = &record.id;
    let mut view = sweep.table.to_json();
    view["id"] = id.as_str().into();
    view["created_at"] = rfc3339(record.created_ms).into();
    view["variants"] = record.variant_jobs.len().into();
    view["complete"] = sweep.table.is_complete().into();
    view["progress"] = json!({"finished": sweep.finished, "runs": sweep.runs});
    view["jobs"] = json!({
        "reference": record.reference_job.as_ref().map(|j| j.as_str()),
        "variants": record.variant_jobs.iter().map(|j| j.as_str()).collect::<Vec<_>>(),
    });
    view["links"] = json!({
        "self": format!("/sweeps/{id}"),
        "csv": format!("/sweeps/{id}?format=csv"),
        "plot": format!("/sweeps/{id}/plot.svg"),
    });
    view
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
