//! Convolution kernels and their closed-form integrals.
//!
//! Every kernel is radial, `k(s)` with `s` the distance **in units of the element's radius**,
//! and scaled as in the dissertation's figure 5.54 so that `k(0) = 1` and `k(1) = ½`: a lone
//! point source of radius `r` then has its iso-½ surface at distance `r` whatever the kernel.
//!
//! | kernel | `k(s)` | support | source |
//! |---|---|---|---|
//! | [`Kernel::Gaussian`] | `e^{−ω s²}`, `ω = ln 2` | none (cut at `s = √40`, where `k = 2⁻⁴⁰`) | DIS eq. 5.26, 5.32 |
//! | [`Kernel::Wyvill`] | `W(s/2)`, `W(x) = (9 − 22x² + 17x⁴ − 4x⁶)/9` | `s ≤ 2` | DIS eq. 5.34 (Wyvill's soft objects) |
//! | [`Kernel::Triweight`] | `(1 − s²/R²)³`, `R = 1/√(1 − 2^{−1/3})` | `s ≤ R ≈ 2.20` | the `(1 − x²)³` kernel the chapter also tried \[Wyvill 94\] |
//! | [`Kernel::BSpline`] | `1.5·B(β s)`, `B` the uniform cubic B-spline, `β ≈ 0.72235` | `s ≤ 2/β ≈ 2.77` | DIS eq. 5.31, scaled per fig. 5.54 |
//! | [`Kernel::Sinc`] | `sin(a s)/(a s)`, `sin a / a = ½`, `a ≈ 1.89549` | none (cut at its third zero, `s = 3π/a ≈ 4.97`) | DIS §5.6.8, fig. 5.48; rejected there (fig. 5.49) |
//!
//! The dissertation convolves segments with the non-Gaussian kernels as if they were
//! separable (an integration filter along the segment times a distance filter), which is
//! only an approximation. skelform computes the true line integral `∫ k(|p − u|) du`
//! instead: the Wyvill and triweight kernels are polynomials in `s²` and the B-spline is a
//! polynomial in `s`, so `∫ k(√(d² + t²)) dt` has a closed form (polynomials, `t·s` and
//! `ln(t + s)` terms). The Gaussian's is the dissertation's: `e^{−ω d²}` times an `erf`
//! difference.
//!
//! The sinc is here to show why the dissertation rejected it (§5.6.8): it is not monotone —
//! a negative lobe, then a second positive one — so where elements crowd, the ringing of the
//! summed lobes makes a spurious contour away from the skeleton (fig. 5.49: a row of point
//! sources grows a second shell, at about 3.7 radii, around its surface). It applies to points
//! (a point's convolution is the kernel itself) and to every element under the `sum` blend
//! (the kernel of the distance). Segments and polygons under convolution are refused by
//! [`crate::SkeletonField`] (see [`Kernel::convolves_extended`]); the integrals here still
//! answer for it, by quadrature, so that every kernel has every method.

use std::f64::consts::PI;
use std::str::FromStr;

use crate::quad::integrate;

/// `ω = ln 2`: with it a long Gaussian segment's iso-½ surface lies at exactly one radius
/// (DIS eq. 5.32: `½ − e^{−ω} = 0`).
pub const OMEGA: f64 = std::f64::consts::LN_2;

/// Where the Gaussian is cut off, in radii: `k(√40) = 2⁻⁴⁰ ≈ 9·10⁻¹³`. An element contributes
/// nothing beyond this distance, which is what makes bounding-box culling possible; the
/// jump this leaves in the field is below 10⁻¹² of an element's peak value.
pub const GAUSSIAN_CUTOFF: f64 = 6.324_555_320_336_759;

/// The root in (0, 1) of `3x³ − 6x² + 2 = 0`, where the cubic B-spline is a third of its
/// peak (so `1.5·B(β) = ½`); the dissertation prints it rounded, `.72235`.
const BETA: f64 = 0.722_351_724_464_376_3;

/// `R⁻²` of the triweight kernel: `(1 − s²/R²)³ = ½` at `s = 1`.
const TRI_A: f64 = 0.206_299_474_015_900_2;

/// `a` of the sinc kernel `sin(a s)/(a s)`: the root of `sin a / a = ½`, so that `k(1) = ½`
/// (fig. 5.54's scaling).
const SINC_A: f64 = 1.895_494_267_033_981;

/// Where the sinc is cut, in radii: its third zero, `s = 3π/a ≈ 4.97`. Its tail never dies
/// (the lobes shrink only like `1/s`, and neither its plane nor its volume integral
/// converges), so any cut is a choice. Why this one: at a zero of the sine the field stays
/// continuous (only its slope jumps, by `a/(3π) ≈ 0.2` per radius); it is the first zero
/// that keeps both the negative lobe and the second positive lobe, which are what makes the
/// spurious contours the dissertation rejected the kernel for (a cut at the first zero would
/// leave a plain monotone bump); and ending after a positive lobe (an odd multiple of π)
/// keeps the truncated kernel's plane and volume integrals positive — at an even multiple
/// the plane integral is exactly 0 and the volume integral negative, so a dense cloud of
/// points would have negative density. The reach, 4.97 radii, is within the Gaussian's.
pub const SINC_CUTOFF: f64 = 3.0 * PI / SINC_A;

/// A radial convolution kernel, scaled to `k(0) = 1`, `k(1) = ½` (distance in radii).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Kernel {
    /// `e^{−ln2·s²}`: separable and spherically symmetric, so segment and polygon integrals
    /// are exact products (DIS §5.6). The default.
    #[default]
    Gaussian,
    /// Wyvill's soft-object polynomial (DIS eq. 5.34): finite support, near-circular cross
    /// sections; the dissertation recommends it for polygons.
    Wyvill,
    /// `(1 − x²)³`, scaled; finite support, cheap.
    Triweight,
    /// The uniform cubic B-spline (DIS eq. 5.31), scaled per fig. 5.54.
    BSpline,
    /// `sin(a s)/(a s)` (DIS §5.6.8), scaled per fig. 5.54 and cut at [`SINC_CUTOFF`]: the
    /// ideal low-pass filter, but not monotone, so it makes spurious contours (fig. 5.49).
    /// Points only under convolution; any element under the `sum` blend.
    Sinc,
}

/// One polynomial piece of a kernel: `k(s) = Σ c[n]·sⁿ` for `lo ≤ s ≤ hi`.
#[derive(Clone, Copy, Debug)]
struct Piece {
    lo: f64,
    hi: f64,
    c: [f64; 7],
}

const WYVILL: [Piece; 1] = [Piece {
    lo: 0.0,
    hi: 2.0,
    // W(s/2) = 1 − 22/9·(s²/4) + 17/9·(s⁴/16) − 4/9·(s⁶/64)
    c: [1.0, 0.0, -22.0 / 36.0, 0.0, 17.0 / 144.0, 0.0, -4.0 / 576.0],
}];

const TRIWEIGHT: [Piece; 1] = [Piece {
    lo: 0.0,
    hi: 2.201_663_485_154_594,
    c: [1.0, 0.0, -3.0 * TRI_A, 0.0, 3.0 * TRI_A * TRI_A, 0.0, -TRI_A * TRI_A * TRI_A],
}];

const BSPLINE: [Piece; 2] = [
    // 1.5·(3x³ − 6x² + 4)/6 with x = βs
    Piece {
        lo: 0.0,
        hi: 1.0 / BETA,
        c: [1.0, 0.0, -1.5 * BETA * BETA, 0.75 * BETA * BETA * BETA, 0.0, 0.0, 0.0],
    },
    // 1.5·(2 − x)³/6 = (8 − 12x + 6x² − x³)/4
    Piece {
        lo: 1.0 / BETA,
        hi: 2.0 / BETA,
        c: [2.0, -3.0 * BETA, 1.5 * BETA * BETA, -0.25 * BETA * BETA * BETA, 0.0, 0.0, 0.0],
    },
];

/// A kernel name that is not one of [`Kernel::ALL`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown kernel '{0}'; expected one of: gaussian, wyvill, triweight, bspline, sinc")]
pub struct ParseKernelError(pub String);

impl FromStr for Kernel {
    type Err = ParseKernelError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Kernel::ALL
            .iter()
            .find(|(n, _)| *n == s)
            .map(|(_, k)| *k)
            .ok_or_else(|| ParseKernelError(s.to_string()))
    }
}

impl Kernel {
    /// Every kernel with its scene-file name.
    pub const ALL: &'static [(&'static str, Kernel)] = &[
        ("gaussian", Kernel::Gaussian),
        ("wyvill", Kernel::Wyvill),
        ("triweight", Kernel::Triweight),
        ("bspline", Kernel::BSpline),
        ("sinc", Kernel::Sinc),
    ];

    /// Whether [`crate::SkeletonField`] convolves segments and polygons with this kernel
    /// (points it convolves with every kernel: a point's convolution is the kernel itself).
    /// False for the sinc: it is not separable, so a segment's integral has no closed form
    /// (it would be quadrature at every evaluation), and its plane integral does not
    /// converge — truncated, it is `2π·2cos²(a z/2)/a²` at height `z`, periodic, so a large
    /// polygon would be a stack of slabs 3.3 radii apart up to the cut.
    pub fn convolves_extended(self) -> bool {
        self != Kernel::Sinc
    }

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        Kernel::ALL.iter().find(|(_, k)| *k == self).map_or("?", |(n, _)| n)
    }

    fn pieces(self) -> &'static [Piece] {
        match self {
            Kernel::Wyvill => &WYVILL,
            Kernel::Triweight => &TRIWEIGHT,
            Kernel::BSpline => &BSPLINE,
            Kernel::Gaussian | Kernel::Sinc => &[],
        }
    }

    /// Distance (in radii) beyond which the kernel is zero: exact for the polynomial
    /// kernels, [`GAUSSIAN_CUTOFF`] for the Gaussian, [`SINC_CUTOFF`] for the sinc.
    #[inline]
    pub fn support(self) -> f64 {
        match self {
            Kernel::Gaussian => GAUSSIAN_CUTOFF,
            Kernel::Sinc => SINC_CUTOFF,
            k => k.pieces().last().map_or(0.0, |p| p.hi),
        }
    }

    /// `k(s)` from `s²`.
    #[inline]
    pub fn value(self, s2: f64) -> f64 {
        self.value_d(s2).0
    }

    /// `k` and `dk/d(s²)` from `s²`; both zero outside the support. Evaluated in factored
    /// form (powers of the distance to the support), so values near the support's edge keep
    /// their relative precision.
    #[inline]
    pub fn value_d(self, s2: f64) -> (f64, f64) {
        let s2 = s2.max(0.0);
        match self {
            Kernel::Gaussian => {
                if s2 >= GAUSSIAN_CUTOFF * GAUSSIAN_CUTOFF {
                    return (0.0, 0.0);
                }
                let k = (-OMEGA * s2).exp();
                (k, -OMEGA * k)
            }
            Kernel::Wyvill => {
                // (1 − u)²(9 − 4u)/9 with u = s²/4.
                let u = 0.25 * s2;
                if u >= 1.0 {
                    return (0.0, 0.0);
                }
                let w = 1.0 - u;
                let k = w * w * (9.0 - 4.0 * u) / 9.0;
                // dk/du = (−2w(9 − 4u) − 4w²)/9; du/d(s²) = ¼.
                (k, 0.25 * (-2.0 * w * (9.0 - 4.0 * u) - 4.0 * w * w) / 9.0)
            }
            Kernel::Triweight => {
                let w = 1.0 - TRI_A * s2;
                if w <= 0.0 {
                    return (0.0, 0.0);
                }
                (w * w * w, -3.0 * TRI_A * w * w)
            }
            Kernel::BSpline => {
                let s = s2.sqrt();
                let x = BETA * s;
                if x >= 2.0 {
                    (0.0, 0.0)
                } else if x >= 1.0 {
                    // (2 − x)³/4; dk/d(s²) = dk/ds/(2s) = −3β(2 − x)²/(8s).
                    let y = 2.0 - x;
                    (0.25 * y * y * y, -3.0 * BETA * y * y / (8.0 * s))
                } else {
                    // (3x³ − 6x² + 4)/4; dk/d(s²) = β²(9x − 12)/8.
                    (
                        (3.0 * x * x * x - 6.0 * x * x + 4.0) * 0.25,
                        BETA * BETA * (9.0 * x - 12.0) / 8.0,
                    )
                }
            }
            Kernel::Sinc => {
                let s = s2.sqrt();
                if s >= SINC_CUTOFF {
                    return (0.0, 0.0);
                }
                // k = sin x / x, x = a s; dk/d(s²) = dk/ds/(2s) = a²(x cos x − sin x)/(2x³).
                let x = SINC_A * s;
                if x < 0.5 {
                    // (x cos x − sin x)/x³ cancels near 0: its series, Σ (−1)ⁿ 2n x²ⁿ⁻²/(2n+1)!.
                    let x2 = x * x;
                    let g = SINC_G.iter().rev().fold(0.0, |acc, c| acc * x2 + c);
                    let k = if x == 0.0 { 1.0 } else { x.sin() / x };
                    (k, 0.5 * SINC_A * SINC_A * g)
                } else {
                    let (sn, cs) = x.sin_cos();
                    (sn / x, 0.5 * SINC_A * SINC_A * (x * cs - sn) / (x * x * x))
                }
            }
        }
    }

    /// The line integral `∫_{t1}^{t2} k(√(d² + t²)) dt` and its derivative with respect to
    /// `d²`, `∫ k′(√(d² + t²)) dt` with `k′ = dk/d(s²)`. All lengths in radii; `t1 ≤ t2`
    /// (either may be infinite).
    #[inline]
    pub fn line_integral(self, d2: f64, t1: f64, t2: f64) -> (f64, f64) {
        if t2 <= t1 {
            return (0.0, 0.0);
        }
        // One copy of the piecewise integral per kernel, its pieces constants there: the
        // zero coefficients' terms (most of them: the Wyvill and triweight kernels are even
        // polynomials of degree 6) and the tests on them fold away. Why: on the skeletons'
        // segments and polygon edges this was a sixth to a quarter of a run. The arithmetic
        // on what is left is the same, so the values are the same to the bit.
        match self {
            Kernel::Gaussian => {
                let v = (-OMEGA * d2).exp() * gauss_1d(t1, t2);
                (v, -OMEGA * v)
            }
            Kernel::Sinc => sinc_line_integral(d2.max(0.0), t1, t2),
            Kernel::Wyvill => line_of::<WYVILL_ID>(d2, t1, t2),
            Kernel::Triweight => line_of::<TRIWEIGHT_ID>(d2, t1, t2),
            Kernel::BSpline => line_of::<BSPLINE_ID>(d2, t1, t2),
        }
    }

    /// [`Kernel::line_integral`]'s value alone, the same to the bit: a polygon's gradient
    /// needs only the edges' line integrals, not their derivatives, whose terms (as many
    /// again) are not computed here.
    #[inline]
    pub(crate) fn line_integral_value(self, d2: f64, t1: f64, t2: f64) -> f64 {
        if t2 <= t1 {
            return 0.0;
        }
        match self {
            Kernel::Gaussian => (-OMEGA * d2).exp() * gauss_1d(t1, t2),
            Kernel::Sinc => sinc_line_integral(d2.max(0.0), t1, t2).0,
            Kernel::Wyvill => line_value_of::<WYVILL_ID>(d2, t1, t2),
            Kernel::Triweight => line_value_of::<TRIWEIGHT_ID>(d2, t1, t2),
            Kernel::BSpline => line_value_of::<BSPLINE_ID>(d2, t1, t2),
        }
    }

    /// The radial tail `T(σ) = ∫_σ^∞ k(x)·x dx`, which turns area integrals over a polygon
    /// into one-dimensional integrals over its edges (see [`crate::convolution`]). Closed
    /// forms in powers of the distance to the support, so the tail keeps its relative
    /// precision all the way to zero.
    #[inline]
    pub fn tail(self, sigma: f64) -> f64 {
        let sigma = sigma.max(0.0);
        match self {
            Kernel::Gaussian => {
                if sigma >= GAUSSIAN_CUTOFF {
                    return 0.0;
                }
                (-OMEGA * sigma * sigma).exp() / (2.0 * OMEGA)
            }
            Kernel::Wyvill => {
                // x dx = 2 du, u = x²/4, w = 1 − u: 2/9 ∫_0^{w0} w²(5 + 4w) dw.
                let w0 = (1.0 - 0.25 * sigma * sigma).max(0.0);
                2.0 / 9.0 * (5.0 / 3.0 * w0 * w0 * w0 + w0 * w0 * w0 * w0)
            }
            Kernel::Triweight => {
                let w0 = (1.0 - TRI_A * sigma * sigma).max(0.0);
                w0 * w0 * w0 * w0 / (8.0 * TRI_A)
            }
            Kernel::BSpline => {
                // Outer piece with y = 2 − βx: ∫ y³/4·(2 − y)/β² dy = (y⁴/2 − y⁵/5)/(4β²).
                let outer = |y: f64| (0.5 * y.powi(4) - 0.2 * y.powi(5)) / (4.0 * BETA * BETA);
                let y0 = 2.0 - BETA * sigma;
                if y0 <= 0.0 {
                    0.0
                } else if y0 <= 1.0 {
                    outer(y0)
                } else {
                    let p = &BSPLINE[0];
                    let inner: f64 =
                        p.c.iter()
                            .enumerate()
                            .map(|(n, c)| {
                                let e = n as i32 + 2;
                                c * (p.hi.powi(e) - sigma.powi(e)) / e as f64
                            })
                            .sum();
                    outer(1.0) + inner
                }
            }
            Kernel::Sinc => {
                // ∫ sin(a x)/a dx = (cos(a σ) − cos 3π)/a² = 2cos²(a σ/2)/a²: no cancellation
                // at the cut.
                if sigma >= SINC_CUTOFF {
                    return 0.0;
                }
                let c = (0.5 * SINC_A * sigma).cos();
                2.0 * c * c / (SINC_A * SINC_A)
            }
        }
    }

    /// For kernels that are polynomials in `w = 1 − α·s²` on their support (Wyvill,
    /// triweight): `α`, and the coefficients (in powers of `w`) of the tail `T` and of the
    /// kernel `k`. With them a polygon edge's angle integral has a closed form (see
    /// [`crate::convolution`]).
    #[inline]
    pub(crate) fn w_polynomial(self) -> Option<(f64, [f64; 5], [f64; 5])> {
        match self {
            // T = 2/9·(5/3·w³ + w⁴); k = w²(5 + 4w)/9.
            Kernel::Wyvill => Some((
                0.25,
                [0.0, 0.0, 0.0, 10.0 / 27.0, 2.0 / 9.0],
                [0.0, 0.0, 5.0 / 9.0, 4.0 / 9.0, 0.0],
            )),
            // T = w⁴/(8a); k = w³.
            Kernel::Triweight => {
                Some((TRI_A, [0.0, 0.0, 0.0, 0.0, 1.0 / (8.0 * TRI_A)], [0.0, 0.0, 0.0, 1.0, 0.0]))
            }
            Kernel::Gaussian | Kernel::BSpline | Kernel::Sinc => None,
        }
    }

    /// Breakpoints of the kernel's pieces in `(0, support]`: where a polygon's edge integrand
    /// stops being smooth (for the sinc, its cut).
    pub(crate) fn breakpoints(self) -> impl Iterator<Item = f64> {
        let cut = (self == Kernel::Sinc).then_some(SINC_CUTOFF);
        self.pieces().iter().map(|p| p.hi).chain(cut)
    }

    /// `∫_{−∞}^{∞} k(√(1 + t²)) dt`·2: divides a segment's line integral so that a long
    /// segment of radius `r` has its iso-½ surface at distance `r`. For the Gaussian it is
    /// `√(π/ω)`, the dissertation's normalisation of the integration filter.
    pub fn line_norm(self) -> f64 {
        match self {
            Kernel::Gaussian => (PI / OMEGA).sqrt(),
            k => 2.0 * k.line_integral(1.0, f64::NEG_INFINITY, f64::INFINITY).0,
        }
    }

    /// `∫_{ℝ²} k(√(1 + |u|²)) du`·2 `= 4π·T(1)`: divides a polygon's area integral so that a
    /// large polygon of radius `r` has its iso-½ surfaces at distance `r` on either side. For
    /// the Gaussian it is `π/ω`, the unit-area 2-D filter of DIS eq. 6.1.
    pub fn area_norm(self) -> f64 {
        match self {
            Kernel::Gaussian => PI / OMEGA,
            k => 4.0 * PI * k.tail(1.0),
        }
    }
}

/// `∫_{t1}^{t2} e^{−ω t²} dt` through `erf`, choosing `erfc` differences in the tails so
/// that nothing cancels: `√(π/ω)/2·(erf(√ω t2) − erf(√ω t1))`.
pub(crate) fn gauss_1d(t1: f64, t2: f64) -> f64 {
    let sw = OMEGA.sqrt();
    let (x1, x2) = (sw * t1, sw * t2);
    let diff = if x1 >= 0.0 {
        libm::erfc(x1) - libm::erfc(x2)
    } else if x2 <= 0.0 {
        libm::erfc(-x2) - libm::erfc(-x1)
    } else {
        libm::erf(x2) - libm::erf(x1)
    };
    0.5 * (PI / OMEGA).sqrt() * diff
}

/// Coefficients of `(x cos x − sin x)/x³ = Σ_{n≥1} (−1)ⁿ 2n x²ⁿ⁻²/(2n+1)!` in powers of
/// `x²`; eight terms reach double precision for `x < ½`.
const SINC_G: [f64; 8] = [
    -1.0 / 3.0,
    1.0 / 30.0,
    -1.0 / 840.0,
    1.0 / 45_360.0,
    -1.0 / 3_991_680.0,
    1.0 / 518_918_400.0,
    -1.0 / 93_405_312_000.0,
    1.0 / 22_230_464_256_000.0,
];

/// [`Kernel::line_integral`] for the sinc, which has no closed form: adaptive Gauss–Kronrod
/// quadrature to 10⁻¹³ over the part of `[t1, t2]` within the cut, split at `t = 0` (the
/// integrand is even and smooth in `t` on either side).
fn sinc_line_integral(d2: f64, t1: f64, t2: f64) -> (f64, f64) {
    let reach2 = SINC_CUTOFF * SINC_CUTOFF - d2;
    if reach2 <= 0.0 {
        return (0.0, 0.0);
    }
    let reach = reach2.sqrt();
    let (lo, hi) = (t1.max(-reach), t2.min(reach));
    if hi <= lo {
        return (0.0, 0.0);
    }
    let f = |t: f64| {
        let (k, dk) = Kernel::Sinc.value_d(d2 + t * t);
        [k, dk]
    };
    let tol = [1e-13 * (hi - lo), 1e-13 * (hi - lo)];
    let [v, dv] = if lo < 0.0 && hi > 0.0 {
        let [a, b] = integrate(f, lo, 0.0, tol);
        let [c, d] = integrate(f, 0.0, hi, tol);
        [a + c, b + d]
    } else {
        integrate(f, lo, hi, tol)
    };
    (v, dv)
}

/// The piecewise-polynomial kernels' pieces, by the index each kernel's copies of the line
/// integral are instantiated with ([`line_of`]).
const PIECES: [&[Piece]; 3] = [&WYVILL, &TRIWEIGHT, &BSPLINE];
const WYVILL_ID: usize = 0;
const TRIWEIGHT_ID: usize = 1;
const BSPLINE_ID: usize = 2;

/// [`Kernel::line_integral`] of the kernel whose pieces are `PIECES[K]`, `t1 < t2`: a
/// function of its own for each kernel (never inlined into a `match` over the kernels, where
/// the optimiser would merge the copies back into one that reads the pieces from memory).
#[inline(never)]
fn line_of<const K: usize>(d2: f64, t1: f64, t2: f64) -> (f64, f64) {
    if K == BSPLINE_ID {
        pieces_line_integral::<false>(PIECES[K], d2, t1, t2)
    } else {
        pieces_line_integral::<true>(PIECES[K], d2, t1, t2)
    }
}

/// [`line_of`]'s value alone (the derivative's terms are dead code here).
#[inline(never)]
fn line_value_of<const K: usize>(d2: f64, t1: f64, t2: f64) -> f64 {
    if K == BSPLINE_ID {
        pieces_line_integral::<false>(PIECES[K], d2, t1, t2).0
    } else {
        pieces_line_integral::<true>(PIECES[K], d2, t1, t2).0
    }
}

/// [`Kernel::line_integral`] of a piecewise-polynomial kernel, `t1 < t2`; `EVEN` when every
/// piece is an even polynomial in `s` with no zero coefficient below its degree 6 (the
/// Wyvill and triweight kernels), see [`even_piece_integral`].
#[inline(always)]
fn pieces_line_integral<const EVEN: bool>(
    pieces: &[Piece],
    d2: f64,
    t1: f64,
    t2: f64,
) -> (f64, f64) {
    let mut sums = (0.0, 0.0);
    let d2 = d2.max(0.0);
    // The integrand is even in t: integrate over non-negative t only, reflecting the
    // negative part, so that every log term is ln(t + s) with t ≥ 0 (no cancellation).
    if t2 > 0.0 {
        add_pieces::<EVEN>(pieces, d2, t1.max(0.0), t2, &mut sums);
    }
    if t1 < 0.0 {
        add_pieces::<EVEN>(pieces, d2, (-t2).max(0.0), -t1, &mut sums);
    }
    sums
}

/// Adds `∫_{u1}^{u2}` (`0 ≤ u1`) of each piece's part to `sums` (value, derivative), in
/// order. A function, not a closure, so that it too is inlined into each kernel's copy.
#[inline(always)]
fn add_pieces<const EVEN: bool>(
    pieces: &[Piece],
    d2: f64,
    u1: f64,
    u2: f64,
    sums: &mut (f64, f64),
) {
    for p in pieces {
        if d2 >= p.hi * p.hi {
            continue;
        }
        let tau_lo = (p.lo * p.lo - d2).max(0.0).sqrt();
        let tau_hi = (p.hi * p.hi - d2).sqrt();
        let a = u1.max(tau_lo);
        let b = u2.min(tau_hi);
        if b > a {
            let (pv, pdv) = if EVEN {
                even_piece_integral(&p.c, d2, a, b)
            } else {
                piece_integral(&p.c, d2, a, b)
            };
            sums.0 += pv;
            sums.1 += pdv;
        }
    }
}

/// [`piece_integral`] for a piece `c₀ + c₂s² + c₄s⁴ + c₆s⁶` with none of these zero: the same
/// operations on the same numbers in the same order, so the same bits, without the
/// roots, the logarithm and the odd powers' terms (all multiplied by zero coefficients) and
/// without a test per coefficient. Why: the line integrals of the polygons' edges (their
/// gradients) and of the segments were a sixth to a quarter of meshing the hand and
/// random-1000, most of it in that general loop.
#[inline(always)]
fn even_piece_integral(c: &[f64; 7], d2: f64, a: f64, b: f64) -> (f64, f64) {
    debug_assert!(c[1] == 0.0 && c[3] == 0.0 && c[5] == 0.0);
    debug_assert!(c[0] != 0.0 && c[2] != 0.0 && c[4] != 0.0 && c[6] != 0.0);
    let [j0, j2, j4, j6] = even_moments(d2, a, b);
    let mut v = 0.0;
    v += c[0] * j0;
    v += c[2] * j2;
    v += c[4] * j4;
    v += c[6] * j6;
    let mut dv = 0.0;
    dv += c[2] * 0.5 * 2.0 * j0;
    dv += c[4] * 0.5 * 4.0 * j2;
    dv += c[6] * 0.5 * 6.0 * j4;
    (v, dv)
}

/// `∫_a^b s^{2k} dt` for `k = 0..=3`, `s = √(d² + t²)`, `0 ≤ a < b`: polynomials in `t`.
/// `bⁿ − aⁿ` without cancellation, as `(b − a)·Sₙ` with `Sₙ = Σ b^i a^{n−1−i}`, by
/// `Sₙ₊₁ = b·Sₙ + aⁿ` (all terms ≥ 0 here): a few products instead of fourteen integer
/// powers per call, on every polygon edge's gradient and every segment.
#[inline(always)]
fn even_moments(d2: f64, a: f64, b: f64) -> [f64; 4] {
    let h = b - a;
    let a2 = a * a;
    let s3 = b * b + a * b + a2;
    let s4 = b * s3 + a2 * a;
    let s5 = b * s4 + a2 * a2;
    let s6 = b * s5 + a2 * a2 * a;
    let s7 = b * s6 + a2 * a2 * a2;
    let (p3, p5, p7) = (h * s3, h * s5, h * s7);
    [
        h,
        d2 * h + p3 / 3.0,
        d2 * d2 * h + 2.0 / 3.0 * d2 * p3 + p5 / 5.0,
        d2 * d2 * d2 * h + d2 * d2 * p3 + 0.6 * d2 * p5 + p7 / 7.0,
    ]
}

/// `∫_a^b Σ c_n sⁿ dt` and `∫_a^b Σ c_n (n/2) s^{n−2} dt` with `s = √(d² + t²)`,
/// `0 ≤ a < b`.
#[inline(always)]
fn piece_integral(c: &[f64; 7], d2: f64, a: f64, b: f64) -> (f64, f64) {
    // The roots and the logarithm serve only the odd powers of s (and, through the
    // derivative, the s⁻¹ term of s¹): a piece in even powers alone (the Wyvill and
    // triweight kernels) integrates to a polynomial in t, and skips them. Why: on the
    // skeletons' polygons a logarithm per edge was a twentieth of a run.
    let odd = c[1] != 0.0 || c[3] != 0.0 || c[5] != 0.0;
    let (sa, sb, lg) = if odd {
        let sa = (d2 + a * a).sqrt();
        let sb = (d2 + b * b).sqrt();
        // ln((b + sb)/(a + sa)); only ever multiplied by a power of d² except for the s⁻¹
        // term, which occurs only in pieces away from s = 0 (so a + sa > 0 there).
        let lg = if a + sa > 0.0 { ((b + sb) / (a + sa)).ln() } else { 0.0 };
        (sa, sb, lg)
    } else {
        (0.0, 0.0, 0.0)
    };
    let [j0, j2, j4, j6] = even_moments(d2, a, b);
    let dlg = |m: f64| if d2 > 0.0 { m * lg } else { 0.0 };
    // j(n) = ∫ sⁿ dt for n = −1..=6, each once, at index n + 1 (kernels have no s⁵ term):
    // a few operations each, where a closure called for each term (the derivative's
    // j(n − 2) again) cost more.
    let j = [
        lg,
        j0,
        0.5 * (b * sb - a * sa + dlg(d2)),
        j2,
        (b * sb * (2.0 * b * b + 5.0 * d2) - a * sa * (2.0 * a * a + 5.0 * d2)) / 8.0
            + dlg(0.375 * d2 * d2),
        j4,
        0.0,
        j6,
    ];
    let mut v = 0.0;
    let mut dv = 0.0;
    for (n, &cn) in c.iter().enumerate() {
        if cn == 0.0 {
            continue;
        }
        debug_assert!(n != 5, "kernels have no s^5 term");
        v += cn * j[n + 1];
        if n >= 1 {
            dv += cn * 0.5 * n as f64 * j[n - 1];
        }
    }
    (v, dv)
}

/// Uniform numbers in `[0, 1)` from a xorshift generator seeded with `seed`: the same
/// sequence on every run, for the tests that compare specialised code with its reference.
#[cfg(test)]
pub(crate) fn units(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each kernel's copy of the piecewise line integral (its pieces constants there) gives
    /// the bits of the same integral over pieces it cannot see through (`black_box`), and
    /// the value-only form the bits of the pair's value: over lines near and beyond the
    /// support, ends on either side of the foot, equal, infinite and reversed.
    #[test]
    fn specialised_line_integrals_equal_the_generic_one_bit_for_bit() {
        let mut unit = units(0x2545_f491_4f6c_dd1d);
        let mut cases = vec![
            (0.0, 0.0, 1.0),
            (0.0, -1.0, 1.0),
            (1.0, f64::NEG_INFINITY, f64::INFINITY),
            (4.0, -1.0, 1.0),
            (-0.5, -2.0, 3.0),
            (0.3, 1.0, 1.0),
            (0.3, 2.0, 1.0),
        ];
        for _ in 0..20_000 {
            let d2 = 8.0 * unit() * unit() - 0.01;
            let t1 = 6.0 * unit() - 3.0;
            let t2 = if unit() < 0.1 { t1 } else { t1 + 4.0 * unit() };
            cases.push((d2, t1, t2));
        }
        for (_, k) in Kernel::ALL {
            for &(d2, t1, t2) in &cases {
                let want = if t2 <= t1 || k.pieces().is_empty() {
                    k.line_integral(d2, t1, t2)
                } else {
                    pieces_line_integral::<false>(std::hint::black_box(k.pieces()), d2, t1, t2)
                };
                let got = k.line_integral(d2, t1, t2);
                assert_eq!(got.0.to_bits(), want.0.to_bits(), "{k:?} {d2} {t1} {t2}");
                assert_eq!(got.1.to_bits(), want.1.to_bits(), "{k:?} {d2} {t1} {t2}");
                let value = k.line_integral_value(d2, t1, t2);
                assert_eq!(value.to_bits(), want.0.to_bits(), "{k:?} {d2} {t1} {t2}");
            }
        }
    }

    #[test]
    fn every_kernel_is_one_at_zero_and_half_at_one() {
        for (name, k) in Kernel::ALL {
            assert!((k.value(0.0) - 1.0).abs() < 1e-15, "{name}");
            assert!((k.value(1.0) - 0.5).abs() < 1e-15, "{name}: {}", k.value(1.0));
            let s = k.support();
            assert!(k.value(s * s * 1.0001) == 0.0, "{name}");
        }
    }

    #[test]
    fn kernels_are_continuous_at_breakpoints_and_vanish_at_support() {
        for (name, k) in Kernel::ALL.iter().skip(1) {
            for b in k.breakpoints() {
                let lo = k.value_d((b * (1.0 - 1e-9)).powi(2));
                let hi = k.value_d((b * (1.0 + 1e-9)).powi(2));
                assert!((lo.0 - hi.0).abs() < 1e-8, "{name} at {b}: {lo:?} {hi:?}");
                // The sinc is cut at a zero of the sine, not of its slope (see SINC_CUTOFF).
                if *k != Kernel::Sinc {
                    assert!((lo.1 - hi.1).abs() < 1e-6, "{name} at {b}: {lo:?} {hi:?}");
                }
            }
            assert!(k.value(k.support().powi(2) * (1.0 - 1e-12)).abs() < 1e-10, "{name}");
        }
    }

    #[test]
    fn derivative_matches_finite_difference() {
        for (name, k) in Kernel::ALL {
            for s2 in [0.01, 0.3, 1.0, 1.7, 2.5, 3.9, 6.0] {
                let h = 1e-6;
                let fd = (k.value(s2 + h) - k.value(s2 - h)) / (2.0 * h);
                let (_, d) = k.value_d(s2);
                assert!((fd - d).abs() < 1e-7, "{name} at s²={s2}: {fd} vs {d}");
            }
        }
    }

    #[test]
    fn tail_derivative_is_minus_k_times_sigma() {
        for (name, k) in Kernel::ALL {
            for s in [0.05, 0.2, 0.9, 1.3, 1.9, 2.5] {
                let h = 1e-6;
                let fd = (k.tail(s + h) - k.tail(s - h)) / (2.0 * h);
                assert!((fd + k.value(s * s) * s).abs() < 1e-7, "{name} at {s}");
            }
        }
    }

    #[test]
    fn gaussian_norms_are_the_dissertations() {
        let k = Kernel::Gaussian;
        // A long segment: field e^{−ω d²} at distance d, ½ at d = 1.
        let v = k.line_integral(1.0, -50.0, 50.0).0 / k.line_norm();
        assert!((v - 0.5).abs() < 1e-15, "{v}");
        // A large polygon: ½ at one radius above it.
        let a = 2.0 * PI * k.tail(1.0) / k.area_norm();
        assert!((a - 0.5).abs() < 1e-15, "{a}");
    }

    #[test]
    fn line_norm_puts_a_long_segment_surface_at_one_radius() {
        for (name, k) in Kernel::ALL {
            let v = 2.0 * k.line_integral(1.0, -100.0, 100.0).0 / k.line_norm();
            assert!((v - 1.0).abs() < 1e-12, "{name}: {v}");
        }
    }

    #[test]
    fn sinc_is_scaled_like_the_others_and_rings() {
        let k = Kernel::Sinc;
        assert_eq!(k.value(0.0), 1.0);
        assert!((k.value(1.0) - 0.5).abs() < 1e-15, "{}", k.value(1.0));
        // Continuous at the cut (a zero of the sine), zero beyond it.
        assert!(k.value(SINC_CUTOFF * SINC_CUTOFF * (1.0 - 1e-12)).abs() < 1e-11);
        assert_eq!(k.value_d(SINC_CUTOFF * SINC_CUTOFF), (0.0, 0.0));
        // Not monotone: negative past the first zero π/a, positive again past 2π/a — the
        // ringing the dissertation rejected it for — but never back up to ½, so a lone
        // point has one surface.
        let at = |x: f64| k.value((x / SINC_A).powi(2));
        assert!(at(4.4934) < -0.217 && at(4.4934) > -0.218, "{}", at(4.4934));
        assert!(at(7.7253) > 0.128 && at(7.7253) < 0.1284, "{}", at(7.7253));
    }

    #[test]
    fn sinc_derivative_is_accurate_on_both_sides_of_the_series_switch() {
        // x = a·s around ½, where value_d switches from the series to sin and cos, and near 0.
        let k = Kernel::Sinc;
        for x in [0.01, 0.3, 0.499_999, 0.5, 0.500_001, 1.0, 3.0, 9.0] {
            let s2 = (x / SINC_A).powi(2);
            let h = (1e-3 * s2).min(1e-5);
            let fd = (k.value(s2 + h) - k.value(s2 - h)) / (2.0 * h);
            let (_, d) = k.value_d(s2);
            assert!((fd - d).abs() < 1e-6 * (1.0 + d.abs()), "x={x}: {fd} vs {d}");
        }
        // At and near 0: dk/d(s²) = −a²/6 + a⁴s²/60 − a⁶s⁴/1680 + ….
        assert!((k.value_d(0.0).1 + SINC_A * SINC_A / 6.0).abs() < 1e-15);
        let s2 = 1e-6;
        let want =
            -SINC_A.powi(2) / 6.0 + SINC_A.powi(4) * s2 / 60.0 - SINC_A.powi(6) * s2 * s2 / 1680.0;
        assert!((k.value_d(s2).1 - want).abs() < 1e-14, "{}", k.value_d(s2).1);
    }

    #[test]
    fn sinc_line_integral_is_the_truncated_bessel_one() {
        // ∫ sin(a√(d² + t²))/(a√(d² + t²)) dt over the whole line is π·J₀(a d)/a; the cut at
        // 3π/a changes it by a few per cent at most. Its secondary maximum (J₀'s, at a d ≈
        // 7.016) exceeds its value at one radius: a long row of sinc sources has a second
        // iso-½ contour (DIS fig. 5.49).
        let k = Kernel::Sinc;
        let line = |d: f64| 2.0 * k.line_integral(d * d, 0.0, f64::INFINITY).0;
        assert!((line(0.0) - 1.7671).abs() < 1e-3, "{}", line(0.0));
        assert!((line(1.0) - 0.5832).abs() < 1e-3, "{}", line(1.0));
        let second = line(7.0156 / SINC_A);
        assert!(second > 1.1 * line(1.0), "{second} vs {}", line(1.0));
        // Its d²-derivative is the line integral of dk/d(s²).
        for d in [0.3, 1.0, 2.5] {
            let h = 1e-6;
            let fd = (k.line_integral(d * d + h, -1.0, 3.0).0
                - k.line_integral(d * d - h, -1.0, 3.0).0)
                / (2.0 * h);
            let dv = k.line_integral(d * d, -1.0, 3.0).1;
            assert!((fd - dv).abs() < 1e-7, "d={d}: {fd} vs {dv}");
        }
    }
}
