//! `drape serve --memory-budget`: whatever the scenes, the server's peak resident memory
//! (`VmHWM` in `/proc/PID/status`) stays under the budget; what would not fit is refused before
//! it runs.

mod deadline;
mod serve;

use serde_json::{Value, json};
use serve::{Server, ended, wait_for};

/// The peak resident memory of a process, in bytes.
fn peak_rss(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse::<u64>().unwrap() * 1024
}

fn cloth(n: usize) -> Value {
    json!({"type": "cloth", "resolution": [n, n], "size": [1, 1]})
}

fn lattice(n: usize) -> Value {
    json!({"type": "lattice", "resolution": [n, n, n], "size": [1, 1, 1], "pin": [[0, 0, 0]]})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_server_stays_under_its_memory_budget_whatever_the_scenes() {
    const BUDGET: u64 = 1 << 30;
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path(), "sqlite://jobs.db", &["--memory-budget", "1G", "--workers", "2"]);
    let client = reqwest::Client::new();
    let post = |path: &'static str, scene: Value| {
        let client = client.clone();
        let url = format!("{}{path}", server.base);
        async move {
            let response = client.post(url).json(&scene).send().await.unwrap();
            (response.status().as_u16(), response.json::<Value>().await.unwrap())
        }
    };

    // Over a run's share ((1 GiB - 64 MiB) / 2 workers): refused at the field, before any work.
    let refused = [
        (
            json!({"duration": 0.01, "dt": 0.005, "error_estimate": "none", "self_collision": {"thickness": 10},
                "bodies": [cloth(300)], "output": {"frames": "final"}}),
            "/self_collision/thickness",
        ),
        (
            json!({"duration": 0.005, "dt": 0.005, "error_estimate": "none", "self_collision": {"thickness": 0.02},
                "bodies": [cloth(300)], "output": {"frames": "final"}}),
            "/self_collision/thickness",
        ),
        (
            json!({"duration": 0.2, "bodies": [cloth(100)], "output": {"fps": 1500, "fields": ["positions", "velocities"]}}),
            "/output/fps",
        ),
        // Implicit Euler's hierarchy of a lattice's spring graph: about 500 MiB here.
        (
            json!({"duration": 0.01, "dt": 0.005, "integrator": "implicit_euler", "error_estimate": "none",
                "bodies": [lattice(30)], "output": {"frames": "final"}}),
            "/bodies/0/resolution",
        ),
    ];
    for (scene, pointer) in refused {
        let (status, problem) = post("/jobs", scene).await;
        assert_eq!((status, problem["errors"][0]["pointer"].as_str()), (422, Some(pointer)), "{problem}");
    }

    // Heavy but admissible, two at a time: implicit Euler on 90,000 particles and on a lattice
    // of 13,824, self-collision with millions of pairs, hundreds of recorded frames.
    let admitted = [
        json!({"duration": 0.004, "dt": 0.002, "integrator": "implicit_euler", "error_estimate": "none",
               "bodies": [cloth(300)], "output": {"frames": "final"}}),
        json!({"duration": 3e-5, "error_estimate": "none", "self_collision": {"thickness": 0.012},
               "bodies": [cloth(300)], "output": {"frames": "final"}}),
        json!({"duration": 3e-5, "self_collision": {"thickness": 0.005}, "strain_limit": 0.1,
               "colliders": [{"type": "plane"}, {"type": "sphere", "center": [0, 0, 0], "radius": 0.3}],
               "wind": {"model": "aerodynamic", "velocity": [3, 0, 0], "coefficient": 1},
               "bodies": [cloth(300)], "output": {"frames": "final"}}),
        json!({"duration": 0.2, "bodies": [cloth(100)], "output": {"fps": 600}}),
        json!({"duration": 0.01, "dt": 0.005, "integrator": "implicit_euler", "error_estimate": "none",
               "bodies": [lattice(24)], "output": {"frames": "final"}}),
    ];
    let mut ids = Vec::new();
    for scene in admitted {
        let (status, job) = post("/jobs", scene).await;
        assert_eq!(status, 202, "{job}");
        ids.push(job["id"].as_str().unwrap().to_string());
    }
    for id in &ids {
        let job = wait_for(&client, &server.base, id, ended).await;
        assert!(matches!(job["status"].as_str(), Some("succeeded" | "diverged")), "{job}");
    }
    let peak = peak_rss(server.pid());
    assert!(peak < BUDGET, "peak resident memory {peak} bytes over the budget of {BUDGET}");
    eprintln!("peak resident memory: {} MiB of a {} MiB budget", peak >> 20, BUDGET >> 20);
    server.terminate();
}
