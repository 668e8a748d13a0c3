//! A sweep's table read back from its JSON ([`Table::to_json`]), the exact inverse: a table
//! fetched from a server prints, plots and meets thresholds as one made here does.

use serde_json::Value;

use super::{Row, Table};
use crate::solver::Energy;

impl Table {
    /// Reads a table from the JSON [`Table::to_json`] makes (members it does not make, such as
    /// a server's `id` or `links`, are ignored); the error names the member at fault.
    pub fn from_json(table: &Value) -> Result<Self, String> {
        let pointers: Vec<String> = table["pointers"]
            .as_array()
            .ok_or("/pointers is not an array")?
            .iter()
            .map(|p| p.as_str().map(str::to_string).ok_or("/pointers holds a non-string"))
            .collect::<Result<_, _>>()?;
        let rows = table["rows"]
            .as_array()
            .ok_or("/rows is not an array")?
            .iter()
            .enumerate()
            .map(|(i, row)| read_row(row, &pointers).map_err(|e| format!("/rows/{i}{e}")))
            .collect::<Result<_, _>>()?;
        let reference = match table.get("reference") {
            Some(row) => Some(read_row(row, &[]).map_err(|e| format!("/reference{e}"))?),
            None => None,
        };
        Ok(Self { pointers, rows, reference })
    }
}

fn read_row(row: &Value, pointers: &[String]) -> Result<Row, String> {
    let text = |key: &str| row[key].as_str().map(str::to_string).ok_or(format!("/{key} is not a string"));
    let number = |key: &str| row[key].as_f64().ok_or(format!("/{key} is not a number"));
    let optional = |key: &str| row.get(key).map(|_| number(key)).transpose();
    let pair = |key: &str| -> Result<Option<(f64, f64)>, String> {
        let Some(value) = row.get(key) else { return Ok(None) };
        let part = |p: &str| value[p].as_f64().ok_or(format!("/{key}/{p} is not a number"));
        Ok(Some((part("max")?, part("rms")?)))
    };
    let values = pointers
        .iter()
        .map(|p| row["values"].get(p).cloned().ok_or(format!("/values has no {p}")))
        .collect::<Result<_, _>>()?;
    let energy = match row.get("energy") {
        Some(e) => {
            let part = |p: &str| e[p].as_f64().ok_or(format!("/energy/{p} is not a number"));
            Some(Energy {
                kinetic: part("kinetic")?,
                gravitational: part("gravitational")?,
                spring: part("spring")?,
            })
        }
        None => None,
    };
    Ok(Row {
        values,
        status: text("status")?,
        detail: row.get("detail").map(|_| text("detail")).transpose()?,
        integrator: text("integrator")?,
        // A row without a step (a run that never reported) has none: `to_json` leaves it out.
        dt: optional("dt")?.unwrap_or(f64::NAN),
        steps: row["steps"].as_u64().ok_or("/steps is not a whole number")?,
        wall_time_s: number("wall_time_s")?,
        estimate: pair("error_estimate")?,
        reference_error: pair("error_vs_reference")?,
        max_strain: optional("max_strain")?,
        energy,
    })
}
