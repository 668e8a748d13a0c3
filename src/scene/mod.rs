//! The public JSON contract for a scene: types, defaults, validation, and compilation into the
//! solver's inputs.
//!
//! Every field but `duration` and `bodies` has a default, stated on the field. Unknown fields are
//! refused. [`Scene::from_json`] returns either a scene in which every number is finite and
//! within its physical range, or every problem found, each naming its field by JSON Pointer
//! (RFC 6901). An integer field takes any number with no fractional part (`39` or `39.0`), as
//! JSON Schema's `integer` does. This module knows the solver's inputs but nothing of HTTP.

mod coarsen;
mod compile;
mod disk;
mod drape_tester;
mod error;
mod fabric_presets;
mod fabrics;
mod material_points;
mod parse;
mod placement;
mod types;
mod validate;
mod whole;

pub use coarsen::{MIN_RESOLUTION_FOR_ESTIMATE, MIN_RINGS_FOR_ESTIMATE, coarser_count};
pub use compile::{BodyInfo, Coarser, Compiled, DtSource};
pub use disk::DEFAULT_DIAMETER;
pub use drape_tester::DrapeTester;
pub use error::{FieldError, SceneError};
pub use fabric_presets::PRESETS as FABRIC_PRESETS;
pub use fabrics::{DEFAULT_DAMPING_TIME, FabricSpec};
pub use material_points::MaterialPoints;
pub use placement::{Placement, ROTATION_NORM_TOLERANCE};
pub use types::*;

#[cfg(test)]
mod mesh_collider_tests;
#[cfg(test)]
mod placement_tests;
#[cfg(test)]
mod tests;
