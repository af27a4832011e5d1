//! Issue 18, defect 6, at pinch points: where a self-intersection curve ends and its two
//! sheets fold into one (the Whitney umbrella, both ways round as in `examples/healed/`, and
//! the quartic cross-cap), the curve must be healed up
//! to the pinch point at every resolution and lattice offset: no zone left as marching
//! cubes made it, no duplicate faces, every curve edge with four triangles once welded and
//! none off the curves with more than two, the meshed curve as long as the true one (within
//! a cell and a half), the sheets split up to the pinch point (before welding no edge
//! has more than two triangles, and every curve edge two), and no folded edges (welded
//! faces more than 175° apart, as `skelform check` counts them).
//!
//! `pinch_sweep` runs a sample of resolutions (the ones that failed before, and others) at
//! four offsets; `cargo test --release -p skelform-polygonize --test healed_pinch --
//! --ignored --nocapture pinch_survey` runs every resolution from 30 to 128
//! (`SKELFORM_PINCH_SWEEP=N..=M` for others) and prints every failing case.
//!
//! Before: the cross-cap failed at 90 of the 396 cases of the survey (every one "2 sheet
//! pieces (not 4) meet the self-intersection" next to the pinch point, the whole curve left
//! as marching cubes made it), and was never split into sheets; the Whitney umbrella passed.

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec3;
use skelform_field::{Aabb, Field, FnField};
use skelform_mesh::Mesh;
use skelform_mesh::check::{check, weld};
use skelform_polygonize::healed::{Options, Stats, polygonize};
use skelform_polygonize::{LatticeOptions, Resolution};

/// The quartic cross-cap of issue 18: its crossing is the segment `x = y = 0`, `0 < z < 1`,
/// between two pinch points.
fn cross_cap(p: DVec3) -> f64 {
    let (x2, y2, z2) = (p.x * p.x, p.y * p.y, p.z * p.z);
    4.0 * x2 * (x2 + y2 + z2 + p.z) + y2 * (y2 + z2 - 1.0)
}

/// The Whitney umbrella `x² = y²z`: its crossing is the half-axis `x = y = 0`, `z > 0`,
/// from the pinch point at the origin.
fn umbrella(p: DVec3) -> f64 {
    p.x * p.x - p.y * p.y * p.z
}

/// `examples/healed/cross-cap.toml`: `x²y = z²`, the umbrella turned about, its crossing
/// the half-axis `x = z = 0`, `y > 0`, along another lattice axis.
fn turned_umbrella(p: DVec3) -> f64 {
    p.x * p.x * p.y - p.z * p.z
}

#[derive(Clone, Copy, Debug)]
enum Surface {
    CrossCap,
    Umbrella,
    TurnedUmbrella,
}

impl Surface {
    fn field(self) -> FnField<fn(DVec3) -> f64> {
        match self {
            Surface::CrossCap => FnField(cross_cap as fn(DVec3) -> f64),
            Surface::Umbrella => FnField(umbrella as fn(DVec3) -> f64),
            Surface::TurnedUmbrella => FnField(turned_umbrella as fn(DVec3) -> f64),
        }
    }

    /// The length of the crossing inside the domain (every crossing lies on an axis, from
    /// the origin on).
    fn curve_length(self, domain: &Aabb) -> f64 {
        let (lo, hi) = match self {
            Surface::CrossCap => (domain.min.z, domain.max.z.min(1.0)),
            Surface::Umbrella => (domain.min.z, domain.max.z),
            Surface::TurnedUmbrella => (domain.min.y, domain.max.y),
        };
        (hi - lo.max(0.0)).max(0.0)
    }
}

/// Polygonizes on `[-1, 1]³` shifted by `offset` cells, at `samples` samples a side.
fn heal(field: &dyn Field, samples: usize, offset: DVec3) -> (Mesh, Stats, Aabb) {
    let h = 2.0 / (samples - 1) as f64;
    let domain = Aabb::new(DVec3::splat(-1.0) + offset * h, DVec3::splat(1.0) + offset * h);
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Samples(samples), ..Default::default() };
    let (m, s) = polygonize(field, &Options { lattice, ..Options::default() }).expect("healed");
    (m, s, domain)
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

/// Triangles on each edge.
fn edge_degrees(m: &Mesh) -> BTreeMap<(u32, u32), usize> {
    let mut degree: BTreeMap<(u32, u32), usize> = BTreeMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *degree.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    degree
}

/// What must hold, as words (empty when it does).
fn violations(surface: Surface, samples: usize, offset: DVec3) -> Vec<String> {
    let (m, s, domain) = heal(&surface.field(), samples, offset);
    let h = s.cell;
    let w = &weld(&m, 0.0).0;
    let mut out = Vec::new();
    // Split sheets: before welding, every sheet is its own surface ending on the curve, up to
    // the pinch point, where the sheets become one: no edge has more than two triangles and
    // every curve edge (on one sheet's copies) has two.
    let unwelded = edge_degrees(&m);
    let over = unwelded.values().filter(|d| **d > 2).count();
    if over > 0 {
        out.push(format!("{over} edges with more than two triangles before welding"));
    }
    let curve_not_two = m
        .curves
        .iter()
        .filter(|c| unwelded.get(&(c.v[0].min(c.v[1]), c.v[0].max(c.v[1]))) != Some(&2))
        .count();
    if curve_not_two > 0 {
        out.push(format!("{curve_not_two} curve edges without two triangles before welding"));
    }
    for c in &s.curves {
        if !c.healed {
            out.push(format!("a curve of length {:.3} not healed", c.length));
        }
    }
    for u in &s.unresolved {
        out.push(format!("not healed ({} cubes): {}", u.cubes, u.reason));
    }
    let d = duplicate_faces(w);
    if d > 0 {
        out.push(format!("{d} duplicate faces"));
    }
    // No two welded faces turned back on each other (more than 175° apart).
    let folded = check(w).folded_edges;
    if folded > 0 {
        out.push(format!("{folded} folded edges"));
    }
    let degree = edge_degrees(w);
    let curves: BTreeSet<(u32, u32)> =
        w.curves.iter().map(|c| (c.v[0].min(c.v[1]), c.v[0].max(c.v[1]))).collect();
    let bad_curve = curves.iter().filter(|e| degree.get(e).copied().unwrap_or(0) != 4).count();
    if bad_curve > 0 {
        out.push(format!("{bad_curve} curve edges without four triangles"));
    }
    let stray = degree.iter().filter(|(e, d)| **d > 2 && !curves.contains(e)).count();
    if stray > 0 {
        out.push(format!("{stray} edges off the curves with more than two triangles"));
    }
    // The meshed crossing: its edges' length against the true segment's.
    let meshed: f64 = w
        .curves
        .iter()
        .map(|c| {
            let (a, b) = (w.positions[c.v[0] as usize], w.positions[c.v[1] as usize]);
            let (a, b) = (DVec3::from(a.map(f64::from)), DVec3::from(b.map(f64::from)));
            (a - b).length()
        })
        .sum();
    let truth = surface.curve_length(&domain);
    if (meshed - truth).abs() > 1.5 * h {
        out.push(format!("curve edges {meshed:.4} long, the crossing {truth:.4}"));
    }
    out
}

/// Lattice offsets (fractions of a cell) of the sweeps.
const OFFSETS: [[f64; 3]; 4] =
    [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [0.31, 0.17, 0.43], [0.77, 0.61, 0.09]];

/// Sweeps `surface` over resolutions and offsets, every failing case as a line.
fn sweep(surface: Surface, samples: impl Iterator<Item = usize>) -> Vec<String> {
    let mut failures = Vec::new();
    for n in samples {
        for o in OFFSETS {
            let v = violations(surface, n, DVec3::from(o));
            if !v.is_empty() {
                failures.push(format!("{surface:?} {n} samples, offset {o:?}: {}", v.join("; ")));
            }
        }
    }
    failures
}

/// Resolutions of the survey: `SKELFORM_PINCH_SWEEP=30..=128` (the default) or `N..=M`.
fn survey_range() -> std::ops::RangeInclusive<usize> {
    let s = std::env::var("SKELFORM_PINCH_SWEEP").unwrap_or_else(|_| "30..=128".into());
    let (a, b) = s.split_once("..=").unwrap_or(("30", "128"));
    a.parse().unwrap_or(30)..=b.parse().unwrap_or(128)
}

/// The sweep run with the tests: resolutions where the cross-cap failed before (at 32, 35,
/// 41, 61, 84, 100 and 123 samples, at one offset or another) and others, at four offsets.
#[test]
fn pinch_sweep() {
    let samples = [30, 32, 35, 41, 48, 61, 84, 100, 123];
    let mut all = sweep(Surface::CrossCap, samples.into_iter());
    all.extend(sweep(Surface::Umbrella, samples.into_iter()));
    all.extend(sweep(Surface::TurnedUmbrella, samples.into_iter()));
    assert!(all.is_empty(), "{all:#?}");
}

/// Every resolution and offset of the survey; prints the failing cases.
///
/// Folded edges were only counted here before the bands were re-zipped where they fold
/// (`zone.rs`, `Band::rezip`): 1–4 per mesh in 40 of the 108 cases of `pinch_sweep`, in
/// the fans round the curve's nodes next to a pinch point (a trace in the lattice plane of
/// the node, running straight away from it, fanned from it in slivers) and where a trace
/// passes within a cell of the pinch point.
#[test]
#[ignore = "a survey: every resolution from 30 to 128 at four offsets; run by hand"]
fn pinch_survey() {
    let mut all = Vec::new();
    for surface in [Surface::CrossCap, Surface::Umbrella, Surface::TurnedUmbrella] {
        let f = sweep(surface, survey_range());
        // Printed per surface: the whole survey takes minutes.
        for l in &f {
            println!("FAIL {l}");
        }
        all.extend(f);
    }
    println!("{} failures", all.len());
    assert!(all.is_empty());
}
