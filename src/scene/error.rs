//! What is wrong with a scene, field by field.

use thiserror::Error;

/// One problem with one field.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    /// The field, as a JSON Pointer into the submitted document (`""` is the whole document).
    pub pointer: String,
    /// Why the value is refused, in words a user can act on.
    pub detail: String,
}

impl FieldError {
    /// A problem at `pointer`.
    pub fn new(pointer: impl Into<String>, detail: impl Into<String>) -> Self {
        Self { pointer: pointer.into(), detail: detail.into() }
    }
}

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let at = if self.pointer.is_empty() { "(document)" } else { &self.pointer };
        write!(f, "{at}: {}", self.detail)
    }
}

/// Why a document is not a valid scene.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum SceneError {
    /// The text is not JSON.
    #[error("malformed JSON at line {line}, column {column}: {message}")]
    Syntax {
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// What the parser expected.
        message: String,
    },
    /// The JSON does not describe a valid scene; every problem found is listed.
    #[error("invalid scene: {}", list(.0))]
    Invalid(Vec<FieldError>),
}

impl SceneError {
    /// The field problems, empty for a syntax error.
    pub fn field_errors(&self) -> &[FieldError] {
        match self {
            Self::Syntax { .. } => &[],
            Self::Invalid(errors) => errors,
        }
    }
}

fn list(errors: &[FieldError]) -> String {
    errors.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
}
