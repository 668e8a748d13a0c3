//! `drape run`, `drape submit` and `drape sweep` as clients of a real `drape serve`
//! (`--server URL`): the same bytes and tables as the local commands, one job for a retried
//! request, bearer tokens, and the exit codes a CI step reads (0 succeeded, 1 a run failed or
//! diverged or a threshold was crossed, 2 a bad scene, 3 no server or a refusal).

mod deadline;
mod serve;
mod terminal;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use serde_json::Value;
use serve::Server;
use terminal::drape_in_terminal;

/// A 10 × 10 cloth pinned at two corners for 0.3 s, recording positions and velocities.
const CLOTH: &str = r#"{"duration": 0.3, "dt": 0.0002,
    "bodies": [{"type": "cloth", "size": [1, 1], "resolution": [10, 10], "pin": [[0, 0], [9, 0]]}],
    "output": {"fps": 30, "fields": ["positions", "velocities"]}}"#;

/// A stiff, light chain at a step far beyond its stability bound: it diverges.
const DIVERGING: &str = r#"{"duration": 1, "dt": 0.05, "bodies": [{"type": "chain", "count": 3, "mass": 0.001,
    "pin": [0], "spring": {"k": 100000}}]}"#;

/// The single spring of the sweep tests, by two integrators at three steps, against an RK4
/// reference.
const SWEEP: &str = r#"{"scene": {"duration": 1.0, "gravity": [0, 0, 0], "error_estimate": "none",
    "bodies": [{"type": "chain", "start": [0, 0, 0], "end": [1.1, 0, 0], "count": 2, "mass": 2.0,
                "spring": {"k": 100, "rest_length": 1.0}, "pin": [0]}], "output": {"frames": "none"}},
  "vary": {"/integrator": ["symplectic_euler", "rk4"], "/dt": [0.004, 0.002, 0.001]},
  "reference": {"integrator": "rk4", "dt": 1e-5}}"#;

const TOKEN: &str = "ci-token-0123456789";

/// `drape ARGS` in `dir` with `input` on standard input, and neither `DRAPE_SERVER` nor
/// `DRAPE_TOKEN` from the environment of the tests.
fn drape(dir: &Path, args: &[&str], input: &str) -> Output {
    drape_with(dir, args, input, &[])
}

fn drape_with(dir: &Path, args: &[&str], input: &str, env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_drape"));
    command.current_dir(dir).args(args).env_remove("DRAPE_SERVER").env_remove("DRAPE_TOKEN");
    for (key, value) in env {
        command.env(key, value);
    }
    let mut child =
        command.stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    // A command refused before it reads its input (`drape submit` without a server) closes it.
    match child.stdin.take().unwrap().write_all(input.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => panic!("cannot write to drape: {e}"),
        _ => {}
    }
    child.wait_with_output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The jobs `GET /jobs` lists, sent `token` if given.
fn job_count(server: &Server, token: Option<&str>) -> usize {
    let mut request = ureq::get(format!("{}/jobs?limit=100", server.base));
    if let Some(token) = token {
        request = request.header("authorization", format!("Bearer {token}"));
    }
    let jobs: Value =
        serde_json::from_slice(&request.call().unwrap().into_body().read_to_vec().unwrap()).unwrap();
    jobs["jobs"].as_array().unwrap().len()
}

#[test]
fn a_run_on_a_server_writes_the_bytes_a_local_run_writes() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cloth.json"), CLOTH).unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    // npy of positions and velocities is NPZ; PC2 carries positions only and says so.
    for (format, file) in [("npy", "cloth.npz"), ("pc2", "cloth.pc2")] {
        let local = |name: &str| {
            let out = drape(dir.path(), &["run", "cloth.json", "--format", format, "-o", name], "");
            assert!(out.status.success(), "{}", stderr(&out));
            std::fs::read(dir.path().join(name)).unwrap()
        };
        let first = local(&format!("local-{file}"));
        assert_eq!(local(&format!("again-{file}")), first, "the local run of {format} is deterministic");
        let remote = drape(
            dir.path(),
            &[
                "run",
                "cloth.json",
                "--server",
                &server.base,
                "--format",
                format,
                "-o",
                &format!("remote-{file}"),
            ],
            "",
        );
        assert_eq!(remote.status.code(), Some(0), "{}", stderr(&remote));
        assert_eq!(std::fs::read(dir.path().join(format!("remote-{file}"))).unwrap(), first, "{format}");
        if format == "pc2" {
            assert!(stderr(&remote).contains("pc2 cannot carry velocities"), "{}", stderr(&remote));
        }
    }
    // `drape submit --wait` is `drape run --server`.
    let waited = drape(
        dir.path(),
        &["submit", "cloth.json", "--wait", "--server", &server.base, "--format", "npy", "-o", "waited.npz"],
        "",
    );
    assert_eq!(waited.status.code(), Some(0), "{}", stderr(&waited));
    assert_eq!(
        std::fs::read(dir.path().join("waited.npz")).unwrap(),
        std::fs::read(dir.path().join("local-cloth.npz")).unwrap()
    );
    // The JSON result on standard output is the local one but for the wall times.
    let strip = |out: &Output| {
        assert!(out.status.success(), "{}", stderr(out));
        let mut result: Value = serde_json::from_slice(&out.stdout).unwrap();
        result["stats"]["wall_time_s"] = Value::Null;
        result["stats"]["error"]["extra_wall_time_s"] = Value::Null;
        result
    };
    let local_json = strip(&drape(dir.path(), &["run", "-"], CLOTH));
    let remote_json = strip(&drape(dir.path(), &["run", "-", "--server", &server.base], CLOTH));
    assert_eq!(remote_json, local_json);
    assert_eq!(remote_json["frames"].as_array().unwrap().len(), 10);
}

#[test]
fn a_bad_scene_exits_2_with_each_field_the_server_names() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    let bad = r#"{"duration": 1, "dt": -1, "bodies": [{"type": "cloth", "resolution": [1, 8]}]}"#;
    let out = drape(dir.path(), &["run", "-", "--server", &server.base], bad);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
    let text = stderr(&out);
    assert!(text.contains("answered 422"), "{text}");
    assert!(text.contains("\n  /dt: must be positive, got -1\n"), "{text}");
    assert!(text.contains("\n  /bodies/0/resolution/0: must be at least 2, got 1\n"), "{text}");
    assert_eq!(job_count(&server, None), 0);
    // A sweep whose pointer leads nowhere, and a scene that is not JSON, are bad input too.
    let sweep = r#"{"scene": {"duration": 1, "bodies": [{"type": "chain", "count": 3}]}, "vary": {"/nowhere/x": [1]}}"#;
    let out = drape(dir.path(), &["sweep", "-", "--server", &server.base], sweep);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("  /vary/~1nowhere~1x: "), "{}", stderr(&out));
    let out = drape(dir.path(), &["submit", "-", "--server", &server.base], "{\"duration\": ");
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

#[test]
fn a_diverging_run_exits_1_and_still_writes_its_result() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    let out = drape(dir.path(), &["run", "-", "--server", &server.base], DIVERGING);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("diverged at step"), "{}", stderr(&out));
    let result: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(result["stats"]["status"], "diverged");
    assert!(result["stats"]["diverged"]["suggested_dt"].as_f64().unwrap() < 0.05);
}

#[test]
fn no_server_exits_3() {
    let dir = tempfile::tempdir().unwrap();
    // A port just freed: nothing listens on it.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let base = format!("http://127.0.0.1:{port}");
    for args in [vec!["run", "-"], vec!["submit", "-"], vec!["sweep", "-"]] {
        let scene = if args[0] == "sweep" { SWEEP } else { CLOTH };
        let out = drape(dir.path(), &[args, vec!["--server", &base]].concat(), scene);
        assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
        assert!(stderr(&out).contains(&format!("cannot reach {base}/")), "{}", stderr(&out));
    }
    // `drape submit` has nothing to do without a server.
    let out = drape(dir.path(), &["submit", "-"], CLOTH);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--server URL or DRAPE_SERVER"), "{}", stderr(&out));
}

#[test]
fn a_server_with_a_token_serves_only_its_token() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &["--auth-token", TOKEN]);
    let missing = drape(dir.path(), &["run", "-", "--server", &server.base], CLOTH);
    assert_eq!(missing.status.code(), Some(3), "{}", stderr(&missing));
    assert!(stderr(&missing).contains("answered 401 Unauthorized"), "{}", stderr(&missing));
    let wrong = drape(dir.path(), &["run", "-", "--server", &server.base, "--token", "not-the-token"], CLOTH);
    assert_eq!(wrong.status.code(), Some(3), "{}", stderr(&wrong));
    assert!(stderr(&wrong).contains("not one this server accepts"), "{}", stderr(&wrong));
    assert_eq!(job_count(&server, Some(TOKEN)), 0, "a refused client queues nothing");
    let right = drape(dir.path(), &["run", "-", "--server", &server.base, "--token", TOKEN], CLOTH);
    assert_eq!(right.status.code(), Some(0), "{}", stderr(&right));
    let result: Value = serde_json::from_slice(&right.stdout).unwrap();
    assert_eq!(result["stats"]["status"], "succeeded");
    // The variables do what the flags do.
    let from_env = drape_with(
        dir.path(),
        &["submit", "-"],
        CLOTH,
        &[("DRAPE_SERVER", &server.base), ("DRAPE_TOKEN", TOKEN)],
    );
    assert_eq!(from_env.status.code(), Some(0), "{}", stderr(&from_env));
}

#[test]
fn a_retried_submit_answers_with_the_job_it_queued() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    let submit = |extra: &[&str]| {
        let out = drape(dir.path(), &[&["submit", "-", "--server", &server.base], extra].concat(), CLOTH);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let job: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(job["links"]["self"], format!("/jobs/{}", job["id"].as_str().unwrap()));
        job["id"].as_str().unwrap().to_string()
    };
    let first = submit(&[]);
    assert_eq!(submit(&[]), first, "the same request is the same job");
    assert_eq!(job_count(&server, None), 1);
    // A run of the same request follows that job too.
    let out = drape(dir.path(), &["run", "-", "--server", &server.base], CLOTH);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    // A key of the caller's, or another format, is another request.
    let keyed = submit(&["--idempotency-key", "pipeline-7"]);
    assert_ne!(keyed, first);
    assert_eq!(submit(&["--idempotency-key", "pipeline-7"]), keyed);
    assert_ne!(submit(&["--format", "npy"]), first);
    assert_eq!(job_count(&server, None), 3, "the plain request, the keyed one, the npy one");
}

#[test]
fn a_retried_sweep_step_runs_one_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    let sweep = |key: &str| {
        let args = ["sweep", "-", "--csv", "--server", &server.base, "--idempotency-key", key];
        let out = drape(dir.path(), &args, SWEEP);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        out.stdout
    };
    let sweeps = || {
        let answer = ureq::get(format!("{}/sweeps", server.base)).call().unwrap();
        let listed: Value = serde_json::from_slice(&answer.into_body().read_to_vec().unwrap()).unwrap();
        listed["sweeps"].as_array().unwrap().len()
    };
    let first = sweep("pipeline-7");
    // The retry reads the sweep the first step made: the same table, wall times included.
    assert_eq!(sweep("pipeline-7"), first);
    assert_eq!(sweeps(), 1);
    assert_ne!(sweep("pipeline-8"), first, "another key is another sweep, with its own wall times");
    assert_eq!(sweeps(), 2);
}

/// The CSV of a sweep without its `wall_time_s` column, which no two runs share.
fn without_wall_times(csv: &[u8]) -> Vec<Vec<String>> {
    let mut reader = csv::Reader::from_reader(csv);
    let wall = reader.headers().unwrap().iter().position(|h| h == "wall_time_s").unwrap();
    let keep = |record: &csv::StringRecord| {
        record.iter().enumerate().filter(|(i, _)| *i != wall).map(|(_, s)| s.to_string()).collect::<Vec<_>>()
    };
    let mut rows = vec![keep(reader.headers().unwrap())];
    rows.extend(reader.records().map(|r| keep(&r.unwrap())));
    rows
}

#[test]
fn a_sweep_on_a_server_prints_the_local_table_and_keeps_the_gate() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    let local = drape(dir.path(), &["sweep", "-", "--csv"], SWEEP);
    assert!(local.status.success(), "{}", stderr(&local));
    let remote = drape(dir.path(), &["sweep", "-", "--csv", "--server", &server.base], SWEEP);
    assert_eq!(remote.status.code(), Some(0), "{}", stderr(&remote));
    let table = without_wall_times(&local.stdout);
    assert_eq!(table.len(), 7, "a header and six variants");
    assert_eq!(without_wall_times(&remote.stdout), table);
    // The JSON table: the same observed orders (RK4's 4 over the spring, symplectic Euler's 1).
    let remote_json = drape(dir.path(), &["sweep", "-", "--server", &server.base], SWEEP);
    let json: Value = serde_json::from_slice(&remote_json.stdout).unwrap();
    let orders: Vec<f64> =
        json["convergence"].as_array().unwrap().iter().map(|c| c["order"].as_f64().unwrap()).collect();
    assert!((orders[0] - 1.0).abs() < 0.15 && (orders[1] - 4.0).abs() < 0.15, "{orders:?}");
    // A bound between the worst RK4 error (about 1.1e-8 m) and the best symplectic Euler one
    // (about 2.7e-4 m) fails the three symplectic rows alone; RK4 keeps --min-order 3.5 too.
    let gated = drape(
        dir.path(),
        &["sweep", "-", "--server", &server.base, "--max-error", "1e-6", "--min-order", "3.5"],
        SWEEP,
    );
    assert_eq!(gated.status.code(), Some(1), "{}", stderr(&gated));
    let text = stderr(&gated);
    assert_eq!(text.matches("is above --max-error 1e-6").count(), 3, "{text}");
    assert_eq!(text.matches("/integrator = symplectic_euler").count(), 4, "{text}");
    assert!(text.contains("/integrator = symplectic_euler: order 1.0"), "{text}");
    assert!(!text.contains("/integrator = rk4"), "{text}");
    let kept = drape(dir.path(), &["sweep", "-", "--server", &server.base, "--max-error", "1e-2"], SWEEP);
    assert_eq!(kept.status.code(), Some(0), "{}", stderr(&kept));
    // --min-order without a reference cannot be applied: bad input, and nothing is sent.
    let no_reference =
        SWEEP.replace(r#""reference": {"integrator": "rk4", "dt": 1e-5}"#, r#""reference": null"#);
    let out = drape(dir.path(), &["sweep", "-", "--server", &server.base, "--min-order", "1"], &no_reference);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// The requests `GET /sweeps/{id}...` the server logged, each as what follows `/sweeps/`.
fn sweep_reads(server: &Server) -> Vec<String> {
    // Its log is in order: once this request's line is read, every earlier one is.
    ureq::get(format!("{}/sweeps?limit=1", server.base)).call().unwrap();
    let log = server.wait_for_log("uri=/sweeps?limit=1");
    let finished = log.iter().filter(|line| line.contains("finished processing request"));
    finished
        .filter_map(|line| line.split_once("method=GET uri=/sweeps/"))
        .map(|(_, rest)| rest.split_whitespace().next().unwrap_or_default().to_string())
        .collect()
}

#[test]
fn a_sweep_on_a_server_is_followed_through_its_events_with_progress_on_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "memory", &[]);
    // Three runs of up to 20,000 steps: long enough that the bar is drawn before the end.
    let chain = r#"{"duration": 2, "dt": 0.0001, "bodies": [{"type": "chain", "count": 50}], "output": {"frames": "final"}}"#;
    let sweep = dir.path().join("sweep.json");
    std::fs::write(&sweep, format!(r#"{{"scene": {chain}, "vary": {{"/dt": [0.0001, 0.0002, 0.0004]}}}}"#))
        .unwrap();
    let args = format!("sweep {} --csv --server {}", sweep.display(), server.base);
    let shown = drape_in_terminal(&args);
    assert!(shown.contains("/3 runs") && shown.contains(" left"), "{shown:?}");
    let rows = |shown: &str| shown.lines().filter(|l| l.contains(",succeeded,symplectic_euler,")).count();
    assert_eq!(rows(&shown), 3, "{shown:?}");
    // Quiet, or not a terminal: the table alone.
    let quiet = drape_in_terminal(&format!("{args} --quiet --idempotency-key quiet"));
    assert!(!quiet.contains("runs"), "{quiet:?}");
    assert_eq!(rows(&quiet), 3, "{quiet:?}");
    let piped = drape(dir.path(), &["sweep", "-", "--csv", "--server", &server.base], SWEEP);
    assert_eq!(piped.status.code(), Some(0), "{}", stderr(&piped));
    assert_eq!(stderr(&piped), "");

    // Each sweep was followed through one event stream, which carried its table: no sweep was
    // looked at otherwise.
    let reads = sweep_reads(&server);
    assert_eq!(reads.len(), 3, "{reads:?}");
    assert!(reads.iter().all(|target| target.ends_with("/events")), "{reads:?}");
}
