//! Adaptive Gauss–Kronrod quadrature (7-point Gauss, 15-point Kronrod) for the smooth
//! one-dimensional integrals that remain in polygon convolution.
//!
//! Why our own: the integrands are smooth on each interval we hand in (kernel breakpoints are
//! split off by the caller), so a compact adaptive rule reaches 1e-12 in a few dozen
//! evaluations; the error estimate is the difference of the two rules, and an interval is
//! bisected until that difference is below the tolerance. Deterministic: the same interval
//! and integrand always give the same subdivision.

/// Kronrod nodes on [-1, 1] (the positive half; the last is the centre).
const XK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
/// Kronrod weights, matching [`XK`].
const WK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_8,
];
/// Gauss weights for the odd-indexed Kronrod nodes 1, 3, 5 and the centre 7.
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// How many bisections deep the adaptive rule may go. 2^-30 of the interval is far below any
/// feature the kernels have; the cap only guards against a non-smooth integrand.
const MAX_DEPTH: u32 = 30;

/// Most sub-intervals one integral may use. Far more than any smooth integrand here needs;
/// it bounds the cost when rounding noise, not the integrand, sets the error estimate.
const MAX_INTERVALS: usize = 4096;

/// One Kronrod and one Gauss estimate of `∫ f` over `[a, b]` for an `N`-vector integrand.
fn gk15<const N: usize>(
    f: &mut impl FnMut(f64) -> [f64; N],
    a: f64,
    b: f64,
) -> ([f64; N], [f64; N]) {
    let c = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let mut k = [0.0; N];
    let mut g = [0.0; N];
    let fc = f(c);
    for n in 0..N {
        k[n] = WK[7] * fc[n];
        g[n] = WG[3] * fc[n];
    }
    for i in 0..7 {
        let dx = h * XK[i];
        let f1 = f(c - dx);
        let f2 = f(c + dx);
        for n in 0..N {
            let s = f1[n] + f2[n];
            k[n] += WK[i] * s;
            if i % 2 == 1 {
                g[n] += WG[i / 2] * s;
            }
        }
    }
    let mut err = [0.0; N];
    for n in 0..N {
        k[n] *= h;
        g[n] *= h;
        err[n] = (k[n] - g[n]).abs();
    }
    (k, err)
}

/// `∫_a^b f` for a smooth vector integrand, to the absolute tolerance `tol[n]` on component
/// `n` (checked per sub-interval, with the tolerance split in proportion to length).
pub(crate) fn integrate<const N: usize>(
    mut f: impl FnMut(f64) -> [f64; N],
    a: f64,
    b: f64,
    tol: [f64; N],
) -> [f64; N] {
    let mut total = [0.0; N];
    if b <= a {
        return total;
    }
    let len = b - a;
    // Explicit stack: (a, b, depth). Intervals are taken in a fixed order, so the result is
    // deterministic.
    let mut stack: Vec<(f64, f64, u32)> = Vec::with_capacity(16);
    stack.push((a, b, 0));
    let mut intervals = 0;
    while let Some((x0, x1, depth)) = stack.pop() {
        let (est, err) = gk15(&mut f, x0, x1);
        intervals += 1;
        let share = ((x1 - x0) / len).max(1e-3);
        let done = (0..N).all(|n| err[n] <= tol[n] * share || !err[n].is_finite());
        if done || depth >= MAX_DEPTH || intervals + stack.len() >= MAX_INTERVALS {
            for n in 0..N {
                total[n] += est[n];
            }
        } else {
            let m = 0.5 * (x0 + x1);
            stack.push((m, x1, depth + 1));
            stack.push((x0, m, depth + 1));
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kronrod_rule_is_exact_for_polynomials_up_to_degree_22() {
        // A wrong digit in any node or weight breaks exactness at some degree.
        for deg in 0..=22 {
            let (k, _) = gk15(&mut |x: f64| [x.powi(deg)], -1.0, 1.0);
            let exact = if deg % 2 == 1 { 0.0 } else { 2.0 / (deg as f64 + 1.0) };
            assert!((k[0] - exact).abs() < 1e-15, "degree {deg}: {} vs {exact}", k[0]);
        }
    }

    #[test]
    fn gauss_rule_is_exact_up_to_degree_13() {
        for deg in 0..=13 {
            let (_, err) = gk15(&mut |x: f64| [x.powi(deg)], -1.0, 1.0);
            assert!(err[0] < 1e-15, "degree {deg}: gauss and kronrod differ by {:?}", err);
        }
    }

    #[test]
    fn adaptive_reaches_tolerance_on_a_peaked_integrand() {
        // ∫_{-1}^{1} 1/(1e-4 + x²) dx = 2·atan(1/0.01)/0.01
        let exact = 2.0 * (100.0f64).atan() / 0.01;
        let got = integrate(|x| [1.0 / (1e-4 + x * x)], -1.0, 1.0, [1e-10]);
        assert!((got[0] - exact).abs() < 1e-8, "{} vs {exact}", got[0]);
    }
}
