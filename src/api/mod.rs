//! The HTTP API: an axum [`Router`] over the job system.
//!
//! [`app`] builds the router from [`routes`], the one list of endpoints that both the router and
//! the OpenAPI test read. Handlers talk to [`jobs`](crate::jobs), never to the solver. Every
//! error is an [`AppError`] answered as `application/problem+json`; limits and overload are
//! layers (`layers.rs`) or checks before work starts.

mod access;
mod assets;
mod events;
mod examples;
mod extract;
mod jobs;
mod layers;
mod metrics;
mod openapi;
mod problem;
mod simulate;
mod sse;
mod sweep_events;
mod sweeps;
mod viewer;
mod views;

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::handler::Handler;
use axum::http::{Method, Uri};
use axum::routing::{MethodFilter, MethodRouter, on};

pub use access::{AllowedHosts, AuthToken};
pub use examples::EXAMPLES;
pub use metrics::HttpMetrics;
pub use openapi::{OPENAPI_YAML, spec as openapi_spec};
pub use problem::{AppError, PROBLEM_JSON};
pub use viewer::viewer_files;

use crate::jobs::Jobs;

/// Settings of the HTTP side.
#[derive(Clone, Debug)]
pub struct ApiConfig {
    /// Largest request body, in bytes.
    pub body_limit: usize,
    /// Largest run `POST /simulate` takes, in element-steps (see [`Cost`](crate::jobs::Cost));
    /// larger runs go to `POST /jobs`.
    pub simulate_work_budget: u64,
    /// Longest time to the response head of any request.
    pub request_timeout: Duration,
    /// Requests handled at once; more are refused with `503`.
    pub max_concurrent_requests: usize,
    /// Origins allowed by CORS; `*` allows any.
    pub cors_origins: Vec<String>,
    /// Most variants one sweep may make.
    pub max_sweep_variants: u64,
    /// Bearer tokens, any of which a request must carry (but `/healthz` and CORS preflights);
    /// none: no token is asked for.
    pub auth_tokens: Vec<AuthToken>,
    /// The `Host` names requests may be addressed to.
    pub allowed_hosts: AllowedHosts,
    /// Longest a connection may take from the first byte of a request to the end of its headers.
    pub header_read_timeout: Duration,
    /// Longest a connection may stay open with no request in flight and none arriving.
    pub idle_timeout: Duration,
}

impl Default for ApiConfig {
    fn default() -> Self {
        Self {
            body_limit: 4 << 20,
            simulate_work_budget: 400_000_000,
            request_timeout: Duration::from_secs(330),
            max_concurrent_requests: 1024,
            cors_origins: vec!["*".into()],
            max_sweep_variants: 10_000,
            auth_tokens: Vec::new(),
            allowed_hosts: AllowedHosts::Any,
            header_read_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
        }
    }
}

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    /// The job system.
    pub jobs: Jobs,
    /// HTTP settings.
    pub config: Arc<ApiConfig>,
    /// Request counts and latencies.
    pub http_metrics: Arc<HttpMetrics>,
}

impl AppState {
    /// State over a running job system.
    pub fn new(jobs: Jobs, config: ApiConfig) -> Self {
        Self { jobs, config: Arc::new(config), http_metrics: Arc::default() }
    }
}

/// One endpoint: method, path (axum syntax, as in the OpenAPI file) and handler.
pub struct Route {
    /// The method.
    pub method: Method,
    /// The path, e.g. `/jobs/{id}`.
    pub path: &'static str,
    handler: MethodRouter<AppState>,
}

fn route<H, T>(method: Method, path: &'static str, handler: H) -> Route
where
    H: Handler<T, AppState>,
    T: 'static,
{
    let filter = MethodFilter::try_from(method.clone()).expect("a standard method");
    Route { method, path, handler: on(filter, handler) }
}

/// Every endpoint of the API.
pub fn routes() -> Vec<Route> {
    vec![
        route(Method::POST, "/simulate", simulate::simulate),
        route(Method::POST, "/jobs", jobs::submit),
        route(Method::GET, "/jobs", jobs::list),
        route(Method::GET, "/jobs/{id}", jobs::get),
        route(Method::DELETE, "/jobs/{id}", jobs::cancel),
        route(Method::GET, "/jobs/{id}/result", jobs::result),
        route(Method::GET, "/jobs/{id}/events", events::events),
        route(Method::POST, "/sweeps", sweeps::submit),
        route(Method::GET, "/sweeps", sweeps::list),
        route(Method::GET, "/sweeps/{id}", sweeps::get),
        route(Method::GET, "/sweeps/{id}/events", sweep_events::events),
        route(Method::DELETE, "/sweeps/{id}", sweeps::cancel),
        route(Method::GET, "/sweeps/{id}/plot.svg", sweeps::plot),
        route(Method::POST, "/assets", assets::upload),
        route(Method::GET, "/assets", assets::list),
        route(Method::GET, "/assets/{id}", assets::get),
        route(Method::DELETE, "/assets/{id}", assets::delete),
        route(Method::GET, "/healthz", healthz),
        route(Method::GET, "/metrics", metrics::metrics),
        route(Method::GET, "/openapi.json", openapi::openapi),
        route(Method::GET, "/", viewer::index),
        route(Method::GET, "/viewer/{file}", viewer::file),
        route(Method::GET, "/examples", examples::list),
    ]
}

/// The application: every route, with its layers.
pub fn app(state: AppState) -> Router {
    let router = routes().into_iter().fold(Router::new(), |router, r| router.route(r.path, r.handler));
    let router = router.fallback(not_found).method_not_allowed_fallback(method_not_allowed);
    layers::wrap(router, &state).with_state(state)
}

/// `GET /healthz`: the server is up and answering.
async fn healthz() -> axum::Json<serde_json::Value> {
    axum::Json(serde_json::json!({"status": "ok"}))
}

async fn not_found(uri: Uri) -> AppError {
    AppError::NoRoute { path: uri.path().to_string() }
}

async fn method_not_allowed(method: Method, uri: Uri) -> AppError {
    AppError::MethodNotAllowed { method: method.to_string(), path: uri.path().to_string() }
}
