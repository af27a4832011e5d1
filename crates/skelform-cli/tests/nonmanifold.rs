//! `skelform mesh` on region scenes (`--method nonmanifold`).

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
    // Gradients and curves name declared regions, once.
    let body = "[regions]\ndefault = 0\n[[regions.region]]\nid = 1\nformula = \"x\"\n";
    for (name, extra, line, says) in [
        ("gradient.toml", "[[regions.gradient]]\npair = [1, 9]\nformula = \"x\"\n", 10, "region 9"),
        (
            "twice.toml",
            "[[regions.gradient]]\npair = [0, 1]\nformula = \"x\"\n[[regions.gradient]]\npair = [1, 0]\nformula = \"x\"\n",
            13,
            "has a gradient already",
        ),
        ("gradformula.toml", "[[regions.gradient]]\npair = [0, 1]\nformula = \"x *\"\n", 11, ""),
    ] {
        let p = scene(name, format!("{head}{body}{extra}"));
        let r = skelform(&["mesh", &p, "-o", o, "--method", "nonmanifold"]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("{name}:{line}:")) && err.contains(says), "{err}");
    }
    let p = scene(
        "curve.toml",
        format!(
            "{head}[regions]\ndefault = 0\ncurves = [[0, 1, 1]]\n[[regions.region]]\nid = 1\nformula = \"x\"\n"
        ),
    );
    let r = skelform(&["mesh", &p, "-o", o, "--method", "nonmanifold"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2));
    assert!(err.contains("curve.toml:6:") && err.contains("names one region twice"), "{err}");
    assert!(!out.exists());
}

/// What an example scene must produce.
struct Expect {
    name: &'static str,
    pairs: &'static [[u32; 2]],
    /// Curves that must be present and closed loops.
    closed_curves: &'static [[u32; 3]],
    /// Curves that must be present (open: they end where other curves meet them).
    open_curves: &'static [[u32; 3]],
    /// Edge degrees (after welding the per-pair copies) that must occur; no other may.
    degrees: &'static [usize],
}

/// Meshes an example scene as `skelform mesh` does, through the library's front door.
fn mesh_example(name: &str) -> (skelform::Scene, skelform::Mesh, nonmanifold::Stats) {
    let scene = skelform::Scene::load(example(name)).unwrap();
    let meshed = scene.mesh(&skelform::Overrides::default()).unwrap();
    let skelform::Stats::NonManifold(s) = meshed.stats else { panic!("{name}: not nonmanifold") };
    (scene, meshed.mesh, *s)
}

use skelform::polygonize::nonmanifold;

mod common;
use common::{example, skelform};

/// Issue 18: the non-manifold polygonizer evaluates the region function at most twice as
/// often as a conventional tetrahedral polygonizer would on the same cubes (the count the
/// library reports beside its own), on every example: the chapter's, the full-grid one
/// (sphere-and-square) and the leaves among them. The counts are exact, so this is not a timing.
#[test]
fn evaluations_stay_within_twice_a_conventional_polygonizer() {
    for name in [
        "nonmanifold/saucer-and-square.toml",
        "nonmanifold/sphere-and-square.toml",
        "nonmanifold/sphere-plane-hole.toml",
        "nonmanifold/sphere-with-hole.toml",
        "nonmanifold/sphere-with-hole-scoop.toml",
        "nonmanifold/patch-blend.toml",
        "nonmanifold/tee-in-square.toml",
        "nonmanifold/tee-in-square-fillet.toml",
        "nonmanifold/leaf.toml",
        "nonmanifold/leaf-three-lobes.toml",
    ] {
        let (_, _, s) = mesh_example(name);
        let ratio = s.region_evaluations as f64 / s.conventional_evaluations as f64;
        assert!(
            ratio <= 2.0,
            "{name}: {} region evaluations, {} conventional: {ratio:.2}x",
            s.region_evaluations,
            s.conventional_evaluations
        );
    }
}

/// Every example of the chapter: the surfaces and curves it describes, vertices between
/// their regions, triangles facing their lesser region, the expected edge degrees once the
/// per-pair copies are welded, closed curves, and no triangle crossing another.
#[test]
fn the_chapter_examples_are_what_the_chapter_describes() {
    let cases = [
        Expect {
            name: "nonmanifold/saucer-and-square.toml",
            pairs: &[[1, 2], [1, 3], [2, 3]],
            closed_curves: &[[1, 2, 3], [0, 2, 3]],
            open_curves: &[],
            degrees: &[1, 2, 3],
        },
        Expect {
            name: "nonmanifold/sphere-and-square.toml",
            pairs: &[[1, 3], [1, 4], [3, 4]],
            closed_curves: &[[1, 3, 4], [2, 3, 4]],
            open_curves: &[],
            degrees: &[1, 2, 3],
        },
        Expect {
            name: "nonmanifold/sphere-with-hole.toml",
            pairs: &[[0, 2]],
            closed_curves: &[[0, 1, 2]],
            open_curves: &[],
            degrees: &[1, 2],
        },
        Expect {
            name: "nonmanifold/sphere-with-hole-scoop.toml",
            pairs: &[[0, 2], [1, 2]],
            closed_curves: &[[0, 1, 2]],
            open_curves: &[],
            degrees: &[2],
        },
        Expect {
            name: "nonmanifold/sphere-plane-hole.toml",
            pairs: &[[0, 2], [0, 3], [2, 3]],
            closed_curves: &[[2, 3, 4]],
            open_curves: &[[0, 1, 2], [0, 1, 3], [1, 2, 3], [0, 2, 3]],
            degrees: &[1, 2, 3],
        },
        // The blend to a patch ([regions.patch_blend]): the bump's rim and the patch's border.
        Expect {
            name: "nonmanifold/patch-blend.toml",
            pairs: &[[1, 2], [1, 3], [2, 3]],
            closed_curves: &[[1, 2, 3], [0, 2, 3]],
            open_curves: &[],
            degrees: &[1, 2, 3],
        },
    ];
    for e in cases {
        let (scene, m, s) = mesh_example(e.name);
        let regions = scene.regions.as_ref().unwrap();
        let pairs: Vec<[u32; 2]> = s.triangles_per_pair.iter().map(|(p, _)| [p.0, p.1]).collect();
        assert_eq!(pairs, e.pairs, "{}", e.name);
        let v = nonmanifold::verify::verify(&m, regions.field.as_ref(), 2.0 * s.epsilon);
        let r = skelform::mesh::check::check_welded(&m, 0.0);
        let crossing = skelform::mesh::check::crossings(&m, 1e-3 * s.epsilon);
        eprintln!(
            "{}: {v:?}\n  degrees {:?} curves {:?}\n  fallbacks {} of {} face vertices, {} crossing pairs, {} gradient normals of {}",
            e.name,
            r.edge_degrees,
            r.curve_labels,
            s.face_vertex_fallbacks,
            s.face_vertices,
            crossing.len(),
            s.gradient_normals,
            s.vertices
        );
        assert!(v.vertex_fraction() >= 0.97 && v.vertices_reversed == 0, "{}: {v:?}", e.name);
        assert!(v.triangle_fraction() >= 0.97 && v.triangles_reversed == 0, "{}: {v:?}", e.name);
        let degrees: Vec<usize> = r.edge_degrees.keys().copied().collect();
        assert_eq!(degrees, e.degrees, "{}: {:?}", e.name, r.edge_degrees);
        for t in e.closed_curves.iter().chain(e.open_curves) {
            let c = r.curve_labels.iter().find(|c| c.label.0 == *t);
            let c = c.unwrap_or_else(|| panic!("{}: no curve {t:?}", e.name));
            if e.closed_curves.contains(t) {
                assert_eq!(c.open_ends, 0, "{}: curve {t:?} is not closed", e.name);
            } else {
                // An arc from one meeting point of curves to the other.
                assert_eq!(c.open_ends, 2, "{}: curve {t:?} is not one arc", e.name);
            }
        }
        let expected = e.closed_curves.len() + e.open_curves.len();
        assert_eq!(r.curve_labels.len(), expected, "{}: {:?}", e.name, r.curve_labels);
        assert!(crossing.is_empty(), "{}: triangles cross: {crossing:?}", e.name);
        assert!(s.face_vertex_fallbacks * 100 <= s.face_vertices.max(1), "{}: {s:?}", e.name);
        assert_eq!(s.gradient_normals, s.vertices, "{}: every pair has a gradient", e.name);
    }
}

/// Signed distance from `p` to the saddle `z = 0.1 (x² − y² + x)`, positive above: Newton's
/// method on the nearest point `(u, v, h(u, v))`, where `p − q` is normal to the surface.
fn distance_to_saddle([x, y, z]: [f64; 3]) -> f64 {
    let h = |u: f64, v: f64| 0.1 * (u * u - v * v + u);
    let (mut u, mut v) = (x, y);
    for _ in 0..20 {
        let (hu, hv, e) = (0.1 * (2.0 * u + 1.0), -0.2 * v, h(u, v) - z);
        let (f, g) = (u - x + e * hu, v - y + e * hv);
        let (a, b, d) = (1.0 + hu * hu + 0.2 * e, hu * hv, 1.0 + hv * hv - 0.2 * e);
        let det = a * d - b * b;
        (u, v) = (u - (d * f - b * g) / det, v - (a * g - b * f) / det);
    }
    let q = [u, v, h(u, v)];
    let len = ((x - q[0]).powi(2) + (y - q[1]).powi(2) + (z - q[2]).powi(2)).sqrt();
    if z >= q[2] { len } else { -len }
}

/// The blend to a patch: the scene's control points make the saddle z = 0.1 (x² − y² + x)
/// over [-1, 1]² exactly, so the patch's sheet (2,3) lies on it within the polygonizer's
/// accuracy, with normals from the patch (the built-in's gradient) facing up into region 2;
/// the bump's sheets (1,2) and (1,3) are where the distance to the patch is the bump's height
/// 0.35 Sigmoid(1.4 |p|) (centred on P(½, ½), the origin), above and below.
#[test]
fn the_patch_blend_lies_on_its_patch_and_bump() {
    let (_, m, s) = mesh_example("nonmanifold/patch-blend.toml");
    let sigmoid = |d: f64| {
        if d > 1.0 { 0.0 } else { 1.0 - (4.0 * d.powi(6) - 17.0 * d.powi(4) + 22.0 * d * d) / 9.0 }
    };
    let mut pair_of = vec![None; m.positions.len()];
    for (t, l) in m.triangles.iter().zip(&m.labels) {
        for &v in t {
            pair_of[v as usize] = Some((l.0, l.1));
        }
    }
    // Vertices on the rim and the border (found by the face contour follower) apart.
    let on_curve: std::collections::HashSet<[u32; 3]> = m
        .curves
        .iter()
        .flat_map(|c| c.v)
        .map(|v| m.positions[v as usize].map(f32::to_bits))
        .collect();
    let (mut sheet, mut edge, mut bump, mut normal) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut counted = [0usize; 3];
    for (i, p) in m.positions.iter().enumerate() {
        let [x, y, z] = p.map(f64::from);
        let off = distance_to_saddle([x, y, z]);
        let r = (x * x + y * y + z * z).sqrt();
        match pair_of[i] {
            Some((2, 3)) => {
                let worst =
                    if on_curve.contains(&p.map(f32::to_bits)) { &mut edge } else { &mut sheet };
                *worst = worst.max(off.abs());
                counted[0] += 1;
                let (gx, gy) = (0.1 * (2.0 * x + 1.0), -0.2 * y);
                let n = m.normals[i].map(f64::from);
                let cos = (-gx * n[0] - gy * n[1] + n[2]) / (1.0 + gx * gx + gy * gy).sqrt();
                normal = normal.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
            }
            Some((1, b)) => {
                let want = 0.35 * sigmoid(1.4 * r);
                bump = bump.max((off.abs() - want).abs());
                // Above for (1,2), below for (1,3) (at the rim, where the bump is thinner
                // than the accuracy, both sheets touch the patch).
                assert!(
                    want < 4.0 * s.epsilon || off * if b == 2 { 1.0 } else { -1.0 } > 0.0,
                    "{p:?} on the wrong side"
                );
                counted[b as usize - 1] += 1;
            }
            other => panic!("unexpected pair {other:?}"),
        }
    }
    eprintln!(
        "patch sheet off by {sheet:.2e} ({edge:.2e} on curves), normals by {normal:.3}°; bump off by {bump:.2e} (ε {:.2e}); {counted:?}",
        s.epsilon
    );
    assert!(counted.iter().all(|&c| c > 500), "{counted:?}");
    assert!(sheet < s.epsilon, "the patch's sheet is {sheet} off the patch");
    assert!(edge < 4.0 * s.epsilon, "the rim and border are {edge} off the patch");
    assert!(normal < 0.5, "normals {normal}° off the patch's");
    assert!(bump < 4.0 * s.epsilon, "the bump's sheets are {bump} off the bump");
}

/// The saucer's per-pair gradient functions (scene `[[regions.gradient]]`) give the vertex
/// normals: they agree with the analytic normals of the saucer's top (z = Saucer), bottom
/// (z = −Saucer) and the square, pointing into the lesser region.
#[test]
fn saucer_normals_come_from_the_gradient_functions() {
    let (_, m, s) = mesh_example("nonmanifold/saucer-and-square.toml");
    let saucer = |x: f64, y: f64| {
        let d = 1.4 * (x * x + y * y).sqrt();
        if d.abs() > 1.0 {
            0.0
        } else {
            0.35 * (1.0 - (4.0 * d.powi(6) - 17.0 * d.powi(4) + 22.0 * d * d) / 9.0)
        }
    };
    let h = 1e-6;
    let mut pair_of = vec![None; m.positions.len()];
    for (t, l) in m.triangles.iter().zip(&m.labels) {
        for &v in t {
            pair_of[v as usize] = Some(*l);
        }
    }
    let mut worst: f64 = 0.0;
    for (i, p) in m.positions.iter().enumerate() {
        let [x, y, _] = p.map(f64::from);
        let (sx, sy) = (
            (saucer(x + h, y) - saucer(x - h, y)) / (2.0 * h),
            (saucer(x, y + h) - saucer(x, y - h)) / (2.0 * h),
        );
        let expected = match pair_of[i].map(|p| (p.0, p.1)) {
            // Into the saucer (1): down from the top, up from the bottom; into 2 from the square.
            Some((1, 2)) => [sx, sy, -1.0],
            Some((1, 3)) => [sx, sy, 1.0],
            Some((2, 3)) => [0.0, 0.0, 1.0],
            other => panic!("unexpected pair {other:?}"),
        };
        let len = expected.iter().map(|c| c * c).sum::<f64>().sqrt();
        let n = m.normals[i].map(f64::from);
        let cos: f64 = (0..3).map(|k| n[k] * expected[k] / len).sum();
        worst = worst.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
    }
    eprintln!("worst normal error {worst:.3}° over {} vertices", m.positions.len());
    assert_eq!(s.gradient_normals, m.positions.len());
    assert!(worst < 0.5, "worst normal error {worst}°");
}

/// The real saucer-and-square scene written as `.glb`: one primitive and one material per
/// region pair, and `skelform check` reads the three labels back with the counts `mesh`
/// reported; `check --weld` sees the closed non-manifold complex (degree 3 on the rim).
#[test]
fn saucer_as_glb_keeps_its_three_labels_and_welds_into_one_complex() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("saucer.glb");
    let o = skelform(&[
        "mesh",
        &example("nonmanifold/saucer-and-square.toml"),
        "-o",
        glb.to_str().unwrap(),
        "--json",
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let run: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let surfaces: Vec<(serde_json::Value, u64)> = run["surfaces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["pair"].clone(), s["triangles"].as_u64().unwrap()))
        .collect();
    assert_eq!(surfaces.len(), 3);
    // The glTF JSON chunk: after the 12-byte header, a chunk length and type.
    let bytes = std::fs::read(&glb).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    assert_eq!(doc["meshes"][0]["primitives"].as_array().unwrap().len(), 3);
    // Three region pairs and the curves.
    assert_eq!(doc["materials"].as_array().unwrap().len(), 4);
    let c = skelform(&["check", glb.to_str().unwrap(), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
    let labels: Vec<(serde_json::Value, u64)> = report["labels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            (serde_json::json!([l["label"][0], l["label"][1]]), l["triangles"].as_u64().unwrap())
        })
        .collect();
    assert_eq!(labels, surfaces);
    // Welded, the rim's edges have three triangles.
    let c = skelform(&["check", "--weld", glb.to_str().unwrap()]);
    assert!(c.status.success(), "--weld before the mesh is not its tolerance");
    let text = String::from_utf8_lossy(&c.stdout);
    assert!(text.contains("welded ") && text.contains("(3: "), "{text}");
    let c = skelform(&["check", glb.to_str().unwrap(), "--weld=-1"]);
    assert_eq!(c.status.code(), Some(2));
    let c = skelform(&["check", glb.to_str().unwrap(), "--weld=1e-45"]);
    let text = String::from_utf8_lossy(&c.stdout);
    assert!(text.contains("welded ") && text.contains("(3: "), "{text}");
}
