//! Tests of the formula language: values, batching, gradients, errors, and property tests
//! against a reference tree-walking evaluator.

use std::f64::consts::{E, PI};

use glam::DVec3;
use proptest::prelude::*;

use super::*;

/// A small deterministic generator (splitmix64) for test points.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn point(&mut self, h: f64) -> DVec3 {
        DVec3::new(self.uniform(-h, h), self.uniform(-h, h), self.uniform(-h, h))
    }
}

fn points(n: usize, h: f64, seed: u64) -> Vec<DVec3> {
    let mut rng = Rng(seed);
    (0..n).map(|_| rng.point(h)).collect()
}

fn parse(s: &str) -> Formula {
    Formula::parse(s).unwrap_or_else(|e| panic!("{s:?}: {e}"))
}

fn err(s: &str) -> FormulaError {
    match Formula::parse(s) {
        Ok(f) => panic!("{s:?} parsed, tape:\n{}", f.tape()),
        Err(e) => e,
    }
}

fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    same(a, b) || (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

fn smin_ref(a: f64, b: f64, k: f64) -> f64 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b * (1.0 - h) + a * h - k * h * (1.0 - h)
}

// ---------------------------------------------------------------------------------------
// Values

#[test]
fn precedence_and_associativity() {
    let o = DVec3::ZERO;
    assert_eq!(parse("2^3^2").eval(o), 512.0);
    assert_eq!(parse("8/2/2").eval(o), 2.0);
    assert_eq!(parse("10-4-3").eval(o), 3.0);
    assert_eq!(parse("-2^2").eval(o), -4.0);
    assert_eq!(parse("(-2)^2").eval(o), 4.0);
    assert_eq!(parse("2^-1").eval(o), 0.5);
    assert_eq!(parse("2^-1^2").eval(o), 0.5); // 2^(-(1^2))
    assert_eq!(parse("2*3+4*5").eval(o), 26.0);
    assert_eq!(parse("2*(3+4)*5").eval(o), 70.0);
    assert_eq!(parse("-3*-2").eval(o), 6.0);
    assert_eq!(parse("+-+2").eval(o), -2.0);
    assert_eq!(parse("--2").eval(o), 2.0);
    assert_eq!(parse("2^2*3").eval(o), 12.0);
    assert_eq!(parse("1e-3 + .5 + 2.5E+2 + 3.").eval(o), 1e-3 + 0.5 + 250.0 + 3.0);
    assert_eq!(parse("pi").eval(o), PI);
    assert_eq!(parse("e").eval(o), E);
    assert_eq!(parse("2*pi").eval(o), 2.0 * PI);
}

/// Formulas against closures written independently.
#[test]
fn formulas_match_closures() {
    type Case = (&'static str, fn(f64, f64, f64) -> f64);
    let cases: &[Case] = &[
        ("-x^2", |x, _, _| -(x * x)),
        ("x - y - z", |x, y, z| (x - y) - z),
        ("x / y / z", |x, y, z| (x / y) / z),
        ("x + y * z", |x, y, z| x + y * z),
        ("(x + y) * z", |x, y, z| (x + y) * z),
        ("-x * y", |x, y, _| -x * y),
        ("x^3 - y^-2 + abs(z)^0.5 + abs(x)^1.5 + y^0", |x, y, z| {
            x.powi(3) - y.powi(-2) + z.abs().sqrt() + x.abs().powf(1.5) + 1.0
        }),
        ("x^2 + y^2 + z^2 - 1", |x, y, z| x * x + y * y + z * z - 1.0),
        ("abs(x) + sqrt(abs(y)) + exp(z)", |x, y, z| x.abs() + y.abs().sqrt() + z.exp()),
        ("ln(abs(x) + 1) + log(y + 3)", |x, y, _| (x.abs() + 1.0).ln() + (y + 3.0).ln()),
        ("sin(x) + cos(y) + tan(z)", |x, y, z| x.sin() + y.cos() + z.tan()),
        ("asin(x/2) + acos(y/2) + atan(z)", |x, y, z| {
            (x / 2.0).asin() + (y / 2.0).acos() + z.atan()
        }),
        ("atan2(y, x)", |x, y, _| y.atan2(x)),
        ("pow(abs(x) + 0.1, y)", |x, y, _| (x.abs() + 0.1).powf(y)),
        ("pow(x, 2)", |x, _, _| x * x),
        ("hypot(x, y)", |x, y, _| x.hypot(y)),
        ("min(x, y, z)", |x, y, z| x.min(y).min(z)),
        ("max(x, y, z)", |x, y, z| x.max(y).max(z)),
        ("union(x, y)", |x, y, _| x.min(y)),
        ("intersection(x, y, z)", |x, y, z| x.max(y).max(z)),
        ("difference(x, y)", |x, y, _| x.max(-y)),
        ("clamp(x, -0.5, 0.5)", |x, _, _| x.clamp(-0.5, 0.5)),
        ("floor(3*x) + sign(y)", |x, y, _| (3.0 * x).floor() + y.signum()),
        ("mix(x, y, z) + lerp(y, z, 0.25)", |x, y, z| x + (y - x) * z + y + (z - y) * 0.25),
        ("smooth_union(x, y, 0.3)", |x, y, _| smin_ref(x, y, 0.3)),
        ("smin(x, y, abs(z))", |x, y, z| smin_ref(x, y, z.abs())),
        ("smooth_intersection(x, y, 0.4)", |x, y, _| -smin_ref(-x, -y, 0.4)),
        ("smax(x, y, 0.4)", |x, y, _| -smin_ref(-x, -y, 0.4)),
        ("smooth_difference(x, y, 0.2)", |x, y, _| -smin_ref(-x, y, 0.2)),
        ("smooth_union(x, y, 0)", |x, y, _| x.min(y)),
        ("smooth_union(x, y, -1)", |x, y, _| x.min(y)),
        ("smooth_union(x, y, z)", |x, y, z| smin_ref(x, y, z)), // runtime k may be ≤ 0
        ("r = sqrt(x^2 + y^2); q = r - 0.5; q^2 + z^2 - 0.1", |x, y, z| {
            let q = (x * x + y * y).sqrt() - 0.5;
            q * q + z * z - 0.1
        }),
        (
            "# a torus\nR = 1   # major radius\n\nr = 0.25\nq = sqrt(x^2 + y^2) - R\n  sqrt(q^2 + z^2) - r  # done\n",
            |x, y, z| {
                let q = (x * x + y * y).sqrt() - 1.0;
                (q * q + z * z).sqrt() - 0.25
            },
        ),
        ("a = x +\n  y *\n  z\nb = max(a,\n  x,\n\n  y)\n(a\n + b\n)", |x, y, z| {
            let a = x + y * z;
            let b = a.max(x).max(y);
            a + b
        }),
        ("sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)", |x, y, z| {
            x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos()
        }),
    ];
    let pts = points(200, 1.5, 1);
    for (src, reference) in cases {
        let f = parse(src);
        for p in &pts {
            let (got, want) = (f.eval(*p), reference(p.x, p.y, p.z));
            assert!(
                close(got, want, 1e-13),
                "{src:?} at {p}: got {got}, want {want}\n{}",
                f.tape()
            );
        }
    }
}

/// Distance in units in the last place (for finite values of the same sign).
fn ulps(a: f64, b: f64) -> u64 {
    if a == b {
        return 0;
    }
    if a.signum() != b.signum() {
        return u64::MAX;
    }
    a.to_bits().abs_diff(b.to_bits())
}

#[test]
fn sine_and_cosine_are_accurate() {
    let mut rng = Rng(17);
    let mut worst = 0;
    for range in [1e-8, 0.1, 1.0, 4.0, 100.0, 1e4, 8e5] {
        for _ in 0..20_000 {
            let a = rng.uniform(-range, range);
            let (s, c) = (ops::lane::sin(a), ops::lane::cos(a));
            // Near a zero the libm value is tiny; compare absolutely there.
            for (got, want) in [(s, a.sin()), (c, a.cos())] {
                if want.abs() > 1e-3 {
                    worst = worst.max(ulps(got, want));
                } else {
                    assert!(
                        (got - want).abs() <= 1e-16 * (1.0 + a.abs() * 1e-6),
                        "{a}: {got} vs {want}"
                    );
                }
            }
        }
    }
    assert!(worst <= 2, "worst error {worst} ulps");
    // Special values and the libm fallback beyond the fast range.
    for a in [0.0, -0.0, 1e6, -3e9, 1e300, f64::MAX, f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
        assert!(same(ops::lane::sin(a), a.sin()) && same(ops::lane::cos(a), a.cos()), "{a}");
    }
    assert!(ops::lane::sin(-0.0).is_sign_negative());
    // Exact quadrant values.
    assert_eq!(ops::lane::cos(0.0), 1.0);
    assert_eq!(ops::lane::sin(PI / 2.0), 1.0);
    assert_eq!(ops::lane::cos(PI), -1.0);
}

#[test]
fn non_finite_values_propagate() {
    let o = DVec3::ZERO;
    assert!(parse("ln(x - 1)").eval(o).is_nan());
    assert_eq!(parse("1 / x").eval(o), f64::INFINITY);
    assert_eq!(parse("-1 / x").eval(o), f64::NEG_INFINITY);
    assert!(parse("sqrt(-1 + x)").eval(o).is_nan());
    assert_eq!(parse("ln(x)").eval(o), f64::NEG_INFINITY);
    // min ignores NaN; the smooth union does not blow up next to an infinite operand.
    assert_eq!(parse("min(ln(-1 + x), 2)").eval(o), 2.0);
    assert_eq!(parse("smooth_union(1/x, 2, 0.5)").eval(o), 2.0);
    assert_eq!(parse("smooth_union(2, 1/x, 0.5)").eval(o), 2.0);
    assert_eq!(parse("smooth_union(2, 3, 0 * x)").eval(o), 2.0);
    assert_eq!(parse("smooth_union(ln(x - 1), 3, 1)").eval(o), 3.0);
    assert_eq!(parse("smooth_union(3, ln(x - 1), 1)").eval(o), 3.0);
    assert_eq!(parse("sign(x)").eval(o), 0.0);
}

#[test]
fn constants_can_be_injected() {
    let f = Formula::parse_with_constants(
        "sqrt(x^2 + y^2 + z^2) - radius * k2",
        &[("radius", 2.0), ("k2", 0.5)],
    )
    .unwrap();
    assert_eq!(f.eval(DVec3::new(3.0, 0.0, 0.0)), 2.0);
    assert_eq!(f.instruction_count(), 7, "{}", f.tape()); // radius * k2 is folded
    let e = Formula::parse_with_constants("k = 2\nk", &[("k", 1.0)]).unwrap_err();
    assert_eq!(
        (e.line(), e.column(), e.message()),
        (1, 1, "'k' is already defined as a parameter")
    );
    let e = Formula::parse_with_constants("x", &[("x", 1.0)]).unwrap_err();
    assert_eq!(e.message(), "parameter 'x' is reserved and cannot be defined");
    let e = Formula::parse_with_constants("x", &[("2a", 1.0)]).unwrap_err();
    assert!(e.message().starts_with("parameter '2a' is not a valid name"), "{e}");
    let e = Formula::parse_with_constants("x", &[("a", 1.0), ("a", 2.0)]).unwrap_err();
    assert_eq!(e.message(), "parameter 'a' is given twice");
}

// ---------------------------------------------------------------------------------------
// Compilation

#[test]
fn constants_fold_and_powers_become_multiplications() {
    assert_eq!(parse("2*pi*x").instruction_count(), 1);
    assert_eq!(parse("sin(pi/2) + 2^10 + x").tape().constant_count(), 1);
    assert_eq!(parse("x^2").instruction_count(), 1); // mul
    assert_eq!(parse("x^4").instruction_count(), 2); // two squarings
    assert_eq!(parse("x^-1").instruction_count(), 1); // div
    assert!(parse("x^0.5").tape().to_string().contains("sqrt"));
    assert!(parse("x^1.5").tape().to_string().contains("pow"));
    assert_eq!(parse("x^1").instruction_count(), 0);
    assert_eq!(parse("x*1 - 0 + 0*0").instruction_count(), 1); // x + 0 stays (−0 + 0 is +0)
    assert_eq!(parse("--x").instruction_count(), 0);
    assert_eq!(parse("1 + 2").tape().constant_result(), Some(3.0));
    assert_eq!(parse("x").tape().constant_result(), None);
    assert_eq!(
        parse("smooth_union(x, y, 0)")
            .tape()
            .to_string()
            .lines()
            .filter(|l| l.contains("min"))
            .count(),
        1
    );
}

#[test]
fn definitions_and_repeats_are_computed_once() {
    // sin(x) appears three times but is one instruction; r is used twice.
    let f = parse("r = sqrt(x^2 + y^2)\nr*sin(x) + r/sin(x) + sin(x)");
    let listing = f.tape().to_string();
    assert_eq!(listing.matches(" sin ").count(), 1, "{listing}");
    assert_eq!(listing.matches(" sqrt ").count(), 1, "{listing}");
    // Commutative operands are canonicalised: x*y and y*x are one product.
    assert_eq!(parse("x*y + y*x").instruction_count(), 2);
    // Unused definitions cost nothing.
    assert_eq!(parse("unused = sin(x) * cos(y)\nx + 1").instruction_count(), 1);
}

#[test]
fn registers_are_reused() {
    // A long chain needs only a couple of temporaries.
    let src: String = (0..200).map(|i| format!("sin(x + {i}) + ")).collect::<String>() + "0";
    let f = parse(&src);
    assert!(f.instruction_count() >= 400);
    let temps = f.register_count() - 3 - f.tape().constant_count();
    assert!(temps <= 3, "{temps} temporaries");
}

#[test]
fn tape_listing() {
    let f = parse("a = x*x\na + 2");
    let s = f.tape().to_string();
    assert!(s.starts_with("; 2 instructions"), "{s}");
    assert!(s.contains("r0 = x") && s.contains("mul r0 r0") && s.contains("r3 = 2.0"), "{s}");
    assert!(s.ends_with(&format!("result r{}", f.tape().result)), "{s}");
    assert_eq!(f.to_string(), "a = x*x\na + 2");
    assert_eq!(f.source(), "a = x*x\na + 2");
    assert_eq!("x + 1".parse::<Formula>().unwrap().eval(DVec3::ONE), 2.0);
}

#[test]
fn formulas_are_send_and_sync() {
    fn check<T: Send + Sync + Clone>() {}
    check::<Formula>();
    check::<FormulaError>();
}

// ---------------------------------------------------------------------------------------
// Batches

/// A formula that needs more registers than the single-point path keeps on the stack.
fn wide_formula() -> String {
    let mut s = String::new();
    for i in 0..80 {
        s += &format!("a{i} = sin(x * {} + y) * cos(z - {i})\n", i + 1);
    }
    s += &(0..80).map(|i| format!("a{i} * a{}", 79 - i)).collect::<Vec<_>>().join(" + ");
    s
}

fn batch_formulas() -> Vec<String> {
    vec![
        "x".into(),
        "3.5".into(),
        "sqrt(x^2 + y^2 + z^2) - 1".into(),
        "R = 1; r = 0.3; q = sqrt(x^2 + y^2) - R; sqrt(q^2 + z^2) - r".into(),
        "sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)".into(),
        "smooth_union(x - 0.2, y^3 + ln(z), z) + floor(x*5) + sign(y) + atan2(y, x) + pow(abs(x), y)".into(),
        "min(x, y, z) + max(x / y, z) + clamp(x, y, z) + hypot(x, z) + tan(x) + asin(y) + acos(z)".into(),
        wide_formula(),
    ]
}

#[test]
fn batches_are_bit_identical_to_points() {
    for src in batch_formulas() {
        let f = parse(&src);
        for n in [1, 7, 64, 65, 255, 1000] {
            let pts = points(n, 1.2, n as u64);
            let mut out = vec![0.0; n];
            f.eval_many(&pts, &mut out);
            let mut vals = vec![0.0; n];
            let mut grads = vec![DVec3::ZERO; n];
            f.eval_grad_many(&pts, &mut vals, &mut grads);
            for (i, p) in pts.iter().enumerate() {
                let v = f.eval(*p);
                assert!(same(out[i], v), "{src:?} n={n} i={i}: batch {} vs point {v}", out[i]);
                assert!(
                    same(vals[i], v),
                    "{src:?} n={n} i={i}: grad batch value {} vs {v}",
                    vals[i]
                );
                let g = f.gradient(*p);
                for c in 0..3 {
                    assert!(same(grads[i][c], g[c]), "{src:?} n={n} i={i}: {} vs {g}", grads[i]);
                }
            }
        }
    }
}

/// Lattice layers (terms that depend on fewer axes computed once per layer, row or column)
/// give every point's value bit for bit, for formulas of every mix of axes.
#[test]
fn lattice_layers_are_bit_identical_to_points() {
    let mut formulas = batch_formulas();
    formulas.extend(
        [
            "z",
            "y * z - 1",
            "sin(z) * 2",
            "exp(-2*(x-0.1)^2) * exp(-2*(y-0.2)^2) * exp(-2*(z+0.3)^2) - 0.5",
            "exp(-3*((x-0.1)^2 + (y-0.2)^2 + (z+0.3)^2)) + x*y*z",
            "smin(x^2, y^2 + z, 0.3) + smin(z, y, x)",
        ]
        .map(String::from),
    );
    let mut rng = Rng(5);
    for src in formulas {
        let f = parse(&src);
        for (nx, ny) in [(1, 1), (7, 3), (130, 2), (300, 1)] {
            let xs: Vec<f64> = (0..nx).map(|_| rng.uniform(-1.5, 1.5)).collect();
            let ys: Vec<f64> = (0..ny).map(|_| rng.uniform(-1.5, 1.5)).collect();
            let z = rng.uniform(-1.5, 1.5);
            let mut out = vec![f64::NAN; nx * ny];
            f.eval_layer(&xs, &ys, z, &mut out);
            let check = |out: &[f64], rows: std::ops::Range<usize>, z: f64, how: &str| {
                for (j, &y) in ys[rows.clone()].iter().enumerate() {
                    for (i, &x) in xs.iter().enumerate() {
                        let (got, want) = (out[i + nx * j], f.eval(DVec3::new(x, y, z)));
                        assert!(
                            same(got, want),
                            "{src:?} {how} at ({x}, {y}, {z}): {got} vs {want}"
                        );
                    }
                }
            };
            check(&out, 0..ny, z, "layer");
            // A sampler of the same lattice (terms of x and y alone computed once), on
            // several layers and on a part of the rows.
            let sampler = f.sampler(&xs, &ys);
            for z in [z, rng.uniform(-1.5, 1.5)] {
                out.fill(f64::NAN);
                sampler.layer(z, 0..ny, &mut out);
                check(&out, 0..ny, z, "sampler");
                let rows = ny / 2..ny;
                let mut part = vec![f64::NAN; nx * rows.len()];
                sampler.layer(z, rows.clone(), &mut part);
                check(&part, rows, z, "sampler rows");
            }
        }
    }
}

/// Sampling a lattice leaves per point only what depends on x, y and z together: the
/// torus keeps a sum and a difference, the gyroid two sums (its `sin(x)·cos(y)` computed
/// once for all layers, `sin(y)·cos(z)` once per row, `sin(z)·cos(x)` once per column).
#[test]
fn lattice_sampling_hoists_terms_of_fewer_axes() {
    let per_point = |src: &str| {
        let f = parse(src);
        let planar = f.planar.as_ref().map(|p| p.lattice.point.instruction_count());
        (f.lattice.point.instruction_count(), planar)
    };
    assert_eq!(per_point("(sqrt(x^2 + y^2) - 0.6)^2 + z^2 - 0.0625"), (6, Some(2)));
    assert_eq!(per_point("sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)"), (3, Some(2)));
    // Nothing of x and y alone: one layer at a time does as well.
    assert_eq!(per_point("x*z + y*z").1, None);
}

#[test]
fn batches_of_nothing_and_alternating_formulas() {
    let small = parse("x + y");
    small.eval_many(&[], &mut []);
    small.eval_grad_many(&[], &mut [], &mut []);
    // The per-thread scratch is shared by formulas of different sizes.
    let wide = parse(&wide_formula());
    assert!(wide.register_count() > 64, "{}", wide.register_count());
    let pts = points(300, 1.0, 3);
    for f in [&wide, &small, &wide, &small] {
        let mut out = vec![0.0; pts.len()];
        f.eval_many(&pts, &mut out);
        for (p, v) in pts.iter().zip(&out) {
            assert_eq!(*v, f.eval(*p));
        }
    }
}

// ---------------------------------------------------------------------------------------
// Gradients

#[test]
fn exact_gradients_of_simple_formulas() {
    let f = parse("x^2 + y^2 + z^2");
    assert!(f.has_exact_gradient());
    for p in points(50, 2.0, 5) {
        assert_eq!(f.gradient(p), 2.0 * p);
    }
    let f = parse("3*x - 2*y + z/4");
    assert_eq!(f.gradient(DVec3::new(0.3, 0.1, 7.0)), DVec3::new(3.0, -2.0, 0.25));
    // Documented choices at non-differentiable points.
    let o = DVec3::ZERO;
    assert_eq!(parse("sqrt(x^2 + y^2 + z^2)").gradient(o), DVec3::ZERO);
    assert_eq!(parse("abs(x) + abs(y)").gradient(o), DVec3::ZERO);
    assert_eq!(parse("floor(x) + sign(y) + z").gradient(DVec3::new(0.5, 0.5, 0.5)), DVec3::Z);
    assert_eq!(parse("min(x, y)").gradient(o), DVec3::X); // the first operand on ties
    assert_eq!(parse("max(y, x)").gradient(o), DVec3::Y);
    assert_eq!(parse("min(x, sqrt(y))").gradient(DVec3::new(-1.0, 0.0, 0.0)), DVec3::X);
    assert_eq!(parse("atan2(y, x) + hypot(x, y)").gradient(o), DVec3::ZERO);
    assert_eq!(parse("sqrt(x)").gradient(o).x, f64::INFINITY);
    // The smooth union's gradient is a blend of the operands'.
    let g = parse("smooth_union(x, y, 1)").gradient(o);
    assert_eq!(g, DVec3::new(0.5, 0.5, 0.0));
    assert_eq!(parse("smooth_union(x, y, 0)").gradient(DVec3::new(1.0, 0.0, 0.0)), DVec3::Y);
}

#[test]
fn gradients_match_finite_differences() {
    let src = "
        a = sin(x) * cos(y) + tan(z/3) - x/(2 + y)
        b = exp(x/4) + ln(2 + y) + log(3 + z) + sqrt(3 + z) + abs(x - 5) - abs(y + 5)
        c = asin(x/3) + acos(y/3) + atan(z) + atan2(y + 3, x + 4) + hypot(x, y + 2)
        d = pow(2 + x, 1 + y/5) + (1 + y^2)^1.5 + x^3 - 1/(2 + z)^2 + 2^z + (1.5 + z)^-3
        s = smooth_union(a, b, 0.7) + smooth_intersection(c, d, 0.5 + x^2) + smooth_difference(a, c, 0.3)
        m = min(a, b, c) + max(c, d, a) + union(a, d) + intersection(b, c) + difference(a, b)
        mix(a, d, 0.3 + 0.1*z) + lerp(s, m, y) + clamp(x*y, -0.2, 0.2) + s*m - pi*e*z
    ";
    let f = parse(src);
    let h = 1e-6;
    let mut checked = 0;
    for p in points(300, 0.9, 11) {
        let g = f.gradient(p);
        for (axis, e) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
            let fd = (f.eval(p + e * h) - f.eval(p - e * h)) / (2.0 * h);
            assert!(
                (g[axis] - fd).abs() <= 1e-5 * (1.0 + g[axis].abs()),
                "at {p} axis {axis}: ad {} fd {fd}",
                g[axis]
            );
        }
        checked += 1;
    }
    assert_eq!(checked, 300);
}

// ---------------------------------------------------------------------------------------
// Errors

#[track_caller]
fn assert_err(src: &str, line: usize, column: usize, message: &str) {
    let e = err(src);
    assert_eq!((e.line(), e.column(), e.message()), (line, column, message), "{src:?}");
    assert_eq!(e.to_string(), format!("line {line}, column {column}: {message}"));
}

#[test]
fn error_positions_and_messages() {
    assert_err("r = sqrt(x^2 + y^2)\nrr - 1", 2, 1, "unknown name 'rr' (did you mean 'r'?)");
    assert_err(
        "a = 1\nb = 2\nc = (a + b) * (a 1)\nc",
        3,
        18,
        "expected ')' to close '(' opened at line 3, column 15, found the number 1",
    );
    assert_err(
        "q = (x +\n  (y - 1)\n",
        3,
        1,
        "expected ')' to close '(' opened at line 1, column 5, found the end of the formula",
    );
    assert_err("atan2(y)", 1, 1, "'atan2' takes 2 arguments, got 1");
    assert_err("1 + sin(x, y)", 1, 5, "'sin' takes 1 argument, got 2");
    assert_err("min(x)", 1, 1, "'min' takes at least 2 arguments, got 1");
    assert_err("clamp()", 1, 1, "'clamp' takes 3 arguments, got 0");
    assert_err(
        "  max(x, y\n",
        2,
        1,
        "expected ',' or ')' to close '(' opened at line 1, column 6, found the end of the formula",
    );
    assert_err("x = 1\nx", 1, 1, "'x' is reserved and cannot be defined");
    assert_err("a = 2\n pi = 3\n pi", 2, 2, "'pi' is reserved and cannot be defined");
    assert_err("sin = 1\n1", 1, 1, "'sin' is reserved and cannot be defined");
    assert_err("", 1, 1, "the formula is empty");
    assert_err("  # just a comment\n\n ; \n", 1, 1, "the formula is empty");
    assert_err("a = 1", 1, 1, "the last statement must be an expression, not a definition");
    assert_err(
        "\n  a = 1 # c\n",
        2,
        3,
        "the last statement must be an expression, not a definition",
    );
    assert_err("x + $", 1, 5, "unexpected character '$'");
    assert_err("a = 1\n  b = a ° 2\nb", 2, 9, "unexpected character '°'");
    assert_err("a = 1\na = 2\na", 2, 1, "'a' is already defined (at line 1, column 1)");
    assert_err(
        "x + 1\ny",
        1,
        1,
        "only the last statement may be an expression; the ones before it must be definitions 'name = expression'",
    );
    assert_err("1 + sin", 1, 5, "'sin' is a function: call it as sin(...)");
    assert_err("a = 1; a(2)", 1, 8, "'a' is not a function");
    assert_err("x(2)", 1, 1, "'x' is not a function");
    assert_err("sn(x)", 1, 1, "unknown function 'sn' (did you mean 'sin'?)");
    assert_err(
        "smooth_unoin(x, y, 1)",
        1,
        1,
        "unknown function 'smooth_unoin' (did you mean 'smooth_union'?)",
    );
    assert_err("foo(x)", 1, 1, "unknown function 'foo'");
    assert_err("w + 1", 1, 1, "unknown name 'w'");
    assert_err("radius = 1\nradiu + 1", 2, 1, "unknown name 'radiu' (did you mean 'radius'?)");
    assert_err("r = r + 1\nr", 1, 5, "'r' is used in its own definition");
    assert_err("x)", 1, 2, "unmatched ')'");
    assert_err(
        "2 = x",
        1,
        3,
        "unexpected '=': a definition is a name, '=', then an expression, on a statement of its own",
    );
    assert_err("2x", 1, 2, "expected an operator, a new line or ';', found 'x'");
    assert_err("x + 1 y", 1, 7, "expected an operator, a new line or ';', found 'y'");
    assert_err("x +", 1, 4, "expected a number, a name or '(', found the end of the formula");
    assert_err("x + \n\n", 3, 1, "expected a number, a name or '(', found the end of the formula");
    assert_err("x * ()", 1, 6, "expected a number, a name or '(', found ')'");
    assert_err("min(x,, y)", 1, 7, "expected a number, a name or '(', found ','");
    assert_err("a =\n", 2, 1, "expected a number, a name or '(', found the end of the formula");
    assert_err("1e999 * x", 1, 1, "the number '1e999' is too large");
    assert_err(
        "x + 1 ..5",
        1,
        7,
        "unexpected character '.' (a number needs a digit next to its decimal point)",
    );
    // Columns count characters, not bytes.
    assert_err("é_r = 1", 1, 1, "unexpected character 'é'");
    assert_err("# ééé\nq = 1 + ww\nq", 2, 9, "unknown name 'ww'");
}

#[test]
fn deep_nesting_is_an_error_not_a_crash() {
    for src in [
        "(".repeat(100_000) + "x",
        "-".repeat(100_000) + "x",
        "2^".repeat(100_000) + "2",
        "sin(".repeat(10_000),
    ] {
        let e = err(&src);
        assert!(e.message().contains("nested too deeply"), "{e}");
    }
    // Moderate nesting is fine.
    let src = "(".repeat(50) + "x" + &")".repeat(50);
    assert_eq!(parse(&src).eval(DVec3::X), 1.0);
    // Long flat chains are not nesting.
    let src = vec!["x"; 100_000].join(" + ");
    assert_eq!(parse(&src).eval(DVec3::X), 100_000.0);
}

// ---------------------------------------------------------------------------------------
// Property tests

proptest! {
    #[test]
    fn arbitrary_text_never_panics(s in any::<String>()) {
        let _ = Formula::parse(&s);
    }

    #[test]
    fn token_soup_never_panics(s in r"[xyzabr0-9.eE+\-*/^(),;=# \n\t]{0,80}|(sin|min|smin|clamp|atan2|pi|e|[xyz()+\-*/^,;=\n 0-9.])*") {
        if let Ok(f) = Formula::parse(&s) {
            let pts = points(5, 1.0, 9);
            let mut out = [0.0; 5];
            f.eval_many(&pts, &mut out);
            let _ = f.gradient(pts[0]);
            let _ = f.tape().to_string();
        }
    }
}

/// A formula tree for the reference evaluator.
#[derive(Clone, Debug)]
enum T {
    Num(f64),
    Var(usize),
    Pi,
    E,
    /// A previous definition (an index, reduced modulo the definitions in scope).
    Def(usize),
    Neg(Box<T>),
    Pos(Box<T>),
    /// `+ - * / ^`, with whether a new line follows the operator.
    Bin(char, Box<T>, Box<T>, bool),
    Call(&'static str, Vec<T>),
}

const UNARY_FNS: &[&str] = &[
    "abs", "sqrt", "exp", "ln", "log", "sin", "cos", "tan", "asin", "acos", "atan", "floor", "sign",
];
const BINARY_FNS: &[&str] = &["atan2", "pow", "hypot", "difference"];
const FOLD_FNS: &[&str] = &["min", "max", "union", "intersection"];
const TERNARY_FNS: &[&str] = &[
    "clamp",
    "mix",
    "lerp",
    "smooth_union",
    "smin",
    "smooth_intersection",
    "smax",
    "smooth_difference",
];

fn tree() -> impl Strategy<Value = T> {
    let leaf = prop_oneof![
        prop_oneof![
            Just(0.0),
            Just(0.5),
            Just(1.0),
            Just(2.0),
            Just(3.0),
            Just(10.0),
            Just(1e-7),
            0.0..100.0f64,
            (0u32..70).prop_map(f64::from),
        ]
        .prop_map(T::Num),
        (0usize..3).prop_map(T::Var),
        (0usize..3).prop_map(T::Var),
        Just(T::Pi),
        Just(T::E),
        (0usize..8).prop_map(T::Def),
    ];
    leaf.prop_recursive(5, 40, 4, |inner| {
        let b = || inner.clone().prop_map(Box::new);
        prop_oneof![
            b().prop_map(T::Neg),
            b().prop_map(T::Pos),
            (prop::sample::select(vec!['+', '-', '*', '/', '^']), b(), b(), any::<bool>())
                .prop_map(|(op, l, r, nl)| T::Bin(op, l, r, nl)),
            (prop::sample::select(vec!['+', '-', '*', '/', '^']), b(), b(), any::<bool>())
                .prop_map(|(op, l, r, nl)| T::Bin(op, l, r, nl)),
            (prop::sample::select(UNARY_FNS), inner.clone()).prop_map(|(f, a)| T::Call(f, vec![a])),
            (prop::sample::select(BINARY_FNS), inner.clone(), inner.clone())
                .prop_map(|(f, a, b)| T::Call(f, vec![a, b])),
            (prop::sample::select(FOLD_FNS), prop::collection::vec(inner.clone(), 2..5))
                .prop_map(|(f, args)| T::Call(f, args)),
            (prop::sample::select(TERNARY_FNS), inner.clone(), inner.clone(), inner.clone())
                .prop_map(|(f, a, b, c)| T::Call(f, vec![a, b, c])),
        ]
    })
}

impl T {
    /// Points `Def` nodes at one of the `n` definitions in scope (or at a variable).
    fn bind(&mut self, n: usize) {
        match self {
            T::Def(i) if n == 0 => *self = T::Var(*i % 3),
            T::Def(i) => *i %= n,
            T::Num(_) | T::Var(_) | T::Pi | T::E => {}
            T::Neg(a) | T::Pos(a) => a.bind(n),
            T::Bin(_, a, b, _) => {
                a.bind(n);
                b.bind(n);
            }
            T::Call(_, args) => args.iter_mut().for_each(|a| a.bind(n)),
        }
    }

    fn prec(&self) -> u8 {
        match self {
            T::Bin('+' | '-', ..) => 1,
            T::Bin('*' | '/', ..) => 2,
            T::Neg(_) | T::Pos(_) => 3,
            T::Bin(..) => 4,
            _ => 5,
        }
    }

    /// Prints with as few parentheses as the grammar needs.
    fn print(&self, out: &mut String, need: u8) {
        let wrap = self.prec() < need;
        if wrap {
            out.push('(');
        }
        match self {
            T::Num(v) => out.push_str(&format!("{v:?}")),
            T::Var(i) => out.push(['x', 'y', 'z'][*i]),
            T::Pi => out.push_str("pi"),
            T::E => out.push('e'),
            T::Def(i) => out.push_str(&format!("d{i}")),
            T::Neg(a) => {
                out.push('-');
                a.print(out, 3);
            }
            T::Pos(a) => {
                out.push('+');
                a.print(out, 3);
            }
            T::Bin(op, a, b, nl) => {
                let (l, r) = match op {
                    '+' | '-' => (1, 2),
                    '*' | '/' => (2, 3),
                    _ => (5, 3),
                };
                a.print(out, l);
                out.push(' ');
                out.push(*op);
                out.push(if *nl { '\n' } else { ' ' });
                b.print(out, r);
            }
            T::Call(f, args) => {
                out.push_str(f);
                out.push('(');
                for (i, a) in args.iter().enumerate() {
                    if i > 0 {
                        out.push_str(if i % 2 == 0 { ",\n  " } else { ", " });
                    }
                    a.print(out, 0);
                }
                out.push(')');
            }
        }
        if wrap {
            out.push(')');
        }
    }

    /// Whether the value does not depend on the point (the compiler folds it to a constant).
    fn is_const(&self, defs: &[(f64, bool)]) -> bool {
        match self {
            T::Num(_) | T::Pi | T::E => true,
            T::Var(_) => false,
            T::Def(i) => defs[*i].1,
            T::Neg(a) | T::Pos(a) => a.is_const(defs),
            T::Bin(_, a, b, _) => a.is_const(defs) && b.is_const(defs),
            T::Call(_, args) => args.iter().all(|a| a.is_const(defs)),
        }
    }

    /// The reference evaluator: a plain tree walk following the documented semantics.
    fn eval(&self, p: DVec3, defs: &[(f64, bool)]) -> f64 {
        let ev = |t: &T| t.eval(p, defs);
        match self {
            T::Num(v) => *v,
            T::Var(i) => p[*i],
            T::Pi => PI,
            T::E => E,
            T::Def(i) => defs[*i].0,
            T::Neg(a) => -ev(a),
            T::Pos(a) => ev(a),
            T::Bin(op, a, b, _) => {
                let (x, y) = (ev(a), ev(b));
                match op {
                    '+' => x + y,
                    '-' => x - y,
                    '*' => x * y,
                    '/' => x / y,
                    _ => ref_pow(x, y, b.is_const(defs)),
                }
            }
            T::Call(f, args) => {
                let v: Vec<f64> = args.iter().map(ev).collect();
                let min = |a: f64, b: f64| if a <= b || b.is_nan() { a } else { b };
                let max = |a: f64, b: f64| if a >= b || b.is_nan() { a } else { b };
                let smin = |a: f64, b: f64, k: f64| {
                    let h = 0.5 + 0.5 * (b - a) / k;
                    if k > 0.0 && h > 0.0 && h < 1.0 {
                        b * (1.0 - h) + a * h - k * h * (1.0 - h)
                    } else {
                        min(a, b)
                    }
                };
                match *f {
                    "abs" => v[0].abs(),
                    "sqrt" => v[0].sqrt(),
                    "exp" => v[0].exp(),
                    "ln" | "log" => v[0].ln(),
                    "sin" => ops::lane::sin(v[0]),
                    "cos" => ops::lane::cos(v[0]),
                    "tan" => v[0].tan(),
                    "asin" => v[0].asin(),
                    "acos" => v[0].acos(),
                    "atan" => v[0].atan(),
                    "floor" => v[0].floor(),
                    "sign" => {
                        if v[0] > 0.0 {
                            1.0
                        } else if v[0] < 0.0 {
                            -1.0
                        } else {
                            v[0]
                        }
                    }
                    "atan2" => v[0].atan2(v[1]),
                    "pow" => ref_pow(v[0], v[1], args[1].is_const(defs)),
                    "hypot" => v[0].hypot(v[1]),
                    "difference" => max(v[0], -v[1]),
                    "min" | "union" => v[1..].iter().fold(v[0], |a, &b| min(a, b)),
                    "max" | "intersection" => v[1..].iter().fold(v[0], |a, &b| max(a, b)),
                    "clamp" => min(max(v[0], v[1]), v[2]),
                    "mix" | "lerp" => v[0] + (v[1] - v[0]) * v[2],
                    "smooth_union" | "smin" => smin(v[0], v[1], v[2]),
                    "smooth_intersection" | "smax" => -smin(-v[0], -v[1], v[2]),
                    "smooth_difference" => -smin(-v[0], v[1], v[2]),
                    other => unreachable!("{other}"),
                }
            }
        }
    }
}

/// `a^b` as documented: constant exponents 0, 1, 0.5 and integers up to 64 are special.
fn ref_pow(a: f64, b: f64, b_const: bool) -> f64 {
    if !b_const {
        return a.powf(b);
    }
    if b == 0.0 {
        return 1.0;
    }
    if b == 1.0 {
        return a;
    }
    if b == 0.5 {
        return a.sqrt();
    }
    if b.fract() == 0.0 && b.abs() <= 64.0 {
        let mut n = b.abs() as u32;
        let mut result: Option<f64> = None;
        let mut base = a;
        loop {
            if n & 1 == 1 {
                result = Some(result.map_or(base, |r| r * base));
            }
            n >>= 1;
            if n == 0 {
                break;
            }
            base *= base;
        }
        let r = result.unwrap_or(a);
        return if b < 0.0 { 1.0 / r } else { r };
    }
    a.powf(b)
}

fn program() -> impl Strategy<Value = (Vec<T>, T)> {
    (prop::collection::vec(tree(), 0..4), tree()).prop_map(|(mut defs, mut last)| {
        for (i, d) in defs.iter_mut().enumerate() {
            d.bind(i);
        }
        last.bind(defs.len());
        (defs, last)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn compiled_formulas_match_the_reference_evaluator(
        (defs, last) in program(),
        pts in prop::collection::vec((-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64), 1..6),
        sep in prop::sample::select(vec!["\n", ";", " ; ", "\n\n# comment\n"]),
    ) {
        let mut src = String::new();
        for (i, d) in defs.iter().enumerate() {
            src += &format!("d{i} = ");
            d.print(&mut src, 0);
            src += sep;
        }
        last.print(&mut src, 0);
        let f = Formula::parse(&src).map_err(|e| TestCaseError::fail(format!("{src:?}: {e}")))?;
        let pts: Vec<DVec3> = pts.into_iter().map(|(x, y, z)| DVec3::new(x, y, z)).collect();
        let mut batch = vec![0.0; pts.len()];
        f.eval_many(&pts, &mut batch);
        for (p, b) in pts.iter().zip(&batch) {
            let mut env: Vec<(f64, bool)> = Vec::new();
            for d in &defs {
                let v = (d.eval(*p, &env), d.is_const(&env));
                env.push(v);
            }
            let want = last.eval(*p, &env);
            let got = f.eval(*p);
            prop_assert!(same(got, want), "{}\nat {}: got {}, want {}\n{}", src, p, got, want, f.tape());
            prop_assert!(same(*b, got));
        }
        // The same points' coordinates as a lattice layer.
        let xs: Vec<f64> = pts.iter().map(|p| p.x).collect();
        let ys: Vec<f64> = pts.iter().map(|p| p.y).collect();
        let mut layer = vec![0.0; xs.len() * ys.len()];
        f.eval_layer(&xs, &ys, pts[0].z, &mut layer);
        let mut sampled = vec![0.0; xs.len() * ys.len()];
        f.sampler(&xs, &ys).layer(pts[0].z, 0..ys.len(), &mut sampled);
        for (k, (v, s)) in layer.iter().zip(&sampled).enumerate() {
            let p = DVec3::new(xs[k % xs.len()], ys[k / xs.len()], pts[0].z);
            prop_assert!(same(*v, f.eval(p)), "{}\nlayer at {}: {} vs {}", src, p, v, f.eval(p));
            prop_assert!(same(*s, f.eval(p)), "{}\nsampler at {}: {} vs {}", src, p, s, f.eval(p));
        }
    }
}

#[test]
fn an_unclosed_paren_before_a_bad_token_reports_the_token() {
    // The lexer's error wins over "expected ')'", and it cites no second position.
    for s in ["(2 $", "(x @", "(1 + (y ?"] {
        let e = err(s);
        assert_eq!(e.related(), None, "{s:?}: {e}");
        assert!(!e.to_string().contains("opened at"), "{s:?}: {e}");
    }
    let e = err("(x 1");
    assert_eq!(e.related(), Some((1, 1)), "{e}");
}
