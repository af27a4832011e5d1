//! What `skelform mesh` writes for other programs: the PLY layout (curves beside the mesh
//! by default, `--ply-curves inline|none`), `--no-curves`, the OBJ material library, and
//! the same components from every format `check` reads back.

mod common;

use common::{example, skelform};

fn check(path: &std::path::Path) -> serde_json::Value {
    let c = skelform(&["check", path.to_str().unwrap(), "--json"]);
    assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    serde_json::from_slice(&c.stdout).unwrap()
}

fn header(path: &std::path::Path) -> String {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes.windows(10).position(|w| w == b"end_header").unwrap();
    String::from_utf8(bytes[..end].to_vec()).unwrap()
}

#[test]
fn the_saucer_has_the_same_components_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("nonmanifold/saucer-and-square.toml");
    let mut reports: Vec<(&str, serde_json::Value)> = Vec::new();
    for ext in ["ply", "obj", "glb"] {
        let out = dir.path().join(format!("saucer.{ext}"));
        let r = skelform(&["mesh", &scene, "-o", out.to_str().unwrap(), "--quiet"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        reports.push((ext, check(&out)));
    }
    let names = |d: &std::path::Path| {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    assert_eq!(
        names(dir.path()),
        ["saucer.curves.ply", "saucer.glb", "saucer.mtl", "saucer.obj", "saucer.ply"]
    );
    // Faces come in another order from OBJ (grouped by label): compare all but that.
    for (_, r) in &mut reports {
        for c in r["components"].as_array_mut().unwrap() {
            c.as_object_mut().unwrap().remove("first_face");
        }
    }
    let (_, ply) = &reports[0];
    for (ext, r) in &reports {
        for key in ["components", "non_manifold_edges", "labels", "curves"] {
            assert_eq!(r[key], ply[key], "{key} of .{ext}");
        }
    }
    assert_eq!(ply["components"].as_array().unwrap().len(), 3);
    assert_eq!(ply["non_manifold_edges"], 0);
    assert!(ply["curves"].as_u64().unwrap() > 0);
    // The default PLY has only vertices and faces, with labels and colours.
    let h = header(&dir.path().join("saucer.ply"));
    assert!(!h.contains("element edge"), "{h}");
    assert!(h.contains("property int region_b\nproperty uchar red\n"), "{h}");
    let h = header(&dir.path().join("saucer.curves.ply"));
    assert!(h.contains("comment skelform curves") && h.contains("element edge"), "{h}");
    let obj = std::fs::read_to_string(dir.path().join("saucer.obj")).unwrap();
    assert!(obj.contains("mtllib saucer.mtl\n") && obj.contains("usemtl region_"));
    let mtl = std::fs::read_to_string(dir.path().join("saucer.mtl")).unwrap();
    assert!(mtl.contains("newmtl region_") && mtl.contains("\nKd "), "{mtl}");
}

#[test]
fn curve_layouts_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("nonmanifold/saucer-and-square.toml");
    let out = dir.path().join("s.ply");
    let o = out.to_str().unwrap();
    let side = dir.path().join("s.curves.ply");
    let run = |extra: &[&str]| {
        let mut args = vec!["mesh", &scene, "-o", o, "--quiet"];
        args.extend_from_slice(extra);
        let r = skelform(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    };
    run(&[]);
    assert!(side.exists());
    let curves = check(&out)["curves"].as_u64().unwrap();
    // Inline: one file, and the stale curves file is gone.
    run(&["--ply-curves", "inline"]);
    assert!(!side.exists());
    assert!(header(&out).contains("element edge"));
    assert_eq!(check(&out)["curves"].as_u64(), Some(curves));
    // None, and --no-curves: no curves anywhere.
    run(&["--ply-curves", "none"]);
    assert!(!side.exists() && !header(&out).contains("element edge"));
    assert_eq!(check(&out)["curves"].as_u64(), Some(0));
    run(&["--no-curves"]);
    assert!(!side.exists());
    let glb = dir.path().join("s.glb");
    let r = skelform(&["mesh", &scene, "-o", glb.to_str().unwrap(), "--quiet", "--no-curves"]);
    assert!(r.status.success());
    assert_eq!(check(&glb)["curves"].as_u64(), Some(0));
    let r = skelform(&["mesh", &scene, "-o", o, "--ply-curves", "sideways"]);
    assert_eq!(r.status.code(), Some(2));
}
