//! Finding and following the singular set: from seeds near it, converge onto a singular
//! point, classify it, and march along singular curves (the thesis's future work, §5.4:
//! "march along 1-dimensional singularities directly, instead of finding them inside each
//! cube"). The result is the self-intersection network that healing fans the sheets onto:
//! nodes where the curves cross lattice faces (the thesis's face self-intersection points),
//! triple points where curves meet (its class-13 interior points), pinch points where a
//! crossing curve turns into a bare line, and exits through the domain box.
//!
//! The march is predictor–corrector: a step along the null direction of the Hessian, then a
//! damped Gauss–Newton correction back onto `∇f = 0, f = 0` within the plane across the
//! step. Each point is classified by the signs of the Hessian's two other eigenvalues:
//! opposite signs, two sheets cross there; equal signs, the zero set is the line alone (a
//! "handle", as on the Whitney umbrella's negative axis), which is reported and not meshed.

use glam::DVec3;
use rustc_hash::FxHashMap;
use skelform_field::Aabb;
use skelform_field::grid::Grid;

use super::local::{
    Local, Probe, SolveOptions, classify, perpendicular_basis, solve_singular, sym_eigen,
};

/// What a traced curve is at one of its points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LineKind {
    /// Two sheets cross along it.
    Crossing,
    /// The zero set is the line alone.
    Isolated,
}

/// How a march along a curve stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum End {
    /// It left the lattice; `outside` is the first predicted point beyond it.
    Domain { outside: DVec3 },
    /// It came back to its start.
    Closed,
    /// The corrector failed even with small steps (the curve ends, or is not resolvable).
    Lost,
    /// It ran into curve `curve` at its point `index`, going the same way.
    Join { curve: usize, index: usize },
    /// Too many steps.
    Budget,
}

/// A traced curve: points about a quarter of a cell apart, each on the singular set.
#[derive(Clone, Debug)]
pub(crate) struct Curve {
    pub points: Vec<DVec3>,
    pub tangents: Vec<DVec3>,
    pub kinds: Vec<LineKind>,
    /// How the curve ends before its first point and after its last.
    pub ends: [End; 2],
}

impl Curve {
    pub fn closed(&self) -> bool {
        self.ends[1] == End::Closed
    }
}

/// What an isolated singular point is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(rename_all = "snake_case"))]
pub enum PointKind {
    /// Two nappes touching at a point (the double cone's apex).
    Cone,
    /// The zero set is the point alone.
    Isolated,
    /// A crossing curve turns into a bare line (the Whitney umbrella's origin).
    Pinch,
    /// Three sheets meet (or more crossing curves).
    Triple,
    /// The Hessian has fewer than two non-zero eigenvalues and the point is on no traced
    /// curve: not classified further.
    Degenerate,
}

/// A singular point found by the search.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct SingularPoint {
    /// Where it is, after the Gauss–Newton solve for `∇f = 0, f = 0`.
    pub position: DVec3,
    /// What the Hessian there says it is.
    pub kind: PointKind,
}

/// Settings of the search.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TraceOptions {
    /// March step, as a fraction of the cell.
    pub step: f64,
    /// Most march steps per curve.
    pub max_steps: usize,
}

/// Converges seeds onto the singular set and traces the curves through them.
pub(crate) struct Tracer<'a> {
    pub probe: Probe<'a>,
    grid: Grid,
    bounds: Aabb,
    opts: TraceOptions,
    pub curves: Vec<Curve>,
    pub points: Vec<SingularPoint>,
    /// Curve points by lattice cell: `(curve, index)`.
    buckets: FxHashMap<[i64; 3], Vec<(u32, u32)>>,
    /// Seeds that converged to nothing, by lattice cell.
    failed: FxHashMap<[i64; 3], Vec<DVec3>>,
    pub seeds_tried: u64,
}

impl<'a> Tracer<'a> {
    pub fn new(probe: Probe<'a>, grid: Grid, opts: TraceOptions) -> Self {
        Tracer {
            probe,
            grid,
            bounds: grid.bounds(),
            opts,
            curves: Vec::new(),
            points: Vec::new(),
            buckets: FxHashMap::default(),
            failed: FxHashMap::default(),
            seeds_tried: 0,
        }
    }

    fn h(&self) -> f64 {
        self.grid.cell
    }

    fn bucket(&self, p: DVec3) -> [i64; 3] {
        let r = (p - self.grid.origin) / self.grid.cell;
        [r.x.floor() as i64, r.y.floor() as i64, r.z.floor() as i64]
    }

    /// The nearest curve point within `radius` of `p`, with its tangent.
    fn near_curve(&self, p: DVec3, radius: f64) -> Option<(usize, usize, DVec3, f64)> {
        let b = self.bucket(p);
        let r = (radius / self.h()).ceil().max(1.0) as i64;
        let mut best: Option<(usize, usize, DVec3, f64)> = None;
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    let Some(list) = self.buckets.get(&[b[0] + dx, b[1] + dy, b[2] + dz]) else {
                        continue;
                    };
                    for &(c, i) in list {
                        let q = self.curves[c as usize].points[i as usize];
                        let d = (q - p).length();
                        if d <= radius && best.is_none_or(|b| d < b.3) {
                            let t = self.curves[c as usize].tangents[i as usize];
                            best = Some((c as usize, i as usize, t, d));
                        }
                    }
                }
            }
        }
        best
    }

    fn near_failed(&self, p: DVec3, radius: f64) -> bool {
        let b = self.bucket(p);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = self.failed.get(&[b[0] + dx, b[1] + dy, b[2] + dz])
                        && list.iter().any(|q| (*q - p).length() <= radius)
                    {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Whether a cone apex or isolated point was found within `radius` of `p` (degenerate
    /// points do not count: they lie on curves that other seeds must still trace).
    fn near_point(&self, p: DVec3, radius: f64) -> bool {
        self.points
            .iter()
            .any(|s| s.kind != PointKind::Degenerate && (s.position - p).length() <= radius)
    }

    fn inside(&self, p: DVec3) -> bool {
        let slack = 1e-9 * self.h();
        p.cmpge(self.bounds.min - DVec3::splat(slack)).all()
            && p.cmple(self.bounds.max + DVec3::splat(slack)).all()
    }

    fn solve_options(&self, max_move: f64, gradient_scale: f64) -> SolveOptions {
        SolveOptions { length: self.h(), max_move, gradient_scale, iterations: 60 }
    }

    /// Tries one seed: `basis` restricts the search (a lattice face's two axes, or all three).
    /// Returns whether it found something new.
    pub fn seed(&mut self, p0: DVec3, basis: &[DVec3]) -> bool {
        let h = self.h();
        // Critical vertices lie within about two cells of a curve (the default test): once
        // the curve is traced they have nothing new to show.
        if !p0.is_finite() || self.near_curve(p0, 2.0 * h).is_some() || self.near_point(p0, 1.5 * h)
        {
            return false;
        }
        if self.near_failed(p0, 0.5 * h) {
            return false;
        }
        self.seeds_tried += 1;
        let fail = |t: &mut Self| {
            let b = t.bucket(p0);
            t.failed.entry(b).or_default().push(p0);
            false
        };
        let Some(scale) = self.probe.gradient_scale(p0, h) else { return fail(self) };
        if scale <= 0.0 {
            return fail(self);
        }
        let o = self.solve_options(2.0 * h, scale);
        let Some(s) = solve_singular(&mut self.probe, p0, basis, &o) else { return fail(self) };
        if !self.inside(s.p) {
            return fail(self);
        }
        let Some(hs) = self.probe.gradient_scale(s.p, h) else { return fail(self) };
        match classify(s.jet.h, hs / h) {
            Local::Crossing { tangent } => self.trace(s.p, tangent, LineKind::Crossing, hs),
            Local::IsolatedLine { tangent } => self.trace(s.p, tangent, LineKind::Isolated, hs),
            Local::Cone => self.add_point(s.p, PointKind::Cone),
            Local::IsolatedPoint => self.add_point(s.p, PointKind::Isolated),
            Local::Degenerate => self.add_point(s.p, PointKind::Degenerate),
        }
    }

    fn add_point(&mut self, p: DVec3, kind: PointKind) -> bool {
        let h = self.h();
        if self.points.iter().any(|s| (s.position - p).length() <= 0.5 * h) {
            return false;
        }
        self.points.push(SingularPoint { position: p, kind });
        true
    }

    fn trace(&mut self, start: DVec3, t0: DVec3, kind: LineKind, scale: f64) -> bool {
        let h = self.h();
        if self.near_curve(start, 0.5 * h).is_some() {
            return false;
        }
        let id = self.curves.len();
        let fwd = self.march(start, t0, scale, id);
        let (bwd_pts, bwd_end) = if fwd.1 == End::Closed {
            (Vec::new(), End::Closed)
        } else {
            self.march(start, -t0, scale, id)
        };
        let mut points = Vec::with_capacity(bwd_pts.len() + fwd.0.len() + 1);
        for &(p, t, k) in bwd_pts.iter().rev() {
            points.push((p, -t, k));
        }
        points.push((start, t0, kind));
        points.extend(fwd.0.iter().copied());
        let curve = Curve {
            points: points.iter().map(|x| x.0).collect(),
            tangents: points.iter().map(|x| x.1).collect(),
            kinds: points.iter().map(|x| x.2).collect(),
            ends: [bwd_end, fwd.1],
        };
        for (i, &p) in curve.points.iter().enumerate() {
            let b = self.bucket(p);
            self.buckets.entry(b).or_default().push((id as u32, i as u32));
        }
        self.curves.push(curve);
        true
    }

    /// Marches from `start` along `t` until the curve leaves the lattice, closes, ends or
    /// joins another curve.
    fn march(
        &mut self,
        start: DVec3,
        t: DVec3,
        scale: f64,
        id: usize,
    ) -> (Vec<(DVec3, DVec3, LineKind)>, End) {
        let h = self.h();
        let nominal = self.opts.step * h;
        let mut out = Vec::new();
        let (mut p, mut t, mut g_ref) = (start, t.normalize(), scale);
        let mut step = nominal;
        let mut travelled = 0.0;
        loop {
            if out.len() >= self.opts.max_steps {
                return (out, End::Budget);
            }
            let q = p + t * step;
            if !self.inside(q) {
                return (out, End::Domain { outside: q });
            }
            let basis = perpendicular_basis(t);
            let o = self.solve_options(step, g_ref);
            let Some(s) = solve_singular(&mut self.probe, q, &basis, &o) else {
                step *= 0.5;
                if step < h / 64.0 {
                    return (out, End::Lost);
                }
                continue;
            };
            let np = s.p;
            let Some(hs) = self.probe.gradient_scale(np, h) else {
                return (out, End::Lost);
            };
            g_ref = g_ref.max(hs);
            let moved = np - p;
            let secant = moved.normalize_or(t);
            // The kind by the sign of the two larger eigenvalues' product, without a threshold:
            // it changes sign exactly at a pinch point (and not at a triple point, where both
            // vanish together).
            let (vals, vecs) = sym_eigen(s.jet.h);
            let kind =
                if vals[1] * vals[2] < 0.0 { LineKind::Crossing } else { LineKind::Isolated };
            let mut nt = if vals[0].abs() < 0.3 * vals[1].abs() { vecs[0] } else { secant };
            if nt.dot(t) < 0.0 {
                nt = -nt;
            }
            // Near triple points the null direction is ill-defined: keep going straight.
            if nt.dot(t) < 0.7 {
                nt = secant;
            }
            travelled += moved.length();
            if travelled > 2.0 * h && (np - start).length() < 0.6 * nominal {
                return (out, End::Closed);
            }
            if travelled > 0.5 * h
                && let Some((c, i, tc, _)) = self.near_curve(np, 0.3 * h)
                && c != id
                && tc.dot(nt).abs() > 0.9
            {
                return (out, End::Join { curve: c, index: i });
            }
            out.push((np, nt, kind));
            p = np;
            t = nt;
            step = (step * 2.0).min(nominal);
        }
    }

    /// The sign of the product of the two larger Hessian eigenvalues at the curve point
    /// nearest to `q` across direction `t` (negative where sheets cross), and that point.
    fn crossing_sign(&mut self, q: DVec3, t: DVec3, g_ref: f64) -> Option<(f64, DVec3)> {
        let o = self.solve_options(0.5 * self.h(), g_ref);
        let basis = perpendicular_basis(t);
        let s = solve_singular(&mut self.probe, q, &basis, &o)?;
        let (vals, _) = sym_eigen(s.jet.h);
        Some((vals[1] * vals[2], s.p))
    }

    /// Where a curve turns from crossing into a bare line between two of its points: bisection
    /// on the sign of the Hessian's eigenvalue product.
    pub fn pinch_between(&mut self, a: DVec3, b: DVec3) -> DVec3 {
        let h = self.h();
        let t = (b - a).normalize_or(DVec3::Z);
        let g_ref = self.probe.gradient_scale(a, h).unwrap_or(1.0).max(f64::MIN_POSITIVE);
        let sa = self.crossing_sign(a, t, g_ref).map_or(-1.0, |x| x.0);
        let (mut lo, mut hi) = (0.0, 1.0);
        let mut best = a.lerp(b, 0.5);
        for _ in 0..30 {
            let m = 0.5 * (lo + hi);
            match self.crossing_sign(a.lerp(b, m), t, g_ref) {
                Some((s, p)) => {
                    best = p;
                    if (s < 0.0) == (sa < 0.0) {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                None => break,
            }
        }
        best
    }

    /// A point where two curves cross, refined from an estimate.
    pub fn junction_near(&mut self, p0: DVec3) -> DVec3 {
        let h = self.h();
        let scale = self.probe.gradient_scale(p0, h).unwrap_or(0.0);
        if scale > 0.0 {
            let o = self.solve_options(0.25 * h, scale);
            if let Some(s) =
                solve_singular(&mut self.probe, p0, &[DVec3::X, DVec3::Y, DVec3::Z], &o)
            {
                return s.p;
            }
        }
        p0
    }

    /// The point where the curve crosses the lattice plane `axis = k` between `a` and `b`,
    /// solved on that plane.
    pub fn on_plane(&mut self, a: DVec3, b: DVec3, axis: usize, k: i64) -> DVec3 {
        let h = self.h();
        let plane = self.grid.origin[axis] + k as f64 * h;
        let u = ((plane - a[axis]) / (b[axis] - a[axis])).clamp(0.0, 1.0);
        let mut q = a.lerp(b, u);
        q[axis] = plane;
        let basis: Vec<DVec3> =
            (0..3).filter(|&d| d != axis).map(|d| DVec3::from_array(unit(d))).collect();
        let scale = self.probe.gradient_scale(q, h).unwrap_or(0.0);
        if scale > 0.0 {
            let o = self.solve_options(0.5 * h, scale);
            if let Some(s) = solve_singular(&mut self.probe, q, &basis, &o) {
                let mut p = s.p;
                p[axis] = plane;
                return p;
            }
        }
        q
    }

    pub fn grid(&self) -> &Grid {
        &self.grid
    }
}

fn unit(d: usize) -> [f64; 3] {
    let mut u = [0.0; 3];
    u[d] = 1.0;
    u
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::FnField;

    fn tracer_for<'a>(f: &'a dyn skelform_field::Field, h: f64) -> Tracer<'a> {
        let grid = Grid::with_cell(&Aabb::new(DVec3::splat(-1.0), DVec3::splat(1.05)), h).unwrap();
        Tracer::new(Probe::new(f, h), grid, TraceOptions { step: 0.25, max_steps: 100_000 })
    }

    #[test]
    fn a_straight_crossing_is_traced_from_box_to_box() {
        let f = FnField(|p: DVec3| p.y * p.z);
        let mut t = tracer_for(&f, 0.1);
        assert!(t.seed(DVec3::new(0.2, 0.03, -0.02), &[DVec3::X, DVec3::Y, DVec3::Z]));
        assert_eq!(t.curves.len(), 1);
        let c = &t.curves[0];
        assert!(matches!(c.ends[0], End::Domain { .. }) && matches!(c.ends[1], End::Domain { .. }));
        assert!(c.points.iter().all(|p| p.y.abs() < 1e-9 && p.z.abs() < 1e-9));
        assert!(c.kinds.iter().all(|k| *k == LineKind::Crossing));
        let xs: Vec<f64> = c.points.iter().map(|p| p.x).collect();
        assert!(xs.windows(2).all(|w| w[1] > w[0]), "ordered along the curve");
        // A second seed near the traced curve adds nothing.
        assert!(!t.seed(DVec3::new(-0.4, 0.02, 0.01), &[DVec3::X, DVec3::Y, DVec3::Z]));
    }

    #[test]
    fn a_circle_closes() {
        let f = FnField(|p: DVec3| p.z * (p.length_squared() - 0.5));
        let mut t = tracer_for(&f, 0.1);
        let r = 0.5f64.sqrt();
        assert!(t.seed(DVec3::new(r + 0.02, 0.01, 0.03), &[DVec3::X, DVec3::Y, DVec3::Z]));
        let c = &t.curves[0];
        assert!(c.closed());
        for p in &c.points {
            assert!((p.length() - r).abs() < 1e-7 && p.z.abs() < 1e-7, "{p}");
        }
        let len: f64 = c.points.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        assert!((len - 2.0 * std::f64::consts::PI * r).abs() < 0.1, "{len}");
    }

    #[test]
    fn the_whitney_axis_is_crossing_above_and_a_handle_below() {
        let f = FnField(|p: DVec3| p.x * p.x - p.y * p.y * p.z);
        let mut t = tracer_for(&f, 0.1);
        assert!(t.seed(DVec3::new(0.02, 0.01, 0.5), &[DVec3::X, DVec3::Y, DVec3::Z]));
        let c = &t.curves[0];
        for (p, k) in c.points.iter().zip(&c.kinds) {
            assert!(p.x.abs() < 1e-6 && p.y.abs() < 1e-3, "{p}");
            if p.z > 0.05 {
                assert_eq!(*k, LineKind::Crossing, "{p}");
            } else if p.z < -0.05 {
                assert_eq!(*k, LineKind::Isolated, "{p}");
            }
        }
        let zs: Vec<f64> = c.points.iter().map(|p| p.z).collect();
        let (lo, hi) = zs.iter().fold((1.0f64, -1.0f64), |(l, h), &z| (l.min(z), h.max(z)));
        assert!(lo < -0.9 && hi > 0.9, "{lo} {hi}");
        let i = c.kinds.windows(2).position(|w| w[0] != w[1]).unwrap();
        let pinch = t.pinch_between(c.points[i], c.points[i + 1]);
        assert!(pinch.length() < 1e-3, "{pinch}");
    }
}
