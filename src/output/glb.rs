//! glTF 2.0 binary (GLB), as the Khronos glTF 2.0 specification defines it: a 12-byte header,
//! a JSON chunk and a BIN chunk, little-endian, every chunk padded to 4 bytes.
//!
//! Each body is one node and one mesh named after it. Its primitive holds the last recorded
//! frame: `POSITION` (with the `min`/`max` the specification requires), and for a surface
//! `NORMAL` and `indices` (triangles, mode 4); a chain, having no triangles, is a line strip
//! (mode 3). Normals are the recording's when the run recorded them, otherwise computed here
//! from the triangles; a vertex on no triangle (inside a lattice) is not drawn, but glTF wants
//! unit normals, so it gets +y. With more than one frame, every frame is a morph target holding
//! `POSITION` (and `NORMAL`, if recorded) deltas against the last frame, and an animation drives
//! the mesh `weights` with one keyframe per frame time and `STEP` interpolation, so that at each
//! frame's time exactly that frame's target shows, fully (the weights are a sparse accessor: one
//! 1 per keyframe over zeros). three.js's `GLTFLoader` plays it as is.
//!
//! Floats are `f32`, as glTF requires: an `f64` run is rounded to the nearest `f32`. A delta is
//! the exact difference rounded once to `f32`, so a frame shows within half an `f32` step of the
//! delta's size. glTF has no place for a value that is not finite (the Khronos validator refuses
//! NaN and infinity in accessors, and `min`/`max` must be numbers), so a frame that holds one in
//! `f32` (a position beyond `f32`'s range, a NaN read back from a JSON `null`), or whose delta
//! would be one, is left out: the file shows the other frames, the last of them as its base, and
//! lists the indices of the frames it left out in `asset.extras.omitted_frames`. A recording with
//! no such frame at all cannot be a GLB ([`shown_frames`] is empty, and `encode` refuses it). The BIN chunk is written straight from the recording; only the last frame of
//! each body is held in `f32` while the header is built.
//!
//! Each collider is one more node, named as in the result (`collider:0`, ...), after the
//! bodies' nodes, with a closed mesh of its shape ([`tessellate`]; a plane is a square reaching
//! twice as far from its point as the farthest particle of the base frame, and at least 5 m) in
//! a material of its own. A collider that moves has its transform at the base frame as the
//! node's `translation` and `rotation`, and with several frames shown the animation drives them
//! with the same keyframe times (`STEP`). A collider whose shape or transforms are not finite in
//! `f32` is left out and listed in `asset.extras.omitted_colliders`.

use std::io::{self, Write};

use serde_json::{Value, json};

use super::Selected;
use super::collider_mesh::tessellate;
use super::surface::{body_range, body_triangles, body_vectors, vertex_normals};
use crate::run::{ColliderShape, RecordedCollider, Recording, RigidTransform, Samples};
use crate::scene::BodyInfo;

const MAGIC: &[u8; 4] = b"glTF";
const VERSION: u32 = 2;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const MODE_LINE_STRIP: u32 = 3;
const MODE_TRIANGLES: u32 = 4;
/// The normal given to a vertex on no triangle, which glTF would otherwise refuse as non-unit.
const UNDRAWN_NORMAL: [f32; 3] = [0.0, 1.0, 0.0];
/// The least half-size of the square that shows a plane collider, in metres.
const PLANE_MIN_HALF_SIZE: f64 = 5.0;

/// Writes `recording` as a GLB file. It needs positions and at least one frame that glTF can
/// show (see [`shown_frames`]).
pub(super) fn write_glb<W: Write>(recording: &Recording, selected: &Selected, w: &mut W) -> io::Result<()> {
    let shown = shown_frames(recording, selected);
    if shown.is_empty() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "no frame has finite f32 positions"));
    }
    let glb = Glb::plan(recording, selected, shown);
    let mut json_chunk = serde_json::to_vec(&glb.document).map_err(io::Error::other)?;
    json_chunk.resize(json_chunk.len().next_multiple_of(4), b' ');
    let bin_length = glb.layout_length;
    let total = 12 + 8 + json_chunk.len() + 8 + bin_length;
    let too_large = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{total} bytes is more than a GLB file can hold (4 GiB)"),
        )
    };
    let total = u32::try_from(total).map_err(|_| too_large())?;
    w.write_all(MAGIC)?;
    w.write_all(&VERSION.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    w.write_all(&(json_chunk.len() as u32).to_le_bytes())?;
    w.write_all(&CHUNK_JSON.to_le_bytes())?;
    w.write_all(&json_chunk)?;
    w.write_all(&(bin_length as u32).to_le_bytes())?;
    w.write_all(&CHUNK_BIN.to_le_bytes())?;
    glb.write_bin(w)
}

/// A GLB file planned: its JSON document, and what to write into its BIN chunk in what order.
struct Glb<'a> {
    recording: &'a Recording,
    positions: &'a Samples,
    normals: Option<&'a Samples>,
    bodies: Vec<BodyPlan<'a>>,
    colliders: Vec<ColliderPlan>,
    /// The indices of the recorded frames the file shows, in order.
    shown: Vec<usize>,
    times: Vec<f32>,
    document: Value,
    layout_length: usize,
}

impl<'a> Glb<'a> {
    /// Lays out the BIN chunk (body by body: base positions, normals, indices, then the targets;
    /// then the animation's times and weights) and describes it in the JSON document. Reads the
    /// frames once, for the targets' bounds.
    fn plan(recording: &'a Recording, selected: &Selected<'a>, shown: Vec<usize>) -> Self {
        let positions = selected.positions.expect("checked by encode");
        let normals = selected.normals;
        let frames = shown.len();
        let last = shown[frames - 1];
        let bodies: Vec<BodyPlan> = recording
            .bodies
            .iter()
            .map(|body| BodyPlan::new(recording, body, last, positions, normals))
            .collect();
        let mut layout = Layout::default();
        let meshes: Vec<Value> =
            bodies.iter().map(|plan| plan.mesh(&mut layout, recording, &shown, positions, normals)).collect();
        let mut nodes: Vec<Value> = bodies
            .iter()
            .enumerate()
            .map(|(index, plan)| json!({ "name": plan.body.name, "mesh": index }))
            .collect();
        let plane_half_size = |point: [f64; 3]| {
            let farthest =
                bodies.iter().flat_map(|b| b.base_positions.chunks_exact(3)).fold(0.0, |far: f64, p| {
                    let d = [0, 1, 2].map(|a| f64::from(p[a]) - point[a]);
                    far.max((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
                });
            (2.0 * farthest).max(PLANE_MIN_HALF_SIZE)
        };
        let (colliders, omitted_colliders): (Vec<_>, Vec<_>) = recording
            .colliders
            .iter()
            .map(|c| ColliderPlan::new(c, &shown, &plane_half_size))
            .partition(Option::is_some);
        let colliders: Vec<ColliderPlan> = colliders.into_iter().flatten().collect();
        let cloth_material = bodies.iter().any(|b| !b.triangles.is_empty());
        let collider_material = usize::from(cloth_material);
        for plan in &colliders {
            let mut node = json!({ "name": plan.name, "mesh": nodes.len() });
            if let Some(base) = &plan.base {
                node["translation"] = json!(base.translation);
                node["rotation"] = json!(base.rotation);
            }
            nodes.push(node);
        }
        let mut meshes = meshes;
        meshes.extend(colliders.iter().map(|plan| plan.mesh(&mut layout, collider_material)));
        let mut document = json!({
            "asset": { "version": "2.0", "generator": concat!("drape ", env!("CARGO_PKG_VERSION")) },
            "scene": 0,
            "scenes": [{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
            "nodes": nodes,
            "meshes": meshes,
        });
        if frames < recording.frames.len() {
            let omitted: Vec<usize> =
                (0..recording.frames.len()).filter(|k| shown.binary_search(k).is_err()).collect();
            document["asset"]["extras"]["omitted_frames"] = json!(omitted);
        }
        if !omitted_colliders.is_empty() {
            let names: Vec<&str> = recording
                .colliders
                .iter()
                .filter(|c| !colliders.iter().any(|plan| plan.name == c.name))
                .map(|c| c.name.as_str())
                .collect();
            document["asset"]["extras"]["omitted_colliders"] = json!(names);
        }
        // Only triangle primitives use a material; the validator flags an unused one.
        let mut materials = Vec::new();
        if cloth_material {
            materials.push(json!({ "name": "cloth", "doubleSided": true,
                "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8 } }));
        }
        if !colliders.is_empty() {
            materials.push(json!({ "name": "collider", "doubleSided": true,
                "pbrMetallicRoughness": { "baseColorFactor": [0.55, 0.57, 0.6, 1.0],
                                          "metallicFactor": 0.0, "roughnessFactor": 0.9 } }));
        }
        if !materials.is_empty() {
            document["materials"] = materials.into();
        }
        let times: Vec<f32> = shown.iter().map(|&k| recording.frames.times[k] as f32).collect();
        if frames > 1 {
            let time_view = layout.view(4 * frames, None, None);
            let bounds = (json!([times[0]]), json!([times[frames - 1]]));
            let input = layout.accessor(time_view, 0, FLOAT, frames, "SCALAR", Some(bounds));
            // Keyframe k's weights are zero but for target k: a sparse accessor over zeros
            // holds just the F ones, where a dense one would hold F² floats.
            let one_indices = layout.view(4 * frames, None, None);
            let ones = layout.view(4 * frames, None, None);
            layout.accessors.push(json!({
                "componentType": FLOAT, "count": frames * frames, "type": "SCALAR",
                "sparse": { "count": frames,
                            "indices": { "bufferView": one_indices, "componentType": UNSIGNED_INT },
                            "values": { "bufferView": ones } },
            }));
            let output = layout.accessors.len() - 1;
            let mut channels: Vec<Value> = (0..bodies.len())
                .map(|node| json!({ "sampler": 0, "target": { "node": node, "path": "weights" } }))
                .collect();
            let mut samplers = vec![json!({ "input": input, "output": output, "interpolation": "STEP" })];
            for (k, plan) in colliders.iter().enumerate() {
                if plan.shown.is_none() {
                    continue;
                }
                let node = bodies.len() + k;
                let translations = layout.view(12 * frames, None, None);
                let translations = layout.vec3(translations, 0, frames, None);
                let rotations = layout.view(16 * frames, None, None);
                let rotations = layout.accessor(rotations, 0, FLOAT, frames, "VEC4", None);
                for (path, output) in [("translation", translations), ("rotation", rotations)] {
                    channels
                        .push(json!({ "sampler": samplers.len(), "target": { "node": node, "path": path } }));
                    samplers.push(json!({ "input": input, "output": output, "interpolation": "STEP" }));
                }
            }
            document["animations"] = json!([{
                "name": "motion",
                "samplers": samplers,
                "channels": channels,
            }]);
        }
        let layout_length = layout.length;
        document["accessors"] = layout.accessors.into();
        document["bufferViews"] = layout.views.into();
        document["buffers"] = json!([{ "byteLength": layout_length }]);
        Self { recording, positions, normals, bodies, colliders, shown, times, document, layout_length }
    }

    /// The BIN chunk, in the order [`Glb::plan`] laid it out.
    fn write_bin<W: Write>(&self, w: &mut W) -> io::Result<()> {
        let (recording, frames) = (self.recording, self.shown.len());
        let mut buffer = Vec::new();
        for plan in &self.bodies {
            let body = plan.body;
            write_f32s(w, plan.base_positions.iter().copied())?;
            if let Some(base_normals) = &plan.base_normals {
                write_f32s(w, base_normals.iter().copied())?;
            }
            plan.triangles.iter().flatten().try_for_each(|index| w.write_all(&index.to_le_bytes()))?;
            if frames == 1 {
                continue;
            }
            for &k in &self.shown {
                buffer.clear();
                for_each_delta(self.positions, recording.particles, k, body, &plan.base_positions, |d| {
                    d.iter().for_each(|x| buffer.extend_from_slice(&x.to_le_bytes()))
                });
                w.write_all(&buffer)?;
            }
            if let (Some(normals), Some(base_normals)) = (self.normals, &plan.base_normals) {
                for &k in &self.shown {
                    let shown =
                        body_vectors(normals, recording.particles, k, body).into_iter().map(shown_normal);
                    let deltas = shown
                        .zip(base_normals.chunks_exact(3))
                        .map(|(n, base)| [0, 1, 2].map(|a| (f64::from(n[a]) - f64::from(base[a])) as f32));
                    write_f32s(w, deltas.flatten())?;
                }
            }
        }
        for plan in &self.colliders {
            write_f32s(w, plan.positions.iter().flatten().copied())?;
            write_f32s(w, plan.normals.iter().flatten().copied())?;
            plan.triangles.iter().flatten().try_for_each(|index| w.write_all(&index.to_le_bytes()))?;
        }
        if frames > 1 {
            write_f32s(w, self.times.iter().copied())?;
            (0..frames).try_for_each(|k| w.write_all(&((k * frames + k) as u32).to_le_bytes()))?;
            write_f32s(w, (0..frames).map(|_| 1.0))?;
            for shown in self.colliders.iter().filter_map(|plan| plan.shown.as_ref()) {
                write_f32s(w, shown.iter().flat_map(|t| t.translation))?;
                write_f32s(w, shown.iter().flat_map(|t| t.rotation))?;
            }
        }
        Ok(())
    }
}

/// A collider's transform as glTF holds it.
#[derive(Clone, Copy)]
struct NodeTransform {
    translation: [f32; 3],
    rotation: [f32; 4],
}

/// What one collider contributes: its shape in `f32`, and for one that moves its transform at
/// each frame shown.
struct ColliderPlan {
    name: String,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    /// The transform at the base (last shown) frame, for a collider that moves.
    base: Option<NodeTransform>,
    /// The transform at each frame shown, for a collider that moves.
    shown: Option<Vec<NodeTransform>>,
}

impl ColliderPlan {
    /// `None` when glTF cannot show the collider: a value not finite in `f32`, a quaternion of
    /// no length, an index past its vertices, or no triangle.
    fn new(
        collider: &RecordedCollider,
        shown: &[usize],
        plane_half_size: &dyn Fn([f64; 3]) -> f64,
    ) -> Option<Self> {
        let half_size = match collider.shape {
            ColliderShape::Plane { point, .. } => plane_half_size(point),
            _ => 0.0,
        };
        let surface = tessellate(&collider.shape, half_size);
        let positions: Vec<[f32; 3]> = surface.positions.iter().map(|p| p.map(|x| x as f32)).collect();
        let normals: Vec<[f32; 3]> = surface.normals.iter().map(|&n| shown_normal(n)).collect();
        let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
        let drawable = !surface.triangles.is_empty()
            && surface.triangles.iter().flatten().all(|&i| (i as usize) < positions.len())
            && positions.iter().all(|p| finite(p))
            && normals.iter().all(|n| finite(n));
        if !drawable {
            return None;
        }
        let shown = match &collider.frames {
            None => None,
            Some(frames) => {
                let transforms =
                    shown.iter().map(|&k| node_transform(frames.get(k)?)).collect::<Option<Vec<_>>>()?;
                Some(transforms)
            }
        };
        let base = shown.as_ref().and_then(|s| s.last()).copied();
        Some(Self {
            name: collider.name.clone(),
            positions,
            normals,
            triangles: surface.triangles,
            base,
            shown,
        })
    }

    /// The collider's mesh; lays out its views.
    fn mesh(&self, layout: &mut Layout, material: usize) -> Value {
        let count = self.positions.len();
        let mut bounds = Bounds::default();
        self.positions.iter().for_each(|&p| bounds.add(p));
        let view = layout.view(12 * count, Some(ARRAY_BUFFER), None);
        let position = layout.vec3(view, 0, count, Some(bounds.json()));
        let view = layout.view(12 * count, Some(ARRAY_BUFFER), None);
        let normal = layout.vec3(view, 0, count, None);
        let view = layout.view(12 * self.triangles.len(), Some(ELEMENT_ARRAY_BUFFER), None);
        let indices = layout.accessor(view, 0, UNSIGNED_INT, 3 * self.triangles.len(), "SCALAR", None);
        json!({ "name": self.name, "primitives": [{
            "attributes": { "POSITION": position, "NORMAL": normal },
            "indices": indices, "mode": MODE_TRIANGLES, "material": material,
        }] })
    }
}

/// `transform` in `f32`, its quaternion made unit (glTF requires it); `None` when a value is
/// not finite in `f32` or the quaternion has no length.
fn node_transform(transform: &RigidTransform) -> Option<NodeTransform> {
    let q = transform.rotation;
    let length = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(length > 0.0 && length.is_finite()) {
        return None;
    }
    let rotation = q.map(|x| (x / length) as f32);
    let translation = transform.translation.map(|x| x as f32);
    (translation.iter().chain(&rotation).all(|x| x.is_finite()))
        .then_some(NodeTransform { translation, rotation })
}

/// What one body contributes: its last frame in `f32`, its normals and its re-based triangles.
struct BodyPlan<'a> {
    body: &'a BodyInfo,
    base_positions: Vec<f32>,
    /// Present for a body with triangles.
    base_normals: Option<Vec<f32>>,
    triangles: Vec<[u32; 3]>,
}

impl<'a> BodyPlan<'a> {
    /// The body in frame `last`, which the file shows as its base.
    fn new(
        recording: &Recording,
        body: &'a BodyInfo,
        last: usize,
        positions: &Samples,
        normals: Option<&Samples>,
    ) -> Self {
        let base_positions = to_f32(positions, body_range(recording.particles, last, body));
        let triangles = body_triangles(recording, body);
        let base_normals = (!triangles.is_empty()).then(|| {
            let vectors = match normals {
                Some(normals) => body_vectors(normals, recording.particles, last, body),
                None => vertex_normals(&body_vectors(positions, recording.particles, last, body), &triangles),
            };
            vectors.into_iter().flat_map(shown_normal).collect()
        });
        Self { body, base_positions, base_normals, triangles }
    }
}

impl BodyPlan<'_> {
    /// The body's mesh: one primitive of its base frame and, with several frames shown, one morph
    /// target per frame shown. Lays out the views it uses.
    fn mesh(
        &self,
        layout: &mut Layout,
        recording: &Recording,
        shown: &[usize],
        positions: &Samples,
        normals: Option<&Samples>,
    ) -> Value {
        let (body, frames) = (self.body, shown.len());
        let mut base = Bounds::default();
        self.base_positions.chunks_exact(3).for_each(|c| base.add([c[0], c[1], c[2]]));
        let view = layout.view(12 * body.count, Some(ARRAY_BUFFER), None);
        let mut attributes = json!({ "POSITION": layout.vec3(view, 0, body.count, Some(base.json())) });
        if self.base_normals.is_some() {
            let view = layout.view(12 * body.count, Some(ARRAY_BUFFER), None);
            attributes["NORMAL"] = layout.vec3(view, 0, body.count, None).into();
        }
        let mut primitive = json!({ "attributes": attributes, "mode": MODE_LINE_STRIP });
        if !self.triangles.is_empty() {
            let view = layout.view(12 * self.triangles.len(), Some(ELEMENT_ARRAY_BUFFER), None);
            let count = 3 * self.triangles.len();
            primitive["indices"] = layout.accessor(view, 0, UNSIGNED_INT, count, "SCALAR", None).into();
            primitive["mode"] = MODE_TRIANGLES.into();
            primitive["material"] = 0.into();
        }
        let mut mesh = json!({ "name": body.name, "primitives": [primitive] });
        if frames == 1 {
            return mesh;
        }
        let frame_bytes = 12 * body.count;
        // Targets share a view, so it needs a stride (glTF 2.0 §3.6.2.4).
        let position_view = layout.view(frames * frame_bytes, Some(ARRAY_BUFFER), Some(12));
        let mut targets: Vec<Value> = shown
            .iter()
            .enumerate()
            .map(|(target, &k)| {
                let mut deltas = Bounds::default();
                for_each_delta(positions, recording.particles, k, body, &self.base_positions, |d| {
                    deltas.add(d)
                });
                let offset = target * frame_bytes;
                json!({ "POSITION": layout.vec3(position_view, offset, body.count, Some(deltas.json())) })
            })
            .collect();
        if normals.is_some() && self.base_normals.is_some() {
            let normal_view = layout.view(frames * frame_bytes, Some(ARRAY_BUFFER), Some(12));
            for (k, target) in targets.iter_mut().enumerate() {
                target["NORMAL"] = layout.vec3(normal_view, k * frame_bytes, body.count, None).into();
            }
        }
        mesh["primitives"][0]["targets"] = targets.into();
        mesh["weights"] = vec![0.0; frames].into();
        mesh
    }
}

/// The recorded frames a GLB file can show, in order: those whose positions (and normals, if
/// recorded) are finite in `f32`, and whose position deltas against the last of them are too.
pub(super) fn shown_frames(recording: &Recording, selected: &Selected) -> Vec<usize> {
    let Some(positions) = selected.positions else { return Vec::new() };
    let per_frame = 3 * recording.particles;
    let finite = |samples: &Samples, k: usize| {
        let range = k * per_frame..(k + 1) * per_frame;
        match samples {
            Samples::F32(v) => v[range].iter().all(|x| x.is_finite()),
            Samples::F64(v) => v[range].iter().all(|&x| (x as f32).is_finite()),
        }
    };
    let normals = selected.normals;
    let candidates: Vec<usize> = (0..recording.frames.len())
        .filter(|&k| finite(positions, k) && normals.is_none_or(|n| finite(n, k)))
        .collect();
    let Some(&last) = candidates.last() else { return candidates };
    let base = to_f32(positions, last * per_frame..(last + 1) * per_frame);
    let whole = BodyInfo { name: String::new(), kind: "", offset: 0, count: recording.particles };
    candidates
        .into_iter()
        .filter(|&k| {
            let mut all_finite = true;
            for_each_delta(positions, recording.particles, k, &whole, &base, |d| {
                all_finite &= d.iter().all(|x| x.is_finite())
            });
            all_finite
        })
        .collect()
}

/// A normal as glTF shows it: in `f32`, and unit even where the surface gave none.
fn shown_normal(n: [f64; 3]) -> [f32; 3] {
    if n == [0.0; 3] { UNDRAWN_NORMAL } else { n.map(|x| x as f32) }
}

/// Calls `f` with each `f32` position delta of `body` in frame `k` against its base positions:
/// the exact difference, rounded once.
fn for_each_delta(
    positions: &Samples,
    particles: usize,
    k: usize,
    body: &BodyInfo,
    base: &[f32],
    f: impl FnMut([f32; 3]),
) {
    fn each<T: Copy + Into<f64>>(values: &[T], base: &[f32], mut f: impl FnMut([f32; 3])) {
        for (x, b) in values.chunks_exact(3).zip(base.chunks_exact(3)) {
            f([0, 1, 2].map(|a| (x[a].into() - f64::from(b[a])) as f32));
        }
    }
    let range = body_range(particles, k, body);
    match positions {
        Samples::F32(v) => each(&v[range], base, f),
        Samples::F64(v) => each(&v[range], base, f),
    }
}

fn to_f32(samples: &Samples, range: std::ops::Range<usize>) -> Vec<f32> {
    match samples {
        Samples::F32(v) => v[range].to_vec(),
        Samples::F64(v) => v[range].iter().map(|&x| x as f32).collect(),
    }
}

/// Component-wise minimum and maximum, for an accessor's `min` and `max`.
struct Bounds {
    min: [f32; 3],
    max: [f32; 3],
}

impl Default for Bounds {
    fn default() -> Self {
        Self { min: [f32::INFINITY; 3], max: [f32::NEG_INFINITY; 3] }
    }
}

impl Bounds {
    fn add(&mut self, v: [f32; 3]) {
        self.min = [0, 1, 2].map(|a| self.min[a].min(v[a]));
        self.max = [0, 1, 2].map(|a| self.max[a].max(v[a]));
    }

    fn json(&self) -> (Value, Value) {
        (json!(self.min), json!(self.max))
    }
}

fn write_f32s<W: Write>(w: &mut W, values: impl Iterator<Item = f32>) -> io::Result<()> {
    for x in values {
        w.write_all(&x.to_le_bytes())?;
    }
    Ok(())
}

/// The buffer views and accessors, laid out in the order the BIN chunk is written.
#[derive(Default)]
struct Layout {
    views: Vec<Value>,
    accessors: Vec<Value>,
    length: usize,
}

impl Layout {
    /// A view of the next `length` bytes (a multiple of 4, so every view stays aligned).
    fn view(&mut self, length: usize, target: Option<u32>, stride: Option<usize>) -> usize {
        debug_assert_eq!(length % 4, 0);
        let mut view = json!({ "buffer": 0, "byteOffset": self.length, "byteLength": length });
        if let Some(target) = target {
            view["target"] = target.into();
        }
        if let Some(stride) = stride {
            view["byteStride"] = stride.into();
        }
        self.views.push(view);
        self.length += length;
        self.views.len() - 1
    }

    fn accessor(
        &mut self,
        view: usize,
        offset: usize,
        component: u32,
        count: usize,
        kind: &str,
        bounds: Option<(Value, Value)>,
    ) -> usize {
        let mut accessor = json!({ "bufferView": view, "byteOffset": offset, "componentType": component, "count": count, "type": kind });
        if let Some((min, max)) = bounds {
            accessor["min"] = min;
            accessor["max"] = max;
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn vec3(&mut self, view: usize, offset: usize, count: usize, bounds: Option<(Value, Value)>) -> usize {
        self.accessor(view, offset, FLOAT, count, "VEC3", bounds)
    }
}
