//! A scene at about half the resolution: the companion of the spatial error estimate
//! (`error_estimate: "resolution"`), and what a scene must be to have one.
//!
//! Each cloth of `n` particles along a side becomes one of `(n + 1) / 2`. A grid of `2^k + 1`
//! particles keeps every other particle of the finer one, so the two share those particles
//! exactly; any other `n` gives particles that fall between the finer one's (`32 → 16`: spacings
//! of 1/31 and 1/15 of the side), where [`MaterialPoints`](super::MaterialPoints) reads the finer
//! cloth by interpolation. A disk of `R` rings becomes one of `(R + 1) / 2` rings. A pin goes to
//! the coarser particle nearest its material point (the same particle, for a grid of `2^k + 1`
//! and a pin at an even index or a corner).
//!
//! Only a cloth with a `material` is the same cloth at another resolution: spring constants
//! given per spring would make another material at another spacing. So every body must be one,
//! with at least 9 particles along each side (4 rings for a disk), which leaves a quarter
//! resolution of at least 3 (1 ring), and each companion must itself be a valid scene (a
//! material's springs and masses stay in range at its spacing).

use super::error::FieldError;
use super::types::{Body, ClothShape, ClothSpec, ErrorEstimateName, Scene};
use crate::solver;

/// The fewest particles along a cloth's side for a spatial estimate: its companion at a quarter
/// of the resolution keeps 3.
pub const MIN_RESOLUTION_FOR_ESTIMATE: usize = 9;
/// The fewest rings of a disk for a spatial estimate: its companion at a quarter keeps 1.
pub const MIN_RINGS_FOR_ESTIMATE: usize = 4;

/// Particles along a side at about half the resolution: `(n + 1) / 2`, which keeps every other
/// particle of a grid of `2^k + 1`.
pub fn coarser_count(n: usize) -> usize {
    n.div_ceil(2)
}

impl Scene {
    /// The same scene with every cloth at about half its resolution, estimating nothing; `None`
    /// when a body is not a cloth.
    pub fn coarsened(&self) -> Option<Scene> {
        let bodies = self
            .bodies
            .iter()
            .map(|body| match body {
                Body::Cloth(c) => Some(Body::Cloth(coarsened_cloth(c))),
                _ => None,
            })
            .collect::<Option<Vec<_>>>()?;
        Some(Scene { bodies, error_estimate: ErrorEstimateName::None, ..self.clone() })
    }

    /// Why the scene cannot have a spatial error estimate, at `/error_estimate`; empty when it
    /// can. Read only of a scene whose other fields are valid.
    pub(super) fn resolution_problems(&self) -> Vec<FieldError> {
        let refuse = |detail: String| vec![FieldError::new("/error_estimate", detail)];
        for (index, body) in self.bodies.iter().enumerate() {
            let at = format!("/bodies/{index}");
            let Body::Cloth(cloth) = body else {
                return refuse(format!(
                    "`resolution` compares the scene with itself at half the resolution, which needs \
                     every body to be a cloth with a `material`; {at} is a {}",
                    body.type_name()
                ));
            };
            if cloth.material.is_none() {
                return refuse(format!(
                    "`resolution` needs every cloth to have a `material` ({at} has spring constants, \
                     which describe another material at another spacing)"
                ));
            }
            match cloth.shape {
                ClothShape::Rectangle
                    if cloth.resolution.iter().any(|&n| n < MIN_RESOLUTION_FOR_ESTIMATE) =>
                {
                    return refuse(format!(
                        "`resolution` needs at least {MIN_RESOLUTION_FOR_ESTIMATE} particles along each \
                         side, so that the companion at a quarter of the resolution keeps 3; {at}/resolution \
                         is {:?}",
                        cloth.resolution
                    ));
                }
                ClothShape::Disk if cloth.disk_rings() < MIN_RINGS_FOR_ESTIMATE => {
                    return refuse(format!(
                        "`resolution` needs a disk of at least {MIN_RINGS_FOR_ESTIMATE} rings (resolution \
                         {}), so that the companion at a quarter of the resolution keeps 1; {at} has {}",
                        2 * MIN_RINGS_FOR_ESTIMATE,
                        cloth.disk_rings()
                    ));
                }
                _ => {}
            }
        }
        let Some(half) = self.coarsened() else { return Vec::new() };
        for companion in [half.clone(), half.coarsened().unwrap_or(half)] {
            if let Some(problem) = companion.problems().into_iter().next() {
                return refuse(format!(
                    "the companion at {} would not be a valid scene: {}: {}",
                    resolutions(&companion),
                    problem.pointer,
                    problem.detail
                ));
            }
        }
        Vec::new()
    }
}

/// The bodies' resolutions, in words.
fn resolutions(scene: &Scene) -> String {
    let each: Vec<String> = scene
        .bodies
        .iter()
        .map(|body| match body {
            Body::Cloth(c) => format!("{:?}", c.resolution),
            other => other.type_name().to_string(),
        })
        .collect();
    format!("resolution {}", each.join(", "))
}

fn coarsened_cloth(fine: &ClothSpec) -> ClothSpec {
    match fine.shape {
        ClothShape::Rectangle => {
            let resolution = fine.resolution.map(coarser_count);
            let nearest = |index: usize, axis: usize| {
                let (n, m) = (fine.resolution[axis], resolution[axis]);
                if n < 2 || m < 2 {
                    return 0;
                }
                ((index * (m - 1)) as f64 / (n - 1) as f64).round() as usize
            };
            let pin = fine.pin.iter().map(|&[i, j]| [nearest(i, 0), nearest(j, 1)]).collect();
            ClothSpec { resolution, pin, ..fine.clone() }
        }
        ClothShape::Disk => {
            let (rings, coarse_rings) = (fine.disk_rings(), coarser_count(fine.disk_rings()));
            let pin = fine
                .pin
                .iter()
                .map(|&[ring, k]| nearest_disk_particle(ring, k, rings, coarse_rings))
                .collect();
            let n = 2 * coarse_rings + 1;
            ClothSpec { resolution: [n, n], pin, ..fine.clone() }
        }
    }
}

/// The particle `[ring, k]` of a disk of `coarse_rings` rings nearest particle `[ring, k]` of one
/// of `rings` rings, in the unit disk's layout ([`solver::disk_layout`]).
fn nearest_disk_particle(ring: usize, k: usize, rings: usize, coarse_rings: usize) -> [usize; 2] {
    if ring == 0 || rings == 0 {
        return [0, 0];
    }
    let coarse_ring = ((ring * coarse_rings) as f64 / rings as f64).round() as usize;
    if coarse_ring == 0 {
        return [0, 0];
    }
    // Particle k of ring r is at angle 2π (k + ½) / 6r.
    let turn = (k as f64 + 0.5) / solver::disk_ring_size(ring) as f64;
    let size = solver::disk_ring_size(coarse_ring);
    let coarse_k = (turn * size as f64 - 0.5).round().rem_euclid(size as f64) as usize;
    [coarse_ring, coarse_k.min(size - 1)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_of_two_to_the_k_plus_one_keeps_every_other_particle_and_its_pins() {
        assert_eq!([33, 17, 9, 5, 3].map(coarser_count), [17, 9, 5, 3, 2]);
        assert_eq!([32, 16, 10].map(coarser_count), [16, 8, 5]);
        let fine = ClothSpec {
            resolution: [17, 9],
            pin: vec![[0, 0], [16, 0], [8, 8], [3, 3]],
            ..ClothSpec::default()
        };
        let coarse = coarsened_cloth(&fine);
        assert_eq!(coarse.resolution, [9, 5]);
        // Corners and even indices are the same material point; [3, 3] lies halfway between
        // coarse particles along both axes (1.5 coarse spacings in), and goes to the upper one.
        assert_eq!(coarse.pin, [[0, 0], [8, 0], [4, 4], [2, 2]]);
    }

    #[test]
    fn a_disk_keeps_its_centre_and_pins_the_nearest_particle_of_half_the_rings() {
        assert_eq!(nearest_disk_particle(0, 0, 8, 4), [0, 0]);
        // Ring 8 has 48 particles; particle 0 is at 0.5/48 of a turn, and ring 4's first (of 24)
        // at 0.5/24: the nearest. Particle 47 is at 47.5/48, nearest ring 4's last, 23.5/24.
        assert_eq!(nearest_disk_particle(8, 0, 8, 4), [4, 0]);
        assert_eq!(nearest_disk_particle(8, 47, 8, 4), [4, 23]);
        // Particle 12 of ring 8 (a quarter turn and a bit) is 12.5/48 = 6.25/24: particle 6 (6.5/24).
        assert_eq!(nearest_disk_particle(8, 12, 8, 4), [4, 6]);
        let fine = ClothSpec { shape: ClothShape::Disk, resolution: [17, 17], ..ClothSpec::default() };
        assert_eq!(coarsened_cloth(&fine).resolution, [9, 9]);
        assert_eq!(coarsened_cloth(&coarsened_cloth(&fine)).disk_rings(), 2);
    }
}
