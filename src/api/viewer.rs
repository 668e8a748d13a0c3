//! The viewer: `GET /` is a web page that runs scenes and plays their results with three.js,
//! and `GET /viewer/{file}` its scripts, styles and the three.js it uses, all embedded in the
//! binary so that it works with no internet. It is a client of the public API only.
//!
//! Each file is answered with its media type, an `ETag` of its bytes and `Cache-Control:
//! no-cache`, so a browser keeps a copy and asks again with `If-None-Match`, getting `304` until
//! the binary serving it changes. The page and its files hold nothing secret and stay open
//! without a token, like `/healthz` (a browser sends none when it navigates); every API call the
//! page makes carries the token its user gives it.

use std::collections::HashMap;
use std::sync::LazyLock;

use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::problem::AppError;

/// One embedded file.
struct Asset {
    name: &'static str,
    media_type: &'static str,
    bytes: &'static [u8],
}

macro_rules! asset {
    ($name:literal, $media_type:expr) => {
        Asset { name: $name, media_type: $media_type, bytes: include_bytes!(concat!("viewer/", $name)) }
    };
    (vendor $name:literal, $media_type:expr) => {
        Asset {
            name: $name,
            media_type: $media_type,
            bytes: include_bytes!(concat!("viewer/vendor/", $name)),
        }
    };
}

const JAVASCRIPT: &str = "text/javascript; charset=utf-8";
const INDEX: Asset = asset!("index.html", "text/html; charset=utf-8");

/// The files under `/viewer/`.
const FILES: &[Asset] = &[
    asset!("viewer.css", "text/css; charset=utf-8"),
    asset!("api.js", JAVASCRIPT),
    asset!("editor.js", JAVASCRIPT),
    asset!("jobs.js", JAVASCRIPT),
    asset!("main.js", JAVASCRIPT),
    asset!("player.js", JAVASCRIPT),
    asset!("shading.js", JAVASCRIPT),
    asset!("stats.js", JAVASCRIPT),
    asset!("sweeps.js", JAVASCRIPT),
    asset!(vendor "three.module.js", JAVASCRIPT),
    asset!(vendor "three.core.js", JAVASCRIPT),
    asset!(vendor "OrbitControls.js", JAVASCRIPT),
    asset!(vendor "three-LICENSE.txt", "text/plain; charset=utf-8"),
];

/// The names of the files under `/viewer/`.
pub fn viewer_files() -> impl Iterator<Item = &'static str> {
    FILES.iter().map(|asset| asset.name)
}

/// `GET /`: the viewer page.
pub(super) async fn index(headers: HeaderMap) -> Response {
    serve(&INDEX, &headers)
}

/// `GET /viewer/{file}`: one of the page's files.
pub(super) async fn file(Path(name): Path<String>, headers: HeaderMap) -> Result<Response, AppError> {
    let asset = FILES
        .iter()
        .find(|asset| asset.name == name)
        .ok_or_else(|| AppError::NoRoute { path: format!("/viewer/{name}") })?;
    Ok(serve(asset, &headers))
}

/// Every file's `ETag`, by name, hashed once: the files are part of the binary and never change
/// while it runs.
static ETAGS: LazyLock<HashMap<&'static str, HeaderValue>> = LazyLock::new(|| {
    std::iter::once(&INDEX)
        .chain(FILES)
        .map(|asset| {
            let etag = format!("\"{:016x}\"", fnv1a(asset.bytes));
            (asset.name, HeaderValue::from_str(&etag).expect("hex digits in quotes are a header value"))
        })
        .collect()
});

fn serve(asset: &Asset, headers: &HeaderMap) -> Response {
    let etag = ETAGS[asset.name].clone();
    let cache = [(header::CACHE_CONTROL, HeaderValue::from_static("no-cache")), (header::ETAG, etag.clone())];
    let fresh = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|tags| tags.split(',').any(|tag| tag.trim() == etag || tag.trim() == "*"));
    if fresh {
        return (StatusCode::NOT_MODIFIED, cache).into_response();
    }
    let media_type = [
        (header::CONTENT_TYPE, HeaderValue::from_static(asset.media_type)),
        (header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff")),
    ];
    (cache, media_type, asset.bytes).into_response()
}

/// The 64-bit FNV-1a hash: a stable fingerprint of a file's bytes for its `ETag`.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| (hash ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}
