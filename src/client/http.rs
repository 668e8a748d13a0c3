//! The HTTP calls to a drape server, and what their failures mean to the command line.
//!
//! Every answer outside 2xx becomes a [`ClientError`] carrying the server's problem body:
//! statuses about the request's content (400, 409, 413, 415, 422, ...) are the caller's to fix
//! ([`Exit::BadInput`]); those about the server or the caller's standing (401, 403, 404, 408,
//! 429, 5xx) and every failure to connect are [`Exit::Unavailable`].

use std::time::Duration;

use serde_json::Value;
use thiserror::Error;
use ureq::http::Response;
use ureq::{Agent, Body};

use super::{Exit, Problem};

/// How long a connection may take to open.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// The largest JSON reply read (a job or a sweep's table; results are streamed instead).
const MAX_JSON_REPLY: u64 = 1 << 30;

/// A drape server: its base URL and the token sent to it.
pub struct Server {
    agent: Agent,
    base: String,
    token: Option<String>,
}

/// Why a call to the server did not give what was asked.
#[derive(Debug, Error)]
pub enum ClientError {
    /// No answer: the connection was refused, timed out or broke.
    #[error("cannot reach {url}: {reason}")]
    Unreachable {
        /// What was called.
        url: String,
        /// The transport's error.
        reason: String,
    },
    /// The server answered outside 2xx.
    #[error("{method} {url} answered {status} {}", reason_phrase(*.status))]
    Answered {
        /// The method used.
        method: &'static str,
        /// What was called.
        url: String,
        /// The status.
        status: u16,
        /// The problem body.
        problem: Box<Problem>,
    },
    /// The answer is not what a drape server sends.
    #[error("{url} answered what no drape server sends: {reason}")]
    Unexpected {
        /// What was called.
        url: String,
        /// What was wrong with it.
        reason: String,
    },
}

impl ClientError {
    /// The exit code this failure gives.
    pub fn exit(&self) -> Exit {
        match self {
            Self::Answered { status: 401 | 403 | 404 | 408 | 429, .. } => Exit::Unavailable,
            Self::Answered { status, .. } if (400..500).contains(status) => Exit::BadInput,
            _ => Exit::Unavailable,
        }
    }

    /// Prints the failure on standard error, the problem field by field, and gives its exit code.
    pub fn report(&self) -> Exit {
        eprintln!("drape: {self}");
        if let Self::Answered { problem, .. } = self {
            problem.print();
        }
        self.exit()
    }
}

impl Server {
    /// The server at `base` (`http://host:port`, with or without a trailing `/`), sent `token`
    /// as a bearer token if given.
    pub fn new(base: &str, token: Option<&str>) -> Self {
        let config = Agent::config_builder()
            .http_status_as_error(false)
            .timeout_connect(Some(CONNECT_TIMEOUT))
            .user_agent(concat!("drape/", env!("CARGO_PKG_VERSION")))
            .build();
        Self {
            agent: config.into(),
            base: base.trim_end_matches('/').to_string(),
            token: token.map(str::to_string),
        }
    }

    /// The absolute URL of `target` (a path with its query).
    pub fn url(&self, target: &str) -> String {
        format!("{}{target}", self.base)
    }

    /// `POST target` with a JSON `body` and an `Idempotency-Key`; the answer if it is 2xx.
    pub fn post(&self, target: &str, body: &[u8], key: &str) -> Result<Response<Body>, ClientError> {
        let url = self.url(target);
        let mut request =
            self.agent.post(&url).header("content-type", "application/json").header("idempotency-key", key);
        if let Some(token) = &self.token {
            request = request.header("authorization", format!("Bearer {token}"));
        }
        accepted("POST", url.clone(), request.send(body).map_err(|e| unreachable(&url, e))?)
    }

    /// `GET target`, accepting `accept`; the answer if it is 2xx.
    pub fn get(&self, target: &str, accept: &str) -> Result<Response<Body>, ClientError> {
        let url = self.url(target);
        let mut request = self.agent.get(&url).header("accept", accept);
        if let Some(token) = &self.token {
            request = request.header("authorization", format!("Bearer {token}"));
        }
        accepted("GET", url.clone(), request.call().map_err(|e| unreachable(&url, e))?)
    }

    /// `GET target` as JSON.
    pub fn get_json(&self, target: &str) -> Result<Value, ClientError> {
        read_json(&self.url(target), self.get(target, "application/json")?)
    }
}

/// The JSON body of a 2xx answer from `url`.
pub fn read_json(url: &str, response: Response<Body>) -> Result<Value, ClientError> {
    let bytes = response
        .into_body()
        .into_with_config()
        .limit(MAX_JSON_REPLY)
        .read_to_vec()
        .map_err(|e| unreachable(url, e))?;
    serde_json::from_slice(&bytes)
        .map_err(|e| ClientError::Unexpected { url: url.to_string(), reason: format!("not JSON: {e}") })
}

/// The transport's failure to get an answer from `url`.
pub fn unreachable(url: &str, error: impl std::fmt::Display) -> ClientError {
    ClientError::Unreachable { url: url.to_string(), reason: error.to_string() }
}

fn accepted(
    method: &'static str,
    url: String,
    response: Response<Body>,
) -> Result<Response<Body>, ClientError> {
    let status = response.status().as_u16();
    if (200..300).contains(&status) {
        return Ok(response);
    }
    let retry_after = response.headers().get("retry-after").and_then(|v| v.to_str().ok()).map(str::to_string);
    // A problem body is small; a broken one is reported as what could be read.
    let bytes = response.into_body().into_with_config().limit(1 << 20).read_to_vec().unwrap_or_default();
    let problem = Box::new(Problem::from_body(&bytes, retry_after));
    Err(ClientError::Answered { method, url, status, problem })
}

fn reason_phrase(status: u16) -> &'static str {
    ureq::http::StatusCode::from_u16(status).ok().and_then(|s| s.canonical_reason()).unwrap_or("")
}
