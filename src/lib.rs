//! drape simulates cloth and other mass-spring bodies, as a library, a command-line tool and an
//! HTTP service.
//!
//! # Layout
//! - [`solver`]: the physics. Pure, synchronous, deterministic; no I/O, no serde, no async.
//! - [`scene`]: the public JSON contract for a scene: types, defaults, validation, and its
//!   compilation into solver inputs.
//! - [`run`]: runs one compiled scene to a [`run::Recording`]: steps it, records the frames and
//!   fields asked for, watches for divergence.
//! - [`output`]: encoders that turn a recording into the bytes a client asked for.
//! - [`sweep`]: parameter sweeps: variants of a scene at JSON Pointers, run into one table with
//!   errors, CSV and a work-precision plot.
//! - [`jobs`]: the worker threads that run scenes off the async runtime, limits, cancellation,
//!   progress, and the job stores (memory, SQLite, PostgreSQL) that are also the queue.
//! - [`assets`]: mesh files (OBJ, GLB) read into vertices and triangles, their stored form, and
//!   the references a scene makes to them.
//! - [`api`]: the HTTP API over [`jobs`]: routes, problem+json errors, limits, OpenAPI.
//! - [`client`]: the command line as a client of a drape server (`--server URL`): the HTTP
//!   calls, the server's problems printed field by field, and the exit codes.
//! - [`config`] and [`server`]: the settings of `drape serve` and the server's life.
//! - [`progress`]: the progress bar `drape run` and `drape sweep` draw on a terminal.
//!
//! Data flows one way: scene JSON → [`scene::Scene`] → [`scene::Compiled`] → [`run::execute`] →
//! [`run::Recording`] → [`output`].

pub mod api;
pub mod assets;
pub mod client;
pub mod config;
pub mod jobs;
pub mod output;
pub mod progress;
pub mod run;
pub mod scene;
pub mod server;
pub mod solver;
pub mod sweep;
