//! The particle system a scene builds, in `f64`, before it is compiled into a simulation.
//!
//! A [`Model`] is plain data: particle positions, velocities, masses and pins, the spring list and
//! the surface triangles. Body builders ([`bodies`](crate::solver::bodies)) append to it; a
//! [`Simulation`](crate::solver::simulation::Simulation) converts it once to its own precision and layout.

use std::ops::Range;

use glam::DVec3;

/// Which family a spring belongs to; each family has its own stiffness and damping.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SpringKind {
    /// Between grid neighbours (or along mesh edges and chains): resists stretch.
    Structural,
    /// Across grid-cell diagonals: resists shear.
    Shear,
    /// Between particles two apart (or across a shared mesh edge): resists folding.
    Bending,
}

/// A damped spring between two particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring<T> {
    /// First particle.
    pub i: u32,
    /// Second particle.
    pub j: u32,
    /// Length at which the spring exerts no force, in metres.
    pub rest_length: T,
    /// Stiffness `k`, in N/m.
    pub stiffness: T,
    /// Damping along the spring `c`, in N·s/m.
    pub damping: T,
    /// The family the spring belongs to.
    pub kind: SpringKind,
}

/// A particle system: structure-of-arrays particle data, springs and surface triangles.
#[derive(Clone, Debug, Default)]
pub struct Model {
    /// Initial positions, in metres.
    pub positions: Vec<DVec3>,
    /// Initial velocities, in m/s (zero for pinned particles).
    pub velocities: Vec<DVec3>,
    /// Masses, in kg (every one positive).
    pub masses: Vec<f64>,
    /// Whether each particle is pinned where it starts.
    pub pinned: Vec<bool>,
    /// Every spring.
    pub springs: Vec<Spring<f64>>,
    /// Surface triangles, as particle indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// The bodies whose springs follow a grid stencil, which a simulation evaluates without
    /// the spring list.
    pub grids: Vec<SpringGrid>,
    /// Dihedral bending elements, one per interior edge of a body that bends by hinges.
    pub bending: Vec<BendingElement>,
}

/// A bending element on the edge `vertices[0]`–`vertices[1]` shared by the triangles whose far
/// vertices are `vertices[2]` and `vertices[3]`: energy `½ stiffness |Σₖ weights[k] xₖ|²` (see
/// [`hinges`](crate::solver::forces::bending)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BendingElement {
    /// The edge's two vertices, then the two far vertices.
    pub vertices: [u32; 4],
    /// The rest shape's cotangent weights (dimensionless; they sum to zero).
    pub weights: [f64; 4],
    /// In N/m: the bending rigidity over the two triangles' rest area.
    pub stiffness: f64,
    /// In N·s/m: the damping of the same mode.
    pub damping: f64,
}

/// A rectangular block of particles whose springs a fixed stencil generates.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringGrid {
    /// Index of particle `(0, 0)`; particle `(i, j)` is `first_particle + j * nx + i`.
    pub first_particle: usize,
    /// `[nx, ny]`.
    pub resolution: [usize; 2],
    /// The stencil's spring families as offsets `[ai, aj, bi, bj]`: each joins `(i + ai, j + aj)`
    /// to `(i + bi, j + bj)` for every `(i, j)` where both are on the grid, `i` fastest.
    pub stencil: Vec<[usize; 4]>,
    /// The springs the stencil generated, family after family, as a range of the spring list.
    pub springs: Range<usize>,
}

impl Model {
    /// The number of particles.
    pub fn particle_count(&self) -> usize {
        self.positions.len()
    }

    /// Appends particles with their masses and one shared initial velocity; returns their range.
    pub(crate) fn add_particles(
        &mut self,
        positions: impl IntoIterator<Item = DVec3>,
        mass_of: impl Fn(usize) -> f64,
        velocity: DVec3,
    ) -> Range<usize> {
        let start = self.positions.len();
        self.positions.extend(positions);
        let end = self.positions.len();
        self.masses.extend((0..end - start).map(mass_of));
        self.velocities.extend(std::iter::repeat_n(velocity, end - start));
        self.pinned.extend(std::iter::repeat_n(false, end - start));
        start..end
    }

    /// Adds a spring whose rest length is the particles' current distance.
    pub(crate) fn connect(&mut self, i: usize, j: usize, params: SpringParams, kind: SpringKind) {
        let rest_length = self.positions[i].distance(self.positions[j]);
        self.connect_with_rest(i, j, rest_length, params, kind);
    }

    /// Adds a spring with a given rest length.
    pub(crate) fn connect_with_rest(
        &mut self,
        i: usize,
        j: usize,
        rest_length: f64,
        params: SpringParams,
        kind: SpringKind,
    ) {
        self.springs.push(Spring {
            i: i as u32,
            j: j as u32,
            rest_length,
            stiffness: params.stiffness,
            damping: params.damping,
            kind,
        });
    }

    /// Pins a particle where it is: it keeps its position and has no velocity.
    pub(crate) fn pin(&mut self, particle: usize) {
        self.pinned[particle] = true;
        self.velocities[particle] = DVec3::ZERO;
    }

    /// The sum of every particle's mass, in kg.
    pub fn total_mass(&self) -> f64 {
        self.masses.iter().sum()
    }
}

/// Stiffness and damping shared by one family of springs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringParams {
    /// Stiffness `k`, in N/m.
    pub stiffness: f64,
    /// Damping along the spring, in N·s/m.
    pub damping: f64,
}
