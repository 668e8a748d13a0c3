//! The arithmetic the solver is written in, with no physics in it: the scalar trait that lets
//! one solver run in `f32` or `f64`, 3-vectors, per-axis arrays of them, and symmetric 3×3
//! blocks.

pub(crate) mod real;
pub(crate) mod sym3;
pub(crate) mod vec3;
pub(crate) mod vectors;
