//! The scene's types, as the JSON spells them, with their defaults.

use serde::Deserialize;

use super::fabrics::FabricSpec;
use super::placement::Placement;
use super::whole;

/// A scene: the bodies, the forces on them, how to integrate and what to record.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Simulated time, in seconds (required, positive). The last frame is at exactly `duration`.
    pub duration: f64,
    /// Integration method (default `symplectic_euler`).
    pub integrator: IntegratorName,
    /// Step, in seconds; left out, one below the scene's stability bound is chosen.
    pub dt: Option<f64>,
    /// Arithmetic precision of the run (default `f64`).
    pub precision: Precision,
    /// Gravitational acceleration, in m/s² (default `[0, -9.81, 0]`).
    pub gravity: [f64; 3],
    /// Drag rate, in 1/s: each particle feels `-drag · m · v` (default 0).
    pub drag: f64,
    /// Verlet's damping factor: the fraction of velocity removed per step, in [0, 1) (default 0).
    pub verlet_damping: f64,
    /// Settings of implicit Euler's linear solver.
    pub solver: SolverSettings,
    /// End the run early once at rest: every particle slower than this, in m/s, and balanced
    /// (default: never; the rule is [`run`](crate::run)'s).
    pub stop_at_rest: Option<f64>,
    /// How the run estimates its own error (default `richardson`).
    pub error_estimate: ErrorEstimateName,
    /// The bodies, in order; particle indices in results run over them in this order.
    pub bodies: Vec<Body>,
    /// Fixed shapes the particles cannot enter, resolved in this order (default none).
    pub colliders: Vec<ColliderSpec>,
    /// Wind on the bodies' surfaces (default none).
    pub wind: Option<WindSpec>,
    /// Keeps particles that no spring joins apart (default off).
    pub self_collision: Option<SelfCollisionSpec>,
    /// The largest strain `(l - L) / L` any spring may end a step with, a positive fraction
    /// (default: no limit).
    pub strain_limit: Option<f64>,
    /// What to record and how to encode it.
    pub output: Output,
}

/// The top level of a scene as parsed, before its bodies are read by type.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
    pub duration: f64,
    #[serde(default)]
    pub integrator: IntegratorName,
    #[serde(default)]
    pub dt: Option<f64>,
    #[serde(default)]
    pub precision: Precision,
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 3],
    #[serde(default)]
    pub drag: f64,
    #[serde(default)]
    pub verlet_damping: f64,
    #[serde(default)]
    pub solver: SolverSettings,
    #[serde(default)]
    pub stop_at_rest: Option<f64>,
    #[serde(default)]
    pub error_estimate: ErrorEstimateName,
    pub bodies: Vec<serde_json::Value>,
    #[serde(default)]
    pub colliders: Vec<serde_json::Value>,
    #[serde(default)]
    pub wind: Option<WindSpec>,
    #[serde(default)]
    pub self_collision: Option<SelfCollisionSpec>,
    #[serde(default)]
    pub strain_limit: Option<f64>,
    #[serde(default)]
    pub output: Output,
}

fn default_gravity() -> [f64; 3] {
    [0.0, -9.81, 0.0]
}

/// The integration methods, as the JSON names them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorName {
    /// Forward Euler.
    ExplicitEuler,
    /// Semi-implicit Euler (the default).
    #[default]
    SymplecticEuler,
    /// Position Verlet with damping.
    Verlet,
    /// Classic fourth-order Runge-Kutta.
    Rk4,
    /// Linearised backward Euler with conjugate gradients.
    ImplicitEuler,
}

/// Arithmetic precision.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Precision {
    /// Single precision.
    F32,
    /// Double precision (the default).
    #[default]
    F64,
}

impl Precision {
    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::F64 => "f64",
        }
    }
}

/// How a run estimates its own error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorEstimateName {
    /// A companion run at twice the step, or at half the step with contacts or near the
    /// stability bound (the default).
    #[default]
    Richardson,
    /// Companions at twice and four times the step (or half and a quarter), which also measure
    /// the order.
    Richardson3,
    /// Companions at half and a quarter of the resolution, which measure the spatial error and
    /// its order (every body a cloth with a `material`).
    Resolution,
    /// No estimate.
    None,
}

impl ErrorEstimateName {
    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Richardson => "richardson",
            Self::Richardson3 => "richardson3",
            Self::Resolution => "resolution",
            Self::None => "none",
        }
    }
}

/// Settings of implicit Euler's conjugate-gradient solve.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// Relative residual at which a solve stops, in (0, 1) (default 1e-6).
    pub tolerance: f64,
    /// Reduction of its starting guess's residual at which a solve stops, in [0, 0.1] (default
    /// 0.01; 0 solves to `tolerance`).
    pub reduction: f64,
    /// Iteration cap per solve, at least 1 (default 200).
    #[serde(deserialize_with = "whole::one")]
    pub max_iterations: usize,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self { tolerance: 1e-6, reduction: 0.01, max_iterations: 200 }
    }
}

/// A body, by its `type`.
#[derive(Clone, Debug, PartialEq)]
pub enum Body {
    /// A rectangular sheet.
    Cloth(ClothSpec),
    /// Particles in a line.
    Chain(ChainSpec),
    /// A 3-D block.
    Lattice(LatticeSpec),
    /// A triangle mesh.
    Mesh(MeshSpec),
}

impl Body {
    /// The `type` as the JSON spells it.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::Cloth(_) => "cloth",
            Self::Chain(_) => "chain",
            Self::Lattice(_) => "lattice",
            Self::Mesh(_) => "mesh",
        }
    }

    /// The body's name, if it was given one.
    pub fn name(&self) -> Option<&str> {
        match self {
            Self::Cloth(b) => b.name.as_deref(),
            Self::Chain(b) => b.name.as_deref(),
            Self::Lattice(b) => b.name.as_deref(),
            Self::Mesh(b) => b.name.as_deref(),
        }
    }

    /// How its pinned particles move, if they do.
    pub fn pin_motion(&self) -> Option<&MotionSpec> {
        match self {
            Self::Cloth(b) => b.pin_motion.as_ref(),
            Self::Chain(b) => b.pin_motion.as_ref(),
            Self::Lattice(b) => b.pin_motion.as_ref(),
            Self::Mesh(b) => b.pin_motion.as_ref(),
        }
    }

    /// How many particles the body will have, computed without building it (saturating).
    pub fn particle_count(&self) -> u64 {
        match self {
            Self::Cloth(c) if c.shape == ClothShape::Disk => c.disk_particle_count(),
            Self::Cloth(c) => product(&c.resolution),
            Self::Chain(c) => c.count as u64,
            Self::Lattice(l) => product(&l.resolution),
            Self::Mesh(m) => (m.vertices.len() / 3) as u64,
        }
    }

    /// How many springs the body will have, computed without building it (saturating; an upper
    /// bound for meshes).
    pub fn spring_count(&self) -> u64 {
        let pairs = |n: u64, reach: u64| n.saturating_sub(reach);
        match self {
            Self::Cloth(c) if c.shape == ClothShape::Disk => c.disk_spring_count(),
            Self::Cloth(c) => {
                let (nx, ny) = (c.resolution[0] as u64, c.resolution[1] as u64);
                let grid = |di: u64, dj: u64| pairs(nx, di).saturating_mul(pairs(ny, dj));
                // A material's cloth bends by hinges, without the springs two apart.
                let bending = if c.material.is_some() { [0, 0] } else { [grid(2, 0), grid(0, 2)] };
                [grid(1, 0), grid(0, 1), grid(1, 1), grid(1, 1), bending[0], bending[1]]
                    .into_iter()
                    .fold(0, u64::saturating_add)
            }
            Self::Chain(c) => (c.count as u64).saturating_sub(1),
            Self::Lattice(l) => product(&l.resolution).saturating_mul(16),
            Self::Mesh(m) => (m.triangles.len() as u64 / 3).saturating_mul(6),
        }
    }
}

fn product(values: &[usize]) -> u64 {
    values.iter().fold(1u64, |acc, &n| acc.saturating_mul(n as u64))
}

/// A spring family's stiffness and damping.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    /// Stiffness, in N/m per spring (positive).
    pub k: f64,
    /// Damping along the spring, in N·s/m (at least 0; default 0).
    #[serde(default)]
    pub damping: f64,
}

/// Springs of a cloth or lattice.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GridSprings {
    /// Neighbours (default k 5000, damping 0.5).
    pub structural: SpringSpec,
    /// Diagonals (default k 500, damping 0.2).
    pub shear: SpringSpec,
    /// Two apart (default k 50, damping 0.1).
    pub bending: SpringSpec,
}

impl Default for GridSprings {
    fn default() -> Self {
        Self {
            structural: SpringSpec { k: 5000.0, damping: 0.5 },
            shear: SpringSpec { k: 500.0, damping: 0.2 },
            bending: SpringSpec { k: 50.0, damping: 0.1 },
        }
    }
}

/// Springs of a mesh.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeshSprings {
    /// Along edges (default k 5000, damping 0.5).
    pub structural: SpringSpec,
    /// Across shared edges (default k 50, damping 0.1).
    pub bending: SpringSpec,
}

impl Default for MeshSprings {
    fn default() -> Self {
        let grid = GridSprings::default();
        Self { structural: grid.structural, bending: grid.bending }
    }
}

/// How a cloth or mesh resists bending.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BendingModelName {
    /// A hinge on every interior edge, from the angle between its two triangles; its rigidity is
    /// the material's `bending`.
    Dihedral,
    /// Springs between particles two apart, of stiffness `springs.bending.k`.
    Springs,
}

impl BodyMaterial for ClothSpec {
    fn material(&self) -> Option<&FabricSpec> {
        self.material.as_ref()
    }
    fn bending_model(&self) -> Option<BendingModelName> {
        self.bending_model
    }
}

impl BodyMaterial for MeshSpec {
    fn material(&self) -> Option<&FabricSpec> {
        self.material.as_ref()
    }
    fn bending_model(&self) -> Option<BendingModelName> {
        self.bending_model
    }
}

/// What a cloth and a mesh share about their material.
pub trait BodyMaterial {
    /// The `material`, if given.
    fn material(&self) -> Option<&FabricSpec>;
    /// The `bending_model`, if given.
    fn bending_model(&self) -> Option<BendingModelName>;
    /// The bending model in force: the given one, else `dihedral` with a material and `springs`
    /// without.
    fn bending(&self) -> BendingModelName {
        self.bending_model().unwrap_or(match self.material() {
            Some(_) => BendingModelName::Dihedral,
            None => BendingModelName::Springs,
        })
    }
}

/// The plane a cloth starts in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OrientationName {
    /// In the x-z plane (the default).
    #[default]
    Horizontal,
    /// In the x-y plane, row `j = 0` on top.
    Vertical,
}

/// A cloth's outline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClothShape {
    /// A rectangular grid of `size` (the default).
    #[default]
    Rectangle,
    /// A disk of `diameter`, triangulated in rings (see [`scene::disk`](super::disk)).
    Disk,
}

/// A cloth: particle `(i, j)` is index `j * nx + i`, `i` along `size[0]`; a disk's particles are
/// numbered by ring (see [`scene::disk`](super::disk)).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClothSpec {
    /// Name in results (default `cloth<index>`).
    pub name: Option<String>,
    /// Outline (default `rectangle`).
    pub shape: ClothShape,
    /// A disk's diameter, in metres (default 1; a disk's only).
    pub diameter: Option<f64>,
    /// Extent, in metres (default `[1, 1]`).
    pub size: [f64; 2],
    /// Particles along each side, each at least 2 (default `[32, 32]`).
    #[serde(deserialize_with = "whole::array")]
    pub resolution: [usize; 2],
    /// Centre, in metres (default `[0, 1, 0]`).
    pub center: [f64; 3],
    /// Starting plane (default `horizontal`).
    pub orientation: OrientationName,
    /// Total mass, in kg (default 0.5).
    pub mass: f64,
    /// Initial velocity of every particle, in m/s (default 0).
    pub velocity: [f64; 3],
    /// Spring families (not with `material`).
    pub springs: GridSprings,
    /// The fabric, in physical units, in place of `springs` and `mass`.
    pub material: Option<FabricSpec>,
    /// How the body resists bending (default `dihedral` with `material`, `springs` without).
    pub bending_model: Option<BendingModelName>,
    /// Pinned particles as `[i, j]`.
    #[serde(deserialize_with = "whole::list_of_arrays")]
    pub pin: Vec<[usize; 2]>,
    /// Moves the pinned particles rigidly about the body's rest centroid (default: they stay).
    pub pin_motion: Option<MotionSpec>,
}

impl Default for ClothSpec {
    fn default() -> Self {
        Self {
            name: None,
            shape: ClothShape::Rectangle,
            diameter: None,
            size: [1.0, 1.0],
            resolution: [32, 32],
            center: [0.0, 1.0, 0.0],
            orientation: OrientationName::Horizontal,
            mass: 0.5,
            velocity: [0.0; 3],
            springs: GridSprings::default(),
            material: None,
            bending_model: None,
            pin: Vec::new(),
            pin_motion: None,
        }
    }
}

/// A chain's spring.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainSpring {
    /// Stiffness, in N/m (positive).
    pub k: f64,
    /// Damping, in N·s/m (default 0).
    #[serde(default)]
    pub damping: f64,
    /// Rest length of every link, in metres (default: the initial spacing).
    #[serde(default)]
    pub rest_length: Option<f64>,
}

impl Default for ChainSpring {
    fn default() -> Self {
        Self { k: 100.0, damping: 0.0, rest_length: None }
    }
}

/// A chain: `count` particles evenly from `start` to `end`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChainSpec {
    /// Name in results (default `chain<index>`).
    pub name: Option<String>,
    /// First particle, in metres (default `[0, 1, 0]`).
    pub start: [f64; 3],
    /// Last particle, in metres (default `[1, 1, 0]`).
    pub end: [f64; 3],
    /// Particles, at least 2 (default 10).
    #[serde(deserialize_with = "whole::one")]
    pub count: usize,
    /// Total mass, in kg (default 0.1).
    pub mass: f64,
    /// Initial velocity, in m/s (default 0).
    pub velocity: [f64; 3],
    /// The links (default k 100, damping 0).
    pub spring: ChainSpring,
    /// Pinned particle indices.
    #[serde(deserialize_with = "whole::list")]
    pub pin: Vec<usize>,
    /// Moves the pinned particles rigidly about the body's rest centroid (default: they stay).
    pub pin_motion: Option<MotionSpec>,
}

impl Default for ChainSpec {
    fn default() -> Self {
        Self {
            name: None,
            start: [0.0, 1.0, 0.0],
            end: [1.0, 1.0, 0.0],
            count: 10,
            mass: 0.1,
            velocity: [0.0; 3],
            spring: ChainSpring::default(),
            pin: Vec::new(),
            pin_motion: None,
        }
    }
}

/// A 3-D block: particle `(i, j, k)` is index `(k * ny + j) * nx + i`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LatticeSpec {
    /// Name in results (default `lattice<index>`).
    pub name: Option<String>,
    /// Extent, in metres (default `[0.2, 0.2, 0.2]`).
    pub size: [f64; 3],
    /// Particles along each axis, each at least 2 (default `[6, 6, 6]`).
    #[serde(deserialize_with = "whole::array")]
    pub resolution: [usize; 3],
    /// Centre, in metres (default `[0, 0.5, 0]`).
    pub center: [f64; 3],
    /// Total mass, in kg (default 1).
    pub mass: f64,
    /// Initial velocity, in m/s (default 0).
    pub velocity: [f64; 3],
    /// Spring families.
    pub springs: GridSprings,
    /// Pinned particles as `[i, j, k]`.
    #[serde(deserialize_with = "whole::list_of_arrays")]
    pub pin: Vec<[usize; 3]>,
    /// Moves the pinned particles rigidly about the body's rest centroid (default: they stay).
    pub pin_motion: Option<MotionSpec>,
}

impl Default for LatticeSpec {
    fn default() -> Self {
        Self {
            name: None,
            size: [0.2, 0.2, 0.2],
            resolution: [6, 6, 6],
            center: [0.0, 0.5, 0.0],
            mass: 1.0,
            velocity: [0.0; 3],
            springs: GridSprings::default(),
            pin: Vec::new(),
            pin_motion: None,
        }
    }
}

/// A triangle mesh.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// Name in results (default `mesh<index>`).
    #[serde(default)]
    pub name: Option<String>,
    /// Flat vertex coordinates `[x0, y0, z0, x1, ...]`, in metres (required).
    pub vertices: Vec<f64>,
    /// Flat vertex indices, three per triangle (required).
    #[serde(deserialize_with = "whole::list")]
    pub triangles: Vec<usize>,
    /// Total mass, spread by area, in kg (default 0.5).
    #[serde(default = "default_mesh_mass")]
    pub mass: f64,
    /// Initial velocity, in m/s (default 0).
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Spring families (not with `material`).
    #[serde(default)]
    pub springs: MeshSprings,
    /// The fabric, in physical units, in place of `springs` and `mass`.
    #[serde(default)]
    pub material: Option<FabricSpec>,
    /// How the body resists bending (default `dihedral` with `material`, `springs` without).
    #[serde(default)]
    pub bending_model: Option<BendingModelName>,
    /// Pinned vertex indices.
    #[serde(default, deserialize_with = "whole::list")]
    pub pin: Vec<usize>,
    /// Moves the pinned particles rigidly about the body's rest centroid (default: they stay).
    #[serde(default)]
    pub pin_motion: Option<MotionSpec>,
    /// Moves it after rotating, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Turns it about the origin after scaling: a unit quaternion `[x, y, z, w]` (default the
    /// identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
    /// Scales it about the origin, a positive number (default 1).
    #[serde(default = "super::placement::default_scale")]
    pub scale: f64,
}

fn default_mesh_mass() -> f64 {
    0.5
}

/// A collider, by its `type`. Each has `friction` (Coulomb μ, at least 0; default 0.3) and
/// `restitution` (in [0, 1]; default 0).
#[derive(Clone, Debug, PartialEq)]
pub enum ColliderSpec {
    /// A plane; the side behind its normal is solid.
    Plane(PlaneSpec),
    /// A solid ball.
    Sphere(SphereSpec),
    /// A solid axis-aligned box.
    Box(BoxSpec),
    /// A solid cylinder with its axis along y (a round table).
    Cylinder(CylinderSpec),
    /// A triangle mesh: a two-sided sheet, or a solid when closed.
    Mesh(MeshColliderSpec),
}

impl ColliderSpec {
    /// The `type` as the JSON spells it.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::Plane(_) => "plane",
            Self::Sphere(_) => "sphere",
            Self::Box(_) => "box",
            Self::Cylinder(_) => "cylinder",
            Self::Mesh(_) => "mesh",
        }
    }

    /// Where the scene puts it.
    pub fn placement(&self) -> Placement {
        let (translation, rotation, scale) = match self {
            Self::Plane(c) => (c.translation, c.rotation, c.scale),
            Self::Sphere(c) => (c.translation, c.rotation, c.scale),
            Self::Box(c) => (c.translation, c.rotation, c.scale),
            Self::Cylinder(c) => (c.translation, c.rotation, c.scale),
            Self::Mesh(c) => (c.translation, c.rotation, c.scale),
        };
        Placement { translation, rotation, scale }
    }

    /// How it moves, if it does.
    pub fn motion(&self) -> Option<&MotionSpec> {
        match self {
            Self::Plane(c) => c.motion.as_ref(),
            Self::Sphere(c) => c.motion.as_ref(),
            Self::Box(c) => c.motion.as_ref(),
            Self::Cylinder(c) => c.motion.as_ref(),
            Self::Mesh(c) => c.motion.as_ref(),
        }
    }

    /// Friction and restitution.
    pub fn surface(&self) -> (f64, f64) {
        match self {
            Self::Plane(c) => (c.friction, c.restitution),
            Self::Sphere(c) => (c.friction, c.restitution),
            Self::Box(c) => (c.friction, c.restitution),
            Self::Cylinder(c) => (c.friction, c.restitution),
            Self::Mesh(c) => (c.friction, c.restitution),
        }
    }
}

fn default_friction() -> f64 {
    crate::solver::DEFAULT_FRICTION
}

/// A plane collider: the floor by default.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// A point on the plane, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub point: [f64; 3],
    /// The side particles stay on; any length but zero (default `[0, 1, 0]`).
    #[serde(default = "default_up")]
    pub normal: [f64; 3],
    /// Coulomb friction μ (default 0.3).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Restitution, in [0, 1] (default 0).
    #[serde(default)]
    pub restitution: f64,
    /// Moves it after rotating, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Turns it about the origin after scaling: a unit quaternion `[x, y, z, w]` (default the
    /// identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
    /// Scales it about the origin, a positive number (default 1).
    #[serde(default = "super::placement::default_scale")]
    pub scale: f64,
    /// How it moves (default: it stands still).
    #[serde(default)]
    pub motion: Option<MotionSpec>,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

/// A sphere collider.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSpec {
    /// Centre, in metres (required).
    pub center: [f64; 3],
    /// Radius, in metres (required, positive).
    pub radius: f64,
    /// Coulomb friction μ (default 0.3).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Restitution, in [0, 1] (default 0).
    #[serde(default)]
    pub restitution: f64,
    /// Moves it after rotating, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Turns it about the origin after scaling: a unit quaternion `[x, y, z, w]` (default the
    /// identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
    /// Scales it about the origin, a positive number (default 1).
    #[serde(default = "super::placement::default_scale")]
    pub scale: f64,
    /// How it moves (default: it stands still).
    #[serde(default)]
    pub motion: Option<MotionSpec>,
}

/// An axis-aligned box collider.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Centre, in metres (required).
    pub center: [f64; 3],
    /// Half its size along x, y and z, in metres (required, each positive).
    pub half_extents: [f64; 3],
    /// Coulomb friction μ (default 0.3).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Restitution, in [0, 1] (default 0).
    #[serde(default)]
    pub restitution: f64,
    /// Moves it after rotating, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Turns it about the origin after scaling: a unit quaternion `[x, y, z, w]` (default the
    /// identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
    /// Scales it about the origin, a positive number (default 1).
    #[serde(default = "super::placement::default_scale")]
    pub scale: f64,
    /// How it moves (default: it stands still).
    #[serde(default)]
    pub motion: Option<MotionSpec>,
}

/// A cylinder collider with its axis along y.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CylinderSpec {
    /// The middle of its axis, in metres (required); the top is at `center[1] + height / 2`.
    pub center: [f64; 3],
    /// Radius, in metres (required, positive).
    pub radius: f64,
    /// Height, in metres (required, positive).
    pub height: f64,
    /// Coulomb friction μ (default 0.3).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Restitution, in [0, 1] (default 0).
    #[serde(default)]
    pub restitution: f64,
    /// Moves it after rotating, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Turns it about the origin after scaling: a unit quaternion `[x, y, z, w]` (default the
    /// identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
    /// Scales it about the origin, a positive number (default 1).
    #[serde(default = "super::placement::default_scale")]
    pub scale: f64,
    /// How it moves (default: it stands still).
    #[serde(default)]
    pub motion: Option<MotionSpec>,
}

/// A triangle-mesh collider. It is a solid when closed (every edge shared by exactly two
/// triangles, once in each direction, vertices at one position counted as one), else a
/// two-sided sheet.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshColliderSpec {
    /// Flat vertex coordinates `[x0, y0, z0, x1, ...]`, in metres (required).
    pub vertices: Vec<f64>,
    /// Flat vertex indices, three per triangle (required).
    #[serde(deserialize_with = "whole::list")]
    pub triangles: Vec<usize>,
    /// The distance particles keep from the triangles, in metres, positive (default 0.005); a
    /// `scale` does not change it.
    #[serde(default = "default_mesh_thickness")]
    pub thickness: f64,
    /// Coulomb friction μ (default 0.3).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Restitution, in [0, 1] (default 0).
    #[serde(default)]
    pub restitution: f64,
    /// Moves it after rotating, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Turns it about the origin after scaling: a unit quaternion `[x, y, z, w]` (default the
    /// identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
    /// Scales it about the origin, a positive number (default 1).
    #[serde(default = "super::placement::default_scale")]
    pub scale: f64,
    /// How it moves (default: it stands still).
    #[serde(default)]
    pub motion: Option<MotionSpec>,
}

fn default_mesh_thickness() -> f64 {
    0.005
}

/// A rigid motion: `keyframes`, or a `velocity` and `angular_velocity`.
///
/// Keyframes are piecewise linear in translation and slerped in rotation, held before the first
/// and after the last; each key's transform replaces the static `translation` and `rotation` and
/// applies to the shape as defined (after its `scale`). A velocity moves the shape from its static
/// placement: `x(t) = translation + velocity·t + exp(angular_velocity·t)·rotation·(scale·x)`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSpec {
    /// Keys in strictly increasing time (at least one).
    #[serde(default)]
    pub keyframes: Option<Vec<KeyframeSpec>>,
    /// Velocity, in m/s (default 0 when `angular_velocity` is given).
    #[serde(default)]
    pub velocity: Option<[f64; 3]>,
    /// Angular velocity about the shape's origin, in rad/s (default 0 when `velocity` is given).
    #[serde(default)]
    pub angular_velocity: Option<[f64; 3]>,
}

/// One key of a motion.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// Time, in seconds, at least 0 (required).
    pub t: f64,
    /// Translation, in metres (default `[0, 0, 0]`).
    #[serde(default)]
    pub translation: [f64; 3],
    /// Rotation, a unit quaternion `[x, y, z, w]` (default the identity).
    #[serde(default = "super::placement::default_rotation")]
    pub rotation: [f64; 4],
}

/// How wind turns into forces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WindModelName {
    /// Per vertex, `c [n·(u - v)] n`, `c` in N·s/m.
    Viscous,
    /// Per triangle, area-weighted, `c A [n·(u - v̄)] n`, `c` in N·s/m³ (the default).
    #[default]
    Aerodynamic,
}

/// Wind.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindSpec {
    /// The force model (default `aerodynamic`).
    #[serde(default)]
    pub model: WindModelName,
    /// The air's mean velocity, in m/s (required).
    pub velocity: [f64; 3],
    /// The drag coefficient `c`, at least 0 (default 1).
    #[serde(default = "default_wind_coefficient")]
    pub coefficient: f64,
    /// Variation in space and time (default none: steady wind).
    #[serde(default)]
    pub gust: Option<GustSpec>,
}

fn default_wind_coefficient() -> f64 {
    1.0
}

/// A gust: the wind scaled by `1 + amplitude · sin(2π (frequency · t - x·ŵ / wavelength))`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GustSpec {
    /// Relative amplitude, in [0, 1] (default 0.5).
    pub amplitude: f64,
    /// Frequency, in Hz, at least 0 (default 1).
    pub frequency: f64,
    /// Wavelength along the wind, in metres, positive (default 2).
    pub wavelength: f64,
}

impl Default for GustSpec {
    fn default() -> Self {
        Self { amplitude: 0.5, frequency: 1.0, wavelength: 2.0 }
    }
}

/// Self-collision.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SelfCollisionSpec {
    /// Half the distance particles that no spring joins keep apart, in metres, positive
    /// (default 0.005). Keep `2 · thickness` below the distance of particles two apart in a
    /// grid, which no spring joins.
    pub thickness: f64,
}

impl Default for SelfCollisionSpec {
    fn default() -> Self {
        Self { thickness: 0.005 }
    }
}

/// What a run records and how it is encoded.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Output {
    /// Frames per simulated second for `frames: all` (default 30).
    pub fps: f64,
    /// Which frames to keep (default `all`).
    pub frames: FrameSelection,
    /// Which fields each frame carries (default `["positions"]`).
    pub fields: Vec<Field>,
    /// The encoding of the result (default `json`).
    pub format: Format,
}

impl Default for Output {
    fn default() -> Self {
        Self { fps: 30.0, frames: FrameSelection::All, fields: vec![Field::Positions], format: Format::Json }
    }
}

/// Which frames a result keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameSelection {
    /// One every `1/fps` seconds from 0 to the end, inclusive (the default).
    #[default]
    All,
    /// Only the state at the end.
    Final,
    /// None: statistics only.
    None,
}

/// A per-frame field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Field {
    /// Particle positions, flat `[x0, y0, z0, ...]`.
    Positions,
    /// Particle velocities, flat.
    Velocities,
    /// Unit vertex normals, flat (zero off any surface).
    Normals,
    /// Kinetic, gravitational and spring energy.
    Energy,
    /// Strain `(l - L) / L` of every spring, in spring order.
    Strain,
}

impl Field {
    /// Every field, in the order results list them.
    pub const ALL: [Field; 5] =
        [Field::Positions, Field::Velocities, Field::Normals, Field::Energy, Field::Strain];

    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Positions => "positions",
            Self::Velocities => "velocities",
            Self::Normals => "normals",
            Self::Energy => "energy",
            Self::Strain => "strain",
        }
    }
}

/// Encodings of a result, and the fields each can carry.
///
/// JSON carries everything. The mesh formats (glTF binary, OBJ) carry positions and normals; NPY
/// is one array of positions, NPZ one array per field; PC2 is a point cache of positions. Every
/// format but JSON and NPZ needs positions, and every format but JSON needs a frame to encode.
/// Media types and the negotiation with a client live in `output::format`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// JSON (the default).
    #[default]
    Json,
    /// glTF 2.0 binary: one node and mesh per body, the motion as morph targets.
    Glb,
    /// Wavefront OBJ: the last frame's mesh.
    Obj,
    /// A NumPy array of positions, frames × particles × 3. With more fields asked, NPZ.
    Npy,
    /// A NumPy archive: one array per field, plus `times`.
    Npz,
    /// A PC2 point cache of positions.
    Pc2,
}

impl Format {
    /// Every format, in the order the contract lists them.
    pub const ALL: [Format; 6] =
        [Format::Json, Format::Glb, Format::Obj, Format::Npy, Format::Npz, Format::Pc2];

    /// The name the contract uses (`output.format`, `?format=`, `--format`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Json => "json",
            Self::Glb => "glb",
            Self::Obj => "obj",
            Self::Npy => "npy",
            Self::Npz => "npz",
            Self::Pc2 => "pc2",
        }
    }

    /// Whether this format can carry `field`.
    pub fn carries(self, field: Field) -> bool {
        match self {
            Self::Json | Self::Npz => true,
            Self::Glb | Self::Obj => matches!(field, Field::Positions | Field::Normals),
            Self::Npy | Self::Pc2 => field == Field::Positions,
        }
    }

    /// Whether this format has nothing to say without positions.
    pub fn needs_positions(self) -> bool {
        !matches!(self, Self::Json | Self::Npz)
    }

    /// The format actually sent for `fields`: NPY becomes NPZ when more than positions are asked;
    /// every other format stays as it is.
    pub fn for_fields(self, fields: &[Field]) -> Format {
        if self == Self::Npy && fields.iter().any(|&f| f != Field::Positions) { Self::Npz } else { self }
    }
}
