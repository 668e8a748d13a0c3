//! How large a step the explicit integrators can take, and the watch that stops a run that
//! diverges anyway.
//!
//! The bound is Gershgorin's on `M⁻¹K` with damping: with `ω̂² = maxᵢ 2 Σⱼ kᵢⱼ / mᵢ` and
//! `ĉ = maxᵢ (drag + 2 Σⱼ cᵢⱼ / mᵢ)` over free particles, a damped oscillator of frequency up to
//! `ω̂` and damping rate up to `ĉ` stays bounded under symplectic Euler for
//! `h < 4 / (ĉ + √(ĉ² + 4ω̂²))`, which is `2/ω̂` without damping. A bending hinge adds its row
//! of `M⁻¹ c K Kᵀ` the same way.

use crate::solver::model::Model;

/// The step bound of the module docs, in seconds, or `None` when nothing limits the step
/// (no springs and no drag on any free particle).
pub fn stable_step(model: &Model, drag: f64) -> Option<f64> {
    let n = model.particle_count();
    let mut stiffness = vec![0.0; n];
    let mut damping = vec![0.0; n];
    for s in &model.springs {
        for p in [s.i as usize, s.j as usize] {
            stiffness[p] += s.stiffness;
            damping[p] += s.damping;
        }
    }
    // A hinge's row of `c K Kᵀ` sums to `c |Kᵢ| Σⱼ |Kⱼ|`; halved, as the springs' `2 Σ k` doubles.
    for h in &model.bending {
        let total: f64 = h.weights.iter().map(|w| w.abs()).sum();
        for (&p, w) in h.vertices.iter().zip(h.weights) {
            stiffness[p as usize] += 0.5 * h.stiffness * w.abs() * total;
            damping[p as usize] += 0.5 * h.damping * w.abs() * total;
        }
    }
    let free = (0..n).filter(|&p| !model.pinned[p]);
    let (omega2, c) = free.fold((0.0f64, 0.0f64), |(w, c), p| {
        let m = model.masses[p];
        (w.max(2.0 * stiffness[p] / m), c.max(drag.max(0.0) + 2.0 * damping[p] / m))
    });
    let bound = 4.0 / (c + (c * c + 4.0 * omega2).sqrt());
    bound.is_finite().then_some(bound)
}

/// Why a run was stopped as diverged.
#[derive(Clone, Debug, PartialEq)]
pub enum DivergenceReason {
    /// A position or velocity became infinite or NaN.
    NonFinite,
    /// The kinetic energy grew past any amount the scene's energy sources can supply.
    EnergyRunaway {
        /// Kinetic energy when the run was stopped, in joules.
        kinetic: f64,
        /// The largest kinetic energy the watch accepts for this scene, in joules.
        limit: f64,
    },
}

impl std::fmt::Display for DivergenceReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NonFinite => write!(f, "a position or velocity became non-finite"),
            Self::EnergyRunaway { kinetic, limit } => write!(
                f,
                "kinetic energy ran away to {kinetic:.3e} J, beyond the {limit:.3e} J this scene can hold"
            ),
        }
    }
}

/// A run that stopped because its state blew up.
#[derive(Clone, Debug, PartialEq)]
pub struct Divergence {
    /// The step after which the state was found bad (1-based: the first step is 1).
    pub step: u64,
    /// Simulated time at that step, in seconds.
    pub time: f64,
    /// What went wrong.
    pub reason: DivergenceReason,
}

/// The kinetic energy above which a run counts as diverged, in joules.
///
/// A scene can hold no more than its initial kinetic and spring energy, plus what gravity can
/// release over the scene's extent and a metre beyond, plus the kinetic energy of every particle
/// moving with the wind. Runaway means a thousand times that: far beyond any physical motion
/// (symplectic Euler just inside its stability limit, at h·ω = 1.98, swings to 50 times its
/// energy), and reached within a few dozen steps by an exponential blow-up. A factor much larger
/// would miss instabilities that saturate, such as a spring whose blown-up swing carries its mass
/// through its anchor.
pub fn runaway_limit(initial_energy: f64, released_energy: f64) -> f64 {
    const FACTOR: f64 = 1e3;
    FACTOR * (initial_energy + released_energy).max(1e-9)
}
