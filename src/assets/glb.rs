//! The glTF 2.0 binary (GLB) reader: the triangles of every mesh primitive of every node, placed
//! by the node's transform in the scene.
//!
//! The container (a 12-byte header, a JSON chunk, a binary chunk) and the parts of the JSON a
//! triangle mesh needs are read by hand, following the glTF 2.0 specification (sections 4.4
//! Binary glTF Layout, 5.1 Accessors, 5.11 Buffer Views, 5.25 Nodes). Primitives of mode
//! TRIANGLES (4, the default) are read; points, lines, strips and fans are skipped. POSITION
//! must be a float `VEC3`; indices `u8`, `u16` or `u32` scalars, or none (each three positions a
//! triangle). A node's transform is its `matrix` or its translation, rotation and scale, after
//! those of its parents. Only the binary chunk is read as a buffer: a GLB that refers to other
//! files is refused, as are sparse accessors. Every offset, length and count is checked against
//! the chunk before anything is read, and the counts against the [`MeshLimits`] before the
//! arrays are made.

use glam::{DMat4, DQuat, DVec3};
use serde::Deserialize;
use thiserror::Error;

use super::mesh::{Mesh, MeshLimits};

/// Where in a GLB file a problem is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GlbPlace {
    /// The 12-byte header.
    Header,
    /// A chunk, by its 0-based place in the file.
    Chunk(usize),
    /// The JSON document as a whole.
    Json,
    /// An accessor, by index.
    Accessor(usize),
    /// A buffer view, by index.
    BufferView(usize),
    /// A node, by index.
    Node(usize),
    /// A mesh, by index.
    Mesh(usize),
}

impl std::fmt::Display for GlbPlace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Header => write!(f, "header"),
            Self::Chunk(i) => write!(f, "chunk {i}"),
            Self::Json => write!(f, "JSON chunk"),
            Self::Accessor(i) => write!(f, "accessor {i}"),
            Self::BufferView(i) => write!(f, "bufferView {i}"),
            Self::Node(i) => write!(f, "node {i}"),
            Self::Mesh(i) => write!(f, "mesh {i}"),
        }
    }
}

/// A bad GLB file: where, and what is wrong there.
#[derive(Debug, Error, PartialEq, Eq)]
#[error("GLB {place}: {reason}")]
pub struct GlbError {
    /// Where.
    pub place: GlbPlace,
    /// What is wrong.
    pub reason: String,
}

fn fail<T>(place: GlbPlace, reason: impl Into<String>) -> Result<T, GlbError> {
    Err(GlbError { place, reason: reason.into() })
}

const MAGIC: u32 = 0x4654_6C67;
const JSON_CHUNK: u32 = 0x4E4F_534A;
const BIN_CHUNK: u32 = 0x004E_4942;
const TRIANGLES: u32 = 4;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
/// The largest magnitude of a coordinate, as in the scene contract.
const MAX_COORDINATE: f64 = 1e6;

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Document {
    #[serde(default)]
    nodes: Vec<Node>,
    #[serde(default)]
    meshes: Vec<MeshDef>,
    #[serde(default)]
    accessors: Vec<Accessor>,
    #[serde(default)]
    buffer_views: Vec<BufferView>,
    #[serde(default)]
    buffers: Vec<Buffer>,
}

#[derive(Deserialize)]
struct Node {
    mesh: Option<usize>,
    #[serde(default)]
    children: Vec<usize>,
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
}

#[derive(Deserialize)]
struct MeshDef {
    primitives: Vec<Primitive>,
}

#[derive(Deserialize)]
struct Primitive {
    attributes: std::collections::BTreeMap<String, usize>,
    indices: Option<usize>,
    mode: Option<u32>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Accessor {
    buffer_view: Option<usize>,
    #[serde(default)]
    byte_offset: u64,
    component_type: u32,
    count: u64,
    #[serde(rename = "type")]
    kind: String,
    sparse: Option<serde_json::Value>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct BufferView {
    buffer: usize,
    #[serde(default)]
    byte_offset: u64,
    byte_length: u64,
    byte_stride: Option<u64>,
}

#[derive(Deserialize)]
struct Buffer {
    uri: Option<String>,
}

/// Reads the triangles of a GLB file within `limits`.
pub fn read_glb(bytes: &[u8], limits: MeshLimits) -> Result<Mesh, GlbError> {
    let (json, bin) = chunks(bytes)?;
    let document: Document = serde_json::from_slice(json)
        .map_err(|e| GlbError { place: GlbPlace::Json, reason: format!("not a glTF document: {e}") })?;
    for (i, buffer) in document.buffers.iter().enumerate() {
        if i > 0 || buffer.uri.is_some() {
            return fail(
                GlbPlace::Json,
                format!("buffer {i} is not the GLB's binary chunk; other files are not read"),
            );
        }
    }
    let world = world_transforms(&document.nodes)?;
    let reader = Reader { document: &document, bin };

    // First every primitive is checked and counted, then the arrays are made at their size.
    let mut parts = Vec::new();
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for (n, node) in document.nodes.iter().enumerate() {
        let Some(m) = node.mesh else { continue };
        let Some(mesh) = document.meshes.get(m) else {
            return fail(GlbPlace::Node(n), format!("names mesh {m}, which does not exist"));
        };
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if primitive.mode.unwrap_or(TRIANGLES) != TRIANGLES {
                continue;
            }
            let Some(&position) = primitive.attributes.get("POSITION") else {
                return fail(GlbPlace::Mesh(m), format!("primitive {p} has no POSITION"));
            };
            let positions = reader.view(position, FLOAT, "VEC3")?;
            let corners = match primitive.indices {
                Some(a) => reader.view(a, 0, "SCALAR")?.count,
                None => positions.count,
            };
            if corners % 3 != 0 {
                let place = primitive.indices.map_or(GlbPlace::Accessor(position), GlbPlace::Accessor);
                return fail(place, format!("{corners} corners do not make whole triangles"));
            }
            vertices += positions.count;
            triangles += corners / 3;
            if vertices > limits.max_vertices {
                return fail(
                    GlbPlace::Accessor(position),
                    format!(
                        "the file has more than {} vertices, the most this server takes (--max-particles)",
                        limits.max_vertices
                    ),
                );
            }
            if triangles > limits.max_triangles {
                return fail(
                    GlbPlace::Accessor(primitive.indices.unwrap_or(position)),
                    format!(
                        "the file has more than {} triangles, the most this server takes (--max-asset-triangles)",
                        limits.max_triangles
                    ),
                );
            }
            parts.push((n, positions, primitive.indices));
        }
    }
    if triangles == 0 {
        return fail(GlbPlace::Json, "no node holds a mesh primitive of triangles");
    }
    let mut mesh = Mesh {
        vertices: Vec::with_capacity(3 * vertices as usize),
        triangles: Vec::with_capacity(3 * triangles as usize),
    };
    for (node, positions, indices) in parts {
        let base = (mesh.vertices.len() / 3) as u32;
        let transform = world[node];
        for k in 0..positions.count {
            let p = reader.position(&positions, k);
            let q = transform.transform_point3(DVec3::from_array(p));
            if !q.is_finite() || q.abs().max_element() > MAX_COORDINATE {
                return fail(
                    GlbPlace::Accessor(positions.accessor),
                    format!(
                        "position {k} is {p:?}, which node {node} places outside ±1e6 or at no finite point"
                    ),
                );
            }
            mesh.vertices.extend_from_slice(&q.to_array());
        }
        let count = positions.count;
        match indices {
            Some(a) => {
                let view = reader.view(a, 0, "SCALAR")?;
                for k in 0..view.count / 3 {
                    let triangle = [0, 1, 2].map(|c| reader.index(&view, 3 * k + c));
                    if let Some(bad) = triangle.iter().find(|&&i| i as u64 >= count) {
                        return fail(
                            GlbPlace::Accessor(a),
                            format!("index {bad} of triangle {k} is past the {count} positions"),
                        );
                    }
                    if triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]
                    {
                        return fail(
                            GlbPlace::Accessor(a),
                            format!("triangle {k} repeats a vertex: {triangle:?}"),
                        );
                    }
                    mesh.triangles.extend(triangle.map(|i| base + i));
                }
            }
            None => mesh.triangles.extend((0..count as u32).map(|i| base + i)),
        }
    }
    Ok(mesh.without_unused_vertices())
}

/// The JSON chunk and the binary chunk (empty if there is none) of a GLB file.
fn chunks(bytes: &[u8]) -> Result<(&[u8], &[u8]), GlbError> {
    let word = |at: usize| -> Option<u32> {
        bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if word(0) != Some(MAGIC) {
        return fail(GlbPlace::Header, "the file does not start with `glTF`");
    }
    if word(4) != Some(2) {
        return fail(GlbPlace::Header, format!("version {:?}; only glTF 2 is read", word(4)));
    }
    match word(8) {
        Some(length) if length as usize == bytes.len() => {}
        length => {
            return fail(
                GlbPlace::Header,
                format!("says the file has {length:?} bytes; it has {}", bytes.len()),
            );
        }
    }
    let (mut json, mut bin) = (None, None);
    let mut at = 12usize;
    let mut index = 0;
    while at < bytes.len() {
        let (Some(length), Some(kind)) = (word(at), word(at + 4)) else {
            return fail(GlbPlace::Chunk(index), "the chunk header is cut short");
        };
        let start = at + 8;
        let Some(data) = start.checked_add(length as usize).and_then(|end| bytes.get(start..end)) else {
            return fail(GlbPlace::Chunk(index), format!("{length} bytes run past the end of the file"));
        };
        match (index, kind) {
            (0, JSON_CHUNK) => json = Some(data),
            (0, _) => return fail(GlbPlace::Chunk(0), "the first chunk is not JSON"),
            (1, BIN_CHUNK) => bin = Some(data),
            _ => {}
        }
        at = start + length as usize;
        index += 1;
    }
    match json {
        Some(json) => Ok((json, bin.unwrap_or(&[]))),
        None => fail(GlbPlace::Chunk(0), "the file has no JSON chunk"),
    }
}

/// Each node's transform in the scene: its own after its parents'. A node with two parents or
/// a cycle of children is refused. Each transform is computed once, from its parent's, so a deep
/// hierarchy costs no more than a flat one.
fn world_transforms(nodes: &[Node]) -> Result<Vec<DMat4>, GlbError> {
    let mut parent: Vec<Option<usize>> = vec![None; nodes.len()];
    for (n, node) in nodes.iter().enumerate() {
        for &child in &node.children {
            match parent.get(child) {
                None => return fail(GlbPlace::Node(n), format!("child {child} does not exist")),
                Some(Some(_)) => return fail(GlbPlace::Node(child), "the node has two parents"),
                Some(None) => parent[child] = Some(n),
            }
        }
    }
    let local: Vec<DMat4> =
        nodes.iter().enumerate().map(|(n, node)| local_transform(n, node)).collect::<Result<_, _>>()?;
    let mut world: Vec<Option<DMat4>> = vec![None; nodes.len()];
    let mut on_path = vec![false; nodes.len()];
    let mut path = Vec::new();
    for start in 0..nodes.len() {
        // Climb to the first ancestor already placed (or a root), then place the path down.
        path.clear();
        let mut at = start;
        let mut base = DMat4::IDENTITY;
        loop {
            if let Some(placed) = world[at] {
                base = placed;
                break;
            }
            if on_path[at] {
                return fail(GlbPlace::Node(start), "the node is its own ancestor");
            }
            on_path[at] = true;
            path.push(at);
            match parent[at] {
                Some(p) => at = p,
                None => break,
            }
        }
        for &node in path.iter().rev() {
            base *= local[node];
            world[node] = Some(base);
            on_path[node] = false;
        }
    }
    Ok(world.into_iter().map(|w| w.unwrap_or(DMat4::IDENTITY)).collect())
}

fn local_transform(n: usize, node: &Node) -> Result<DMat4, GlbError> {
    let finite = |values: &[f64]| values.iter().all(|v| v.is_finite());
    if let Some(matrix) = node.matrix {
        if !finite(&matrix) {
            return fail(GlbPlace::Node(n), "the matrix is not finite");
        }
        return Ok(DMat4::from_cols_array(&matrix));
    }
    let translation = node.translation.unwrap_or([0.0; 3]);
    let rotation = node.rotation.unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let scale = node.scale.unwrap_or([1.0; 3]);
    if !finite(&translation) || !finite(&rotation) || !finite(&scale) {
        return fail(GlbPlace::Node(n), "the translation, rotation or scale is not finite");
    }
    let rotation = DQuat::from_array(rotation);
    let norm = rotation.length();
    if (norm - 1.0).abs() > 1e-3 {
        return fail(
            GlbPlace::Node(n),
            format!("the rotation is not a unit quaternion (its length is {norm})"),
        );
    }
    Ok(DMat4::from_scale_rotation_translation(
        DVec3::from_array(scale),
        rotation / norm,
        DVec3::from_array(translation),
    ))
}

/// An accessor checked against its buffer view and the binary chunk.
struct View {
    accessor: usize,
    count: u64,
    /// Bytes of one element.
    size: usize,
    /// The element's component type.
    component: u32,
    /// Offset of the first element in the binary chunk.
    start: usize,
    stride: usize,
}

struct Reader<'a> {
    document: &'a Document,
    bin: &'a [u8],
}

impl Reader<'_> {
    /// Accessor `a`, which must be of `kind` and, unless `component` is 0 (any index type), of
    /// that component type, with every element inside the binary chunk.
    fn view(&self, a: usize, component: u32, kind: &str) -> Result<View, GlbError> {
        let place = GlbPlace::Accessor(a);
        let Some(accessor) = self.document.accessors.get(a) else {
            return fail(place, "does not exist");
        };
        if accessor.sparse.is_some() {
            return fail(place, "sparse accessors are not read");
        }
        if accessor.kind != kind {
            return fail(place, format!("type {} where {kind} is needed", accessor.kind));
        }
        let component_size = match (component, accessor.component_type) {
            (FLOAT, FLOAT) => 4,
            (0, UNSIGNED_BYTE) => 1,
            (0, UNSIGNED_SHORT) => 2,
            (0, UNSIGNED_INT) => 4,
            (FLOAT, other) => {
                return fail(place, format!("componentType {other} where float (5126) is needed"));
            }
            (_, other) => {
                return fail(
                    place,
                    format!("componentType {other} where an unsigned integer (5121, 5123, 5125) is needed"),
                );
            }
        };
        let size = if kind == "VEC3" { 3 * component_size } else { component_size };
        let Some(v) = accessor.buffer_view else {
            return fail(place, "has no bufferView");
        };
        let Some(buffer_view) = self.document.buffer_views.get(v) else {
            return fail(place, format!("names bufferView {v}, which does not exist"));
        };
        if buffer_view.buffer != 0 {
            return fail(
                GlbPlace::BufferView(v),
                format!("names buffer {}; only the binary chunk (0) is read", buffer_view.buffer),
            );
        }
        let view_end = buffer_view.byte_offset.checked_add(buffer_view.byte_length);
        if view_end.is_none_or(|end| end > self.bin.len() as u64) {
            return fail(
                GlbPlace::BufferView(v),
                format!(
                    "bytes {} to {} run past the binary chunk of {} bytes",
                    buffer_view.byte_offset,
                    buffer_view.byte_offset.saturating_add(buffer_view.byte_length),
                    self.bin.len()
                ),
            );
        }
        let stride = buffer_view.byte_stride.unwrap_or(size as u64);
        if stride < size as u64 || stride > 252 {
            return fail(
                GlbPlace::BufferView(v),
                format!("byteStride {stride} is not between {size} and 252"),
            );
        }
        if accessor.count == 0 {
            return fail(place, "has no elements");
        }
        let last = (accessor.count - 1)
            .checked_mul(stride)
            .and_then(|bytes| bytes.checked_add(accessor.byte_offset))
            .and_then(|bytes| bytes.checked_add(size as u64));
        if last.is_none_or(|end| end > buffer_view.byte_length) {
            return fail(
                place,
                format!(
                    "{} elements from byteOffset {} run past its bufferView {v} of {} bytes",
                    accessor.count, accessor.byte_offset, buffer_view.byte_length
                ),
            );
        }
        // Within the view (checked above), so the sum cannot overflow.
        if accessor.byte_offset % component_size as u64 != 0
            || (buffer_view.byte_offset + accessor.byte_offset) % component_size as u64 != 0
        {
            return fail(
                place,
                format!(
                    "byteOffset {} is not aligned to its {component_size}-byte components",
                    accessor.byte_offset
                ),
            );
        }
        Ok(View {
            accessor: a,
            count: accessor.count,
            size,
            component: accessor.component_type,
            start: (buffer_view.byte_offset + accessor.byte_offset) as usize,
            stride: stride as usize,
        })
    }

    fn element(&self, view: &View, k: u64) -> &[u8] {
        let at = view.start + k as usize * view.stride;
        &self.bin[at..at + view.size]
    }

    fn position(&self, view: &View, k: u64) -> [f64; 3] {
        let e = self.element(view, k);
        [0, 4, 8].map(|o| f32::from_le_bytes([e[o], e[o + 1], e[o + 2], e[o + 3]]) as f64)
    }

    fn index(&self, view: &View, k: u64) -> u32 {
        let e = self.element(view, k);
        match view.component {
            UNSIGNED_BYTE => e[0] as u32,
            UNSIGNED_SHORT => u16::from_le_bytes([e[0], e[1]]) as u32,
            _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
        }
    }
}
