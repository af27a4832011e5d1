//! Local analysis of the field near singular points: value, gradient and Hessian at a point,
//! a damped Gauss–Newton search for points where the surface is singular (`f = 0` and
//! `∇f = 0`), and the classification of such points by their Hessian.
//!
//! Why these numbers: at a regular point of the surface `∇f ≠ 0`. Where two sheets cross,
//! `f` behaves like a product `a·u·v` of the distances to the two sheets, so `∇f` vanishes
//! on the crossing curve and the Hessian there has one zero eigenvalue (along the curve) and
//! two of opposite signs. Where the surface is a bare line (the handle of the Whitney
//! umbrella) the two are of the same sign; at a cone apex none is zero and they have mixed
//! signs; at an isolated point they share one sign; pinch and triple points have fewer than
//! two non-zero eigenvalues.

use glam::{DMat3, DVec3};
use skelform_field::Field;

/// Value, gradient and Hessian at a point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Jet {
    pub f: f64,
    pub g: DVec3,
    pub h: DMat3,
}

/// Evaluates the field for the local analyses and counts the evaluations.
pub(crate) struct Probe<'a> {
    field: &'a dyn Field,
    /// Step of the central differences of the gradient that give the Hessian.
    step: f64,
    pub evals: u64,
}

impl<'a> Probe<'a> {
    /// `cell` sets the scale: the Hessian step is `1e-4` cells.
    pub fn new(field: &'a dyn Field, cell: f64) -> Self {
        Probe { field, step: 1e-4 * cell, evals: 0 }
    }

    /// Values and gradients at several points; `None` if any is not finite.
    pub fn grads(&mut self, pts: &[DVec3]) -> Option<(Vec<f64>, Vec<DVec3>)> {
        let mut v = vec![0.0; pts.len()];
        let mut g = vec![DVec3::ZERO; pts.len()];
        self.field.eval_grad_many(pts, &mut v, &mut g);
        self.evals += pts.len() as u64;
        let ok = v.iter().all(|x| x.is_finite()) && g.iter().all(|x| x.is_finite());
        ok.then_some((v, g))
    }

    pub fn grad(&mut self, p: DVec3) -> Option<(f64, DVec3)> {
        let (v, g) = self.grads(&[p])?;
        Some((v[0], g[0]))
    }

    /// Value, gradient and (by central differences of the gradient) Hessian.
    pub fn jet(&mut self, p: DVec3) -> Option<Jet> {
        let d = self.step;
        let pts = [
            p,
            p + DVec3::X * d,
            p - DVec3::X * d,
            p + DVec3::Y * d,
            p - DVec3::Y * d,
            p + DVec3::Z * d,
            p - DVec3::Z * d,
        ];
        let (v, g) = self.grads(&pts)?;
        let cols =
            [(g[1] - g[2]) / (2.0 * d), (g[3] - g[4]) / (2.0 * d), (g[5] - g[6]) / (2.0 * d)];
        let m = DMat3::from_cols(cols[0], cols[1], cols[2]);
        let h = (m + m.transpose()) * 0.5;
        Some(Jet { f: v[0], g: g[0], h })
    }

    /// How large the gradient gets one `length` away from `p` (the largest of eight probes
    /// along the cube diagonals, which no coordinate-aligned singular set contains): the
    /// scale against which "the gradient vanishes" is judged, and `/length` the scale of the
    /// Hessian.
    pub fn gradient_scale(&mut self, p: DVec3, length: f64) -> Option<f64> {
        let d = length / 3f64.sqrt();
        let pts: Vec<DVec3> = (0..8)
            .map(|i| {
                let s = |b: usize| if i & b == 0 { -d } else { d };
                p + DVec3::new(s(1), s(2), s(4))
            })
            .collect();
        let (_, g) = self.grads(&pts)?;
        Some(g.iter().map(|g| g.length()).fold(0.0, f64::max))
    }
}

/// Eigenvalues and unit eigenvectors of a symmetric matrix, by Jacobi rotations, sorted by
/// increasing absolute value.
pub(crate) fn sym_eigen(m: DMat3) -> ([f64; 3], [DVec3; 3]) {
    let mut a = [[0.0f64; 3]; 3];
    for (i, row) in a.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = m.col(j)[i];
        }
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let diag = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < f64::MIN_POSITIVE {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← Jᵀ A J with the rotation J in the (p, q) plane.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| a[i][i].abs().total_cmp(&a[j][j].abs()));
    let vals = idx.map(|i| a[i][i]);
    let vecs = idx.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize_or_zero());
    (vals, vecs)
}

/// What a singular point is, from its Hessian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Local {
    /// On a curve where two sheets cross; `tangent` along the curve.
    Crossing { tangent: DVec3 },
    /// On a line where the zero set is the line alone (a "handle").
    IsolatedLine { tangent: DVec3 },
    /// Two nappes touching at a point.
    Cone,
    /// The zero set is the point alone near here.
    IsolatedPoint,
    /// Fewer than two non-zero eigenvalues: a pinch point, a triple point, or worse.
    Degenerate,
}

/// Classifies a singular point. `hessian_scale` is the Hessian's size nearby (a gradient one
/// cell away over the cell); eigenvalues under 5% of it count as zero.
pub(crate) fn classify(h: DMat3, hessian_scale: f64) -> Local {
    let (vals, vecs) = sym_eigen(h);
    let thr = 0.05 * hessian_scale;
    let rank = vals.iter().filter(|v| v.abs() > thr).count();
    match rank {
        3 => {
            if vals.iter().all(|&v| v > 0.0) || vals.iter().all(|&v| v < 0.0) {
                Local::IsolatedPoint
            } else {
                Local::Cone
            }
        }
        2 => {
            if vals[1] * vals[2] < 0.0 {
                Local::Crossing { tangent: vecs[0] }
            } else {
                Local::IsolatedLine { tangent: vecs[0] }
            }
        }
        _ => Local::Degenerate,
    }
}

/// A point where the surface is singular, found by [`solve_singular`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Singular {
    pub p: DVec3,
    pub jet: Jet,
}

/// Settings of [`solve_singular`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct SolveOptions {
    /// Length that makes `f` comparable with `∇f` (`f / length`): the cell.
    pub length: f64,
    /// Give up when the point moves further than this from the start.
    pub max_move: f64,
    /// Size of the gradient one cell away: `∇f` counts as zero below `1e-5` of it.
    pub gradient_scale: f64,
    pub iterations: u32,
}

/// Gauss–Newton on `r(p) = (∇f(p), f(p)/length) = 0`, with `p` restricted to
/// `p0 + span(basis)` (one, two or three orthonormal directions: a line, a plane such as a
/// lattice face, or all of space). Returns the point when the residual vanishes to within the
/// tolerances.
///
/// The singular set is usually a curve, along which the Jacobian is (nearly) singular, so the
/// normal equations are solved by eigen-decomposition with the directions of singular values
/// under 3% of the largest left out in space: steps go straight to the nearest point of the
/// curve instead of sliding along it (plain Newton on `∇(xyz)` halves every coordinate and
/// runs to the triple point). Restricted to a plane (one across the curve, or a lattice
/// face) only singular values under 0.1% are left out: there the weak direction is the
/// crossing's own, and leaving it out lost curves whose sheets cross at 20° or less. Steps
/// that do not reduce the residual are halved.
pub(crate) fn solve_singular(
    probe: &mut Probe,
    p0: DVec3,
    basis: &[DVec3],
    o: &SolveOptions,
) -> Option<Singular> {
    let k = basis.len().min(3);
    let tol = 1e-5 * o.gradient_scale;
    let fine = 1e-10 * o.gradient_scale;
    let residual = |j: &Jet| (j.g.length_squared() + (j.f / o.length).powi(2)).sqrt();
    // In space the curve's own direction must be left out (3% of the largest singular
    // value); within a plane across the curve (the march's corrector, a lattice face) there
    // is none, and the weaker of the two directions across a crossing is `tan²(α/2)` of the
    // stronger for sheets at an angle `α` (3% at 20°): only a true degeneracy is left out.
    let cutoff = if k == 3 { 1e-3 } else { 1e-6 };
    let mut p = p0;
    let mut jet = probe.jet(p)?;
    let mut r = residual(&jet);
    for _ in 0..o.iterations {
        if r <= fine {
            break;
        }
        // Columns of J: (H b, (∇f · b) / length).
        let cols: Vec<[f64; 4]> = basis[..k]
            .iter()
            .map(|&b| {
                let hb = jet.h * b;
                [hb.x, hb.y, hb.z, jet.g.dot(b) / o.length]
            })
            .collect();
        let res = [jet.g.x, jet.g.y, jet.g.z, jet.f / o.length];
        // A = JᵀJ and −Jᵀr, padded to 3 × 3.
        let mut a = DMat3::ZERO;
        let mut rhs = DVec3::ZERO;
        for i in 0..k {
            for j in 0..k {
                let v: f64 = (0..4).map(|t| cols[i][t] * cols[j][t]).sum();
                a.col_mut(j)[i] = v;
            }
            rhs[i] = -(0..4).map(|t| cols[i][t] * res[t]).sum::<f64>();
        }
        let (vals, vecs) = sym_eigen(a);
        let top = vals[2].abs();
        if !(top > 0.0 && top.is_finite()) {
            break;
        }
        let mut d = DVec3::ZERO;
        for (l, v) in vals.iter().zip(vecs) {
            if *l > cutoff * top {
                d += v * (v.dot(rhs) / l);
            }
        }
        let mut step = DVec3::ZERO;
        for i in 0..k {
            step += basis[i] * d[i];
        }
        let len = step.length();
        if !(len.is_finite() && len > 0.0) {
            break;
        }
        if len > 0.5 * o.length {
            step *= 0.5 * o.length / len;
        }
        let mut improved = false;
        for _ in 0..12 {
            let q = p + step;
            if (q - p0).length() <= o.max_move
                && let Some(jq) = probe.jet(q)
            {
                let rq = residual(&jq);
                if rq < r {
                    p = q;
                    jet = jq;
                    r = rq;
                    improved = true;
                    break;
                }
            }
            step *= 0.5;
        }
        if !improved {
            break;
        }
    }
    let ok = jet.g.length() <= tol && (jet.f / o.length).abs() <= tol;
    ok.then_some(Singular { p, jet })
}

/// Two unit vectors perpendicular to `t` and to each other.
pub(crate) fn perpendicular_basis(t: DVec3) -> [DVec3; 2] {
    let t = t.normalize_or(DVec3::Z);
    let helper = if t.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
    let a = t.cross(helper).normalize();
    [a, t.cross(a)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::FnField;

    #[test]
    fn eigen_of_a_rotated_diagonal() {
        let r = DMat3::from_rotation_y(0.4) * DMat3::from_rotation_x(-0.7);
        let m = r * DMat3::from_diagonal(DVec3::new(3.0, -0.5, 0.01)) * r.transpose();
        let (vals, vecs) = sym_eigen(m);
        assert!((vals[0] - 0.01).abs() < 1e-12 && (vals[1] + 0.5).abs() < 1e-12);
        assert!((vals[2] - 3.0).abs() < 1e-12);
        for (l, v) in vals.iter().zip(vecs) {
            assert!((m * v - v * *l).length() < 1e-12);
        }
    }

    #[test]
    fn classification_of_the_standard_singularities() {
        type Case = (&'static str, fn(DVec3) -> f64, DVec3);
        let cases: [Case; 5] = [
            ("crossing", |p| p.x * p.y, DVec3::new(0.3, 0.0, 0.0)),
            ("handle", |p| p.x * p.x - p.y * p.y * p.z, DVec3::new(0.0, 0.0, -0.5)),
            ("cone", |p| p.x * p.x + p.y * p.y - p.z * p.z, DVec3::ZERO),
            ("point", |p| p.length_squared(), DVec3::ZERO),
            ("triple", |p| p.x * p.y * p.z, DVec3::ZERO),
        ];
        for (name, f, at) in cases {
            let field = FnField(f);
            let mut probe = Probe::new(&field, 0.1);
            let jet = probe.jet(at).unwrap();
            let scale = probe.gradient_scale(at, 0.1).unwrap() / 0.1;
            let got = classify(jet.h, scale);
            let ok = match name {
                "crossing" => matches!(got, Local::Crossing { tangent } if tangent.z.abs() > 0.999),
                "handle" => {
                    matches!(got, Local::IsolatedLine { tangent } if tangent.z.abs() > 0.999)
                }
                "cone" => got == Local::Cone,
                "point" => got == Local::IsolatedPoint,
                _ => got == Local::Degenerate,
            };
            assert!(ok, "{name}: {got:?}");
        }
    }

    #[test]
    fn singular_points_are_found_in_space_and_on_a_face() {
        let field = FnField(|p: DVec3| p.x * p.y * p.z);
        let mut probe = Probe::new(&field, 0.1);
        let o = SolveOptions { length: 0.1, max_move: 0.3, gradient_scale: 0.01, iterations: 80 };
        let p0 = DVec3::new(0.03, -0.04, 0.05);
        let s = solve_singular(&mut probe, p0, &[DVec3::X, DVec3::Y, DVec3::Z], &o).unwrap();
        // Some point of the three axes near the start.
        let on_axis = |p: DVec3| {
            let a = [p.x.abs(), p.y.abs(), p.z.abs()];
            let mut b = a;
            b.sort_by(f64::total_cmp);
            b[1] < 1e-6
        };
        assert!(on_axis(s.p), "{}", s.p);
        // On the face x = 0.07: the crossing of the y = 0 and z = 0 sheets is (0.07, 0, 0).
        let q0 = DVec3::new(0.07, 0.02, -0.03);
        let s = solve_singular(&mut probe, q0, &[DVec3::Y, DVec3::Z], &o).unwrap();
        assert!((s.p - DVec3::new(0.07, 0.0, 0.0)).length() < 1e-9, "{}", s.p);
        // A regular point is not singular.
        let f = FnField(|p: DVec3| p.x - 0.2);
        let mut probe = Probe::new(&f, 0.1);
        let o = SolveOptions { gradient_scale: 1.0, ..o };
        assert!(
            solve_singular(&mut probe, DVec3::ZERO, &[DVec3::X, DVec3::Y, DVec3::Z], &o).is_none()
        );
    }
}
