//! Reading a JSON result back into a [`Recording`]: the exact inverse of
//! [`write_json`](super::write_json).
//!
//! The JSON result is drape's canonical form of a run: it carries every number in the run's own
//! precision, bit for bit, and every statistic. A service can keep it alone and still answer in
//! any other format later, by reading it back and encoding the recording again; writing what
//! this reads gives back the same bytes.
//!
//! JSON has no number for NaN or infinity, so the writer puts `null` where a value is not
//! finite (an energy that overflowed, say); this reads every such `null` back as NaN. Which
//! non-finite value it was is lost, and nothing else is: writing the recording again gives the
//! same `null`. A statistic that does not apply is left out, not `null`, so the two stay apart.

use serde::Deserialize;
use serde_json::Value;
use thiserror::Error;

use crate::run::{
    ColliderShape, CompanionStep, Diverged, ErrorEstimate, EstimateOutcome, Frames, RecordedCollider,
    Recording, RigidTransform, Samples, Stats, Status,
};
use crate::scene::{BodyInfo, DtSource, ErrorEstimateName, FrameSelection, Precision};
use crate::solver::{Energy, Equilibrium, IntegratorKind, LinearSolveStats, STAGE_NAMES};

/// Why bytes are not a JSON result drape wrote.
#[derive(Debug, Error)]
pub enum ReadError {
    /// Not JSON, or not of the result's shape.
    #[error("not a drape JSON result: {0}")]
    Shape(#[from] serde_json::Error),
    /// A field holds a value drape does not write.
    #[error("not a drape JSON result: `{field}` is {value}")]
    Value {
        /// The field.
        field: &'static str,
        /// What it held.
        value: String,
    },
}

#[derive(Deserialize)]
struct ResultIn {
    mesh: MeshIn,
    #[serde(default)]
    colliders: Vec<ColliderIn>,
    #[serde(default)]
    frames: Option<Vec<FrameIn>>,
    #[serde(default, rename = "final")]
    last: Option<FrameIn>,
    stats: Value,
}

#[derive(Deserialize)]
struct MeshIn {
    particles: usize,
    springs: usize,
    triangles: Vec<u32>,
    bodies: Vec<BodyIn>,
}

#[derive(Deserialize)]
struct BodyIn {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    offset: usize,
    count: usize,
}

/// A collider entry: `type` says which of the shape fields it has.
#[derive(Deserialize)]
struct ColliderIn {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    point: Option<[Number; 3]>,
    normal: Option<[Number; 3]>,
    center: Option<[Number; 3]>,
    radius: Option<Number>,
    half_extents: Option<[Number; 3]>,
    height: Option<Number>,
    vertices: Option<Vec<Number>>,
    triangles: Option<Vec<u32>>,
    frames: Option<Vec<TransformIn>>,
}

#[derive(Deserialize)]
struct TransformIn {
    translation: [Number; 3],
    rotation: [Number; 4],
}

impl ColliderIn {
    fn read(self, frames: usize) -> Result<RecordedCollider, ReadError> {
        fn given<T>(value: Option<T>, field: &'static str) -> Result<T, ReadError> {
            value.ok_or(ReadError::Value { field, value: "missing".into() })
        }
        let v = |a: [Number; 3]| a.map(|n| n.0);
        let shape = match self.kind.as_str() {
            "plane" => ColliderShape::Plane {
                point: v(given(self.point, "colliders.point")?),
                normal: v(given(self.normal, "colliders.normal")?),
            },
            "sphere" => ColliderShape::Sphere {
                center: v(given(self.center, "colliders.center")?),
                radius: given(self.radius, "colliders.radius")?.0,
            },
            "box" => ColliderShape::Box {
                center: v(given(self.center, "colliders.center")?),
                half_extents: v(given(self.half_extents, "colliders.half_extents")?),
            },
            "cylinder" => ColliderShape::Cylinder {
                center: v(given(self.center, "colliders.center")?),
                radius: given(self.radius, "colliders.radius")?.0,
                height: given(self.height, "colliders.height")?.0,
            },
            "mesh" => {
                let triangles = given(self.triangles, "colliders.triangles")?;
                if triangles.len() % 3 != 0 {
                    let value = format!("{} indices, not whole triangles", triangles.len());
                    return Err(ReadError::Value { field: "colliders.triangles", value });
                }
                ColliderShape::Mesh {
                    vertices: given(self.vertices, "colliders.vertices")?.iter().map(|n| n.0).collect(),
                    triangles: triangles.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
                }
            }
            _ => return Err(ReadError::Value { field: "colliders.type", value: self.kind }),
        };
        let transforms = self
            .frames
            .map(|list| {
                if list.len() != frames {
                    let value = format!("{} transforms for {frames} frames", list.len());
                    return Err(ReadError::Value { field: "colliders.frames", value });
                }
                Ok(list
                    .iter()
                    .map(|f| RigidTransform {
                        translation: v(f.translation),
                        rotation: f.rotation.map(|n| n.0),
                    })
                    .collect())
            })
            .transpose()?;
        Ok(RecordedCollider { name: self.name, shape, frames: transforms })
    }
}

#[derive(Deserialize)]
struct FrameIn {
    t: Number,
    positions: Option<Vec<Number>>,
    velocities: Option<Vec<Number>>,
    normals: Option<Vec<Number>>,
    energy: Option<EnergyIn>,
    strain: Option<Vec<Number>>,
}

#[derive(Deserialize)]
struct EnergyIn {
    kinetic: Number,
    gravitational: Number,
    spring: Number,
}

impl From<&EnergyIn> for Energy {
    fn from(e: &EnergyIn) -> Self {
        Energy { kinetic: e.kinetic.0, gravitational: e.gravitational.0, spring: e.spring.0 }
    }
}

/// A number of the result: `null` stands for a value that was not finite, and reads as NaN.
#[derive(Clone, Copy)]
struct Number(f64);

impl<'de> Deserialize<'de> for Number {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Ok(Number(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN)))
    }
}

/// Reads a JSON result.
pub fn read_json(bytes: &[u8]) -> Result<Recording, ReadError> {
    let result: ResultIn = serde_json::from_slice(bytes)?;
    let stats = read_stats(&result.stats)?;
    let (selection, frames, has_final) = match (result.frames, result.last) {
        (Some(frames), last) => (FrameSelection::All, frames, last.is_some()),
        (None, Some(last)) => (FrameSelection::Final, vec![last], true),
        (None, None) => (FrameSelection::None, Vec::new(), false),
    };
    // A field is recorded when the first frame carries it.
    let samples = |pick: fn(&FrameIn) -> Option<&Vec<Number>>| -> Option<Samples> {
        pick(frames.first()?)?;
        let values = frames.iter().flat_map(|f| pick(f).into_iter().flatten().map(|n| n.0));
        Some(match stats.precision {
            Precision::F32 => Samples::F32(values.map(|v| v as f32).collect()),
            Precision::F64 => Samples::F64(values.collect()),
        })
    };
    let bodies = result
        .mesh
        .bodies
        .into_iter()
        .map(|b| {
            let kind = ["cloth", "chain", "lattice", "mesh"]
                .into_iter()
                .find(|k| *k == b.kind)
                .ok_or(ReadError::Value { field: "mesh.bodies.type", value: b.kind.clone() })?;
            Ok(BodyInfo { name: b.name, kind, offset: b.offset, count: b.count })
        })
        .collect::<Result<_, ReadError>>()?;
    let recorded = Frames {
        times: frames.iter().map(|f| f.t.0).collect(),
        positions: samples(|f| f.positions.as_ref()),
        velocities: samples(|f| f.velocities.as_ref()),
        normals: samples(|f| f.normals.as_ref()),
        energy: frames
            .first()
            .and_then(|f| f.energy.as_ref())
            .map(|_| frames.iter().filter_map(|f| f.energy.as_ref()).map(Energy::from).collect()),
        strain: frames
            .first()
            .and_then(|f| f.strain.as_ref())
            .map(|_| frames.iter().flat_map(|f| f.strain.iter().flatten().map(|n| n.0)).collect()),
    };
    let colliders =
        result.colliders.into_iter().map(|c| c.read(recorded.times.len())).collect::<Result<_, _>>()?;
    Ok(Recording {
        particles: result.mesh.particles,
        springs: result.mesh.springs,
        triangles: result.mesh.triangles.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        bodies,
        selection,
        frames: recorded,
        colliders,
        has_final,
        stats,
    })
}

/// The part of a JSON result [`read_json_final`] reads; the rest is skipped unread.
#[derive(Deserialize)]
struct FinalIn {
    mesh: ParticlesIn,
    #[serde(default)]
    frames: Option<serde::de::IgnoredAny>,
    #[serde(default, rename = "final")]
    last: Option<PositionsIn>,
    stats: Value,
}

#[derive(Deserialize)]
struct ParticlesIn {
    particles: usize,
}

#[derive(Deserialize)]
struct PositionsIn {
    positions: Option<Vec<Number>>,
}

/// The statistics of a JSON result and its final positions widened to `f64` (`None` without a
/// final frame of positions), as [`read_json`] would give them, without reading the rest: the
/// mesh and other fields are skipped. A result of every frame is read whole.
pub fn read_json_final(bytes: &[u8]) -> Result<(Stats, Option<Vec<f64>>), ReadError> {
    let result: FinalIn = serde_json::from_slice(bytes)?;
    if result.frames.is_some() && result.last.is_some() {
        let recording = read_json(bytes)?;
        let per_frame = 3 * recording.particles;
        let samples = recording.frames.positions.as_ref().map(Samples::to_f64);
        let last = samples.filter(|s| s.len() >= per_frame).map(|s| s[s.len() - per_frame..].to_vec());
        return Ok((recording.stats, last));
    }
    let stats = read_stats(&result.stats)?;
    let per_frame = 3 * result.mesh.particles;
    let positions = result.last.and_then(|last| last.positions).map(|numbers| match stats.precision {
        // Widened as a recording's `f32` samples are: the number written is the `f32`'s.
        Precision::F32 => numbers.iter().map(|n| f64::from(n.0 as f32)).collect::<Vec<f64>>(),
        Precision::F64 => numbers.iter().map(|n| n.0).collect(),
    });
    let last = positions.filter(|p| p.len() >= per_frame).map(|p| p[p.len() - per_frame..].to_vec());
    Ok((stats, last))
}

/// Looks a name up among those drape writes.
fn named<T: Copy>(field: &'static str, value: &Value, options: &[(&str, T)]) -> Result<T, ReadError> {
    let name = value.as_str().unwrap_or_default();
    options
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, t)| *t)
        .ok_or(ReadError::Value { field, value: value.to_string() })
}

/// A statistic's number; `null` is one that was not finite, read as NaN.
fn number(field: &'static str, value: &Value) -> Result<f64, ReadError> {
    if value.is_null() {
        return Ok(f64::NAN);
    }
    value.as_f64().ok_or(ReadError::Value { field, value: value.to_string() })
}

fn count(field: &'static str, value: &Value) -> Result<u64, ReadError> {
    value.as_u64().ok_or(ReadError::Value { field, value: value.to_string() })
}

/// A statistic that is left out when it does not apply: absent is `None`, while `null` is a
/// value that was not finite.
fn optional<T>(
    value: Option<&Value>,
    read: impl FnOnce(&Value) -> Result<T, ReadError>,
) -> Result<Option<T>, ReadError> {
    value.map(read).transpose()
}

fn read_stats(s: &Value) -> Result<Stats, ReadError> {
    let integrators: Vec<(&str, IntegratorKind)> =
        IntegratorKind::ALL.iter().map(|k| (k.name(), *k)).collect();
    let steps = count("stats.steps", &s["steps"])?;
    let stages = s["stages"]
        .as_array()
        .ok_or(ReadError::Value { field: "stats.stages", value: s["stages"].to_string() })?
        .iter()
        .map(|stage| named("stats.stages", stage, &STAGE_NAMES.map(|n| (n, n))))
        .collect::<Result<_, _>>()?;
    Ok(Stats {
        status: named(
            "stats.status",
            &s["status"],
            &[
                ("succeeded", Status::Succeeded),
                ("diverged", Status::Diverged),
                ("cancelled", Status::Cancelled),
                ("failed", Status::Failed),
            ],
        )?,
        wall_time_s: number("stats.wall_time_s", &s["wall_time_s"])?,
        steps,
        dt: number("stats.dt", &s["dt"])?,
        dt_source: named(
            "stats.dt_source",
            &s["dt_source"],
            &[("scene", DtSource::Scene), ("stability", DtSource::Stability)],
        )?,
        integrator: named("stats.integrator", &s["integrator"], &integrators)?,
        precision: named(
            "stats.precision",
            &s["precision"],
            &[("f32", Precision::F32), ("f64", Precision::F64)],
        )?,
        stages,
        energy: optional(s.get("energy"), |e| Ok(Energy::from(&EnergyIn::deserialize(e)?)))?,
        max_strain: optional(s.get("max_strain"), |v| number("stats.max_strain", v))?,
        stable_dt: optional(s.get("stable_dt"), |v| number("stats.stable_dt", v))?,
        diverged: optional(s.get("diverged"), |d| {
            Ok(Diverged {
                step: count("stats.diverged.step", &d["step"])?,
                t: number("stats.diverged.t", &d["t"])?,
                reason: d["reason"].as_str().unwrap_or_default().to_string(),
                suggested_dt: optional(d.get("suggested_dt"), |v| number("stats.diverged.suggested_dt", v))?,
            })
        })?,
        failure: s["failure"].as_str().map(str::to_string),
        stopped_at_rest: optional(s.get("stopped_at_rest"), |v| number("stats.stopped_at_rest", v))?,
        drape_coefficient: optional(s.get("drape_coefficient"), |v| number("stats.drape_coefficient", v))?,
        linear_solver: optional(s.get("linear_solver"), |l| {
            let mean = number("stats.linear_solver.mean_iterations", &l["mean_iterations"])?;
            Ok(LinearSolveStats {
                tolerance: number("stats.linear_solver.tolerance", &l["tolerance"])?,
                reduction: number("stats.linear_solver.reduction", &l["reduction"])?,
                max_iterations: count("stats.linear_solver.max_iterations", &l["max_iterations"])? as usize,
                last_iterations: count("stats.linear_solver.last_iterations", &l["last_iterations"])?
                    as usize,
                most_iterations: count("stats.linear_solver.most_iterations", &l["most_iterations"])?
                    as usize,
                total_iterations: (mean * steps as f64).round() as u64,
                unconverged_solves: count(
                    "stats.linear_solver.unconverged_solves",
                    &l["unconverged_solves"],
                )?,
                last_residual: number("stats.linear_solver.last_residual", &l["last_residual"])?,
            })
        })?,
        error: optional(s.get("error"), read_error)?,
    })
}

fn read_error(e: &Value) -> Result<ErrorEstimate, ReadError> {
    let outcome = match e.get("unavailable") {
        Some(reason) => {
            EstimateOutcome::Unavailable { reason: reason.as_str().unwrap_or_default().to_string() }
        }
        None => EstimateOutcome::Estimate {
            max: number("stats.error.max", &e["max"])?,
            rms: number("stats.error.rms", &e["rms"])?,
            observed_order: optional(e.get("observed_order"), |v| number("stats.error.observed_order", v))?,
            reliable: e["reliable"].as_bool(),
        },
    };
    Ok(ErrorEstimate {
        method: named(
            "stats.error.method",
            &e["method"],
            &[
                ("richardson", ErrorEstimateName::Richardson),
                ("richardson3", ErrorEstimateName::Richardson3),
                ("resolution", ErrorEstimateName::Resolution),
            ],
        )?,
        order: number("stats.error.order", &e["order"])?,
        outcome,
        extra_wall_time_s: number("stats.error.extra_wall_time_s", &e["extra_wall_time_s"])?,
        companion_step: optional(e.get("companion_step"), |step| {
            named(
                "stats.error.companion_step",
                step,
                &[("doubled", CompanionStep::Doubled), ("halved", CompanionStep::Halved)],
            )
        })?,
        equilibrium: optional(e.get("equilibrium"), read_equilibrium)?,
    })
}

fn read_equilibrium(q: &Value) -> Result<Equilibrium, ReadError> {
    Ok(Equilibrium {
        residual_force: number("stats.error.equilibrium.residual_force", &q["residual_force"])?,
        residual_relative: optional(q.get("residual_relative"), |v| {
            number("stats.error.equilibrium.residual_relative", v)
        })?,
        displacement_max: number("stats.error.equilibrium.displacement_max", &q["displacement_max"])?,
        displacement_rms: number("stats.error.equilibrium.displacement_rms", &q["displacement_rms"])?,
        iterations: count("stats.error.equilibrium.iterations", &q["iterations"])? as usize,
    })
}
