//! When a step's conjugate-gradient solve stops.
//!
//! A solve starts from the last step's `Δv`. The residual of that guess,
//! `b − A Δv₍ₙ₋₁₎ = A (Δvₙ − Δv₍ₙ₋₁₎)`, is the system applied to how much this step's velocity
//! change differs from the last one's, `h²` times the change of acceleration: about twice
//! implicit Euler's local error in the velocity. Reducing the residual far below that buys no
//! accuracy the step has, so a solve stops once its residual is below `reduction` times the
//! guess's residual, which keeps the solve's error a fraction of the step's own. `tolerance`
//! times the right-hand side's norm is the other way to stop, for a guess that is already close,
//! and the only one with `reduction` 0 or for a run's first solve, whose guess is zero and whose
//! residual is the whole right-hand side; `max_iterations` is the cap.

/// The stopping rule of a step's solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Stopping {
    /// A residual below this times the right-hand side's norm ends the solve.
    pub tolerance: f64,
    /// A residual below this times the starting guess's residual ends the solve.
    pub reduction: f64,
    /// The iteration cap per solve.
    pub max_iterations: usize,
}

impl Stopping {
    /// The residual norm at which a solve whose right-hand side has norm `rhs_norm` and whose
    /// starting guess leaves `initial_residual` stops.
    pub fn target(&self, rhs_norm: f64, initial_residual: f64) -> f64 {
        (self.tolerance * rhs_norm).max(self.reduction * initial_residual)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_solve_stops_at_the_looser_of_its_two_targets() {
        let stopping = Stopping { tolerance: 1e-6, reduction: 0.01, max_iterations: 200 };
        assert_eq!(stopping.target(1.0, 1e-3), 1e-5);
        assert_eq!(stopping.target(1.0, 1e-5), 1e-6);
        let strict = Stopping { reduction: 0.0, ..stopping };
        assert_eq!(strict.target(2.0, 1.0), 2e-6);
    }
}
