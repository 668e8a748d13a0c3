//! The thresholds a CI step puts on a sweep's table (`drape sweep --max-error E --min-order P`):
//! which rows and which convergence groups cross them, in words a build log can show.
//!
//! `--max-error` bounds each row's error in metres: the maximum distance of its final positions
//! from the reference run's, or, in a sweep without a reference, the run's own error estimate
//! (max). A row that did not succeed, or has no error to check, crosses it: its error is not
//! known to be within the bound. `--min-order` bounds each group's observed convergence order
//! ([`Table::convergence`]), which needs `/dt` varied and a reference ([`Thresholds::check`]).

use serde_json::Value;

use super::{Sweep, Table};

/// The bounds a sweep must keep.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Thresholds {
    /// The largest error a row may have, in metres.
    pub max_error: Option<f64>,
    /// The smallest convergence order a group may show.
    pub min_order: Option<f64>,
}

impl Thresholds {
    /// Why these thresholds cannot be applied to `sweep`, before it runs: a bound that is not a
    /// positive finite number, or `--min-order` on a sweep that yields no convergence order.
    pub fn check(&self, sweep: &Sweep) -> Result<(), String> {
        self.check_for(&sweep.pointers, sweep.reference.is_some())
    }

    /// [`Thresholds::check`] for a sweep that varies `pointers` and has a reference or not
    /// (what a client knows of a sweep it sends to a server).
    pub fn check_for(&self, pointers: &[String], has_reference: bool) -> Result<(), String> {
        for (flag, value) in [("--max-error", self.max_error), ("--min-order", self.min_order)] {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(format!("{flag} must be a positive number, got {v}"));
            }
        }
        let orders = has_reference && pointers.iter().any(|p| p == "/dt");
        if self.min_order.is_some() && !orders {
            return Err("--min-order needs a sweep that varies /dt and has a reference".into());
        }
        Ok(())
    }

    /// Every crossing in `table`, one line each; empty when the table keeps every bound.
    pub fn crossings(&self, table: &Table) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(bound) = self.max_error {
            for row in &table.rows {
                let label = label(table.pointers.iter().zip(&row.values));
                match row.error() {
                    _ if row.status != "succeeded" => lines.push(format!("{label}: the run {}", row.status)),
                    Some(error) if error > bound => {
                        lines.push(format!("{label}: error {error:.3e} m is above --max-error {bound:e}"))
                    }
                    Some(_) => {}
                    None => lines
                        .push(format!("{label}: no error to check (give a reference or an error estimate)")),
                }
            }
        }
        if let Some(bound) = self.min_order {
            for group in table.convergence() {
                // A NaN order (no usable fit) crosses too.
                if group.order.is_nan() || group.order < bound {
                    let label = label(group.group.iter().map(|(p, v)| (p, v)));
                    lines.push(format!("{label}: order {:.2} is below --min-order {bound}", group.order));
                }
            }
        }
        lines
    }
}

/// `/integrator = rk4, /dt = 0.004`: a row or group by its varied values.
fn label<'a>(values: impl Iterator<Item = (&'a String, &'a Value)>) -> String {
    let parts: Vec<String> = values
        .map(|(pointer, value)| match value {
            Value::String(s) => format!("{pointer} = {s}"),
            other => format!("{pointer} = {other}"),
        })
        .collect();
    if parts.is_empty() { "the sweep".into() } else { parts.join(", ") }
}
