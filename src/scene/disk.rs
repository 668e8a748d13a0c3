//! A cloth of `shape: disk`: how its fields read, what it must meet, and the solver body it
//! builds.
//!
//! `resolution: [n, n]` means `n` particles across the diameter, as for a rectangle along a side:
//! the disk has `rings = ⌊n / 2⌋` rings around a centre particle, so a diameter carries `n`
//! particles when `n` is odd and `n + 1` when it is even (the centre is always a particle). Both
//! entries must be equal. `size` does not apply. A pin `[ring, k]` is the `k`-th particle of ring
//! `ring` (0 is the centre, whose only particle is `[0, 0]`; ring `r ≥ 1` has `6r`, counted
//! counter-clockwise seen from above from the one just past +x), and its index in results is
//! `1 + 3r(r - 1) + k` ([`solver::disk_index`](crate::solver::disk_index)).

use glam::DVec3;

use super::error::FieldError;
use super::types::{ClothSpec, OrientationName};
use crate::solver::{self, SpringParams};

/// A disk's diameter when the scene gives none, in metres.
pub const DEFAULT_DIAMETER: f64 = 1.0;

impl ClothSpec {
    /// A disk's rings around its centre particle.
    pub fn disk_rings(&self) -> usize {
        self.resolution[0] / 2
    }

    /// A disk's diameter, given or defaulted, in metres.
    pub fn disk_diameter(&self) -> f64 {
        self.diameter.unwrap_or(DEFAULT_DIAMETER)
    }

    /// A disk's particles, `1 + 3 rings (rings + 1)` (saturating).
    pub(super) fn disk_particle_count(&self) -> u64 {
        let rings = self.disk_rings() as u64;
        rings.saturating_mul(rings.saturating_add(1)).saturating_mul(3).saturating_add(1)
    }

    /// A disk's springs, exactly: `9 rings² + 3 rings` edges and a bending spring across each of
    /// the `9 rings² - 3 rings` interior ones (saturating).
    pub(super) fn disk_spring_count(&self) -> u64 {
        let rings = self.disk_rings() as u64;
        rings.saturating_mul(rings).saturating_mul(18)
    }

    /// What a disk must meet beyond the fields it shares with a rectangle, each at its pointer
    /// below `at`: a square resolution and pins on its rings.
    pub(super) fn disk_problems(&self, at: &str) -> Vec<FieldError> {
        let mut problems = Vec::new();
        let [n, other] = self.resolution;
        if other != n {
            problems.push(FieldError::new(
                format!("{at}/resolution/1"),
                format!("a disk's resolution is [n, n], n particles across its diameter; got [{n}, {other}]"),
            ));
        }
        let rings = self.disk_rings();
        for (p, &[ring, k]) in self.pin.iter().enumerate() {
            if ring > rings {
                problems.push(FieldError::new(
                    format!("{at}/pin/{p}/0"),
                    format!("ring {ring} is out of range: the disk has rings 0 to {rings}"),
                ));
            } else if k >= solver::disk_ring_size(ring) {
                problems.push(FieldError::new(
                    format!("{at}/pin/{p}/1"),
                    format!("particle {k} is out of range: ring {ring} has {}", solver::disk_ring_size(ring)),
                ));
            }
        }
        problems
    }

    /// The solver's disk for this cloth.
    pub(super) fn solver_disk(&self) -> solver::Disk {
        let params = |s: super::types::SpringSpec| SpringParams { stiffness: s.k, damping: s.damping };
        solver::Disk {
            diameter: self.disk_diameter(),
            rings: self.disk_rings(),
            center: DVec3::from_array(self.center),
            orientation: match self.orientation {
                OrientationName::Horizontal => solver::Orientation::Horizontal,
                OrientationName::Vertical => solver::Orientation::Vertical,
            },
            mass: self.mass,
            velocity: DVec3::from_array(self.velocity),
            structural: params(self.springs.structural),
            bending: params(self.springs.bending),
            pins: self.pin.clone(),
        }
    }
}

#[cfg(test)]
mod tests;
