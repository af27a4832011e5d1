//! Sine and cosine without a libm call, so that a batch loop vectorises.
//!
//! The argument is reduced to `r ∈ [−π/4, π/4]` (about) with `a = kπ/2 + r`, using π/2
//! split into three parts whose products with `k` are exact for `|k| < 2^19` (Cody–Waite),
//! then Taylor polynomials through degree 17 (sine) and 18 (cosine), whose truncation error
//! is far below an ulp there. Results are within about one ulp of the correctly rounded
//! value (at most two ulps in the tests). Beyond [`FAST_MAX`] (and for non-finite arguments) callers use `f64::sin` /
//! `f64::cos` instead.

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
