//! The rules a parsed scene must meet beyond its types: finite numbers, physical ranges and
//! indices in range.

use super::error::FieldError;
use super::fabrics::FabricSpec;
use super::placement::{Placement, ROTATION_NORM_TOLERANCE};
use super::types::MotionSpec;
use super::types::{
    BendingModelName, Body, BodyMaterial, ClothShape, ColliderSpec, ErrorEstimateName, Field, Format,
    FrameSelection, GridSprings, Output, Scene, SpringSpec, WindSpec,
};

/// Collects problems, each at its JSON Pointer.
struct Problems(Vec<FieldError>);

/// The tightest linear-solver tolerance: relative residuals much below it are lost in the
/// rounding of double precision, so a solve would only run to its iteration limit.
pub const MIN_TOLERANCE: f64 = 1e-12;
/// The loosest: a residual a tenth of the right-hand side is no longer a solution.
pub const MAX_TOLERANCE: f64 = 0.1;
/// The loosest stop on the reduction of a solve's starting guess's residual: a solve left with
/// more than a tenth of how much its step differs from the last one is no longer a solution.
pub const MAX_REDUCTION: f64 = 0.1;
/// The most conjugate-gradient iterations a step may take; with the multigrid preconditioner a
/// solve takes tens, and more only prolongs a step that cannot converge.
pub const MAX_ITERATIONS: usize = 10_000;
/// The largest coordinate, speed or acceleration a scene may give, in metres and seconds: far
/// beyond any drape, and small enough that distances, their squares and energies stay finite in
/// single precision.
pub const MAX_MAGNITUDE: f64 = 1e6;
/// The range of every other positive quantity (masses, stiffnesses, times): wide enough for any
/// physical unit, narrow enough that a mass shared among a million particles, its inverse and
/// the product of two such quantities stay finite and nonzero in single precision.
pub const POSITIVE_RANGE: std::ops::RangeInclusive<f64> = 1e-30..=1e30;

impl Problems {
    fn add(&mut self, pointer: impl Into<String>, detail: impl Into<String>) {
        self.0.push(FieldError::new(pointer, detail));
    }

    fn finite(&mut self, pointer: &str, values: &[f64]) -> bool {
        let ok = values.iter().all(|v| v.is_finite());
        if !ok {
            self.add(pointer, "must be a finite number");
        }
        ok
    }

    /// Finite, and no component beyond [`MAX_MAGNITUDE`]: a position, velocity or acceleration.
    fn vector(&mut self, pointer: &str, values: &[f64]) -> bool {
        if !self.finite(pointer, values) {
            return false;
        }
        let ok = values.iter().all(|v| v.abs() <= MAX_MAGNITUDE);
        if !ok {
            self.add(pointer, format!("every component must be within ±{MAX_MAGNITUDE:e}"));
        }
        ok
    }

    fn positive(&mut self, pointer: &str, value: f64) {
        if self.finite(pointer, &[value]) && value <= 0.0 {
            self.add(pointer, format!("must be positive, got {value}"));
        } else if value.is_finite() && !POSITIVE_RANGE.contains(&value) {
            let (low, high) = POSITIVE_RANGE.into_inner();
            self.add(pointer, format!("must be in [{low:e}, {high:e}], got {value:e}"));
        }
    }

    /// Positive and no longer than [`MAX_MAGNITUDE`] metres.
    fn length(&mut self, pointer: &str, value: f64) {
        if value.is_finite() && value > MAX_MAGNITUDE {
            self.add(pointer, format!("must be at most {MAX_MAGNITUDE:e} m, got {value:e}"));
        } else {
            self.positive(pointer, value);
        }
    }

    fn non_negative(&mut self, pointer: &str, value: f64) {
        if self.finite(pointer, &[value]) && value < 0.0 {
            self.add(pointer, format!("must not be negative, got {value}"));
        } else if value > *POSITIVE_RANGE.end() {
            self.add(pointer, format!("must be at most {:e}, got {value:e}", POSITIVE_RANGE.end()));
        }
    }

    fn lengths(&mut self, pointer: &str, values: &[f64]) {
        for (axis, &v) in values.iter().enumerate() {
            self.length(&format!("{pointer}/{axis}"), v);
        }
    }

    fn resolution(&mut self, pointer: &str, values: &[usize]) {
        for (axis, &n) in values.iter().enumerate() {
            if n < 2 {
                self.add(format!("{pointer}/{axis}"), format!("must be at least 2, got {n}"));
            }
        }
    }

    fn spring(&mut self, pointer: &str, spring: &SpringSpec) {
        self.positive(&format!("{pointer}/k"), spring.k);
        self.non_negative(&format!("{pointer}/damping"), spring.damping);
    }

    fn grid_springs(&mut self, pointer: &str, springs: &GridSprings) {
        self.spring(&format!("{pointer}/structural"), &springs.structural);
        self.spring(&format!("{pointer}/shear"), &springs.shear);
        self.spring(&format!("{pointer}/bending"), &springs.bending);
    }

    /// A material's own values; returns whether they are all in range.
    fn fabric(&mut self, pointer: &str, f: &FabricSpec) -> bool {
        let before = self.0.len();
        {
            self.positive(&format!("{pointer}/density"), f.density);
            self.positive(&format!("{pointer}/stretch"), f.stretch);
            self.positive(&format!("{pointer}/shear"), f.shear);
            self.positive(&format!("{pointer}/bending"), f.bending);
            self.non_negative(&format!("{pointer}/damping"), f.damping);
            if self.0.len() == before && f.shear >= f.stretch {
                self.add(
                    format!("{pointer}/shear"),
                    format!(
                        "must be below `stretch` ({}), got {}: the diagonal springs that carry shear \
                         also resist stretch",
                        f.stretch, f.shear
                    ),
                );
            }
        }
        self.0.len() == before
    }

    /// The constants a material gives a grid of spacings `[a, b]`: each must be in
    /// [`POSITIVE_RANGE`] (a damping may be 0), so that no size and resolution make them
    /// overflow or vanish.
    fn fabric_grid(&mut self, pointer: &str, fabric: &FabricSpec, [a, b]: [f64; 2]) {
        let solver_fabric = fabric.fabric();
        let stiffness = solver_fabric.grid_stiffness(a, b);
        let derived = [
            ("spring stiffness (N/m)", stiffness.iter().copied().fold(f64::INFINITY, f64::min)),
            ("spring stiffness (N/m)", stiffness.iter().copied().fold(0.0, f64::max)),
            ("hinge stiffness (N/m)", fabric.bending / (a * b)),
            ("particle mass (kg)", fabric.density * a * b / 4.0),
            ("particle mass (kg)", fabric.density * a * b),
        ];
        let dampings = stiffness.map(|k| k * fabric.damping);
        let (low, high) = POSITIVE_RANGE.into_inner();
        for (what, value) in derived {
            if !(value.is_finite() && POSITIVE_RANGE.contains(&value)) {
                self.add(
                    pointer,
                    format!("with this size and resolution its {what} would be {value:e}, outside [{low:e}, {high:e}]"),
                );
                return;
            }
        }
        if dampings.iter().any(|&d| !d.is_finite() || d > high) {
            self.add(pointer, format!("with this size and resolution its damping would exceed {high:e}"));
        }
    }

    /// `bending_model` against the body's `material`: hinges take their rigidity from the
    /// material, and a material's rigidity has no spring equivalent.
    fn bending_model(&mut self, at: &str, body: &impl BodyMaterial) {
        match (body.bending_model(), body.material()) {
            (Some(BendingModelName::Springs), Some(_)) => self.add(
                format!("{at}/bending_model"),
                "`springs` cannot carry a material's bending rigidity (a spring's energy is quartic \
                 in the bend angle): use `dihedral`, the default with `material`",
            ),
            (Some(BendingModelName::Dihedral), None) => self.add(
                format!("{at}/bending_model"),
                "`dihedral` takes its rigidity from `material`, which this body does not have",
            ),
            _ => {}
        }
    }

    fn pins<const N: usize>(&mut self, pointer: &str, pins: &[[usize; N]], extent: [usize; N]) {
        for (p, pin) in pins.iter().enumerate() {
            for axis in 0..N {
                if pin[axis] >= extent[axis] {
                    self.add(
                        format!("{pointer}/{p}/{axis}"),
                        format!(
                            "index {} is out of range: the resolution there is {}",
                            pin[axis], extent[axis]
                        ),
                    );
                }
            }
        }
    }

    fn indices(&mut self, pointer: &str, indices: &[usize], count: usize, what: &str) {
        for (p, &index) in indices.iter().enumerate() {
            if index >= count {
                self.add(
                    format!("{pointer}/{p}"),
                    format!("{what} {index} is out of range: there are {count}"),
                );
            }
        }
    }
}

impl Scene {
    /// Every problem with the scene; empty when it is valid.
    pub(super) fn problems(&self) -> Vec<FieldError> {
        let mut p = Problems(Vec::new());
        p.positive("/duration", self.duration);
        if let Some(dt) = self.dt {
            p.positive("/dt", dt);
        }
        p.vector("/gravity", &self.gravity);
        p.non_negative("/drag", self.drag);
        if p.finite("/verlet_damping", &[self.verlet_damping]) && !(0.0..1.0).contains(&self.verlet_damping) {
            p.add("/verlet_damping", format!("must be in [0, 1), got {}", self.verlet_damping));
        }
        let tolerance = self.solver.tolerance;
        if p.finite("/solver/tolerance", &[tolerance])
            && !(MIN_TOLERANCE..=MAX_TOLERANCE).contains(&tolerance)
        {
            p.add(
                "/solver/tolerance",
                format!("must be in [{MIN_TOLERANCE:e}, {MAX_TOLERANCE}], got {tolerance}"),
            );
        }
        let reduction = self.solver.reduction;
        if p.finite("/solver/reduction", &[reduction]) && !(0.0..=MAX_REDUCTION).contains(&reduction) {
            p.add("/solver/reduction", format!("must be in [0, {MAX_REDUCTION}], got {reduction}"));
        }
        if !(1..=MAX_ITERATIONS).contains(&self.solver.max_iterations) {
            p.add(
                "/solver/max_iterations",
                format!("must be in [1, {MAX_ITERATIONS}], got {}", self.solver.max_iterations),
            );
        }
        if let Some(speed) = self.stop_at_rest {
            p.positive("/stop_at_rest", speed);
        }
        if self.bodies.is_empty() {
            p.add("/bodies", "a scene needs at least one body");
        }
        for (index, body) in self.bodies.iter().enumerate() {
            body_problems(&mut p, &format!("/bodies/{index}"), body);
        }
        for (index, collider) in self.colliders.iter().enumerate() {
            collider_problems(&mut p, &format!("/colliders/{index}"), collider);
        }
        if let Some(wind) = &self.wind {
            wind_problems(&mut p, wind);
        }
        if let Some(self_collision) = &self.self_collision {
            p.length("/self_collision/thickness", self_collision.thickness);
        }
        if let Some(limit) = self.strain_limit {
            p.positive("/strain_limit", limit);
        }
        p.positive("/output/fps", self.output.fps);
        for (i, field) in self.output.fields.iter().enumerate() {
            if self.output.fields[..i].contains(field) {
                p.add(format!("/output/fields/{i}"), "listed twice");
            }
        }
        p.0.extend(self.output.format_problems(self.output.format));
        if self.error_estimate == ErrorEstimateName::Resolution && p.0.is_empty() {
            p.0.extend(self.resolution_problems());
        }
        p.0
    }
}

impl Output {
    /// Why this output cannot be encoded as `format`, each problem at its JSON Pointer: a field
    /// asked for that the format cannot carry (at `/output/fields/i`), positions missing where
    /// the format needs them, or no frame to encode. Empty when it can.
    pub fn format_problems(&self, format: Format) -> Vec<FieldError> {
        let sent = format.for_fields(&self.fields);
        let mut problems = Vec::new();
        for (i, &field) in self.fields.iter().enumerate() {
            if !sent.carries(field) {
                let carriers: Vec<&str> =
                    Format::ALL.iter().filter(|f| f.carries(field)).map(|f| f.name()).collect();
                problems.push(FieldError::new(
                    format!("/output/fields/{i}"),
                    format!(
                        "format {} cannot carry {}; {} can",
                        format.name(),
                        field.name(),
                        carriers.join(", ")
                    ),
                ));
            }
        }
        if sent.needs_positions() && !self.fields.contains(&Field::Positions) {
            problems.push(FieldError::new(
                "/output/fields",
                format!("format {} needs positions among the fields", format.name()),
            ));
        }
        if format != Format::Json && self.frames == FrameSelection::None {
            problems.push(FieldError::new(
                "/output/frames",
                format!("format {} needs a frame to encode; frames none keeps none", format.name()),
            ));
        }
        problems
    }
}

fn body_problems(p: &mut Problems, at: &str, body: &Body) {
    let field = |name: &str| format!("{at}/{name}");
    if let Some(motion) = body.pin_motion() {
        motion_problems(p, &field("pin_motion"), motion);
        let pins = match body {
            Body::Cloth(c) => c.pin.len(),
            Body::Chain(c) => c.pin.len(),
            Body::Lattice(l) => l.pin.len(),
            Body::Mesh(m) => m.pin.len(),
        };
        if pins == 0 {
            p.add(field("pin_motion"), "moves the pinned particles, and the body has none: give `pin`");
        }
    }
    match body {
        Body::Cloth(c) => {
            p.resolution(&field("resolution"), &c.resolution);
            match c.shape {
                ClothShape::Rectangle => {
                    p.lengths(&field("size"), &c.size);
                    p.pins(&field("pin"), &c.pin, c.resolution);
                    if c.diameter.is_some() {
                        p.add(field("diameter"), "only a cloth of shape disk has a diameter");
                    }
                }
                ClothShape::Disk => {
                    p.length(&field("diameter"), c.disk_diameter());
                    p.0.extend(c.disk_problems(at));
                }
            }
            p.vector(&field("center"), &c.center);
            p.positive(&field("mass"), c.mass);
            p.vector(&field("velocity"), &c.velocity);
            p.grid_springs(&field("springs"), &c.springs);
            if let Some(fabric) = &c.material
                && p.fabric(&field("material"), fabric)
            {
                match c.shape {
                    ClothShape::Rectangle => {
                        let spacing = [0, 1].map(|a| c.size[a] / (c.resolution[a].max(2) - 1) as f64);
                        p.fabric_grid(&field("material"), fabric, spacing);
                    }
                    ClothShape::Disk if p.0.iter().all(|e| !e.pointer.starts_with(at)) => {
                        mesh_fabric_range(p, &field("material"), c.solver_disk().mesh(), fabric);
                    }
                    ClothShape::Disk => {}
                }
            }
            p.bending_model(at, c);
        }
        Body::Chain(c) => {
            p.vector(&field("start"), &c.start);
            p.vector(&field("end"), &c.end);
            if c.count < 2 {
                p.add(field("count"), format!("must be at least 2, got {}", c.count));
            }
            p.positive(&field("mass"), c.mass);
            p.vector(&field("velocity"), &c.velocity);
            p.positive(&field("spring/k"), c.spring.k);
            p.non_negative(&field("spring/damping"), c.spring.damping);
            if let Some(rest) = c.spring.rest_length {
                // Zero is a valid rest length: a spring that pulls its ends together.
                if rest != 0.0 {
                    p.length(&field("spring/rest_length"), rest);
                }
            }
            p.indices(&field("pin"), &c.pin, c.count, "particle");
        }
        Body::Lattice(l) => {
            p.lengths(&field("size"), &l.size);
            p.resolution(&field("resolution"), &l.resolution);
            p.vector(&field("center"), &l.center);
            p.positive(&field("mass"), l.mass);
            p.vector(&field("velocity"), &l.velocity);
            p.grid_springs(&field("springs"), &l.springs);
            p.pins(&field("pin"), &l.pin, l.resolution);
        }
        Body::Mesh(m) => mesh_problems(p, at, m),
    }
}

fn mesh_problems(p: &mut Problems, at: &str, m: &super::types::MeshSpec) {
    let field = |name: &str| format!("{at}/{name}");
    let vertex_count = m.vertices.len() / 3;
    if !m.vertices.len().is_multiple_of(3) || vertex_count < 3 {
        p.add(
            field("vertices"),
            format!("must hold x, y, z for at least 3 vertices; got {} numbers", m.vertices.len()),
        );
    }
    p.vector(&field("vertices"), &m.vertices);
    if !m.triangles.len().is_multiple_of(3) || m.triangles.is_empty() {
        p.add(
            field("triangles"),
            format!("must hold three indices per triangle, at least one; got {}", m.triangles.len()),
        );
    }
    p.indices(&field("triangles"), &m.triangles, vertex_count, "vertex");
    p.positive(&field("mass"), m.mass);
    p.vector(&field("velocity"), &m.velocity);
    p.spring(&field("springs/structural"), &m.springs.structural);
    p.spring(&field("springs/bending"), &m.springs.bending);
    p.indices(&field("pin"), &m.pin, vertex_count, "vertex");
    if let Some(material) = &m.material {
        p.fabric(&field("material"), material);
    }
    p.bending_model(at, m);
    let placement = m.placement();
    if placement_problems(p, at, &placement) && placement != Placement::default() {
        let blame = placement_field(at, &placement);
        let out = m
            .vertices
            .chunks_exact(3)
            .map(|v| placement.point(glam::DVec3::new(v[0], v[1], v[2])))
            .find(|x| !x.is_finite() || x.abs().max_element() > MAX_MAGNITUDE);
        if out.is_some() {
            p.add(blame, format!("puts a vertex beyond ±{MAX_MAGNITUDE:e}"));
        }
    }
    let well_formed = p.0.iter().all(|e| !e.pointer.starts_with(at));
    if !well_formed {
        return;
    }
    let (vertices, triangles) = (m.vertex_positions(), m.triangle_indices());
    for (t, tri) in triangles.iter().enumerate() {
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            p.add(format!("{at}/triangles/{}", 3 * t), format!("triangle {t} repeats a vertex: {tri:?}"));
        }
    }
    let areas = crate::solver::vertex_areas(&vertices, &triangles);
    if let Some(v) = areas.iter().position(|&a| a <= 0.0 || !a.is_finite()) {
        p.add(
            field("vertices"),
            format!("vertex {v} is on no triangle of positive area, so it would have no mass"),
        );
        return;
    }
    if let Some(fabric) = &m.material
        && p.0.iter().all(|e| !e.pointer.starts_with(at))
    {
        let placement = m.placement();
        let mesh = crate::solver::Mesh {
            vertices: m.vertex_positions().into_iter().map(|x| placement.point(x)).collect(),
            triangles: m.triangle_indices(),
            mass: 1.0,
            velocity: glam::DVec3::ZERO,
            structural: crate::solver::SpringParams { stiffness: 1.0, damping: 0.0 },
            bending: crate::solver::SpringParams { stiffness: 1.0, damping: 0.0 },
            pins: Vec::new(),
        };
        mesh_fabric_range(p, &field("material"), mesh, fabric);
    }
}

/// A mesh's material makes constants from its triangles' shapes: each spring's stiffness and
/// damping, each hinge's stiffness times its largest squared weight (a sliver triangle's
/// cotangents are large) and each vertex's mass must stay in [`POSITIVE_RANGE`], so that no valid
/// scene overflows or vanishes in single precision.
fn mesh_fabric_range(p: &mut Problems, pointer: &str, mesh: crate::solver::Mesh, fabric: &FabricSpec) {
    let mut model = crate::solver::Model::default();
    model.add_fabric_mesh(&mesh, &fabric.fabric());
    let in_range = |v: f64| v.is_finite() && POSITIVE_RANGE.contains(&v);
    let at_most = |v: f64| v.is_finite() && v <= *POSITIVE_RANGE.end();
    let springs = model.springs.iter().all(|s| in_range(s.stiffness) && at_most(s.damping));
    let hinges = model.bending.iter().all(|h| {
        let largest = h.weights.iter().fold(0.0f64, |w, k| w.max(k.abs()));
        in_range(h.stiffness)
            && at_most(h.stiffness * largest * largest)
            && at_most(h.damping * largest * largest)
    });
    let masses = model.masses.iter().all(|&mass| in_range(mass));
    if !(springs && hinges && masses) {
        let (low, high) = POSITIVE_RANGE.into_inner();
        p.add(
            pointer,
            format!(
                "with these triangles a spring's stiffness, a hinge's or a vertex's mass would leave \
                 [{low:e}, {high:e}]"
            ),
        );
    }
}

fn collider_problems(p: &mut Problems, at: &str, collider: &ColliderSpec) {
    let field = |name: &str| format!("{at}/{name}");
    let placement = collider.placement();
    if placement_problems(p, at, &placement) {
        if matches!(collider, ColliderSpec::Box(_) | ColliderSpec::Cylinder(_)) && !placement.is_unrotated() {
            p.add(
                field("rotation"),
                format!(
                    "a {} stays axis-aligned: only the identity rotation [0, 0, 0, 1]; give a rotated one as a `mesh`",
                    collider.type_name()
                ),
            );
        }
        placed_collider_problems(p, at, collider, &placement);
    }
    if let Some(motion) = collider.motion() {
        motion_problems(p, &field("motion"), motion);
    }
    match collider {
        ColliderSpec::Plane(c) => {
            p.vector(&field("point"), &c.point);
            if p.vector(&field("normal"), &c.normal)
                && c.normal.iter().all(|&n| n.abs() < *POSITIVE_RANGE.start())
            {
                p.add(
                    field("normal"),
                    "must not be the zero vector, nor so short that its length underflows",
                );
            }
        }
        ColliderSpec::Sphere(c) => {
            p.vector(&field("center"), &c.center);
            p.length(&field("radius"), c.radius);
        }
        ColliderSpec::Box(c) => {
            p.vector(&field("center"), &c.center);
            p.lengths(&field("half_extents"), &c.half_extents);
        }
        ColliderSpec::Cylinder(c) => {
            p.vector(&field("center"), &c.center);
            p.length(&field("radius"), c.radius);
            p.length(&field("height"), c.height);
        }
        ColliderSpec::Mesh(c) => mesh_collider_problems(p, at, c),
    }
    let (friction, restitution) = collider.surface();
    p.non_negative(&field("friction"), friction);
    if p.finite(&field("restitution"), &[restitution]) && !(0.0..=1.0).contains(&restitution) {
        p.add(field("restitution"), format!("must be in [0, 1], got {restitution}"));
    }
}

/// A mesh collider's triangles: indices in range, coordinates in range, some triangle with a
/// surface. Triangles of zero area are allowed (they have no surface and are left out).
fn mesh_collider_problems(p: &mut Problems, at: &str, m: &super::types::MeshColliderSpec) {
    let field = |name: &str| format!("{at}/{name}");
    let vertex_count = m.vertices.len() / 3;
    let before = p.0.len();
    if !m.vertices.len().is_multiple_of(3) || vertex_count < 3 {
        p.add(
            field("vertices"),
            format!("must hold x, y, z for at least 3 vertices; got {} numbers", m.vertices.len()),
        );
    } else if vertex_count > u32::MAX as usize {
        p.add(field("vertices"), format!("must hold at most {} vertices", u32::MAX));
    }
    p.vector(&field("vertices"), &m.vertices);
    if !m.triangles.len().is_multiple_of(3) || m.triangles.is_empty() {
        p.add(
            field("triangles"),
            format!("must hold three indices per triangle, at least one; got {}", m.triangles.len()),
        );
    }
    p.indices(&field("triangles"), &m.triangles, vertex_count, "vertex");
    p.length(&field("thickness"), m.thickness);
    if p.0.len() > before {
        return;
    }
    let at_vertex = |i: usize| glam::DVec3::from_slice(&m.vertices[3 * i..3 * i + 3]);
    let has_surface = m.triangles.chunks_exact(3).any(|t| {
        let [a, b, c] = [at_vertex(t[0]), at_vertex(t[1]), at_vertex(t[2])];
        (b - a).cross(c - a).length_squared() > 0.0
    });
    if !has_surface {
        p.add(field("triangles"), "no triangle has a positive area: the mesh has no surface");
    }
}

/// A motion: keyframes in increasing time with sound transforms, or velocities in range.
fn motion_problems(p: &mut Problems, at: &str, motion: &MotionSpec) {
    match (&motion.keyframes, motion.velocity.is_some() || motion.angular_velocity.is_some()) {
        (Some(_), true) => p.add(at, "gives keyframes and a velocity: one or the other"),
        (None, false) => p.add(at, "needs `keyframes`, or a `velocity` or `angular_velocity`"),
        (Some(keys), false) => {
            if keys.is_empty() {
                p.add(format!("{at}/keyframes"), "needs at least one keyframe");
            }
            for (k, key) in keys.iter().enumerate() {
                let here = format!("{at}/keyframes/{k}");
                let t = format!("{here}/t");
                if p.finite(&t, &[key.t]) {
                    if !(0.0..=*POSITIVE_RANGE.end()).contains(&key.t) {
                        p.add(&t, format!("must be in [0, {:e}] s, got {}", POSITIVE_RANGE.end(), key.t));
                    } else if k > 0 && key.t <= keys[k - 1].t {
                        p.add(&t, format!("must come after the previous keyframe's {} s", keys[k - 1].t));
                    }
                }
                let placement =
                    Placement { translation: key.translation, rotation: key.rotation, scale: 1.0 };
                placement_problems(p, &here, &placement);
            }
        }
        (None, true) => {
            if let Some(v) = &motion.velocity {
                p.vector(&format!("{at}/velocity"), v);
            }
            if let Some(w) = &motion.angular_velocity {
                p.vector(&format!("{at}/angular_velocity"), w);
            }
        }
    }
}

/// A placement's own numbers; whether they are sound enough to apply.
fn placement_problems(p: &mut Problems, at: &str, placement: &Placement) -> bool {
    let before = p.0.len();
    p.vector(&format!("{at}/translation"), &placement.translation);
    let rotation = format!("{at}/rotation");
    if p.finite(&rotation, &placement.rotation) {
        let norm = placement.rotation.iter().map(|c| c * c).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > ROTATION_NORM_TOLERANCE {
            p.add(
                rotation,
                format!("must be a unit quaternion [x, y, z, w]: its norm is {norm}, not within {ROTATION_NORM_TOLERANCE:e} of 1"),
            );
        }
    }
    p.positive(&format!("{at}/scale"), placement.scale);
    p.0.len() == before
}

/// The field a placed shape's numbers out of range are blamed on: the part of the placement
/// that changes them.
fn placement_field(at: &str, placement: &Placement) -> String {
    let part = if placement.scale != 1.0 {
        "scale"
    } else if !placement.is_unrotated() {
        "rotation"
    } else {
        "translation"
    };
    format!("{at}/{part}")
}

/// A placed collider's coordinates and lengths stay within their ranges.
fn placed_collider_problems(p: &mut Problems, at: &str, collider: &ColliderSpec, placement: &Placement) {
    if *placement == Placement::default() {
        return;
    }
    let blame = placement_field(at, placement);
    let mut placed = Problems(Vec::new());
    let point = |x: [f64; 3]| placement.point(glam::DVec3::from_array(x)).to_array();
    match collider {
        ColliderSpec::Plane(c) => {
            placed.vector(&blame, &point(c.point));
        }
        ColliderSpec::Sphere(c) => {
            placed.vector(&blame, &point(c.center));
            placed.length(&blame, placement.scale * c.radius);
        }
        ColliderSpec::Box(c) => {
            placed.vector(&blame, &point(c.center));
            placed.lengths(&blame, &c.half_extents.map(|h| placement.scale * h));
        }
        ColliderSpec::Cylinder(c) => {
            placed.vector(&blame, &point(c.center));
            placed.length(&blame, placement.scale * c.radius);
            placed.length(&blame, placement.scale * c.height);
        }
        ColliderSpec::Mesh(c) => {
            for vertex in c.vertices.chunks_exact(3) {
                if !placed.vector(&blame, &point([vertex[0], vertex[1], vertex[2]])) {
                    break;
                }
            }
        }
    }
    if let Some(first) = placed.0.into_iter().next() {
        p.add(blame, format!("puts the collider out of range: {}", first.detail));
    }
}

fn wind_problems(p: &mut Problems, wind: &WindSpec) {
    p.vector("/wind/velocity", &wind.velocity);
    p.non_negative("/wind/coefficient", wind.coefficient);
    if let Some(gust) = &wind.gust {
        let amplitude = gust.amplitude;
        if p.finite("/wind/gust/amplitude", &[amplitude]) && !(0.0..=1.0).contains(&amplitude) {
            p.add("/wind/gust/amplitude", format!("must be in [0, 1], got {amplitude}"));
        }
        p.non_negative("/wind/gust/frequency", gust.frequency);
        p.length("/wind/gust/wavelength", gust.wavelength);
    }
}
