//! Tunnels through a cube whose trilinear interpolant has no xyz term (issue 18, defect 1):
//! the tube must be kept, by `extract` and by `mesh` with both cube-based methods.

mod common;
use common::{check_json, skelform};

fn components(mesh: &std::path::Path) -> u64 {
    let r = check_json(mesh);
    assert_eq!(r["boundary_edges"], 0);
    assert_eq!(r["outward"], true);
    r["components"].as_array().unwrap().len() as u64
}

#[test]
fn a_diagonal_tube_without_a_cubic_term_is_one_piece() {
    // 4×4×4 of 1.0; the inner cube has -1 at (0,0,0) and (1,1,1) and 0.1 elsewhere: the
    // interpolant is point-symmetric about the cube's centre (h = 0) and stays below -0.17
    // on the diagonal, so the two inside corners are joined by a tube.
    let mut v = [1.0f32; 64];
    let at = |x: usize, y: usize, z: usize| x + 4 * y + 16 * z;
    for x in 1..3 {
        for y in 1..3 {
            for z in 1..3 {
                v[at(x, y, z)] = 0.1;
            }
        }
    }
    v[at(1, 1, 1)] = -1.0;
    v[at(2, 2, 2)] = -1.0;
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("tube.raw");
    std::fs::write(&vol, v.iter().flat_map(|s| s.to_le_bytes()).collect::<Vec<_>>()).unwrap();
    let out = dir.path().join("tube.ply");
    let o = skelform(&[
        "extract",
        vol.to_str().unwrap(),
        "--dims",
        "4,4,4",
        "-o",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(components(&out), 1);
}

#[test]
fn a_thin_capsule_along_the_lattice_diagonal_is_not_beads() {
    // Radius 0.7 cells at 13 samples: every cube on the diagonal holds a tunnel.
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("capsule.toml");
    std::fs::write(
        &scene,
        r#"[domain]
min = [-1, -1, -1]
max = [1, 1, 1]
[mesh]
resolution = 13
[field]
formula = """
t = min(max((x + y + z) / 3, -0.8), 0.8)
sqrt((x - t)^2 + (y - t)^2 + (z - t)^2) - 0.7 * 2 / 12
"""
"#,
    )
    .unwrap();
    for method in ["grid", "continuation"] {
        let out = dir.path().join(format!("capsule-{method}.ply"));
        let o = skelform(&[
            "mesh",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--method",
            method,
            "-q",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(components(&out), 1, "{method}");
    }
}
