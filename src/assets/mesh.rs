//! A mesh read from a file, the limits a reader keeps to, and the compact form a mesh is
//! stored in.

use std::io::{Read, Write};

use flate2::Compression;
use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;
use sha2::{Digest, Sha256};
use thiserror::Error;

use super::glb::{GlbError, read_glb};
use super::obj::{ObjError, read_obj};

/// A triangle mesh: what a scene's `vertices` and `triangles` hold.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Flat vertex coordinates `[x0, y0, z0, x1, ...]`.
    pub vertices: Vec<f64>,
    /// Flat vertex indices, three per triangle.
    pub triangles: Vec<u32>,
}

/// The largest mesh a reader returns; a file over either is refused before its arrays are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshLimits {
    /// Vertices (a mesh body's particles), after unused ones are dropped.
    pub max_vertices: u64,
    /// Triangles, after polygons are split.
    pub max_triangles: u64,
}

/// The file formats a mesh is read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ text.
    Obj,
    /// glTF 2.0 binary.
    Glb,
}

impl MeshFormat {
    /// The format of a body's media type (`model/obj`, `text/plain`, `model/gltf-binary`),
    /// parameters ignored.
    pub fn from_media_type(media_type: &str) -> Option<Self> {
        let essence = media_type.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
        match essence.as_str() {
            "model/obj" | "text/plain" => Some(Self::Obj),
            "model/gltf-binary" => Some(Self::Glb),
            _ => None,
        }
    }

    /// The format of a file by its extension (`.obj` or `.glb`, any case).
    pub fn from_path(path: &std::path::Path) -> Option<Self> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "obj" => Some(Self::Obj),
            "glb" => Some(Self::Glb),
            _ => None,
        }
    }
}

/// Why a mesh file could not be read.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum ReadError {
    /// A bad OBJ file.
    #[error(transparent)]
    Obj(#[from] ObjError),
    /// A bad GLB file.
    #[error(transparent)]
    Glb(#[from] GlbError),
}

/// Reads a mesh file of `format`, within `limits`.
pub fn read_mesh(bytes: &[u8], format: MeshFormat, limits: MeshLimits) -> Result<Mesh, ReadError> {
    Ok(match format {
        MeshFormat::Obj => read_obj(bytes, limits)?,
        MeshFormat::Glb => read_glb(bytes, limits)?,
    })
}

/// The content address of a file's bytes: `sha256:` and the SHA-256 digest in lowercase hex.
pub fn asset_id(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    let mut id = String::with_capacity(7 + 64);
    id.push_str("sha256:");
    for byte in digest {
        id.push_str(&format!("{byte:02x}"));
    }
    id
}

/// A stored mesh that does not decode.
#[derive(Debug, Error, PartialEq, Eq)]
#[error("a stored mesh is damaged: {0}")]
pub struct CompactError(String);

/// Bytes of the compact form's header: the vertex and triangle counts, `u32` little-endian.
const HEADER: usize = 8;

impl Mesh {
    /// Vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices.len() / 3
    }

    /// Triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len() / 3
    }

    /// Drops the vertices no triangle uses and renumbers the rest, keeping their order: a mesh
    /// body gives every vertex a mass from the triangles around it, so an unused one has none.
    pub(super) fn without_unused_vertices(mut self) -> Self {
        let count = self.vertex_count();
        let mut new_index = vec![u32::MAX; count];
        for &v in &self.triangles {
            new_index[v as usize] = 0;
        }
        if new_index.iter().all(|&n| n == 0) {
            return self;
        }
        let mut kept = 0u32;
        for (v, slot) in new_index.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = kept;
                self.vertices.copy_within(3 * v..3 * v + 3, 3 * kept as usize);
                kept += 1;
            }
        }
        self.vertices.truncate(3 * kept as usize);
        for v in &mut self.triangles {
            *v = new_index[*v as usize];
        }
        self
    }

    /// The compact form: the counts, the coordinates as `f64` and the indices as `u32`, all
    /// little-endian, deflated.
    pub fn to_compact(&self) -> Vec<u8> {
        let raw_len = HEADER + 8 * self.vertices.len() + 4 * self.triangles.len();
        let mut encoder = DeflateEncoder::new(Vec::with_capacity(raw_len / 3), Compression::fast());
        let mut raw = Vec::with_capacity(raw_len);
        raw.extend_from_slice(&(self.vertex_count() as u32).to_le_bytes());
        raw.extend_from_slice(&(self.triangle_count() as u32).to_le_bytes());
        for x in &self.vertices {
            raw.extend_from_slice(&x.to_le_bytes());
        }
        for i in &self.triangles {
            raw.extend_from_slice(&i.to_le_bytes());
        }
        // Writing into a `Vec` cannot fail.
        encoder.write_all(&raw).expect("deflating into memory");
        encoder.finish().expect("deflating into memory")
    }

    /// Reads the compact form back, checking its sizes and indices.
    pub fn from_compact(bytes: &[u8]) -> Result<Self, CompactError> {
        let mut header = [0u8; HEADER];
        let mut decoder = DeflateDecoder::new(bytes);
        decoder.read_exact(&mut header).map_err(|e| CompactError(e.to_string()))?;
        let vertices = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
        let triangles = u32::from_le_bytes([header[4], header[5], header[6], header[7]]) as usize;
        let body_len = 24 * vertices + 12 * triangles;
        let mut body = Vec::new();
        decoder.take(body_len as u64 + 1).read_to_end(&mut body).map_err(|e| CompactError(e.to_string()))?;
        if body.len() != body_len {
            return Err(CompactError(format!(
                "{} bytes for {vertices} vertices and {triangles} triangles",
                body.len()
            )));
        }
        let (coordinates, indices) = body.split_at(24 * vertices);
        let vertices: Vec<f64> = coordinates
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect();
        let triangles: Vec<u32> =
            indices.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        if let Some(bad) = triangles.iter().find(|&&i| i as usize >= vertices.len() / 3) {
            return Err(CompactError(format!("index {bad} past the vertices")));
        }
        Ok(Self { vertices, triangles })
    }
}
