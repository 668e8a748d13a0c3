//! Runs scenes and reads their JSON results, for the format tests.

use std::path::PathBuf;
use std::process::Command;

use drape::output::{Format, encode, write_json};
use drape::run::{Control, Recording, execute};
use drape::scene::Scene;
use serde_json::Value;

/// A run's recording and its JSON result, parsed.
pub struct Run {
    pub recording: Recording,
    pub json: Value,
}

impl Run {
    pub fn new(scene: &str) -> Self {
        let scene = Scene::from_json(scene.as_bytes()).expect("a valid scene");
        Self::of(execute(&scene.compile(), &Control::new()))
    }

    /// A recording made or changed by hand, with its JSON result.
    pub fn of(recording: Recording) -> Self {
        let mut bytes = Vec::new();
        write_json(&recording, &mut bytes).unwrap();
        Self { recording, json: serde_json::from_slice(&bytes).unwrap() }
    }

    pub fn encode(&self, format: Format) -> Vec<u8> {
        let mut bytes = Vec::new();
        encode(&self.recording, format, &mut bytes).unwrap();
        bytes
    }

    /// The frames the result holds: every frame, or only the final one.
    pub fn frames(&self) -> Vec<&Value> {
        match self.json.get("frames") {
            Some(frames) => frames.as_array().unwrap().iter().collect(),
            None => vec![&self.json["final"]],
        }
    }

    /// The last frame, which the mesh formats show.
    pub fn last(&self) -> &Value {
        self.frames().last().copied().unwrap()
    }

    pub fn precision(&self) -> &str {
        self.json["stats"]["precision"].as_str().unwrap()
    }

    /// Each body's name, particle offset and count.
    pub fn bodies(&self) -> Vec<(String, usize, usize)> {
        let bodies = self.json["mesh"]["bodies"].as_array().unwrap();
        bodies
            .iter()
            .map(|b| (b["name"].as_str().unwrap().to_string(), index(&b["offset"]), index(&b["count"])))
            .collect()
    }

    /// Triangles as global particle indices.
    pub fn triangles(&self) -> Vec<[usize; 3]> {
        let flat: Vec<usize> = self.json["mesh"]["triangles"].as_array().unwrap().iter().map(index).collect();
        flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
    }
}

fn index(v: &Value) -> usize {
    v.as_u64().unwrap() as usize
}

/// The numbers of a JSON array, as the `f64` they read as.
pub fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}

/// A scene with one body of each kind, small and short.
pub fn mixed_scene(precision: &str, frames: &str, fields: &[&str]) -> String {
    let fields = serde_json::to_string(fields).unwrap();
    format!(
        r#"{{"duration": 0.25, "precision": "{precision}", "bodies": [
            {{"type": "cloth", "name": "sheet", "resolution": [5, 4], "pin": [[0, 0], [4, 0]], "velocity": [0.3, 0, 0.1]}},
            {{"type": "chain", "name": "rope", "count": 4, "pin": [0]}},
            {{"type": "lattice", "name": "jelly", "resolution": [3, 3, 3], "velocity": [0, 1, 0]}},
            {{"type": "mesh", "name": "flag", "vertices": [0,2,0, 1,2,0, 0,2,1, 1,2.2,1],
              "triangles": [0,2,1, 1,2,3], "pin": [0]}}],
           "output": {{"fps": 20, "frames": "{frames}", "fields": {fields}}}}}"#
    )
}

/// Checks that an external reader can be run, and fails the test saying how to install it if
/// not. The tests that call this are `#[ignore]`d with the same reason, so they run only when
/// asked for (`--include-ignored`), and then a missing reader is a failure, never a pass.
pub fn require_reader(what: &str, program: &str, args: &[&str], install: &str) {
    let ok = Command::new(program).args(args).output().is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "this test needs {what}, and `{program} {}` failed; install it with {install}",
        args.join(" ")
    );
}

/// How to install NumPy, which the NPY and NPZ tests read back with.
pub const INSTALL_NUMPY: &str = "`python3 -m pip install numpy`";

/// How to install node's readers (the Khronos glTF-Validator and three.js, pinned in
/// `.ci/node/package-lock.json`).
pub const INSTALL_NODE_READERS: &str = "node, then `npm ci --prefix .ci/node`";

/// Fails the test if NumPy cannot be imported.
pub fn require_numpy() {
    require_reader("NumPy", "python3", &["-c", "import numpy"], INSTALL_NUMPY);
}

/// Fails the test if node cannot be run.
pub fn require_node() {
    require_reader("node", "node", &["--version"], INSTALL_NODE_READERS);
}

/// A fresh directory for one test's files.
pub fn scratch_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("drape-formats-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The repository root, where the test support scripts live.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
