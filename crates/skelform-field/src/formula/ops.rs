//! The operations of the tape and what they mean: the one-operand and two-operand
//! operations, their value on one `f64` (the lane functions), their derivatives, and the
//! polynomial smooth minimum.
//!
//! Both the compiler (constant folding, in [`super::compile`]) and the interpreters (in
//! [`super::eval`]) take their arithmetic from here, so a folded constant and a computed value
//! are the same bits. This module uses neither of them: `compile` and `eval` use `ops`, and
//! `eval` uses `compile`'s tape, so the dependencies run one way.

use super::trig;

/// One-operand operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum UnOp {
    Neg,
    Abs,
    Sqrt,
    Exp,
    Ln,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Floor,
    Sign,
}

impl UnOp {
    pub(crate) fn name(self) -> &'static str {
        match self {
            UnOp::Neg => "neg",
            UnOp::Abs => "abs",
            UnOp::Sqrt => "sqrt",
            UnOp::Exp => "exp",
            UnOp::Ln => "ln",
            UnOp::Sin => "sin",
            UnOp::Cos => "cos",
            UnOp::Tan => "tan",
            UnOp::Asin => "asin",
            UnOp::Acos => "acos",
            UnOp::Atan => "atan",
            UnOp::Floor => "floor",
            UnOp::Sign => "sign",
        }
    }
}

/// Two-operand operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Atan2,
    Min,
    Max,
    Hypot,
}

impl BinOp {
    pub(crate) fn name(self) -> &'static str {
        match self {
            BinOp::Add => "add",
            BinOp::Sub => "sub",
            BinOp::Mul => "mul",
            BinOp::Div => "div",
            BinOp::Pow => "pow",
            BinOp::Atan2 => "atan2",
            BinOp::Min => "min",
            BinOp::Max => "max",
            BinOp::Hypot => "hypot",
        }
    }

    /// Whether swapping the operands gives bit-identical results (used to canonicalise before
    /// hash-consing). `min`/`max` are not: on ties they pick the first operand, which decides
    /// which gradient is taken.
    pub(super) fn commutes(self) -> bool {
        matches!(self, BinOp::Add | BinOp::Mul)
    }
}

/// Lane functions that are not plain `f64` methods. Both paths, and constant folding, use
/// exactly these.
pub(crate) mod lane {
    #[inline(always)]
    pub(crate) fn neg(a: f64) -> f64 {
        -a
    }
    /// `1` for positive, `−1` for negative, the argument itself for `±0` and NaN.
    #[inline(always)]
    pub(crate) fn sign(a: f64) -> f64 {
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
    pub(crate) fn add(a: f64, b: f64) -> f64 {
        a + b
    }
    #[inline(always)]
    pub(crate) fn sub(a: f64, b: f64) -> f64 {
        a - b
    }
    #[inline(always)]
    pub(crate) fn mul(a: f64, b: f64) -> f64 {
        a * b
    }
    #[inline(always)]
    pub(crate) fn div(a: f64, b: f64) -> f64 {
        a / b
    }
    /// Whether `min(a, b)` takes `a`: on ties and when `b` is NaN.
    #[inline(always)]
    pub(crate) fn min_takes_a(a: f64, b: f64) -> bool {
        a <= b || b.is_nan()
    }
    #[inline(always)]
    pub(crate) fn max_takes_a(a: f64, b: f64) -> bool {
        a >= b || b.is_nan()
    }
    #[inline(always)]
    pub(crate) fn min(a: f64, b: f64) -> f64 {
        if min_takes_a(a, b) { a } else { b }
    }
    #[inline(always)]
    pub(crate) fn max(a: f64, b: f64) -> f64 {
        if max_takes_a(a, b) { a } else { b }
    }
    /// The weight of `a` in the smooth minimum, `0.5 + 0.5 (b − a) / k`, and whether the
    /// point is in the blend zone `0 < h < 1` (which needs `k > 0`).
    #[inline(always)]
    pub(crate) fn smin_blend(a: f64, b: f64, k: f64) -> (f64, bool) {
        let h = 0.5 + 0.5 * (b - a) / k;
        (h, k > 0.0 && h > 0.0 && h < 1.0)
    }
    /// Polynomial smooth minimum. Outside the blend zone (and when `k` is not positive or
    /// NaN, or an operand is NaN) it is exactly `min(a, b)`: no division by zero is used, and
    /// an infinite operand does not turn the result into NaN.
    #[inline(always)]
    pub(crate) fn smin(a: f64, b: f64, k: f64) -> f64 {
        let (h, blend) = smin_blend(a, b, k);
        if blend { b * (1.0 - h) + a * h - k * h * (1.0 - h) } else { min(a, b) }
    }
}

/// Binds `$f` to the lane function of a unary op and evaluates `$body`.
macro_rules! with_unary {
    ($op:expr, $f:ident => $body:expr) => {
        match $op {
            $crate::formula::ops::UnOp::Neg => {
                let $f = $crate::formula::ops::lane::neg;
                $body
            }
            $crate::formula::ops::UnOp::Abs => {
                let $f = f64::abs;
                $body
            }
            $crate::formula::ops::UnOp::Sqrt => {
                let $f = f64::sqrt;
                $body
            }
            $crate::formula::ops::UnOp::Exp => {
                let $f = f64::exp;
                $body
            }
            $crate::formula::ops::UnOp::Ln => {
                let $f = f64::ln;
                $body
            }
            $crate::formula::ops::UnOp::Sin => {
                let $f = $crate::formula::ops::lane::sin;
                $body
            }
            $crate::formula::ops::UnOp::Cos => {
                let $f = $crate::formula::ops::lane::cos;
                $body
            }
            $crate::formula::ops::UnOp::Tan => {
                let $f = f64::tan;
                $body
            }
            $crate::formula::ops::UnOp::Asin => {
                let $f = f64::asin;
                $body
            }
            $crate::formula::ops::UnOp::Acos => {
                let $f = f64::acos;
                $body
            }
            $crate::formula::ops::UnOp::Atan => {
                let $f = f64::atan;
                $body
            }
            $crate::formula::ops::UnOp::Floor => {
                let $f = f64::floor;
                $body
            }
            $crate::formula::ops::UnOp::Sign => {
                let $f = $crate::formula::ops::lane::sign;
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
            $crate::formula::ops::UnOp::Neg => {
                let $g = |a: f64| ($crate::formula::ops::lane::neg(a), -1.0);
                $body
            }
            $crate::formula::ops::UnOp::Abs => {
                // abs'(0) = 0.
                let $g = |a: f64| (f64::abs(a), $crate::formula::ops::lane::sign(a));
                $body
            }
            $crate::formula::ops::UnOp::Sqrt => {
                // sqrt'(0) = +inf; a zero tangent still gives a zero derivative (see `tm`).
                let $g = |a: f64| {
                    let v = f64::sqrt(a);
                    (v, 0.5 / v)
                };
                $body
            }
            $crate::formula::ops::UnOp::Exp => {
                let $g = |a: f64| {
                    let v = f64::exp(a);
                    (v, v)
                };
                $body
            }
            $crate::formula::ops::UnOp::Ln => {
                let $g = |a: f64| (f64::ln(a), 1.0 / a);
                $body
            }
            $crate::formula::ops::UnOp::Sin => {
                let $g = |a: f64| {
                    ($crate::formula::ops::lane::sin(a), $crate::formula::ops::lane::cos(a))
                };
                $body
            }
            $crate::formula::ops::UnOp::Cos => {
                let $g = |a: f64| {
                    ($crate::formula::ops::lane::cos(a), -$crate::formula::ops::lane::sin(a))
                };
                $body
            }
            $crate::formula::ops::UnOp::Tan => {
                let $g = |a: f64| {
                    let v = f64::tan(a);
                    (v, 1.0 + v * v)
                };
                $body
            }
            $crate::formula::ops::UnOp::Asin => {
                let $g = |a: f64| (f64::asin(a), 1.0 / (1.0 - a * a).sqrt());
                $body
            }
            $crate::formula::ops::UnOp::Acos => {
                let $g = |a: f64| (f64::acos(a), -1.0 / (1.0 - a * a).sqrt());
                $body
            }
            $crate::formula::ops::UnOp::Atan => {
                let $g = |a: f64| (f64::atan(a), 1.0 / (1.0 + a * a));
                $body
            }
            $crate::formula::ops::UnOp::Floor => {
                let $g = |a: f64| (f64::floor(a), 0.0);
                $body
            }
            $crate::formula::ops::UnOp::Sign => {
                let $g = |a: f64| ($crate::formula::ops::lane::sign(a), 0.0);
                $body
            }
        }
    };
}

/// Binds `$f` to the lane function of a binary op and evaluates `$body`.
macro_rules! with_binary {
    ($op:expr, $f:ident => $body:expr) => {
        match $op {
            $crate::formula::ops::BinOp::Add => {
                let $f = $crate::formula::ops::lane::add;
                $body
            }
            $crate::formula::ops::BinOp::Sub => {
                let $f = $crate::formula::ops::lane::sub;
                $body
            }
            $crate::formula::ops::BinOp::Mul => {
                let $f = $crate::formula::ops::lane::mul;
                $body
            }
            $crate::formula::ops::BinOp::Div => {
                let $f = $crate::formula::ops::lane::div;
                $body
            }
            $crate::formula::ops::BinOp::Pow => {
                let $f = f64::powf;
                $body
            }
            $crate::formula::ops::BinOp::Atan2 => {
                let $f = f64::atan2;
                $body
            }
            $crate::formula::ops::BinOp::Min => {
                let $f = $crate::formula::ops::lane::min;
                $body
            }
            $crate::formula::ops::BinOp::Max => {
                let $f = $crate::formula::ops::lane::max;
                $body
            }
            $crate::formula::ops::BinOp::Hypot => {
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
            $crate::formula::ops::BinOp::Add => {
                let $g = |a: f64, b: f64| ($crate::formula::ops::lane::add(a, b), 1.0, 1.0);
                $body
            }
            $crate::formula::ops::BinOp::Sub => {
                let $g = |a: f64, b: f64| ($crate::formula::ops::lane::sub(a, b), 1.0, -1.0);
                $body
            }
            $crate::formula::ops::BinOp::Mul => {
                let $g = |a: f64, b: f64| ($crate::formula::ops::lane::mul(a, b), b, a);
                $body
            }
            $crate::formula::ops::BinOp::Div => {
                let $g = |a: f64, b: f64| {
                    let q = $crate::formula::ops::lane::div(a, b);
                    (q, 1.0 / b, -q / b)
                };
                $body
            }
            $crate::formula::ops::BinOp::Pow => {
                let $g = |a: f64, b: f64| {
                    let v = f64::powf(a, b);
                    (v, b * a.powf(b - 1.0), v * a.ln())
                };
                $body
            }
            $crate::formula::ops::BinOp::Atan2 => {
                // atan2(a, b) is the angle of (b, a); its derivatives are taken as 0 at the origin.
                let $g = |a: f64, b: f64| {
                    let v = f64::atan2(a, b);
                    let r2 = a * a + b * b;
                    if r2 == 0.0 { (v, 0.0, 0.0) } else { (v, b / r2, -a / r2) }
                };
                $body
            }
            $crate::formula::ops::BinOp::Min => {
                let $g = |a: f64, b: f64| {
                    let s = if $crate::formula::ops::lane::min_takes_a(a, b) { 1.0 } else { 0.0 };
                    ($crate::formula::ops::lane::min(a, b), s, 1.0 - s)
                };
                $body
            }
            $crate::formula::ops::BinOp::Max => {
                let $g = |a: f64, b: f64| {
                    let s = if $crate::formula::ops::lane::max_takes_a(a, b) { 1.0 } else { 0.0 };
                    ($crate::formula::ops::lane::max(a, b), s, 1.0 - s)
                };
                $body
            }
            $crate::formula::ops::BinOp::Hypot => {
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

// Re-exported as items, so that the interpreters can name them by path.
pub(crate) use {with_binary, with_binary_ad, with_unary, with_unary_ad};

/// `(value, ∂/∂a, ∂/∂b, ∂/∂k)` of the smooth minimum. In the blend zone the `∂h` terms
/// cancel (the polynomial smooth minimum is C¹), leaving `h`, `1 − h` and `−h(1 − h)`;
/// outside it, those of the operand `min` selects.
#[inline(always)]
pub(crate) fn smin_ad(a: f64, b: f64, k: f64) -> (f64, f64, f64, f64) {
    let v = lane::smin(a, b, k);
    let (h, blend) = lane::smin_blend(a, b, k);
    if blend {
        (v, h, 1.0 - h, -h * (1.0 - h))
    } else {
        let s = if lane::min_takes_a(a, b) { 1.0 } else { 0.0 };
        (v, s, 1.0 - s, 0.0)
    }
}

/// The value of a one-operand operation on one number (constant folding, single points).
pub(crate) fn eval_un(op: UnOp, a: f64) -> f64 {
    with_unary!(op, f => f(a))
}

/// The value of a two-operand operation on one number.
pub(crate) fn eval_bin(op: BinOp, a: f64, b: f64) -> f64 {
    with_binary!(op, f => f(a, b))
}

/// The smooth minimum on one number.
pub(crate) fn eval_smin(a: f64, b: f64, k: f64) -> f64 {
    lane::smin(a, b, k)
}
