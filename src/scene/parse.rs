//! Reading a scene from JSON, with every type error placed by JSON Pointer.
//!
//! The top level is read first with bodies and colliders left as raw JSON; each is then read by
//! its `type` into its own struct. Reading in two steps keeps the path of an error inside a body
//! exact, which an internally tagged enum would lose.

use serde::de::DeserializeOwned;
use serde_json::Value;

use super::error::{FieldError, SceneError};
use super::types::{Body, ColliderSpec, RawScene, Scene};

impl Scene {
    /// Parses and validates a scene from JSON text.
    pub fn from_json(text: &[u8]) -> Result<Self, SceneError> {
        let value: Value = serde_json::from_slice(text).map_err(|e| SceneError::Syntax {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        Self::from_value(value)
    }

    /// Reads and validates a scene from a parsed JSON document.
    pub fn from_value(value: Value) -> Result<Self, SceneError> {
        let raw: RawScene = read("", value).map_err(|e| SceneError::Invalid(vec![e]))?;
        let mut errors = Vec::new();
        let mut bodies = Vec::with_capacity(raw.bodies.len());
        for (index, body) in raw.bodies.into_iter().enumerate() {
            match read_body(&format!("/bodies/{index}"), body) {
                Ok(body) => bodies.push(body),
                Err(e) => errors.push(e),
            }
        }
        let mut colliders = Vec::with_capacity(raw.colliders.len());
        for (index, collider) in raw.colliders.into_iter().enumerate() {
            match read_collider(&format!("/colliders/{index}"), collider) {
                Ok(collider) => colliders.push(collider),
                Err(e) => errors.push(e),
            }
        }
        if !errors.is_empty() {
            return Err(SceneError::Invalid(errors));
        }
        let scene = Scene {
            duration: raw.duration,
            integrator: raw.integrator,
            dt: raw.dt,
            precision: raw.precision,
            gravity: raw.gravity,
            drag: raw.drag,
            verlet_damping: raw.verlet_damping,
            solver: raw.solver,
            stop_at_rest: raw.stop_at_rest,
            error_estimate: raw.error_estimate,
            bodies,
            colliders,
            wind: raw.wind,
            self_collision: raw.self_collision,
            strain_limit: raw.strain_limit,
            output: raw.output,
        };
        let errors = scene.problems();
        if errors.is_empty() { Ok(scene) } else { Err(SceneError::Invalid(errors)) }
    }
}

const BODY_TYPES: &str = "`cloth`, `chain`, `lattice` or `mesh`";
const COLLIDER_TYPES: &str = "`plane`, `sphere`, `box`, `cylinder` or `mesh`";

/// Takes the `type` out of an object that must have one.
fn take_type(pointer: &str, value: &mut Value, what: &str, types: &str) -> Result<String, FieldError> {
    let Some(object) = value.as_object_mut() else {
        return Err(FieldError::new(pointer, format!("{what} must be a JSON object with a `type`")));
    };
    match object.remove("type") {
        Some(Value::String(kind)) => Ok(kind),
        Some(_) => Err(FieldError::new(format!("{pointer}/type"), format!("must be a string: {types}"))),
        None => Err(FieldError::new(format!("{pointer}/type"), format!("missing: {types}"))),
    }
}

fn read_collider(pointer: &str, mut value: Value) -> Result<ColliderSpec, FieldError> {
    let kind = take_type(pointer, &mut value, "a collider", COLLIDER_TYPES)?;
    match kind.as_str() {
        "plane" => read(pointer, value).map(ColliderSpec::Plane),
        "sphere" => read(pointer, value).map(ColliderSpec::Sphere),
        "box" => read(pointer, value).map(ColliderSpec::Box),
        "cylinder" => read(pointer, value).map(ColliderSpec::Cylinder),
        "mesh" => read(pointer, value).map(ColliderSpec::Mesh),
        other => Err(FieldError::new(
            format!("{pointer}/type"),
            format!("unknown collider type `{other}`: expected {COLLIDER_TYPES}"),
        )),
    }
}

fn read_body(pointer: &str, mut value: Value) -> Result<Body, FieldError> {
    let kind = take_type(pointer, &mut value, "a body", BODY_TYPES)?;
    if matches!(kind.as_str(), "cloth" | "mesh") {
        material_conflict(pointer, &value)?;
    }
    match kind.as_str() {
        "cloth" => read(pointer, value).map(Body::Cloth),
        "chain" => read(pointer, value).map(Body::Chain),
        "lattice" => read(pointer, value).map(Body::Lattice),
        "mesh" => read(pointer, value).map(Body::Mesh),
        other => Err(FieldError::new(
            format!("{pointer}/type"),
            format!("unknown body type `{other}`: expected {BODY_TYPES}"),
        )),
    }
}

/// A body with a `material` takes its stiffness and its mass from it: `springs` or `mass` beside
/// it is a contradiction, refused rather than resolved.
fn material_conflict(pointer: &str, value: &Value) -> Result<(), FieldError> {
    let has = |field: &str| value.get(field).is_some();
    if !has("material") {
        return Ok(());
    }
    for (field, what) in [("springs", "stiffness"), ("mass", "mass (density × area)")] {
        if has(field) {
            return Err(FieldError::new(
                format!("{pointer}/{field}"),
                format!("give `material` or `{field}`, not both: the material sets the body's {what}"),
            ));
        }
    }
    Ok(())
}

/// Deserializes `value`, placing any error by JSON Pointer below `base`.
fn read<T: DeserializeOwned>(base: &str, value: Value) -> Result<T, FieldError> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let mut pointer = base.to_string();
        for segment in e.path().iter() {
            use serde_path_to_error::Segment;
            match segment {
                Segment::Seq { index } => pointer.push_str(&format!("/{index}")),
                Segment::Map { key } => {
                    pointer.push('/');
                    pointer.push_str(&key.replace('~', "~0").replace('/', "~1"));
                }
                Segment::Enum { .. } | Segment::Unknown => {}
            }
        }
        let message = e.into_inner().to_string();
        // serde places a missing field at its parent; the field itself is the useful place.
        if let Some(field) = message.strip_prefix("missing field `").and_then(|m| m.split('`').next()) {
            pointer.push('/');
            pointer.push_str(field);
        }
        FieldError::new(pointer, message)
    })
}
