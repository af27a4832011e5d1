//! The leaf of chapter 7: venation, web, blade distance, and the leaf polygonized by the
//! non-manifold polygonizer.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use glam::{DVec2, DVec3};
use skelform_field::{Aabb, RegionField};
use skelform_leaf::regions::{ABOVE, BELOW, BEYOND, VEIN};
use skelform_leaf::web::signed_area2;
use skelform_leaf::{
    Fillet, Leaf, LeafParams, Side, TextureParams, VeinCurve, VeinKind, VeinRule, Venation, Web,
};
use skelform_mesh::{Mesh, RegionPair, RegionTriple};
use skelform_polygonize::nonmanifold::{Options, Stats, polygonize};
use skelform_polygonize::{LatticeOptions, Resolution};
use skelform_skeleton::Kernel;

/// A small deterministic stream of numbers in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn the_venation_is_a_tree_with_the_stated_counts() {
    let p = LeafParams::default();
    let v = Venation::maple(&p).unwrap();
    // 5 primaries; per primary 3 secondaries on the left (one into the sinus) and 2 on the
    // right, plus the last lobe's basal sinus vein: 5·5 + 1 = 26; one petiole.
    assert_eq!(v.counts(), (5, 26, 1));
    eprintln!("venation: {} points, veins {:?}", v.points.len(), v.counts());
    // A tree: every point but the base has a parent and reaches the base.
    for i in 0..v.points.len() {
        let path = v.path_to_base(i);
        assert_eq!(*path.last().unwrap(), v.base, "point {i}");
        assert!(path.len() <= v.points.len());
    }
    assert_eq!(v.parent.iter().filter(|p| p.is_none()).count(), 1);
    // Each vein starts on its parent's chain; descendants are ordered from the parent's base.
    for (i, vein) in v.veins.iter().enumerate() {
        match vein.kind {
            VeinKind::Primary | VeinKind::Petiole => assert_eq!(vein.points[0], v.base),
            VeinKind::Secondary => {
                let parent = &v.veins[vein.parent.unwrap()];
                assert!(parent.points.contains(&vein.points[0]), "vein {i}");
            }
        }
        for side in [&vein.left, &vein.right] {
            let at: Vec<usize> = side
                .iter()
                .map(|&c| vein.points.iter().position(|&q| q == v.veins[c].points[0]).unwrap())
                .collect();
            assert!(at.windows(2).all(|w| w[0] <= w[1]), "vein {i}: {at:?}");
        }
    }
    // Primaries clockwise round the petiole (seen from +z): their angles from the petiole's
    // direction (−y), measured clockwise, increase.
    let angles: Vec<f64> = v
        .primaries
        .iter()
        .map(|&k| {
            let t = v.points[v.tip(k)];
            let a = (-t.x).atan2(-t.y); // clockwise from −y
            if a < 0.0 { a + std::f64::consts::TAU } else { a }
        })
        .collect();
    assert!(angles.windows(2).all(|w| w[0] < w[1]), "{angles:?}");
    // The margin: the base and every blade vein's tip, a clockwise simple loop.
    let margin = v.margin();
    assert_eq!(margin.len(), 1 + 5 + 26);
    let tips: BTreeSet<usize> = v
        .veins
        .iter()
        .enumerate()
        .filter(|(_, w)| w.kind != VeinKind::Petiole)
        .map(|(k, _)| v.tip(k))
        .collect();
    assert_eq!(margin[1..].iter().copied().collect::<BTreeSet<_>>(), tips);
    let outline: Vec<DVec2> = margin.iter().map(|&k| v.points[k]).collect();
    assert!(signed_area2(&outline) < 0.0, "clockwise");
    assert!(skelform_leaf::web::simple(&outline));
    // Curvature: set at the primaries' tips, spread to every blade point.
    assert!(
        v.veins
            .iter()
            .filter(|w| w.kind != VeinKind::Petiole)
            .flat_map(|w| &w.points)
            .all(|&k| v.curvature[k] != 0.0)
    );
}

#[test]
fn the_web_tiles_the_blade() {
    let p = LeafParams::default();
    let v = Venation::maple(&p).unwrap();
    let margin = v.margin();
    let outline: Vec<DVec2> = margin.iter().map(|&k| v.points[k]).collect();
    let blade_area = signed_area2(&outline).abs() / 2.0;
    let mut web = Web::from_venation(&v).unwrap();
    assert_eq!(web.polygons.len(), margin.len(), "one polygon per adjacent pair of margin points");
    let unsplit = web.refine(p.max_area, p.max_ratio);
    let tris = web.triangulate().unwrap();
    eprintln!(
        "web: {} polygons, refined to {}, {unsplit} left uncut; {} triangles (the dissertation's maple: 475)",
        margin.len(),
        web.polygons.len(),
        tris.len()
    );
    let pts = &web.points;
    let area = |t: &[usize; 3]| (pts[t[1]] - pts[t[0]]).perp_dot(pts[t[2]] - pts[t[0]]) / 2.0;
    assert!(tris.iter().all(|t| area(t) > 0.0), "every triangle counter-clockwise");
    let sum: f64 = tris.iter().map(area).sum();
    assert!((sum - blade_area).abs() < 1e-9 * blade_area, "{sum} vs {blade_area}");
    // Every edge inside the blade has two triangles, in opposite directions; the rest is the
    // margin, one closed loop.
    let mut directed: HashMap<(usize, usize), usize> = HashMap::new();
    for t in &tris {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    assert!(directed.values().all(|&c| c == 1), "no edge twice in one direction");
    let boundary: Vec<(usize, usize)> =
        directed.keys().filter(|(a, b)| !directed.contains_key(&(*b, *a))).copied().collect();
    let next: HashMap<usize, usize> = boundary.iter().copied().collect();
    assert_eq!(next.len(), boundary.len(), "the margin never branches");
    let start = boundary[0].0;
    let (mut at, mut steps) = (start, 0);
    loop {
        at = next[&at];
        steps += 1;
        if at == start {
            break;
        }
        assert!(steps <= boundary.len());
    }
    assert_eq!(steps, boundary.len(), "the margin is one loop");
    // No two triangles overlap: interiors are disjoint (areas add up, orientation is
    // consistent, and no edge crosses another).
    let crosses = |a: DVec2, b: DVec2, c: DVec2, d: DVec2| {
        let o = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
        let tol = 1e-14;
        o(a, b, c) * o(a, b, d) < -tol && o(c, d, a) * o(c, d, b) < -tol
    };
    let edges: Vec<(usize, usize)> = directed
        .keys()
        .filter(|(a, b)| a < b || !directed.contains_key(&(*b, *a)))
        .copied()
        .collect();
    for (i, &(a, b)) in edges.iter().enumerate() {
        for &(c, d) in &edges[i + 1..] {
            if a == c || a == d || b == c || b == d {
                continue;
            }
            assert!(!crosses(pts[a], pts[b], pts[c], pts[d]), "edges {a}-{b} and {c}-{d} cross");
        }
    }
}

#[test]
fn blade_distance_is_the_brute_force_distance() {
    let leaf = Leaf::maple(&LeafParams::default()).unwrap();
    let b = &leaf.blade;
    let (lo, hi) = b.bounds();
    let (lo, hi) = (lo - DVec3::splat(0.2), hi + DVec3::splat(0.2));
    let mut rng = Lcg(7);
    let mut sides = [0; 3];
    for _ in 0..3000 {
        let p = lo + (hi - lo) * DVec3::new(rng.next(), rng.next(), rng.next());
        let (fast, slow) = (b.distance(p), b.distance_brute_force(p));
        assert_eq!(fast, slow, "at {p:?}");
        sides[match fast.side {
            Side::Above => 0,
            Side::Below => 1,
            Side::Beyond => 2,
        }] += 1;
    }
    // Points near the blade too, where the nearest feature changes fastest.
    for i in 0..2000 {
        let t = b.triangles[i % b.triangles.len()].map(|k| b.vertices[k as usize]);
        let c = (t[0] + t[1] + t[2]) / 3.0;
        let p = c + (DVec3::new(rng.next(), rng.next(), rng.next()) - 0.5) * 0.05;
        assert_eq!(b.distance(p), b.distance_brute_force(p), "at {p:?}");
    }
    assert!(sides.iter().all(|&s| s > 100), "{sides:?}");
}

#[test]
fn blade_distance_of_a_flat_leaf_is_height_inside_and_beyond_outside() {
    let flat = LeafParams { curvature: 0.0, smooth_margin: false, ..LeafParams::default() };
    let leaf = Leaf::maple(&flat).unwrap();
    let v = leaf.venation.as_ref().unwrap();
    let outline: Vec<DVec2> = v.margin().iter().map(|&k| v.points[k]).collect();
    let inside = |q: DVec2| {
        // Winding by crossings.
        let mut c = false;
        for i in 0..outline.len() {
            let (a, b) = (outline[i], outline[(i + 1) % outline.len()]);
            if (a.y > q.y) != (b.y > q.y) && q.x < a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x) {
                c = !c;
            }
        }
        c
    };
    let mut rng = Lcg(3);
    let mut checked = 0;
    for _ in 0..2000 {
        let q = DVec2::new(rng.next() * 1.6 - 0.8, rng.next() * 1.6 - 0.6);
        let z = rng.next() * 0.4 - 0.2;
        let d = leaf.blade.distance(DVec3::new(q.x, q.y, z));
        if inside(q) {
            assert!((d.distance - z).abs() < 1e-12, "at {q:?} {z}: {d:?}");
            assert_eq!(d.side, if z > 0.0 { Side::Above } else { Side::Below });
            checked += 1;
        } else {
            assert_eq!(d.side, Side::Beyond, "at {q:?}");
            assert!(d.distance >= z.abs() - 1e-12);
        }
    }
    assert!(checked > 400);
}

/// Non-manifold options for a region field with the leaf's interest.
fn options(leaf: &Leaf, r: &skelform_leaf::BladeRegions, cell: f64) -> Options {
    let (lo, hi) = leaf.bounds(r.veins.as_ref().map_or(Kernel::Wyvill, |v| v.kernel));
    // The lattice starts a fraction of a cell off the round numbers, so that no lattice
    // plane holds the flat parts of the blade (z = 0) or a straight margin (x = ±1): a
    // region boundary lying in a lattice plane is the chapter's degenerate case.
    let lo = lo - DVec3::splat(2.0 * cell) + DVec3::splat(0.17 * cell);
    let domain = Aabb::new(lo, hi + DVec3::splat(2.0 * cell));
    Options {
        lattice: LatticeOptions {
            domain,
            resolution: Resolution::Cell(cell),
            ..Default::default()
        },
        seeds: r.seeds(),
        interest: r.interest(),
        ..Options::default()
    }
}

/// Vertices whose ±2ε steps along their normal land in their pair's two regions (lesser
/// region in front), those facing the wrong way, and the total; vertices on curves excluded.
fn between_regions(m: &Mesh, regions: &dyn RegionField, eps: f64) -> (usize, usize, usize) {
    let v = skelform_polygonize::nonmanifold::verify::verify(m, regions, 2.0 * eps);
    (v.vertices_between, v.vertices_reversed, v.vertices)
}

fn pairs(s: &Stats) -> Vec<RegionPair> {
    s.triangles_per_pair.iter().map(|(p, _)| *p).collect()
}

fn curve_length(s: &Stats, t: [u32; 3]) -> f64 {
    s.curve_length_per_triple
        .iter()
        .filter(|(c, _)| *c == RegionTriple::new(t))
        .map(|(_, l)| l)
        .sum()
}

#[test]
fn the_leaf_polygonizes_into_labelled_blade_and_veins() {
    let leaf = Leaf::maple(&LeafParams::default()).unwrap();
    let r = leaf.regions(Kernel::Wyvill, Fillet::Both).unwrap();
    let opts = options(&leaf, &r, 0.05);
    let (m, s) = polygonize(&r, &opts).unwrap();
    eprintln!("{:?}; mesh {:?}", leaf.stats, s.triangles_per_pair);
    assert_eq!(
        pairs(&s),
        vec![
            RegionPair(BEYOND, VEIN),
            RegionPair(VEIN, ABOVE),
            RegionPair(VEIN, BELOW),
            RegionPair(ABOVE, BELOW)
        ]
    );
    assert!(s.triangles_per_pair.iter().all(|(_, n)| *n > 50), "{:?}", s.triangles_per_pair);
    let (ok, wrong, total) = between_regions(&m, &r, s.epsilon);
    eprintln!("{ok} of {total} vertices between their regions, {wrong} facing the wrong way");
    // Vertices near a curve (a vein's fillet edge, the margin) may step into a third region;
    // nearly all lie between their own two.
    assert!(ok as f64 >= 0.9 * total as f64, "{ok} of {total}");
    assert!((wrong as f64) < 0.01 * total as f64, "{wrong} of {total} face their greater region");
    // The margin and the vein/blade fillet edges are curves; the margin is about as long as
    // the blade's outline.
    let v = leaf.venation.as_ref().unwrap();
    let outline: Vec<DVec2> = v.margin().iter().map(|&k| v.points[k]).collect();
    let perimeter: f64 =
        (0..outline.len()).map(|i| outline[i].distance(outline[(i + 1) % outline.len()])).sum();
    let margin = curve_length(&s, [BEYOND, ABOVE, BELOW]);
    eprintln!("margin curve {margin:.3}, outline {perimeter:.3}");
    assert!(margin > 0.7 * perimeter && margin < 1.3 * perimeter, "{margin} vs {perimeter}");
    assert!(curve_length(&s, [VEIN, ABOVE, BELOW]) > 1.0);
    // Deterministic.
    let (m2, _) = polygonize(&r, &opts).unwrap();
    assert_eq!(m.positions, m2.positions);
    assert_eq!(m.triangles, m2.triangles);
    assert_eq!(m.labels, m2.labels);
}

#[test]
fn leaves_are_deterministic_and_the_seed_perturbs_them() {
    let a = Leaf::maple(&LeafParams::default()).unwrap();
    let b = Leaf::maple(&LeafParams::default()).unwrap();
    assert_eq!(a.blade.vertices, b.blade.vertices);
    assert_eq!(a.blade.triangles, b.blade.triangles);
    assert_eq!(a.veins, b.veins);
    let c = Leaf::maple(&LeafParams { seed: 2, ..LeafParams::default() }).unwrap();
    assert_ne!(a.blade.vertices, c.blade.vertices);
    // Other shapes build too: three lobes, seven lobes, no lobes, a flat one.
    for p in [
        LeafParams { lobes: 3, spread: 120.0, ..LeafParams::default() },
        LeafParams { lobes: 7, spread: 240.0, secondaries: 2, ..LeafParams::default() },
        LeafParams { lobe_depth: 0.0, ..LeafParams::default() },
        LeafParams { lobes: 1, curvature: 0.0, ..LeafParams::default() },
        LeafParams { secondary_radius: 0.012, curvature: -0.8, ..LeafParams::default() },
    ] {
        let leaf = Leaf::maple(&p).unwrap_or_else(|e| panic!("{p:?}: {e}"));
        assert!(leaf.blade.triangles.len() > 50);
    }
    let bad = Leaf::maple(&LeafParams { lobes: 0, ..LeafParams::default() }).unwrap_err();
    assert!(bad.to_string().contains("lobes"), "{bad}");
}

/// The chapter's test: a tee of two segments embedded in a square blade (figs. 7.11, 7.12).
fn tee_in_square(fillet: Fillet) -> (Leaf, skelform_leaf::BladeRegions) {
    let square = [
        DVec2::new(-1.0, -1.0),
        DVec2::new(1.0, -1.0),
        DVec2::new(1.0, 1.0),
        DVec2::new(-1.0, 1.0),
    ];
    let vein = |a: DVec3, b: DVec3| VeinCurve { points: vec![a, b], radii: vec![0.1, 0.1] };
    let veins = vec![
        vein(DVec3::new(-0.6, -0.2, 0.0), DVec3::new(0.6, -0.2, 0.0)),
        vein(DVec3::new(0.0, -0.2, 0.0), DVec3::new(0.0, 0.6, 0.0)),
    ];
    let leaf = Leaf::from_outline(&square, veins, 0.25, 20.0).unwrap();
    let r = leaf.regions(Kernel::Wyvill, fillet).unwrap();
    (leaf, r)
}

#[test]
fn a_tee_fillets_into_a_square_blade() {
    for (fillet, rule) in [
        (Fillet::Both, VeinRule::Capped),
        (Fillet::Below, VeinRule::Capped),
        (Fillet::Both, VeinRule::Dissertation),
        (Fillet::Below, VeinRule::Dissertation),
    ] {
        let (leaf, mut r) = tee_in_square(fillet);
        assert_eq!(r.vein_rule, VeinRule::Dissertation, "the default");
        r.vein_rule = rule;
        let opts = options(&leaf, &r, 0.04);
        let (m, s) = polygonize(&r, &opts).unwrap();
        eprintln!("{fillet:?}: {:?}", s.triangles_per_pair);
        // The tee stays inside the square: no vein beyond the margin.
        assert_eq!(
            pairs(&s),
            vec![RegionPair(VEIN, ABOVE), RegionPair(VEIN, BELOW), RegionPair(ABOVE, BELOW)]
        );
        // The square's border is the margin curve: 8 long.
        let margin = curve_length(&s, [BEYOND, ABOVE, BELOW]);
        assert!((margin - 8.0).abs() < 0.2, "margin {margin}");
        let (ok, wrong, total) = between_regions(&m, &r, s.epsilon);
        assert!(ok as f64 >= 0.9 * total as f64 && wrong == 0, "{ok} {wrong} {total}");
        // Heights of the vein's surfaces above the bar, away from the junction.
        let z_of = |pair: RegionPair| -> (f64, f64) {
            let mut zs = m
                .triangles
                .iter()
                .zip(&m.labels)
                .filter(|(_, l)| **l == pair)
                .flat_map(|(t, _)| t.map(|v| m.positions[v as usize]))
                .filter(|p| (p[0] + 0.4).abs() < 0.05 && (p[1] + 0.2).abs() < 0.05)
                .map(|p| p[2] as f64);
            let first = zs.next().unwrap_or(f64::NAN);
            zs.fold((first, first), |(lo, hi), z| (lo.min(z), hi.max(z)))
        };
        let (_, top) = z_of(RegionPair(VEIN, ABOVE));
        let (bottom, _) = z_of(RegionPair(VEIN, BELOW));
        eprintln!("{fillet:?}: vein from z = {bottom:.3} to {top:.3}");
        // Capped, the vein is its convolution surface away from the blade: one radius deep.
        // By the dissertation's rule it ends where Σ = |d|/r, shallower (Σ = ½ at one
        // radius): found here by bisection on the region function, and the mesh agrees.
        let depth = match rule {
            VeinRule::Capped => 0.1,
            VeinRule::Dissertation => {
                let (mut lo, mut hi) = (0.0, 0.2);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if r.region(DVec3::new(-0.4, -0.2, -mid)) == VEIN {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                assert!(lo > 0.05 && lo < 0.09, "depth {lo}");
                lo
            }
        };
        assert!((bottom + depth).abs() < 0.015, "{rule:?}: bottom {bottom}, depth {depth}");
        match fillet {
            Fillet::Both => assert!((top - depth).abs() < 0.015, "{rule:?}: top {top}"),
            // Localized: nothing above the blade is vein; its upper side is the flat blade.
            Fillet::Below => assert!(top.abs() < 0.002, "top {top}"),
        }
    }
}

#[test]
fn the_vein_region_widens_near_the_blade() {
    // The fillet: in the blade's plane the vein reaches farther from its axis than a radius.
    let (_, r) = tee_in_square(Fillet::Both);
    let at = |y: f64, z: f64| r.region(DVec3::new(-0.4, -0.2 + y, z));
    assert_eq!(at(0.0, 0.05), VEIN);
    assert_eq!(at(0.12, 0.001), VEIN, "beyond one radius, next to the blade: fillet");
    assert_eq!(at(0.12, 0.05), ABOVE);
    assert_eq!(at(0.3, 0.001), ABOVE);
    assert_eq!(at(0.3, -0.001), BELOW);
    let mut edges: BTreeMap<u32, usize> = BTreeMap::new();
    for i in 0..100 {
        *edges.entry(at(i as f64 * 0.004, 0.002)).or_default() += 1;
    }
    assert_eq!(edges.keys().copied().collect::<Vec<_>>(), vec![VEIN, ABOVE]);
}

#[test]
fn any_parameters_in_range_give_a_leaf_or_a_clear_error() {
    // Corners of the parameter ranges: never a panic; a venation whose veins would cross is
    // refused with an error that says so.
    for lobes in [1, 2, 5, 15] {
        for spread in [20.0, 200.0, 300.0] {
            for depth in [0.0, 0.9] {
                for secondaries in [1, 12] {
                    for angle in [15.0, 80.0] {
                        let p = LeafParams {
                            lobes,
                            spread,
                            lobe_depth: depth,
                            secondaries,
                            branch_angle: angle,
                            jitter: 0.05,
                            ..LeafParams::default()
                        };
                        if let Err(e) = Leaf::maple(&p) {
                            let m = e.to_string();
                            assert!(m.contains("web") || m.contains("spread"), "{p:?}: {m}");
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn maple_like_parameters_always_give_a_leaf() {
    let mut n = 0;
    for lobes in [1, 3, 5, 7] {
        for depth in [0.1, 0.45, 0.7] {
            for secondaries in [2, 3, 5] {
                for angle in [35.0, 50.0, 65.0] {
                    for seed in [1, 2] {
                        let p = LeafParams {
                            lobes,
                            spread: (40.0 * (lobes as f64 - 1.0)).min(240.0),
                            lobe_depth: depth,
                            secondaries,
                            branch_angle: angle,
                            seed,
                            ..LeafParams::default()
                        };
                        match Leaf::maple(&p) {
                            Ok(leaf) => {
                                assert!(leaf.blade.area() > 0.0);
                                n += 1;
                            }
                            Err(e) => eprintln!(
                                "FAIL lobes {lobes} depth {depth} sec {secondaries} angle {angle} seed {seed}: {e}"
                            ),
                        }
                    }
                }
            }
        }
    }
    assert_eq!(n, 216);
}

#[test]
fn the_leaf_is_the_same_on_any_number_of_threads() {
    let leaf =
        Leaf::maple(&LeafParams { lobes: 3, spread: 100.0, ..LeafParams::default() }).unwrap();
    let r = leaf.regions(Kernel::Wyvill, Fillet::Below).unwrap();
    let opts = options(&leaf, &r, 0.06);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| polygonize(&r, &opts).unwrap())
    };
    let ((a, sa), (b, _)) = (run(1), run(3));
    assert_eq!(a.positions, b.positions);
    assert_eq!(a.triangles, b.triangles);
    assert_eq!(a.labels, b.labels);
    // The localized fillet: the vein's upper side is the blade itself, so (1, 2) vertices lie
    // on the blade (within the polygonizer's accuracy), except on the short walls where a vein
    // leaves the blade at the margin (the petiole, the vein tips).
    assert!(pairs(&sa).contains(&RegionPair(VEIN, BELOW)));
    let d: Vec<f64> = a
        .triangles
        .iter()
        .zip(&a.labels)
        .filter(|(_, l)| **l == RegionPair(VEIN, ABOVE))
        .flat_map(|(t, _)| *t)
        .map(|v| {
            leaf.blade
                .distance(DVec3::from_array(a.positions[v as usize].map(f64::from)))
                .distance
                .abs()
        })
        .collect();
    let near = d.iter().filter(|&&x| x < 0.06 / 16.0).count();
    eprintln!("{near} of {} (1,2) vertices on the blade", d.len());
    assert!(near as f64 > 0.9 * d.len() as f64, "{near} of {}", d.len());
}

#[test]
fn the_smoothed_margin_still_tiles_and_passes_through_every_tip() {
    let p = LeafParams::default();
    let v = Venation::maple(&p).unwrap();
    let straight = Web::from_venation(&v).unwrap();
    let mut web = Web::from_venation_smoothed(&v, 0.5 * p.max_area.sqrt()).unwrap();
    assert!(web.points.len() > straight.points.len() + 20, "the spline adds margin points");
    web.refine(p.max_area, p.max_ratio);
    let tris = web.triangulate().unwrap();
    let pts = &web.points;
    let area = |t: &[usize; 3]| (pts[t[1]] - pts[t[0]]).perp_dot(pts[t[2]] - pts[t[0]]) / 2.0;
    assert!(tris.iter().all(|t| area(t) > 0.0));
    let mut directed: HashMap<(usize, usize), usize> = HashMap::new();
    for t in &tris {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    assert!(directed.values().all(|&c| c == 1));
    let next: HashMap<usize, usize> =
        directed.keys().filter(|(a, b)| !directed.contains_key(&(*b, *a))).copied().collect();
    // Walk the boundary loop: it holds every margin point, and encloses the triangles' area.
    let start = v.base;
    let mut loop_pts = vec![pts[start]];
    let mut on_loop = BTreeSet::from([start]);
    let mut at = next[&start];
    while at != start {
        loop_pts.push(pts[at]);
        on_loop.insert(at);
        at = next[&at];
        assert!(loop_pts.len() <= next.len());
    }
    assert_eq!(loop_pts.len(), next.len(), "one loop");
    assert!(v.margin().iter().all(|k| on_loop.contains(k)), "the spline passes through the tips");
    let enclosed = signed_area2(&loop_pts).abs() / 2.0;
    let sum: f64 = tris.iter().map(area).sum();
    assert!((sum - enclosed).abs() < 1e-9 * enclosed, "{sum} vs {enclosed}");
    eprintln!("smoothed margin: {} triangles, area {enclosed:.4}", tris.len());
}

#[test]
fn veins_and_blade_take_their_normals_from_gradients() {
    // Every vertex of the tee's blade and veins gets its normal from the region function's
    // gradient (the run used to report "0 normals from gradients" and the veins shaded
    // faceted), and the normals are smooth: neighbours on a vein agree closely, and every
    // normal agrees with its triangles' side.
    for rule in [VeinRule::Dissertation, VeinRule::Capped] {
        let (leaf, mut r) = tee_in_square(Fillet::Both);
        r.vein_rule = rule;
        let opts = options(&leaf, &r, 0.04);
        let (m, s) = polygonize(&r, &opts).unwrap();
        assert_eq!(m.normals.len(), m.positions.len());
        let used: std::collections::BTreeSet<u32> = m.triangles.iter().flatten().copied().collect();
        assert!(
            s.gradient_normals >= used.len() * 9 / 10,
            "{rule:?}: {} of {}",
            s.gradient_normals,
            used.len()
        );
        // The blade's normals are its plane's, ±z.
        let n = |v: u32| DVec3::from_array(m.normals[v as usize].map(f64::from));
        for (t, l) in m.triangles.iter().zip(&m.labels) {
            if *l == RegionPair(ABOVE, BELOW) {
                for &v in t {
                    let at = DVec3::from_array(m.positions[v as usize].map(f64::from));
                    assert!(
                        n(v).z.abs() > 0.999,
                        "{rule:?}: blade normal {} at {at}, gradient {:?}",
                        n(v),
                        r.gradient(at, (ABOVE, BELOW))
                    );
                }
            }
        }
        // On the vein's upper surface, away from where it meets the blade, the normals of a
        // triangle's corners differ by less than 25° (one cell of a tube of radius 2.5
        // cells), and face the same side as the triangle.
        let mut worst: f64 = 1.0;
        for (t, l) in m.triangles.iter().zip(&m.labels) {
            if *l != RegionPair(VEIN, ABOVE) {
                continue;
            }
            let p = t.map(|v| DVec3::from_array(m.positions[v as usize].map(f64::from)));
            if p.iter().any(|q| q.z < 0.02) {
                continue;
            }
            let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            for k in 0..3 {
                worst = worst.min(n(t[k]).dot(n(t[(k + 1) % 3])));
                assert!(n(t[k]).dot(face).abs() > 0.5, "{rule:?}: {} vs face {face}", n(t[k]));
            }
        }
        // The capped rule's surface has a kink where the cap takes over (|d|/r = ½): its
        // normals turn by up to 40° across one cell there.
        let limit: f64 = if rule == VeinRule::Capped { 40.0 } else { 25.0 };
        assert!(worst > limit.to_radians().cos(), "{rule:?}: worst corner agreement {worst}");
    }
}

#[test]
fn the_default_blade_has_about_the_dissertations_475_triangles() {
    // The dissertation's maple: 117 digitized venation points, refined and triangulated into
    // 475 triangles (§7.2, fig. 7.8). Ours: 113 points, and the default refinement makes
    // about as many triangles.
    let l = Leaf::maple(&LeafParams::default()).unwrap();
    let v = l.venation.as_ref().unwrap();
    eprintln!("{} venation points; {:?}", v.points.len(), l.stats);
    assert!((100..=130).contains(&v.points.len()), "{} points", v.points.len());
    assert_eq!(l.stats.unsplit, 0);
    let t = l.stats.triangles as f64;
    assert!((t / 475.0 - 1.0).abs() < 0.05, "{} triangles, not within 5% of 475", t);
}

#[test]
fn the_tertiary_venation_lies_in_the_blade_and_is_deterministic() {
    let p = LeafParams::default();
    let leaf = Leaf::maple(&p).unwrap();
    let tp = TextureParams::default();
    let tex = leaf.texture(&tp).unwrap();
    let t = &tex.tertiary;
    // One line per cut; the areoles are the refined polygons, so each cut added one.
    assert_eq!(t.lines.len(), leaf.web.cuts.len());
    assert_eq!(t.areoles, leaf.stats.polygons);
    assert_eq!(t.areoles, leaf.stats.web_polygons + t.lines.len());
    eprintln!("{} tertiary lines, {} areoles", t.lines.len(), t.areoles);
    assert!((100..=200).contains(&t.areoles), "{} areoles", t.areoles);
    // Every point of every line is inside the blade (the margin polygon, or on it at a cut's
    // end on the margin).
    let outline = &leaf.web.outline;
    let inside = |q: DVec2| {
        let mut c = false;
        for i in 0..outline.len() {
            let (a, b) = (outline[i], outline[(i + 1) % outline.len()]);
            if (a.y > q.y) != (b.y > q.y) && q.x < a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x) {
                c = !c;
            }
        }
        c
    };
    let on_margin = |q: DVec2| {
        (0..outline.len()).any(|i| {
            let (a, b) = (outline[i], outline[(i + 1) % outline.len()]);
            let ab = b - a;
            let s = ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            q.distance(a + ab * s) < 1e-9
        })
    };
    let mut points = 0;
    for line in &t.lines {
        assert!(line.len() > 1 << tp.levels);
        for &q in line {
            assert!(inside(q) || on_margin(q), "{q} outside the blade");
            points += 1;
        }
    }
    // Perturbed, but slightly: no point strays from its cut by more than the roughness allows.
    // A piece of length L has halves of at most q·L, q = √(¼ + roughness²), and each midpoint
    // moves at most roughness × its piece: the moves add up to at most roughness·L / (1 − q).
    let q = (0.25 + tp.roughness * tp.roughness).sqrt();
    for (line, &(a, b)) in t.lines.iter().zip(&leaf.web.cuts) {
        let (pa, pb) = (leaf.web.points[a], leaf.web.points[b]);
        let dir = (pb - pa).normalize();
        let len = pa.distance(pb);
        let worst = line.iter().map(|q| (*q - pa).perp_dot(dir).abs()).fold(0.0, f64::max);
        assert!(worst <= tp.roughness * len / (1.0 - q), "{worst} from a cut of length {len}");
    }
    eprintln!("{points} points on tertiary lines");
    // The same on every run and on any thread.
    let again =
        std::thread::spawn(move || Leaf::maple(&p).unwrap().texture(&tp).unwrap()).join().unwrap();
    assert_eq!(again.tertiary, tex.tertiary);
    // Another seed, another pattern, the same areoles.
    let other = leaf.texture(&TextureParams { seed: 2, ..TextureParams::default() }).unwrap();
    assert_ne!(other.tertiary.lines, tex.tertiary.lines);
    assert_eq!(other.tertiary.areoles, tex.tertiary.areoles);
}

#[test]
fn the_texture_colours_the_blade_between_veins_and_lightens_on_them() {
    let leaf = Leaf::maple(&LeafParams::default()).unwrap();
    let tp = TextureParams::default();
    let tex = leaf.texture(&tp).unwrap();
    // Blade vertices map back to their own plane points.
    for (k, q) in leaf.blade.vertices.iter().enumerate().step_by(5) {
        assert!(tex.plane_point(&leaf.blade, *q).distance(leaf.plane[k]) < 1e-9);
    }
    // On a tertiary line's middle: the tertiary colour (unless a vein is there too); at an
    // areole's centroid far from every line: the blade colour.
    let mid_line: Vec<DVec2> = tex.tertiary.lines.iter().map(|l| l[l.len() / 2]).collect();
    let lit = mid_line.iter().filter(|q| tex.colour(**q) == tp.tertiary).count();
    assert!(lit * 2 > mid_line.len(), "{lit} of {} line middles lit", mid_line.len());
    let plain = leaf
        .web
        .polygons
        .iter()
        .map(|p| p.iter().map(|&k| leaf.web.points[k]).sum::<DVec2>() / p.len() as f64)
        .filter(|c| tex.colour(*c) == tp.blade)
        .count();
    assert!(
        plain * 3 > leaf.web.polygons.len(),
        "{plain} of {} areole centres",
        leaf.web.polygons.len()
    );
    // On a primary vein near the base: the vein colour.
    let v = leaf.venation.as_ref().unwrap();
    let primary = &v.veins[v.primaries[v.primaries.len() / 2]];
    let q = v.points[primary.points[1]];
    assert_eq!(tex.colour(q), tp.vein);
    // Bad parameters are named.
    let e = leaf.texture(&TextureParams { roughness: 0.7, ..tp }).unwrap_err();
    assert!(e.to_string().contains("tertiary_roughness"), "{e}");
}

#[test]
fn the_texture_image_holds_the_tertiary_lines_and_blade_vertices_map_into_it() {
    let leaf = Leaf::maple(&LeafParams::default()).unwrap();
    let tp = TextureParams::default();
    let tex = leaf.texture(&tp).unwrap();
    let img = tex.image();
    // The longer side is `size`, texels square: the flat leaf's box, padded.
    assert_eq!(img.width.max(img.height), tp.size);
    img.validate().unwrap();
    // Blade vertices: texture coordinates in [0, 1], inside the border, and their flat
    // points in the same proportions (u along x, v down y).
    let uvs: Vec<[f32; 2]> = leaf.blade.vertices.iter().map(|q| tex.uv(&leaf.blade, *q)).collect();
    for uv in &uvs {
        assert!(uv.iter().all(|c| (0.005..=0.995).contains(c)), "{uv:?}");
    }
    let (i, j) = (0, leaf.plane.len() / 2);
    let (du, dv) = (uvs[j][0] - uvs[i][0], uvs[j][1] - uvs[i][1]);
    let d = leaf.plane[j] - leaf.plane[i];
    let (w, h) = (f64::from(img.width), f64::from(img.height));
    // One texel of the image is the same length across and down.
    assert!((f64::from(du) * w / d.x - -f64::from(dv) * h / d.y).abs() < 0.01 * (w / d.x).abs());
    // Texels by their nearest colour: (measured 0.40, 0.063, 0.54 at 1024 x 901) mostly
    // blade inside the margin, a few per cent on the tertiary lines (half-width 0.008 on a
    // leaf about 1.4 across), the veins and everything outside the margin in vein colour.
    let byte = |c: [f32; 3]| c.map(|x| (x * 255.0).round() as u8);
    let palette = [tp.blade, tp.tertiary, tp.vein].map(byte);
    let mut nearest = [0usize; 3];
    for t in img.rgba.chunks_exact(4) {
        let d = palette
            .map(|c| (0..3).map(|k| (i32::from(t[k]) - i32::from(c[k])).pow(2)).sum::<i32>());
        nearest[(0..3).min_by_key(|&k| d[k]).unwrap()] += 1;
    }
    let n = f64::from(img.width * img.height);
    let [blade, tertiary, vein] = nearest.map(|c| c as f64 / n);
    eprintln!(
        "{}x{}: blade {blade:.3}, tertiary {tertiary:.4}, vein {vein:.3}",
        img.width, img.height
    );
    assert!((0.15..0.6).contains(&blade), "{blade}");
    assert!((0.03..0.1).contains(&tertiary), "{tertiary}");
    assert!((0.3..0.8).contains(&vein), "{vein}");
    // The corners are outside the margin: the vein colour.
    assert_eq!(img.texel(0, 0).unwrap()[..3], byte(tp.vein));
    // Deterministic, and the size follows the parameter.
    assert_eq!(tex.image(), img);
    let small = leaf.texture(&TextureParams { size: 256, ..tp.clone() }).unwrap().image();
    assert_eq!(small.width.max(small.height), 256);
    let e = leaf.texture(&TextureParams { size: 8, ..tp }).unwrap_err();
    assert!(e.to_string().contains("texture_size"), "{e}");
}
