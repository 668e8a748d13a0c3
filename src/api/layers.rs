//! The layers around every route: tracing, CORS, compression, request metrics, limits and
//! overload, and a last net that turns any bare error status into a problem body.
//!
//! Outermost first: tracing sees everything; a request target or header section over the limits is
//! refused (`414`, `431`) before anything reads it; the `Host` check refuses requests addressed to
//! other names before anything else answers them, CORS preflights included; CORS headers go on
//! errors too, and preflights are answered without a token (browsers send none with them); gzip
//! applies to large responses (never to event streams); the token check comes before any limit, so
//! requests without a token take no place of those with one; the body limit refuses a
//! declared-too-large body before reading it, and counts a gzip body (`Content-Encoding: gzip`;
//! other encodings are a `415` problem) after decompression, so a small body that inflates past
//! the limit is a `413` once the limit is reached, never inflated whole; a global concurrency
//! limit with load shedding answers `503` at once rather than queueing requests; the timeout
//! answers `408`.

use std::time::Duration;

use axum::Router;
use axum::error_handling::HandleErrorLayer;
use axum::extract::{DefaultBodyLimit, Request};
use axum::http::{HeaderName, HeaderValue, Method, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use tower::limit::GlobalConcurrencyLimitLayer;
use tower::{BoxError, ServiceBuilder};
use tower_http::compression::CompressionLayer;
use tower_http::compression::predicate::{DefaultPredicate, Predicate, SizeAbove};
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::decompression::RequestDecompressionLayer;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::trace::{DefaultMakeSpan, DefaultOnResponse, TraceLayer};
use tracing::Level;

use super::problem::{AppError, PROBLEM_JSON};
use super::{AppState, access, metrics};

/// The longest request target (path and query) read, in bytes; longer is a `414` problem.
pub const MAX_URI_BYTES: usize = 8 << 10;

/// The largest header section read, in bytes (each field counted as `name: value` and its line
/// end); larger is a `431` problem.
pub const MAX_HEADER_BYTES: usize = 32 << 10;

/// The most header fields read; more is a `431` problem.
pub const MAX_HEADER_FIELDS: usize = 100;

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
        // Outside the body limit, so that the limit counts the bytes after decompression.
        .layer(RequestDecompressionLayer::new().gzip(true).pass_through_unaccepted(false))
        .layer(middleware::from_fn(accept_content_encoding))
        .layer(overload)
        .layer(middleware::from_fn(problem_for_bare_errors))
        .layer(middleware::from_fn_with_state(state.clone(), access::require_token))
        .layer(middleware::from_fn_with_state(state.clone(), metrics::track))
        .layer(
            CompressionLayer::new()
                .compress_when(DefaultPredicate::new().and(SizeAbove::new(COMPRESS_ABOVE_BYTES))),
        )
        .layer(cors(&config.cors_origins))
        .layer(middleware::from_fn_with_state(state.clone(), access::check_host))
        .layer(middleware::from_fn(refuse_oversized_heads))
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
            header::AUTHORIZATION,
            "idempotency-key".parse().expect("a header name"),
        ])
        // Every response header the description declares, so that a page on another origin can
        // read them (a browser hides all but a few safe ones otherwise).
        .expose_headers([
            header::LOCATION,
            header::RETRY_AFTER,
            header::CONTENT_LOCATION,
            header::WWW_AUTHENTICATE,
            header::ETAG,
            header::CACHE_CONTROL,
            HeaderName::from_static("drape-job-id"),
            HeaderName::from_static("drape-job-status"),
            HeaderName::from_static("drape-omitted-fields"),
            HeaderName::from_static("idempotent-replayed"),
        ])
        .max_age(Duration::from_secs(3600))
}

/// Refuses a request whose target or header section is over the limits above. hyper refuses
/// larger heads still on its own, with an empty `414` or `431` (a target over 65534 bytes, more
/// header fields than the server's connection allows, or a head over hyper's read buffer).
async fn refuse_oversized_heads(request: Request, next: Next) -> Response {
    let uri = request.uri();
    let target = uri.path_and_query().map_or(0, |p| p.as_str().len())
        + uri.authority().map_or(0, |a| a.as_str().len());
    if target > MAX_URI_BYTES {
        return AppError::UriTooLong { length: target, limit: MAX_URI_BYTES }.into_response();
    }
    let headers = request.headers();
    if headers.len() > MAX_HEADER_FIELDS {
        let detail = format!(
            "the request has {} header fields, over the {MAX_HEADER_FIELDS} this server reads",
            headers.len()
        );
        return AppError::HeadersTooLarge { detail }.into_response();
    }
    let size: usize = headers.iter().map(|(name, value)| name.as_str().len() + value.len() + 4).sum();
    if size > MAX_HEADER_BYTES {
        let detail =
            format!("the header fields take {size} bytes, over the {MAX_HEADER_BYTES} this server reads");
        return AppError::HeadersTooLarge { detail }.into_response();
    }
    next.run(request).await
}

/// Lets through a body sent as it is or as gzip (`Content-Encoding: gzip`, `x-gzip` or
/// `identity`, in any case) in the spelling the decompression layer reads, and refuses any other
/// encoding with a `415` problem naming it.
async fn accept_content_encoding(mut request: Request, next: Next) -> Response {
    let Some(value) = request.headers().get(header::CONTENT_ENCODING) else {
        return next.run(request).await;
    };
    let encoding = String::from_utf8_lossy(value.as_bytes()).trim().to_ascii_lowercase();
    let canonical = match encoding.as_str() {
        "gzip" | "x-gzip" => "gzip",
        "identity" => "identity",
        _ => return AppError::UnsupportedEncoding { found: encoding }.into_response(),
    };
    request.headers_mut().insert(header::CONTENT_ENCODING, HeaderValue::from_static(canonical));
    next.run(request).await
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
