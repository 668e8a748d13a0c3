//! Measures of a state: energies and strain. Computed only when asked for, never in a step.

use crate::solver::forces::dynamics::Dynamics;
use crate::solver::forces::springs;
use crate::solver::math::real::Real;
use crate::solver::state::State;

/// The mechanical energy of a state, in joules.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// `½ Σ m v²`.
    pub kinetic: f64,
    /// `-Σ m g·x`: zero at the origin, growing with height against gravity.
    pub gravitational: f64,
    /// The elastic energy: `½ Σ k (l - L)²` over the springs, plus the bending hinges'.
    pub spring: f64,
}

impl Energy {
    /// The sum of the three parts.
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravitational + self.spring
    }
}

/// Kinetic energy `½ Σ m v²`, in joules.
pub fn kinetic_energy<T: Real>(dynamics: &Dynamics<T>, state: &State<T>) -> f64 {
    0.5 * dynamics
        .masses
        .iter()
        .zip(state.velocities.iter())
        .map(|(&m, v)| m.to_f64() * v.to_dvec3().length_squared())
        .sum::<f64>()
}

/// The three energies of a state.
pub fn energy<T: Real>(dynamics: &Dynamics<T>, state: &State<T>) -> Energy {
    let gravity = dynamics.gravity.map(|g| g.to_dvec3()).unwrap_or_default();
    // Adding zero turns the -0 of a scene without gravity into 0.
    let gravitational = 0.0
        - dynamics
            .masses
            .iter()
            .zip(state.positions.iter())
            .map(|(&m, x)| m.to_f64() * gravity.dot(x.to_dvec3()))
            .sum::<f64>();
    Energy {
        kinetic: kinetic_energy(dynamics, state),
        gravitational,
        spring: springs::energy(&dynamics.springs, &state.positions)
            + dynamics.bending.as_ref().map_or(0.0, |h| h.energy(&state.positions)),
    }
}
