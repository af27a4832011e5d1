//! `skelform mesh --method continuation|tetra` as a user runs it.

use std::path::Path;

mod common;
use common::{check_json as check, example, skelform};

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn chapter_three_scenes_mesh_as_the_chapter_describes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.ply");
    let o = out.to_str().unwrap();
    for (scene, genus) in [
        ("continuation/sphere-cell-0.4.toml", 0),
        ("continuation/sphere-cell-0.1.toml", 0),
        ("continuation/torus.toml", 1),
        ("continuation/jacks.toml", 0),
    ] {
        let r = skelform(&["mesh", &example(scene), "-o", o, "--stats"]);
        assert!(r.status.success(), "{scene}: {}", text(&r.stderr));
        assert!(
            text(&r.stdout).contains("stopped by    nothing (closed)"),
            "{scene}: {}",
            text(&r.stdout)
        );
        let c = check(&out);
        assert_eq!(c["boundary_edges"], 0, "{scene}");
        assert_eq!(c["non_manifold_edges"], 0, "{scene}");
        assert_eq!(c["outward"], true, "{scene}");
        assert_eq!(c["components"][0]["genus"], genus, "{scene}");
    }
    // The unbounded surface stops at the propagation limit, says so, and is open there.
    let r = skelform(&["mesh", &example("continuation/two-tori.toml"), "-o", o]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(
        text(&r.stderr).contains("warning: propagation reached its limit"),
        "{}",
        text(&r.stderr)
    );
    let c = check(&out);
    assert!(c["boundary_edges"].as_u64().unwrap() > 0);
    assert_eq!(c["non_manifold_edges"], 0);
}

#[test]
fn methods_agree_and_tetra_makes_more_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let mut tris = Vec::new();
    for m in ["grid", "continuation", "tetra"] {
        let out = dir.path().join(format!("{m}.ply"));
        let r = skelform(&[
            "mesh",
            &example("torus.toml"),
            "-o",
            out.to_str().unwrap(),
            "--method",
            m,
            "--cell",
            "0.04",
            "--seed",
            "0.6,0,0",
            "--json",
        ]);
        assert!(r.status.success(), "{m}: {}", text(&r.stderr));
        let j: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
        assert_eq!(j["method"], m);
        assert_eq!(check(&out)["components"][0]["genus"], 1, "{m}");
        tris.push(j["triangles"].as_u64().unwrap());
    }
    assert_eq!(tris[0], tris[1], "continuation with cubes makes the grid's mesh");
    assert!(tris[2] > tris[1]);
}

#[test]
fn seed_problems_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.ply");
    let o = out.to_str().unwrap();
    let sphere = example("sphere.toml");
    let r = skelform(&["mesh", &sphere, "-o", o, "--method", "continuation", "--seed", "5,0,0"]);
    assert_eq!(r.status.code(), Some(2), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("outside the domain"), "{}", text(&r.stderr));
    let r = skelform(&["mesh", &sphere, "-o", o, "--method", "continuation", "--seed", "0,0"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(text(&r.stderr).contains("not a point"), "{}", text(&r.stderr));
    let r = skelform(&["mesh", &sphere, "-o", o, "--method", "continuation", "--root", "newton"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        text(&r.stderr).contains(
            "invalid value 'newton' for '--root <ROOT>' [possible values: regula-falsi, bisection, hermite]"
        ),
        "{}",
        text(&r.stderr)
    );
    // A cell budget cuts the mesh short and says so.
    let r = skelform(&[
        "mesh",
        &sphere,
        "-o",
        o,
        "--method",
        "continuation",
        "--seed",
        "0,0,0",
        "--max-cells",
        "50",
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("ran out of cells"), "{}", text(&r.stderr));
    assert!(!text(&r.stderr).contains("panicked"));
}

/// Issue 18, defect 2: a wall thinner than a cell's diagonal is cut through by the six
/// tetrahedra's long diagonals; tetra must say so, and must stay quiet where it agrees.
#[test]
fn tetra_warns_where_its_topology_differs_from_the_cubes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |name: &str, formula: &str, cell: f64| {
        let path = dir.path().join(name);
        std::fs::write(
            &path,
            format!(
                "[domain]\nmin = [-0.6, -0.6, -0.6]\nmax = [0.6, 0.6, 0.6]\n[mesh]\ncell = {cell}\n[field]\nformula = \"{formula}\"\n"
            ),
        )
        .unwrap();
        path
    };
    let run = |scene: &Path| {
        let out = dir.path().join("out.ply");
        let o = skelform(&[
            "mesh",
            scene.to_str().unwrap(),
            "--method",
            "tetra",
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        (j, text(&o.stderr))
    };
    let shell = scene("shell.toml", "abs(sqrt(x^2+y^2+z^2)-0.5)-0.01", 0.015);
    let (j, err) = run(&shell);
    assert!(j["tetra_disagreements"].as_u64().unwrap() > 0, "{j}");
    assert!(err.contains("warning:") && err.contains("cube method"), "{err}");
    let sphere = scene("sphere.toml", "sqrt(x^2+y^2+z^2)-0.5", 0.05);
    let (j, err) = run(&sphere);
    assert_eq!(j["tetra_disagreements"], 0, "{j}");
    assert!(!err.contains("warning:"), "{err}");
}
