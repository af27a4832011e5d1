//! `skelform mesh` on `[leaf]` scenes (chapter 7 with the non-manifold polygonizer).

mod common;
use common::{example, skelform};

#[test]
fn the_leaf_meshes_into_blade_and_vein_surfaces() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("leaf.ply");
    let r = skelform(&[
        "mesh",
        &example("nonmanifold/leaf.toml"),
        "-o",
        out.to_str().unwrap(),
        "--cell",
        "0.05",
        "--json",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(j["method"], "nonmanifold");
    // The blade's web: about the dissertation's 475 triangles (fig. 7.8); the texture's
    // areoles are the refined polygons, one more per tertiary line than the web had.
    let leaf = &j["leaf"];
    let triangles = leaf["triangles"].as_u64().unwrap();
    assert!((450..=500).contains(&triangles), "{leaf}");
    assert_eq!(leaf["areoles"], leaf["polygons"], "{leaf}");
    assert_eq!(
        leaf["areoles"].as_u64().unwrap(),
        leaf["web_polygons"].as_u64().unwrap() + leaf["tertiary_lines"].as_u64().unwrap()
    );
    let pairs: Vec<serde_json::Value> =
        j["surfaces"].as_array().unwrap().iter().map(|s| s["pair"].clone()).collect();
    let want: Vec<serde_json::Value> =
        [[0, 1], [1, 2], [1, 3], [2, 3]].iter().map(|p| serde_json::json!(p)).collect();
    assert_eq!(pairs, want);
    let curves: Vec<serde_json::Value> =
        j["curves"].as_array().unwrap().iter().map(|c| c["regions"].clone()).collect();
    assert!(curves.contains(&serde_json::json!([0, 2, 3])), "the margin: {curves:?}");
    assert!(curves.contains(&serde_json::json!([1, 2, 3])), "the fillet edges: {curves:?}");
    let c = skelform(&["check", out.to_str().unwrap(), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
    assert_eq!(report["labels"].as_array().unwrap().len(), 4);
}

#[test]
fn a_bad_leaf_is_reported_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    std::fs::write(&p, "[domain]\nmin = [-2, -2, -2]\nmax = [2, 2, 2]\n[leaf]\nlobe_depth = 2\n")
        .unwrap();
    let out = dir.path().join("o.ply");
    let r = skelform(&["mesh", p.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("bad.toml:5:14") && err.contains("lobe_depth"), "{err}");
    // A leaf is regions: only the non-manifold method meshes it.
    std::fs::write(&p, "[domain]\nmin = [-2, -2, -2]\nmax = [2, 2, 2]\n[leaf]\n").unwrap();
    let r =
        skelform(&["mesh", p.to_str().unwrap(), "-o", out.to_str().unwrap(), "--method", "grid"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("nonmanifold"));
    assert!(!out.exists());
}
