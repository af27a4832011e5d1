//! `[regions.patch_blend]`: the example is the chapter's patch blend (the same region
//! function as the Rust API builds), formulas in front of it trim it, and every mistake is
//! reported at its line and column.

use std::path::Path;

use glam::DVec3;
use skelform_field::RegionField;
use skelform_leaf::patch::{BicubicPatch, PatchBlend};
use skelform_mesh::RegionPair;
use skelform_scene::{Scene, SceneError};

/// The example's patch through the Rust API: control points `(x, y, 0.15 (x² − y²) + 0.1 x)`
/// on a 4 × 4 lattice over [-1, 1]², the saucer's bump at the patch's centre.
fn rust_blend() -> PatchBlend {
    let patch = BicubicPatch::over_square(|x, y| 0.15 * (x * x - y * y) + 0.1 * x);
    PatchBlend { centre: patch.centre(), patch, radius: 1.0 / 1.4, height: 0.35 }
}

/// Points through the domain, a little off any lattice.
fn probes() -> Vec<DVec3> {
    (0..4000)
        .map(|i| {
            DVec3::new(
                (i % 20) as f64 * 0.117 - 1.13,
                (i / 20 % 20) as f64 * 0.117 - 1.13,
                (i / 400) as f64 * 0.061 - 0.29,
            )
        })
        .collect()
}

#[test]
fn the_example_is_the_chapters_patch_blend() {
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/nonmanifold/patch-blend.toml");
    let scene = Scene::load(&p).unwrap();
    assert!(scene.regions_only);
    assert_eq!(scene.figure.as_deref(), Some("4.35"));
    let setup = scene.nonmanifold_regions().unwrap();
    assert_eq!(setup.interest, vec![RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)]);
    assert_eq!(setup.field.region_ids(), Some(vec![0, 1, 2, 3]));
    let rust = rust_blend();
    let pts = probes();
    let mut ids = vec![0; pts.len()];
    setup.field.region_many(&pts, &mut ids);
    let mut seen = [0usize; 4];
    for (p, id) in pts.iter().zip(&ids) {
        assert_eq!(*id, rust.region(*p), "{p}");
        seen[*id as usize] += 1;
    }
    assert!(seen.iter().all(|&n| n > 50), "{seen:?}");
    // The built-in's gradients give the normals of all three surfaces.
    let q = DVec3::new(0.3, -0.2, 0.1);
    for pair in [(1, 2), (1, 3), (2, 3)] {
        let (a, b) = (setup.field.gradient(q, pair).unwrap(), rust.gradient(q, pair).unwrap());
        assert!((a - b).length() < 1e-9, "{pair:?}: {a} {b}");
    }
}

const HEAD: &str =
    "[domain]\nmin = [-2, -2, -2]\nmax = [2, 2, 2]\n[mesh]\nmethod = \"nonmanifold\"\n";

/// A flat patch z = 0 over [-1, 1]², one row per line.
const FLAT: &str = "control = [\n\
  [[-1, -1, 0], [-1, -0.3, 0], [-1, 0.3, 0], [-1, 1, 0]],\n\
  [[-0.3, -1, 0], [-0.3, -0.3, 0], [-0.3, 0.3, 0], [-0.3, 1, 0]],\n\
  [[0.3, -1, 0], [0.3, -0.3, 0], [0.3, 0.3, 0], [0.3, 1, 0]],\n\
  [[1, -1, 0], [1, -0.3, 0], [1, 0.3, 0], [1, 1, 0]],\n\
]\n";

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, "patch.toml")
}

fn err(text: &str) -> (usize, usize, String) {
    match parse(text) {
        Err(SceneError::At { line, column, message, .. }) => (line, column, message),
        Err(e) => panic!("unpositioned error: {e}"),
        Ok(_) => panic!("accepted:\n{text}"),
    }
}

#[test]
fn formulas_in_front_trim_the_blend_and_defaults_apply() {
    // A ball claims region 4 before the patch blend; the interest must then be given.
    let text = format!(
        "{HEAD}[regions]\ninterest = [[2, 3], [3, 4]]\n[[regions.region]]\nid = 4\nformula = \"sqrt((x - 0.6)^2 + y^2 + z^2) - 0.2\"\n[regions.patch_blend]\n{FLAT}"
    );
    let scene = parse(&text).unwrap();
    let setup = scene.nonmanifold_regions().unwrap();
    assert_eq!(setup.interest, vec![RegionPair(2, 3), RegionPair(3, 4)]);
    let f = setup.field;
    assert_eq!(f.region_ids(), Some(vec![0, 1, 2, 3, 4]));
    assert_eq!(f.region(DVec3::new(0.6, 0.0, 0.1)), 4);
    // The saucer's bump (height 0.35, radius 1/1.4) at the patch's centre, the origin.
    // Its top is at 0.24, where 0.35 Sigmoid(1.4 h) = h.
    assert_eq!(f.region(DVec3::new(0.0, 0.0, 0.2)), 1);
    assert_eq!(f.region(DVec3::new(0.0, 0.0, 0.3)), 2);
    assert_eq!(f.region(DVec3::new(0.0, 0.9, -0.1)), 3);
    assert_eq!(f.region(DVec3::new(1.5, 0.0, 0.0)), 0);
    // centre, radius and height move and shape the bump.
    let text = format!(
        "{HEAD}[regions]\n[regions.patch_blend]\n{FLAT}centre = [0.5, 0, 0]\nradius = 0.2\nheight = 0.1\n"
    );
    let f = parse(&text).unwrap().nonmanifold_regions().unwrap().field;
    assert_eq!(f.region(DVec3::new(0.5, 0.0, 0.05)), 1);
    assert_eq!(f.region(DVec3::new(0.5, 0.0, 0.15)), 2);
    assert_eq!(f.region(DVec3::new(0.0, 0.0, 0.05)), 2);
}

#[test]
fn patch_blend_mistakes_name_their_line() {
    let cases: Vec<(String, usize, &str)> = vec![
        // Three rows.
        (
            format!(
                "{HEAD}[regions]\n[regions.patch_blend]\ncontrol = [\n[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]],\n[[0, 1, 0], [1, 1, 0], [2, 1, 0], [3, 1, 0]],\n[[0, 2, 0], [1, 2, 0], [2, 2, 0], [3, 2, 0]],\n]\n"
            ),
            8,
            "has 3 rows",
        ),
        // A row of three points, on the row's line.
        (
            format!(
                "{HEAD}[regions]\n[regions.patch_blend]\n{}",
                FLAT.replace(", [-0.3, 1, 0]],", "],")
            ),
            10,
            "row 2 of 'control' has 3 points",
        ),
        // A point of two numbers.
        (
            format!(
                "{HEAD}[regions]\n[regions.patch_blend]\n{}",
                FLAT.replace("[0.3, 0.3, 0]", "[0.3, 0.3]")
            ),
            11,
            "three numbers",
        ),
        (
            format!(
                "{HEAD}[regions]\n[regions.patch_blend]\n{}",
                FLAT.replace("[1, 1, 0]]", "[1, 1, nan]]")
            ),
            12,
            "finite",
        ),
        (
            format!("{HEAD}[regions]\n[regions.patch_blend]\n{FLAT}radius = 0\n"),
            14,
            "radius must be a positive",
        ),
        (
            format!("{HEAD}[regions]\n[regions.patch_blend]\n{FLAT}height = -0.3\n"),
            14,
            "height must be a positive",
        ),
        (
            format!("{HEAD}[regions]\n[regions.patch_blend]\n{FLAT}centre = [0, inf, 0]\n"),
            14,
            "finite",
        ),
        (format!("{HEAD}[regions]\n[regions.patch_blend]\n{FLAT}radiu = 1\n"), 14, "unknown field"),
        // Every control point the same: no normal.
        (
            format!(
                "{HEAD}[regions]\n[regions.patch_blend]\ncontrol = [{}]\n",
                ["[[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]]"; 4].join(", ")
            ),
            8,
            "degenerate",
        ),
        // 'default' beside the built-in, and neither.
        (
            format!("{HEAD}[regions]\ndefault = 3\n[regions.patch_blend]\n{FLAT}"),
            7,
            "'default' is never used",
        ),
        (format!("{HEAD}[regions]\ninterest = [[1, 2]]\n"), 6, "needs a 'default'"),
        // Pairs name the built-in's regions.
        (
            format!("{HEAD}[regions]\ninterest = [[1, 5]]\n[regions.patch_blend]\n{FLAT}"),
            7,
            "region 5",
        ),
        // Two formulas for one region, even one of the built-in's.
        (
            format!(
                "{HEAD}[regions]\n[[regions.region]]\nid = 2\nformula = \"x\"\n[[regions.region]]\nid = 2\nformula = \"y\"\n[regions.patch_blend]\n{FLAT}"
            ),
            11,
            "region 2 is given twice",
        ),
    ];
    for (text, line, says) in cases {
        let (l, c, m) = err(&text);
        assert!(
            l == line && m.contains(says),
            "{l}:{c}: {m} (expected line {line}: {says})\n{text}"
        );
    }
}
