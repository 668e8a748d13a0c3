//! The table a sweep makes: one row per variant, observed convergence orders, and CSV.
//!
//! Each row holds the varied values, how the run went, its own error estimate and, with a
//! reference, the error of its final positions against the reference's (max and root-mean-square
//! distance over particles, in metres). When `/dt` is varied and there is a reference, rows that
//! differ only in `dt` form a group whose observed order is the least-squares slope of
//! `ln(error)` against `ln(dt)`.

use std::io::{self, Write};

use serde::Serialize;
use serde::ser::{SerializeMap, Serializer};
use serde_json::Value;

use crate::run::{EstimateOutcome, Recording, Stats, Status};
use crate::scene::{Compiled, Field, FrameSelection, Scene};
use crate::solver::Energy;

/// Compiles a variant for a table: whatever its own output asks, the run keeps only its final
/// positions, which the reference comparison needs.
pub fn compile_for_table(scene: &Scene) -> Compiled {
    let mut compiled = scene.compile();
    compiled.output.frames = FrameSelection::Final;
    compiled.output.fields = vec![Field::Positions];
    compiled
}

/// One variant's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The varied values, in pointer order.
    pub values: Vec<Value>,
    /// `succeeded`, `diverged`, `cancelled` or `failed`.
    pub status: String,
    /// Why a run did not succeed, in words.
    pub detail: Option<String>,
    /// The integrator's name.
    pub integrator: String,
    /// The step, in seconds.
    pub dt: f64,
    /// Steps taken.
    pub steps: u64,
    /// Wall time of the run, in seconds.
    pub wall_time_s: f64,
    /// The run's own error estimate (max, rms), in metres.
    pub estimate: Option<(f64, f64)>,
    /// Error against the reference (max, rms), in metres.
    pub reference_error: Option<(f64, f64)>,
    /// Largest spring strain at the end.
    pub max_strain: Option<f64>,
    /// Energies at the end.
    pub energy: Option<Energy>,
}

impl Row {
    /// The row of a finished run, compared with the reference's final positions if given.
    pub fn from_finished(values: Vec<Value>, finished: &Finished, reference: Option<&[f64]>) -> Self {
        let stats = &finished.stats;
        let estimate = stats.error.as_ref().and_then(|e| match e.outcome {
            EstimateOutcome::Estimate { max, rms, .. } => Some((max, rms)),
            EstimateOutcome::Unavailable { .. } => None,
        });
        let detail = match (&stats.diverged, stats.status) {
            (Some(d), _) => Some(format!("diverged at step {} (t = {} s): {}", d.step, d.t, d.reason)),
            (None, Status::Cancelled) => Some("cancelled".into()),
            (None, Status::Failed) => stats.failure.clone(),
            _ => None,
        };
        Self {
            values,
            status: stats.status.name().into(),
            detail,
            integrator: stats.integrator.name().into(),
            dt: stats.dt,
            steps: stats.steps,
            wall_time_s: stats.wall_time_s,
            estimate,
            reference_error: finished.final_positions.as_deref().zip(reference).map(|(p, r)| distances(p, r)),
            max_strain: stats.max_strain,
            energy: stats.energy,
        }
    }

    /// The row of a run that failed before it could report (a panic, a time limit).
    pub fn failed(values: Vec<Value>, integrator: &str, detail: String) -> Self {
        Self::without_result(values, integrator, "failed", Some(detail))
    }

    /// The row of a run that has no result yet, or none to give: `status` says why (`queued`,
    /// `running`, `failed`, `cancelled`).
    pub fn without_result(
        values: Vec<Value>,
        integrator: &str,
        status: &str,
        detail: Option<String>,
    ) -> Self {
        Self {
            values,
            status: status.into(),
            detail,
            integrator: integrator.into(),
            dt: f64::NAN,
            steps: 0,
            wall_time_s: 0.0,
            estimate: None,
            reference_error: None,
            max_strain: None,
            energy: None,
        }
    }

    /// The error a plot or a convergence fit uses: against the reference if there is one, else
    /// the run's own estimate (max).
    pub fn error(&self) -> Option<f64> {
        self.reference_error.or(self.estimate).map(|(max, _)| max).filter(|e| e.is_finite() && *e > 0.0)
    }
}

/// A recording's last frame of positions, widened to `f64`.
pub fn final_positions(recording: &Recording) -> Option<Vec<f64>> {
    let samples = recording.frames.positions.as_ref()?.to_f64();
    let per_frame = 3 * recording.particles;
    (samples.len() >= per_frame).then(|| samples[samples.len() - per_frame..].to_vec())
}

fn distances(a: &[f64], b: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = a
        .chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
        .collect();
    let max = d.iter().copied().fold(0.0, f64::max);
    let rms = if d.is_empty() { 0.0 } else { (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt() };
    (max, rms)
}

/// What a table row needs of a run that finished: its statistics, and its final positions
/// widened to `f64` (for the comparison with the reference).
#[derive(Clone, Debug)]
pub struct Finished {
    /// The run's statistics.
    pub stats: Stats,
    /// The last frame of positions, if the run recorded one.
    pub final_positions: Option<Vec<f64>>,
}

impl From<Recording> for Finished {
    fn from(recording: Recording) -> Self {
        let final_positions = recording.has_final.then(|| final_positions(&recording)).flatten();
        Self { stats: recording.stats, final_positions }
    }
}

/// Where one run of a sweep stands.
#[derive(Debug)]
pub enum Outcome {
    /// It finished with a result (succeeded, diverged or cancelled).
    Finished(Box<Finished>),
    /// It has no recording: its status (`queued`, `running`, `failed`, ...) and why.
    Pending {
        /// The status to show.
        status: String,
        /// Why, for a failure.
        detail: Option<String>,
    },
}

impl Table {
    /// Makes the table of a sweep from the outcome of its reference run (when it has one) and
    /// of each variant, in variant order.
    pub fn assemble(sweep: &super::Sweep, reference: Option<&Outcome>, variants: &[Outcome]) -> Self {
        let row =
            |values: Vec<Value>, scene: &Scene, outcome: &Outcome, against: Option<&[f64]>| match outcome {
                Outcome::Finished(finished) => Row::from_finished(values, finished, against),
                Outcome::Pending { status, detail } => {
                    Row::without_result(values, scene.integrator.kind().name(), status, detail.clone())
                }
            };
        let reference_positions = match reference {
            Some(Outcome::Finished(finished)) => finished.final_positions.as_deref(),
            _ => None,
        };
        let reference_row = sweep
            .reference
            .as_ref()
            .zip(reference)
            .map(|(scene, outcome)| row(Vec::new(), scene, outcome, None));
        let rows = sweep
            .variants
            .iter()
            .zip(variants)
            .map(|(variant, outcome)| {
                row(variant.values.clone(), &variant.scene, outcome, reference_positions)
            })
            .collect();
        Table { pointers: sweep.pointers.clone(), rows, reference: reference_row }
    }

    /// Whether every run of the sweep has finished.
    pub fn is_complete(&self) -> bool {
        let done = |r: &Row| !matches!(r.status.as_str(), "queued" | "running");
        self.rows.iter().all(done) && self.reference.as_ref().is_none_or(done)
    }
}

/// The observed order of one group of rows that differ only in `dt`.
#[derive(Clone, Debug, PartialEq)]
pub struct Convergence {
    /// The other varied values the group shares, as (pointer, value).
    pub group: Vec<(String, Value)>,
    /// The least-squares slope of ln(error against the reference) over ln(dt).
    pub order: f64,
    /// Rows the fit used.
    pub points: usize,
}

/// A finished sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The varied pointers.
    pub pointers: Vec<String>,
    /// One row per variant, in variant order.
    pub rows: Vec<Row>,
    /// The reference run's row, if there was one.
    pub reference: Option<Row>,
}

impl Table {
    /// The observed orders, when `/dt` is varied and there is a reference.
    pub fn convergence(&self) -> Vec<Convergence> {
        let Some(dt_slot) = self.pointers.iter().position(|p| p == "/dt") else { return Vec::new() };
        if self.reference.is_none() {
            return Vec::new();
        }
        // Each group: the values of the other pointers, and its (ln dt, ln error) points.
        type Group = (Vec<Value>, Vec<(f64, f64)>);
        let mut groups: Vec<Group> = Vec::new();
        for row in &self.rows {
            let key: Vec<Value> = row
                .values
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != dt_slot)
                .map(|(_, v)| v.clone())
                .collect();
            let Some(error) = row.reference_error.map(|(max, _)| max).filter(|e| *e > 0.0) else { continue };
            let point = (row.dt.ln(), error.ln());
            match groups.iter_mut().find(|(k, _)| *k == key) {
                Some((_, points)) => points.push(point),
                None => groups.push((key, vec![point])),
            }
        }
        let others: Vec<&String> =
            self.pointers.iter().enumerate().filter(|(i, _)| *i != dt_slot).map(|(_, p)| p).collect();
        groups
            .into_iter()
            .filter(|(_, points)| points.len() >= 2)
            .map(|(key, points)| Convergence {
                group: others.iter().map(|p| p.to_string()).zip(key).collect(),
                order: slope(&points),
                points: points.len(),
            })
            .collect()
    }

    /// The table as the JSON the API and `drape sweep` print (see its [`Serialize`] impl).
    pub fn to_json(&self) -> Value {
        serde_json::to_value(self).expect("a table serializes")
    }
}

/// The table as the API and `drape sweep` print it: `pointers`, `rows` (each with its `values`
/// by pointer, how the run went and what it measured; a measure that does not apply is left
/// out), the `reference` row and the observed orders (`convergence`) when there are any. Written
/// as it is read, with no tree of values in between, so a table of thousands of rows costs its
/// bytes alone.
impl Serialize for Table {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let convergence = self.convergence();
        let mut table = serializer.serialize_map(None)?;
        table.serialize_entry("pointers", &self.pointers)?;
        let rows: Vec<RowJson<'_>> =
            self.rows.iter().map(|row| RowJson { pointers: &self.pointers, row }).collect();
        table.serialize_entry("rows", &rows)?;
        if let Some(row) = &self.reference {
            table.serialize_entry("reference", &RowJson { pointers: &self.pointers, row })?;
        }
        if !convergence.is_empty() {
            table.serialize_entry(
                "convergence",
                &convergence.iter().map(ConvergenceJson).collect::<Vec<_>>(),
            )?;
        }
        table.end()
    }
}

/// A row with the pointers its values belong to.
struct RowJson<'a> {
    pointers: &'a [String],
    row: &'a Row,
}

impl Serialize for RowJson<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let row = self.row;
        let mut map = serializer.serialize_map(None)?;
        map.serialize_entry("values", &PairsJson(self.pointers.iter().zip(&row.values)))?;
        map.serialize_entry("status", &row.status)?;
        map.serialize_entry("integrator", &row.integrator)?;
        map.serialize_entry("steps", &row.steps)?;
        map.serialize_entry("wall_time_s", &row.wall_time_s)?;
        if row.dt.is_finite() {
            map.serialize_entry("dt", &row.dt)?;
        }
        if let Some(detail) = &row.detail {
            map.serialize_entry("detail", detail)?;
        }
        if let Some((max, rms)) = row.estimate {
            map.serialize_entry("error_estimate", &MaxRms { max, rms })?;
        }
        if let Some((max, rms)) = row.reference_error {
            map.serialize_entry("error_vs_reference", &MaxRms { max, rms })?;
        }
        if let Some(strain) = row.max_strain {
            map.serialize_entry("max_strain", &strain)?;
        }
        if let Some(e) = row.energy {
            let energy = EnergyJson { kinetic: e.kinetic, gravitational: e.gravitational, spring: e.spring };
            map.serialize_entry("energy", &energy)?;
        }
        map.end()
    }
}

/// Pointers and their values, as one JSON object.
struct PairsJson<I>(I);

impl<'a, I: Iterator<Item = (&'a String, &'a Value)> + Clone> Serialize for PairsJson<I> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.0.clone())
    }
}

#[derive(Serialize)]
struct MaxRms {
    max: f64,
    rms: f64,
}

#[derive(Serialize)]
struct EnergyJson {
    kinetic: f64,
    gravitational: f64,
    spring: f64,
}

struct ConvergenceJson<'a>(&'a Convergence);

impl Serialize for ConvergenceJson<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(3))?;
        map.serialize_entry("group", &PairsJson(self.0.group.iter().map(|(p, v)| (p, v))))?;
        map.serialize_entry("order", &self.0.order)?;
        map.serialize_entry("points", &self.0.points)?;
        map.end()
    }
}

fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    sxy / sxx
}

/// Writes the rows as CSV (RFC 4180): one column per varied pointer, then the measures.
pub fn write_csv<W: Write>(table: &Table, mut out: W) -> io::Result<()> {
    let mut header: Vec<String> = table.pointers.clone();
    header.extend(
        [
            "status",
            "integrator",
            "dt",
            "steps",
            "wall_time_s",
            "error_estimate_max",
            "error_estimate_rms",
            "error_vs_reference_max",
            "error_vs_reference_rms",
            "max_strain",
            "energy_kinetic",
            "energy_gravitational",
            "energy_spring",
            "detail",
        ]
        .map(String::from),
    );
    writeln!(out, "{}", header.iter().map(|h| quote(h)).collect::<Vec<_>>().join(","))?;
    for row in &table.rows {
        let number = |x: Option<f64>| x.filter(|v| v.is_finite()).map(|v| v.to_string()).unwrap_or_default();
        let mut cells: Vec<String> = row
            .values
            .iter()
            .map(|v| quote(&v.as_str().map_or_else(|| v.to_string(), str::to_string)))
            .collect();
        cells.extend([
            quote(&row.status),
            quote(&row.integrator),
            number(Some(row.dt)),
            row.steps.to_string(),
            number(Some(row.wall_time_s)),
            number(row.estimate.map(|e| e.0)),
            number(row.estimate.map(|e| e.1)),
            number(row.reference_error.map(|e| e.0)),
            number(row.reference_error.map(|e| e.1)),
            number(row.max_strain),
            number(row.energy.map(|e| e.kinetic)),
            number(row.energy.map(|e| e.gravitational)),
            number(row.energy.map(|e| e.spring)),
            quote(row.detail.as_deref().unwrap_or("")),
        ]);
        writeln!(out, "{}", cells.join(","))?;
    }
    Ok(())
}

/// Quotes a CSV field when it holds a comma, a quote or a line break.
fn quote(field: &str) -> String {
    if field.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}
