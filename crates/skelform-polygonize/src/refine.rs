//! Moving vertices onto the surface: root finding along the edge each vertex lies on, and
//! normals from the field's gradient. Shared by the polygonizers.
//!
//! Work is done in fixed chunks of vertices, each chunk evaluating all of its unfinished
//! vertices in one batch per iteration, so the field's batch path is used and results do not
//! depend on the thread count.

use glam::DVec3;
use rayon::prelude::*;
use skelform_field::Field;

/// Vertices per batch.
pub(crate) const CHUNK: usize = 1024;

/// A vertex on the segment `p0 → p1`, where the field has opposite signs at the two ends.
#[derive(Clone, Copy, Debug)]
pub struct Bracket {
    /// The segment's end where `t = 0`.
    pub p0: DVec3,
    /// The segment's end where `t = 1`.
    pub p1: DVec3,
    /// Field values at the ends (opposite signs; one may be zero): the samples, so that
    /// refinement need not evaluate the ends again.
    pub f0: f64,
    /// See `f0`.
    pub f1: f64,
    /// Current estimate of the root as a fraction of the segment; refined in place.
    pub t: f64,
}

/// How a root is found between the ends of a segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum RootMethod {
    /// Illinois-modified regula falsi: superlinear on smooth fields, never leaves the bracket.
    #[default]
    RegulaFalsi,
    /// Halve the bracket each step: one bit of position per evaluation, whatever the field.
    /// The dissertation's choice (ten steps).
    Bisection,
    /// Where the corners' values and gradients are known (continuation with a field that
    /// has an exact gradient): the root of the edge's Hermite cubic, with no evaluation, and
    /// the normal from the ends' gradients ([`hermite_roots`]). Faster, and less accurate
    /// where a kernel's support ends inside an edge, which the ends do not see. Elsewhere it
    /// is regula falsi.
    Hermite,
}

/// How root finding stops.
#[derive(Clone, Copy, Debug)]
pub struct RootOptions {
    /// Regula falsi or bisection.
    pub method: RootMethod,
    /// Stop when the bracket is shorter than this fraction of the segment.
    pub tolerance: f64,
    /// Never take more evaluations than this per vertex.
    pub max_iterations: u32,
    /// Keep `t` in `[t_min, 1 − t_min]` (see the extractor's `T_MIN`).
    pub t_min: f64,
}

impl Default for RootOptions {
    fn default() -> Self {
        Self { method: RootMethod::RegulaFalsi, tolerance: 1e-4, max_iterations: 40, t_min: 0.0 }
    }
}

/// Refines every bracket by `opts.method`; returns the field evaluations made.
///
/// Converges superlinearly on smooth fields and never leaves the bracket. A non-finite value
/// stops that vertex where it is (its interpolated position is kept).
///
/// Regula falsi stops when the bracket is shorter than the tolerance or, sooner, when the
/// secant through its last two evaluations puts the root within the tolerance of the last
/// one; the vertex is then placed at that secant's root (inside the bracket). Why: Illinois
/// steps approach a smooth root from one side, so the bracket itself shrinks late (4.6
/// evaluations per vertex on the hand), while two evaluations near the root already locate
/// it to second order (about 2 per vertex, vertices no farther from the surface).
pub fn refine_roots(field: &dyn Field, brackets: &mut [Bracket], opts: &RootOptions) -> u64 {
    brackets.par_chunks_mut(CHUNK).map(|chunk| refine_chunk(field, chunk, opts)).sum()
}

/// [`refine_roots`], asking `control` between chunks: once it is cancelled the chunks not yet
/// refined are left as they are and `None` is returned (the caller drops the run). Why: in a
/// run from scratch, root finding is the last long step before the mesh, and a newer edit
/// (the studio's drag) must not wait for it.
pub fn refine_roots_until(
    field: &dyn Field,
    brackets: &mut [Bracket],
    opts: &RootOptions,
    control: &skelform_field::control::Control,
) -> Option<u64> {
    brackets
        .par_chunks_mut(CHUNK)
        .map(|chunk| (!control.is_cancelled()).then(|| refine_chunk(field, chunk, opts)))
        .sum()
}

struct State {
    a: f64,
    fa: f64,
    b: f64,
    fb: f64,
    /// Which end was kept last time: -1 a, +1 b, 0 none.
    kept: i8,
    done: bool,
    /// The previous evaluation inside the segment (`t`, value), for the secant estimate of
    /// the error.
    last: Option<(f64, f64)>,
}

fn refine_chunk(field: &dyn Field, chunk: &mut [Bracket], opts: &RootOptions) -> u64 {
    let mut states: Vec<State> = chunk
        .iter()
        .map(|b| {
            let ok = b.f0.is_finite() && b.f1.is_finite() && (b.f0 <= 0.0) != (b.f1 <= 0.0);
            State { a: 0.0, fa: b.f0, b: 1.0, fb: b.f1, kept: 0, done: !ok, last: None }
        })
        .collect();
    let mut points = Vec::with_capacity(chunk.len());
    let mut which = Vec::with_capacity(chunk.len());
    let mut values = Vec::new();
    let mut evals = 0u64;
    for _ in 0..opts.max_iterations {
        points.clear();
        which.clear();
        for (n, (s, br)) in states.iter_mut().zip(chunk.iter_mut()).enumerate() {
            if s.done {
                continue;
            }
            if s.b - s.a <= opts.tolerance {
                s.done = true;
                continue;
            }
            let mut t = match opts.method {
                RootMethod::RegulaFalsi | RootMethod::Hermite => {
                    (s.a * s.fb - s.b * s.fa) / (s.fb - s.fa)
                }
                RootMethod::Bisection => 0.5 * (s.a + s.b),
            };
            if t.is_nan() || t <= s.a || t >= s.b {
                t = 0.5 * (s.a + s.b);
            }
            br.t = t;
            points.push(br.p0.lerp(br.p1, t));
            which.push(n);
        }
        if points.is_empty() {
            break;
        }
        values.resize(points.len(), 0.0);
        field.eval_many(&points, &mut values);
        evals += points.len() as u64;
        for (&n, &f) in which.iter().zip(&values) {
            let s = &mut states[n];
            let t = chunk[n].t;
            if !f.is_finite() || f == 0.0 {
                s.done = true;
                continue;
            }
            let last = s.last.replace((t, f));
            // `t` takes the place of `a` (same sign), else of `b`.
            let replaces_a = (f < 0.0) == (s.fa < 0.0) && s.fa != 0.0;
            if let (RootMethod::RegulaFalsi | RootMethod::Hermite, Some((tp, fp))) =
                (opts.method, last)
            {
                // The secant through the last two evaluations, both near the root, estimates
                // how far `t` is from it; once that is within the tolerance, the secant's own
                // root (one more step, not evaluated) is far closer than the tolerance.
                let delta = f * (t - tp) / (f - fp);
                if delta.is_finite() && delta.abs() <= opts.tolerance {
                    let (lo, hi) = if replaces_a { (t, s.b) } else { (s.a, t) };
                    chunk[n].t = (t - delta).clamp(lo, hi);
                    s.done = true;
                    continue;
                }
            }
            if replaces_a {
                s.a = t;
                s.fa = f;
                if s.kept == 1 {
                    s.fb *= 0.5;
                }
                s.kept = 1;
            } else {
                s.b = t;
                s.fb = f;
                if s.kept == -1 {
                    s.fa *= 0.5;
                }
                s.kept = -1;
            }
        }
    }
    for br in chunk.iter_mut() {
        br.t = br.t.clamp(opts.t_min, 1.0 - opts.t_min);
    }
    evals
}

/// A vertex on the segment `p0 → p1` whose ends' values and gradients are known (a lattice
/// that keeps gradients, as continuation does for fields with an exact gradient).
#[derive(Clone, Copy, Debug)]
pub struct GradBracket {
    /// The segment's end where `t = 0`.
    pub p0: DVec3,
    /// The segment's end where `t = 1`.
    pub p1: DVec3,
    /// Field value at `p0` (opposite in sign to `f1`; one may be zero).
    pub f0: f64,
    /// Field value at `p1`.
    pub f1: f64,
    /// Field gradient at `p0`.
    pub g0: DVec3,
    /// Field gradient at `p1`.
    pub g1: DVec3,
    /// The root as a fraction of the segment: the estimate on entry (kept where the values do
    /// not bracket a root), the answer on return.
    pub t: f64,
    /// On return, the field's gradient at the last point evaluated for the root (at an end
    /// that is a root, the end's; zero where unknown).
    pub grad: DVec3,
}

/// Finds the root of each bracket from the values and gradients at its ends and, mostly,
/// one evaluation of the field with its gradient; returns the field evaluations made (a
/// value with its gradient counts as one).
///
/// Why: the four numbers at the ends fix a cubic (Hermite) model of the field along the
/// segment, whose root is typically within a thousandth of a cell of the true one. It cannot
/// be trusted alone: a skeleton's kernels end inside segments (a piecewise field), which no
/// estimate from the ends sees (tried: errors of a hundredth of a cell went unseen). So the
/// field and its gradient are evaluated at the model's root, and a Newton step along the
/// segment from there is taken as the answer when the error it leaves (`f''/(2f')` times its
/// square, `f''` the larger of the model's and the secant's to the bracket's far end) or its
/// length is within `opts.tolerance`: with a start that close, that is almost always so.
/// Otherwise safeguarded Newton steps follow (within the bracket, halving when a step leaves
/// it). The last evaluation's gradient is the vertex's normal (taken at most a Newton step,
/// a thousandth of a cell or so, from the vertex), so normals need no evaluation either.
///
/// Non-finite values stop a vertex where it is; all in fixed chunks, each iteration one
/// batch, so the result does not depend on the thread count.
///
/// With `colors` (one per bracket, for a field that [`Field::has_colors`]), each vertex also
/// gets the field's colour, taken in its last evaluation ([`Field::eval_grad_color_many`]),
/// like its normal at most a Newton step from the vertex; a vertex that took no evaluation
/// (a root at an end, a non-bracketing segment) is coloured where it ends. Why: painting
/// afterwards evaluated every element's density at every vertex again (22 ms of the hand's
/// 128-sample run on one thread), where the last evaluation had them already.
pub fn refine_roots_with_gradients(
    field: &dyn Field,
    brackets: &mut [GradBracket],
    opts: &RootOptions,
    colors: Option<&mut [[f32; 3]]>,
) -> u64 {
    match colors {
        None => brackets
            .par_chunks_mut(CHUNK)
            .map(|chunk| refine_grad_chunk(field, chunk, opts, None))
            .sum(),
        Some(colors) => {
            debug_assert_eq!(colors.len(), brackets.len());
            brackets
                .par_chunks_mut(CHUNK)
                .zip(colors.par_chunks_mut(CHUNK))
                .map(|(chunk, colors)| refine_grad_chunk(field, chunk, opts, Some(colors)))
                .sum()
        }
    }
}

/// Places each bracket's root at the root of its Hermite cubic (the ends' values and slopes
/// along the segment), with no evaluation ([`RootMethod::Hermite`]), and gives it the
/// gradient interpolated linearly between the ends' for its normal; where the end data are
/// not finite, the chord's root and the gradient of the nearer end. Brackets whose values do
/// not differ in sign keep their estimate. Each bracket is its own, so the result does not
/// depend on the thread count.
///
/// The answer is what [`refine_roots_with_gradients`] starts its Newton step from; it is
/// within the cubic's error of the root, small where the field is smooth along the edge
/// but not where a kernel's support ends inside it.
pub fn hermite_roots(brackets: &mut [GradBracket], opts: &RootOptions) {
    brackets.par_chunks_mut(CHUNK).for_each(|chunk| {
        for br in chunk {
            br.grad = DVec3::ZERO;
            let ok = br.f0.is_finite() && br.f1.is_finite() && (br.f0 <= 0.0) != (br.f1 <= 0.0);
            if !ok {
                continue;
            }
            let t = match hermite(br) {
                Some((t, _)) => t,
                None => br.f0 / (br.f0 - br.f1),
            };
            let g = br.g0.lerp(br.g1, t);
            br.grad = if g.is_finite() {
                g
            } else if t < 0.5 {
                br.g0
            } else {
                br.g1
            };
            br.t = t.clamp(opts.t_min, 1.0 - opts.t_min);
        }
    });
}

/// A polynomial's root in `[0, 1]` where its values at 0 and 1 differ in sign (coefficients
/// from the constant up): safeguarded Newton, from the chord's root.
fn unit_root(c: [f64; 4]) -> f64 {
    let at = |t: f64| ((c[3] * t + c[2]) * t + c[1]) * t + c[0];
    let slope = |t: f64| (3.0 * c[3] * t + 2.0 * c[2]) * t + c[1];
    let (v0, v1) = (c[0], c.iter().sum::<f64>());
    if v0 == 0.0 {
        return 0.0;
    }
    if v1 == 0.0 {
        return 1.0;
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    let mut t = (v0 / (v0 - v1)).clamp(0.0, 1.0);
    for _ in 0..64 {
        let v = at(t);
        if v == 0.0 {
            return t;
        }
        if (v < 0.0) == (v0 < 0.0) {
            lo = t;
        } else {
            hi = t;
        }
        let mut n = t - v / slope(t);
        if !(n > lo && n < hi) {
            n = 0.5 * (lo + hi);
        }
        if (n - t).abs() <= 1e-15 {
            return n;
        }
        t = n;
    }
    t
}

/// The root of a bracket's Hermite model (the cubic with the ends' values and slopes) and
/// the cubic's coefficients; `None` where the end data are not finite.
fn hermite(b: &GradBracket) -> Option<(f64, [f64; 4])> {
    let d = b.p1 - b.p0;
    let (f0, f1, s0, s1) = (b.f0, b.f1, b.g0.dot(d), b.g1.dot(d));
    if !(f0.is_finite() && f1.is_finite() && s0.is_finite() && s1.is_finite()) {
        return None;
    }
    let cubic = [f0, s0, 3.0 * (f1 - f0) - 2.0 * s0 - s1, 2.0 * (f0 - f1) + s0 + s1];
    Some((unit_root(cubic), cubic))
}

/// The error a last Newton step may leave, as a fraction of the tolerance: the vertices
/// end as close to the surface as regula falsi's secant stop put them (a hundredth of the
/// tolerance on the hand), at a second evaluation for a few percent of them.
const LEFT: f64 = 0.01;

struct Newton {
    a: f64,
    fa: f64,
    b: f64,
    fb: f64,
    /// The next point to evaluate.
    next: f64,
    /// The Hermite cubic (for its second derivative), if the end data were finite.
    cubic: Option<[f64; 4]>,
}

fn refine_grad_chunk(
    field: &dyn Field,
    chunk: &mut [GradBracket],
    opts: &RootOptions,
    mut colors: Option<&mut [[f32; 3]]>,
) -> u64 {
    // Which vertices took their colour from an evaluation.
    let mut painted = vec![false; if colors.is_some() { chunk.len() } else { 0 }];
    let mut shades = Vec::new();
    let mut open: Vec<(usize, Newton)> = Vec::new();
    for (n, br) in chunk.iter_mut().enumerate() {
        br.grad = DVec3::ZERO;
        let ok = br.f0.is_finite() && br.f1.is_finite() && (br.f0 <= 0.0) != (br.f1 <= 0.0);
        if !ok {
            continue;
        }
        if br.f0 == 0.0 || br.f1 == 0.0 {
            (br.t, br.grad) = if br.f0 == 0.0 { (0.0, br.g0) } else { (1.0, br.g1) };
            continue;
        }
        let model = hermite(br);
        let next = model.map_or(br.f0 / (br.f0 - br.f1), |m| m.0);
        let cubic = model.map(|m| m.1);
        open.push((n, Newton { a: 0.0, fa: br.f0, b: 1.0, fb: br.f1, next, cubic }));
    }
    let mut evals = 0u64;
    let (mut points, mut values, mut grads) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..opts.max_iterations {
        if open.is_empty() {
            break;
        }
        points.clear();
        points.extend(open.iter().map(|(n, s)| chunk[*n].p0.lerp(chunk[*n].p1, s.next)));
        values.resize(points.len(), 0.0);
        grads.resize(points.len(), DVec3::ZERO);
        let shaded = match colors.as_deref_mut() {
            Some(_) => {
                shades.resize(points.len(), [0f32; 3]);
                field.eval_grad_color_many(&points, &mut values, &mut grads, &mut shades)
            }
            None => {
                field.eval_grad_many(&points, &mut values, &mut grads);
                false
            }
        };
        evals += points.len() as u64;
        let mut k = 0;
        open.retain_mut(|(n, s)| {
            let (f, g) = (values[k], grads[k]);
            if shaded && let Some(out) = colors.as_deref_mut() {
                out[*n] = shades[k];
                painted[*n] = true;
            }
            k += 1;
            let br = &mut chunk[*n];
            let t = s.next;
            br.t = t;
            if !f.is_finite() {
                return false;
            }
            br.grad = if g.is_finite() { g } else { DVec3::ZERO };
            if f == 0.0 {
                return false;
            }
            let (far, ffar) = if (f < 0.0) == (s.fa < 0.0) {
                let far = (s.b, s.fb);
                (s.a, s.fa) = (t, f);
                far
            } else {
                let far = (s.a, s.fa);
                (s.b, s.fb) = (t, f);
                far
            };
            let slope = g.dot(br.p1 - br.p0);
            if slope.is_finite() && slope != 0.0 {
                let step = f / slope;
                let landing = t - step;
                if landing > s.a && landing < s.b {
                    let secant = (ffar - f) / (far - t);
                    let mut curve = (2.0 * (secant - slope) / (far - t)).abs();
                    if let Some(c) = s.cubic {
                        curve = curve.max((2.0 * c[2] + 6.0 * c[3] * t).abs());
                    }
                    let left = curve / (2.0 * slope.abs()) * step * step;
                    if step.abs() <= opts.tolerance
                        || (left.is_finite() && left <= LEFT * opts.tolerance)
                    {
                        br.t = landing;
                        return false;
                    }
                    s.next = landing;
                } else {
                    s.next = 0.5 * (s.a + s.b);
                }
            } else {
                s.next = 0.5 * (s.a + s.b);
            }
            s.b - s.a > opts.tolerance
        });
    }
    for br in chunk.iter_mut() {
        br.t = br.t.clamp(opts.t_min, 1.0 - opts.t_min);
    }
    if let Some(out) = colors {
        let rest: Vec<usize> = (0..chunk.len()).filter(|&n| !painted[n]).collect();
        if !rest.is_empty() {
            let pts: Vec<DVec3> =
                rest.iter().map(|&n| chunk[n].p0.lerp(chunk[n].p1, chunk[n].t)).collect();
            shades.resize(pts.len(), [0f32; 3]);
            if field.colors_many(&pts, &mut shades) {
                for (&n, c) in rest.iter().zip(&shades) {
                    out[n] = *c;
                }
            }
        }
    }
    evals
}

/// A segment of a line through a point, on which [`roots_on_lines`] looks for the field's
/// zero nearest the point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// The starting point (e.g. where the trilinear interpolant is zero).
    pub p: DVec3,
    /// The line's unit direction.
    pub dir: DVec3,
    /// How far behind `p` the zero may lie (a distance, zero or more).
    pub back: f64,
    /// How far ahead of `p` (along `dir`) the zero may lie.
    pub ahead: f64,
}

/// For each line, the field's zero on its segment nearest its point (`None` where the field
/// keeps one sign on the whole segment, as far as the search sees); returns the zeros and
/// the field evaluations made.
///
/// The segment is searched outward from the point on both sides at once, in steps of
/// `first`, then twice, four times that distance and so on (so a zero a hundredth of a cell
/// away costs a step or two, one at the segment's end a few more), and the first step on
/// either side that changes the sign brackets the zero; where both sides change sign in the
/// same round, the side whose secant puts the zero nearer wins. The bracket is then refined
/// by regula falsi to `tolerance` (a distance). Why a search on a fixed line rather than
/// Newton steps along the gradient: the line is chosen to keep several points apart (a
/// tube's ring on rays from its saddle), which free steps need not (see
/// [`crate::grid::Slide`]). In fixed chunks, one batch per round, so the result does not
/// depend on the thread count.
pub fn roots_on_lines(
    field: &dyn Field,
    lines: &[Line],
    first: f64,
    tolerance: f64,
) -> (Vec<Option<DVec3>>, u64) {
    let parts: Vec<(Vec<Option<DVec3>>, u64)> =
        lines.par_chunks(CHUNK).map(|chunk| lines_chunk(field, chunk, first, tolerance)).collect();
    let evals = parts.iter().map(|p| p.1).sum();
    (parts.into_iter().flat_map(|p| p.0).collect(), evals)
}

/// A bracket of a line's zero: its ends as signed distances from the line's point, the
/// values there, and the round of the search that found it (which fixes its length).
#[derive(Clone, Copy)]
struct Found {
    line: usize,
    a: f64,
    fa: f64,
    b: f64,
    fb: f64,
    round: u32,
}

/// One side's search: the last point evaluated on it (as a signed distance from `p`) and
/// the value there, and whether it goes on.
#[derive(Clone, Copy)]
struct Side {
    s: f64,
    f: f64,
    open: bool,
}

fn lines_chunk(
    field: &dyn Field,
    lines: &[Line],
    first: f64,
    tolerance: f64,
) -> (Vec<Option<DVec3>>, u64) {
    let starts: Vec<DVec3> = lines.iter().map(|l| l.p).collect();
    let mut values = vec![0.0; lines.len()];
    field.eval_many(&starts, &mut values);
    let mut out: Vec<Option<DVec3>> =
        values.iter().zip(&starts).map(|(&f, &p)| (f == 0.0).then_some(p)).collect();
    let mut evals = lines.len() as u64;
    let ok = |x: f64| x.is_finite() && x > 0.0;
    let mut sides: Vec<[Side; 2]> = lines
        .iter()
        .zip(&values)
        .map(|(l, &f)| {
            let go = f.is_finite() && f != 0.0 && ok(first);
            [
                Side { s: 0.0, f, open: go && ok(l.back) },
                Side { s: 0.0, f, open: go && ok(l.ahead) },
            ]
        })
        .collect();
    let mut found: Vec<Found> = Vec::new();
    let (mut points, mut which) = (Vec::new(), Vec::new());
    for round in 0..64u32 {
        points.clear();
        which.clear();
        let step = first * 2f64.powi(round as i32);
        for (n, (l, sd)) in lines.iter().zip(&sides).enumerate() {
            for (k, side) in sd.iter().enumerate() {
                if side.open {
                    let s = if k == 0 { -step.min(l.back) } else { step.min(l.ahead) };
                    points.push(l.p + l.dir * s);
                    which.push((n, k, s));
                }
            }
        }
        if points.is_empty() {
            break;
        }
        values.resize(points.len(), 0.0);
        field.eval_many(&points, &mut values);
        evals += points.len() as u64;
        // The bracket this round found on the line at hand, if any, with the distance to
        // its secant's root.
        let mut best: Option<(f64, Found)> = None;
        let mut flush = |best: &mut Option<(f64, Found)>, sides: &mut [[Side; 2]]| {
            if let Some((_, b)) = best.take() {
                let n = b.line;
                found.push(b);
                sides[n] =
                    [Side { open: false, ..sides[n][0] }, Side { open: false, ..sides[n][1] }];
            }
        };
        for (&(n, k, s), &f) in which.iter().zip(&values) {
            if best.as_ref().is_some_and(|b| b.1.line != n) {
                flush(&mut best, &mut sides);
            }
            let side = sides[n][k];
            if !side.open {
                continue; // the other side already ended this line's search
            }
            if f == 0.0 {
                out[n] = Some(lines[n].p + lines[n].dir * s);
                best = None;
                sides[n] = [Side { open: false, ..side }; 2];
                continue;
            }
            if !f.is_finite() {
                sides[n][k].open = false;
                continue;
            }
            if (f < 0.0) != (side.f < 0.0) {
                let secant = side.s + (s - side.s) * side.f / (side.f - f);
                if best.as_ref().is_none_or(|b| secant.abs() < b.0) {
                    let b = Found { line: n, a: side.s, fa: side.f, b: s, fb: f, round };
                    best = Some((secant.abs(), b));
                }
                continue;
            }
            let bound = if k == 0 { lines[n].back } else { lines[n].ahead };
            sides[n][k] = Side { s, f, open: s.abs() < bound };
        }
        flush(&mut best, &mut sides);
    }
    // Regula falsi in each bracket, those of one round (one length, or less at a segment's
    // end) together so that the relative tolerance fits them all.
    let mut rounds: Vec<u32> = found.iter().map(|b| b.round).collect();
    rounds.sort_unstable();
    rounds.dedup();
    for round in rounds {
        let group: Vec<&Found> = found.iter().filter(|b| b.round == round).collect();
        let mut brackets: Vec<Bracket> = group
            .iter()
            .map(|b| {
                let l = &lines[b.line];
                let (p0, p1) = (l.p + l.dir * b.a, l.p + l.dir * b.b);
                Bracket { p0, p1, f0: b.fa, f1: b.fb, t: b.fa / (b.fa - b.fb) }
            })
            .collect();
        let length = if round == 0 { first } else { first * 2f64.powi(round as i32 - 1) };
        let opts = RootOptions { tolerance: tolerance / length, ..RootOptions::default() };
        evals += refine_chunk(field, &mut brackets, &opts);
        for (br, b) in brackets.iter().zip(&group) {
            out[b.line] = Some(br.p0.lerp(br.p1, br.t));
        }
    }
    (out, evals)
}

/// Newton steps `p ← p − f ∇f / |∇f|²` towards the surface, each point kept inside its box;
/// a point whose step fails (no gradient, non-finite value) stays where it was. Returns the
/// evaluations made (value and gradient count as one).
///
/// Free steps can carry several points onto one corner of their box: the polygonizers use
/// this only as a second try for interior vertices whose lines have no zero, and keep its
/// result only where the vertices stay apart and no triangle turns over (see
/// `grid::place_cells`).
pub fn project_to_surface(
    field: &dyn Field,
    points: &mut [DVec3],
    boxes: &[(DVec3, DVec3)],
    tolerance: f64,
) -> u64 {
    points
        .par_chunks_mut(CHUNK)
        .zip(boxes.par_chunks(CHUNK))
        .map(|(pts, bxs)| {
            let mut vals = vec![0.0; pts.len()];
            let mut grads = vec![DVec3::ZERO; pts.len()];
            let mut evals = 0;
            for _ in 0..8 {
                field.eval_grad_many(pts, &mut vals, &mut grads);
                evals += pts.len() as u64;
                let mut moved = false;
                for ((p, (lo, hi)), (f, g)) in pts.iter_mut().zip(bxs).zip(vals.iter().zip(&grads))
                {
                    let g2 = g.length_squared();
                    if !(f.is_finite() && g2 > 0.0 && g2.is_finite()) {
                        continue;
                    }
                    let step = *g * (*f / g2);
                    if step.length() > tolerance {
                        moved = true;
                    }
                    *p = (*p - step).clamp(*lo, *hi);
                }
                if !moved {
                    break;
                }
            }
            evals
        })
        .sum()
}

/// Unit normals from the field's gradient at each position; where the gradient vanishes or
/// is not finite, the area-weighted normal of the surrounding triangles instead. Returns the
/// normals and the field evaluations made (a gradient counts as one).
pub fn gradient_normals(
    field: &dyn Field,
    positions: &[DVec3],
    triangles: &[[u32; 3]],
) -> (Vec<[f32; 3]>, u64) {
    let mut normals = unit_gradients(field, positions);
    fill_from_faces(&mut normals, positions, triangles);
    (normals, positions.len() as u64)
}

/// The field's unit gradient at each position (a batch per chunk, in parallel), or zero
/// where it vanishes or is not finite. Each point's value is its own, whatever the chunks.
pub(crate) fn unit_gradients(field: &dyn Field, positions: &[DVec3]) -> Vec<[f32; 3]> {
    let mut normals = vec![[0f32; 3]; positions.len()];
    normals.par_chunks_mut(CHUNK).zip(positions.par_chunks(CHUNK)).for_each(|(out, pts)| {
        let mut vals = vec![0.0; pts.len()];
        let mut grads = vec![DVec3::ZERO; pts.len()];
        field.eval_grad_many(pts, &mut vals, &mut grads);
        for (o, g) in out.iter_mut().zip(&grads) {
            *o = unit_normal(*g);
        }
    });
    normals
}

/// A gradient as a unit normal, or zero where it vanishes or is not finite (the mark that
/// [`fill_from_faces`] replaces).
pub(crate) fn unit_normal(g: DVec3) -> [f32; 3] {
    let n = g.normalize_or_zero();
    if n.is_finite() { n.as_vec3().to_array() } else { [0.0; 3] }
}

/// Replaces the zero normals (no gradient there) by the area-weighted normal of the
/// surrounding triangles.
pub(crate) fn fill_from_faces(
    normals: &mut [[f32; 3]],
    positions: &[DVec3],
    triangles: &[[u32; 3]],
) {
    if normals.contains(&[0.0; 3]) {
        let face = face_normals(positions, triangles);
        for (o, f) in normals.iter_mut().zip(face) {
            if *o == [0.0; 3] {
                *o = f;
            }
        }
    }
}

/// Area-weighted vertex normals from the triangles alone.
pub fn face_normals(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut acc = vec![DVec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            acc[i as usize] += n;
        }
    }
    acc.into_iter().map(|n| n.normalize_or_zero().as_vec3().to_array()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::FnField;

    #[test]
    fn roots_converge_to_the_surface() {
        let f = FnField(|p: DVec3| p.length() - 1.0);
        let mut b: Vec<Bracket> = (0..100)
            .map(|i| {
                let d = DVec3::new(1.0, i as f64 / 50.0, 0.3).normalize();
                let (p0, p1) = (d * 0.5, d * 1.7);
                Bracket { p0, p1, f0: f.eval(p0), f1: f.eval(p1), t: 0.5 }
            })
            .collect();
        let opts = RootOptions { tolerance: 1e-9, ..RootOptions::default() };
        let evals = refine_roots(&f, &mut b, &opts);
        for br in &b {
            let p = br.p0.lerp(br.p1, br.t);
            assert!((p.length() - 1.0).abs() < 1e-8, "{}", p.length());
        }
        assert!(evals < 100 * 12, "Illinois converges in few steps: {evals}");
    }

    /// With the default tolerance, the secant estimate stops after about two evaluations
    /// per vertex, and the vertices are far closer to the surface than the tolerance.
    #[test]
    fn secant_stop_is_cheap_and_accurate() {
        let f = FnField(|p: DVec3| p.length() - 1.0);
        let cell = 0.05;
        let mut b: Vec<Bracket> = (0..500)
            .map(|i| {
                let d = DVec3::new(1.0, (i as f64 * 0.37).sin(), (i as f64 * 0.11).cos());
                let d = d.normalize();
                let p0 = d * (1.0 - cell * (0.1 + 0.8 * ((i * 7 % 13) as f64 / 13.0)));
                let p1 = p0 + DVec3::new(cell, 0.0, 0.0);
                Bracket { p0, p1, f0: f.eval(p0), f1: f.eval(p1), t: 0.5 }
            })
            .filter(|b| (b.f0 < 0.0) != (b.f1 < 0.0))
            .collect();
        assert!(b.len() > 100);
        let evals = refine_roots(&f, &mut b, &RootOptions::default());
        assert!(evals as f64 / (b.len() as f64) < 2.5, "{evals} for {}", b.len());
        for br in &b {
            let p = br.p0.lerp(br.p1, br.t);
            assert!((p.length() - 1.0).abs() < 1e-2 * 1e-4 * cell, "{}", p.length() - 1.0);
        }
    }

    /// From the ends' values and gradients, about one evaluation per vertex puts the
    /// vertices within a hundredth of the tolerance of the surface (as the secant stop of
    /// regula falsi does at two), and the gradient returned is the field's near the vertex.
    #[test]
    fn gradients_at_the_ends_need_about_one_evaluation() {
        let f = skelform_field::formula::Formula::parse(
            "sqrt(x^2 + 2*y^2 + z^2) - 0.7 + 0.05*sin(9*x)*cos(7*z)",
        )
        .unwrap();
        assert!(f.has_exact_gradient());
        let cell = 0.05;
        // Lattice segments along x, each where the field changes sign.
        let mut b: Vec<GradBracket> = Vec::new();
        for i in 0..600 {
            let (y, z) = ((i as f64 * 0.37).sin() * 0.45, (i as f64 * 0.11).cos() * 0.45);
            let p0 = DVec3::new(0.0, y, z);
            let p1 = (0..40).map(|k| p0 + DVec3::X * (cell * k as f64));
            let pairs = p1.clone().zip(p1.skip(1));
            if let Some((p0, p1)) =
                pairs.into_iter().find(|(a, b)| (f.eval(*a) < 0.0) != (f.eval(*b) < 0.0))
            {
                let (f0, f1) = (f.eval(p0), f.eval(p1));
                let (g0, g1) = (f.gradient(p0), f.gradient(p1));
                b.push(GradBracket { p0, p1, f0, f1, g0, g1, t: 0.5, grad: DVec3::ZERO });
            }
        }
        assert!(b.len() > 100);
        let opts = RootOptions::default();
        let evals = refine_roots_with_gradients(&f, &mut b, &opts, None);
        assert!(evals as f64 / (b.len() as f64) < 1.2, "{evals} for {}", b.len());
        for br in &b {
            let p = br.p0.lerp(br.p1, br.t);
            let distance = f.eval(p).abs() / f.gradient(p).length();
            assert!(distance < 1e-2 * opts.tolerance * cell, "{distance}");
            let angle = br.grad.angle_between(f.gradient(p));
            assert!(angle < 1e-3, "{angle}");
        }
    }

    /// On each line the zero nearest the start is found, on either side, to the tolerance;
    /// a line on which the field keeps its sign gives none, and a segment's bounds are kept.
    #[test]
    fn lines_find_the_nearest_zero_within_their_segment() {
        // Zeros at x = 0.3 and x = 0.8 on the x axis (planes), none on the y axis segment.
        let f = FnField(|p: DVec3| (p.x - 0.3) * (p.x - 0.8) + p.y * p.y + 0.01 * p.z);
        let line = |x: f64, back: f64, ahead: f64| Line {
            p: DVec3::new(x, 0.0, 0.0),
            dir: DVec3::X,
            back,
            ahead,
        };
        let lines = [
            line(0.5, 1.0, 1.0), // 0.3 is nearer than 0.8
            line(0.6, 1.0, 1.0), // 0.8 is nearer
            line(0.5, 0.1, 1.0), // 0.3 out of reach behind: 0.8
            line(0.5, 0.1, 0.2), // neither within reach
            Line { p: DVec3::new(0.5, 2.0, 0.0), dir: DVec3::Y, back: 0.5, ahead: 0.5 },
        ];
        let (zeros, evals) = roots_on_lines(&f, &lines, 1.0 / 32.0, 1e-9);
        let xs: Vec<Option<f64>> = zeros.iter().map(|z| z.map(|p| p.x)).collect();
        for (got, want) in xs.iter().zip([Some(0.3), Some(0.8), Some(0.8), None, None]) {
            match (got, want) {
                (Some(g), Some(w)) => assert!((g - w).abs() < 1e-8, "{xs:?}"),
                (g, w) => assert_eq!(*g, w, "{xs:?}"),
            }
        }
        assert!(evals < 5 * 40, "{evals}");
    }

    #[test]
    fn bisection_takes_one_bit_per_step() {
        let f = FnField(|p: DVec3| p.x - 0.3);
        let mut b = [Bracket { p0: DVec3::ZERO, p1: DVec3::X, f0: -0.3, f1: 0.7, t: 0.3 }];
        let opts = RootOptions {
            method: RootMethod::Bisection,
            tolerance: 1.0 / 1024.0,
            ..RootOptions::default()
        };
        assert_eq!(refine_roots(&f, &mut b, &opts), 10);
        assert!((b[0].t - 0.3).abs() < 1.0 / 1024.0);
    }

    #[test]
    fn nan_stops_refinement_without_panic() {
        let f = FnField(|p: DVec3| if p.x > 0.4 && p.x < 0.6 { f64::NAN } else { p.x - 0.5 });
        let mut b = [Bracket { p0: DVec3::ZERO, p1: DVec3::X, f0: -0.5, f1: 0.5, t: 0.5 }];
        refine_roots(&f, &mut b, &RootOptions::default());
        assert!(b[0].t.is_finite());
    }
}
