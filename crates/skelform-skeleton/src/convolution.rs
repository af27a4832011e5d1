//! Convolution of one skeletal element with a kernel: `∫_S k(|p − u|/r) du`, normalised.
//!
//! * **Point** (DIS eq. 5.19): `k(|p − c|/r)`.
//! * **Segment** (DIS §5.6.3–5.6.6): the exact line integral. With `τ` the position of `p`'s
//!   projection along the segment and `d` its distance to the segment's *line*, the integral
//!   is `∫_{−τ}^{L−τ} k(√(d² + t²)) dt` — for the Gaussian the dissertation's "integration
//!   filter × distance filter", `e^{−ω d²}·(erf difference)`; for the other kernels a closed
//!   form too (see [`crate::kernel`]). Divided by [`Kernel::line_norm`], so a long segment of
//!   radius `r` has its iso-½ surface at distance `r` and its ends on the surface.
//! * **Polygon** (DIS ch. 6 and the untried analytic route of §6.2): the exact area
//!   integral, by splitting the polygon into signed wedges from the query point's projection
//!   `q`. In polar coordinates about `q` the radial integral of any radial kernel is closed
//!   form — `∫_0^R k(√(z² + ρ²)) ρ dρ = T(|z|) − T(√(z² + R²))` with `T` the kernel's
//!   [tail](Kernel::tail) — so what remains is, per edge, one integral over the angle the
//!   edge subtends. For the Wyvill and triweight kernels (polynomials in `s²`) that integral
//!   is closed form too (powers of `tan φ` and `φ`); for the Gaussian it is Owen's T
//!   function, computed from `erf`s and one fixed 20-point Gauss–Legendre rule
//!   ([`crate::gauss_edge`]); for the B-spline it is smooth and done by adaptive
//!   Gauss–Kronrod quadrature (each interval refined until the Gauss and Kronrod estimates
//!   agree to 10⁻¹² of the integrand's peak, which leaves the Kronrod value far more
//!   accurate than that; [`convolve_adaptive`] takes this route for the Gaussian too). The angles themselves add up to
//!   `2π·winding`, which is snapped to the exact multiple.
//!   Divided by [`Kernel::area_norm`], so a large polygon of radius `r` is a slab of
//!   half-thickness `r`.
//!
//! Gradients are analytic: `∂/∂τ` of a segment integral is the kernel at the two ends, `∂/∂d²`
//! is the line integral of `dk/d(s²)`; the in-plane gradient of a polygon integral is, by the
//! divergence theorem, minus the sum over edges of the outward normal times the edge's line
//! integral (closed form), and the normal derivative is one more angle integral of `k`.

use std::f64::consts::TAU;

use glam::{DVec2, DVec3};

use crate::gauss_edge::edge_part;
use crate::geometry::{Polygon, Segment, Shape};
use crate::kernel::{Kernel, OMEGA};
use crate::quad::integrate;

/// Relative accuracy asked of each edge's angle integral.
const EDGE_RTOL: f64 = 1e-12;

/// A segment ready for evaluation.
#[derive(Clone, Debug)]
pub(crate) struct PreparedSegment {
    a: DVec3,
    u: DVec3,
    /// Length in world units.
    length: f64,
    inv_r: f64,
    /// `strength / line_norm`, or `strength / ∫ k` when separable.
    scale: f64,
    /// The dissertation's separable approximation instead of the exact line integral.
    separable: bool,
    strength: f64,
}

impl PreparedSegment {
    /// Switches to the dissertation's separable approximation of the segment's convolution
    /// (DIS §5.6.10, figs. 5.52 and 5.53): the "product of filters" `k(d)·∫_{−τ}^{L−τ} k(t) dt /
    /// ∫_ℝ k`, the kernel of the distance to the segment's line times the kernel integrated
    /// along it. Exact for the Gaussian (`e^{−ω(d² + t²)} = e^{−ωd²}e^{−ωt²}`), an
    /// approximation for the others; its normalisation keeps a long segment's surface at
    /// one radius, as the exact one does.
    pub(crate) fn set_separable(&mut self, kernel: Kernel, on: bool) {
        self.separable = on;
        self.scale = self.strength
            / if on {
                kernel.line_integral(0.0, f64::NEG_INFINITY, f64::INFINITY).0
            } else {
                kernel.line_norm()
            };
    }

    pub(crate) fn new(kernel: Kernel, s: &Segment, radius: f64, strength: f64) -> Self {
        PreparedSegment {
            a: s.a(),
            u: s.direction(),
            length: s.length(),
            inv_r: 1.0 / radius,
            scale: strength / kernel.line_norm(),
            separable: false,
            strength,
        }
    }

    pub(crate) fn eval(&self, kernel: Kernel, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        let (v, g, _) = self.eval_at(kernel, p, self.inv_r, want_grad);
        (v, g)
    }

    /// The value at `p` with the radius `1/inv_r` instead of the segment's own, its
    /// gradient at that fixed radius, and the derivative with respect to the radius (for
    /// tapered segments, whose radius depends on `p`). The integral depends on the radius
    /// only through `w = (p − a)/r` and the length in radii `ℓ = L/r`, so
    /// `∂v/∂r = −(∇_w I·w + ∂I/∂ℓ·ℓ)/r` with `∂I/∂ℓ` the kernel at the far end.
    pub(crate) fn eval_at(
        &self,
        kernel: Kernel,
        p: DVec3,
        inv_r: f64,
        want_grad: bool,
    ) -> (f64, DVec3, f64) {
        // A copy for each closed-form kernel with the kernel a constant there, as for
        // polygons (`PreparedPolygon::eval`): the kernel's values and its line integral are
        // called without dispatching on the kernel. Same arithmetic, same bits.
        match kernel {
            Kernel::Wyvill => self.eval_at_wyvill(p, inv_r, want_grad),
            Kernel::Triweight => self.eval_at_triweight(p, inv_r, want_grad),
            _ => self.eval_at_in(kernel, p, inv_r, want_grad),
        }
    }

    /// [`PreparedSegment::eval_at`] for the Wyvill kernel: a function of its own, so that
    /// the optimiser cannot merge it with the other kernels' copies again.
    #[inline(never)]
    fn eval_at_wyvill(&self, p: DVec3, inv_r: f64, want_grad: bool) -> (f64, DVec3, f64) {
        self.eval_at_in(Kernel::Wyvill, p, inv_r, want_grad)
    }

    /// [`PreparedSegment::eval_at`] for the triweight kernel (see `eval_at_wyvill`).
    #[inline(never)]
    fn eval_at_triweight(&self, p: DVec3, inv_r: f64, want_grad: bool) -> (f64, DVec3, f64) {
        self.eval_at_in(Kernel::Triweight, p, inv_r, want_grad)
    }

    /// [`PreparedSegment::eval_at`] with the kernel unknown to the compiler: the reference
    /// the specialised copies are tested against.
    #[cfg(test)]
    #[inline(never)]
    fn eval_at_generic(
        &self,
        kernel: Kernel,
        p: DVec3,
        inv_r: f64,
        want_grad: bool,
    ) -> (f64, DVec3, f64) {
        self.eval_at_in(std::hint::black_box(kernel), p, inv_r, want_grad)
    }

    #[inline(always)]
    fn eval_at_in(
        &self,
        kernel: Kernel,
        p: DVec3,
        inv_r: f64,
        want_grad: bool,
    ) -> (f64, DVec3, f64) {
        let w = (p - self.a) * inv_r;
        let len = self.length * inv_r;
        let tau = w.dot(self.u);
        let perp = w - tau * self.u;
        let d2 = perp.length_squared();
        if self.separable {
            let (kd, dkd) = kernel.value_d(d2);
            let along = kernel.line_integral(0.0, -tau, len - tau).0;
            if !want_grad {
                return (self.scale * kd * along, DVec3::ZERO, 0.0);
            }
            let ka = kernel.value(tau * tau);
            let kb = kernel.value((len - tau) * (len - tau));
            let gw = kd * (ka - kb) * self.u + 2.0 * dkd * along * perp;
            let dv_dr = -self.scale * inv_r * (gw.dot(w) + kd * kb * len);
            return (self.scale * kd * along, gw * (self.scale * inv_r), dv_dr);
        }
        let (v, dv) = kernel.line_integral(d2, -tau, len - tau);
        if !want_grad {
            return (self.scale * v, DVec3::ZERO, 0.0);
        }
        let ka = kernel.value(w.length_squared());
        let kb = kernel.value((w - len * self.u).length_squared());
        let gw = (ka - kb) * self.u + 2.0 * dv * perp;
        let dv_dr = -self.scale * inv_r * (gw.dot(w) + kb * len);
        (self.scale * v, gw * (self.scale * inv_r), dv_dr)
    }
}

/// One polygon edge, in radii, in the plane frame.
#[derive(Clone, Copy, Debug)]
struct Edge {
    start: DVec2,
    dir: DVec2,
    len: f64,
    /// The `y` of the edge's end, the next edge's start (the same bits): read by the
    /// crossing count without indexing the next edge.
    end_y: f64,
}

/// A polygon ready for evaluation.
#[derive(Clone, Debug)]
pub(crate) struct PreparedPolygon {
    origin: DVec3,
    e1: DVec3,
    e2: DVec3,
    n: DVec3,
    edges: Vec<Edge>,
    inv_r: f64,
    /// `strength / area_norm`.
    scale: f64,
    /// Gaussian edges by adaptive quadrature instead of [`crate::gauss_edge`].
    adaptive: bool,
}

impl PreparedPolygon {
    pub(crate) fn new(kernel: Kernel, poly: &Polygon, radius: f64, strength: f64) -> Self {
        let (e1, e2, n) = poly.frame();
        let flat = poly.flat_vertices();
        let k = flat.len();
        let edges = (0..k)
            .map(|i| {
                let a = flat[i] / radius;
                let b = flat[(i + 1) % k] / radius;
                let len = (b - a).length();
                Edge { start: a, dir: (b - a) / len, len, end_y: b.y }
            })
            .collect();
        PreparedPolygon {
            origin: poly.origin(),
            e1,
            e2,
            n,
            edges,
            inv_r: 1.0 / radius,
            scale: strength / kernel.area_norm(),
            adaptive: false,
        }
    }

    /// The angle the polygon winds about `q`, summed from each edge's arc tangents: `2π`
    /// times the winding number, but `π` on an edge and the interior angle at a vertex.
    fn winding_angle(&self, q: DVec2) -> f64 {
        let mut theta = 0.0;
        for e in &self.edges {
            let rel = e.start - q;
            let ta = rel.dot(e.dir);
            let hs = rel.perp_dot(e.dir);
            if hs != 0.0 {
                let h = hs.abs();
                theta += hs.signum() * ((ta + e.len).atan2(h) - ta.atan2(h));
            }
        }
        theta
    }

    pub(crate) fn eval(&self, kernel: Kernel, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        // One copy of the evaluation for each of the closed-form kernels, with the kernel a
        // constant there: its support, its polynomials' coefficients (most of them zero)
        // and its line integral fold into the code. Why: the hand's polygons were a third
        // of meshing it. The arithmetic is the same, so the values are the same to the bit.
        match (kernel, self.adaptive) {
            (Kernel::Wyvill, false) => self.eval_wyvill(p, want_grad),
            (Kernel::Triweight, false) => self.eval_triweight(p, want_grad),
            _ => self.eval_in(kernel, p, want_grad),
        }
    }

    /// [`PreparedPolygon::eval`] for the Wyvill kernel: a function of its own, so that the
    /// optimiser cannot merge it with the other kernels' copies again.
    #[inline(never)]
    fn eval_wyvill(&self, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        self.eval_in(Kernel::Wyvill, p, want_grad)
    }

    /// [`PreparedPolygon::eval`] for the triweight kernel (see `eval_wyvill`).
    #[inline(never)]
    fn eval_triweight(&self, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        self.eval_in(Kernel::Triweight, p, want_grad)
    }

    /// [`PreparedPolygon::eval`] with the kernel unknown to the compiler: the reference the
    /// specialised copies are tested against.
    #[cfg(test)]
    #[inline(never)]
    fn eval_generic(&self, kernel: Kernel, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        self.eval_in(std::hint::black_box(kernel), p, want_grad)
    }

    #[inline(always)]
    fn eval_in(&self, kernel: Kernel, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        let w = (p - self.origin) * self.inv_r;
        let q = DVec2::new(w.dot(self.e1), w.dot(self.e2));
        let z = w.dot(self.n);
        let z2 = z * z;
        let support2 = kernel.support() * kernel.support();
        // A piecewise-polynomial kernel is zero beyond its support, and so is its line
        // integral along any line that far away (`Kernel::line_integral` skips every piece).
        let finite_support = matches!(kernel, Kernel::Wyvill | Kernel::Triweight | Kernel::BSpline);
        // Beyond the kernel's reach of the polygon's plane every edge is skipped below
        // (`z² + h² ≥ z²`), so the value is `T(|z|)·θ`: exactly zero where the tail is, and
        // the winding angle θ (two arc tangents per edge) need not be computed. The gradient
        // is zero there too for a kernel of finite support (its edge terms are line
        // integrals beyond the support, its normal term `k(|z|) = 0`), not for the Gaussian
        // (its line integral is not cut off). The sums this is added to never hold −0, so
        // returning +0 for the ±0 the loop would give changes no bit of a field value.
        if (!want_grad || finite_support) && z2 >= support2 && kernel.tail(z.abs()) == 0.0 {
            return (0.0, DVec3::ZERO);
        }
        let mut tail_sum = 0.0;
        let mut k_sum = 0.0;
        let mut grad_q = DVec2::ZERO;
        // The angles the edges subtend add up to 2π times the winding number of the
        // polygon about `q`, so it is counted by crossings rather than summed from arc
        // tangents; only when `q` lies on or next to an edge's line are the angles summed
        // after all.
        let mut winding = 0i32;
        let mut on_a_line = false;
        let poly = if self.adaptive { None } else { kernel.w_polynomial() };
        // With a polynomial kernel, the wedges' polynomial parts and the angles they span
        // (summed as one product, see `Turning`).
        let (mut poly_tail, mut poly_k) = (0.0, 0.0);
        let mut turning = Turning::new();
        for e in &self.edges {
            let rel = e.start - q;
            let ta = rel.dot(e.dir);
            let tb = ta + e.len;
            let hs = rel.perp_dot(e.dir);
            let h = hs.abs();
            // An edge whose line is beyond a kernel of finite support has a line integral
            // of exactly zero, so it is not computed: most of a polygon's edges, seen from
            // most lattice points.
            if want_grad && (z2 + h * h < support2 || !finite_support) {
                // Divergence theorem: ∇_q ∫_P k = −Σ n_out ∫_edge k.
                let n_out = DVec2::new(e.dir.y, -e.dir.x);
                grad_q -= n_out * kernel.line_integral_value(z2 + h * h, ta, tb);
            }
            if h < 1e-9 {
                // Near an edge's line, rounding could give the crossing test and the
                // wedge's orientation different sides: the angles are summed instead.
                on_a_line = true;
                if h == 0.0 {
                    continue; // q on the edge's line: the wedge has no area
                }
            }
            // Crossings of the ray from q along +e1, counted with the sign of `hs`, the
            // same sign that orients the edge's wedge below, so the two always agree.
            let (ya, yb) = (e.start.y - q.y, e.end_y - q.y);
            if ya <= 0.0 && yb > 0.0 && hs > 0.0 {
                winding += 1;
            } else if ya > 0.0 && yb <= 0.0 && hs < 0.0 {
                winding -= 1;
            }
            if z2 + h * h >= support2 {
                continue; // the whole edge is beyond the kernel's reach
            }
            let sign = hs.signum();
            if let Some((alpha, tail, kern)) = &poly {
                if let Some(w) = wedge_closed(*alpha, tail, kern, z2, h, ta, tb, want_grad) {
                    poly_tail += sign * w.tail;
                    poly_k += sign * w.k;
                    turning.turn(w.angle, hs > 0.0);
                }
                continue;
            }
            if kernel == Kernel::Gaussian && !self.adaptive {
                // T = k/(2ω) for the Gaussian: one integral serves value and gradient.
                let part = (-OMEGA * z2).exp() * (edge_part(h, tb) - edge_part(h, ta));
                tail_sum += sign * part / (2.0 * OMEGA);
                k_sum += sign * part;
                continue;
            }
            let (pa, pb) = (ta.atan2(h), tb.atan2(h));
            tail_sum += sign * edge_integral(kernel, z2, h, pa, pb, false);
            if want_grad {
                k_sum += sign * edge_integral(kernel, z2, h, pa, pb, true);
            }
        }
        let mut theta = TAU * f64::from(winding);
        if on_a_line {
            theta = self.winding_angle(q);
        }
        let turns = (theta / TAU).round();
        if (theta - turns * TAU).abs() < 1e-9 {
            theta = turns * TAU;
        }
        // Each wedge's integral is its polynomial part plus `G(−1)·Δφ`, where `G(−1)` is the
        // kernel's polynomial at `w = 1 − α z²` for every edge alike (`w₀ + b`, see
        // `wedge_closed`): the tail `T(|z|)` and the kernel `k(|z|)` there. So the angles
        // are summed first and multiplied once.
        if let Some((alpha, tail, kern)) = &poly {
            let wz = 1.0 - alpha * z2;
            let at = |c: &[f64; 5]| c.iter().rev().fold(0.0, |acc, &cn| acc * wz + cn);
            let phi = turning.angle();
            tail_sum += poly_tail + at(tail) * phi;
            k_sum += poly_k + at(kern) * phi;
        }
        let az = z.abs();
        let v = kernel.tail(az) * theta - tail_sum;
        if !want_grad {
            return (self.scale * v, DVec3::ZERO);
        }
        let gz = -z * (kernel.value(z2) * theta - k_sum);
        let g = grad_q.x * self.e1 + grad_q.y * self.e2 + gz * self.n;
        (self.scale * v, g * (self.scale * self.inv_r))
    }
}

/// One triangle of a weighted polygon's fan: its unweighted integral, its edges in the
/// parent polygon's frame (radii, counter-clockwise) and its linear weight there.
#[derive(Clone, Debug)]
struct WeightedTriangle {
    /// `∫ k` over the triangle, unnormalised (prepared with `strength = area_norm`).
    plain: PreparedPolygon,
    edges: [Edge; 3],
    /// The weight `c + g·q` at `q` (radii, plane frame): `g` per radius.
    c: f64,
    g: DVec2,
}

/// A polygon whose strength varies linearly over each triangle of a fan (per-vertex weights,
/// DIS §6.4; see [`crate::weights`]), integrated exactly.
///
/// Over one triangle with weight `w(u) = w(q) + g·(u − q)` (`q` the query point's
/// projection, `z` its height) the density is `F = w(q)·A₀ + g·J` with `A₀ = ∫ k` (the
/// unweighted closed form) and `J = ∫ (u − q)·k(√(z² + |u − q|²)) du`. Since
/// `(u − q)·k = −∇_u T(σ)` (`T` the kernel's [tail](Kernel::tail)), the divergence theorem
/// gives `J = −Σ_edges n_out ∫_edge T ds`: one line integral of the tail per edge, closed
/// form for the Gaussian (`T = k/2ω`), the Wyvill and the triweight kernels (a polynomial
/// in `t²`), and by adaptive Gauss–Kronrod quadrature (split at the kernel's breakpoints,
/// to 10⁻¹² of the integrand's peak) for the B-spline. The
/// gradient is closed form: in the plane `∇F = g·A₀ − Σ n_out ∫_edge w·k ds`, where along an
/// edge `∫ t·k dt` is a difference of tails; normal to it `∂F/∂z = w(q)·∂A₀/∂z +
/// z·g·Σ n_out ∫_edge k ds`.
#[derive(Clone, Debug)]
pub(crate) struct PreparedWeighted {
    origin: DVec3,
    e1: DVec3,
    e2: DVec3,
    n: DVec3,
    tris: Vec<WeightedTriangle>,
    radius: f64,
    /// `strength / area_norm`.
    scale: f64,
}

impl PreparedWeighted {
    /// `weights` already checked against `poly` ([`crate::weights`]).
    pub(crate) fn new(
        kernel: Kernel,
        poly: &Polygon,
        weights: &[f64],
        radius: f64,
        strength: f64,
    ) -> Self {
        let (e1, e2, n) = poly.frame();
        let origin = poly.origin();
        let flat = poly.flat_vertices();
        let pieces = crate::weights::fan_pieces(poly, weights);
        let verts = poly.vertices();
        let k = flat.len();
        let mut tris = Vec::with_capacity(k);
        for (i, piece) in pieces.iter().enumerate() {
            let j = (i + 1) % k;
            // Checked star-shaped, so the fan triangle has area; skip it otherwise rather
            // than fail (a caller may have moved the shape after the check).
            let Ok(t) = Polygon::triangle(origin, verts[i], verts[j]) else {
                continue;
            };
            let corners = [DVec2::ZERO, flat[i] / radius, flat[j] / radius];
            let edges = std::array::from_fn(|m| {
                let (a, b) = (corners[m], corners[(m + 1) % 3]);
                let len = (b - a).length();
                Edge { start: a, dir: (b - a) / len, len, end_y: b.y }
            });
            tris.push(WeightedTriangle {
                plain: PreparedPolygon::new(kernel, &t, radius, kernel.area_norm()),
                edges,
                c: piece.c,
                g: piece.g * radius,
            });
        }
        PreparedWeighted { origin, e1, e2, n, tris, radius, scale: strength / kernel.area_norm() }
    }

    pub(crate) fn eval(&self, kernel: Kernel, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        let inv_r = 1.0 / self.radius;
        let w = (p - self.origin) * inv_r;
        let q = DVec2::new(w.dot(self.e1), w.dot(self.e2));
        let z = w.dot(self.n);
        let z2 = z * z;
        let (mut v, mut grad_q, mut gz) = (0.0, DVec2::ZERO, 0.0);
        for t in &self.tris {
            let (a0, ga0) = t.plain.eval(kernel, p, want_grad);
            let wq = t.c + t.g.dot(q);
            let (mut tail_n, mut wk_n, mut k_n) = (DVec2::ZERO, DVec2::ZERO, DVec2::ZERO);
            for e in &t.edges {
                let rel = e.start - q;
                let ta = rel.dot(e.dir);
                let tb = ta + e.len;
                let h = rel.perp_dot(e.dir);
                let d2 = z2 + h * h;
                let n_out = DVec2::new(e.dir.y, -e.dir.x);
                tail_n += n_out * tail_line_integral(kernel, d2, ta, tb);
                if want_grad {
                    let l0 = kernel.line_integral(d2, ta, tb).0;
                    let l1 =
                        kernel.tail((d2 + ta * ta).sqrt()) - kernel.tail((d2 + tb * tb).sqrt());
                    // The weight along the edge: at its foot (t = 0) plus g·dir per unit t.
                    let foot = wq + t.g.dot(rel - ta * e.dir);
                    wk_n += n_out * (foot * l0 + t.g.dot(e.dir) * l1);
                    k_n += n_out * l0;
                }
            }
            v += wq * a0 - t.g.dot(tail_n);
            if want_grad {
                grad_q += t.g * a0 - wk_n;
                gz += wq * ga0.dot(self.n) * self.radius + z * t.g.dot(k_n);
            }
        }
        if !want_grad {
            return (self.scale * v, DVec3::ZERO);
        }
        let g = grad_q.x * self.e1 + grad_q.y * self.e2 + gz * self.n;
        (self.scale * v, g * (self.scale * inv_r))
    }
}

/// The tail's line integral in closed form for a kernel whose tail is a polynomial
/// `Σ cₙ wⁿ` in `w = 1 − α σ²` on its support (Wyvill, triweight): with `σ² = d² + t²`,
/// `w = w₀ − α t²` (`w₀ = 1 − α d²`), so the integrand is a polynomial in `t²`, integrated
/// term by term between the ends clipped to the support (`α t² ≤ w₀`, so no term is large).
fn tail_line_closed(alpha: f64, tail: &[f64; 5], d2: f64, ta: f64, tb: f64) -> f64 {
    let w0 = 1.0 - alpha * d2;
    if w0 <= 0.0 {
        return 0.0;
    }
    let half = (w0 / alpha).sqrt();
    let (t0, t1) = (ta.max(-half), tb.min(half));
    if t1 <= t0 {
        return 0.0;
    }
    // g_j: coefficients of Σ cₙ (w₀ − α t²)ⁿ in powers of t².
    let g = binomial_powers(tail, w0, -alpha);
    let (s0, s1) = (t0 * t0, t1 * t1);
    let (mut p0, mut p1) = (t0, t1);
    let mut total = 0.0;
    for (j, gj) in g.iter().enumerate() {
        total += gj * (p1 - p0) / (2 * j + 1) as f64;
        p0 *= s0;
        p1 *= s1;
    }
    total
}

/// `∫_{ta}^{tb} T(√(d² + t²)) dt`, the line integral of the kernel's tail: for the Gaussian
/// `T = k/2ω`, so the kernel's own closed form; for the Wyvill and triweight kernels a
/// polynomial ([`tail_line_closed`]); for the B-spline adaptive quadrature, split where `σ`
/// crosses a kernel breakpoint and cut at the support.
fn tail_line_integral(kernel: Kernel, d2: f64, ta: f64, tb: f64) -> f64 {
    if kernel == Kernel::Gaussian {
        return kernel.line_integral(d2, ta, tb).0 / (2.0 * OMEGA);
    }
    if let Some((alpha, tail, _)) = kernel.w_polynomial() {
        return tail_line_closed(alpha, &tail, d2, ta, tb);
    }
    let peak = kernel.tail(d2.sqrt());
    if peak == 0.0 || tb <= ta {
        return 0.0;
    }
    let mut cuts: Vec<f64> = Vec::with_capacity(8);
    let mut limit = f64::INFINITY;
    for b in kernel.breakpoints() {
        let r2 = b * b - d2;
        if r2 <= 0.0 {
            continue;
        }
        let c = r2.sqrt();
        cuts.push(-c);
        cuts.push(c);
        limit = c; // the last breakpoint is the support
    }
    let (lo, hi) = (ta.max(-limit), tb.min(limit));
    if hi <= lo {
        return 0.0;
    }
    cuts.retain(|c| *c > lo && *c < hi);
    cuts.sort_by(f64::total_cmp);
    let f = |t: f64| [kernel.tail((d2 + t * t).sqrt())];
    let tol = [(hi - lo) * (EDGE_RTOL * peak).max(1e-16)];
    let mut total = 0.0;
    let mut x0 = lo;
    for x1 in cuts.into_iter().chain(std::iter::once(hi)) {
        total += integrate(f, x0, x1, tol)[0];
        x0 = x1;
    }
    total
}

/// `∫_{φa}^{φb} F(√(z² + h² sec² φ)) dφ` with `F` the kernel's tail `T` (or the kernel `k`
/// itself when `of_kernel`): one edge's share of a polygon integral. Split where `σ` crosses
/// a kernel breakpoint so that every piece is smooth.
fn edge_integral(kernel: Kernel, z2: f64, h: f64, pa: f64, pb: f64, of_kernel: bool) -> f64 {
    let h2 = h * h;
    if kernel == Kernel::Gaussian {
        // T(σ) = e^{−ωσ²}/(2ω): factor out e^{−ω(z² + h²)} and integrate e^{−ω h² tan² φ}.
        let f = |phi: f64| {
            let t = phi.tan();
            [(-OMEGA * h2 * t * t).exp()]
        };
        let i = integrate(f, pa, pb, [EDGE_RTOL * (pb - pa)])[0];
        let front = (-OMEGA * (z2 + h2)).exp();
        return if of_kernel { front * i } else { front * i / (2.0 * OMEGA) };
    }
    let eval = |sigma2: f64| {
        if of_kernel { kernel.value(sigma2) } else { kernel.tail(sigma2.sqrt()) }
    };
    let peak = eval(z2 + h2);
    if peak == 0.0 {
        return 0.0;
    }
    // Angles where σ reaches each breakpoint b: h·sec φ = √(b² − z²).
    let mut cuts: Vec<f64> = Vec::with_capacity(8);
    let mut limit = f64::INFINITY;
    for b in kernel.breakpoints() {
        let r2 = b * b - z2;
        if r2 <= h2 {
            continue;
        }
        let phi = (h / r2.sqrt()).acos();
        cuts.push(-phi);
        cuts.push(phi);
        limit = phi; // the last breakpoint is the support
    }
    let (lo, hi) = (pa.max(-limit), pb.min(limit));
    if hi <= lo {
        return 0.0;
    }
    cuts.retain(|c| *c > lo && *c < hi);
    cuts.sort_by(f64::total_cmp);
    let f = |phi: f64| {
        let c = phi.cos();
        [eval(z2 + h2 / (c * c))]
    };
    // Relative to the integrand's peak, with a floor at the kernel's rounding level (values
    // are at most k(0) = 1 and T(0) < 1) so that a vanishing integrand cannot demand the
    // impossible.
    let tol = [(hi - lo) * (EDGE_RTOL * peak).max(1e-16)];
    let mut total = 0.0;
    let mut x0 = lo;
    for x1 in cuts.into_iter().chain(std::iter::once(hi)) {
        total += integrate(f, x0, x1, tol)[0];
        x0 = x1;
    }
    total
}

/// One edge's wedge, for [`wedge_closed`]: its integrals less their angle terms, and the
/// angle it spans as a complex number (see [`Turning`]).
struct Wedge {
    /// `∫ Q(x²) dx` of the tail.
    tail: f64,
    /// `∫ Q(x²) dx` of the kernel (0 unless asked for).
    k: f64,
    /// `(h² + t₀t₁, h(t₁ − t₀))`, whose argument (in `[0, π]`) is the angle `Δφ`.
    angle: (f64, f64),
}

/// One edge's wedge in closed form, for a kernel that is a polynomial `Σ cₙ wⁿ` in
/// `w = 1 − α σ²` on its support: the integrals of the tail `T` and (when `want_k`) of the
/// kernel `k` over the angle the edge subtends, `σ = √(z² + h² sec² φ)`. With `x = tan φ`,
/// `σ² = z² + h²(1 + x²)`, so `w = w₀ − b x²` (`w₀ = 1 − α(z² + h²)`, `b = α h²`),
/// `dφ = dx/(1 + x²)`, and the integrand is a polynomial `G(x²)` over `1 + x²`. Dividing,
/// `G(y) = (1 + y) Q(y) + G(−1)`, so the integral is `∫ Q(x²) dx + G(−1)·Δφ`: powers of `x`
/// and the angle itself. Every term is bounded (`b x² ≤ w₀ ≤ 1` on the support), so nothing
/// large cancels. The ends are the edge's ends `ta`, `tb` along it (`x = t/h`) clipped to
/// where `w` reaches 0.
///
/// Only the first part is returned, with the angle as a complex number: `G(−1) = Σ cₙ(w₀ +
/// b)ⁿ` is the polynomial at `w = 1 − α z²`, the same for every edge of the polygon, so the
/// caller sums the edges' angles (without an arc tangent each, [`Turning`]) and multiplies
/// once. `None` where the edge is beyond the support.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn wedge_closed(
    alpha: f64,
    tail: &[f64; 5],
    kern: &[f64; 5],
    z2: f64,
    h: f64,
    ta: f64,
    tb: f64,
    want_k: bool,
) -> Option<Wedge> {
    let h2 = h * h;
    let w0 = 1.0 - alpha * (z2 + h2);
    if w0 <= 0.0 {
        return None;
    }
    // Where w reaches 0 along the edge: |t| = √(w₀/α).
    let half = (w0 / alpha).sqrt();
    let (t0, t1) = (ta.max(-half), tb.min(half));
    if t1 <= t0 {
        return None;
    }
    // |x| is bounded by √(w₀/b); the clamp only keeps an edge at a denormal distance finite
    // (its terms are multiplied by powers of b = 0 there).
    let (x0, x1) = ((t0 / h).clamp(-1e30, 1e30), (t1 / h).clamp(-1e30, 1e30));
    // (x1^e − x0^e)/e for e = 1, 3, 5, 7.
    let (s0, s1) = (x0 * x0, x1 * x1);
    let mut d = [0.0f64; 4];
    let (mut p0, mut p1) = (x0, x1);
    for (j, dj) in d.iter_mut().enumerate() {
        *dj = (p1 - p0) / (2 * j + 1) as f64;
        p0 *= s0;
        p1 *= s1;
    }
    let b = alpha * h2;
    Some(Wedge {
        tail: wedge_part(tail, w0, b, &d),
        k: if want_k { wedge_part(kern, w0, b, &d) } else { 0.0 },
        angle: (h2 + t0 * t1, h * (t1 - t0)),
    })
}

/// The coefficients of `Σ cₙ (w₀ + m y)ⁿ` in powers of `y`, expanded by the binomial
/// theorem; a function so that, inlined, the terms of zero coefficients vanish.
#[inline(always)]
fn binomial_powers(c: &[f64; 5], w0: f64, m: f64) -> [f64; 5] {
    let mut g = [0.0f64; 5];
    for (n, &cn) in c.iter().enumerate() {
        if cn == 0.0 {
            continue;
        }
        let mut binom = 1.0;
        for (j, gj) in g.iter_mut().enumerate().take(n + 1) {
            *gj += cn * binom * w0.powi((n - j) as i32) * m.powi(j as i32);
            binom = binom * (n - j) as f64 / (j + 1) as f64;
        }
    }
    g
}

/// `∫ Q(x²) dx` of [`wedge_closed`] for the polynomial `Σ cₙ wⁿ`, `w = w₀ − b x²`, given
/// `d[j] = (x₁^{2j+1} − x₀^{2j+1})/(2j + 1)`. A function, not a closure, so that it is
/// inlined where the coefficients are constants (most of them zero, their terms gone).
#[inline(always)]
fn wedge_part(c: &[f64; 5], w0: f64, b: f64, d: &[f64; 4]) -> f64 {
    // g_j: coefficients of G(y) = Σ cₙ (w₀ − b y)ⁿ in powers of y.
    let g = binomial_powers(c, w0, -b);
    // Synthetic division by (1 + y): q_{m−1} = g_m, q_{j−1} = g_j − q_j.
    let mut q = [0.0f64; 4];
    q[3] = g[4];
    for j in (1..4).rev() {
        q[j - 1] = g[j] - q[j];
    }
    q.iter().zip(d).map(|(qj, dj)| qj * dj).sum::<f64>()
}

/// A sum of angles `±Δφᵢ`, each in `[0, π]` and given as a complex number `cᵢ` of that
/// argument, taken as the argument of the product `Π cᵢ^{±1}` (one arc tangent in all) plus
/// the turns counted as the product goes: a step of at most `π` forward crosses the branch
/// cut at `±π` exactly when it leaves the upper half plane for the lower (backward: the
/// lower for the upper). Why: one arc tangent per polygon edge was a fifth of the time of
/// meshing the hand; a complex product is a few multiplications. The half planes are read
/// from the sign bits (−0 is the lower), as `atan2` reads them, so the count and the final
/// argument agree even on the axis.
struct Turning {
    re: f64,
    im: f64,
    turns: i32,
}

impl Turning {
    fn new() -> Self {
        Turning { re: 1.0, im: 0.0, turns: 0 }
    }

    /// Adds the argument of `(re, im)` (in `[0, π]`), or subtracts it when not `forward`.
    #[inline]
    fn turn(&mut self, (re, im): (f64, f64), forward: bool) {
        if re == 0.0 && im == 0.0 {
            return; // no angle (atan2(0, 0) = 0)
        }
        let im = if forward { im } else { -im };
        let lower = self.im.is_sign_negative();
        let (mut r, mut i) = (self.re * re - self.im * im, self.re * im + self.im * re);
        let m = r.abs().max(i.abs());
        if !(1e-100..=1e100).contains(&m) {
            // Rescaled, rarely, to keep the product in range (the argument is unchanged).
            (r, i) = (r / m, i / m);
        }
        (self.re, self.im) = (r, i);
        match (forward, lower, self.im.is_sign_negative()) {
            (true, false, true) => self.turns += 1,
            (false, true, false) => self.turns -= 1,
            _ => {}
        }
    }

    /// The sum of the angles.
    fn angle(&self) -> f64 {
        if self.turns == 0 && self.im == 0.0 && self.re > 0.0 {
            return 0.0; // no angle given (a point seeing no edge), without the arc tangent
        }
        self.im.atan2(self.re) + TAU * f64::from(self.turns)
    }
}

/// The normalised convolution of one element (strength 1) with `kernel` at `p`, and its
/// gradient: the slow, self-contained path, for tests and one-off use. A lone element of
/// radius `radius` has its surface where this is ½.
///
/// ```
/// use skelform_skeleton::{Kernel, Segment, Shape, convolution::convolve};
/// use glam::DVec3;
/// let s = Shape::Segment(Segment::new(DVec3::ZERO, DVec3::X * 10.0).unwrap());
/// // Half-way along a long segment, one radius away: on the surface.
/// let (v, g) = convolve(Kernel::Gaussian, &s, 0.5, DVec3::new(5.0, 0.5, 0.0));
/// assert!((v - 0.5).abs() < 1e-12);
/// assert!(g.y < 0.0); // the density falls away from the skeleton
/// ```
pub fn convolve(kernel: Kernel, shape: &Shape, radius: f64, p: DVec3) -> (f64, DVec3) {
    match shape {
        Shape::Point(c) => {
            let w = (p - *c) / radius;
            let (k, dk) = kernel.value_d(w.length_squared());
            (k, 2.0 * dk * w / radius)
        }
        Shape::Segment(s) => PreparedSegment::new(kernel, s, radius, 1.0).eval(kernel, p, true),
        Shape::Polygon(poly) => {
            PreparedPolygon::new(kernel, poly, radius, 1.0).eval(kernel, p, true)
        }
    }
}

/// [`convolve`] with every polygon edge integrated by adaptive Gauss–Kronrod quadrature,
/// the Gaussian's too (the default path gives the Gaussian's edges in closed form up to a
/// fixed 20-point rule, [`crate::gauss_edge`]): the reference the fast path is tested
/// against, and the baseline of the `polygon` benchmark.
pub fn convolve_adaptive(kernel: Kernel, shape: &Shape, radius: f64, p: DVec3) -> (f64, DVec3) {
    match shape {
        Shape::Polygon(poly) => {
            let mut prepared = PreparedPolygon::new(kernel, poly, radius, 1.0);
            prepared.adaptive = true;
            prepared.eval(kernel, p, true)
        }
        other => convolve(kernel, other, radius, p),
    }
}

/// The normalised convolution at `p` of a polygon whose strength varies over it:
/// `weights[i]` at vertex `i`, interpolated over the fan from the vertex average (DIS §6.4;
/// see [`crate::weights`]), and its gradient. With every weight 1 it is [`convolve`]'s
/// value.
///
/// ```
/// use skelform_skeleton::{Kernel, Polygon, convolution::{convolve, convolve_weighted}};
/// use skelform_skeleton::Shape;
/// use glam::DVec3;
/// let tri = Polygon::triangle(DVec3::ZERO, DVec3::X, DVec3::Y).unwrap();
/// let p = DVec3::new(0.3, 0.3, 0.1);
/// let (w, _) = convolve_weighted(Kernel::Wyvill, &tri, &[2.0; 3], 0.2, p).unwrap();
/// let (v, _) = convolve(Kernel::Wyvill, &Shape::Polygon(tri), 0.2, p);
/// assert!((w - 2.0 * v).abs() < 1e-12);
/// ```
pub fn convolve_weighted(
    kernel: Kernel,
    poly: &Polygon,
    weights: &[f64],
    radius: f64,
    p: DVec3,
) -> Result<(f64, DVec3), crate::SkeletonError> {
    crate::weights::check_vertex_weights(poly, weights)?;
    Ok(PreparedWeighted::new(kernel, poly, weights, radius, 1.0).eval(kernel, p, true))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kernel-specialised copies of the segment evaluation give the bits of the copy
    /// that cannot see the kernel (`black_box`): value, gradient and radius derivative, exact
    /// and separable, at the segment's radius and others.
    #[test]
    fn specialised_segment_evaluation_equals_the_generic_one_bit_for_bit() {
        let mut unit = crate::kernel::units(0x7f4a_7c15_9e37_79b9);
        let seg = Segment::new(DVec3::new(0.1, -0.2, 0.3), DVec3::new(0.9, 0.4, -0.1)).unwrap();
        for (_, kernel) in Kernel::ALL {
            for separable in [false, true] {
                let mut prepared = PreparedSegment::new(*kernel, &seg, 0.3, 0.7);
                prepared.set_separable(*kernel, separable);
                for i in 0..2000 {
                    let p = DVec3::new(unit(), unit(), unit()) * 2.0 - DVec3::splat(0.5);
                    // The segment's own radius, or another (a tapered segment's).
                    let inv_r = if i % 2 == 0 { 1.0 / 0.3 } else { 1.0 / (0.05 + unit()) };
                    for want_grad in [false, true] {
                        let (v, g, dr) = prepared.eval_at(*kernel, p, inv_r, want_grad);
                        let (rv, rg, rdr) = prepared.eval_at_generic(*kernel, p, inv_r, want_grad);
                        assert_eq!(v.to_bits(), rv.to_bits(), "{kernel:?} {p} {v} {rv}");
                        assert_eq!(dr.to_bits(), rdr.to_bits(), "{kernel:?} {p} {dr} {rdr}");
                        for a in 0..3 {
                            assert_eq!(g[a].to_bits(), rg[a].to_bits(), "{kernel:?} {p} {g} {rg}");
                        }
                    }
                }
            }
        }
    }

    /// The kernel-specialised copies of the polygon evaluation give the bits of the copy
    /// that cannot see the kernel (`black_box`), values and gradients, for every kernel, at
    /// points inside, near, on the edges' lines and beyond the reach of a triangle, a
    /// non-convex polygon and a square.
    #[test]
    fn specialised_polygon_evaluation_equals_the_generic_one_bit_for_bit() {
        let mut unit = crate::kernel::units(0x9e37_79b9_7f4a_7c15);
        let polys = [
            Polygon::triangle(DVec3::ZERO, DVec3::X, DVec3::new(0.2, 0.9, 0.1)).unwrap(),
            Polygon::new(vec![
                DVec3::ZERO,
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.5, 0.3, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ])
            .unwrap(),
            Polygon::new(vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 1.0),
                DVec3::new(0.0, 0.0, 1.0),
            ])
            .unwrap(),
        ];
        for (_, kernel) in Kernel::ALL {
            for poly in &polys {
                let prepared = PreparedPolygon::new(*kernel, poly, 0.3, 1.0);
                let verts = poly.vertices();
                for i in 0..1000 {
                    let p = if i % 10 == 0 {
                        // On an edge's line (often exactly, in the plane frame).
                        let (a, b) = (verts[i % verts.len()], verts[(i + 1) % verts.len()]);
                        a + (b - a) * (3.0 * unit() - 1.0)
                    } else {
                        DVec3::new(unit(), unit(), unit()) * 3.0 - DVec3::splat(1.0)
                    };
                    for want_grad in [false, true] {
                        let (v, g) = prepared.eval(*kernel, p, want_grad);
                        let (rv, rg) = prepared.eval_generic(*kernel, p, want_grad);
                        assert_eq!(v.to_bits(), rv.to_bits(), "{kernel:?} {p} {v} {rv}");
                        for a in 0..3 {
                            assert_eq!(g[a].to_bits(), rg[a].to_bits(), "{kernel:?} {p} {g} {rg}");
                        }
                    }
                }
            }
        }
    }

    /// The product's angle equals the sum of the arc tangents it replaces, across the branch
    /// cut in both directions, many turns round, on the axes (±0 included) and with factors
    /// tiny and large enough to need rescaling.
    #[test]
    fn turning_sums_the_angles_it_is_given() {
        let cases: Vec<Vec<((f64, f64), bool)>> = vec![
            vec![((1.0, 0.0), true)],
            vec![((-1.0, 0.0), true), ((-1.0, 0.0), true)],
            vec![((-1.0, 0.0), false), ((-1.0, 0.0), false), ((0.0, 1.0), false)],
            vec![((-1.0, 1e-300), true); 7],
            vec![((0.3, 2.0), true), ((-2.0, 0.1), true), ((-1.0, 1.0), false), ((0.0, 5.0), true)],
            vec![((1e-200, 1e-200), true), ((-1e200, 1e200), true), ((1e-80, 3e-80), false)],
            vec![((-0.9, 0.2), true); 40],
            vec![((-0.9, 0.2), false); 40],
            vec![((0.0, 0.0), true), ((-1.0, 0.0), false)],
        ];
        for case in cases {
            let mut turning = Turning::new();
            let mut sum = 0.0;
            for &((re, im), forward) in &case {
                turning.turn((re, im), forward);
                let a = im.atan2(re);
                sum += if forward { a } else { -a };
            }
            let got = turning.angle();
            assert!((got - sum).abs() <= 1e-12 * (1.0 + sum.abs()), "{case:?}: {got} vs {sum}");
        }
    }
}
