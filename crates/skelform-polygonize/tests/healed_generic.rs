//! Issue 18, defect 6: healing of generic (off-symmetry) transversal crossings must not depend
//! on where the lattice falls. Random sphere pairs, sphere × torus and tilted plane × sphere,
//! over resolutions and lattice offsets: every crossing healed (no zone left as marching
//! cubes made it), no duplicate faces, and the sheets meet along the curve as the healed
//! method promises (every curve edge has four triangles, no other edge more than two).
//!
//! The sweeps run 12 cases each from a fixed seed; `SKELFORM_HEAL_SWEEP_CASES=300
//! SKELFORM_HEAL_SWEEP_SEED=random cargo test --release -p skelform-polygonize --test
//! healed_generic -- --ignored --nocapture sweep_failure_rates` counts the failures of each
//! sweep over a fresh draw and prints every failing case (as a `Case` to paste into a test).
//! The issue's reproducers (two spheres at 40-100 samples, the cross-cap at 41-81) and the
//! failures the sweeps found run as they are.
//!
//! The sphere × torus draws used to fail at about 2% (7, 8 and 2 of 300 at seeds 7, 8 and 9:
//! the sphere near the tube's inner side), in plain marching cubes as much as in healing:
//! tunnel ring vertices collapsed onto cell corners. They pass now, at 0 of 300 for each
//! seed (see `plain_mc33_tunnel_rings_stay_apart_on_sphere_torus` and
//! `sphere_torus_draws_with_collapsed_rings_heal`).

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use skelform_field::{Aabb, Field, FnField};
use skelform_mesh::Mesh;
use skelform_mesh::check::weld;
use skelform_polygonize::healed::{Options, Stats, polygonize};
use skelform_polygonize::{LatticeOptions, Resolution};

/// Polygonizes on `[-1.6, 1.6]³` shifted by `offset` cells, at `samples` samples a side.
fn heal(field: &dyn Field, samples: usize, offset: DVec3) -> (Mesh, Stats) {
    let h = 3.2 / (samples - 1) as f64;
    let domain = Aabb::new(DVec3::splat(-1.6) + offset * h, DVec3::splat(1.6) + offset * h);
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Samples(samples), ..Default::default() };
    polygonize(field, &Options { lattice, ..Options::default() }).expect("healed")
}

/// Triangles that have the same three vertices as an earlier one (either winding).
fn duplicate_faces(m: &Mesh) -> usize {
    let mut seen = BTreeSet::new();
    m.triangles
        .iter()
        .filter(|t| {
            let mut k = **t;
            k.sort_unstable();
            !seen.insert(k)
        })
        .count()
}

/// What the healed method promises along a crossing, once the sheets' copies of the curve
/// vertices are welded, as words (empty when it holds).
fn violations(m: &Mesh, s: &Stats) -> Vec<String> {
    let m = &weld(m, 0.0).0;
    let mut out = Vec::new();
    if s.curves.is_empty() {
        out.push("no self-intersection curve found".into());
    }
    for c in &s.curves {
        if !c.healed {
            out.push(format!("a curve of length {:.3} not healed", c.length));
        }
    }
    for u in &s.unresolved {
        out.push(format!("not healed ({} cubes): {}", u.cubes, u.reason));
    }
    let d = duplicate_faces(m);
    if d > 0 {
        out.push(format!("{d} duplicate faces"));
    }
    let mut degree: BTreeMap<(u32, u32), usize> = BTreeMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *degree.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let curves: BTreeSet<(u32, u32)> =
        m.curves.iter().map(|c| (c.v[0].min(c.v[1]), c.v[0].max(c.v[1]))).collect();
    let bad_curve = curves.iter().filter(|e| degree.get(e).copied().unwrap_or(0) != 4).count();
    if bad_curve > 0 {
        out.push(format!("{bad_curve} curve edges without four triangles"));
    }
    let stray = degree.iter().filter(|(e, d)| **d > 2 && !curves.contains(e)).count();
    if stray > 0 {
        out.push(format!("{stray} edges off the curves with more than two triangles"));
    }
    out
}

fn sphere(c: DVec3, r: f64) -> impl Fn(DVec3) -> f64 {
    move |p: DVec3| (p - c).length_squared() - r * r
}

/// Cases per sweep: 12 in the normal test run (a few seconds), more with
/// `SKELFORM_HEAL_SWEEP_CASES` (e.g. 500 for a search).
fn sweep_cases() -> u32 {
    std::env::var("SKELFORM_HEAL_SWEEP_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(12)
}

/// The sweeps' seed: fixed in the normal test run, so that the test command gives the same
/// verdict on every run (random draws still meet the marching-cubes-33 tunnels named at the
/// top); `SKELFORM_HEAL_SWEEP_SEED=N` for another fixed seed, `=random` for a search.
fn sweep_seed() -> RngSeed {
    match std::env::var("SKELFORM_HEAL_SWEEP_SEED").ok().as_deref() {
        Some("random") => RngSeed::Random,
        Some(n) => RngSeed::Fixed(n.parse().unwrap_or(SEED)),
        None => RngSeed::Fixed(SEED),
    }
}

const SEED: u64 = 20261204;

/// A lattice offset: a fraction of a cell along each axis.
fn offset() -> impl Strategy<Value = DVec3> {
    (0.0..1.0f64, 0.0..1.0f64, 0.0..1.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

/// The issue's reproducers: two spheres crossing off the lattice's symmetry.
#[test]
fn issue_reproducers_two_spheres() {
    let f = FnField(|p: DVec3| {
        sphere(DVec3::ZERO, 1.0)(p) * sphere(DVec3::new(0.7, 0.0, 0.0), 0.5f64.sqrt())(p)
    });
    let mut failures = Vec::new();
    for n in [40, 50, 64, 80, 100] {
        let (m, s) = heal(&f, n, DVec3::ZERO);
        let v = violations(&m, &s);
        if !v.is_empty() {
            failures.push(format!("{n} samples: {}", v.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The issue's other reproducer: two equal spheres crossing in a circle whose centre is
/// shifted 0.03 off the lattice's axes.
#[test]
fn issue_reproducers_equal_spheres_off_axis() {
    let f = FnField(|p: DVec3| {
        sphere(DVec3::new(-0.5, 0.03, 0.03), 1.0)(p) * sphere(DVec3::new(0.5, 0.03, 0.03), 1.0)(p)
    });
    let mut failures = Vec::new();
    for n in [40, 50, 64, 80] {
        let (m, s) = heal(&f, n, DVec3::ZERO);
        let v = violations(&m, &s);
        if !v.is_empty() {
            failures.push(format!("{n} samples: {}", v.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// One generated case of the sweeps: a field with a transversal self-intersection, and the
/// lattice it is polygonized on.
#[derive(Clone, Debug)]
enum Case {
    /// Two spheres of radii `r1`, `r2` whose centres are `gap` apart along `dir`, centred
    /// at `shift`.
    SpherePair { r1: f64, r2: f64, t: f64, dir: DVec3, shift: DVec3, samples: usize, off: DVec3 },
    /// A torus (R = 0.8, r = 0.3) and a sphere round its tube: the sphere's centre is in the
    /// plane `y = 0` at `(cx, 0, cz)`, its radius `0.3 + d + margin` with `d` the distance
    /// to the tube's centre circle, so that it holds that cross-section of the tube and
    /// crosses the tube in two loops. (At `margin = 0` the sphere touches the torus: the two
    /// loops meet in a tangential point, which is not a transversal crossing.)
    SphereTorus { margin: f64, cx: f64, cz: f64, samples: usize, off: DVec3 },
    /// A plane with unit normal `n` at distance `d` from the origin through a sphere of
    /// radius `r` at the origin.
    PlaneSphere { n: DVec3, d: f64, r: f64, samples: usize, off: DVec3 },
}

impl Case {
    fn run(&self) -> Vec<String> {
        let (samples, off) = match *self {
            Case::SpherePair { samples, off, .. }
            | Case::SphereTorus { samples, off, .. }
            | Case::PlaneSphere { samples, off, .. } => (samples, off),
        };
        let f = self.field();
        let (m, s) = heal(&f, samples, off);
        violations(&m, &s)
    }

    fn field(&self) -> FnField<Box<dyn Fn(DVec3) -> f64 + Send + Sync>> {
        match *self {
            Case::SpherePair { r1, r2, t, dir, shift, .. } => {
                let d = dir.normalize_or(DVec3::X);
                let gap = (r1 - r2).abs() + t * (r1 + r2 - (r1 - r2).abs());
                let c1 = shift - d * (0.5 * gap);
                let (a, b) = (sphere(c1, r1), sphere(c1 + d * gap, r2));
                FnField(Box::new(move |p: DVec3| a(p) * b(p)))
            }
            Case::SphereTorus { margin, cx, cz, .. } => {
                let (big, small) = (0.8f64, 0.3f64);
                let rs = small + (cx - big).hypot(cz) + margin;
                let s = sphere(DVec3::new(cx, 0.0, cz), rs);
                FnField(Box::new(move |p: DVec3| torus(p) * s(p)))
            }
            Case::PlaneSphere { n, d, r, .. } => {
                let n = n.normalize();
                let s = sphere(DVec3::ZERO, r);
                FnField(Box::new(move |p: DVec3| (n.dot(p) - d) * s(p)))
            }
        }
    }
}

/// The torus of the sphere × torus sweep: R = 0.8, r = 0.3 round the z axis.
fn torus(p: DVec3) -> f64 {
    let (big, small) = (0.8f64, 0.3f64);
    let q = p.length_squared() + big * big - small * small;
    q * q - 4.0 * big * big * (p.x * p.x + p.y * p.y)
}

fn vec3(lo: f64, hi: f64) -> impl Strategy<Value = DVec3> {
    (lo..hi, lo..hi, lo..hi).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

/// Two spheres of radius 0.6–1 whose centres are 0.45–0.85 of the way from touching inside
/// to touching outside (so they cross at an angle the lattice resolves), anywhere on the
/// lattice.
fn sphere_pairs() -> impl Strategy<Value = Case> {
    (0.6..1.0f64, 0.6..1.0f64, 0.45..0.85f64, vec3(-1.0, 1.0), vec3(-0.1, 0.1), 36usize..72)
        .prop_flat_map(|(r1, r2, t, dir, shift, samples)| {
            offset().prop_map(move |off| Case::SpherePair { r1, r2, t, dir, shift, samples, off })
        })
}

/// Sphere × torus, the sphere's margin 0.05–0.35 but at least 1.5 cells: between its two
/// loops the sphere is a sleeve round the tube at most `margin` from it, and two sheets
/// closer than the lattice resolves are not resolved there even without the crossing
/// (margins under a cell fail: the zone takes in the gap, and the sheet pieces between the
/// two loops, bounded by both, are not bands along one curve).
fn sphere_tori() -> impl Strategy<Value = Case> {
    (0.05..0.35f64, 0.5..0.9f64, -0.15..0.15f64, 40usize..72, offset())
        .prop_filter("the sleeve's gap is resolved (1.5 cells)", |(margin, _, _, samples, _)| {
            *margin >= 1.5 * 3.2 / (*samples - 1) as f64
        })
        .prop_map(|(margin, cx, cz, samples, off)| Case::SphereTorus {
            margin,
            cx,
            cz,
            samples,
            off,
        })
}

/// A plane tilted off every lattice axis through a sphere of radius 0.7–1.1.
fn plane_spheres() -> impl Strategy<Value = Case> {
    ((-1.0..1.0f64, -1.0..1.0f64, 0.2..1.0f64), -0.5..0.5f64, 0.7..1.1f64, 36usize..72, offset())
        .prop_map(|(n, d, r, samples, off)| Case::PlaneSphere {
            n: DVec3::new(n.0, n.1, n.2),
            d,
            r,
            samples,
            off,
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: sweep_cases(),
        rng_seed: sweep_seed(),
        ..ProptestConfig::default()
    })]

    #[test]
    fn sphere_pairs_heal(case in sphere_pairs()) {
        let v = case.run();
        prop_assert!(v.is_empty(), "{v:?}");
    }

    #[test]
    fn sphere_torus_heal(case in sphere_tori()) {
        let v = case.run();
        prop_assert!(v.is_empty(), "{v:?}");
    }

    #[test]
    fn tilted_plane_sphere_heal(case in plane_spheres()) {
        let v = case.run();
        prop_assert!(v.is_empty(), "{v:?}");
    }
}

/// The failure rate of each sweep over `SKELFORM_HEAL_SWEEP_CASES` cases (default 12) from
/// `SKELFORM_HEAL_SWEEP_SEED` (default fixed, `random` for a new draw), every failing case
/// printed: the proptests stop at the first failure, this counts them all. Run with
/// `--ignored --nocapture`; `SKELFORM_HEAL_SWEEP_ONLY=torus` runs only the sweeps whose
/// name contains that word (the same cases as in a full run).
#[test]
#[ignore = "a survey: run by hand with SKELFORM_HEAL_SWEEP_CASES"]
fn sweep_failure_rates() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, TestRunner};
    let n = sweep_cases();
    let config = Config { rng_seed: sweep_seed(), ..Config::default() };
    let mut runner = TestRunner::new(config);
    let sweeps: [(&str, BoxedStrategy<Case>); 3] = [
        ("sphere pairs", sphere_pairs().boxed()),
        ("sphere x torus", sphere_tori().boxed()),
        ("tilted plane x sphere", plane_spheres().boxed()),
    ];
    // Every sweep draws its cases, so that a sweep left out does not change the others'.
    let only = std::env::var("SKELFORM_HEAL_SWEEP_ONLY").ok();
    let mut total = 0;
    for (name, strategy) in sweeps {
        let run = only.as_deref().is_none_or(|o| name.contains(o));
        let mut failed = 0;
        for _ in 0..n {
            let case = strategy.new_tree(&mut runner).expect("a case").current();
            if !run {
                continue;
            }
            let v = case.run();
            if !v.is_empty() {
                failed += 1;
                println!("FAIL {name}: {case:?}: {v:?}");
            }
        }
        if run {
            println!("RATE {name}: {failed} of {n} failed");
        }
        total += failed;
    }
    assert_eq!(total, 0, "failures (above)");
}

/// The issue's cross-cap, `4x²(x²+y²+z²+z)+y²(y²+z²-1)` on `[-1, 1]³`: its crossing segment
/// ends in two pinch points. Healed at 41 and 81 samples, not at 48, 50, 60 or 64.
#[test]
fn issue_reproducers_cross_cap() {
    let f = FnField(|p: DVec3| {
        let (x2, y2, z2) = (p.x * p.x, p.y * p.y, p.z * p.z);
        4.0 * x2 * (x2 + y2 + z2 + p.z) + y2 * (y2 + z2 - 1.0)
    });
    let mut failures = Vec::new();
    for n in [41, 48, 50, 60, 64, 81] {
        let lattice = LatticeOptions {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Samples(n),
            ..Default::default()
        };
        let (m, s) = polygonize(&f, &Options { lattice, ..Options::default() }).expect("healed");
        let v = violations(&m, &s);
        if !v.is_empty() {
            failures.push(format!("{n} samples: {}", v.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Found by the sweep at 300 cases: two spheres at 38 samples, where a lattice point lies
/// 2e-6 inside one sphere and a tenth of a cell outside the other, next to their circle.
/// The zone's boundary face there has four crossings and no saddle (the two sheets cross
/// just beyond it), so the contour decides the pairing; it left the face within 3e-5 cells
/// of that corner, and the side it was taken to leave through was the wrong one of the two
/// meeting there, so the face was passed as agreeing with the decider, the boundary's trace
/// joined two sheet pieces through the thin wedge, and the circle got two bands, not four.
/// The exit side is now the side whose crossing is nearest the contour's last step.
#[test]
fn sphere_pair_whose_wedge_tip_holds_a_lattice_point() {
    let case = Case::SpherePair {
        r1: 0.9059414330515698,
        r2: 0.8136454845823808,
        t: 0.49633522776121347,
        dir: DVec3::new(-0.03839578597141715, -0.8533840908944873, -0.506249347884339),
        shift: DVec3::new(-0.022423169265741675, -0.04722052726647596, -0.0736758812994316),
        samples: 38,
        off: DVec3::new(0.3976219454842843, 0.7244441322160805, 0.9757165298123658),
    };
    let v = case.run();
    assert!(v.is_empty(), "{v:?}");
}

/// A torus whose bottom circle lies in a lattice plane (to 3e-5 cells), crossed by a sphere
/// in two loops 0.6 apart (9 cells). The tangency is not a transversal crossing: marching
/// cubes misses the pairs of crossings the plane's edges hide along it, in and out of the
/// zones alike, and it is left so. It must not break the loops' healing: those hidden pairs
/// have nearly the same normal at both crossings (one sheet grazing the edge), so the zones
/// do not grow along the tangency (they used to, joining the two loops' zones, and a trace
/// then ran from one loop to the other).
#[test]
fn torus_bottom_in_a_lattice_plane_heals_both_loops() {
    let case = Case::SphereTorus {
        margin: 0.08,
        cx: 0.7570491779597691,
        cz: 0.0,
        samples: 48,
        off: DVec3::new(0.40952043848373465, 0.0, 0.09395872037464897),
    };
    let Case::SphereTorus { samples, off, .. } = case else { unreachable!() };
    let (m, s) = heal(&case.field(), samples, off);
    let v = violations(&m, &s);
    assert!(v.is_empty(), "{v:?}");
    assert_eq!(s.curves.len(), 2, "two loops");
    assert!(s.curves.iter().all(|c| c.closed && c.healed));
}

/// Plain marching cubes on one of the sphere × torus draws the survey failed (7, 8 and 2 of
/// 300 at seeds 7, 8 and 9, the same in plain marching cubes on the same lattice): the
/// crossing makes marching-cubes-33 tubes, whose ring vertices Newton steps along the
/// gradient, clamped to the cell, used to carry onto one corner of the cell, where they
/// coincided and their triangles collapsed (duplicate faces, edges of three or more
/// triangles once welded). Ring vertices now move on their rays from the tube's saddle.
#[test]
fn plain_mc33_tunnel_rings_stay_apart_on_sphere_torus() {
    let case = Case::SphereTorus {
        margin: 0.31345430729437646,
        cx: 0.5138865977829211,
        cz: -0.07410269307158217,
        samples: 44,
        off: DVec3::new(0.886671823023391, 0.11998854472270927, 0.25339820708802396),
    };
    let f = case.field();
    let Case::SphereTorus { samples, off, .. } = case else { unreachable!() };
    let h = 3.2 / (samples - 1) as f64;
    let domain = Aabb::new(DVec3::splat(-1.6) + off * h, DVec3::splat(1.6) + off * h);
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Samples(samples), ..Default::default() };
    let o = skelform_polygonize::grid::Options { lattice, ..Default::default() };
    let (m, stats) = skelform_polygonize::grid::polygonize(&f, &o).expect("grid");
    assert!(stats.tunnels > 0, "the case must make tubes");
    let w = &weld(&m, 0.0).0;
    let mut degree: BTreeMap<(u32, u32), usize> = BTreeMap::new();
    for t in &w.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *degree.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let stray = degree.values().filter(|d| **d > 2).count();
    assert_eq!((duplicate_faces(w), stray), (0, 0));
    assert!(case.run().is_empty(), "{:?}", case.run());
}

/// Every sphere × torus draw the survey failed at seeds 7, 8 and 9 (300 cases each: 7, 8
/// and 2 failures) before ring vertices moved on their rays: duplicate faces and edges of
/// three triangles where tunnel rings collapsed, in and out of the healed zones.
#[test]
fn sphere_torus_draws_with_collapsed_rings_heal() {
    #[rustfmt::skip]
    let cases: [(f64, f64, f64, usize, [f64; 3]); 17] = [
        (0.1977833717709877, 0.5092833958879568, -0.13682931144560237, 61, [0.4410487964368668, 0.5869173572783529, 0.6141060957969787]),
        (0.16218160210474244, 0.5156677008993967, 0.13322351336366361, 45, [0.14277253306875004, 0.37726138584869756, 0.47786362326974846]),
        (0.18072741596499198, 0.6311483716990013, 0.14358789723581888, 42, [0.17508377787755852, 0.32258744472614403, 0.0986056634135911]),
        (0.31345430729437646, 0.5138865977829211, -0.07410269307158217, 44, [0.886671823023391, 0.11998854472270927, 0.25339820708802396]),
        (0.20390811811851772, 0.5020287159494442, 0.1275071803933726, 71, [0.0645132300587969, 0.8408763744233908, 0.8832126598598969]),
        (0.0995665346126543, 0.5830148700936794, -0.05038738403523374, 58, [0.37869903537657557, 0.6166401800738421, 0.09876086951366919]),
        (0.29148920103318354, 0.5982822457551851, -0.08488581344123095, 42, [0.7579261023227853, 0.7392725482656486, 0.46285237176945865]),
        (0.24205682728059316, 0.6397052654240286, -0.04724183341715476, 57, [0.5967758355334727, 0.5710543516153337, 0.06352715500782397]),
        (0.10932001472348493, 0.6220161150982357, 0.1110815462591446, 68, [0.3965219891423643, 0.819076727255503, 0.5904282179248297]),
        (0.3088080684801513, 0.5706301623670362, -0.028245871087638257, 41, [0.45058910220437043, 0.698913598730797, 0.7386344858746372]),
        (0.30170972842789173, 0.6974750472585379, -0.020241222475332533, 57, [0.5576039568003481, 0.6393606030269228, 0.16552081051400552]),
        (0.3260572689720313, 0.7651304722703555, -0.006871311731517343, 48, [0.7919811844629207, 0.6517253291308704, 0.9856453248341921]),
        (0.11690738602408289, 0.7474739473058553, -0.009987685342841337, 53, [0.827757466114471, 0.44566408975825633, 0.9292950588119134]),
        (0.20974052461243736, 0.6598633916292794, -0.02082961692977752, 71, [0.9591209098852848, 0.11991680562485557, 0.20485414128794732]),
        (0.19513360352681508, 0.5256739610257121, 0.08734008268741537, 62, [0.5128378862642525, 0.7460701607319195, 0.25687979039797204]),
        (0.2581862485887549, 0.5291727747624394, -0.03238226929646992, 63, [0.054273935734253244, 0.29548502542329497, 0.5511760952589853]),
        (0.10832663954937384, 0.5347563135287368, 0.04091230570494767, 62, [0.3757256733822518, 0.7349667554499408, 0.10526284127862234]),
    ];
    let mut failures = Vec::new();
    for (margin, cx, cz, samples, off) in cases {
        let case = Case::SphereTorus { margin, cx, cz, samples, off: DVec3::from_array(off) };
        let v = case.run();
        if !v.is_empty() {
            failures.push(format!("{case:?}: {v:?}"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
