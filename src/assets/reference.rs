//! The references a scene makes to mesh files, found and replaced at the JSON level.
//!
//! A `mesh` object in `bodies` or `colliders` may name its mesh with `"asset": "sha256:..."`
//! (a mesh uploaded to a server) or, on the command line only, `"file": "path.obj"` (or
//! `.glb`, relative to the scene file's directory) in place of `vertices` and `triangles`.
//! Resolving puts the mesh's `vertices` and `triangles` where the reference was, so the typed
//! parse that follows, and every limit and check after it, sees the real mesh.

use std::path::Path;

use serde_json::Value;

use super::mesh::{Mesh, MeshFormat, MeshLimits, read_mesh};
use crate::scene::FieldError;

/// The lists of a scene whose objects may be meshes.
const LISTS: [&str; 2] = ["bodies", "colliders"];

/// What a mesh object names its mesh by.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshSource {
    /// An uploaded asset's id, `sha256:<hex>`.
    Asset(String),
    /// A path, relative to the scene file's directory.
    File(String),
}

/// One reference of a scene: where it is and what it names.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reference {
    /// The list it is in (`bodies` or `colliders`).
    list: &'static str,
    /// Its index in the list.
    index: usize,
    /// The JSON Pointer of the reference's field in the submitted document (`/bodies/0/asset`).
    pub pointer: String,
    /// What it names.
    pub source: MeshSource,
}

/// Whether `id` is an asset id: `sha256:` and 64 lowercase hex digits.
pub fn is_asset_id(id: &str) -> bool {
    id.strip_prefix("sha256:").is_some_and(|hex| {
        hex.len() == 64 && hex.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
    })
}

/// Every reference of `scene`, whose pointers start with `prefix` (`""` for a scene, `/scene`
/// for a sweep's base scene); each malformed one is an error at its field.
pub fn referenced_assets(scene: &Value, prefix: &str) -> Result<Vec<Reference>, Vec<FieldError>> {
    let (mut references, mut errors) = (Vec::new(), Vec::new());
    for list in LISTS {
        let Some(items) = scene.get(list).and_then(Value::as_array) else { continue };
        for (index, item) in items.iter().enumerate() {
            let Some(object) = item.as_object() else { continue };
            if object.get("type").and_then(Value::as_str) != Some("mesh") {
                continue;
            }
            let at = format!("{prefix}/{list}/{index}");
            let (asset, file) = (object.get("asset"), object.get("file"));
            let (key, source) = match (asset, file) {
                (None, None) => continue,
                (Some(_), Some(_)) => {
                    errors.push(FieldError::new(format!("{at}/file"), "give `asset` or `file`, not both"));
                    continue;
                }
                (Some(asset), None) => match asset.as_str().filter(|id| is_asset_id(id)) {
                    Some(id) => ("asset", MeshSource::Asset(id.to_string())),
                    None => {
                        errors.push(FieldError::new(
                            format!("{at}/asset"),
                            "must be an asset id, `sha256:` and 64 lowercase hex digits, as POST /assets gives",
                        ));
                        continue;
                    }
                },
                (None, Some(file)) => match file.as_str().filter(|path| !path.is_empty()) {
                    Some(path) => ("file", MeshSource::File(path.to_string())),
                    None => {
                        errors.push(FieldError::new(
                            format!("{at}/file"),
                            "must be the path of an .obj or .glb file",
                        ));
                        continue;
                    }
                },
            };
            let pointer = format!("{at}/{key}");
            if object.contains_key("vertices") || object.contains_key("triangles") {
                errors.push(FieldError::new(
                    pointer,
                    format!("a mesh named by `{key}` takes its vertices and triangles from it: remove `vertices` and `triangles`"),
                ));
                continue;
            }
            references.push(Reference { list, index, pointer, source });
        }
    }
    if errors.is_empty() { Ok(references) } else { Err(errors) }
}

/// Whether `scene` has any reference to resolve (well-formed or not).
pub fn has_references(scene: &Value) -> bool {
    LISTS.iter().filter_map(|list| scene.get(list).and_then(Value::as_array)).flatten().any(|item| {
        item.get("type").and_then(Value::as_str) == Some("mesh")
            && (item.get("asset").is_some() || item.get("file").is_some())
    })
}

/// Puts `mesh` in place of `reference` in `scene` (the document `referenced_assets` read).
pub fn put_mesh(scene: &mut Value, reference: &Reference, mesh: &Mesh) {
    let Some(object) =
        scene.get_mut(reference.list).and_then(|l| l.get_mut(reference.index)).and_then(Value::as_object_mut)
    else {
        return;
    };
    object.remove("asset");
    object.remove("file");
    object.insert("vertices".into(), mesh.vertices.iter().map(|&x| Value::from(x)).collect());
    object.insert("triangles".into(), mesh.triangles.iter().map(|&i| Value::from(i)).collect());
}

/// Resolves the references of a scene read from a file in `directory`, for `drape run` and
/// `drape sweep`: each `file` is read (by its extension, `.obj` or `.glb`) within `limits`; an
/// `asset` is an error, as only a server holds assets.
pub fn resolve_files(
    scene: &mut Value,
    prefix: &str,
    directory: &Path,
    limits: MeshLimits,
) -> Result<(), Vec<FieldError>> {
    let mut errors = Vec::new();
    for reference in referenced_assets(scene, prefix)? {
        let path = match &reference.source {
            MeshSource::Asset(_) => {
                errors.push(FieldError::new(
                    &reference.pointer,
                    "assets live on a server (POST /assets); on the command line name the mesh with `file`",
                ));
                continue;
            }
            MeshSource::File(path) => directory.join(path),
        };
        let Some(format) = MeshFormat::from_path(&path) else {
            errors.push(FieldError::new(&reference.pointer, "the file must end in .obj or .glb"));
            continue;
        };
        let mesh = std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display())).and_then(
            |bytes| read_mesh(&bytes, format, limits).map_err(|e| format!("{}: {e}", path.display())),
        );
        match mesh {
            Ok(mesh) => put_mesh(scene, &reference, &mesh),
            Err(detail) => errors.push(FieldError::new(&reference.pointer, detail)),
        }
    }
    if errors.is_empty() { Ok(()) } else { Err(errors) }
}
