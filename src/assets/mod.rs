//! Meshes from files: the readers of Wavefront OBJ and glTF 2.0 binary (GLB) that turn an
//! uploaded or local mesh file into a [`Mesh`] (flat vertex coordinates and triangle indices),
//! the compact form a mesh is stored in, and the references a scene makes to them (`"asset"`
//! and, on the command line, `"file"`).
//!
//! References are replaced at the JSON level, before the scene's typed parse: any object in
//! `bodies` or `colliders` of type `mesh` that names a mesh gets `vertices` and `triangles` in
//! place of the reference, so every kind of mesh the scene contract knows takes a mesh file with
//! no code of its own. The readers count before they allocate and refuse a mesh over the
//! [`MeshLimits`] they are given, so a hostile file costs no more than its size. This module
//! uses only [`scene`](crate::scene) (for the field errors it reports); its one I/O is reading
//! the local files `drape run` names.

mod glb;
mod mesh;
mod obj;
mod reference;

pub use glb::{GlbError, GlbPlace, read_glb};
pub use mesh::{CompactError, Mesh, MeshFormat, MeshLimits, ReadError, asset_id, read_mesh};
pub use obj::{ObjError, read_obj};
pub use reference::{
    MeshSource, Reference, has_references, is_asset_id, put_mesh, referenced_assets, resolve_files,
};

#[cfg(test)]
mod tests;
