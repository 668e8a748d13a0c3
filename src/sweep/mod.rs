//! Parameter sweeps: a base scene, values to vary at JSON Pointers, and an optional reference
//! run; every combination of the values is one run, and the runs make one table.
//!
//! [`Sweep::from_json`] checks everything before any run starts: each pointer must reach into
//! the scene (its parent must exist; a missing last key is added, so defaulted fields can vary),
//! and every variant must be a valid scene, or the error names the `vary` entry at fault. The
//! first `vary` key varies slowest. With a `reference` (a JSON merge patch, RFC 7386, applied to
//! the base scene), each variant's final positions are compared with the reference run's.
//! Running is the caller's business: [`run_locally`] uses threads of this process; the service
//! queues each variant as a job.

mod expand;
mod gate;
mod local;
mod plot;
mod table;
mod table_read;

use serde_json::Value;
use thiserror::Error;

pub use gate::Thresholds;
pub use local::{run_locally, run_locally_with};
pub use plot::write_svg;
pub use table::{Convergence, Finished, Outcome, Row, Table, compile_for_table, final_positions, write_csv};

use crate::scene::{FieldError, Scene};

/// A sweep ready to run: its variants and reference, each a valid scene.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The varied pointers, in the order given.
    pub pointers: Vec<String>,
    /// Every combination: the values at each pointer and the scene they make.
    pub variants: Vec<Variant>,
    /// The reference scene, if one was named.
    pub reference: Option<Scene>,
    /// The JSON document the reference scene was read from.
    pub reference_document: Option<Value>,
}

/// One combination of the varied values.
#[derive(Clone, Debug)]
pub struct Variant {
    /// The value at each pointer, in the order of [`Sweep::pointers`].
    pub values: Vec<Value>,
    /// The scene with those values set.
    pub scene: Scene,
    /// The JSON document the scene was read from.
    pub document: Value,
}

/// Why a document is not a sweep that can run.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum SweepError {
    /// The text is not JSON.
    #[error("malformed JSON at line {line}, column {column}: {message}")]
    Syntax {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser expected.
        message: String,
    },
    /// The sweep is not valid; every problem found is listed, each at its JSON Pointer in the
    /// sweep document.
    #[error("invalid sweep: {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    Invalid(Vec<FieldError>),
    /// More variants than the limit allows.
    #[error("the sweep has {variants} variants, more than the limit of {limit}")]
    TooManyVariants {
        /// Variants the sweep would make.
        variants: u64,
        /// The limit.
        limit: u64,
    },
}

impl SweepError {
    /// The field problems, empty for other errors.
    pub fn field_errors(&self) -> &[FieldError] {
        match self {
            Self::Invalid(errors) => errors,
            _ => &[],
        }
    }
}

impl Sweep {
    /// Parses and checks a sweep, making at most `max_variants` variants.
    pub fn from_json(text: &[u8], max_variants: u64) -> Result<Self, SweepError> {
        let value: Value = serde_json::from_slice(text).map_err(|e| SweepError::Syntax {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        Self::from_value(value, max_variants)
    }

    /// Checks a parsed sweep document, making at most `max_variants` variants.
    pub fn from_value(value: Value, max_variants: u64) -> Result<Self, SweepError> {
        expand::expand(value, max_variants)
    }
}

#[cfg(test)]
mod tests;
