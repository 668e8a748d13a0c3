//! The colliders a run records beside its frames, so that a result shows the whole scene: each
//! collider's shape as the scene gives it (after defaults, and for a mesh after its static
//! transform), and for one that moves, the rigid transform at each recorded frame.

use crate::solver::{Collider, Shape};

/// A collider's shape, in the scene's coordinates, in metres.
#[derive(Clone, Debug, PartialEq)]
pub enum ColliderShape {
    /// The solid half-space behind a plane.
    Plane {
        /// A point on the plane.
        point: [f64; 3],
        /// The side particles stay on (not necessarily unit length).
        normal: [f64; 3],
    },
    /// A solid ball.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// A solid axis-aligned box.
    Box {
        /// Centre.
        center: [f64; 3],
        /// Half its size along x, y and z.
        half_extents: [f64; 3],
    },
    /// A solid cylinder with its axis along y.
    Cylinder {
        /// The middle of its axis.
        center: [f64; 3],
        /// Radius.
        radius: f64,
        /// Height.
        height: f64,
    },
    /// A triangle mesh.
    Mesh {
        /// Vertex positions, 3 per vertex.
        vertices: Vec<f64>,
        /// Vertex indices, 3 per triangle.
        triangles: Vec<[u32; 3]>,
    },
}

impl ColliderShape {
    /// The `type` the scene and the result name it by.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::Plane { .. } => "plane",
            Self::Sphere { .. } => "sphere",
            Self::Box { .. } => "box",
            Self::Cylinder { .. } => "cylinder",
            Self::Mesh { .. } => "mesh",
        }
    }
}

/// A rigid motion: rotate by `rotation`, then move by `translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidTransform {
    /// Displacement, in metres.
    pub translation: [f64; 3],
    /// Unit quaternion `[x, y, z, w]`.
    pub rotation: [f64; 4],
}

/// One collider of a run, as a result carries it.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedCollider {
    /// `collider:<index>`, the index in the scene's `colliders`.
    pub name: String,
    /// Where it is as the scene defines it.
    pub shape: ColliderShape,
    /// For a collider that moves: the transform taking `shape` to where the collider is at each
    /// recorded frame (as many as the recording's frames, in order).
    pub frames: Option<Vec<RigidTransform>>,
}

impl RecordedCollider {
    /// The name of the collider at `index` in the scene.
    pub fn name_of(index: usize) -> String {
        format!("collider:{index}")
    }

    /// The solver's collider at `index` in the scene, standing still.
    pub fn from_solver(index: usize, collider: &Collider) -> Self {
        let shape = match &collider.shape {
            Shape::Plane { point, normal } => {
                ColliderShape::Plane { point: point.to_array(), normal: normal.to_array() }
            }
            &Shape::Sphere { center, radius } => ColliderShape::Sphere { center: center.to_array(), radius },
            Shape::Box { center, half_extents } => {
                ColliderShape::Box { center: center.to_array(), half_extents: half_extents.to_array() }
            }
            &Shape::Cylinder { center, radius, height } => {
                ColliderShape::Cylinder { center: center.to_array(), radius, height }
            }
            Shape::Mesh { surface, .. } => ColliderShape::Mesh {
                vertices: surface.vertices.iter().flat_map(|v| v.to_array()).collect(),
                triangles: surface.triangles.clone(),
            },
        };
        Self { name: Self::name_of(index), shape, frames: None }
    }
}
