//! The layers around every route: tracing, CORS, compression, request metrics, limits and
//! overload, and a last net that turns any bare error status into a problem body.
//!
//! Outermost first: tracing sees everything; CORS headers go on errors too; gzip applies to
//! large responses (never to event streams); the body limit refuses a declared-too-large body
//! before reading it; a global concurrency limit with load shedding answers `503` at once
//! rather than queueing requests; the timeout answers `408`.

use std::time::Duration;

use axum::Router;
use axum::error_handling::HandleErrorLayer;
use axum::extract::{DefaultBodyLimit, Request};
use axum::http::{HeaderValue, Method, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use tower::limit::GlobalConcurrencyLimitLayer;
use tower::{BoxError, ServiceBuilder};
use tower_http::compression::CompressionLayer;
use tower_http::compression::predicate::{DefaultPredicate, Predicate, SizeAbove};
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::trace::{DefaultMakeSpan, DefaultOnResponse, TraceLayer};
use tracing::Level;

use super::problem::{AppError, PROBLEM_JSON};
use super::{AppState, metrics};

/// Responses smaller than this are sent uncompressed.
const COMPRESS_ABOVE_BYTES: u16 = 1024;

/// Wraps `router` in the layers.
pub(super) fn wrap(router: Router<AppState>, state: &AppState) -> Router<AppState> {
    let config = &state.config;
    let overload = ServiceBuilder::new()
        .layer(HandleErrorLayer::new(overload_problem))
        .load_shed()
        .layer(GlobalConcurrencyLimitLayer::new(config.max_concurrent_requests))
        .timeout(config.request_timeout);
    router
        .layer(DefaultBodyLimit::disable())
        .layer(RequestBodyLimitLayer::new(config.body_limit))
        .layer(overload)
        .layer(middleware::from_fn(problem_for_bare_errors))
        .layer(middleware::from_fn_with_state(state.clone(), metrics::track))
        .layer(
            CompressionLayer::new()
                .compress_when(DefaultPredicate::new().and(SizeAbove::new(COMPRESS_ABOVE_BYTES))),
        )
        .layer(cors(&config.cors_origins))
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(DefaultMakeSpan::new().level(Level::INFO))
                .on_response(DefaultOnResponse::new().level(Level::INFO)),
        )
}

fn cors(origins: &[String]) -> CorsLayer {
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        AllowOrigin::list(origins.iter().filter_map(|o| HeaderValue::from_str(o).ok()))
    };
    CorsLayer::new()
        .allow_origin(allow)
        .allow_methods([Method::GET, Method::POST, Method::DELETE])
        .allow_headers([
            header::CONTENT_TYPE,
            header::ACCEPT,
            "idempotency-key".parse().expect("a header name"),
        ])
        .expose_headers([header::LOCATION, header::RETRY_AFTER, header::CONTENT_LOCATION])
        .max_age(Duration::from_secs(3600))
}

/// Turns the errors of the timeout, load-shedding and concurrency layers into problems.
async fn overload_problem(error: BoxError) -> AppError {
    if error.is::<tower::timeout::error::Elapsed>() {
        AppError::Timeout
    } else if error.is::<tower::load_shed::error::Overloaded>() {
        AppError::Overloaded
    } else {
        AppError::Internal(format!("unhandled layer error: {error}"))
    }
}

/// Gives any error response that is not yet a problem (a layer's bare `413`, say) a problem body.
async fn problem_for_bare_errors(request: Request, next: Next) -> Response {
    let (method, path) = (request.method().to_string(), request.uri().path().to_string());
    let response = next.run(request).await;
    let status = response.status();
    let is_problem =
        response.headers().get(header::CONTENT_TYPE).is_some_and(|v| v.as_bytes() == PROBLEM_JSON.as_bytes());
    if (status.is_client_error() || status.is_server_error()) && !is_problem {
        let mut problem = AppError::for_status(status, &method, &path).into_response();
        *problem.status_mut() = status;
        return problem;
    }
    response
}
