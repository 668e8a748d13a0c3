//! Colliders: fixed shapes that particles cannot enter, with restitution and Coulomb friction.
//!
//! Contacts are resolved after the integrator and the constraints have moved the particles, by
//! projection rather than penalty forces (which would store and release energy). A free particle
//! found inside a shape (or exactly on its surface: touching) is moved to the surface, the shape's
//! outward normal `n` there is the contact normal, and if it approaches the surface (`v·n < 0`)
//! its velocity changes by
//!
//! - normal: `Δv_n = -(1 + e) v_n`, so it leaves with `-e v_n` (restitution `e` in [0, 1]);
//! - tangential: its tangential speed drops by `μ Δv_n` (Coulomb friction `μ`), and to zero
//!   when that is enough: it sticks.
//!
//! Neither part can add kinetic energy. A particle that leaves the surface is not touched.
//! Particles that start inside are projected out when the simulation is built and again by
//! each step. Pinned particles are never moved.
//!
//! With implicit Euler, whose steps are large, contacts also carry from one step into the next
//! (`carried_friction.rs`). A particle a fixed collider stopped is held against it in the next
//! solve, by a stiff spring that the solve takes implicitly, so that the sheet around it sees the
//! surface; the projection then removes what little inward motion is left, and friction's bound
//! counts that spring's impulse too. The spring acts along the normal for a sliding particle,
//! whose steady friction is given to it before the next step moves it (so that the projection's
//! friction above applies only what that carried part did not), and toward the point where it
//! stopped for a particle that friction stopped, which is stuck there until its spring's pull
//! leaves Coulomb's cone.
//!
//! Fast particles do not tunnel. A plane is a half-space: a particle that crossed it during a
//! step is found behind it, so the end-of-step test is already continuous. Against a sphere the
//! segment from the start-of-step position to the end is tested: a particle that went through the
//! ball within the step, or ended past the centre (where the nearest surface point is on the far
//! side), is put where it first met the surface. A path that only grazes the surface (as a particle
//! sliding over the ball does) is not a passage. The start-of-step positions live in a buffer made
//! once, only when a scene has colliders, and are copied into it only when a collider tests paths
//! (a sphere, a mesh, or a moving collider). Boxes and cylinders are tested at the end of the step.
//! A triangle mesh (`mesh.rs`, through the hierarchy of `triangle_bvh.rs`) tests the segment
//! against its triangles, so that a fast particle stops even at a sheet with no inside.
//!
//! Each shape has its own file: the test "is this point inside, and where is the nearest surface
//! point", the cheap branch-free test it starts with (`reaches`, and for the sphere `dips`), and
//! the signed distance used to check results. A step tests a block of particles against a shape
//! with the cheap test in vector lanes and gives only those that pass the exact one (a fixed
//! plane, whose exact test is as cheap, resolves the whole block in lanes, and a fixed mesh
//! resolves so the particles resting over one triangle's face, `mesh_lanes.rs`); particles
//! are independent, so a large state is resolved in bands on the solver's threads, with the same
//! result.

mod axis_box;
mod carried_friction;
mod cylinder;
mod mesh;
mod mesh_lanes;
mod nearby_triangles;
mod plane;
mod sphere;
mod surface_topology;
mod triangle;
mod triangle_bvh;

pub use triangle_bvh::{LEAF_SIZE as BVH_LEAF_SIZE, TriangleBvh};

#[cfg(test)]
pub(crate) mod mesh_tests;
#[cfg(test)]
mod moving_tests;
#[cfg(test)]
mod tests;

use glam::DVec3;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::solver::forces::spring_blocks::{self as blocks, LANES};
use crate::solver::integrators::implicit::Holds;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::motion::{Motion, Rigid};
use crate::solver::parallel;
use crate::solver::state::State;

pub(crate) use carried_friction::HOLD_STIFFNESS;
use carried_friction::{BandFriction, Carried, CarriedFriction, Given, Next};
use nearby_triangles::{NearbyBand, NearbyTriangles};

/// The friction coefficient a collider has when the scene gives none.
pub const DEFAULT_FRICTION: f64 = 0.3;

/// The triangles of a mesh collider.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleSurface {
    /// Vertex positions, in metres.
    pub vertices: Vec<DVec3>,
    /// Vertex indices, three per triangle, each below `vertices.len()`.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleSurface {
    /// Whether it is closed: every edge of its triangles of positive area shared by exactly
    /// two of them, once in each direction (vertices at one position counted as one).
    pub fn is_closed(&self) -> bool {
        surface_topology::Topology::of(self).pseudo_normals.is_some()
    }
}

/// A collider's shape.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// The half-space behind a plane through `point` with outward `normal` (any non-zero length).
    Plane {
        /// A point on the plane, in metres.
        point: DVec3,
        /// The side particles stay on (need not be unit length; not zero).
        normal: DVec3,
    },
    /// A solid ball.
    Sphere {
        /// Centre, in metres.
        center: DVec3,
        /// Radius, in metres (positive).
        radius: f64,
    },
    /// A solid axis-aligned box.
    Box {
        /// Centre, in metres.
        center: DVec3,
        /// Half the size along x, y and z, in metres (each positive).
        half_extents: DVec3,
    },
    /// A solid cylinder with its axis along y, like a round table.
    Cylinder {
        /// The middle of its axis, in metres; the top is at `center.y + height / 2`.
        center: DVec3,
        /// Radius, in metres (positive).
        radius: f64,
        /// Height, in metres (positive).
        height: f64,
    },
    /// A triangle mesh: a two-sided sheet, or a solid when it is closed.
    Mesh {
        /// Its triangles, shared by the copies of a configuration.
        surface: Arc<TriangleSurface>,
        /// The distance particles keep from its triangles, in metres (positive).
        thickness: f64,
    },
}

impl Shape {
    /// The name the public contract uses, which is also the stage's name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Plane { .. } => "plane",
            Self::Sphere { .. } => "sphere",
            Self::Box { .. } => "box",
            Self::Cylinder { .. } => "cylinder",
            Self::Mesh { .. } => "mesh",
        }
    }

    /// Signed distance from `p` to the surface, in metres: negative inside (for a mesh, the
    /// distance to its triangles, negative only inside a closed one; the thickness not counted).
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        ShapeIn::<f64>::new(self).signed_distance(Vec3::from_dvec3(p))
    }
}

/// A shape with the response of its surface, fixed or moving.
#[derive(Clone, Debug, PartialEq)]
pub struct Collider {
    /// Where it is; for a moving collider, where it is in its own frame, which its motion moves.
    pub shape: Shape,
    /// Coulomb friction coefficient `μ` (at least 0).
    pub friction: f64,
    /// Restitution `e`, in [0, 1]: the fraction of approaching normal speed a particle leaves with.
    pub restitution: f64,
    /// How it moves, if it does.
    pub motion: Option<Motion>,
}

/// A point on a surface and the outward unit normal there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Surface<T> {
    pub point: Vec3<T>,
    pub normal: Vec3<T>,
}

/// A shape in the simulation's precision.
#[derive(Clone, Debug)]
enum ShapeIn<T> {
    Plane(plane::Plane<T>),
    Sphere(sphere::Sphere<T>),
    Box(axis_box::AxisBox<T>),
    Cylinder(cylinder::Cylinder<T>),
    Mesh(Box<mesh::MeshShape<T>>),
}

impl<T: Real> ShapeIn<T> {
    fn new(shape: &Shape) -> Self {
        match *shape {
            Shape::Plane { point, normal } => Self::Plane(plane::Plane::new(point, normal)),
            Shape::Sphere { center, radius } => Self::Sphere(sphere::Sphere::new(center, radius)),
            Shape::Box { center, half_extents } => Self::Box(axis_box::AxisBox::new(center, half_extents)),
            Shape::Cylinder { center, radius, height } => {
                Self::Cylinder(cylinder::Cylinder::new(center, radius, height))
            }
            Shape::Mesh { ref surface, thickness } => {
                Self::Mesh(Box::new(mesh::MeshShape::new(surface, thickness)))
            }
        }
    }

    fn signed_distance(&self, x: Vec3<T>) -> T {
        match self {
            Self::Plane(s) => s.signed_distance(x),
            Self::Sphere(s) => s.signed_distance(x),
            Self::Box(s) => s.signed_distance(x),
            Self::Cylinder(s) => s.signed_distance(x),
            Self::Mesh(s) => s.signed_distance(x),
        }
    }

    /// The nearest surface point and its normal, when `x` is inside or on the surface.
    fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        match self {
            Self::Plane(s) => s.inside(x),
            Self::Sphere(s) => s.inside(x),
            Self::Box(s) => s.inside(x),
            Self::Cylinder(s) => s.inside(x),
            Self::Mesh(s) => s.inside(x),
        }
    }

    /// For the [`LANES`] particles from `first`, moving from `start` to `end`: whether each
    /// passes the test its [`contact`](Self::contact) starts with, so that no particle with a
    /// contact is left out. Branch-free, one lane per particle, so that it compiles to vector
    /// instructions.
    fn reaches_lanes(&self, start: [&[T]; 3], end: [&[T]; 3], first: usize) -> [bool; LANES] {
        let (start, end) = (blocks::axes(start, first), blocks::axes(end, first));
        let at =
            |axes: &[&[T; LANES]; 3], lane: usize| Vec3::new(axes[0][lane], axes[1][lane], axes[2][lane]);
        let mut reaches = [false; LANES];
        match self {
            Self::Plane(s) => (0..LANES).for_each(|l| reaches[l] = s.reaches(at(&end, l))),
            Self::Sphere(s) => (0..LANES)
                .for_each(|l| reaches[l] = s.reaches(at(&end, l)) | s.dips(at(&start, l), at(&end, l))),
            Self::Box(s) => (0..LANES).for_each(|l| reaches[l] = s.reaches(at(&end, l))),
            Self::Cylinder(s) => (0..LANES).for_each(|l| reaches[l] = s.reaches(at(&end, l))),
            Self::Mesh(s) => (0..LANES).for_each(|l| reaches[l] = s.reaches(at(&start, l), at(&end, l))),
        }
        reaches
    }

    /// Where a particle moving from `start` to `end` (outside at both ends) met the surface, for
    /// the shapes a particle can cross within one step without ending inside; a mesh uses the
    /// triangles kept near the particle, when given `nearby` (see [`NearbyTriangles`]) and the
    /// particle's index in its band.
    fn contact(
        &self,
        start: Vec3<T>,
        end: Vec3<T>,
        nearby: Option<(&mut NearbyBand<T>, usize)>,
    ) -> Option<Surface<T>> {
        match self {
            Self::Sphere(s) => {
                let entry = || s.entry(start, end);
                match s.inside(end) {
                    // Ended past the centre: the nearest point would be on the far side.
                    Some(nearest) => match entry() {
                        Some(first) if first.normal.dot(nearest.normal) < T::ZERO => Some(first),
                        _ => Some(nearest),
                    },
                    None => s.passage(start, end),
                }
            }
            Self::Mesh(s) => s.contact(start, end, nearby),
            other => other.inside(end),
        }
    }
}

#[derive(Clone, Debug)]
struct ColliderIn<T> {
    shape: ShapeIn<T>,
    friction: T,
    restitution: T,
    motion: Option<Motion>,
    /// For a moving collider, where the step takes it.
    moving: Option<StepMotion>,
}

/// Where a moving collider is at the start and at the end of a step.
#[derive(Clone, Copy, Debug)]
struct StepMotion {
    from: Rigid,
    to: Rigid,
    dt: f64,
}

impl<T: Real> ColliderIn<T> {
    /// How far `x` is outside the surface a particle rests on, in metres: the signed distance,
    /// less a mesh's thickness.
    fn gap(&self, x: Vec3<T>) -> T {
        match &self.shape {
            ShapeIn::Mesh(mesh) => self.shape.signed_distance(x) - mesh.thickness(),
            shape => shape.signed_distance(x),
        }
    }

    /// The contact of a particle that moved from `start` to `end` over the step, and the velocity
    /// of the collider's surface there (zero for a fixed one). A moving collider is met in its
    /// own frame: the particle's start as seen from where the collider was, its end as seen from
    /// where it is, so that the relative path is tested and a moving surface sweeps up the
    /// particles in its way. `nearby` is a mesh's triangles near the band's particles, with the
    /// particle's index in the band.
    fn contact(
        &self,
        start: Vec3<T>,
        end: Vec3<T>,
        nearby: Option<(&mut NearbyBand<T>, usize)>,
    ) -> Option<(Surface<T>, Vec3<T>)> {
        let Some(m) = self.moving else {
            return self.shape.contact(start, end, nearby).map(|s| (s, Vec3::ZERO));
        };
        let local = |frame: &Rigid, x: Vec3<T>| Vec3::from_dvec3(frame.inverse_point(x.to_dvec3()));
        let surface = self.shape.contact(local(&m.from, start), local(&m.to, end), nearby)?;
        let at = surface.point.to_dvec3();
        let (now, before) = (m.to.point(at), m.from.point(at));
        let normal = Vec3::from_dvec3(m.to.rotation * surface.normal.to_dvec3());
        let surface_velocity = Vec3::from_dvec3((now - before) / m.dt);
        Some((Surface { point: Vec3::from_dvec3(now), normal }, surface_velocity))
    }

    /// Where a particle at `x`, inside or on the collider where it is now, goes.
    fn inside(&self, x: Vec3<T>) -> Option<Surface<T>> {
        let Some(m) = self.moving else { return self.shape.inside(x) };
        let surface = self.shape.inside(Vec3::from_dvec3(m.to.inverse_point(x.to_dvec3())))?;
        Some(Surface {
            point: Vec3::from_dvec3(m.to.point(surface.point.to_dvec3())),
            normal: Vec3::from_dvec3(m.to.rotation * surface.normal.to_dvec3()),
        })
    }

    /// Resolves the contacts of `band`'s particles with this collider, with `nearby` its
    /// triangles near them for a mesh. Returns whether any particle was touched.
    fn resolve_band(&self, mut band: Band<T>, mut nearby: Option<NearbyBand<T>>) -> bool {
        let count = band.inverse_masses.len();
        let whole = count - count % LANES;
        let mut touched = false;
        match (&self.shape, self.moving, nearby.as_mut()) {
            (ShapeIn::Plane(plane), None, _) => {
                for block in (0..whole).step_by(LANES) {
                    let (positions, velocities) = (
                        band.positions.each_mut().map(|a| &mut **a),
                        band.velocities.each_mut().map(|a| &mut **a),
                    );
                    let (friction, restitution) = (self.friction, self.restitution);
                    let (masses, response) = (band.inverse_masses, (friction, restitution));
                    touched |= match band.friction.as_mut() {
                        Some(carry) => plane.resolve_lanes::<true>(
                            positions,
                            velocities,
                            masses,
                            Some(carry),
                            block,
                            response,
                        ),
                        None => {
                            plane.resolve_lanes::<false>(positions, velocities, masses, None, block, response)
                        }
                    };
                }
            }
            (ShapeIn::Mesh(mesh), None, Some(nearby)) => {
                // The lanes first, over a run of blocks, then the particles they left, one at a
                // time: particles are independent, so the order changes nothing.
                const RUN: usize = 64;
                let mut rest = [0u8; RUN];
                for first in (0..whole).step_by(RUN * LANES) {
                    let rest = &mut rest[..RUN.min((whole - first) / LANES)];
                    let (friction, restitution) = (self.friction, self.restitution);
                    touched |= mesh_lanes::resolve_blocks(
                        mesh,
                        nearby,
                        &mut band,
                        first,
                        rest,
                        friction,
                        restitution,
                    );
                    for (k, &rest) in rest.iter().enumerate().filter(|&(_, &rest)| rest != 0) {
                        let block = first + k * LANES;
                        let positions = band.positions.each_ref().map(|a| &**a);
                        let reaches = self.shape.reaches_lanes(band.start, positions, block);
                        for lane in (0..LANES).filter(|&lane| (rest >> lane) & 1 == 1 && reaches[lane]) {
                            touched |= band.contact(self, Some(nearby), block + lane);
                        }
                    }
                }
            }
            (shape, moving, mut nearby) => {
                for block in (0..whole).step_by(LANES) {
                    // A moving collider's particles are seen from its frame one by one.
                    let candidates = match moving {
                        None => {
                            shape.reaches_lanes(band.start, band.positions.each_ref().map(|a| &**a), block)
                        }
                        Some(_) => [true; LANES],
                    };
                    for lane in (0..LANES).filter(|&lane| candidates[lane]) {
                        touched |= band.contact(self, nearby.as_deref_mut(), block + lane);
                    }
                }
            }
        }
        for p in whole..count {
            touched |= band.contact(self, nearby.as_mut(), p);
        }
        touched
    }
}

/// One band's particles: their start-of-step positions, their state and inverse masses.
struct Band<'a, T> {
    start: [&'a [T]; 3],
    positions: [&'a mut [T]; 3],
    velocities: [&'a mut [T]; 3],
    inverse_masses: &'a [T],
    /// The friction carried into the step, when a collider has friction.
    friction: Option<BandFriction<'a, T>>,
}

impl<T: Real> Band<'_, T> {
    /// The first `count` particles, borrowed, every array cut to that length: a loop over them
    /// checks a block's bounds once.
    #[inline(always)]
    fn first(&mut self, count: usize) -> Band<'_, T> {
        let ([sx, sy, sz], [x, y, z], [u, v, w]) = (self.start, &mut self.positions, &mut self.velocities);
        Band {
            start: [&sx[..count], &sy[..count], &sz[..count]],
            positions: [&mut x[..count], &mut y[..count], &mut z[..count]],
            velocities: [&mut u[..count], &mut v[..count], &mut w[..count]],
            inverse_masses: &self.inverse_masses[..count],
            friction: self.friction.as_mut().map(|f| f.first(count)),
        }
    }

    /// Resolves particle `p`'s contact with `c`, if it has one, with `nearby` the mesh's
    /// triangles near the band's particles; pinned particles have none.
    fn contact(&mut self, c: &ColliderIn<T>, nearby: Option<&mut NearbyBand<T>>, p: usize) -> bool {
        if self.inverse_masses[p] == T::ZERO {
            return false;
        }
        let at = |axes: [&[T]; 3]| Vec3::new(axes[0][p], axes[1][p], axes[2][p]);
        let end = at(self.positions.each_ref().map(|a| &**a));
        let Some((surface, surface_velocity)) = c.contact(at(self.start), end, nearby.map(|n| (n, p))) else {
            return false;
        };
        // The response acts on the velocity relative to the surface.
        let mut velocity = at(self.velocities.each_ref().map(|a| &**a)) - surface_velocity;
        let carried = self.friction.as_ref().map(|f| f.get(p));
        let given = carried.map(|c| c.given(end, surface.normal));
        let response = respond(&mut velocity, surface.normal, c.friction, c.restitution, given);
        if let (Some(friction), Some(carried)) = (&mut self.friction, carried) {
            // The solve holds a particle only against a fixed surface, whose normal velocity is zero.
            let before = carried.before - surface_velocity;
            friction.set(p, response.carry_on(&carried, before, surface.point, c.moving.is_none()));
        }
        let velocity = velocity + surface_velocity;
        let (point, velocity) = (surface.point.to_array(), velocity.to_array());
        for (axis, (x, v)) in self.positions.iter_mut().zip(&mut self.velocities).enumerate() {
            x[p] = point[axis];
            v[p] = velocity[axis];
        }
        true
    }
}

/// The contact stage: every collider, and the start-of-step positions for the swept tests.
#[derive(Clone, Debug)]
pub(crate) struct Contacts<T> {
    colliders: Vec<ColliderIn<T>>,
    /// Per collider, for a mesh, the triangles near each particle.
    nearby: Vec<Option<NearbyTriangles<T>>>,
    /// Where the particles started the step, copied only when `swept`: fixed planes, boxes and
    /// cylinders test the end of the step alone and never read it.
    start: Vectors<T>,
    /// Whether a collider tests the particles' paths: a sphere, a mesh, or any moving collider.
    swept: bool,
    /// The friction and the contacts carried from step to step, for implicit Euler.
    friction: Option<CarriedFriction<T>>,
    /// The step being taken, in seconds.
    step: T,
}

impl<T: Real> Contacts<T> {
    /// The stage for these colliders, or `None` when there are none.
    pub fn new(colliders: &[Collider], particles: usize) -> Option<Self> {
        if colliders.is_empty() {
            return None;
        }
        let swept = colliders
            .iter()
            .any(|c| c.motion.is_some() || matches!(c.shape, Shape::Sphere { .. } | Shape::Mesh { .. }));
        let nearby = colliders
            .iter()
            .map(|c| matches!(c.shape, Shape::Mesh { .. }).then(|| NearbyTriangles::new(particles)))
            .collect();
        let colliders = colliders
            .iter()
            .map(|c| ColliderIn {
                shape: ShapeIn::new(&c.shape),
                friction: T::from_f64(c.friction),
                restitution: T::from_f64(c.restitution),
                moving: c.motion.as_ref().map(|m| StepMotion { from: m.at(0.0), to: m.at(0.0), dt: 1.0 }),
                motion: c.motion.clone(),
            })
            .collect();
        Some(Self {
            colliders,
            nearby,
            start: Vectors::zeros(particles),
            swept,
            friction: None,
            step: T::ZERO,
        })
    }

    /// Carries friction and contacts from step to step ([`carried_friction`]): the friction when a
    /// collider has friction, the contacts a solve holds when a collider is fixed.
    pub fn with_carried_friction(mut self) -> Self {
        if self.colliders.iter().any(|c| c.friction > T::ZERO || c.motion.is_none()) {
            self.friction = Some(CarriedFriction::new(self.start.len()));
        }
        self
    }

    /// The contacts the next solve is to hold ([`Holds`]); `None` when contacts are not carried.
    pub fn held(&self) -> Option<Holds<'_, T>> {
        self.friction.as_ref().map(CarriedFriction::holds)
    }

    /// Remembers where the particles are before a step moves them, when a collider tests their
    /// paths, and gives them the friction carried from the last step, when a collider has
    /// friction. Returns whether that changed the velocities.
    pub fn begin_step(&mut self, positions: &Vectors<T>, velocities: &mut Vectors<T>, h: T) -> bool {
        self.step = h;
        if self.swept {
            self.start.copy_from(positions);
        }
        let Some(friction) = &mut self.friction else { return false };
        friction.begin(velocities);
        true
    }

    /// Whether any collider moves.
    pub fn any_moving(&self) -> bool {
        self.colliders.iter().any(|c| c.motion.is_some())
    }

    /// Moves the moving colliders through the step from time `t` to `t + dt`.
    pub fn move_colliders(&mut self, t: f64, dt: f64) {
        for c in &mut self.colliders {
            if let Some(motion) = &c.motion {
                c.moving = Some(StepMotion { from: motion.at(t), to: motion.at(t + dt), dt });
            }
        }
    }

    /// Moves free particles that are inside a collider out onto its surface, leaving velocities
    /// alone: for a state that starts inside, and within the strain limit's sweeps.
    pub fn project_out(&self, positions: &mut Vectors<T>, inverse_masses: &[T]) {
        for (p, &w) in inverse_masses.iter().enumerate() {
            if w == T::ZERO {
                continue;
            }
            for c in &self.colliders {
                if let Some(surface) = c.inside(positions.get(p)) {
                    positions.set(p, surface.point);
                }
            }
        }
    }

    /// Resolves every contact of the step that moved the particles from the positions given to
    /// [`begin_step`](Self::begin_step) to `state`. Returns whether any particle was touched.
    ///
    /// Each particle meets the colliders in order and alone, so the colliders are met one after
    /// the other, each over every particle, and a large state is cut into bands of particles on
    /// the solver's threads, with the same result. Within a band, a block of [`LANES`]
    /// particles is first tested against a collider side by side, in vector lanes, by the cheap
    /// test its exact contact starts with ([`ShapeIn::reaches_lanes`]); only the particles that
    /// pass take the exact, branching test.
    pub fn resolve(&mut self, state: &mut State<T>, inverse_masses: &[T]) -> bool {
        let n = inverse_masses.len();
        let band = n.div_ceil(parallel::band_count(n, n, 1));
        let touched = AtomicBool::new(false);
        let start = &self.start;
        for (c, nearby) in self.colliders.iter().zip(&mut self.nearby) {
            let [x, y, z] = state.positions.axes_mut();
            let [u, v, w] = state.velocities.axes_mut();
            let (given, next) = match &mut self.friction {
                Some(friction) => {
                    let (given, next) = friction.parts();
                    (Some(given), Some(next))
                }
                None => (None, None),
            };
            let h = self.step;
            let rows = (([x, y, z, u, v, w], nearby.as_mut().map(NearbyTriangles::band)), next);
            parallel::in_bands(rows, n, 1, band, &|first, count, (([x, y, z, u, v, w], nearby), next)| {
                let particles = first..first + count;
                let band = Band {
                    start: start.range(particles.clone()),
                    positions: [x, y, z],
                    velocities: [u, v, w],
                    inverse_masses: &inverse_masses[particles.clone()],
                    friction: given.zip(next).map(|(given, next)| given.band(particles, next, h)),
                };
                if c.resolve_band(band, nearby) {
                    touched.store(true, Ordering::Relaxed);
                }
            });
        }
        self.carry_on(state);
        touched.into_inner()
    }

    /// Ends the step's carried friction and contacts: the held particles the projection did not
    /// stop again but that still lie on a fixed surface stay held, and what the step carries on
    /// becomes what the next is given.
    fn carry_on(&mut self, state: &State<T>) {
        let Some(friction) = &mut self.friction else { return };
        let colliders = &self.colliders;
        let gap = |x: Vec3<T>| {
            let fixed = colliders.iter().filter(|c| c.moving.is_none());
            fixed.fold(T::from_f64(f64::INFINITY), |gap, c| gap.min(c.gap(x)))
        };
        friction.keep_holding(state, self.step, gap);
        friction.end();
    }

    /// The names of the collider stages, each type once, in the order they first appear.
    pub fn stages(&self) -> impl Iterator<Item = &'static str> + '_ {
        let name = |c: &ColliderIn<T>| match c.shape {
            ShapeIn::Plane(_) => "plane",
            ShapeIn::Sphere(_) => "sphere",
            ShapeIn::Box(_) => "box",
            ShapeIn::Cylinder(_) => "cylinder",
            ShapeIn::Mesh(_) => "mesh",
        };
        self.colliders
            .iter()
            .enumerate()
            .filter(move |&(i, c)| !self.colliders[..i].iter().any(|d| name(d) == name(c)))
            .map(move |(_, c)| name(c))
    }
}

/// The velocity change of a contact with outward unit normal `n`: restitution on the approaching
/// normal part, Coulomb friction on the tangential part. A separating particle keeps its velocity.
///
/// `given` is what the step gave the particle before ([`carried_friction`]), or `None` where
/// friction is not carried: the friction (a change of velocity, relative to the surface) it was
/// given, carried from the last step or a stuck particle's anchor spring's impulse. The step's
/// friction in all is what would stop the particle's tangential motion, `given - v_t`, limited to
/// `μ` times the normal impulse; the velocity takes what `given` did not already give. A stuck
/// particle responds while anything presses it to the surface (its anchor spring or its own
/// approach), so that it can stay stuck where the solve already stopped it. The returned
/// [`Friction`] tells what to carry into the next step.
///
/// Written without branches, so that a block of particles takes it in vector lanes
/// ([`plane::Plane::resolve_lanes`]): every quantity is computed and the ones that do not apply
/// are discarded, never used.
#[inline(always)]
pub(crate) fn respond<T: Real>(
    v: &mut Vec3<T>,
    n: Vec3<T>,
    friction: T,
    restitution: T,
    given: Option<Given<T>>,
) -> Friction<T> {
    let normal_speed = v.dot(n);
    let normal_change = -(T::ONE + restitution) * normal_speed;
    let tangential = *v - n * normal_speed;
    let approaching = normal_speed < T::ZERO;
    // Written out for `None`, so that a caller without carried friction does no work for it.
    let (stopping, responded, limit, pressed) = match given {
        Some(given) => {
            let load = given.scale * normal_change.max(T::ZERO) + given.load;
            let limit = friction * load;
            let already = given.friction - n * given.friction.dot(n);
            let stopping = already - tangential;
            let pressed = approaching | (given.stuck & (load > T::ZERO));
            // A stuck particle that slides keeps the velocity the solve gave it: its anchor
            // spring was its friction there, and giving back the spring's impulse beyond the cone
            // would give it a velocity the sheet around it never saw.
            let slides = stopping.length_squared() > limit * limit;
            let responded = if given.stuck & slides {
                tangential
            } else {
                tangential - already + within(stopping, limit)
            };
            (stopping, responded, limit, pressed)
        }
        None => {
            let limit = friction * normal_change;
            (-tangential, tangential + within(-tangential, limit), limit, approaching)
        }
    };
    let normal = if approaching { T::ZERO - restitution * normal_speed } else { normal_speed };
    *v = if pressed { responded + n * normal } else { *v };
    Friction { stopping, limit, pressed, n }
}

/// The friction of one contact's response, from which what to carry on follows.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Friction<T> {
    /// The tangential change of velocity that would have stopped the particle in the step.
    stopping: Vec3<T>,
    /// The most friction could change it by, `μ` times the normal impulse.
    limit: T,
    /// Whether the surface pressed on the particle (else nothing was done).
    pressed: bool,
    n: Vec3<T>,
}

impl<T: Real> Friction<T> {
    /// The normal of the contact for the next solve to hold: the surface's, if it pressed on the
    /// particle (the projection stopped it, or it stayed stuck), else zero.
    #[inline(always)]
    pub fn hold(&self) -> Vec3<T> {
        if self.pressed { self.n } else { Vec3::ZERO }
    }

    /// Whether friction stopped the particle within Coulomb's cone.
    #[inline(always)]
    pub fn sticks(&self) -> bool {
        self.pressed & (self.limit > T::ZERO) & (self.stopping.length_squared() <= self.limit * self.limit)
    }

    /// The friction to carry into the next step, for a particle whose velocity at the start of the
    /// step, before the carried friction was given, was `before` (relative to the surface): the
    /// steady part of the step's friction, without the stopping of that velocity, within the
    /// limit; zero for a separating particle.
    #[inline(always)]
    pub fn carried_on(&self, before: Vec3<T>) -> Vec3<T> {
        let steady = within(self.stopping + before - self.n * before.dot(self.n), self.limit);
        if self.pressed { steady } else { Vec3::ZERO }
    }

    /// What a particle that was given `carried` carries on, `before` its velocity at the start of
    /// the step relative to the surface and `point` where the projection put it, against a fixed
    /// surface (`fixed`) or a moving one.
    ///
    /// Against a fixed surface, a particle friction stopped within the cone is stuck: to the point
    /// where it stopped, or to its anchor if it was stuck already, so that it cannot creep, and it
    /// is given no carried friction, its anchor spring holding it instead. One friction did not
    /// stop slides, held along the normal. It carries its steady friction on, unless it was stuck:
    /// a stuck particle's friction is its anchor spring's impulse, which holds the stiff spring's
    /// reaction as well as the steady load, and carried into the next step it would kick the
    /// particle back toward its old anchor (`docs/decisions.md`, "Static friction held in the
    /// solve by an anchor spring"); the next step's own response gives it kinetic friction.
    /// Against a moving surface nothing is held, and only friction is carried.
    #[inline(always)]
    pub(super) fn carry_on(
        &self,
        carried: &Carried<T>,
        before: Vec3<T>,
        point: Vec3<T>,
        fixed: bool,
    ) -> Next<T> {
        let stuck = fixed & self.sticks();
        Next {
            friction: if stuck | carried.stuck { Vec3::ZERO } else { self.carried_on(before) },
            hold: if fixed { self.hold() } else { Vec3::ZERO },
            stuck,
            anchor: if carried.stuck { carried.anchor } else { point },
        }
    }
}

/// `u` shortened to length `limit` if it is longer. Scaling rather than normalising keeps a zero
/// `u` finite: the quotient is kept only when `u` is longer than the limit, so not zero.
#[inline(always)]
fn within<T: Real>(u: Vec3<T>, limit: T) -> Vec3<T> {
    let squared = u.length_squared();
    let scale = if squared > limit * limit { limit / squared.sqrt() } else { T::ONE };
    u * scale
}
