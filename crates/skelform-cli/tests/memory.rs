//! `--max-memory` on every method: a run whose account reaches the limit as it goes stops
//! with one line and exit code 1 (a failure of the run); what the lattice alone shows cannot
//! fit is refused before any work with exit code 2 (bad input). Neither leaves an output.

mod common;

use std::path::Path;

use common::{example, skelform};

fn fails(args: &[&str], code: i32, needles: &[&str], out: &Path) {
    let o = skelform(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
    for needle in needles {
        assert!(err.contains(needle), "{args:?}: expected '{needle}' in: {err}");
    }
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "{args:?} left {}", out.display());
}

#[test]
fn nonmanifold_at_the_limit_stops_with_one_line_and_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("X.ply");
    let o = out.to_str().unwrap();
    let scene = example("nonmanifold/saucer-and-square.toml");
    let args = ["mesh", &scene, "-o", o, "--max-memory", "1M"];
    fails(
        &args,
        1,
        &["saucer-and-square.toml", "nonmanifold run reached the memory limit", "--max-memory"],
        &out,
    );
}

#[test]
fn continuation_and_tetra_at_the_limit_stop_with_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("X.ply");
    let o = out.to_str().unwrap();
    let scene = example("sphere.toml");
    for method in ["continuation", "tetra"] {
        let args = [
            "mesh",
            &scene,
            "-o",
            o,
            "--method",
            method,
            "--resolution",
            "200",
            "--seed",
            "0.8,0,0",
            "--max-memory",
            "1M",
        ];
        fails(&args, 1, &[&format!("{method} run reached the memory limit")], &out);
    }
}

#[test]
fn a_search_the_lattice_cannot_hold_is_refused_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("X.ply");
    let o = out.to_str().unwrap();
    // The gyroid has no seeds: its domain search at 20000 samples would need terabytes.
    let scene = example("gyroid.toml");
    let args = ["mesh", &scene, "-o", o, "--method", "tetra", "--resolution", "20000"];
    fails(&args, 2, &["GiB", "raise the limit"], &out);
}

#[test]
fn under_the_limit_the_run_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("X.ply");
    let o = out.to_str().unwrap();
    let scene = example("nonmanifold/saucer-and-square.toml");
    let r = skelform(&["mesh", &scene, "-o", o, "--max-memory", "256M", "--quiet"]);
    assert_eq!(r.status.code(), Some(0), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists());
}
