//! The mass-spring solver: pure, synchronous and deterministic physics.
//!
//! It does no I/O and knows nothing of serde, HTTP or async; its inputs are plain Rust values.
//! A [`Model`] (particles, springs, triangles, built by the body builders) and a [`Config`]
//! (integrator, step, forces including wind, colliders, strain limit, self-collision) compile
//! into a [`Simulation`] in `f32` or `f64`, which holds only the stages the scene needs and steps
//! without allocating. Two runs of the same inputs give bit-identical results.

mod arrays;
mod bodies;
mod constraints;
mod diagnostics;
mod disk;
mod equilibrium;
mod fabric;
mod forces;
mod integrators;
mod interrupt;
mod math;
mod model;
mod motion;
mod normals;
pub mod parallel;
mod pin_motion;
mod simulation;
mod stability;
mod state;

#[cfg(test)]
mod tests;

pub use bodies::{Chain, Cloth, Lattice, Mesh, Orientation, vertex_areas};
#[cfg(test)]
pub(crate) use constraints::contacts::HOLD_STIFFNESS;
pub use constraints::contacts::{
    BVH_LEAF_SIZE, Collider, DEFAULT_FRICTION, Shape, TriangleBvh, TriangleSurface,
};
pub use constraints::self_collision::{PairCapReached, SelfCollision, candidate_pairs};
pub use diagnostics::Energy;
pub use disk::{Disk, disk_index, disk_layout, disk_particle_count, disk_ring_size};
pub use equilibrium::{Equilibrium, equilibrium};
pub use fabric::Fabric;
pub use forces::bending::isometric_hinges;
pub use forces::dynamics::Dynamics;
pub use forces::wind::{Gust, WindConfig, WindModel};
pub use integrators::{IntegratorKind, IntegratorSettings, LinearSolveStats};
pub use interrupt::Interrupt;
pub use math::real::Real;
pub use math::vec3::Vec3;
pub use math::vectors::Vectors;
pub use model::{BendingElement, Model, Spring, SpringGrid, SpringKind, SpringParams};
pub use motion::{Keyframe, Motion, Rigid};
pub use pin_motion::PinMotion;
pub use simulation::{Config, STAGE_NAMES, Simulation, StepError};
pub use stability::{Divergence, DivergenceReason, stable_step};
pub use state::State;
