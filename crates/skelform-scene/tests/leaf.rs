//! `[leaf]` scenes: the examples load and polygonize; bad input is reported with its line.

use std::path::Path;

use skelform_mesh::RegionPair;
use skelform_polygonize::nonmanifold::{Options, polygonize};
use skelform_polygonize::{LatticeOptions, Resolution};
use skelform_scene::{Scene, SceneError};

fn example(name: &str) -> Scene {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/nonmanifold").join(name);
    Scene::load(&p).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Polygonizes a scene's leaf with a coarser cell than the example's, to stay quick.
fn mesh(scene: &Scene, cell: f64) -> Vec<RegionPair> {
    let setup = scene.nonmanifold_regions().unwrap();
    let lattice = LatticeOptions {
        domain: scene.domain,
        resolution: Resolution::Cell(cell),
        ..Default::default()
    };
    let opts = Options {
        lattice,
        seeds: scene.continuation.seeds.clone(),
        interest: setup.interest,
        full_grid: setup.full_grid,
        ..Options::default()
    };
    let (_, s) = polygonize(setup.field.as_ref(), &opts).unwrap();
    s.triangles_per_pair.iter().map(|(p, _)| *p).collect()
}

#[test]
fn the_leaf_examples_load_and_polygonize() {
    let all = vec![RegionPair(0, 1), RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)];
    for name in ["leaf.toml", "leaf-three-lobes.toml"] {
        let s = example(name);
        assert!(s.regions_only, "{name}");
        let leaf = s.leaf.as_ref().unwrap();
        eprintln!("{name}: {:?}", leaf.stats);
        assert_eq!(leaf.interest, all);
        assert!(!s.continuation.seeds.is_empty());
        assert_eq!(mesh(&s, 0.05), all, "{name}");
        // Both examples draw the tertiary venation texture (§7.4).
        let t = leaf.texture.as_ref().expect("texture = true");
        assert_eq!(t.tertiary.areoles, leaf.stats.polygons, "{name}");
        // Its image, drawn once, 1024 texels along the longer side by default.
        let img = leaf.image.as_ref().expect("an image with the texture");
        assert_eq!(img.width.max(img.height), 1024, "{name}");
    }
    for name in ["tee-in-square.toml", "tee-in-square-fillet.toml"] {
        let s = example(name);
        assert_eq!(
            mesh(&s, 0.06),
            vec![RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)],
            "{name}"
        );
    }
}

fn parse_err(text: &str) -> (usize, usize, String) {
    match Scene::parse(text, "leaf.toml") {
        Err(SceneError::At { line, column, message, .. }) => (line, column, message),
        Err(e) => panic!("unpositioned error: {e}"),
        Ok(_) => panic!("accepted:\n{text}"),
    }
}

const HEAD: &str =
    "[domain]\nmin = [-2, -2, -2]\nmax = [2, 2, 2]\n[mesh]\nmethod = \"nonmanifold\"\n";

#[test]
fn bad_leaves_are_errors_with_their_line() {
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\nlobes = 5\nlobez = 3\n"));
    assert_eq!(l, 8, "{m}");
    assert!(m.contains("lobez"), "{m}");
    let (l, c, m) = parse_err(&format!("{HEAD}[leaf]\nseed = 3\nlobes = 40\n"));
    assert_eq!((l, c), (8, 9), "{m}");
    assert!(m.contains("lobes must be"), "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\nlobe_depth = 1.5\n"));
    assert_eq!(l, 7, "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\nkernel = \"cosine\"\n"));
    assert_eq!(l, 7);
    assert!(m.contains("unknown kernel"), "{m}");
    // The sinc is a kernel, but for points only: veins are segments.
    let (l, c, m) = parse_err(&format!("{HEAD}[leaf]\nkernel = \"sinc\"\n"));
    assert_eq!((l, c), (7, 10));
    assert!(m.contains("points only") && m.contains("wyvill"), "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\nfillet = \"above\"\n"));
    assert_eq!(l, 7);
    assert!(m.contains("both or below"), "{m}");
    let (l, c, m) = parse_err(&format!("{HEAD}[leaf]\nvein_rule = \"min\"\n"));
    assert_eq!((l, c), (7, 13));
    assert!(m.contains("expected dissertation or capped"), "{m}");
    // Outline leaves: generated-leaf keys, veins without radius, radii that do not match.
    let sq = "outline = [[-1, -1], [1, -1], [1, 1], [-1, 1]]\n";
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\n{sq}lobes = 3\n"));
    assert_eq!(l, 8);
    assert!(m.contains("outline"), "{m}");
    let (l, _, m) =
        parse_err(&format!("{HEAD}[leaf]\n{sq}[[leaf.vein]]\npoints = [[0, 0, 0], [1, 0, 0]]\n"));
    assert_eq!(l, 9);
    assert!(m.contains("radius"), "{m}");
    let (l, _, m) = parse_err(&format!(
        "{HEAD}[leaf]\n{sq}[[leaf.vein]]\npoints = [[0, 0, 0], [0.5, 0, 0]]\nradii = [0.1]\n"
    ));
    assert_eq!(l, 10);
    assert!(m.contains("radii"), "{m}");
    let (l, _, m) = parse_err(&format!(
        "{HEAD}[leaf]\n{sq}[[leaf.vein]]\npoints = [[0, 0, 0], [0, 0, 0]]\nradius = 0.1\n"
    ));
    assert_eq!(l, 9);
    assert!(m.contains("zero-length"), "{m}");
    let (l, _, m) =
        parse_err(&format!("{HEAD}[leaf]\noutline = [[0, 0], [1, 1], [1, 0], [0, 1]]\n"));
    assert_eq!(l, 7);
    assert!(m.contains("crosses itself"), "{m}");
    let (_, _, m) = parse_err(&format!(
        "{HEAD}[leaf]\n{sq}[[leaf.vein]]\npoints = [[0, 0, 0], [1, 0, 0]]\nradius = -0.1\n"
    ));
    assert!(m.contains("positive"), "{m}");
    // The texture's keys: a bad value at its line, a texture key without the texture.
    let (l, c, m) = parse_err(&format!("{HEAD}[leaf]\ntexture = true\ntertiary_roughness = 0.9\n"));
    assert_eq!((l, c), (8, 22), "{m}");
    assert!(m.contains("tertiary_roughness must be"), "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\ntexture = true\ntertiary_levels = -1\n"));
    assert_eq!(l, 8, "{m}");
    assert!(m.contains("tertiary_levels"), "{m}");
    let (l, c, m) = parse_err(&format!("{HEAD}[leaf]\ntexture = true\ntexture_size = 8\n"));
    assert_eq!((l, c), (8, 16), "{m}");
    assert!(m.contains("texture_size must be"), "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\ntexture = true\ntexture_size = -5\n"));
    assert_eq!(l, 8, "{m}");
    assert!(m.contains("texture_size"), "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\ntexture_size = 512\n"));
    assert_eq!(l, 7, "{m}");
    assert!(m.contains("texture = true"), "{m}");
    let (l, _, m) = parse_err(&format!("{HEAD}[leaf]\ntertiary_width = 0.01\n"));
    assert_eq!(l, 7, "{m}");
    assert!(m.contains("texture = true"), "{m}");
    // A leaf larger than the domain, and [leaf] beside [regions].
    let small = "[domain]\nmin = [-0.5, -0.5, -0.5]\nmax = [0.5, 0.5, 0.5]\n[leaf]\n";
    let (l, _, m) = parse_err(small);
    assert_eq!(l, 4);
    assert!(m.contains("outside the domain"), "{m}");
    let (_, _, m) = parse_err(&format!(
        "{HEAD}[regions]\ndefault = 0\n[[regions.region]]\nid = 1\nformula = \"x\"\n[leaf]\n"
    ));
    assert!(m.contains("[regions] or [leaf]"), "{m}");
}
