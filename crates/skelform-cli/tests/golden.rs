//! Behaviour pinned across refactors: every example scene, meshed at a small resolution with
//! its own method (and the field examples with every other method that applies), must give
//! the same PLY bytes as when the table in `tests/data/golden.txt` was recorded.
//!
//! Rerecord (only when a change of output is intended, and say why in the commit) with
//! `SKELFORM_BLESS=1 cargo test -p skelform-cli --test golden`.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use common::skelform;

/// 64-bit FNV-1a: a stable digest of the written file (not for security, for equality).
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

fn scenes(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> =
        std::fs::read_dir(dir).expect("read examples").map(|e| e.expect("entry").path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            scenes(&p, out);
        } else if p.extension().is_some_and(|e| e == "toml") {
            out.push(p);
        }
    }
}

/// (name in the table, arguments after `mesh SCENE -o OUT`).
fn cases() -> Vec<(String, PathBuf, Vec<&'static str>)> {
    let root = examples();
    let mut all = Vec::new();
    scenes(&root, &mut all);
    let mut cases = Vec::new();
    for scene in all {
        let rel = scene.strip_prefix(&root).expect("under examples").display().to_string();
        cases.push((rel.clone(), scene.clone(), vec![]));
        let plain_field = !rel.contains('/');
        if plain_field {
            for m in ["continuation", "tetra", "healed"] {
                cases.push((format!("{rel} --method {m}"), scene.clone(), vec!["--method", m]));
            }
        }
    }
    let hand = root.join("skeleton/hand.toml");
    cases.push(("skeleton/hand.toml --pose grip".into(), hand.clone(), vec!["--pose", "grip"]));
    cases.push((
        "skeleton/hand.toml --pose open --method continuation".into(),
        hand,
        vec!["--pose", "open", "--method", "continuation"],
    ));
    cases
}

fn table_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/golden.txt")
}

#[test]
fn every_example_meshes_as_recorded() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut got = BTreeMap::new();
    for (i, (name, scene, extra)) in cases().into_iter().enumerate() {
        let out = dir.path().join(format!("{i}.ply"));
        let mut args = vec!["mesh", scene.to_str().expect("utf-8 path"), "-o"];
        let out_s = out.display().to_string();
        args.push(&out_s);
        args.extend(["--resolution", "24", "--threads", "2", "-q"]);
        args.extend(extra);
        let o = skelform(&args);
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let bytes = std::fs::read(&out).expect("read mesh");
        got.insert(name, format!("{:016x}", fnv1a(&bytes)));
    }
    let text: String = got.iter().map(|(k, v)| format!("{v}  {k}\n")).collect();
    if std::env::var_os("SKELFORM_BLESS").is_some() {
        std::fs::create_dir_all(table_path().parent().expect("parent")).expect("mkdir");
        std::fs::write(table_path(), &text).expect("write table");
        return;
    }
    let want = std::fs::read_to_string(table_path()).expect("tests/data/golden.txt");
    let want: BTreeMap<String, String> = want
        .lines()
        .filter_map(|l| l.split_once("  ").map(|(h, n)| (n.to_string(), h.to_string())))
        .collect();
    let mut diffs = Vec::new();
    for (name, hash) in &got {
        match want.get(name) {
            Some(w) if w == hash => {}
            Some(w) => diffs.push(format!("{name}: {hash}, recorded {w}")),
            None => diffs.push(format!("{name}: not in the table")),
        }
    }
    for name in want.keys().filter(|n| !got.contains_key(*n)) {
        diffs.push(format!("{name}: recorded but no longer run"));
    }
    assert!(diffs.is_empty(), "meshes changed:\n{}", diffs.join("\n"));
}
