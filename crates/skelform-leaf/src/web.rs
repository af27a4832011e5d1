//! The polygonal web and its triangulation (dissertation §7.2).
//!
//! Two adjacent margin points are joined along the margin and, through the veins, by their
//! paths to a common ancestor: each such circuit is a polygon, and together they tile the
//! blade ("polygonal web"). Because every polygon side between two vein points is a piece of
//! vein, the veins lie on triangle edges of the blade, even after the leaf is bent.
//!
//! The web's polygons are too large for the bending (creases), so each is split recursively,
//! across its long axis (a cut parallel to its narrow axis), until its area is below
//! `max_area` and its perimeter/area below `max_ratio` (thin pieces are cut only while
//! cutting makes them less thin, and pieces below an eighth of `max_area` are left alone, so
//! that the sharp corner where two veins meet is not cut forever); a cut that is not wholly
//! inside a concave polygon is rotated until one is, and a cut that would end near a corner
//! ends at that corner. A cut's ends land on polygon sides shared with
//! neighbours; those sides are split for the neighbours too, so the mesh has no T-junctions.
//! Finally each polygon is triangulated by cutting off, again and again, the ear with the
//! shortest diagonal between semi-adjacent vertices, rejecting ears that contain another
//! vertex.

use std::collections::HashMap;

use glam::DVec2;

use crate::LeafError;
use crate::venation::Venation;

/// A web of polygons over shared points in the plane.
#[derive(Clone, Debug, Default)]
pub struct Web {
    /// Point positions in the leaf's plane, in scene units: the venation's points first, then
    /// those added by margin smoothing and by refinement cuts.
    pub points: Vec<DVec2>,
    /// Per point, the curvature it is wrapped with ([`crate::wrap`]); added points interpolate
    /// their neighbours'.
    pub curvature: Vec<f64>,
    /// Counter-clockwise polygons (point ids).
    pub polygons: Vec<Vec<usize>>,
    /// Sides split by a cut: (lo, hi) → the point inserted between them.
    splits: HashMap<(usize, usize), usize>,
    /// The refinement's cuts, in the order made: the two point ids at a cut's ends. Later
    /// cuts may end on an earlier one, splitting it ([`Web::refined_chain`] gives its
    /// pieces). The tertiary venation texture (§7.4) grows from these lines.
    pub cuts: Vec<(usize, usize)>,
    /// The blade's margin, a closed loop of points in the plane (before refinement; cuts do
    /// not move it).
    pub outline: Vec<DVec2>,
}

/// Statistics of a web's construction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WebStats {
    /// Polygons of the web before refinement (one per pair of adjacent margin points).
    pub web_polygons: usize,
    /// Polygons after refinement.
    pub polygons: usize,
    /// Polygons left larger than asked because no cut inside them was found.
    pub unsplit: usize,
    /// Triangles of the blade after ear cutting; the size of the mesh to be searched for
    /// distances.
    pub triangles: usize,
}

/// Twice the signed area of a polygon (positive counter-clockwise).
pub fn signed_area2(pts: &[DVec2]) -> f64 {
    let n = pts.len();
    (0..n).map(|i| pts[i].perp_dot(pts[(i + 1) % n])).sum()
}

fn key(a: usize, b: usize) -> (usize, usize) {
    if a < b { (a, b) } else { (b, a) }
}

impl Web {
    /// The venation's web: one polygon per adjacent pair of margin points.
    pub fn from_venation(v: &Venation) -> Result<Web, LeafError> {
        Web::build(v, None)
    }

    /// The same with a smooth margin (§7.6, note 1): natural cubic splines run from each
    /// convex margin point through the concave ones after it to the next convex one, and each
    /// margin side gets points of its spline about `step` apart. A side whose spline would
    /// cross its polygon's veins stays straight.
    pub fn from_venation_smoothed(v: &Venation, step: f64) -> Result<Web, LeafError> {
        Web::build(v, Some(step))
    }

    fn build(v: &Venation, smooth: Option<f64>) -> Result<Web, LeafError> {
        let margin = v.margin();
        let n = margin.len();
        let mut web = Web {
            points: v.points.clone(),
            curvature: v.curvature.clone(),
            polygons: Vec::new(),
            splits: HashMap::new(),
            cuts: Vec::new(),
            outline: Vec::new(),
        };
        let samples: Vec<Vec<DVec2>> = match smooth {
            Some(step) if step > 0.0 => {
                let pts: Vec<DVec2> = margin.iter().map(|&k| v.points[k]).collect();
                margin_splines(&pts, step)
            }
            _ => vec![Vec::new(); n],
        };
        let mut outline: Vec<DVec2> = Vec::new();
        for i in 0..n {
            let (a, b) = (margin[i], margin[(i + 1) % n]);
            let path = v.web_polygon(a, b);
            // The margin side runs from b back to a: its spline points in that order.
            let mut poly = path.clone();
            let mut extra = Vec::new();
            for q in samples[i].iter().rev() {
                let t = (q.distance(v.points[a])
                    / (q.distance(v.points[a]) + q.distance(v.points[b])).max(1e-300))
                .clamp(0.0, 1.0);
                extra.push((*q, v.curvature[a] + (v.curvature[b] - v.curvature[a]) * t));
            }
            let mut with: Vec<DVec2> = path.iter().map(|&k| v.points[k]).collect();
            with.extend(extra.iter().map(|e| e.0));
            let keep = !extra.is_empty() && simple(&with);
            outline.push(v.points[a]);
            if keep {
                outline.extend(extra.iter().rev().map(|e| e.0));
                for (q, c) in extra {
                    web.points.push(q);
                    web.curvature.push(c);
                    poly.push(web.points.len() - 1);
                }
            }
            let pts: Vec<DVec2> = poly.iter().map(|&k| web.points[k]).collect();
            let area2 = signed_area2(&pts);
            if poly.len() < 3
                || area2.abs()
                    < 1e-12 * v.points.iter().map(|p| p.length_squared()).fold(0.0, f64::max)
            {
                return Err(LeafError::BadWeb(format!(
                    "the polygon between margin points {a} and {b} has no area"
                )));
            }
            if area2 < 0.0 {
                poly.reverse();
            }
            web.polygons.push(poly);
        }
        if !simple(&outline) {
            return Err(LeafError::BadWeb("the margin crosses itself".into()));
        }
        web.check_tiling(&outline)?;
        web.outline = outline;
        Ok(web)
    }

    /// A single flat polygon (a blade given by its outline).
    pub fn from_outline(outline: &[DVec2]) -> Result<Web, LeafError> {
        if outline.len() < 3 {
            return Err(LeafError::TooFewPoints(outline.len()));
        }
        let mut poly: Vec<usize> = (0..outline.len()).collect();
        let a2 = signed_area2(outline);
        if a2 == 0.0 || !a2.is_finite() || !simple(outline) {
            return Err(LeafError::BadOutline);
        }
        if a2 < 0.0 {
            poly.reverse();
        }
        Ok(Web {
            points: outline.to_vec(),
            curvature: vec![0.0; outline.len()],
            polygons: vec![poly],
            splits: HashMap::new(),
            cuts: Vec::new(),
            outline: outline.to_vec(),
        })
    }

    /// The polygons' areas must add up to the area inside the margin, and each polygon must be
    /// simple: otherwise veins cross each other or the margin.
    fn check_tiling(&self, outline: &[DVec2]) -> Result<(), LeafError> {
        let total = signed_area2(outline).abs();
        let sum: f64 = self
            .polygons
            .iter()
            .map(|p| signed_area2(&p.iter().map(|&k| self.points[k]).collect::<Vec<_>>()))
            .sum();
        for (i, p) in self.polygons.iter().enumerate() {
            let pts: Vec<DVec2> = p.iter().map(|&k| self.points[k]).collect();
            if !simple(&pts) {
                return Err(LeafError::BadWeb(format!("polygon {i} crosses itself (veins cross)")));
            }
        }
        if (sum - total).abs() > 1e-9 * total.max(1e-300) {
            return Err(LeafError::BadWeb(format!(
                "polygon areas add up to {:.6} but the margin encloses {:.6}",
                sum / 2.0,
                total / 2.0
            )));
        }
        Ok(())
    }

    /// A polygon with every split side expanded into its pieces.
    fn expanded(&self, poly: &[usize]) -> Vec<usize> {
        fn side(w: &Web, a: usize, b: usize, out: &mut Vec<usize>) {
            if let Some(&m) = w.splits.get(&key(a, b)) {
                side(w, a, m, out);
                out.push(m);
                side(w, m, b, out);
            }
        }
        let mut out = Vec::with_capacity(poly.len());
        for i in 0..poly.len() {
            out.push(poly[i]);
            side(self, poly[i], poly[(i + 1) % poly.len()], &mut out);
        }
        out
    }

    /// Splits polygons until each has area below `max_area` and perimeter/area below
    /// `max_ratio` (or cannot be cut); returns how many could not be cut.
    pub fn refine(&mut self, max_area: f64, max_ratio: f64) -> usize {
        let mut todo: Vec<Vec<usize>> = std::mem::take(&mut self.polygons);
        todo.reverse();
        let mut done = Vec::new();
        let mut unsplit = 0;
        while let Some(poly) = todo.pop() {
            let poly = self.expanded(&poly);
            let pts: Vec<DVec2> = poly.iter().map(|&k| self.points[k]).collect();
            let area = signed_area2(&pts) / 2.0;
            let perimeter: f64 =
                (0..pts.len()).map(|i| pts[i].distance(pts[(i + 1) % pts.len()])).sum();
            // A thin polygon cut across its long axis gets shorter, not wider: once it is about
            // as long as it is wide, the ratio is as low as cutting can make it.
            let (long, narrow) = extents(&pts);
            let elongated = long > 2.0 * narrow;
            // Small pieces are left alone whatever their shape: a sharp corner (two veins leaving
            // one point) is a wedge at every scale, and cutting it would never end.
            let small = area < max_area / 8.0;
            if area < max_area && (perimeter / area < max_ratio || !elongated || small) {
                done.push(poly);
                continue;
            }
            if todo.len() + done.len() > MAX_POLYGONS {
                unsplit += 1;
                done.push(poly);
                continue;
            }
            match self.cut(&poly) {
                Some((a, b)) => {
                    // Depth first, in a fixed order: deterministic.
                    todo.push(b);
                    todo.push(a);
                }
                None => {
                    unsplit += 1;
                    done.push(poly);
                }
            }
        }
        self.polygons = done.into_iter().map(|p| self.expanded(&p)).collect();
        unsplit
    }

    /// Cuts a polygon in two along a chord across its long axis; `None` if no chord at any
    /// rotation lies inside it.
    fn cut(&mut self, poly: &[usize]) -> Option<(Vec<usize>, Vec<usize>)> {
        let pts: Vec<DVec2> = poly.iter().map(|&k| self.points[k]).collect();
        let n = pts.len();
        let area = signed_area2(&pts) / 2.0;
        // Area centroid and second moments about it.
        let mut c = DVec2::ZERO;
        for i in 0..n {
            let (p, q) = (pts[i], pts[(i + 1) % n]);
            c += (p + q) * p.perp_dot(q);
        }
        c /= 6.0 * area;
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let (p, q) = (pts[i] - c, pts[(i + 1) % n] - c);
            let l = p.distance(q);
            // Perimeter moments: robust for thin and concave polygons alike.
            let m = (p + q) * 0.5;
            sxx += l * m.x * m.x;
            syy += l * m.y * m.y;
            sxy += l * m.x * m.y;
        }
        let long_angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        let scale = pts.iter().map(|p| p.distance(c)).fold(0.0, f64::max);
        for step in 0u32..17 {
            // 0, +10°, −10°, +20°, … up to ±80°.
            let k: f64 = step.div_ceil(2) as f64 * if step % 2 == 1 { 1.0 } else { -1.0 };
            let angle = long_angle + std::f64::consts::FRAC_PI_2 + (10.0 * k).to_radians();
            let dir = DVec2::new(angle.cos(), angle.sin());
            if let Some(r) = self.chord(poly, &pts, c, dir, scale) {
                return Some(r);
            }
        }
        None
    }

    /// The chord of `poly` along the line `c + t·dir` nearest `c`, and the two pieces.
    fn chord(
        &mut self,
        poly: &[usize],
        pts: &[DVec2],
        c: DVec2,
        dir: DVec2,
        scale: f64,
    ) -> Option<(Vec<usize>, Vec<usize>)> {
        let n = pts.len();
        let normal = dir.perp();
        let side: Vec<f64> = pts.iter().map(|p| (*p - c).dot(normal)).collect();
        // A line through (or almost through) a vertex is degenerate: rotate instead.
        if side.iter().any(|s| s.abs() < 1e-6 * scale) {
            return None;
        }
        let mut hits: Vec<(f64, usize, f64)> = Vec::new(); // (t along the line, side, s along it)
        for i in 0..n {
            let (s0, s1) = (side[i], side[(i + 1) % n]);
            if (s0 < 0.0) != (s1 < 0.0) {
                let s = s0 / (s0 - s1);
                let q = pts[i].lerp(pts[(i + 1) % n], s);
                hits.push(((q - c).dot(dir), i, s));
            }
        }
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        if hits.len() < 2 || hits.len() % 2 == 1 {
            return None;
        }
        // Inside chords are consecutive pairs; take the one nearest the centroid.
        let (mut best, mut best_d) = (0, f64::INFINITY);
        for k in (0..hits.len()).step_by(2) {
            let (t0, t1) = (hits[k].0, hits[k + 1].0);
            let d = if t0 <= 0.0 && 0.0 <= t1 { 0.0 } else { t0.abs().min(t1.abs()) };
            if d < best_d {
                (best, best_d) = (k, d);
            }
        }
        let (h0, h1) = (hits[best], hits[best + 1]);
        let chord = (h1.0 - h0.0).abs();
        // Each end: an existing corner when the crossing is near one (no sliver triangles, and
        // short sides such as a smoothed margin's can still be cut), else a new point.
        #[derive(Clone, Copy)]
        enum End {
            Corner(usize),
            New { side: usize, s: f64 },
        }
        let end = |h: (f64, usize, f64)| {
            let len = pts[h.1].distance(pts[(h.1 + 1) % n]);
            if h.2 * len < 0.15 * chord {
                End::Corner(h.1)
            } else if (1.0 - h.2) * len < 0.15 * chord {
                End::Corner((h.1 + 1) % n)
            } else {
                End::New { side: h.1, s: h.2 }
            }
        };
        let ends = [end(h0), end(h1)];
        let at = |e: End| match e {
            End::Corner(k) => pts[k],
            End::New { side, s } => pts[side].lerp(pts[(side + 1) % n], s),
        };
        let (p0, p1) = (at(ends[0]), at(ends[1]));
        // The chord must lie inside: it may touch the boundary only at its own ends.
        let touches_end = |k: usize, e: End| match e {
            End::Corner(c) => k == c || (k + 1) % n == c,
            End::New { side, .. } => k == side,
        };
        for k in 0..n {
            if touches_end(k, ends[0]) || touches_end(k, ends[1]) {
                continue;
            }
            if segments_touch(p0, p1, pts[k], pts[(k + 1) % n]) {
                return None;
            }
        }
        // Positions in a ring with the new points inserted, then the two pieces.
        let mut ring: Vec<Option<usize>> = Vec::with_capacity(n + 2); // None: a new point
        let mut pos = [usize::MAX; 2];
        for (k, &corner) in poly.iter().enumerate() {
            for (j, e) in ends.iter().enumerate() {
                if let End::Corner(c) = e
                    && *c == k
                {
                    pos[j] = ring.len();
                }
            }
            ring.push(Some(corner));
            for (j, e) in ends.iter().enumerate() {
                if let End::New { side, .. } = e
                    && *side == k
                {
                    pos[j] = ring.len();
                    ring.push(None);
                }
            }
        }
        if let (End::New { side: a, .. }, End::New { side: b, .. }) = (ends[0], ends[1])
            && a == b
        {
            return None; // both ends on one side
        }
        if !contains(pts, (p0 + p1) * 0.5) {
            return None; // a chord from a reflex corner that leaves the polygon
        }
        let (i0, i1) = (pos[0].min(pos[1]), pos[0].max(pos[1]));
        let m = ring.len();
        if i1 - i0 < 2 || m - (i1 - i0) < 2 {
            return None; // the chord would be a side
        }
        // Commit: create the new points, then cut the ring.
        let mut ids = [usize::MAX; 2];
        for (j, e) in ends.iter().enumerate() {
            if let End::New { side, s } = *e {
                ids[j] = self.split_side(poly[side], poly[(side + 1) % n], s);
            }
        }
        let mut resolved: Vec<usize> = Vec::with_capacity(m);
        for (idx, x) in ring.iter().enumerate() {
            resolved.push(match x {
                Some(k) => *k,
                None => {
                    if idx == pos[0] {
                        ids[0]
                    } else {
                        ids[1]
                    }
                }
            });
        }
        self.cuts.push((resolved[pos[0]], resolved[pos[1]]));
        let a: Vec<usize> = resolved[i0..=i1].to_vec();
        let mut b: Vec<usize> = resolved[i1..].to_vec();
        b.extend_from_slice(&resolved[..=i0]);
        Some((a, b))
    }

    /// Inserts a point on side (a, b) at fraction `s` from `a`, with interpolated curvature.
    fn split_side(&mut self, a: usize, b: usize, s: f64) -> usize {
        let p = self.points[a].lerp(self.points[b], s);
        let k = self.curvature[a] + (self.curvature[b] - self.curvature[a]) * s;
        self.points.push(p);
        self.curvature.push(k);
        let m = self.points.len() - 1;
        self.splits.insert(key(a, b), m);
        m
    }

    /// The chain from `a` to `b` with every point later inserted on its sides (for veins,
    /// which must follow the blade's edges).
    pub fn refined_chain(&self, chain: &[usize]) -> Vec<usize> {
        let mut out = Vec::new();
        fn side(w: &Web, a: usize, b: usize, out: &mut Vec<usize>) {
            if let Some(&m) = w.splits.get(&key(a, b)) {
                side(w, a, m, out);
                out.push(m);
                side(w, m, b, out);
            }
        }
        for w in chain.windows(2) {
            out.push(w[0]);
            side(self, w[0], w[1], &mut out);
        }
        if let Some(&l) = chain.last() {
            out.push(l);
        }
        out
    }

    /// Triangulates every polygon (counter-clockwise triangles).
    pub fn triangulate(&self) -> Result<Vec<[usize; 3]>, LeafError> {
        let mut out = Vec::new();
        for (i, p) in self.polygons.iter().enumerate() {
            if !ear_cut(&self.points, p, &mut out) {
                return Err(LeafError::Triangulation(i));
            }
        }
        Ok(out)
    }
}

/// Natural cubic splines through the margin (a closed loop of points, clockwise): one from
/// each convex point through the following concave points to the next convex point, zero
/// curvature at both ends. Returns, for each side (point i to i + 1), the spline's points
/// strictly between its ends, about `step` apart.
fn margin_splines(pts: &[DVec2], step: f64) -> Vec<Vec<DVec2>> {
    let n = pts.len();
    let mut out = vec![Vec::new(); n];
    // Clockwise loop: a convex (outer) corner turns right.
    let convex: Vec<usize> = (0..n)
        .filter(|&i| {
            let (p, m, q) = (pts[(i + n - 1) % n], pts[i], pts[(i + 1) % n]);
            (m - p).perp_dot(q - m) < 0.0
        })
        .collect();
    if convex.len() < 2 {
        return out;
    }
    for (k, &start) in convex.iter().enumerate() {
        let end = convex[(k + 1) % convex.len()];
        let len = (end + n - start) % n;
        if len == 0 {
            continue;
        }
        let run: Vec<DVec2> = (0..=len).map(|j| pts[(start + j) % n]).collect();
        // Chord-length parameters and the natural spline's second derivatives (tridiagonal).
        let h: Vec<f64> = run.windows(2).map(|w| w[0].distance(w[1]).max(1e-300)).collect();
        let m = run.len();
        let mut second = vec![DVec2::ZERO; m];
        if m > 2 {
            let (mut diag, mut rhs) = (vec![0.0; m], vec![DVec2::ZERO; m]);
            let mut sub = vec![0.0; m];
            for i in 1..m - 1 {
                sub[i] = h[i - 1];
                diag[i] = 2.0 * (h[i - 1] + h[i]);
                rhs[i] = 6.0 * ((run[i + 1] - run[i]) / h[i] - (run[i] - run[i - 1]) / h[i - 1]);
            }
            // Thomas algorithm over rows 1..m−1 (the ends are zero).
            for i in 2..m - 1 {
                let w = sub[i] / diag[i - 1];
                diag[i] -= w * h[i - 1];
                rhs[i] = rhs[i] - rhs[i - 1] * w;
            }
            for i in (1..m - 1).rev() {
                let next = if i + 1 < m - 1 { second[i + 1] } else { DVec2::ZERO };
                second[i] = (rhs[i] - next * h[i]) / diag[i];
            }
        }
        for i in 0..m - 1 {
            let count = (h[i] / step).floor() as usize;
            let side = (start + i) % n;
            for j in 1..=count {
                let t = j as f64 / (count + 1) as f64;
                let (a, b) = (1.0 - t, t);
                let q = run[i] * a
                    + run[i + 1] * b
                    + (second[i] * (a * a * a - a) + second[i + 1] * (b * b * b - b))
                        * (h[i] * h[i] / 6.0);
                out[side].push(q);
            }
        }
    }
    out
}

/// Most polygons refinement may make (a guard against limits too small for the blade).
const MAX_POLYGONS: usize = 200_000;

/// Extents of a polygon along its principal axes: (long, narrow).
fn extents(pts: &[DVec2]) -> (f64, f64) {
    let c = pts.iter().copied().sum::<DVec2>() / pts.len() as f64;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = *p - c;
        sxx += d.x * d.x;
        syy += d.y * d.y;
        sxy += d.x * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (u, w) = (DVec2::new(angle.cos(), angle.sin()), DVec2::new(-angle.sin(), angle.cos()));
    let span = |axis: DVec2| {
        let (lo, hi) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
            let t = p.dot(axis);
            (l.min(t), h.max(t))
        });
        hi - lo
    };
    let (a, b) = (span(u), span(w));
    (a.max(b), a.min(b))
}

/// Whether `q` is inside a closed polygon (crossing number).
pub(crate) fn contains(pts: &[DVec2], q: DVec2) -> bool {
    let mut inside = false;
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
        if (a.y > q.y) != (b.y > q.y) && q.x < a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x) {
            inside = !inside;
        }
    }
    inside
}

/// Whether a closed polygon's sides cross only at shared corners.
pub fn simple(pts: &[DVec2]) -> bool {
    let n = pts.len();
    for i in 0..n {
        for j in i + 1..n {
            if j == i + 1 || (i == 0 && j == n - 1) {
                continue;
            }
            if segments_touch(pts[i], pts[(i + 1) % n], pts[j], pts[(j + 1) % n]) {
                return false;
            }
        }
    }
    true
}

fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// Whether closed segments ab and cd share a point.
fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let (o1, o2, o3, o4) = (orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b));
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, o: f64| {
        o == 0.0
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(a, b, c, o1) || on(a, b, d, o2) || on(c, d, a, o3) || on(c, d, b, o4)
}

/// Whether `p` lies in the closed triangle abc (counter-clockwise).
fn in_triangle(p: DVec2, a: DVec2, b: DVec2, c: DVec2) -> bool {
    let tol = -1e-12 * ((b - a).length_squared() + (c - a).length_squared());
    orient(a, b, p) >= tol && orient(b, c, p) >= tol && orient(c, a, p) >= tol
}

/// Ear cutting with the shortest semi-adjacent diagonal first (§7.2, fig. 7.7); `false` when
/// some step finds no ear free of other vertices (the polygon is not simple).
pub fn ear_cut(points: &[DVec2], poly: &[usize], out: &mut Vec<[usize; 3]>) -> bool {
    let mut ring: Vec<usize> = poly.to_vec();
    while ring.len() > 3 {
        let n = ring.len();
        let mut best: Option<(f64, usize)> = None;
        for k in 0..n {
            let (ia, ib, ic) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
            let (a, b, c) = (points[ia], points[ib], points[ic]);
            let scale = (b - a).length_squared().max((c - b).length_squared());
            if orient(a, b, c) <= 1e-12 * scale {
                continue; // reflex or flat corner
            }
            let blocked = ring.iter().any(|&j| {
                j != ia && j != ib && j != ic && {
                    let q = points[j];
                    q != a && q != b && q != c && in_triangle(q, a, b, c)
                }
            });
            if blocked {
                continue;
            }
            let d = a.distance_squared(c);
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, k));
            }
        }
        let Some((_, k)) = best else { return false };
        out.push([ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]]);
        ring.remove(k);
    }
    let (a, b, c) = (points[ring[0]], points[ring[1]], points[ring[2]]);
    if orient(a, b, c) <= 0.0 {
        return false;
    }
    out.push([ring[0], ring[1], ring[2]]);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ear_cutting_a_concave_polygon_covers_it() {
        // An L shape with a collinear point on one side.
        let pts = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 1.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(1.0, 2.0),
            DVec2::new(0.0, 2.0),
        ];
        let poly: Vec<usize> = (0..pts.len()).collect();
        let mut tris = Vec::new();
        assert!(ear_cut(&pts, &poly, &mut tris));
        assert_eq!(tris.len(), pts.len() - 2);
        let sum: f64 = tris.iter().map(|t| orient(pts[t[0]], pts[t[1]], pts[t[2]])).sum();
        assert!((sum - signed_area2(&pts)).abs() < 1e-12);
        assert!(tris.iter().all(|t| orient(pts[t[0]], pts[t[1]], pts[t[2]]) > 0.0));
    }

    #[test]
    fn refining_a_square_keeps_its_area_and_meets_the_limits() {
        let sq = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ];
        let mut w = Web::from_outline(&sq).unwrap();
        let unsplit = w.refine(0.02, 40.0);
        assert_eq!(unsplit, 0);
        let mut total = 0.0;
        for p in &w.polygons {
            let pts: Vec<DVec2> = p.iter().map(|&k| w.points[k]).collect();
            let a = signed_area2(&pts) / 2.0;
            let per: f64 = (0..pts.len()).map(|i| pts[i].distance(pts[(i + 1) % pts.len()])).sum();
            let (long, narrow) = extents(&pts);
            assert!(a > 0.0 && a < 0.02, "area {a}");
            assert!(per / a < 40.0 || long <= 2.0 * narrow, "ratio {} of a thin piece", per / a);
            total += a;
        }
        assert!((total - 1.0).abs() < 1e-12);
        let tris = w.triangulate().unwrap();
        let area: f64 =
            tris.iter().map(|t| orient(w.points[t[0]], w.points[t[1]], w.points[t[2]]) / 2.0).sum();
        assert!((area - 1.0).abs() < 1e-12);
    }
}
