//! The formula language in which scene files state fields.
//!
//! A [`Formula`] is parsed and compiled once into a flat register tape, then evaluated many
//! points at a time: each instruction runs as one tight loop over a batch of points, with no
//! tree walking and no allocation per point. Gradients are exact, by forward-mode automatic
//! differentiation over the same tape.
//!
//! ```
//! use skelform_field::{Field, formula::Formula};
//! use glam::DVec3;
//!
//! let torus = Formula::parse("
//!     R = 1; r = 0.25          # radii
//!     q = sqrt(x^2 + y^2) - R  # distance to the core circle, in the plane
//!     sqrt(q^2 + z^2) - r
//! ").unwrap();
//! assert!((torus.eval(DVec3::new(1.0, 0.0, 0.0)) + 0.25).abs() < 1e-12);
//! let g = torus.gradient(DVec3::new(1.25, 0.0, 0.0));
//! assert!((g - DVec3::X).length() < 1e-12);
//!
//! let err = Formula::parse("r = sqrt(x^2 + y^2)\nrr - 1").unwrap_err();
//! assert_eq!((err.line(), err.column()), (2, 1));
//! assert_eq!(err.message(), "unknown name 'rr' (did you mean 'r'?)");
//! ```
//!
//! # The language
//!
//! A formula is a sequence of **statements** separated by new lines or `;`. Every statement
//! but the last is a **definition** `name = expression`; the last is the field's expression.
//! A definition may use the ones before it and is computed once per point however often it
//! is used. Defining a name twice is an error; a definition that is never used is fine.
//!
//! - **Comments** run from `#` to the end of the line. Blank lines are allowed.
//! - **Line continuation**: new lines inside parentheses do not end a statement, nor does a
//!   new line right after a binary operator (`+ - * / ^`), a unary sign or `=`.
//! - **Numbers**: `1`, `0.5`, `.5`, `3.`, `1e-3`, `2.5E+2`. There is no implicit
//!   multiplication: write `2*x`, not `2x`.
//! - **Variables** `x`, `y`, `z`; **constants** `pi` and `e` (Euler's number). These and the
//!   function names below are reserved: defining them is an error.
//! - **Operators**, loosest first: `+ -` (left-associative), `* /` (left-associative), unary
//!   `-` and `+`, `^` (power, right-associative). `^` binds tighter than unary minus, and its
//!   exponent may carry a sign: `-x^2` is `-(x^2)`, `2^3^2` is `2^9 = 512`, `2^-1` is `0.5`,
//!   `8/2/2` is `2`.
//! - **Functions**:
//!
//!   | function | meaning |
//!   |---|---|
//!   | `abs sqrt exp sin cos tan asin acos atan floor` | as usual (radians) |
//!   | `ln(u)`, alias `log(u)` | natural logarithm |
//!   | `sign(u)` | `1`, `-1`, or `u` itself for `0` (and NaN) |
//!   | `atan2(y, x)` | angle of the point `(x, y)`, in `(-pi, pi]` |
//!   | `pow(a, b)` | `a^b` |
//!   | `hypot(a, b)` | `sqrt(a^2 + b^2)` without overflow |
//!   | `min(a, b, ...)`, `max(a, b, ...)` | two or more arguments |
//!   | `clamp(v, lo, hi)` | `min(max(v, lo), hi)` |
//!   | `mix(a, b, t)`, alias `lerp` | `a + (b - a)*t` |
//!   | `union(a, b, ...)` | `min`: inside either (inside is negative) |
//!   | `intersection(a, b, ...)` | `max`: inside both |
//!   | `difference(a, b)` | `max(a, -b)`: inside `a`, outside `b` |
//!   | `smooth_union(a, b, k)`, alias `smin` | polynomial smooth minimum with blend radius `k` |
//!   | `smooth_intersection(a, b, k)`, alias `smax` | `-smooth_union(-a, -b, k)` |
//!   | `smooth_difference(a, b, k)` | `smooth_intersection(a, -b, k)` |
//!
//!   The smooth union is `h = clamp(0.5 + 0.5*(b - a)/k, 0, 1)`,
//!   `b*(1 - h) + a*h - k*h*(1 - h)`. Outside the blend zone `0 < h < 1` it is computed as
//!   exactly `min(a, b)` (so an infinite operand gives the other one, not NaN). When `k ≤ 0`
//!   (or NaN) it is the sharp `min(a, b)`: decided once when `k` is a constant, per point
//!   otherwise, so a zero `k` never causes a division by zero.
//!
//! Arithmetic is IEEE `f64`: `ln` of a negative number is NaN, `1/0` is infinite, and such
//! values simply propagate (nothing panics). `min` and `max` ignore a NaN operand (they return
//! the other), and pick the first operand on ties.
//!
//! How some things are computed (this fixes the exact bits, so results can be reproduced):
//! constant subexpressions are folded once at parse time with the same arithmetic; `u^n` for
//! a constant integer `n` with `|n| ≤ 64` is repeated multiplication (binary
//! exponentiation), `u^-n` is `1/u^n`, `u^0` is `1`, `u^0.5` is `sqrt(u)`, and other powers
//! use `powf`. `clamp`, `mix`, `difference` and the smooth operations expand to the
//! formulas above. `sin` and `cos` use skelform's own branch-free kernels (so batches
//! vectorise), within two ulps of the correctly rounded value for `|u| ≤ 823549`, and the
//! platform's `sin`/`cos` beyond; the other functions are the Rust standard library's.
//!
//! # Gradients
//!
//! [`Field::gradient`] and [`Field::eval_grad_many`] are exact (forward-mode automatic
//! differentiation: each register carries a value and its three partial derivatives). At
//! points where an operation is not differentiable the following are used: `abs'(0) = 0`;
//! `min`/`max` (and `union`, ...) take the derivative of the operand they select;
//! `floor' = sign' = 0`; `sqrt'(0) = +∞` and `ln'(0) = ±∞`; `atan2` and `hypot` have zero
//! derivatives at the origin. A chain-rule term whose either factor is zero counts as zero,
//! so `sqrt(x^2 + y^2 + z^2)` has gradient `0` (not NaN) at the origin, and an infinite
//! derivative on the side of a `min` that is not selected does not leak into the result.

mod compile;
mod eval;
mod lexer;
mod ops;
mod parser;
#[cfg(test)]
mod tests;
mod trig;

use std::fmt;

use glam::DVec3;
use thiserror::Error;

use crate::{Field, LayerSampler};

pub use compile::Tape;

/// Why a formula could not be parsed: where (1-based line and column, in characters, within
/// the formula text) and what was expected.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("line {line}, column {column}: {message}")]
pub struct FormulaError {
    line: usize,
    column: usize,
    message: String,
    /// A second position the message cites ("opened at line 2, column 5").
    related: Option<(usize, usize)>,
}

fn position_text(line: usize, column: usize) -> String {
    format!("line {line}, column {column}")
}

impl FormulaError {
    pub(crate) fn new(line: usize, column: usize, message: impl Into<String>) -> Self {
        Self { line, column, message: message.into(), related: None }
    }

    /// Marks the position the message cites, so that [`FormulaError::message_mapped`] can
    /// translate it. The mark is kept only where the message cites it as `line L, column C`:
    /// an error that replaced the intended message (the lexer's, say) cites nothing.
    pub(crate) fn with_related(mut self, line: usize, column: usize) -> Self {
        if self.message.contains(&position_text(line, column)) {
            self.related = Some((line, column));
        }
        self
    }

    /// The second position the message cites, if any.
    pub fn related(&self) -> Option<(usize, usize)> {
        self.related
    }

    /// The message with the position it cites translated by `map` (from formula line and
    /// column to, say, line and column in the scene file that holds the formula).
    pub fn message_mapped(&self, map: impl Fn(usize, usize) -> (usize, usize)) -> String {
        match self.related {
            Some((l, c)) => {
                let (ml, mc) = map(l, c);
                self.message.replacen(&position_text(l, c), &position_text(ml, mc), 1)
            }
            None => self.message.clone(),
        }
    }

    /// 1-based line within the formula text.
    pub fn line(&self) -> usize {
        self.line
    }

    /// 1-based column within the line, counted in characters.
    pub fn column(&self) -> usize {
        self.column
    }

    /// What went wrong, without the position.
    pub fn message(&self) -> &str {
        &self.message
    }
}

/// A parsed and compiled formula; a [`Field`].
#[derive(Clone, Debug)]
pub struct Formula {
    source: String,
    tape: Tape,
    /// The same formula split for sampling lattice layers.
    lattice: compile::Lattice,
    /// And for sampling many layers of one lattice, when it has terms of `x` and `y` alone.
    planar: Option<compile::Planar>,
}

/// The most bytes of plane values ([`Field::sampler`]) a formula's sampler keeps; past it,
/// the terms of `x` and `y` alone are computed on every layer.
const PLANE_CACHE_MAX: usize = 64 << 20;

impl Formula {
    /// Parses and compiles a formula (see the [module documentation](self) for the language).
    pub fn parse(text: &str) -> Result<Formula, FormulaError> {
        Self::parse_with_constants(text, &[])
    }

    /// Like [`Formula::parse`], with named numeric parameters the formula may use like
    /// definitions (and may not redefine). A parameter whose name is not an identifier, is
    /// reserved (`x`, `pi`, `sin`, ...) or is given twice is an error reported at line 1,
    /// column 1.
    ///
    /// ```
    /// use skelform_field::{Field, formula::Formula, DVec3};
    /// let f = Formula::parse_with_constants("sqrt(x^2 + y^2 + z^2) - radius", &[("radius", 2.0)]).unwrap();
    /// assert_eq!(f.eval(DVec3::new(0.0, 3.0, 0.0)), 1.0);
    /// ```
    pub fn parse_with_constants(
        text: &str,
        constants: &[(&str, f64)],
    ) -> Result<Formula, FormulaError> {
        let (builder, root) = parser::parse(text, constants)?;
        let tape = compile::compile(builder.nodes(), root);
        let lattice = compile::lattice(builder.nodes(), root);
        let planar = compile::planar(builder.nodes(), root);
        Ok(Formula { source: text.to_string(), tape, lattice, planar })
    }

    /// The text the formula was parsed from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The compiled tape; its `Display` is a listing (for `skelform info`).
    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    /// Instructions run per point.
    pub fn instruction_count(&self) -> usize {
        self.tape.instruction_count()
    }

    /// Registers the tape uses (inputs, constants and temporaries).
    pub fn register_count(&self) -> usize {
        self.tape.register_count()
    }
}

impl fmt::Display for Formula {
    /// The source text.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.source)
    }
}

impl std::str::FromStr for Formula {
    type Err = FormulaError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Formula::parse(s)
    }
}

impl Field for Formula {
    fn eval(&self, p: DVec3) -> f64 {
        eval::eval_point(&self.tape, p)
    }

    /// In batches of 128 points; bit-identical to [`Formula::eval`] at every point.
    /// If the slices differ in length, only the common prefix is evaluated.
    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        debug_assert_eq!(points.len(), out.len());
        eval::eval_batch(&self.tape, points, out)
    }

    /// Terms that depend on fewer than all of the layer's axes are computed once per layer,
    /// row or column; bit-identical to [`Formula::eval`] at every point.
    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        debug_assert_eq!(xs.len() * ys.len(), out.len());
        eval::eval_layer(&self.lattice, xs, ys, z, out)
    }

    /// Computes the terms of `x` and `y` alone once, at every point of the plane (unless
    /// that would take more than 64 MiB); bit-identical to [`Formula::eval`] at every point.
    fn sampler<'a>(&'a self, xs: &[f64], ys: &[f64]) -> Box<dyn LayerSampler + 'a> {
        let (xs, ys) = (xs.to_vec(), ys.to_vec());
        let plane_bytes = |p: &compile::Planar| p.planes.len() * xs.len() * ys.len() * 8;
        Box::new(match &self.planar {
            Some(planar) if plane_bytes(planar) <= PLANE_CACHE_MAX => {
                eval::Sampler::with_planes(planar, xs, ys)
            }
            _ => eval::Sampler::without_planes(&self.lattice, xs, ys),
        })
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        eval::grad_point(&self.tape, p).1
    }

    /// Values (bit-identical to [`Formula::eval`]) and exact gradients.
    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        debug_assert_eq!(points.len(), values.len());
        debug_assert_eq!(points.len(), grads.len());
        eval::grad_batch(&self.tape, points, values, grads)
    }

    fn has_exact_gradient(&self) -> bool {
        true
    }
}
