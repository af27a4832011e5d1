//! What every CLI test file needs: running the built binary, its checker's report, and the
//! path of an example.
#![allow(dead_code)] // each test file uses its own part

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `skelform` binary built for these tests.
pub fn skelform(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skelform")).args(args).output().expect("run skelform")
}

/// `skelform check MESH --json`, which must succeed, as JSON.
pub fn check_json(mesh: &Path) -> serde_json::Value {
    let o = skelform(&["check", mesh.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("check --json prints JSON")
}

/// The path of `examples/NAME` in the repository.
pub fn example(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples").join(name).display().to_string()
}
