//! What a step enforces after the integrator has moved the particles: springs kept within a
//! strain limit, particles kept apart from each other (self-collision), and colliders they
//! cannot enter (contacts). Each works by projection on the positions and velocities, not by
//! forces.

pub(crate) mod contacts;
pub(crate) mod self_collision;
pub(crate) mod strain_limit;
