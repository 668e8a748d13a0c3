//! The command line as a client of a drape server: with `--server URL` (or `DRAPE_SERVER`),
//! `drape run`, `drape sweep` and `drape submit` send their work to the server and give the same
//! outputs as the local commands, with exit codes a CI step can act on ([`Exit`]).
//!
//! The client speaks only the public HTTP API, the one `openapi/openapi.yaml` describes: it
//! knows results as bytes in a [`Format`](crate::output::Format) and sweeps as
//! [`Table`](crate::sweep::Table)s, and nothing of how the server queues or runs them. A scene's
//! `"file"` references are resolved before it reaches here, since the server reads no paths.

mod events;
mod exit;
mod http;
mod job;
mod key;
mod problem;
mod sweep;

pub use exit::Exit;
pub use http::{ClientError, Server};
pub use job::{RunOptions, run, submit};
pub use key::idempotency_key;
pub use problem::Problem;
pub use sweep::{SweepOptions, sweep};

/// The flags that make a command a client of a server.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ClientArgs {
    /// Send the work to the drape server at this URL (e.g. `http://drape.internal:8080`)
    /// instead of running it here.
    #[arg(long, env = "DRAPE_SERVER")]
    pub server: Option<String>,
    /// The bearer token for a server that requires one (`drape serve --auth-token`).
    #[arg(long, env = "DRAPE_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Mixed into the request's `Idempotency-Key`, which is otherwise derived from the request
    /// alone: the same scene sent again with the same value is answered by the same job (so a
    /// retried CI step runs nothing twice); a new value (e.g. the pipeline's id) runs it anew.
    #[arg(long)]
    pub idempotency_key: Option<String>,
}

impl ClientArgs {
    /// The server to talk to, if one was named.
    pub fn server(&self) -> Option<Server> {
        self.server.as_deref().map(|base| Server::new(base, self.token.as_deref()))
    }
}
