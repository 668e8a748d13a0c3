//! The `/assets` endpoints: upload a mesh file (OBJ or GLB), list, look up and delete the
//! uploaded meshes that scenes name with `"asset"`.

use axum::Json;
use axum::body::Bytes;
use axum::extract::{FromRequest, FromRequestParts, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

use super::AppState;
use super::extract::{body_bytes, content_type};
use super::problem::AppError;
use super::views::rfc3339;
use crate::assets::{MeshFormat, is_asset_id};
use crate::jobs::{AssetRecord, Uploaded};

/// `POST /assets`: reads and stores a mesh file. `201` with the asset and its `Location`; the
/// same bytes uploaded again are the same asset, answered `200` with the same body.
pub async fn upload(
    State(state): State<AppState>,
    MeshBody(format, bytes): MeshBody,
) -> Result<Response, AppError> {
    let (status, asset) = match state.jobs.upload_asset(bytes, format).await? {
        Uploaded::New(asset) => (StatusCode::CREATED, asset),
        Uploaded::Existing(asset) => (StatusCode::OK, asset),
    };
    let mut response = (status, Json(asset_view(&asset))).into_response();
    let location = HeaderValue::from_str(&format!("/assets/{}", asset.id)).expect("asset ids are URL-safe");
    response.headers_mut().insert(header::LOCATION, location);
    Ok(response)
}

/// `GET /assets`: every stored asset, newest first.
pub async fn list(State(state): State<AppState>) -> Result<Response, AppError> {
    let assets = state.jobs.list_assets().await?;
    let views: Vec<Value> = assets.iter().map(asset_view).collect();
    Ok(Json(json!({"assets": views})).into_response())
}

/// `GET /assets/{id}`: the asset's sizes and upload time.
pub async fn get(State(state): State<AppState>, AssetPath(id): AssetPath) -> Result<Response, AppError> {
    let asset = state.jobs.asset(&id).await?.ok_or(AppError::AssetNotFound { id })?;
    Ok(Json(asset_view(&asset)).into_response())
}

/// `DELETE /assets/{id}`: deletes the asset (`204`). Jobs already accepted with it still run.
pub async fn delete(State(state): State<AppState>, AssetPath(id): AssetPath) -> Result<Response, AppError> {
    if state.jobs.delete_asset(&id).await? {
        Ok(StatusCode::NO_CONTENT.into_response())
    } else {
        Err(AppError::AssetNotFound { id })
    }
}

/// An asset as the API shows it.
fn asset_view(asset: &AssetRecord) -> Value {
    json!({
        "id": asset.id,
        "vertices": asset.vertices,
        "triangles": asset.triangles,
        "bytes": asset.bytes,
        "created_at": rfc3339(asset.created_ms),
        "links": {"self": format!("/assets/{}", asset.id)},
    })
}

/// A mesh file from a body of a mesh media type.
pub struct MeshBody(pub MeshFormat, pub Bytes);

impl<S: Send + Sync> FromRequest<S> for MeshBody {
    type Rejection = AppError;

    async fn from_request(request: Request, state: &S) -> Result<Self, AppError> {
        let content_type = content_type(&request);
        let Some(format) = content_type.as_deref().and_then(MeshFormat::from_media_type) else {
            return Err(AppError::NotAMeshType { found: content_type });
        };
        Ok(Self(format, body_bytes(request, state).await?))
    }
}

/// An asset id from the path; anything but `sha256:` and 64 hex digits is an unknown asset.
pub struct AssetPath(pub String);

impl<S: Send + Sync> FromRequestParts<S> for AssetPath {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        let axum::extract::Path(raw) = axum::extract::Path::<String>::from_request_parts(parts, state)
            .await
            .map_err(|e| AppError::Internal(format!("asset route without an id: {e}")))?;
        if is_asset_id(&raw) { Ok(Self(raw)) } else { Err(AppError::AssetNotFound { id: raw }) }
    }
}
