//! What accelerates the particles. [`dynamics`] sums every force of a scene; the other modules
//! are the forces themselves: damped springs, evaluated one by one ([`springs`]), in vector
//! blocks along runs of particles ([`spring_runs`]) or along the rows of a cloth grid, dihedral
//! bending on the interior edges of a surface ([`hinges`]), and wind on the surface triangles.

pub(crate) mod bending;
pub(crate) mod body;
pub(crate) mod dynamics;
pub(crate) mod grid;
pub(crate) mod spring_blocks;
pub(crate) mod spring_runs;
pub(crate) mod springs;
pub(crate) mod wind;
