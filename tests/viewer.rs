//! The viewer: its page and files served as they are in the repository (with their media types
//! and cache validators, open without a token), the examples it offers, and the page itself
//! driven in Chromium by playwright-core (`tests/support/viewer_browser.mjs`).

mod common;
mod deadline;
mod serve;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::{ApiConfig, AuthToken, EXAMPLES, viewer_files};
use serde_json::Value;
use serve::Server;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where a served file lives in the repository.
fn source(file: &str) -> PathBuf {
    let dir = repo().join("src/api/viewer");
    if dir.join(file).exists() { dir.join(file) } else { dir.join("vendor").join(file) }
}

fn media_type(file: &str) -> &'static str {
    match Path::new(file).extension().and_then(|e| e.to_str()) {
        Some("js") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("txt") => "text/plain; charset=utf-8",
        other => panic!("no media type for {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_and_every_file_are_served_as_in_the_repository() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let page = get(&app, "/").await;
    assert_eq!(page.status, 200);
    assert_eq!(page.headers["content-type"], "text/html; charset=utf-8");
    assert_eq!(page.body, std::fs::read(repo().join("src/api/viewer/index.html")).unwrap());
    for file in viewer_files() {
        let answer = get(&app, &format!("/viewer/{file}")).await;
        assert_eq!(answer.status, 200, "{file}");
        assert_eq!(answer.headers["content-type"], media_type(file), "{file}");
        assert_eq!(answer.headers["x-content-type-options"], "nosniff", "{file}");
        assert_eq!(answer.body, std::fs::read(source(file)).unwrap(), "{file}");
    }
    let missing = get(&app, "/viewer/nothing.js").await;
    assert_eq!(missing.status, 404);
    assert_eq!(missing.problem()["type"], "/problems/not-found");
}

/// Every file the page and its modules name is served, and every served file is named by one:
/// nothing is missing and nothing is dead weight.
#[test]
fn the_files_served_are_those_the_page_names() {
    let dir = repo().join("src/api/viewer");
    let mut named = BTreeSet::new();
    let mut texts = vec![std::fs::read_to_string(dir.join("index.html")).unwrap()];
    texts.extend(
        viewer_files().filter(|f| f.ends_with(".js")).map(|f| std::fs::read_to_string(source(f)).unwrap()),
    );
    for text in &texts {
        for quote in ["\"/viewer/", "\"./", "from './"] {
            for piece in text.split(quote).skip(1) {
                let name: String =
                    piece.chars().take_while(|c| c.is_alphanumeric() || "._-".contains(*c)).collect();
                if name.contains('.') {
                    named.insert(name);
                }
            }
        }
    }
    let served: BTreeSet<String> = viewer_files().map(str::to_string).collect();
    assert_eq!(named, served);
}

/// The vendored three.js is the version `.ci/node` pins, byte for byte.
#[test]
#[ignore = "needs node and .ci/node (npm ci --prefix .ci/node)"]
fn the_vendored_three_js_is_the_pinned_one() {
    let three = repo().join(".ci/node/node_modules/three");
    assert!(three.exists(), "install .ci/node: npm ci --prefix .ci/node");
    for (vendored, pinned) in [
        ("three.module.js", "build/three.module.js"),
        ("three.core.js", "build/three.core.js"),
        ("OrbitControls.js", "examples/jsm/controls/OrbitControls.js"),
        ("three-LICENSE.txt", "LICENSE"),
    ] {
        assert!(
            std::fs::read(source(vendored)).unwrap() == std::fs::read(three.join(pinned)).unwrap(),
            "{vendored}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_copy_whose_etag_matches_is_not_sent_again() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    for path in ["/", "/viewer/main.js", "/viewer/three.core.js"] {
        let first = get(&app, path).await;
        assert_eq!(first.headers["cache-control"], "no-cache", "{path}");
        let etag = first.headers["etag"].to_str().unwrap().to_string();
        assert!(etag.starts_with('"') && etag.ends_with('"'), "{etag}");
        let again =
            |tag: String| Request::get(path).header("if-none-match", tag).body(Body::empty()).unwrap();
        let fresh = send(&app, again(etag.clone())).await;
        assert_eq!(fresh.status, 304, "{path}");
        assert!(fresh.body.is_empty());
        assert_eq!(fresh.headers["etag"], etag.as_str());
        let listed = send(&app, again(format!("\"0\", {etag}"))).await;
        assert_eq!(listed.status, 304, "{path}");
        let stale = send(&app, again("\"0\"".into())).await;
        assert_eq!(stale.status, 200, "{path}");
    }
    let page = get(&app, "/").await.headers["etag"].clone();
    assert_ne!(page, get(&app, "/viewer/main.js").await.headers["etag"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_is_open_without_a_token_and_the_api_it_calls_is_not() {
    let config = ApiConfig { auth_tokens: vec![AuthToken::parse("s3cret").unwrap()], ..ApiConfig::default() };
    let (_, app) = test_app(jobs_config(), config);
    assert_eq!(get(&app, "/").await.status, 200);
    assert_eq!(get(&app, "/viewer/api.js").await.status, 200);
    assert_eq!(get(&app, "/examples").await.status, 401);
    let with_token =
        Request::get("/examples").header("authorization", "Bearer s3cret").body(Body::empty()).unwrap();
    assert_eq!(send(&app, with_token).await.status, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn examples_are_the_repository_scenes() {
    let (_, app) = test_app(jobs_config(), ApiConfig::default());
    let answer = get(&app, "/examples").await;
    assert_eq!(answer.status, 200);
    let listed = answer.json()["examples"].as_array().unwrap().clone();
    let on_disk: BTreeSet<String> = std::fs::read_dir(repo().join("examples"))
        .unwrap()
        .filter_map(|e| e.unwrap().file_name().into_string().ok())
        .filter_map(|name| name.strip_suffix(".json").map(str::to_string))
        .collect();
    let names: BTreeSet<String> = listed.iter().map(|e| e["name"].as_str().unwrap().to_string()).collect();
    assert_eq!(names, on_disk);
    for example in &listed {
        let name = example["name"].as_str().unwrap();
        let file: Value =
            serde_json::from_slice(&std::fs::read(repo().join(format!("examples/{name}.json"))).unwrap())
                .unwrap();
        assert_eq!(example["scene"], file, "{name}");
    }
    assert_eq!(EXAMPLES.len(), listed.len());
}

/// Fails the test saying what to install when a browser test's tool is missing.
fn require(program: &str, args: &[&str], install: &str) {
    let ok = Command::new(program).args(args).output().is_ok_and(|o| o.status.success());
    assert!(ok, "this test needs `{program}`; install it with {install}");
}

/// One line of the browser driver's report.
fn report_lines(stdout: &str) -> Vec<Value> {
    stdout.lines().filter(|l| l.starts_with('{')).map(|l| serde_json::from_str(l).unwrap()).collect()
}

/// Each example through the page in Chromium: picked, run as a job, played to its final frame
/// and held there; the screenshot of that frame shows the cloth's colour where the empty view
/// (the control) shows none, and moving the scrubber to the first frame changes the picture.
/// Then every shading draws the cloth, a refused scene's problems are listed at their pointers,
/// and a sweep pasted in the editor shows its table and plot.
/// Screenshots are kept in `target/viewer-screenshots/`.
#[test]
#[ignore = "needs node, .ci/node (npm ci --prefix .ci/node) and Chromium (apt-get install chromium)"]
fn every_example_plays_through_the_page_in_chromium() {
    require("node", &["--version"], "node, then `npm ci --prefix .ci/node`");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    require(&chromium, &["--version"], "`apt-get install -y chromium`");
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &["--workers", "2"]);
    let shots = repo().join("target/viewer-screenshots");
    let _ = std::fs::remove_dir_all(&shots);
    let names: Vec<&str> = EXAMPLES.iter().map(|(name, _)| *name).collect();
    let output = Command::new("node")
        .arg(repo().join("tests/support/viewer_browser.mjs"))
        .arg(&server.base)
        .arg(&shots)
        .args(&names)
        .env("CHROMIUM", &chromium)
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    println!("{stdout}{stderr}");
    match output.status.code() {
        Some(0) => {}
        Some(2) => panic!("playwright-core or Chromium cannot be started:\n{stderr}"),
        _ => panic!("the page met problems:\n{stdout}{stderr}"),
    }
    let lines = report_lines(&stdout);
    let control = lines.iter().find(|l| l["control"] == true).expect("a control screenshot");
    assert_eq!(control["clothPixels"], 0, "the empty view shows no cloth colour");
    assert_eq!(control["title"], "drape viewer");
    let results: Vec<&Value> = lines.iter().filter(|l| l.get("example").is_some()).collect();
    assert_eq!(results.len(), names.len(), "{stdout}");
    for line in results {
        let name = line["example"].as_str().unwrap();
        assert!(line["status"].as_str().unwrap().contains("succeeded"), "{line}");
        let frames = line["frames"].as_u64().unwrap();
        assert!(frames > 1, "{line}");
        // A chain is a line and its particles (the pellets a chain of two), the cantilever a strip
        // 3 mm wide seen from its side; a sheet covers far more of the view.
        let least = match name {
            "chain" | "single_spring" | "fast_particle_sheet" => 20,
            "cantilever" => 200,
            _ => 2000,
        };
        assert!(
            line["clothPixels"].as_u64().unwrap() >= least,
            "{name}: the final frame shows no cloth: {line}"
        );
        assert!(
            line["scrubbedPixelsChanged"].as_u64().unwrap() > 0,
            "{name}: the scrubber moved nothing: {line}"
        );
        assert_eq!(line["timeShownAfterScrub"], "0.000 s", "{line}");
        assert!(shots.join(format!("{name}-final.png")).exists());
    }
    let shadings: Vec<&Value> = lines.iter().filter(|l| l.get("shading").is_some()).collect();
    assert_eq!(shadings.len(), 5, "{stdout}");
    for line in shadings {
        assert!(line["colouredPixels"].as_u64().unwrap() >= 2000, "{line}");
    }
    // The server's problems, each at its pointer, as the page lists them.
    let refused = lines.iter().find(|l| l.get("refused").is_some()).expect("a refused scene");
    let errors: Vec<&str> =
        refused["errors"].as_array().unwrap().iter().map(|e| e.as_str().unwrap()).collect();
    assert!(errors.iter().any(|e| e.starts_with("/duration: ")), "{errors:?}");
    assert!(errors.iter().any(|e| e.starts_with("/bodies/0/mass: ")), "{errors:?}");
    // examples/sweeps/tiny.json: 2 integrators × 2 steps, its rows and its plot.
    let sweep = &lines.iter().find(|l| l.get("sweep").is_some()).expect("a sweep")["sweep"];
    assert_eq!(sweep["rows"], 4, "{sweep}");
    assert!(sweep["heading"].as_str().unwrap().starts_with("5 of 5 runs ended"), "{sweep}");
    assert!(sweep["columns"].as_array().unwrap().iter().any(|c| c == "integrator"), "{sweep}");
    assert!(sweep["plotWidth"].as_u64().unwrap() > 0, "{sweep}");
}
