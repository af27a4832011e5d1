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
const CHUNK: usize = 1024;

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
                RootMethod::RegulaFalsi => (s.a * s.fb - s.b * s.fa) / (s.fb - s.fa),
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
            if let (RootMethod::RegulaFalsi, Some((tp, fp))) = (opts.method, last) {
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

/// Newton steps `p ← p − f ∇f / |∇f|²` towards the surface, each point kept inside its box;
/// a point whose step fails (no gradient, non-finite value) stays where it was. Returns the
/// evaluations made (value and gradient count as one).
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
            let n = g.normalize_or_zero();
            *o = if n == DVec3::ZERO || !n.is_finite() { [0.0; 3] } else { n.as_vec3().to_array() };
        }
    });
    normals
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
