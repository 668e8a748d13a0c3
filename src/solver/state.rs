//! Where the particles are and how fast they move: the part of a simulation that a step changes.

use crate::solver::math::real::Real;
use crate::solver::math::vectors::Vectors;

/// Positions and velocities, one entry per particle, each stored one array per axis.
#[derive(Clone, Debug, Default)]
pub struct State<T> {
    /// Positions, in metres.
    pub positions: Vectors<T>,
    /// Velocities, in m/s.
    pub velocities: Vectors<T>,
}

impl<T: Real> State<T> {
    /// The number of particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}
