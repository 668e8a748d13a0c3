//! Where a collider or a mesh body is put: its points as the scene gives them are scaled by
//! `scale` about the origin, rotated by `rotation` and moved by `translation`,
//! `x ↦ translation + rotation · (scale · x)`.
//!
//! The scale is one positive number: a sphere, a box and a cylinder stay what they are under a
//! uniform scale (a sphere's radius, a box's half extents and a cylinder's radius and height
//! scale with it), which a scale per axis would not give (an ellipsoid, or a cylinder that is not
//! round). A plane's point moves and its normal turns. A box and a cylinder are axis-aligned
//! shapes, so they take no rotation but the identity (a rotated box or cylinder is given as a
//! `mesh`). The rotation is a unit quaternion `[x, y, z, w]`, accepted when its norm is within
//! [`ROTATION_NORM_TOLERANCE`] of 1 (written with the digits JSON clients print) and normalised.

use glam::{DQuat, DVec3};

/// How far from 1 the norm of a rotation quaternion may be.
pub const ROTATION_NORM_TOLERANCE: f64 = 1e-6;

/// A scale, a rotation and a translation, applied in that order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Displacement, in metres.
    pub translation: [f64; 3],
    /// Unit quaternion `[x, y, z, w]`.
    pub rotation: [f64; 4],
    /// Uniform scale factor (positive).
    pub scale: f64,
}

impl Default for Placement {
    fn default() -> Self {
        Self { translation: [0.0; 3], rotation: IDENTITY_ROTATION, scale: 1.0 }
    }
}

/// The rotation that turns nothing.
pub const IDENTITY_ROTATION: [f64; 4] = [0.0, 0.0, 0.0, 1.0];

impl Placement {
    /// The rotation, normalised (a valid scene's is within the tolerance of unit length).
    pub fn quaternion(&self) -> DQuat {
        let q = DQuat::from_array(self.rotation);
        let length = q.length();
        if length > 0.0 && length.is_finite() { q / length } else { DQuat::IDENTITY }
    }

    /// Whether the rotation turns nothing (within the tolerance).
    pub fn is_unrotated(&self) -> bool {
        let [x, y, z, _] = self.rotation;
        x.abs().max(y.abs()).max(z.abs()) <= ROTATION_NORM_TOLERANCE
    }

    /// Where the point `x` goes.
    pub fn point(&self, x: DVec3) -> DVec3 {
        DVec3::from_array(self.translation) + self.quaternion() * (self.scale * x)
    }

    /// Where the direction `v` turns.
    pub fn direction(&self, v: DVec3) -> DVec3 {
        self.quaternion() * v
    }
}

pub(super) fn default_rotation() -> [f64; 4] {
    IDENTITY_ROTATION
}

pub(super) fn default_scale() -> f64 {
    1.0
}
