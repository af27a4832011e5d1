//! The dissertation's integral tables (DIS §5.6.7, `:9817-9850`) against the closed forms
//! skelform uses instead.
//!
//! Bloomenthal sized his Gaussian table by trying a kernel whose integral is known exactly,
//! the cubic B-spline (eq. 5.31): "We evaluated the B-spline integral both analytically and
//! numerically with a 1000 element table; the maximum discrepancy between the two was
//! 0.000000954". The first test rebuilds that table and finds the figure; the second states
//! what the `erf` path of [`Kernel::line_integral`] gains over the 10,000-entry Gaussian
//! table the dissertation then used.

use std::f64::consts::PI;

use skelform_skeleton::Kernel;

/// The uniform cubic B-spline of eq. 5.31 (support [−2, 2], `B(0) = 2/3`, area 1).
fn bspline(x: f64) -> f64 {
    let x = x.abs();
    if x < 1.0 {
        (3.0 * x * x * x - 6.0 * x * x + 4.0) / 6.0
    } else if x < 2.0 {
        (2.0 - x).powi(3) / 6.0
    } else {
        0.0
    }
}

/// `∫_{−2}^{x} B`, the dissertation's `area(x)/24` (`areaNeg` on the negative side, and
/// `24 − areaNeg(−x)` on the positive).
fn bspline_integral(x: f64) -> f64 {
    let area_neg = |x: f64| {
        if x < -2.0 {
            0.0
        } else if x < -1.0 {
            (x + 2.0).powi(4)
        } else {
            -3.0 * x.powi(4) - 8.0 * x.powi(3) + 16.0 * x + 12.0
        }
    };
    let area = if x < 0.0 { area_neg(x) } else { 24.0 - area_neg(-x) };
    area / 24.0
}

/// The largest difference between a trapezoid table of `B` over [0, 2] with `steps` steps,
/// accumulated in `f32` (`single`, as the dissertation's C stored it) or `f64`, and the
/// analytic integral at the table's nodes.
fn table_error(steps: usize, single: bool) -> f64 {
    let round = |x: f64| if single { x as f32 as f64 } else { x };
    let h = 2.0 / steps as f64;
    let (mut entry, mut worst) = (round(bspline_integral(0.0)), 0f64);
    for i in 1..=steps {
        let (a, b) = (round(bspline((i - 1) as f64 * h)), round(bspline(i as f64 * h)));
        entry = round(entry + round(round(0.5 * h) * round(a + b)));
        worst = worst.max((entry - bspline_integral(i as f64 * h)).abs());
    }
    worst
}

#[test]
fn the_dissertations_bspline_table_discrepancy_is_reproduced() {
    // The closed form is the integral: area 1, ½ at the centre, continuous at the knots.
    assert_eq!(bspline_integral(2.0), 1.0);
    assert_eq!(bspline_integral(0.0), 0.5);
    for knot in [-1.0, 1.0] {
        let (l, r) = (bspline_integral(knot - 1e-12), bspline_integral(knot + 1e-12));
        assert!((l - r).abs() < 1e-11, "{knot}");
    }
    // ... and it is what skelform's B-spline kernel integrates in closed form: k(s) =
    // 1.5·B(βs), with β where 1.5·B(β) = ½ (3β³ − 6β² + 2 = 0).
    let mut beta: f64 = 0.7;
    for _ in 0..50 {
        beta -= (3.0 * beta.powi(3) - 6.0 * beta * beta + 2.0) / (9.0 * beta * beta - 12.0 * beta);
    }
    assert!((beta - 0.72235).abs() < 1e-5, "{beta}");
    for t in [0.1, 0.9, 1.384, 2.0, 2.5, 3.0] {
        let (ours, _) = Kernel::BSpline.line_integral(0.0, 0.0, t);
        let theirs = 1.5 / beta * (bspline_integral(beta * t) - 0.5);
        assert!((ours - theirs).abs() < 1e-13, "t = {t}: {ours} vs {theirs}");
    }

    // 1000 trapezoid steps over the kernel's half-support, stored in single precision: the
    // largest discrepancy is 2⁻²⁰ = 0.00000095367, the dissertation's 0.000000954 (sixteen
    // units in the last place of a float just under 1, where the table ends).
    let single = table_error(1000, true);
    let double = table_error(1000, false);
    println!(
        "1000-step B-spline table: {single:.3e} in f32 (DIS: 0.000000954), {double:.3e} in f64"
    );
    assert!((single - 0.000000954).abs() < 0.0000000005, "{single}");
    assert_eq!(single, 2f64.powi(-20));
    // The trapezoid rule's own error, h²/12 times the largest slope (⅔, at x = ⅔), is
    // 2.2·10⁻⁷: the rest of the figure is the float storage.
    let h: f64 = 2.0 / 1000.0;
    assert!((double - h * h / 12.0 * (2.0 / 3.0)).abs() < 0.01 * double, "{double}");
}

/// `∫_0^x e^{−ω t²} dt` by composite Simpson with 20,000 panels: an error of order
/// `(x/20000)⁴`, far below the table's; independent of `erf`.
fn gauss_simpson(x: f64) -> f64 {
    let n = 20_000;
    let h = x / n as f64;
    let g = |t: f64| (-std::f64::consts::LN_2 * t * t).exp();
    let mut s = g(0.0) + g(x);
    for i in 1..n {
        s += g(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

#[test]
fn the_erf_path_is_exact_where_the_dissertations_gaussian_table_was_not() {
    let omega = std::f64::consts::LN_2;
    let half = 0.5 * (PI / omega).sqrt();
    // The dissertation's table (appendix): 10,000 entries over [0, 10], 1000 a unit,
    // normalised so that it runs from ½ to 1, looked up with linear interpolation.
    let gauss = |x: f64| (-omega * x * x).exp();
    let mut table = vec![0.5; 10_001];
    for i in 1..table.len() {
        let step = 0.5 / ((PI / omega).sqrt() * 1000.0);
        table[i] =
            table[i - 1] + step * (gauss((i - 1) as f64 / 1000.0) + gauss(i as f64 / 1000.0));
    }
    let lookup = |x: f64| {
        let u = x * 1000.0;
        let i = (u.floor() as usize).min(table.len() - 2);
        let f = u - i as f64;
        table[i] + f * (table[i + 1] - table[i])
    };
    let (mut table_worst, mut erf_worst) = (0f64, 0f64);
    for k in 0..=400 {
        let x = k as f64 * 0.0137;
        // The normalised integral from −∞ to x.
        let exact = 0.5 + gauss_simpson(x) / (2.0 * half);
        let (ours, _) = Kernel::Gaussian.line_integral(0.0, f64::NEG_INFINITY, x);
        table_worst = table_worst.max((lookup(x) - exact).abs());
        erf_worst = erf_worst.max((ours / (2.0 * half) - exact).abs());
    }
    println!(
        "normalised Gaussian integral: the 10,000-entry table is off by up to {table_worst:.2e}, the erf path by {erf_worst:.2e}"
    );
    // The table is good to about 10⁻⁷ (the 1000-per-unit trapezoid and lookup); the erf
    // path to rounding.
    assert!(table_worst > 1e-9 && table_worst < 1e-6, "{table_worst}");
    assert!(erf_worst < 1e-13, "{erf_worst}");
}
