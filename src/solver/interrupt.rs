//! A flag another thread raises to stop a simulation part-way through a step.
//!
//! A step can be long: an implicit solve runs up to its iteration cap, a self-collision pass
//! visits every close pair. A [`Simulation`](crate::solver::simulation::Simulation) handed an
//! [`Interrupt`] looks at it at the start of each step, before self-collision, at every
//! iteration of its conjugate-gradient loops and every thousand rows of the smoothed-aggregation
//! preconditioner's refill, and gives up the step as soon as it is raised: the
//! step then returns [`StepError::Interrupted`](crate::solver::simulation::StepError::Interrupted).
//! The flag is one relaxed atomic load per look, nothing next to a sparse product, and a run that
//! is not interrupted takes exactly the same path, so its results do not change by a bit.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A shared flag: once raised, every simulation holding a clone of it stops at its next look.
#[derive(Clone, Debug, Default)]
pub struct Interrupt(Arc<AtomicBool>);

impl Interrupt {
    /// A flag not raised.
    pub fn new() -> Self {
        Self::default()
    }

    /// Raises the flag; it stays raised.
    pub fn raise(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether the flag was raised.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}
