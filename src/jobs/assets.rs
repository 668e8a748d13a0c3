//! Uploaded meshes: [`Jobs`]' door to the assets in the store, and the resolution of the
//! `"asset"` references of a scene at admission.
//!
//! An upload is read once (on a blocking thread: parsing is CPU work), checked against the
//! [`AssetLimits`], and stored in its compact form under the SHA-256 of its bytes, so the same
//! file is the same asset on every instance sharing the store. A scene submitted with
//! references gets the meshes put in place before its typed parse (see
//! [`assets`](crate::assets)), and the job stores that resolved document, not the references:
//! a job must run as it was accepted, after a restart, on another instance, and after its asset
//! was deleted or replaced, and a stored scene is dropped when its job ends anyway.

use serde_json::Value;
use thiserror::Error;

use super::now_ms;
use super::service::Jobs;
use super::store::{AssetRecord, AssetRoom, PutAsset, StoreError};
use crate::assets::{
    Mesh, MeshFormat, MeshLimits, MeshSource, ReadError, asset_id, put_mesh, referenced_assets,
};
use crate::scene::FieldError;

/// How large the assets may be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AssetLimits {
    /// The largest mesh a file may hold (vertices: the particle limit; triangles).
    pub mesh: MeshLimits,
    /// The largest upload, in bytes.
    pub max_bytes: u64,
    /// Assets the store may hold.
    pub max_assets: u64,
    /// Uploaded bytes the store may hold over all assets.
    pub max_total_bytes: u64,
}

impl Default for AssetLimits {
    fn default() -> Self {
        Self {
            mesh: MeshLimits { max_vertices: 100_000, max_triangles: 500_000 },
            max_bytes: 4 << 20,
            max_assets: 1000,
            max_total_bytes: 1 << 30,
        }
    }
}

/// What an upload did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Uploaded {
    /// The asset is new.
    New(AssetRecord),
    /// The same bytes were uploaded before; this is that asset.
    Existing(AssetRecord),
}

/// Why an upload was refused.
#[derive(Debug, Error)]
pub enum AssetError {
    /// The file is larger than `--max-asset-bytes`.
    #[error("the file has {bytes} bytes; this server takes at most {max} (--max-asset-bytes)")]
    TooLarge {
        /// Its size.
        bytes: u64,
        /// The limit.
        max: u64,
    },
    /// The file is not a mesh this server reads, or is over the mesh limits.
    #[error(transparent)]
    Unreadable(#[from] ReadError),
    /// The store holds as many assets, or bytes of them, as it may.
    #[error("{0}")]
    StoreFull(String),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Why a scene's references could not be resolved.
#[derive(Debug, Error)]
pub enum ResolveError {
    /// A reference is malformed, names no stored asset, or names a file; each is listed.
    #[error("the scene names meshes that cannot be used")]
    Invalid(Vec<FieldError>),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

impl Jobs {
    /// Reads, checks and stores an uploaded mesh file.
    pub async fn upload_asset(
        &self,
        bytes: bytes::Bytes,
        format: MeshFormat,
    ) -> Result<Uploaded, AssetError> {
        let limits = self.shared.config.assets;
        let size = bytes.len() as u64;
        if size > limits.max_bytes {
            return Err(AssetError::TooLarge { bytes: size, max: limits.max_bytes });
        }
        let store = &self.shared.store;
        let id = asset_id(&bytes);
        if let Some(existing) = store.asset(&id).await? {
            return Ok(Uploaded::Existing(existing));
        }
        let read = tokio::task::spawn_blocking(move || {
            crate::assets::read_mesh(&bytes, format, limits.mesh).map(|mesh| {
                let compact = mesh.to_compact();
                (mesh.vertex_count() as u64, mesh.triangle_count() as u64, compact)
            })
        })
        .await
        .map_err(|e| StoreError::Backend(format!("reading an upload failed: {e}")))?;
        let (vertices, triangles, compact) = read?;
        let record = AssetRecord { id, vertices, triangles, bytes: size, created_ms: now_ms() };
        let room = AssetRoom { max_assets: limits.max_assets, max_bytes: limits.max_total_bytes };
        match store.put_asset(&record, &compact, room).await? {
            PutAsset::Added => Ok(Uploaded::New(record)),
            PutAsset::Exists(existing) => Ok(Uploaded::Existing(existing)),
            PutAsset::Full { assets, .. } if assets >= limits.max_assets => {
                Err(AssetError::StoreFull(format!(
                    "the store holds {assets} assets, the most it may (--max-assets {}); delete some first",
                    limits.max_assets
                )))
            }
            PutAsset::Full { bytes, .. } => Err(AssetError::StoreFull(format!(
                "the store holds {bytes} bytes of assets; {size} more would pass --max-asset-storage {}; \
                 delete some first",
                limits.max_total_bytes
            ))),
        }
    }

    /// The asset with this id.
    pub async fn asset(&self, id: &str) -> Result<Option<AssetRecord>, StoreError> {
        self.shared.store.asset(id).await
    }

    /// The mesh of the asset with this id.
    pub async fn asset_mesh(&self, id: &str) -> Result<Option<Mesh>, StoreError> {
        let Some(compact) = self.shared.store.asset_mesh(id).await? else { return Ok(None) };
        let mesh = tokio::task::spawn_blocking(move || Mesh::from_compact(&compact))
            .await
            .map_err(|e| StoreError::Backend(format!("reading a stored mesh failed: {e}")))?
            .map_err(|e| StoreError::Backend(format!("asset {id}: {e}")))?;
        Ok(Some(mesh))
    }

    /// Every asset, newest first.
    pub async fn list_assets(&self) -> Result<Vec<AssetRecord>, StoreError> {
        self.shared.store.list_assets().await
    }

    /// Deletes an asset; returns whether there was one. Jobs accepted with it still run: they
    /// hold its mesh.
    pub async fn delete_asset(&self, id: &str) -> Result<bool, StoreError> {
        self.shared.store.delete_asset(id).await
    }

    /// Puts the mesh of every `asset` reference of `scene` (a scene, or a sweep's base scene
    /// under `prefix`) in its place. A reference to no stored asset, or a `file` (a server
    /// reads no paths), is an error at its field.
    pub async fn resolve_assets(&self, scene: &mut Value, prefix: &str) -> Result<(), ResolveError> {
        let references = referenced_assets(scene, prefix).map_err(ResolveError::Invalid)?;
        let mut errors = Vec::new();
        for reference in references {
            match &reference.source {
                MeshSource::File(_) => errors.push(FieldError::new(
                    &reference.pointer,
                    "the server reads no files: upload the mesh with POST /assets and name it with `asset`",
                )),
                MeshSource::Asset(id) => match self.asset_mesh(id).await? {
                    Some(mesh) => put_mesh(scene, &reference, &mesh),
                    None => errors.push(FieldError::new(
                        &reference.pointer,
                        format!("no asset {id} is stored: upload it with POST /assets"),
                    )),
                },
            }
        }
        if errors.is_empty() { Ok(()) } else { Err(ResolveError::Invalid(errors)) }
    }
}
