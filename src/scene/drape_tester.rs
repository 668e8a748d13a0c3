//! When a scene is a drape tester, and what the drape coefficient is measured against.
//!
//! A scene is a drape tester when it has exactly one cylinder collider (the support disk) and
//! exactly one cloth of shape `disk` (the specimen) whose diameter exceeds the cylinder's. The
//! specimen's area is its rest area (the sum of its triangles' areas as built, the inscribed
//! polygon of its rings), the support's area `π r²`, and the shadow is the specimen's final
//! projection along the cylinder's axis, y, onto the x-z plane. The coefficient itself is
//! computed at the end of a run, by [`run`](crate::run).

use std::ops::Range;

use super::types::{Body, ClothShape, ColliderSpec, Scene};
use crate::solver::Model;

/// A drape tester's specimen and support.
#[derive(Clone, Debug, PartialEq)]
pub struct DrapeTester {
    /// The specimen's triangles, as a range of the model's.
    pub triangles: Range<usize>,
    /// The specimen's rest area, in m².
    pub specimen_area: f64,
    /// The support disk's centre, `[x, z]`, in metres.
    pub support_center: [f64; 2],
    /// The support disk's radius, in metres.
    pub support_radius: f64,
}

impl DrapeTester {
    /// The tester in `scene`, whose bodies built `model` and own `body_triangles` of its
    /// triangles, one range per body; `None` when the scene is not one.
    pub(super) fn find(scene: &Scene, model: &Model, body_triangles: &[Range<usize>]) -> Option<Self> {
        // A support that moves is no drape tester; a placed one is measured where it is put.
        let [support @ ColliderSpec::Cylinder(cylinder)] = &scene.colliders[..] else {
            return None;
        };
        if cylinder.motion.is_some() {
            return None;
        }
        let placement = support.placement();
        let center = placement.point(glam::DVec3::from_array(cylinder.center));
        let radius = placement.scale * cylinder.radius;
        let mut disks = scene.bodies.iter().zip(body_triangles).filter_map(|(body, triangles)| match body {
            Body::Cloth(c) if c.shape == ClothShape::Disk => Some((c, triangles)),
            _ => None,
        });
        let (specimen, triangles) = disks.next()?;
        if disks.next().is_some() || specimen.disk_diameter() <= 2.0 * radius {
            return None;
        }
        let specimen_area = model.triangles[triangles.clone()]
            .iter()
            .map(|&[a, b, c]| {
                let p = |i: u32| model.positions[i as usize];
                0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length()
            })
            .sum();
        Some(Self {
            triangles: triangles.clone(),
            specimen_area,
            support_center: [center.x, center.z],
            support_radius: radius,
        })
    }

    /// The support disk's area, `π r²`, in m².
    pub fn support_area(&self) -> f64 {
        std::f64::consts::PI * self.support_radius * self.support_radius
    }
}
