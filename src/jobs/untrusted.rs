//! The whole path an untrusted scene takes before its first step, as one call: read and validate
//! the bytes, admit the scene under the [`Limits`], compile it, and build its simulation.
//!
//! The service takes these steps one by one (the API reads and validates, [`Jobs`](super::Jobs)
//! admits, a worker compiles and runs); [`check_untrusted`] takes them all at once, so that the
//! fuzz target (`tests/fuzz`) and the replay of its corpus (`tests/fuzz_replay.rs`) drive exactly
//! this code with any bytes. Whatever the bytes, it answers `Ok` or a refusal: a panic, a hang or
//! an allocation beyond what the limits allow is a bug.

use thiserror::Error;

use super::limits::Limits;
use super::record::Plan;
use crate::scene::{FieldError, Scene, SceneError};

/// Why untrusted bytes do not make a run.
#[derive(Debug, Error)]
pub enum Refusal {
    /// Not JSON, or not a valid scene.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A valid scene beyond the limits; each problem names the field to change.
    #[error("the scene exceeds the limits at {}", .0.iter().map(|e| e.pointer.as_str()).collect::<Vec<_>>().join(", "))]
    OverLimit(Vec<FieldError>),
}

/// Reads `bytes` as a scene, admits it under `limits`, compiles it and builds its simulation,
/// recorder and frame schedule, without taking a step. Gives the admitted run's plan.
pub fn check_untrusted(bytes: &[u8], limits: &Limits) -> Result<Plan, Refusal> {
    let scene = Scene::from_json(bytes)?;
    let admitted = limits.admit(&scene).map_err(Refusal::OverLimit)?;
    crate::run::prepare(&admitted.compiled);
    Ok(admitted.plan)
}
