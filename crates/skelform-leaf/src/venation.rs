//! The venation skeleton (dissertation §7.1): a tree of veins drawn in the plane of the leaf.
//!
//! The dissertation digitized 117 points of a Northwest Maple by hand; those points are not in
//! the text, so [`Venation::maple`] grows a palmate (maple-like) venation of its own from a
//! few parameters. The data structure is the chapter's: a tree-structured graph of points;
//! primary veins leave the leaf base and are ordered clockwise round the petiole; each vein
//! keeps its left and right descendant veins in separate lists, ordered by distance from the
//! vein's base. That ordering is what makes the margin a simple traversal
//! ([`Venation::margin`]) and the polygonal web possible ([`crate::web`]).
//!
//! Every point carries a curvature (default 0, flat). A few points are given one (the tips of
//! the primary veins), the others take the average of their assigned neighbours, and the
//! leaf gets its third dimension by wrapping each point onto a sphere through the leaf base
//! whose radius is 1/curvature ([`wrap`]).

use glam::{DVec2, DVec3};

use crate::LeafError;
use crate::rng::Rng;

/// Which kind of vein.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VeinKind {
    /// The stalk below the leaf base; it is outside the blade.
    Petiole,
    /// A vein that leaves the leaf base.
    Primary,
    /// A vein that branches from another vein.
    Secondary,
}

/// One vein: a chain of points from where it leaves its parent (or the leaf base) to its tip.
#[derive(Clone, Debug, PartialEq)]
pub struct Vein {
    /// Petiole, primary or secondary: sets the vein's radius on the generated leaf.
    pub kind: VeinKind,
    /// Point ids, base first; the first point is shared with the parent vein's chain.
    pub points: Vec<usize>,
    /// The vein (index into [`Venation::veins`]) this one branches from; `None` for primaries
    /// and the petiole.
    pub parent: Option<usize>,
    /// Descendant veins on the left (looking from the base to the tip), nearest the base first.
    pub left: Vec<usize>,
    /// Descendant veins on the right, nearest the base first.
    pub right: Vec<usize>,
}

/// A venation: points in the plane (the leaf base at the origin, the leaf along +y), the tree
/// over them, and the veins.
#[derive(Clone, Debug, PartialEq)]
pub struct Venation {
    /// Point positions in the leaf's plane, in scene units, indexed by point id; the leaf base is
    /// at the origin.
    pub points: Vec<DVec2>,
    /// Curvature (1/radius of the sphere the point is wrapped onto); 0 is flat.
    pub curvature: Vec<f64>,
    /// The tree: each point's parent point, `None` for the leaf base.
    pub parent: Vec<Option<usize>>,
    /// Every vein (primaries, their descendants, the petiole), indexed by vein id.
    pub veins: Vec<Vein>,
    /// Primary veins, clockwise round the petiole (seen from +z).
    pub primaries: Vec<usize>,
    /// The petiole's vein id; `None` when [`LeafParams::petiole`] is 0.
    pub petiole: Option<usize>,
    /// The leaf base, where the primaries meet (point id).
    pub base: usize,
}

/// Parameters of the generated maple-like leaf. Lengths are in the units of the scene;
/// angles in degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct LeafParams {
    /// Length of the longest primary vein.
    pub size: f64,
    /// Number of primary veins (lobes).
    pub lobes: usize,
    /// Angle between the two outermost primary veins.
    pub spread: f64,
    /// How far the sinuses between lobes cut in, as a fraction of the lobe's length (0: no
    /// lobes, 0.9: deep).
    pub lobe_depth: f64,
    /// Outer lobes are shorter: a lobe at the edge of the fan is `1 − outer_shortening` of the
    /// longest.
    pub outer_shortening: f64,
    /// Secondary veins on each side of each primary (the one nearest the base runs into the
    /// sinus).
    pub secondaries: usize,
    /// Angle at which secondaries leave their primary.
    pub branch_angle: f64,
    /// Length of the petiole (0: none).
    pub petiole: f64,
    /// Curvature at the tips of the primary veins, in units of 1/size (0: a flat leaf;
    /// positive cups the leaf upwards, towards +z).
    pub curvature: f64,
    /// Relative random variation of the primaries' curvature (0 to 1).
    pub curvature_jitter: f64,
    /// Random displacement of vein points, as a fraction of `size`; teeth on the margin.
    pub jitter: f64,
    /// Seed of the perturbations: the same seed, the same leaf.
    pub seed: u64,
    /// Radius of the primary veins at the leaf base (and of the petiole).
    pub vein_radius: f64,
    /// Radius at a primary's tip, as a fraction of `vein_radius` (veins taper).
    pub tip_radius: f64,
    /// Radius of secondary veins where they leave their primary; 0 leaves them out of the
    /// vein volume (they still shape the blade), as in the dissertation.
    pub secondary_radius: f64,
    /// Smooth the margin with natural splines through the vein tips (§7.6, note 1) instead of
    /// straight sides.
    pub smooth_margin: bool,
    /// Web refinement: largest polygon area, as a fraction of `size²`, from [`MIN_MAX_AREA`]
    /// to 1.
    pub max_area: f64,
    /// Web refinement: largest perimeter/area ratio, in units of 1/size.
    pub max_ratio: f64,
}

impl Default for LeafParams {
    fn default() -> Self {
        LeafParams {
            size: 1.0,
            lobes: 5,
            spread: 200.0,
            lobe_depth: 0.45,
            outer_shortening: 0.4,
            secondaries: 3,
            branch_angle: 50.0,
            petiole: 0.4,
            curvature: 0.6,
            curvature_jitter: 0.3,
            jitter: 0.015,
            seed: 1,
            vein_radius: 0.03,
            tip_radius: 0.35,
            secondary_radius: 0.0,
            smooth_margin: true,
            // About the dissertation's 475 blade triangles (§7.2, fig. 7.8) for a venation of
            // about its 117 points.
            max_area: 0.012,
            max_ratio: 45.0,
        }
    }
}

/// The smallest `max_area` [`LeafParams::check`] accepts, as a fraction of `size²`.
pub const MIN_MAX_AREA: f64 = 1e-5;

impl LeafParams {
    /// Checks every parameter; the error names the first bad one.
    pub fn check(&self) -> Result<(), LeafError> {
        let bad =
            |name, value: f64, expected| Err(LeafError::BadParameter { name, value, expected });
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.size) {
            return bad("size", self.size, "a positive length");
        }
        if !(1..=15).contains(&self.lobes) {
            return bad("lobes", self.lobes as f64, "a whole number from 1 to 15");
        }
        if !(self.spread.is_finite() && (0.0..=300.0).contains(&self.spread)) {
            return bad("spread", self.spread, "an angle from 0 to 300 degrees");
        }
        if self.lobes > 1 && self.spread / (self.lobes - 1) as f64 <= 5.0 {
            return bad("spread", self.spread, "at least 5 degrees per gap between lobes");
        }
        if !(self.lobe_depth.is_finite() && (0.0..=0.9).contains(&self.lobe_depth)) {
            return bad("lobe_depth", self.lobe_depth, "a fraction from 0 to 0.9");
        }
        if !(self.outer_shortening.is_finite() && (0.0..=0.8).contains(&self.outer_shortening)) {
            return bad("outer_shortening", self.outer_shortening, "a fraction from 0 to 0.8");
        }
        if !(1..=12).contains(&self.secondaries) {
            return bad("secondaries", self.secondaries as f64, "a whole number from 1 to 12");
        }
        if !(self.branch_angle.is_finite() && (15.0..=80.0).contains(&self.branch_angle)) {
            return bad("branch_angle", self.branch_angle, "an angle from 15 to 80 degrees");
        }
        if !(self.petiole.is_finite() && self.petiole >= 0.0) {
            return bad("petiole", self.petiole, "a length of 0 or more");
        }
        if !(self.curvature.is_finite() && self.curvature.abs() <= 2.5) {
            return bad("curvature", self.curvature, "a number from -2.5 to 2.5");
        }
        if !(self.curvature_jitter.is_finite() && (0.0..=1.0).contains(&self.curvature_jitter)) {
            return bad("curvature_jitter", self.curvature_jitter, "a fraction from 0 to 1");
        }
        if !(self.jitter.is_finite() && (0.0..=0.05).contains(&self.jitter)) {
            return bad("jitter", self.jitter, "a fraction from 0 to 0.05");
        }
        if !pos(self.vein_radius) {
            return bad("vein_radius", self.vein_radius, "a positive length");
        }
        if !(self.tip_radius.is_finite() && self.tip_radius > 0.0 && self.tip_radius <= 1.0) {
            return bad("tip_radius", self.tip_radius, "a fraction above 0 and at most 1");
        }
        if !(self.secondary_radius.is_finite() && self.secondary_radius >= 0.0) {
            return bad("secondary_radius", self.secondary_radius, "a length of 0 or more");
        }
        // About 1/max_area polygons, and the margin sampled at steps of its square root:
        // below 1e-5 the refinement would pass its cap of polygons anyway, and ever smaller
        // values made loading take minutes (1e-8) or overflow the margin's sample count.
        if !(self.max_area.is_finite() && (MIN_MAX_AREA..=1.0).contains(&self.max_area)) {
            return bad("max_area", self.max_area, "a fraction of size² from 1e-5 to 1");
        }
        if !(self.max_ratio.is_finite() && self.max_ratio >= 10.0) {
            return bad("max_ratio", self.max_ratio, "a number of at least 10 (1/size)");
        }
        Ok(())
    }
}

/// A point on the plane at `angle` (radians, clockwise from +y) and distance `r` from the base.
fn polar(angle: f64, r: f64) -> DVec2 {
    DVec2::new(angle.sin(), angle.cos()) * r
}

impl Venation {
    /// A palmate, maple-like venation (see [`LeafParams`]).
    ///
    /// Construction: the primaries fan out from the base; the margin is first laid out as a
    /// polar curve with one lobe per primary (the sinus between two lobes at their bisector,
    /// `1 − lobe_depth` of the way out); each margin point is the tip of a straight secondary
    /// vein leaving its lobe's primary at `branch_angle` (or steeper, where that would leave
    /// from too near the base or the tip), so tips nearer the lobe's point leave the primary
    /// farther from the base. Secondaries of one side are then parallel or fan from one point,
    /// and each stays in its lobe's wedge, so veins do not cross for any parameters in the
    /// usual range (tested on a grid of them); a venation whose veins would cross anyway is
    /// refused ([`LeafError::BadWeb`]).
    pub fn maple(p: &LeafParams) -> Result<Venation, LeafError> {
        p.check()?;
        let mut rng = Rng::new(p.seed);
        let n = p.lobes;
        let spread = p.spread.to_radians();
        let half_gap = if n > 1 { spread / (2.0 * (n - 1) as f64) } else { 60f64.to_radians() };
        let beta = p.branch_angle.to_radians();
        let sinus = 1.0 - p.lobe_depth;
        let m = p.secondaries;
        let mut v = Venation {
            points: vec![DVec2::ZERO],
            curvature: vec![0.0],
            parent: vec![None],
            veins: Vec::new(),
            primaries: Vec::new(),
            petiole: None,
            base: 0,
        };
        // Lobe k: its angle, length and the margin tips on each side as (angle, radius).
        for k in 0..n {
            let theta =
                if n > 1 { -spread / 2.0 + spread * k as f64 / (n - 1) as f64 } else { 0.0 };
            let rel = if n > 1 && spread > 0.0 { theta / (spread / 2.0) } else { 0.0 };
            let len = p.size * (1.0 - p.outer_shortening * rel * rel);
            let u = polar(theta, 1.0);
            let lateral_left = DVec2::new(-u.y, u.x);
            // The margin's radius at an angle off the primary: the lobe profile.
            let profile = |off: f64| {
                len * (sinus + (1.0 - sinus) * (1.0 - off / half_gap).max(0.0).powf(0.7))
            };
            // Tips on the left (counter-clockwise side) from the sinus out, then the right.
            let mut sides: [Vec<(f64, f64)>; 2] = [Vec::new(), Vec::new()];
            for j in 0..m {
                let off = half_gap * (1.0 - j as f64 / m as f64);
                sides[0].push((theta - off, profile(off)));
                // The sinus on the right belongs to the next lobe, except for the last lobe.
                if j > 0 || k == n - 1 {
                    sides[1].push((theta + off, profile(off)));
                }
            }
            // The primary's chain: where its secondaries leave it, plus regular samples.
            let mut branches: Vec<(f64, DVec2, usize)> = Vec::new(); // (distance, tip, side)
            for (side, tips) in sides.iter().enumerate() {
                // Tips run from the sinus towards the lobe's point; their veins must leave the
                // primary in that order too (a vein that left earlier would cross the others).
                let mut last_a = 0.0f64;
                for &(angle, r) in tips {
                    let r = r * (1.0 + 2.0 * p.jitter * rng.symmetric());
                    let tip = polar(angle, r);
                    let x = tip.dot(u);
                    let y = tip.dot(lateral_left).abs();
                    // Leave the primary at the branch angle, but always before the tip's
                    // foot on it, so the vein runs outwards.
                    let hi = 0.85 * x.max(0.0);
                    let a = (x - y / beta.tan())
                        .clamp((0.08 * len).min(0.5 * hi), hi.max(1e-9 * len))
                        .max(last_a);
                    last_a = a;
                    branches.push((a, tip, side));
                }
            }
            let mut stops: Vec<f64> = branches.iter().map(|b| b.0).collect();
            for i in 1..=4 {
                stops.push(len * i as f64 / 4.0);
            }
            stops.sort_by(f64::total_cmp);
            let mut chain_d: Vec<f64> = Vec::new();
            for d in stops {
                if chain_d.last().is_none_or(|&l| d - l > 0.03 * len) {
                    chain_d.push(d);
                } else if let Some(l) = chain_d.last_mut() {
                    // Keep the later stop when two are close, so the tip stays the tip.
                    if d >= len * 0.999 {
                        *l = d;
                    }
                }
            }
            let mut chain = vec![v.base];
            for (i, &d) in chain_d.iter().enumerate() {
                let last = i + 1 == chain_d.len();
                let wobble = if last { 0.0 } else { 0.3 * p.jitter * p.size * rng.symmetric() };
                let pt = u * d + lateral_left * wobble;
                chain.push(v.add_point(pt, *chain.last().unwrap_or(&0)));
            }
            let tip_curv = p.curvature / p.size * (1.0 + p.curvature_jitter * rng.symmetric());
            if let Some(&t) = chain.last() {
                v.curvature[t] = tip_curv;
            }
            let primary = v.veins.len();
            v.veins.push(Vein {
                kind: VeinKind::Primary,
                points: chain.clone(),
                parent: None,
                left: Vec::new(),
                right: Vec::new(),
            });
            v.primaries.push(primary);
            for (a, tip, side) in branches {
                // The chain point nearest the branch distance.
                let at = chain_d
                    .iter()
                    .enumerate()
                    .take(chain_d.len().saturating_sub(1).max(1))
                    .min_by(|x, y| (x.1 - a).abs().total_cmp(&(y.1 - a).abs()))
                    .map_or(0, |(i, _)| i + 1);
                let start = chain[at];
                let s0 = v.points[start];
                // Straight: the secondaries of one side then leave the primary at one angle
                // (parallel) or fan from one point, and cannot cross one another; each stays
                // in its lobe's wedge, so it cannot cross a neighbour lobe's veins either.
                let mut pts = vec![start];
                for t in [1.0 / 3.0, 2.0 / 3.0, 1.0] {
                    let q = s0.lerp(tip, t);
                    let prev = *pts.last().unwrap_or(&start);
                    pts.push(v.add_point(q, prev));
                }
                let id = v.veins.len();
                v.veins.push(Vein {
                    kind: VeinKind::Secondary,
                    points: pts,
                    parent: Some(primary),
                    left: Vec::new(),
                    right: Vec::new(),
                });
                if side == 0 {
                    v.veins[primary].left.push(id);
                } else {
                    v.veins[primary].right.push(id);
                }
            }
        }
        if p.petiole > 0.0 {
            let mut pts = vec![v.base];
            for i in 1..=3 {
                let q = DVec2::new(0.0, -p.petiole * i as f64 / 3.0);
                let prev = *pts.last().unwrap_or(&0);
                pts.push(v.add_point(q, prev));
            }
            v.petiole = Some(v.veins.len());
            v.veins.push(Vein {
                kind: VeinKind::Petiole,
                points: pts,
                parent: None,
                left: Vec::new(),
                right: Vec::new(),
            });
        }
        v.sort_descendants();
        v.spread_curvature();
        Ok(v)
    }

    fn add_point(&mut self, p: DVec2, parent: usize) -> usize {
        self.points.push(p);
        self.curvature.push(0.0);
        self.parent.push(Some(parent));
        self.points.len() - 1
    }

    /// Orders every vein's left and right descendants by distance from the vein's base; veins
    /// that leave from the same point are ordered by how far they turn from the parent (the
    /// one that turns most, towards the parent's base, first).
    fn sort_descendants(&mut self) {
        for i in 0..self.veins.len() {
            let chain = self.veins[i].points.clone();
            let key = |id: usize| -> (usize, f64) {
                let w = &self.veins[id];
                let at = chain.iter().position(|&c| c == w.points[0]).unwrap_or(0);
                let (a, tip) =
                    (self.points[w.points[0]], self.points[*w.points.last().unwrap_or(&0)]);
                let next = self.points[chain[(at + 1).min(chain.len() - 1)]];
                let prev = self.points[chain[at.saturating_sub(1)]];
                let dir = (next - prev).normalize_or_zero();
                let turn = dir.angle_to(tip - a).abs();
                (at, -turn)
            };
            let mut sorted: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
            for (side, out) in sorted.iter_mut().enumerate() {
                let mut list = if side == 0 {
                    self.veins[i].left.clone()
                } else {
                    self.veins[i].right.clone()
                };
                list.sort_by(|&a, &b| {
                    let (ka, kb) = (key(a), key(b));
                    ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
                });
                *out = list;
            }
            let [l, r] = sorted;
            self.veins[i].left = l;
            self.veins[i].right = r;
        }
    }

    /// Points without a curvature take the average of their neighbours' non-zero curvatures,
    /// pass after pass outwards from the points that have one (§7.1). The petiole stays flat.
    fn spread_curvature(&mut self) {
        let n = self.points.len();
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
        let petiole: Vec<usize> =
            self.petiole.map(|v| self.veins[v].points[1..].to_vec()).unwrap_or_default();
        for (i, par) in self.parent.iter().enumerate() {
            if let Some(j) = *par
                && !petiole.contains(&i)
            {
                neighbours[i].push(j);
                neighbours[j].push(i);
            }
        }
        let mut set: Vec<bool> = self.curvature.iter().map(|&c| c != 0.0).collect();
        for &i in &petiole {
            set[i] = true;
        }
        loop {
            let mut changed = Vec::new();
            for i in 0..n {
                if set[i] {
                    continue;
                }
                let vals: Vec<f64> = neighbours[i]
                    .iter()
                    .filter(|&&j| set[j] && self.curvature[j] != 0.0)
                    .map(|&j| self.curvature[j])
                    .collect();
                if !vals.is_empty() {
                    changed.push((i, vals.iter().sum::<f64>() / vals.len() as f64));
                }
            }
            if changed.is_empty() {
                break;
            }
            for (i, c) in changed {
                self.curvature[i] = c;
                set[i] = true;
            }
        }
    }

    /// The tip (last point) of a vein.
    pub fn tip(&self, vein: usize) -> usize {
        *self.veins[vein].points.last().unwrap_or(&self.base)
    }

    /// The margin: the leaf base, then, for each primary in clockwise order, its left
    /// descendants' margins in order, its tip, and its right descendants' margins in reverse
    /// order (§7.2). A clockwise loop of vein tips seen from +z.
    pub fn margin(&self) -> Vec<usize> {
        fn visit(v: &Venation, vein: usize, out: &mut Vec<usize>) {
            for &l in &v.veins[vein].left {
                visit(v, l, out);
            }
            out.push(v.tip(vein));
            for &r in v.veins[vein].right.iter().rev() {
                visit(v, r, out);
            }
        }
        let mut out = vec![self.base];
        for &p in &self.primaries {
            visit(self, p, &mut out);
        }
        out
    }

    /// The points from `p` up the tree to the base, `p` first.
    pub fn path_to_base(&self, mut p: usize) -> Vec<usize> {
        let mut out = vec![p];
        while let Some(q) = self.parent[p] {
            out.push(q);
            p = q;
            if out.len() > self.points.len() {
                break; // a cycle: not a tree (cannot happen for a built venation)
            }
        }
        out
    }

    /// The polygon that two adjacent margin points enclose with their vein paths to their
    /// common ancestor: `a`, up to the ancestor, down to `b` (§7.2).
    pub fn web_polygon(&self, a: usize, b: usize) -> Vec<usize> {
        let pa = self.path_to_base(a);
        let pb = self.path_to_base(b);
        let common = pa.iter().position(|x| pb.contains(x)).unwrap_or(pa.len() - 1);
        let ancestor = pa[common];
        let jb = pb.iter().position(|&x| x == ancestor).unwrap_or(pb.len() - 1);
        let mut poly: Vec<usize> = pa[..=common].to_vec();
        poly.extend(pb[..jb].iter().rev());
        poly
    }

    /// Counts of veins by kind: (primary, secondary, petiole).
    pub fn counts(&self) -> (usize, usize, usize) {
        let c = |k| self.veins.iter().filter(|v| v.kind == k).count();
        (c(VeinKind::Primary), c(VeinKind::Secondary), c(VeinKind::Petiole))
    }
}

/// Wraps a point of the leaf's plane onto a sphere through the leaf base (the origin),
/// tangent to the plane there, of radius `1/curvature`: the point keeps its distance from the
/// base along the sphere (§7.1, "rotated so that it rested upon a sphere"). Positive
/// curvature bends upwards (+z); 0 leaves the point where it is.
pub fn wrap(p: DVec2, curvature: f64) -> DVec3 {
    let rho = p.length();
    if rho == 0.0 {
        return DVec3::ZERO;
    }
    let k = curvature;
    let a = k * rho;
    // sin(a)/k and (1 − cos a)/k, written so that they stay exact as k → 0.
    let (along, up) = if a.abs() < 1e-6 {
        (rho * (1.0 - a * a / 6.0), rho * a / 2.0)
    } else {
        (a.sin() / k, (1.0 - a.cos()) / k)
    };
    let d = p / rho;
    DVec3::new(d.x * along, d.y * along, up)
}
