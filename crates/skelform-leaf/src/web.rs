//! The polygonal web and its triangulation (dissertation §7.2).
//!
//! Two adjacent margin points are joined along the margin and, through the veins, by their
//! paths to a common ancestor: each such circuit is a polygon, and together they tile the
//! blade ("polygonal web"). Because every polygon side between two vein points is a piece of
//! vein, the veins lie on triangle edges of the blade, even after the leaf is bent.
//!
//! The web's polygons are too large for the bending (creases), so each is split recursively,
//! across its long axis (a cut parallel to its narrow axis), until its area is below
//! `max_area` and its perimeter/area below `max_ratio`; a cut that is not wholly inside a
//! concave polygon is rotated until one is. A cut's ends land on polygon sides shared with
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
    pub points: Vec<DVec2>,
    pub curvature: Vec<f64>,
    /// Counter-clockwise polygons (point ids).
    pub polygons: Vec<Vec<usize>>,
    /// Sides split by a cut: (lo, hi) → the point inserted between them.
    splits: HashMap<(usize, usize), usize>,
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
        let margin = v.margin();
        let mut web = Web {
            points: v.points.clone(),
            curvature: v.curvature.clone(),
            polygons: Vec::new(),
            splits: HashMap::new(),
        };
        for i in 0..margin.len() {
            let (a, b) = (margin[i], margin[(i + 1) % margin.len()]);
            let mut poly = v.web_polygon(a, b);
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
        web.check_tiling(&margin)?;
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
        })
    }

    /// The polygons' areas must add up to the area inside the margin, and each polygon must be
    /// simple: otherwise veins cross each other or the margin.
    fn check_tiling(&self, margin: &[usize]) -> Result<(), LeafError> {
        let outline: Vec<DVec2> = margin.iter().map(|&k| self.points[k]).collect();
        let total = signed_area2(&outline).abs();
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
        // Keep new points off existing ones, so no sliver triangles come of it.
        for h in [h0, h1] {
            let len = pts[h.1].distance(pts[(h.1 + 1) % n]);
            if h.2 * len < 0.15 * chord || (1.0 - h.2) * len < 0.15 * chord {
                return None;
            }
        }
        let (e0, e1) = if h0.1 < h1.1 { (h0, h1) } else { (h1, h0) };
        if e0.1 == e1.1 {
            return None;
        }
        let m0 = self.split_side(poly[e0.1], poly[(e0.1 + 1) % n], e0.2);
        let m1 = self.split_side(poly[e1.1], poly[(e1.1 + 1) % n], e1.2);
        let mut a = vec![m0];
        a.extend_from_slice(&poly[e0.1 + 1..=e1.1]);
        a.push(m1);
        let mut b = vec![m1];
        b.extend((e1.1 + 1..e1.1 + 1 + (n - (e1.1 - e0.1))).map(|i| poly[i % n]));
        b.push(m0);
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
