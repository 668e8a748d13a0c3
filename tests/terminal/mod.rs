//! `drape` in a pseudo-terminal (util-linux `script`), as a person at a terminal runs it, for
//! the tests of what it shows there (the progress bars), with none of the `DRAPE_*` variables
//! of the tests' environment that would change what it does.

use std::process::{Command, Stdio};

/// What the terminal received from `drape ARGS` (the arguments as one shell command line),
/// which must exit 0.
pub fn drape_in_terminal(args: &str) -> String {
    let command = format!("{} {args}", env!("CARGO_BIN_EXE_drape"));
    let out = Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .env_remove("DRAPE_MEMORY_BUDGET")
        .env_remove("DRAPE_MAX_STEPS")
        .env_remove("DRAPE_SERVER")
        .env_remove("DRAPE_TOKEN")
        .stdin(Stdio::null())
        .output()
        .expect("util-linux `script` runs a command in a pseudo-terminal");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stdout));
    String::from_utf8_lossy(&out.stdout).into_owned()
}
