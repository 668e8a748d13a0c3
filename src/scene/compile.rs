//! Turning a valid scene into the solver's inputs and a plan for the run.
//!
//! Time follows the contract: `steps = ceil(duration / dt)` (with a relative slack of 1e-9 so
//! that an exact division gains no step) and `dt = duration / steps`, so the step never grows
//! and the last step lands on `duration`. Without a `dt`, the explicit integrators take half the
//! scene's stability bound (see [`solver::stable_step`]), or a quarter of the frame interval in a
//! scene with nothing that bounds the step (no springs, no drag). Implicit Euler, stable at any
//! step, takes a share of the frame interval `1 / fps`, or that half-bound if it is larger: half
//! in a scene with colliders, a quarter without. In contact, friction decides which of many rest
//! shapes a drape reaches; at half the frame interval the rest shape is as close to a small
//! step's as at a quarter, and a drape comes to rest in fewer steps. The whole frame interval does
//! not hold: a sheet landing on a ball stretches to twice its length, and a tablecloth does not
//! come to rest. Without contact nothing hides the step's error, so the step stays at a quarter
//! (`docs/decisions.md`, "Implicit Euler's default step in contact is half the frame interval").

use std::sync::Arc;

use glam::DVec3;

use super::drape_tester::DrapeTester;
use super::material_points::MaterialPoints;
use super::placement::Placement;
use super::types::MotionSpec;
use super::types::{
    Body, ClothShape, ColliderSpec, ErrorEstimateName, FrameSelection, IntegratorName, OrientationName,
    Output, Precision, Scene, SpringSpec, WindModelName, WindSpec,
};
use crate::solver::{
    self, Collider, IntegratorKind, IntegratorSettings, Keyframe, Model, Motion, Rigid, Shape, SpringParams,
    TriangleSurface,
};

/// Where a run's step came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DtSource {
    /// The scene's `dt` (possibly shortened to divide `duration` evenly).
    Scene,
    /// Chosen from the scene's stability bound.
    Stability,
}

impl DtSource {
    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Scene => "scene",
            Self::Stability => "stability",
        }
    }
}

/// A body's place among the particles.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyInfo {
    /// Its name, given or defaulted.
    pub name: String,
    /// Its `type`.
    pub kind: &'static str,
    /// Index of its first particle.
    pub offset: usize,
    /// Number of particles.
    pub count: usize,
}

/// A scene ready to run: the solver's inputs and the plan around them.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// Particles, springs, triangles.
    pub model: Model,
    /// Integrator, step, gravity, drag.
    pub config: solver::Config,
    /// Arithmetic precision.
    pub precision: Precision,
    /// Simulated time, in seconds.
    pub duration: f64,
    /// Steps to take.
    pub steps: u64,
    /// Where the step came from.
    pub dt_source: DtSource,
    /// The bodies' names and particle ranges.
    pub bodies: Vec<BodyInfo>,
    /// What to record.
    pub output: Output,
    /// Stop early once at rest: every particle slower than this, in m/s, and balanced.
    pub stop_at_rest: Option<f64>,
    /// How the run estimates its own error.
    pub error_estimate: ErrorEstimateName,
    /// The drape tester the scene is, if it is one: the run then reports the drape coefficient.
    pub drape_tester: Option<DrapeTester>,
    /// With `error_estimate: "resolution"`, the companions: the scene at about half and at about
    /// a quarter of its resolution (empty otherwise).
    pub coarser: Vec<Coarser>,
}

/// A companion of the spatial error estimate: the scene at a coarser resolution, run with the
/// same step and to the same end (or to rest), and where its particles lie on the finer scenes.
#[derive(Clone, Debug)]
pub struct Coarser {
    /// The coarser scene, recording nothing and estimating nothing.
    pub compiled: Compiled,
    /// Its particles as points of the scene one resolution finer.
    pub on_finer: MaterialPoints,
    /// Its particles as points of the scene the run is of.
    pub on_main: MaterialPoints,
}

impl Compiled {
    /// A companion for an error estimate: the same scene over its first `duration` seconds,
    /// taken in `steps` steps (at least one), recording nothing and estimating nothing.
    pub fn companion(&self, steps: u64, duration: f64) -> Self {
        let steps = steps.max(1);
        let mut companion = self.clone();
        companion.steps = steps;
        companion.duration = duration;
        companion.config.dt = duration / steps as f64;
        companion.output = Output { frames: FrameSelection::None, fields: Vec::new(), ..self.output.clone() };
        companion.stop_at_rest = None;
        companion.error_estimate = ErrorEstimateName::None;
        companion.drape_tester = None;
        companion.coarser = Vec::new();
        companion
    }
}

impl IntegratorName {
    /// The solver's integrator of that name.
    pub fn kind(self) -> IntegratorKind {
        match self {
            Self::ExplicitEuler => IntegratorKind::ExplicitEuler,
            Self::SymplecticEuler => IntegratorKind::SymplecticEuler,
            Self::Verlet => IntegratorKind::Verlet,
            Self::Rk4 => IntegratorKind::Rk4,
            Self::ImplicitEuler => IntegratorKind::ImplicitEuler,
        }
    }
}

impl Scene {
    /// Builds the model and plans the run.
    pub fn compile(&self) -> Compiled {
        let mut model = Model::default();
        let mut body_triangles = Vec::with_capacity(self.bodies.len());
        let mut pin_motions = Vec::new();
        let bodies = self
            .bodies
            .iter()
            .enumerate()
            .map(|(index, body)| {
                let first_triangle = model.triangles.len();
                let range = add_body(&mut model, body);
                body_triangles.push(first_triangle..model.triangles.len());
                if let Some(spec) = body.pin_motion() {
                    let rest = &model.positions[range.clone()];
                    pin_motions.push(solver::PinMotion {
                        particles: range.clone().filter(|&p| model.pinned[p]).collect(),
                        centre: rest.iter().sum::<DVec3>() / rest.len() as f64,
                        motion: motion(spec, &Placement::default()),
                    });
                }
                BodyInfo {
                    name: body.name().map_or_else(|| format!("{}{index}", body.type_name()), str::to_string),
                    kind: body.type_name(),
                    offset: range.start,
                    count: range.len(),
                }
            })
            .collect();
        let drape_tester = DrapeTester::find(self, &model, &body_triangles);

        let integrator = self.integrator.kind();
        let (target_dt, dt_source) = match self.dt {
            Some(dt) => (dt, DtSource::Scene),
            None => (self.automatic_dt(&model, integrator), DtSource::Stability),
        };
        let steps = ((self.duration / target_dt) * (1.0 - 1e-9)).ceil().max(1.0) as u64;
        let config = solver::Config {
            integrator,
            settings: IntegratorSettings {
                verlet_damping: self.verlet_damping,
                tolerance: self.solver.tolerance,
                reduction: self.solver.reduction,
                max_iterations: self.solver.max_iterations,
            },
            dt: self.duration / steps as f64,
            gravity: DVec3::from_array(self.gravity),
            drag: self.drag,
            wind: self.wind.as_ref().map(wind),
            colliders: self.colliders.iter().map(collider).collect(),
            strain_limit: self.strain_limit,
            self_collision: self.self_collision.map(|s| s.thickness),
            pin_motions,
            max_self_collision_pairs: usize::MAX,
        };
        let coarser = match self.error_estimate {
            ErrorEstimateName::Resolution => self.coarser_companions(config.dt, steps),
            _ => Vec::new(),
        };
        Compiled {
            model,
            config,
            precision: self.precision,
            duration: self.duration,
            steps,
            dt_source,
            bodies,
            output: self.output.clone(),
            stop_at_rest: self.stop_at_rest,
            error_estimate: self.error_estimate,
            drape_tester,
            coarser,
        }
    }

    /// The companions of the spatial error estimate, at the run's step `dt` for its `steps`:
    /// the same step keeps the time error out of the difference. Each keeps `stop_at_rest`, so
    /// that a run to rest is compared with its companions at their own rest.
    fn coarser_companions(&self, dt: f64, steps: u64) -> Vec<Coarser> {
        let Some(half) = self.coarsened() else { return Vec::new() };
        let Some(quarter) = half.coarsened() else { return Vec::new() };
        let companion = |scene: &Scene| {
            let mut compiled = scene.compile();
            compiled.config.dt = dt;
            compiled.steps = steps;
            compiled.output =
                Output { frames: FrameSelection::None, fields: Vec::new(), ..self.output.clone() };
            compiled.drape_tester = None;
            compiled
        };
        vec![
            Coarser {
                compiled: companion(&half),
                on_finer: MaterialPoints::between(&half, self),
                on_main: MaterialPoints::between(&half, self),
            },
            Coarser {
                compiled: companion(&quarter),
                on_finer: MaterialPoints::between(&quarter, &half),
                on_main: MaterialPoints::between(&quarter, self),
            },
        ]
    }

    /// The step of a scene without `dt` (the module's first paragraph says how it is chosen).
    fn automatic_dt(&self, model: &Model, integrator: IntegratorKind) -> f64 {
        let frame = 1.0 / self.output.fps;
        let half_bound =
            solver::stable_step(model, self.drag).map(|h| 0.5 * h * integrator.stability_factor());
        let dt = match (integrator, half_bound) {
            (IntegratorKind::ImplicitEuler, bound) => {
                let share = if self.colliders.is_empty() { 0.25 } else { 0.5 };
                bound.map_or(share * frame, |h| h.max(share * frame))
            }
            (_, Some(h)) => h,
            (_, None) => 0.25 * frame,
        };
        dt.min(self.duration)
    }
}

fn collider(spec: &ColliderSpec) -> Collider {
    let v = DVec3::from_array;
    let placement = spec.placement();
    let motion = spec.motion().map(|m| motion(m, &placement));
    // A moving collider is defined in its own frame (scaled only), which its motion places.
    let placement = if motion.is_some() {
        Placement { scale: placement.scale, ..Placement::default() }
    } else {
        placement
    };
    let point = |x: [f64; 3]| placement.point(v(x));
    let s = placement.scale;
    let shape = match spec {
        ColliderSpec::Plane(c) => {
            Shape::Plane { point: point(c.point), normal: placement.direction(v(c.normal)) }
        }
        ColliderSpec::Sphere(c) => Shape::Sphere { center: point(c.center), radius: s * c.radius },
        // Validation leaves boxes and cylinders unrotated.
        ColliderSpec::Box(c) => Shape::Box { center: point(c.center), half_extents: s * v(c.half_extents) },
        ColliderSpec::Cylinder(c) => {
            Shape::Cylinder { center: point(c.center), radius: s * c.radius, height: s * c.height }
        }
        ColliderSpec::Mesh(c) => {
            let mut surface = c.surface();
            surface.vertices.iter_mut().for_each(|x| *x = placement.point(*x));
            Shape::Mesh { surface: Arc::new(surface), thickness: c.thickness }
        }
    };
    let (friction, restitution) = spec.surface();
    Collider { shape, friction, restitution, motion }
}

/// The solver's motion: keyframes as given, or velocities from the static placement.
fn motion(spec: &MotionSpec, placement: &Placement) -> Motion {
    let rigid = |translation: [f64; 3], rotation: [f64; 4]| Rigid {
        translation: DVec3::from_array(translation),
        rotation: Placement { translation, rotation, scale: 1.0 }.quaternion(),
    };
    match &spec.keyframes {
        Some(keys) => Motion::Keyframes(
            keys.iter().map(|k| Keyframe { t: k.t, transform: rigid(k.translation, k.rotation) }).collect(),
        ),
        None => Motion::Velocity {
            start: rigid(placement.translation, placement.rotation),
            velocity: DVec3::from_array(spec.velocity.unwrap_or_default()),
            angular_velocity: DVec3::from_array(spec.angular_velocity.unwrap_or_default()),
        },
    }
}

fn wind(spec: &WindSpec) -> solver::WindConfig {
    solver::WindConfig {
        model: match spec.model {
            WindModelName::Viscous => solver::WindModel::Viscous,
            WindModelName::Aerodynamic => solver::WindModel::Aerodynamic,
        },
        velocity: DVec3::from_array(spec.velocity),
        coefficient: spec.coefficient,
        gust: spec.gust.map(|g| solver::Gust {
            amplitude: g.amplitude,
            frequency: g.frequency,
            wavelength: g.wavelength,
        }),
    }
}

fn params(spec: SpringSpec) -> SpringParams {
    SpringParams { stiffness: spec.k, damping: spec.damping }
}

fn add_body(model: &mut Model, body: &Body) -> std::ops::Range<usize> {
    let v = DVec3::from_array;
    match body {
        Body::Cloth(c) if c.shape == ClothShape::Disk => match &c.material {
            Some(material) => model.add_fabric_mesh(&c.solver_disk().mesh(), &material.fabric()),
            None => model.add_disk(&c.solver_disk()),
        },
        Body::Cloth(c) => {
            let cloth = cloth(c);
            match &c.material {
                Some(material) => model.add_fabric_cloth(&cloth, &material.fabric()),
                None => model.add_cloth(&cloth),
            }
        }
        Body::Chain(c) => model.add_chain(&solver::Chain {
            start: v(c.start),
            end: v(c.end),
            count: c.count,
            mass: c.mass,
            velocity: v(c.velocity),
            spring: SpringParams { stiffness: c.spring.k, damping: c.spring.damping },
            rest_length: c.spring.rest_length,
            pins: c.pin.clone(),
        }),
        Body::Lattice(l) => model.add_lattice(&solver::Lattice {
            size: l.size,
            resolution: l.resolution,
            center: v(l.center),
            mass: l.mass,
            velocity: v(l.velocity),
            structural: params(l.springs.structural),
            shear: params(l.springs.shear),
            bending: params(l.springs.bending),
            pins: l.pin.clone(),
        }),
        Body::Mesh(m) => {
            let mesh = solver::Mesh {
                vertices: m.vertex_positions().into_iter().map(|x| m.placement().point(x)).collect(),
                triangles: m.triangle_indices(),
                mass: m.mass,
                velocity: v(m.velocity),
                structural: params(m.springs.structural),
                bending: params(m.springs.bending),
                pins: m.pin.clone(),
            };
            match &m.material {
                Some(material) => model.add_fabric_mesh(&mesh, &material.fabric()),
                None => model.add_mesh(&mesh),
            }
        }
    }
}

fn cloth(c: &super::types::ClothSpec) -> solver::Cloth {
    let v = DVec3::from_array;
    solver::Cloth {
        size: c.size,
        resolution: c.resolution,
        center: v(c.center),
        orientation: match c.orientation {
            OrientationName::Horizontal => solver::Orientation::Horizontal,
            OrientationName::Vertical => solver::Orientation::Vertical,
        },
        mass: c.mass,
        velocity: v(c.velocity),
        structural: params(c.springs.structural),
        shear: params(c.springs.shear),
        bending: params(c.springs.bending),
        pins: c.pin.clone(),
    }
}

impl super::types::MeshColliderSpec {
    /// The triangles as the solver takes them (the indices are checked to fit).
    pub fn surface(&self) -> TriangleSurface {
        TriangleSurface {
            vertices: self.vertices.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect(),
            triangles: self.triangles.chunks_exact(3).map(|c| [c[0], c[1], c[2]].map(|i| i as u32)).collect(),
        }
    }
}

impl super::types::MeshSpec {
    /// Where the scene puts it.
    pub fn placement(&self) -> super::placement::Placement {
        super::placement::Placement {
            translation: self.translation,
            rotation: self.rotation,
            scale: self.scale,
        }
    }

    /// The flat `vertices` as points.
    pub fn vertex_positions(&self) -> Vec<DVec3> {
        self.vertices.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect()
    }

    /// The flat `triangles` as index triples.
    pub fn triangle_indices(&self) -> Vec<[usize; 3]> {
        self.triangles.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }
}
