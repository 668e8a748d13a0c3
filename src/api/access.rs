//! Who may call the API: bearer tokens and the `Host` names requests may be addressed to.
//!
//! With tokens configured (`--auth-token`), every request but `GET /healthz`, the viewer's page
//! and files (`GET /`, `GET /viewer/{file}`: nothing secret, and a browser navigating sends no
//! token) and CORS preflights must carry `Authorization: Bearer <token>` with one of them, or gets a `401` problem with
//! `WWW-Authenticate: Bearer`. Tokens are compared in time that depends on the lengths of the
//! token sent and of the tokens held, never on their contents, and every token held is compared,
//! so a client learns nothing of a token from how long a refusal takes.
//!
//! The `Host` check (`--allowed-hosts`) defends a server on a loopback address against DNS
//! rebinding: a web page whose name an attacker points at 127.0.0.1 reaches the port, but its
//! requests carry the attacker's name in `Host`, and are refused with `421 Misdirected Request`.
//! Names are matched without their port, case-insensitively, and a trailing dot is ignored.

use std::fmt;
use std::net::IpAddr;

use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use subtle::{Choice, ConstantTimeEq};

use super::AppState;
use super::problem::AppError;

/// Whether `path` stays open without a token: liveness probes and the viewer's static files.
fn is_open(path: &str) -> bool {
    path == "/healthz" || path == "/" || path.strip_prefix("/viewer/").is_some_and(|file| !file.contains('/'))
}

/// A secret a client presents as `Authorization: Bearer <token>`. Its `Debug` form hides it.
#[derive(Clone, PartialEq, Eq)]
pub struct AuthToken(String);

impl AuthToken {
    /// Checks a token: 1 to 1024 characters of the RFC 6750 `b64token` alphabet (letters, digits
    /// and `-._~+/`, then optional trailing `=`), which is what a client can send in the header.
    pub fn parse(text: &str) -> Result<Self, String> {
        let body = text.trim_end_matches('=');
        let allowed = |c: char| c.is_ascii_alphanumeric() || "-._~+/".contains(c);
        if text.is_empty() || text.len() > 1024 {
            return Err("a token must be 1 to 1024 characters long".into());
        }
        if body.is_empty() || !body.chars().all(allowed) {
            return Err("a token may hold only letters, digits and `-._~+/`, then trailing `=`".into());
        }
        Ok(Self(text.to_string()))
    }
}

impl fmt::Debug for AuthToken {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("AuthToken(..)")
    }
}

impl std::str::FromStr for AuthToken {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        Self::parse(text)
    }
}

/// Whether `presented` is one of `tokens`. Every token is compared, each in time independent of
/// the bytes compared.
fn is_accepted(presented: &[u8], tokens: &[AuthToken]) -> bool {
    let accepted =
        tokens.iter().fold(Choice::from(0), |found, token| found | presented.ct_eq(token.0.as_bytes()));
    accepted.into()
}

/// The `Host` names the server answers to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AllowedHosts {
    /// Any name (`*`).
    Any,
    /// Only these names, normalised by [`host_name`].
    Names(Vec<String>),
}

impl AllowedHosts {
    /// The loopback names: `localhost`, `127.0.0.1` and `[::1]`.
    pub fn loopback() -> Self {
        Self::Names(["localhost", "127.0.0.1", "[::1]"].map(String::from).to_vec())
    }

    /// The default for a server bound to `ip`: the loopback names on a loopback address (where
    /// only this machine's clients, and web pages rebound to it, can reach the server), any name
    /// elsewhere (where the names clients use are not known in advance).
    pub fn default_for(ip: IpAddr) -> Self {
        if ip.is_loopback() { Self::loopback() } else { Self::Any }
    }

    /// From the names given to `--allowed-hosts`; `*` among them allows any.
    pub fn from_names(names: &[String]) -> Self {
        if names.iter().any(|n| n.trim() == "*") {
            return Self::Any;
        }
        Self::Names(names.iter().map(|n| host_name(n.trim())).filter(|n| !n.is_empty()).collect())
    }

    fn allows(&self, host: &str) -> bool {
        match self {
            Self::Any => true,
            Self::Names(names) => {
                let host = host_name(host);
                names.contains(&host)
            }
        }
    }
}

/// The name of a `Host` value without its port, lowercased, without a trailing dot; an IPv6
/// address in brackets (`[::1]`), whether or not it was given in them.
fn host_name(host: &str) -> String {
    let host = host.trim();
    let name = if let Some(rest) = host.strip_prefix('[') {
        // `[::1]:8080` or `[::1]`.
        rest.split(']').next().unwrap_or("")
    } else if host.matches(':').count() > 1 {
        // A bare IPv6 address has colons of its own and cannot carry a port.
        host
    } else {
        host.split(':').next().unwrap_or("")
    };
    let name = name.trim_end_matches('.').to_ascii_lowercase();
    if name.contains(':') { format!("[{name}]") } else { name }
}

/// Refuses a request whose `Host` is not allowed with `421`.
pub(super) async fn check_host(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let allowed = &state.config.allowed_hosts;
    if *allowed == AllowedHosts::Any {
        return next.run(request).await;
    }
    // An absolute-form request target carries the authority; otherwise the `Host` header does.
    let host = match request.uri().authority() {
        Some(authority) => Some(authority.as_str().to_string()),
        None => {
            request.headers().get(header::HOST).map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned())
        }
    };
    match host {
        Some(host) if allowed.allows(&host) => next.run(request).await,
        host => AppError::HostNotAllowed { host }.into_response(),
    }
}

/// Refuses a request without an accepted bearer token with `401`, when tokens are configured.
pub(super) async fn require_token(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let tokens = &state.config.auth_tokens;
    if tokens.is_empty() || is_open(request.uri().path()) {
        return next.run(request).await;
    }
    let presented = request.headers().get(header::AUTHORIZATION).map(|v| bearer_token(v.as_bytes()));
    match presented {
        Some(Some(token)) if is_accepted(token, tokens) => next.run(request).await,
        Some(Some(_)) => AppError::Unauthorized { reason: Refusal::UnknownToken }.into_response(),
        Some(None) => AppError::Unauthorized { reason: Refusal::NotBearer }.into_response(),
        None => AppError::Unauthorized { reason: Refusal::NoToken }.into_response(),
    }
}

/// Why a request was refused a `401`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// No `Authorization` header.
    NoToken,
    /// An `Authorization` header of another scheme than `Bearer`, or without a token.
    NotBearer,
    /// A bearer token this server does not accept.
    UnknownToken,
}

/// The token of an `Authorization: Bearer <token>` value (the scheme is case-insensitive).
fn bearer_token(value: &[u8]) -> Option<&[u8]> {
    const SCHEME: &[u8] = b"bearer ";
    let scheme = value.get(..SCHEME.len())?;
    if !scheme.eq_ignore_ascii_case(SCHEME) {
        return None;
    }
    let token = value[SCHEME.len()..].trim_ascii();
    (!token.is_empty()).then_some(token)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens(list: &[&str]) -> Vec<AuthToken> {
        list.iter().map(|t| AuthToken::parse(t).unwrap()).collect()
    }

    #[test]
    fn a_token_is_accepted_only_whole_and_exact() {
        let held = tokens(&["s3cret-token", "other.token=="]);
        assert!(is_accepted(b"s3cret-token", &held));
        assert!(is_accepted(b"other.token==", &held));
        for wrong in [&b"s3cret-toke"[..], b"s3cret-token2", b"S3cret-token", b"", b"s3cret-tokeN"] {
            assert!(!is_accepted(wrong, &held), "{}", String::from_utf8_lossy(wrong));
        }
        assert!(!is_accepted(b"s3cret-token", &[]));
    }

    #[test]
    fn tokens_are_checked_and_hidden_from_debug() {
        assert_eq!(AuthToken::parse("abc-DEF_0.9~+/=="), Ok(AuthToken("abc-DEF_0.9~+/==".into())));
        for bad in ["", "two words", "comma,separated", "=", "tab\there", "é"] {
            assert!(AuthToken::parse(bad).is_err(), "{bad:?}");
        }
        assert!(AuthToken::parse(&"a".repeat(1025)).is_err());
        assert_eq!(format!("{:?}", AuthToken::parse("visible").unwrap()), "AuthToken(..)");
    }

    #[test]
    fn bearer_values_are_read_whatever_the_scheme_case() {
        assert_eq!(bearer_token(b"Bearer abc"), Some(&b"abc"[..]));
        assert_eq!(bearer_token(b"bearer  abc "), Some(&b"abc"[..]));
        assert_eq!(bearer_token(b"BEARER abc"), Some(&b"abc"[..]));
        assert_eq!(bearer_token(b"Basic YWJjOmRlZg=="), None);
        assert_eq!(bearer_token(b"Bearer "), None);
        assert_eq!(bearer_token(b"Bearer"), None);
    }

    #[test]
    fn host_names_are_matched_without_port_case_or_trailing_dot() {
        assert_eq!(host_name("LocalHost:8080"), "localhost");
        assert_eq!(host_name("localhost."), "localhost");
        assert_eq!(host_name("127.0.0.1:0"), "127.0.0.1");
        assert_eq!(host_name("[::1]:8080"), "[::1]");
        assert_eq!(host_name("::1"), "[::1]");
        assert_eq!(host_name("[::1]"), "[::1]");
        let loopback = AllowedHosts::loopback();
        for yes in ["localhost", "localhost:8080", "127.0.0.1:80", "[::1]:1", "LOCALHOST."] {
            assert!(loopback.allows(yes), "{yes}");
        }
        for no in ["evil.example", "evil.example:8080", "localhost.evil.example", "127.0.0.2", ""] {
            assert!(!loopback.allows(no), "{no}");
        }
        let listed = AllowedHosts::from_names(&["Drape.Example:8080".into(), "::1".into()]);
        assert_eq!(listed, AllowedHosts::Names(vec!["drape.example".into(), "[::1]".into()]));
        assert!(listed.allows("drape.example:443"));
        assert_eq!(AllowedHosts::from_names(&["a".into(), "*".into()]), AllowedHosts::Any);
        assert_eq!(AllowedHosts::default_for("127.0.0.1".parse().unwrap()), AllowedHosts::loopback());
        assert_eq!(AllowedHosts::default_for("::1".parse().unwrap()), AllowedHosts::loopback());
        assert_eq!(AllowedHosts::default_for("0.0.0.0".parse().unwrap()), AllowedHosts::Any);
    }
}
