//! `skelform mesh` on region scenes (`--method nonmanifold`).

use std::path::Path;
use std::process::{Command, Output};

fn skelform(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skelform")).args(args).output().expect("run skelform")
}

fn example(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples").join(name).display().to_string()
}

#[test]
fn region_scenes_give_labelled_surfaces_and_curves() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.ply");
    let r = skelform(&[
        "mesh",
        &example("nonmanifold/sphere-and-square.toml"),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(j["method"], "nonmanifold");
    let pairs: Vec<serde_json::Value> =
        j["surfaces"].as_array().unwrap().iter().map(|s| s["pair"].clone()).collect();
    assert_eq!(
        pairs,
        vec![serde_json::json!([1, 3]), serde_json::json!([1, 4]), serde_json::json!([3, 4])]
    );
    let circle = j["curves"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["regions"] == serde_json::json!([1, 3, 4]))
        .unwrap();
    let len = circle["length"].as_f64().unwrap();
    assert!((len - std::f64::consts::PI).abs() < 0.1 * std::f64::consts::PI, "circle length {len}");
    // The labels and curves are in the file.
    let c = skelform(&["check", out.to_str().unwrap(), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
    assert_eq!(report["labels"].as_array().unwrap().len(), 3);
    assert!(report["curves"].as_u64().unwrap() > 20);
}

#[test]
fn region_scene_mistakes_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.ply");
    let o = out.to_str().unwrap();
    let head = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n";
    let scene = |name: &str, text: String| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    };
    let p = scene(
        "missing.toml",
        format!(
            "{head}[regions]\ndefault = 0\ninterest = [[0, 7]]\n[[regions.region]]\nid = 1\nformula = \"x\"\n"
        ),
    );
    let r = skelform(&["mesh", &p, "-o", o, "--method", "nonmanifold"]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("missing.toml:6:") && err.contains("region 7"), "{err}");
    let p = scene(
        "bad.toml",
        format!("{head}[regions]\ndefault = 0\n[[regions.region]]\nid = 1\nformula = \"x +\"\n"),
    );
    let r = skelform(&["mesh", &p, "-o", o, "--method", "nonmanifold"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("bad.toml:8:"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let p = scene(
        "grid.toml",
        format!("{head}[regions]\ndefault = 0\n[[regions.region]]\nid = 1\nformula = \"x\"\n"),
    );
    let r = skelform(&["mesh", &p, "-o", o]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("nonmanifold"));
    assert!(!out.exists());
}
