//! The JSON result: `mesh`, `frames`, `final` and `stats`, with flat numeric arrays.
//!
//! `colliders` (present when the scene has any) lists each collider's shape, and for one that
//! moves its transform at each frame; it is not a selectable field, being small next to the
//! frames.
//!
//! Numbers are written in the run's precision: an `f32` run prints the shortest decimal that
//! reads back as the same `f32`. JSON has no NaN or infinity, so a number that is not finite (an
//! energy that overflowed, say) is written as `null`, wherever it is. `frames` is present for
//! `frames: all`, `final` when the run finished with a frame to show. Statistics that do not
//! apply are left out, never `null`: a `null` is always a number that was not finite.

use std::io::{self, Write};

use serde::Serialize;
use serde::ser::{SerializeMap, Serializer};

use super::Selected;
use crate::run::{ColliderShape, EstimateOutcome, RecordedCollider, Recording, Samples, Stats};
use crate::scene::FrameSelection;
use crate::solver::Energy;

/// Writes `recording` as the JSON result, with every field it recorded.
pub fn write_json<W: Write>(recording: &Recording, writer: W) -> io::Result<()> {
    write_json_fields(recording, &Selected::all(recording), writer)
}

/// Writes `recording` as the JSON result, with the fields `selected` only.
pub(super) fn write_json_fields<W: Write>(
    recording: &Recording,
    selected: &Selected,
    writer: W,
) -> io::Result<()> {
    let mut serializer = serde_json::Serializer::new(writer);
    // `From` hands back a writer's own error as it was, so its caller can still tell what it is.
    ResultView { recording, selected }.serialize(&mut serializer).map_err(io::Error::from)
}

/// The `stats` object of the JSON result on its own, for job listings and progress views.
pub fn stats_json(stats: &Stats) -> serde_json::Value {
    serde_json::to_value(StatsView(stats)).expect("statistics are plain JSON values")
}

struct ResultView<'a> {
    recording: &'a Recording,
    selected: &'a Selected<'a>,
}

impl Serialize for ResultView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (r, selected) = (self.recording, self.selected);
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("mesh", &MeshView(r))?;
        if !r.colliders.is_empty() {
            let colliders: Vec<ColliderView> = r.colliders.iter().map(ColliderView).collect();
            map.serialize_entry("colliders", &colliders)?;
        }
        if r.selection == FrameSelection::All {
            let frames: Vec<FrameView> =
                (0..r.frames.len()).map(|k| FrameView { recording: r, selected, index: k }).collect();
            map.serialize_entry("frames", &frames)?;
        }
        if r.has_final {
            map.serialize_entry("final", &FrameView { recording: r, selected, index: r.frames.len() - 1 })?;
        }
        map.serialize_entry("stats", &StatsView(&r.stats))?;
        map.end()
    }
}

struct MeshView<'a>(&'a Recording);

impl Serialize for MeshView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let r = self.0;
        let mut map = s.serialize_map(Some(4))?;
        map.serialize_entry("particles", &r.particles)?;
        map.serialize_entry("springs", &r.springs)?;
        map.serialize_entry("triangles", r.triangles.as_flattened())?;
        let bodies: Vec<_> = r
            .bodies
            .iter()
            .map(
                |b| serde_json::json!({"name": b.name, "type": b.kind, "offset": b.offset, "count": b.count}),
            )
            .collect();
        map.serialize_entry("bodies", &bodies)?;
        map.end()
    }
}

struct ColliderView<'a>(&'a RecordedCollider);

impl Serialize for ColliderView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let c = self.0;
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("name", &c.name)?;
        map.serialize_entry("type", c.shape.type_name())?;
        match &c.shape {
            ColliderShape::Plane { point, normal } => {
                map.serialize_entry("point", point)?;
                map.serialize_entry("normal", normal)?;
            }
            ColliderShape::Sphere { center, radius } => {
                map.serialize_entry("center", center)?;
                map.serialize_entry("radius", radius)?;
            }
            ColliderShape::Box { center, half_extents } => {
                map.serialize_entry("center", center)?;
                map.serialize_entry("half_extents", half_extents)?;
            }
            ColliderShape::Cylinder { center, radius, height } => {
                map.serialize_entry("center", center)?;
                map.serialize_entry("radius", radius)?;
                map.serialize_entry("height", height)?;
            }
            ColliderShape::Mesh { vertices, triangles } => {
                map.serialize_entry("vertices", vertices)?;
                map.serialize_entry("triangles", triangles.as_flattened())?;
            }
        }
        if let Some(frames) = &c.frames {
            let frames: Vec<_> = frames
                .iter()
                .map(|f| serde_json::json!({"translation": f.translation, "rotation": f.rotation}))
                .collect();
            map.serialize_entry("frames", &frames)?;
        }
        map.end()
    }
}

struct FrameView<'a> {
    recording: &'a Recording,
    selected: &'a Selected<'a>,
    index: usize,
}

impl Serialize for FrameView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (f, k) = (self.selected, self.index);
        let per_frame = 3 * self.recording.particles;
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("t", &self.recording.frames.times[k])?;
        for (name, samples) in
            [("positions", f.positions), ("velocities", f.velocities), ("normals", f.normals)]
        {
            if let Some(samples) = samples {
                map.serialize_entry(name, &SliceView { samples, start: k * per_frame, len: per_frame })?;
            }
        }
        if let Some(energy) = f.energy {
            map.serialize_entry("energy", &EnergyView(&energy[k]))?;
        }
        if let Some(strain) = f.strain {
            let n = self.recording.springs;
            map.serialize_entry("strain", &strain[k * n..(k + 1) * n])?;
        }
        map.end()
    }
}

struct SliceView<'a> {
    samples: &'a Samples,
    start: usize,
    len: usize,
}

impl Serialize for SliceView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let range = self.start..self.start + self.len;
        match self.samples {
            Samples::F32(v) => v[range].serialize(s),
            Samples::F64(v) => v[range].serialize(s),
        }
    }
}

struct EnergyView<'a>(&'a Energy);

impl Serialize for EnergyView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("kinetic", &self.0.kinetic)?;
        map.serialize_entry("gravitational", &self.0.gravitational)?;
        map.serialize_entry("spring", &self.0.spring)?;
        map.end()
    }
}

struct StatsView<'a>(&'a Stats);

impl Serialize for StatsView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let st = self.0;
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("status", st.status.name())?;
        map.serialize_entry("wall_time_s", &st.wall_time_s)?;
        map.serialize_entry("steps", &st.steps)?;
        map.serialize_entry("dt", &st.dt)?;
        map.serialize_entry("dt_source", st.dt_source.name())?;
        map.serialize_entry("integrator", st.integrator.name())?;
        map.serialize_entry("precision", st.precision.name())?;
        map.serialize_entry("stages", &st.stages)?;
        if let Some(energy) = &st.energy {
            map.serialize_entry("energy", &EnergyView(energy))?;
        }
        if let Some(strain) = st.max_strain {
            map.serialize_entry("max_strain", &strain)?;
        }
        if let Some(stable) = st.stable_dt {
            map.serialize_entry("stable_dt", &stable)?;
        }
        if let Some(d) = &st.diverged {
            let mut diverged = serde_json::json!({"step": d.step, "t": d.t, "reason": d.reason});
            if let Some(dt) = d.suggested_dt {
                diverged["suggested_dt"] = dt.into();
            }
            map.serialize_entry("diverged", &diverged)?;
        }
        if let Some(failure) = &st.failure {
            map.serialize_entry("failure", failure)?;
        }
        if let Some(t) = st.stopped_at_rest {
            map.serialize_entry("stopped_at_rest", &t)?;
        }
        if let Some(d) = st.drape_coefficient {
            map.serialize_entry("drape_coefficient", &d)?;
        }
        if let Some(ls) = &st.linear_solver {
            let solver = serde_json::json!({
                "tolerance": ls.tolerance,
                "reduction": ls.reduction,
                "max_iterations": ls.max_iterations,
                "last_iterations": ls.last_iterations,
                "most_iterations": ls.most_iterations,
                "mean_iterations": if st.steps > 0 { ls.total_iterations as f64 / st.steps as f64 } else { 0.0 },
                "unconverged_solves": ls.unconverged_solves,
                "last_residual": ls.last_residual,
            });
            map.serialize_entry("linear_solver", &solver)?;
        }
        if let Some(e) = &st.error {
            let mut error = serde_json::json!({
                "method": e.method.name(), "order": e.order, "extra_wall_time_s": e.extra_wall_time_s,
            });
            if let Some(step) = e.companion_step {
                error["companion_step"] = step.name().into();
            }
            match &e.outcome {
                EstimateOutcome::Estimate { max, rms, observed_order, reliable } => {
                    error["max"] = (*max).into();
                    error["rms"] = (*rms).into();
                    if let Some(order) = observed_order {
                        error["observed_order"] = (*order).into();
                    }
                    if let Some(reliable) = reliable {
                        error["reliable"] = (*reliable).into();
                    }
                }
                EstimateOutcome::Unavailable { reason } => error["unavailable"] = reason.as_str().into(),
            }
            if let Some(q) = &e.equilibrium {
                let mut equilibrium = serde_json::json!({
                    "residual_force": q.residual_force,
                    "displacement_max": q.displacement_max, "displacement_rms": q.displacement_rms,
                    "iterations": q.iterations,
                });
                if let Some(relative) = q.residual_relative {
                    equilibrium["residual_relative"] = relative.into();
                }
                error["equilibrium"] = equilibrium;
            }
            map.serialize_entry("error", &error)?;
        }
        map.end()
    }
}
