//! What every CLI test file needs: running the built binary, and the path of an example.
#![allow(dead_code)] // each test file uses its own part

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `skelform` binary built for these tests.
pub fn skelform(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skelform")).args(args).output().expect("run skelform")
}

/// The path of `examples/NAME` in the repository.
pub fn example(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples").join(name).display().to_string()
}
