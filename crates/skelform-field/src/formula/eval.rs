//! Running a tape: values, and values with gradients by forward-mode differentiation.
//!
//! The batch interpreters run one instruction at a time over `L` lanes (one tight loop per
//! instruction, which the compiler vectorises; with AVX2 where the CPU has it). The
//! single-point paths use the same lane functions (values through a scalar interpreter,
//! gradients through the dual interpreter with `L = 1`), so a point gives bit-identical
//! results whichever way it is evaluated. Nothing allocates per point: registers live on the
//! stack (single points) or in a per-thread cache (batches).

use std::cell::RefCell;
use std::ops::Range;
use std::thread::LocalKey;

use glam::DVec3;

use super::compile::{BinOp, FIRST_CONST_REG, Instr, Lattice, Planar, Tape, UnOp, Varies};
use crate::LayerSampler;

/// Lanes per batch for values: 128 × 8 bytes = 1 KiB per register.
pub(crate) const LANES: usize = 128;
/// Lanes per batch for values with gradients: 64 × 4 × 8 bytes = 2 KiB per register.
pub(crate) const AD_LANES: usize = 64;
/// Registers kept on the stack by the single-point paths; larger tapes use a thread-local.
const STACK_REGS: usize = 48;

/// Lane functions that are not plain `f64` methods. Both paths, and constant folding, use
/// exactly these.
pub(crate) mod lane {
    #[inline(always)]
    pub(super) fn neg(a: f64) -> f64 {
        -a
    }
    /// `1` for positive, `−1` for negative, the argument itself for `±0` and NaN.
    #[inline(always)]
    pub(super) fn sign(a: f64) -> f64 {
        if a > 0.0 {
            1.0
        } else if a < 0.0 {
            -1.0
        } else {
            a
        }
    }
    /// `sin`: the vectorisable [`super::trig`] kernel, `f64::sin` for huge or non-finite
    /// arguments. Batches compute the same per lane (see `trig_batch`).
    #[inline(always)]
    pub(crate) fn sin(a: f64) -> f64 {
        if a.abs() <= super::trig::FAST_MAX { super::trig::sin(a) } else { a.sin() }
    }
    #[inline(always)]
    pub(crate) fn cos(a: f64) -> f64 {
        if a.abs() <= super::trig::FAST_MAX { super::trig::cos(a) } else { a.cos() }
    }
    #[inline(always)]
    pub(super) fn add(a: f64, b: f64) -> f64 {
        a + b
    }
    #[inline(always)]
    pub(super) fn sub(a: f64, b: f64) -> f64 {
        a - b
    }
    #[inline(always)]
    pub(super) fn mul(a: f64, b: f64) -> f64 {
        a * b
    }
    #[inline(always)]
    pub(super) fn div(a: f64, b: f64) -> f64 {
        a / b
    }
    /// Whether `min(a, b)` takes `a`: on ties and when `b` is NaN.
    #[inline(always)]
    pub(super) fn min_takes_a(a: f64, b: f64) -> bool {
        a <= b || b.is_nan()
    }
    #[inline(always)]
    pub(super) fn max_takes_a(a: f64, b: f64) -> bool {
        a >= b || b.is_nan()
    }
    #[inline(always)]
    pub(super) fn min(a: f64, b: f64) -> f64 {
        if min_takes_a(a, b) { a } else { b }
    }
    #[inline(always)]
    pub(super) fn max(a: f64, b: f64) -> f64 {
        if max_takes_a(a, b) { a } else { b }
    }
    /// The weight of `a` in the smooth minimum, `0.5 + 0.5 (b − a) / k`, and whether the
    /// point is in the blend zone `0 < h < 1` (which needs `k > 0`).
    #[inline(always)]
    pub(super) fn smin_blend(a: f64, b: f64, k: f64) -> (f64, bool) {
        let h = 0.5 + 0.5 * (b - a) / k;
        (h, k > 0.0 && h > 0.0 && h < 1.0)
    }
    /// Polynomial smooth minimum. Outside the blend zone (and when `k` is not positive or
    /// NaN, or an operand is NaN) it is exactly `min(a, b)`: no division by zero is used, and
    /// an infinite operand does not turn the result into NaN.
    #[inline(always)]
    pub(super) fn smin(a: f64, b: f64, k: f64) -> f64 {
        let (h, blend) = smin_blend(a, b, k);
        if blend { b * (1.0 - h) + a * h - k * h * (1.0 - h) } else { min(a, b) }
    }
}

/// Sine and cosine without a libm call, so that a batch loop vectorises.
///
/// The argument is reduced to `r ∈ [−π/4, π/4]` (about) with `a = kπ/2 + r`, using π/2
/// split into three parts whose products with `k` are exact for `|k| < 2^19` (Cody–Waite),
/// then Taylor polynomials through degree 17 (sine) and 18 (cosine), whose truncation error
/// is far below an ulp there. Results are within about one ulp of the correctly rounded
/// value (at most two ulps in the tests). Beyond [`trig::FAST_MAX`] (and for non-finite arguments) callers use `f64::sin` /
/// `f64::cos` instead.
pub(crate) mod trig {
    /// Largest `|a|` handled here: about `2^19 · π/2`.
    pub(crate) const FAST_MAX: f64 = 823_549.0;
    /// π/2 = `PIO2_1 + PIO2_2 + PIO2_3` to about 160 bits; the first two have 33 significant
    /// bits, so `k · PIO2_i` is exact.
    const PIO2_1: f64 = 1.570_796_326_734_125_6;
    const PIO2_2: f64 = 6.077_100_506_303_966e-11;
    const PIO2_3: f64 = 2.022_266_248_795_950_6e-21;
    /// Adding `1.5 · 2^52` rounds to an integer, which then sits in the low mantissa bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;

    const fn inv_factorial(n: u32) -> f64 {
        let mut f = 1.0;
        let mut i = 2;
        while i <= n {
            f *= i as f64; // exact: 18! < 2^53
            i += 1;
        }
        1.0 / f
    }
    const S3: f64 = -inv_factorial(3);
    const S5: f64 = inv_factorial(5);
    const S7: f64 = -inv_factorial(7);
    const S9: f64 = inv_factorial(9);
    const S11: f64 = -inv_factorial(11);
    const S13: f64 = inv_factorial(13);
    const S15: f64 = -inv_factorial(15);
    const S17: f64 = inv_factorial(17);
    const C4: f64 = inv_factorial(4);
    const C6: f64 = -inv_factorial(6);
    const C8: f64 = inv_factorial(8);
    const C10: f64 = -inv_factorial(10);
    const C12: f64 = inv_factorial(12);
    const C14: f64 = -inv_factorial(14);
    const C16: f64 = inv_factorial(16);
    const C18: f64 = -inv_factorial(18);

    /// `(r, q)` with `a = kπ/2 + r` and `k ≡ q (mod 4)` in the low bits of `q`.
    #[inline(always)]
    fn reduce(a: f64) -> (f64, u64) {
        let t = a * std::f64::consts::FRAC_2_PI + ROUND;
        let k = t - ROUND;
        let r = ((a - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
        (r, t.to_bits())
    }

    #[inline(always)]
    fn sin_kernel(x: f64) -> f64 {
        let z = x * x;
        let p = S3 + z * (S5 + z * (S7 + z * (S9 + z * (S11 + z * (S13 + z * (S15 + z * S17))))));
        // Keeps the sign of zero (−0 + (+0) would be +0).
        if x == 0.0 { x } else { x + x * z * p }
    }

    #[inline(always)]
    fn cos_kernel(x: f64) -> f64 {
        let z = x * x;
        let p = C4 + z * (C6 + z * (C8 + z * (C10 + z * (C12 + z * (C14 + z * (C16 + z * C18))))));
        let hz = 0.5 * z;
        let w = 1.0 - hz;
        // `(1 − w) − hz` recovers the rounding error of `w`.
        w + (((1.0 - w) - hz) + z * z * p)
    }

    /// Picks `sin r` or `cos r` by the quadrant's low bit and negates by the next one, with
    /// bit operations only (so the loop stays branch-free).
    #[inline(always)]
    fn finish(r: f64, q: u64) -> f64 {
        let (s, c) = (sin_kernel(r), cos_kernel(r));
        let take_cos = (q & 1).wrapping_neg();
        let bits = (s.to_bits() & !take_cos) | (c.to_bits() & take_cos);
        f64::from_bits(bits ^ ((q & 2) << 62))
    }

    /// Sine for `|a| ≤ FAST_MAX` (garbage, but no panic, beyond).
    #[inline(always)]
    pub(crate) fn sin(a: f64) -> f64 {
        let (r, q) = reduce(a);
        finish(r, q)
    }

    /// Cosine for `|a| ≤ FAST_MAX`: `cos a = sin(a + π/2)`, one quadrant on.
    #[inline(always)]
    pub(crate) fn cos(a: f64) -> f64 {
        let (r, q) = reduce(a);
        finish(r, q.wrapping_add(1))
    }
}

/// Binds `$f` to the lane function of a unary op and evaluates `$body`.
macro_rules! with_unary {
    ($op:expr, $f:ident => $body:expr) => {
        match $op {
            UnOp::Neg => {
                let $f = lane::neg;
                $body
            }
            UnOp::Abs => {
                let $f = f64::abs;
                $body
            }
            UnOp::Sqrt => {
                let $f = f64::sqrt;
                $body
            }
            UnOp::Exp => {
                let $f = f64::exp;
                $body
            }
            UnOp::Ln => {
                let $f = f64::ln;
                $body
            }
            UnOp::Sin => {
                let $f = lane::sin;
                $body
            }
            UnOp::Cos => {
                let $f = lane::cos;
                $body
            }
            UnOp::Tan => {
                let $f = f64::tan;
                $body
            }
            UnOp::Asin => {
                let $f = f64::asin;
                $body
            }
            UnOp::Acos => {
                let $f = f64::acos;
                $body
            }
            UnOp::Atan => {
                let $f = f64::atan;
                $body
            }
            UnOp::Floor => {
                let $f = f64::floor;
                $body
            }
            UnOp::Sign => {
                let $f = lane::sign;
                $body
            }
        }
    };
}

/// Binds `$g` to `|a| (value, derivative)` for a unary op. Values use the same expressions
/// as [`with_unary`].
macro_rules! with_unary_ad {
    ($op:expr, $g:ident => $body:expr) => {
        match $op {
            UnOp::Neg => {
                let $g = |a: f64| (lane::neg(a), -1.0);
                $body
            }
            UnOp::Abs => {
                // abs'(0) = 0.
                let $g = |a: f64| (f64::abs(a), lane::sign(a));
                $body
            }
            UnOp::Sqrt => {
                // sqrt'(0) = +inf; a zero tangent still gives a zero derivative (see `tm`).
                let $g = |a: f64| {
                    let v = f64::sqrt(a);
                    (v, 0.5 / v)
                };
                $body
            }
            UnOp::Exp => {
                let $g = |a: f64| {
                    let v = f64::exp(a);
                    (v, v)
                };
                $body
            }
            UnOp::Ln => {
                let $g = |a: f64| (f64::ln(a), 1.0 / a);
                $body
            }
            UnOp::Sin => {
                let $g = |a: f64| (lane::sin(a), lane::cos(a));
                $body
            }
            UnOp::Cos => {
                let $g = |a: f64| (lane::cos(a), -lane::sin(a));
                $body
            }
            UnOp::Tan => {
                let $g = |a: f64| {
                    let v = f64::tan(a);
                    (v, 1.0 + v * v)
                };
                $body
            }
            UnOp::Asin => {
                let $g = |a: f64| (f64::asin(a), 1.0 / (1.0 - a * a).sqrt());
                $body
            }
            UnOp::Acos => {
                let $g = |a: f64| (f64::acos(a), -1.0 / (1.0 - a * a).sqrt());
                $body
            }
            UnOp::Atan => {
                let $g = |a: f64| (f64::atan(a), 1.0 / (1.0 + a * a));
                $body
            }
            UnOp::Floor => {
                let $g = |a: f64| (f64::floor(a), 0.0);
                $body
            }
            UnOp::Sign => {
                let $g = |a: f64| (lane::sign(a), 0.0);
                $body
            }
        }
    };
}

/// Binds `$f` to the lane function of a binary op and evaluates `$body`.
macro_rules! with_binary {
    ($op:expr, $f:ident => $body:expr) => {
        match $op {
            BinOp::Add => {
                let $f = lane::add;
                $body
            }
            BinOp::Sub => {
                let $f = lane::sub;
                $body
            }
            BinOp::Mul => {
                let $f = lane::mul;
                $body
            }
            BinOp::Div => {
                let $f = lane::div;
                $body
            }
            BinOp::Pow => {
                let $f = f64::powf;
                $body
            }
            BinOp::Atan2 => {
                let $f = f64::atan2;
                $body
            }
            BinOp::Min => {
                let $f = lane::min;
                $body
            }
            BinOp::Max => {
                let $f = lane::max;
                $body
            }
            BinOp::Hypot => {
                let $f = f64::hypot;
                $body
            }
        }
    };
}

/// Binds `$g` to `|a, b| (value, ∂/∂a, ∂/∂b)` for a binary op.
macro_rules! with_binary_ad {
    ($op:expr, $g:ident => $body:expr) => {
        match $op {
            BinOp::Add => {
                let $g = |a: f64, b: f64| (lane::add(a, b), 1.0, 1.0);
                $body
            }
            BinOp::Sub => {
                let $g = |a: f64, b: f64| (lane::sub(a, b), 1.0, -1.0);
                $body
            }
            BinOp::Mul => {
                let $g = |a: f64, b: f64| (lane::mul(a, b), b, a);
                $body
            }
            BinOp::Div => {
                let $g = |a: f64, b: f64| {
                    let q = lane::div(a, b);
                    (q, 1.0 / b, -q / b)
                };
                $body
            }
            BinOp::Pow => {
                let $g = |a: f64, b: f64| {
                    let v = f64::powf(a, b);
                    (v, b * a.powf(b - 1.0), v * a.ln())
                };
                $body
            }
            BinOp::Atan2 => {
                // atan2(a, b) is the angle of (b, a); its derivatives are taken as 0 at the origin.
                let $g = |a: f64, b: f64| {
                    let v = f64::atan2(a, b);
                    let r2 = a * a + b * b;
                    if r2 == 0.0 { (v, 0.0, 0.0) } else { (v, b / r2, -a / r2) }
                };
                $body
            }
            BinOp::Min => {
                let $g = |a: f64, b: f64| {
                    let s = if lane::min_takes_a(a, b) { 1.0 } else { 0.0 };
                    (lane::min(a, b), s, 1.0 - s)
                };
                $body
            }
            BinOp::Max => {
                let $g = |a: f64, b: f64| {
                    let s = if lane::max_takes_a(a, b) { 1.0 } else { 0.0 };
                    (lane::max(a, b), s, 1.0 - s)
                };
                $body
            }
            BinOp::Hypot => {
                // Derivatives taken as 0 where hypot is 0.
                let $g = |a: f64, b: f64| {
                    let h = f64::hypot(a, b);
                    if h == 0.0 { (h, 0.0, 0.0) } else { (h, a / h, b / h) }
                };
                $body
            }
        }
    };
}

/// `(value, ∂/∂a, ∂/∂b, ∂/∂k)` of the smooth minimum. In the blend zone the `∂h` terms
/// cancel (the polynomial smooth minimum is C¹), leaving `h`, `1 − h` and `−h(1 − h)`;
/// outside it, those of the operand `min` selects.
#[inline(always)]
fn smin_ad(a: f64, b: f64, k: f64) -> (f64, f64, f64, f64) {
    let v = lane::smin(a, b, k);
    let (h, blend) = lane::smin_blend(a, b, k);
    if blend {
        (v, h, 1.0 - h, -h * (1.0 - h))
    } else {
        let s = if lane::min_takes_a(a, b) { 1.0 } else { 0.0 };
        (v, s, 1.0 - s, 0.0)
    }
}

/// One chain-rule term `f · t`, taken as 0 when either factor is 0, so a local derivative
/// that is infinite or NaN (sqrt at 0, ln at 0, the unselected side of a min) does not spoil a
/// gradient it does not contribute to.
#[inline(always)]
fn tm(f: f64, t: f64) -> f64 {
    if f == 0.0 || t == 0.0 { 0.0 } else { f * t }
}

pub(crate) fn eval_un(op: UnOp, a: f64) -> f64 {
    with_unary!(op, f => f(a))
}

pub(crate) fn eval_bin(op: BinOp, a: f64, b: f64) -> f64 {
    with_binary!(op, f => f(a, b))
}

pub(crate) fn eval_smin(a: f64, b: f64, k: f64) -> f64 {
    lane::smin(a, b, k)
}

/// Borrows register `out` mutably and the others shared; `out` differs from every operand
/// (the register allocator guarantees it).
#[inline(always)]
fn split<T, const N: usize>(regs: &mut [T], out: u32, ins: [u32; N]) -> (&mut T, [&T; N]) {
    let out = out as usize;
    let (lo, rest) = regs.split_at_mut(out);
    let (o, hi) = rest.split_first_mut().expect("register out of range");
    let hi: &[T] = hi;
    let lo: &[T] = lo;
    let get = |i: u32| {
        let i = i as usize;
        debug_assert_ne!(i, out, "an instruction overwrites its operand");
        if i < out { &lo[i] } else { &hi[i - out - 1] }
    };
    (o, ins.map(get))
}

/// Runs the tape's instructions over the first `n` lanes of every register. Inputs and
/// constants must already be loaded.
#[inline(always)]
fn run_values<const L: usize>(tape: &Tape, regs: &mut [[f64; L]], n: usize) {
    let n = n.min(L);
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op, out, a } => {
                let (o, [a]) = split(regs, out, [a]);
                match op {
                    UnOp::Sin => trig_batch(&mut o[..n], &a[..n], trig::sin, f64::sin),
                    UnOp::Cos => trig_batch(&mut o[..n], &a[..n], trig::cos, f64::cos),
                    _ => with_unary!(op, f => {
                        for i in 0..n {
                            o[i] = f(a[i]);
                        }
                    }),
                }
            }
            Instr::Binary { op, out, a, b } => {
                let (o, [a, b]) = split(regs, out, [a, b]);
                with_binary!(op, f => {
                    for i in 0..n {
                        o[i] = f(a[i], b[i]);
                    }
                })
            }
            Instr::SMin { out, a, b, k } => {
                let (o, [a, b, k]) = split(regs, out, [a, b, k]);
                for i in 0..n {
                    o[i] = lane::smin(a[i], b[i], k[i]);
                }
            }
        }
    }
}

/// Wider vectors where the CPU has them. The instructions are the same IEEE operations
/// (no fused multiply-add: Rust never contracts `a * b + c`), so the results are
/// bit-identical to the baseline build and to the single-point path.
#[cfg(target_arch = "x86_64")]
mod wide {
    use super::{Dual, Tape};

    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn run_values<const L: usize>(tape: &Tape, regs: &mut [[f64; L]], n: usize) {
        super::run_values(tape, regs, n)
    }

    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn run_duals<const L: usize>(tape: &Tape, regs: &mut [Dual<L>], n: usize) {
        super::run_duals(tape, regs, n)
    }
}

/// [`run_values`] for batches, with the widest vectors available.
fn run_values_batch<const L: usize>(tape: &Tape, regs: &mut [[f64; L]], n: usize) {
    #[cfg(target_arch = "x86_64")]
    if wide::available() {
        // SAFETY: AVX2 was detected at run time.
        unsafe { wide::run_values(tape, regs, n) };
        return;
    }
    run_values(tape, regs, n)
}

/// [`run_duals`] for batches, with the widest vectors available.
fn run_duals_batch<const L: usize>(tape: &Tape, regs: &mut [Dual<L>], n: usize) {
    #[cfg(target_arch = "x86_64")]
    if wide::available() {
        // SAFETY: AVX2 was detected at run time.
        unsafe { wide::run_duals(tape, regs, n) };
        return;
    }
    run_duals(tape, regs, n)
}

/// `lane::sin`/`lane::cos` over a batch: the branch-free kernel on every lane (vectorised),
/// then the libm function on the rare lanes out of its range.
#[inline(always)]
fn trig_batch(o: &mut [f64], a: &[f64], fast: fn(f64) -> f64, slow: fn(f64) -> f64) {
    for (o, &a) in o.iter_mut().zip(a) {
        *o = fast(a);
    }
    for (o, &a) in o.iter_mut().zip(a) {
        if a.abs() > trig::FAST_MAX || a.is_nan() {
            *o = slow(a);
        }
    }
}

/// A register of the differentiating interpreter: values and the three partials per lane.
#[derive(Clone, Copy)]
pub(crate) struct Dual<const L: usize> {
    v: [f64; L],
    d: [[f64; L]; 3],
}

impl<const L: usize> Dual<L> {
    const ZERO: Self = Self { v: [0.0; L], d: [[0.0; L]; 3] };
}

#[inline(always)]
fn run_duals<const L: usize>(tape: &Tape, regs: &mut [Dual<L>], n: usize) {
    let n = n.min(L);
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op: op @ (UnOp::Sin | UnOp::Cos), out, a } => {
                // Value and derivative from the vectorised kernels (same values as `lane`).
                let (o, [a]) = split(regs, out, [a]);
                let mut deriv = [0.0; L];
                if op == UnOp::Sin {
                    trig_batch(&mut o.v[..n], &a.v[..n], trig::sin, f64::sin);
                    trig_batch(&mut deriv[..n], &a.v[..n], trig::cos, f64::cos);
                } else {
                    trig_batch(&mut o.v[..n], &a.v[..n], trig::cos, f64::cos);
                    trig_batch(&mut deriv[..n], &a.v[..n], trig::sin, f64::sin);
                    deriv[..n].iter_mut().for_each(|d| *d = -*d);
                }
                for (od, ad) in o.d.iter_mut().zip(&a.d) {
                    for ((o, &d), &t) in od[..n].iter_mut().zip(&deriv[..n]).zip(&ad[..n]) {
                        *o = tm(d, t);
                    }
                }
            }
            Instr::Unary { op, out, a } => {
                let (o, [a]) = split(regs, out, [a]);
                with_unary_ad!(op, g => {
                    for i in 0..n {
                        let (v, fa) = g(a.v[i]);
                        o.v[i] = v;
                        for c in 0..3 {
                            o.d[c][i] = tm(fa, a.d[c][i]);
                        }
                    }
                })
            }
            Instr::Binary { op, out, a, b } => {
                let (o, [a, b]) = split(regs, out, [a, b]);
                with_binary_ad!(op, g => {
                    for i in 0..n {
                        let (v, fa, fb) = g(a.v[i], b.v[i]);
                        o.v[i] = v;
                        for c in 0..3 {
                            o.d[c][i] = tm(fa, a.d[c][i]) + tm(fb, b.d[c][i]);
                        }
                    }
                })
            }
            Instr::SMin { out, a, b, k } => {
                let (o, [a, b, k]) = split(regs, out, [a, b, k]);
                for i in 0..n {
                    let (v, fa, fb, fk) = smin_ad(a.v[i], b.v[i], k.v[i]);
                    o.v[i] = v;
                    for c in 0..3 {
                        o.d[c][i] = tm(fa, a.d[c][i]) + tm(fb, b.d[c][i]) + tm(fk, k.d[c][i]);
                    }
                }
            }
        }
    }
}

thread_local! {
    static VALUE_SCRATCH: RefCell<Vec<[f64; LANES]>> = const { RefCell::new(Vec::new()) };
    static DUAL_SCRATCH: RefCell<Vec<Dual<AD_LANES>>> = const { RefCell::new(Vec::new()) };
    static POINT_SCRATCH: RefCell<Vec<[f64; 1]>> = const { RefCell::new(Vec::new()) };
    static POINT_DUAL_SCRATCH: RefCell<Vec<Dual<1>>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` on `len` registers from the thread's cache (or fresh ones when the cache is busy
/// or gone), so evaluation does not allocate once a thread has warmed up.
fn with_scratch<T: Copy + 'static, R>(
    key: &'static LocalKey<RefCell<Vec<T>>>,
    len: usize,
    fill: T,
    f: impl FnOnce(&mut [T]) -> R,
) -> R {
    let mut f = Some(f);
    let cached = key.try_with(|cell| {
        let mut regs = cell.try_borrow_mut().ok()?;
        if regs.len() < len {
            regs.resize(len, fill);
        }
        let f = f.take()?;
        Some(f(&mut regs[..len]))
    });
    match (cached, f) {
        (Ok(Some(r)), _) => r,
        (_, Some(f)) => f(&mut vec![fill; len]),
        (_, None) => unreachable!("the closure ran but gave no result"),
    }
}

/// Loads the inputs and constants, runs the tape and returns the result register's value.
fn point_values(tape: &Tape, p: DVec3, regs: &mut [[f64; 1]]) -> f64 {
    regs[0] = [p.x];
    regs[1] = [p.y];
    regs[2] = [p.z];
    for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&tape.consts) {
        *r = [c];
    }
    run_scalar(tape, regs.as_flattened_mut());
    regs[tape.result as usize][0]
}

/// The single-point interpreter: the same lane functions as [`run_values`] (so the same
/// bits), without the batch machinery.
fn run_scalar(tape: &Tape, r: &mut [f64]) {
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op, out, a } => r[out as usize] = eval_un(op, r[a as usize]),
            Instr::Binary { op, out, a, b } => {
                r[out as usize] = eval_bin(op, r[a as usize], r[b as usize])
            }
            Instr::SMin { out, a, b, k } => {
                r[out as usize] = lane::smin(r[a as usize], r[b as usize], r[k as usize]);
            }
        }
    }
}

pub(crate) fn eval_point(tape: &Tape, p: DVec3) -> f64 {
    if tape.n_regs <= STACK_REGS {
        let mut regs = [[0.0; 1]; STACK_REGS];
        point_values(tape, p, &mut regs[..tape.n_regs])
    } else {
        with_scratch(&POINT_SCRATCH, tape.n_regs, [0.0; 1], |regs| point_values(tape, p, regs))
    }
}

pub(crate) fn eval_batch(tape: &Tape, points: &[DVec3], out: &mut [f64]) {
    let m = points.len().min(out.len());
    let (points, out) = (&points[..m], &mut out[..m]);
    if m == 0 {
        return;
    }
    with_scratch(&VALUE_SCRATCH, tape.n_regs, [0.0; LANES], |regs| {
        for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&tape.consts) {
            *r = [c; LANES];
        }
        let result = tape.result as usize;
        for (pts, outs) in points.chunks(LANES).zip(out.chunks_mut(LANES)) {
            let n = pts.len();
            {
                let [xs, ys, zs, ..] = regs else {
                    unreachable!("a tape has at least 3 registers")
                };
                for (i, p) in pts.iter().enumerate() {
                    xs[i] = p.x;
                    ys[i] = p.y;
                    zs[i] = p.z;
                }
            }
            run_values_batch(tape, regs, n);
            outs.copy_from_slice(&regs[result][..n]);
        }
    })
}

/// Values on a lattice layer, `out[i + xs.len()·j] = f(xs[i], ys[j], z)`, with the terms
/// that depend on fewer axes computed once per layer, row or column ([`Lattice`]).
pub(crate) fn eval_layer(lattice: &Lattice, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
    run_layer(lattice, xs, ys, z, &[], out)
}

/// [`eval_layer`] for a split with [`Varies::Plane`] slots: `planes[p]` holds the `p`-th
/// such slot's values at the same points (`xs.len()·ys.len()` each, rows as in `out`).
pub(crate) fn run_layer(
    lattice: &Lattice,
    xs: &[f64],
    ys: &[f64],
    z: f64,
    planes: &[&[f64]],
    out: &mut [f64],
) {
    let nx = xs.len();
    let (Some(&x0), Some(&y0)) = (xs.first(), ys.first()) else { return };
    let mut planes = planes.iter();
    // Where each slot's values come from. Down a column the value is the same, so the first
    // row's points will do; along a row, the first column's.
    let loads: Vec<Load> = lattice
        .slots
        .iter()
        .map(|slot| match slot.varies {
            Varies::Layer => Load::Layer(eval_point(&slot.tape, DVec3::new(x0, y0, z))),
            Varies::Row => Load::Row(
                ys.iter().map(|&y| eval_point(&slot.tape, DVec3::new(x0, y, z))).collect(),
            ),
            Varies::Column => {
                let points: Vec<DVec3> = xs.iter().map(|&x| DVec3::new(x, y0, z)).collect();
                let mut values = vec![0.0; nx];
                eval_batch(&slot.tape, &points, &mut values);
                Load::Column(values)
            }
            Varies::Plane => Load::Plane(planes.next().expect("a plane's values for each slot")),
        })
        .collect();
    let point = &lattice.point;
    let first_slot = FIRST_CONST_REG + point.consts.len();
    with_scratch(&VALUE_SCRATCH, point.n_regs, [0.0; LANES], |regs| {
        for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&point.consts) {
            *r = [c; LANES];
        }
        regs[2] = [z; LANES];
        for (s, load) in loads.iter().enumerate() {
            if let Load::Layer(v) = *load {
                regs[first_slot + s] = [v; LANES];
            }
        }
        // A stretch of columns at a time, down all the rows: the column terms are loaded
        // once per stretch, the row terms (a broadcast) and plane terms once per row.
        for at in (0..nx).step_by(LANES) {
            let n = LANES.min(nx - at);
            regs[0][..n].copy_from_slice(&xs[at..at + n]);
            for (s, load) in loads.iter().enumerate() {
                if let Load::Column(column) = load {
                    regs[first_slot + s][..n].copy_from_slice(&column[at..at + n]);
                }
            }
            for (j, &y) in ys.iter().enumerate() {
                regs[1] = [y; LANES];
                for (s, load) in loads.iter().enumerate() {
                    match load {
                        Load::Row(row) => regs[first_slot + s] = [row[j]; LANES],
                        Load::Plane(plane) => {
                            regs[first_slot + s][..n].copy_from_slice(&plane[j * nx + at..][..n])
                        }
                        Load::Layer(_) | Load::Column(_) => {}
                    }
                }
                run_values_batch(point, regs, n);
                out[j * nx + at..][..n].copy_from_slice(&regs[point.result as usize][..n]);
            }
        }
    })
}

/// The layers of one lattice, the plane slots' values computed once.
pub(crate) struct Sampler<'a> {
    lattice: &'a Lattice,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// Per [`Varies::Plane`] slot, its values at every `(x, y)`, x fastest.
    planes: Vec<Vec<f64>>,
}

impl<'a> Sampler<'a> {
    pub(crate) fn with_planes(planar: &'a Planar, xs: Vec<f64>, ys: Vec<f64>) -> Self {
        let planes = planar
            .planes
            .iter()
            .map(|plane| {
                let mut values = vec![0.0; xs.len() * ys.len()];
                // The term does not depend on z: any layer gives its values.
                eval_layer(plane, &xs, &ys, 0.0, &mut values);
                values
            })
            .collect();
        Sampler { lattice: &planar.lattice, xs, ys, planes }
    }

    /// For a split without plane slots ([`Lattice`]).
    pub(crate) fn without_planes(lattice: &'a Lattice, xs: Vec<f64>, ys: Vec<f64>) -> Self {
        Sampler { lattice, xs, ys, planes: Vec::new() }
    }
}

impl LayerSampler for Sampler<'_> {
    fn layer(&self, z: f64, rows: Range<usize>, out: &mut [f64]) {
        let nx = self.xs.len();
        let planes: Vec<&[f64]> =
            self.planes.iter().map(|p| &p[rows.start * nx..rows.end * nx]).collect();
        run_layer(self.lattice, &self.xs, &self.ys[rows], z, &planes, out)
    }
}

/// Where a lattice slot's values come from, in [`run_layer`].
enum Load<'a> {
    Layer(f64),
    Row(Vec<f64>),
    Column(Vec<f64>),
    Plane(&'a [f64]),
}

/// Seeds the inputs (`∂x/∂x = 1`, ...) and constants (zero partials) of dual registers.
fn seed<const L: usize>(tape: &Tape, regs: &mut [Dual<L>]) {
    for (axis, r) in regs[..FIRST_CONST_REG].iter_mut().enumerate() {
        *r = Dual::ZERO;
        r.d[axis] = [1.0; L];
    }
    for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&tape.consts) {
        *r = Dual { v: [c; L], d: [[0.0; L]; 3] };
    }
}

fn point_duals(tape: &Tape, p: DVec3, regs: &mut [Dual<1>]) -> (f64, DVec3) {
    seed(tape, regs);
    regs[0].v = [p.x];
    regs[1].v = [p.y];
    regs[2].v = [p.z];
    run_duals(tape, regs, 1);
    let r = &regs[tape.result as usize];
    (r.v[0], DVec3::new(r.d[0][0], r.d[1][0], r.d[2][0]))
}

pub(crate) fn grad_point(tape: &Tape, p: DVec3) -> (f64, DVec3) {
    if tape.n_regs <= STACK_REGS {
        let mut regs = [Dual::<1>::ZERO; STACK_REGS];
        point_duals(tape, p, &mut regs[..tape.n_regs])
    } else {
        with_scratch(&POINT_DUAL_SCRATCH, tape.n_regs, Dual::ZERO, |regs| {
            point_duals(tape, p, regs)
        })
    }
}

pub(crate) fn grad_batch(tape: &Tape, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
    let m = points.len().min(values.len()).min(grads.len());
    let (points, values, grads) = (&points[..m], &mut values[..m], &mut grads[..m]);
    if m == 0 {
        return;
    }
    with_scratch(&DUAL_SCRATCH, tape.n_regs, Dual::ZERO, |regs| {
        seed(tape, regs);
        let result = tape.result as usize;
        let chunks = points
            .chunks(AD_LANES)
            .zip(values.chunks_mut(AD_LANES))
            .zip(grads.chunks_mut(AD_LANES));
        for ((pts, vals), gs) in chunks {
            let n = pts.len();
            for (i, p) in pts.iter().enumerate() {
                regs[0].v[i] = p.x;
                regs[1].v[i] = p.y;
                regs[2].v[i] = p.z;
            }
            run_duals_batch(tape, regs, n);
            let r = &regs[result];
            vals.copy_from_slice(&r.v[..n]);
            for (i, g) in gs.iter_mut().enumerate() {
                *g = DVec3::new(r.d[0][i], r.d[1][i], r.d[2][i]);
            }
        }
    })
}
