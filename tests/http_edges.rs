//! The edges of HTTP: oversized request heads, compressed bodies, connections that stall, and
//! what `drape serve` says at start about who may reach it.

mod common;
mod deadline;
mod serve;

use std::io::Write;
use std::time::Instant;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::ApiConfig;
use serve::{PATIENCE, Server};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn post_encoded(path: &str, encoding: &str, body: Vec<u8>) -> Request<Body> {
    Request::post(path)
        .header("content-type", "application/json")
        .header("content-encoding", encoding)
        .body(Body::from(body))
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_overlong_target_is_a_414_problem() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let just_fits = format!("/jobs/{}", "a".repeat(8192 - "/jobs/".len()));
    let answer = get(&app, &just_fits).await;
    assert_eq!(answer.status, 404, "8192 bytes are read");
    let over = format!("/jobs?{}", "a".repeat(8193 - "/jobs?".len()));
    let answer = get(&app, &over).await;
    assert_eq!(answer.status, 414);
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/uri-too-long");
    assert_eq!(problem["detail"], "the path and query are 8193 bytes long, over the 8192 this server reads");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_header_section_is_a_431_problem() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    // One field of 32 KiB in all: name (7) + value + 4 for `: ` and the line end.
    let fits =
        Request::get("/healthz").header("x-large", "v".repeat(32768 - 11)).body(Body::empty()).unwrap();
    assert_eq!(send(&app, fits).await.status, 200);
    let large =
        Request::get("/healthz").header("x-large", "v".repeat(32768 - 10)).body(Body::empty()).unwrap();
    let answer = send(&app, large).await;
    assert_eq!(answer.status, 431);
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/header-fields-too-large");
    assert_eq!(problem["detail"], "the header fields take 32769 bytes, over the 32768 this server reads");

    let mut many = Request::get("/healthz");
    for n in 0..101 {
        many = many.header(format!("x-field-{n}"), "1");
    }
    let answer = send(&app, many.body(Body::empty()).unwrap()).await;
    assert_eq!(answer.status, 431);
    assert_eq!(
        answer.problem()["detail"],
        "the request has 101 header fields, over the 100 this server reads"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gzip_body_is_read_and_its_inflated_size_is_limited() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let answer = send(&app, post_encoded("/jobs", "gzip", gzip(TINY.as_bytes()))).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let id = answer.json()["id"].as_str().unwrap().to_string();
    assert_eq!(poll_until(&app, &id, is_final).await["status"], "succeeded");
    let answer = send(&app, post_encoded("/jobs", "X-GZIP", gzip(TINY.as_bytes()))).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let answer = send(&app, post_encoded("/jobs", "identity", TINY.as_bytes().to_vec())).await;
    assert_eq!(answer.status, 202, "{}", answer.text());

    // 10 MB of zeros inflate from about 10 KB, past the 4 MiB limit.
    let bomb = gzip(&vec![b'0'; 10_000_000]);
    assert!(bomb.len() < 20_000, "{} bytes", bomb.len());
    let answer = send(&app, post_encoded("/jobs", "gzip", bomb)).await;
    assert_eq!(answer.status, 413);
    assert_eq!(answer.problem()["type"], "/problems/body-too-large");

    let answer = send(&app, post_encoded("/jobs", "br", TINY.as_bytes().to_vec())).await;
    assert_eq!(answer.status, 415);
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/unsupported-content-encoding");
    assert_eq!(problem["detail"], "Content-Encoding is `br`; send the body as it is or as `gzip`");

    let answer = send(&app, post_encoded("/jobs", "gzip", b"not gzip at all".to_vec())).await;
    assert_eq!(answer.status, 400);
    assert_eq!(answer.problem()["type"], "/problems/bad-request");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_integral_float_is_an_integer_over_http_and_a_fraction_is_refused_at_its_pointer() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let whole = TINY.replace(r#""count": 3"#, r#""count": 39.0"#);
    assert_ne!(whole, TINY);
    let answer = post_json(&app, "/jobs", &whole).await;
    assert_eq!(answer.status, 202, "{}", answer.text());
    let id = answer.json()["id"].as_str().unwrap().to_string();
    assert_eq!(poll_until(&app, &id, is_final).await["status"], "succeeded");
    let result = get(&app, &format!("/jobs/{id}/result")).await.json();
    assert_eq!(result["mesh"]["particles"], 39);

    let answer = post_json(&app, "/jobs", &TINY.replace(r#""count": 3"#, r#""count": 39.5"#)).await;
    assert_eq!(answer.status, 422);
    let problem = answer.problem();
    assert_eq!(problem["errors"][0]["pointer"], "/bodies/0/count");
    assert_eq!(
        problem["errors"][0]["detail"],
        format!("invalid value: floating point `39.5`, expected a whole number from 0 to {}", usize::MAX)
    );
}

/// Reads from `stream` until the server closes it, within [`PATIENCE`]; returns what was read.
async fn read_until_closed(stream: &mut TcpStream) -> Vec<u8> {
    let mut received = Vec::new();
    let mut buffer = [0u8; 4096];
    let closed = tokio::time::timeout(PATIENCE, async {
        loop {
            match stream.read(&mut buffer).await {
                Ok(0) | Err(_) => return,
                Ok(n) => received.extend_from_slice(&buffer[..n]),
            }
        }
    })
    .await;
    assert!(closed.is_ok(), "the server kept the connection open; read {received:?}");
    received
}

fn address(server: &Server) -> String {
    server.base.strip_prefix("http://").unwrap().to_string()
}

async fn healthz_over(stream: &mut TcpStream) -> String {
    stream.write_all(b"GET /healthz HTTP/1.1\r\nHost: localhost\r\n\r\n").await.unwrap();
    let mut buffer = vec![0u8; 4096];
    let n = tokio::time::timeout(PATIENCE, stream.read(&mut buffer)).await.unwrap().unwrap();
    String::from_utf8_lossy(&buffer[..n]).into_owned()
}

/// 200 connections that send half a request line are closed after the header-read timeout,
/// while a silent connection opened with them is not (it has the idle timeout), and the server
/// answers throughout.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connections_that_never_finish_their_headers_are_closed() {
    let dir = tempfile::tempdir().unwrap();
    let server =
        Server::start(dir.path(), "memory", &["--header-read-timeout", "1", "--idle-timeout", "600"]);
    let addr = address(&server);
    let mut silent = TcpStream::connect(&addr).await.unwrap();
    let mut stalled = Vec::new();
    for _ in 0..200 {
        let mut stream = TcpStream::connect(&addr).await.unwrap();
        stream.write_all(b"GET /heal").await.unwrap();
        stalled.push(stream);
    }
    let started = Instant::now();
    let mut fresh = TcpStream::connect(&addr).await.unwrap();
    assert!(healthz_over(&mut fresh).await.starts_with("HTTP/1.1 200 OK"));
    let closings = stalled.iter_mut().map(|stream| async move { read_until_closed(stream).await });
    let received = futures_util::future::join_all(closings).await;
    assert!(received.iter().all(Vec::is_empty), "a stalled connection got an answer");
    let waited = started.elapsed();
    assert!(waited < PATIENCE, "{waited:?}");
    eprintln!("200 stalled connections closed {waited:?} after they were opened");

    // The silent connection is still open: a request on it is answered.
    assert!(healthz_over(&mut silent).await.starts_with("HTTP/1.1 200 OK"));
    let mut after = TcpStream::connect(&addr).await.unwrap();
    assert!(healthz_over(&mut after).await.starts_with("HTTP/1.1 200 OK"));
}

/// A connection with no request in flight, new or kept alive after a response, is closed after
/// the idle timeout; one whose response is still streaming (an event stream) is not.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_connections_are_closed_after_the_idle_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let server =
        Server::start(dir.path(), "memory", &["--idle-timeout", "1", "--header-read-timeout", "600"]);
    let addr = address(&server);
    let mut never_spoke = TcpStream::connect(&addr).await.unwrap();
    let mut kept_alive = TcpStream::connect(&addr).await.unwrap();
    let answer = healthz_over(&mut kept_alive).await;
    assert!(answer.starts_with("HTTP/1.1 200 OK"), "{answer}");
    assert!(!answer.to_ascii_lowercase().contains("connection: close"), "{answer}");

    // No pooled connections: one kept idle past the 1 s idle timeout is closed by the server, as
    // this test asserts, and a client that reused it for the DELETE below would meet a reset.
    let client = reqwest::Client::builder().pool_max_idle_per_host(0).build().unwrap();
    let id = serve::submit(&client, &server.base, LONG).await;
    let mut events = TcpStream::connect(&addr).await.unwrap();
    let request = format!("GET /jobs/{id}/events HTTP/1.1\r\nHost: localhost\r\n\r\n");
    events.write_all(request.as_bytes()).await.unwrap();

    assert_eq!(read_until_closed(&mut never_spoke).await, b"");
    assert_eq!(read_until_closed(&mut kept_alive).await, b"");
    // Both idle connections are closed; the event stream, open as long, still carries events.
    let mut buffer = vec![0u8; 4096];
    let mut streamed = String::new();
    let started = Instant::now();
    while !streamed.contains("event: progress") {
        assert!(started.elapsed() < PATIENCE, "no progress event within {PATIENCE:?}: {streamed}");
        let n = tokio::time::timeout(PATIENCE, events.read(&mut buffer)).await.unwrap().unwrap();
        assert!(n > 0, "the event stream was closed: {streamed}");
        streamed.push_str(&String::from_utf8_lossy(&buffer[..n]));
    }
    let cancelled = client.delete(format!("{}/jobs/{id}", server.base)).send().await.unwrap();
    assert_eq!(cancelled.status(), 202);
}

/// On SIGTERM the server stops once its connections are done; one that never finishes its
/// headers is closed by the header-read timeout, so it cannot hold the process open.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_connection_does_not_hold_shutdown_open() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &["--header-read-timeout", "1"]);
    let addr = address(&server);
    let mut stalled = TcpStream::connect(&addr).await.unwrap();
    stalled.write_all(b"POST /jobs HTTP/1.1\r\nHost: loc").await.unwrap();
    let mut fresh = TcpStream::connect(&addr).await.unwrap();
    assert!(healthz_over(&mut fresh).await.starts_with("HTTP/1.1 200 OK"));
    tokio::task::spawn_blocking(move || server.terminate()).await.unwrap();
    assert_eq!(read_until_closed(&mut stalled).await, b"");
}

/// Over a real socket, hyper lets the oversized heads through to the API's problem answers.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversized_heads_get_problem_bodies_over_a_socket() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    let client = reqwest::Client::new();
    let long = client.get(format!("{}/jobs?{}", server.base, "a".repeat(20_000))).send().await.unwrap();
    assert_eq!(long.status(), 414);
    assert_eq!(long.headers()["content-type"], "application/problem+json");
    assert_eq!(long.json::<serde_json::Value>().await.unwrap()["type"], "/problems/uri-too-long");
    let large = client
        .get(format!("{}/healthz", server.base))
        .header("x-large", "v".repeat(100_000))
        .send()
        .await
        .unwrap();
    assert_eq!(large.status(), 431);
    assert_eq!(large.headers()["content-type"], "application/problem+json");
    assert_eq!(large.json::<serde_json::Value>().await.unwrap()["type"], "/problems/header-fields-too-large");
    let mut many = client.get(format!("{}/healthz", server.base));
    for n in 0..150 {
        many = many.header(format!("x-field-{n}"), "1");
    }
    let many = many.send().await.unwrap();
    assert_eq!(many.status(), 431);
    assert_eq!(many.headers()["content-type"], "application/problem+json");
    let gzipped = client
        .post(format!("{}/jobs", server.base))
        .header("content-type", "application/json")
        .header("content-encoding", "gzip")
        .body(gzip(&vec![b' '; 10_000_000]))
        .send()
        .await
        .unwrap();
    assert_eq!(gzipped.status(), 413);
    assert_eq!(gzipped.json::<serde_json::Value>().await.unwrap()["type"], "/problems/body-too-large");
    assert_eq!(client.get(format!("{}/healthz", server.base)).send().await.unwrap().status(), 200);
}

const WARNING: &str = "without --auth-token";

/// Makes one request and waits for its log line, after which the start-up lines are all logged.
async fn log_after_one_request(server: &Server, token: Option<&str>) -> Vec<String> {
    let mut request = reqwest::Client::new().get(format!("{}/jobs", server.base));
    if let Some(token) = token {
        request = request.bearer_auth(token);
    }
    assert_eq!(request.send().await.unwrap().status(), 200);
    server.wait_for_log("finished processing request")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_beyond_loopback_without_a_token_warns_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let open = Server::start_on(dir.path(), "memory", "0.0.0.0:0", &[]);
    let log = log_after_one_request(&open, None).await;
    let warning = log.iter().find(|line| line.contains(WARNING)).expect("a warning");
    assert!(warning.contains("WARN"), "{warning}");
    assert!(warning.contains("addr=0.0.0.0:0"), "{warning}");

    let guarded = Server::start_on(dir.path(), "memory", "0.0.0.0:0", &["--auth-token", "t0ken"]);
    let log = log_after_one_request(&guarded, Some("t0ken")).await;
    assert!(!log.iter().any(|line| line.contains(WARNING)), "{}", log.join("\n"));

    let local = Server::start(dir.path(), "memory", &[]);
    let log = log_after_one_request(&local, None).await;
    assert!(!log.iter().any(|line| line.contains(WARNING)), "{}", log.join("\n"));
}
