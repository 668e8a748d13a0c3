//! Encoders that turn a [`Recording`](crate::run::Recording) into the bytes a client asked for,
//! one file per format.

mod json;

pub use json::{stats_json, write_json};
