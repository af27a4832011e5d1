//! Two fields made one by a sharp Boolean: [`Combined`].
//!
//! Scenes use it to join a skeleton with a formula (`combine = "union"` in `[skeleton]`),
//! but it works on any two fields. The operations are the exact `min`/`max` of CSG, not
//! blends: where the surfaces meet there is a crease. For a smooth join, write the formula
//! with `smooth_union` and friends instead.
//!
//! ```
//! use std::sync::Arc;
//! use skelform_field::combine::{Combine, Combined};
//! use skelform_field::{DVec3, Field, FnField};
//!
//! let ball = Arc::new(FnField(|p: DVec3| p.length() - 1.0));
//! let half = Arc::new(FnField(|p: DVec3| p.z)); // inside below z = 0
//! let cup = Combined::new(ball, half, Combine::Difference); // the ball above z = 0
//! assert!(cup.eval(DVec3::new(0.0, 0.0, 0.5)) < 0.0);
//! assert!(cup.eval(DVec3::new(0.0, 0.0, -0.5)) > 0.0);
//! ```

use std::ops::Range;
use std::sync::Arc;

use glam::DVec3;

use crate::{Aabb, Field, LayerSampler};

/// How [`Combined`] joins its two fields (both inside-negative).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Combine {
    /// Inside either: `min(first, second)`.
    Union,
    /// Inside both: `max(first, second)`.
    Intersection,
    /// Inside the first and outside the second: `max(first, −second)`.
    Difference,
}

impl Combine {
    /// The combined value of `a` (the first field's) and `b` (the second's), and whether it
    /// came from `a`. Ties, and a NaN in `b`, go to `a`, so the value and the gradient
    /// [`Combined`] reports are always taken from the same field.
    #[inline]
    pub fn pick(self, a: f64, b: f64) -> (f64, bool) {
        match self {
            Combine::Union => {
                if b < a {
                    (b, false)
                } else {
                    (a, true)
                }
            }
            Combine::Intersection => {
                if b > a {
                    (b, false)
                } else {
                    (a, true)
                }
            }
            Combine::Difference => {
                if -b > a {
                    (-b, false)
                } else {
                    (a, true)
                }
            }
        }
    }

    /// Both operands' values (`eval(true, out)` gives the first's), combined into `out`.
    fn pick_all(self, out: &mut [f64], eval: impl Fn(bool, &mut [f64])) {
        let mut other = vec![0.0; out.len()];
        eval(true, out);
        eval(false, &mut other);
        for (o, b) in out.iter_mut().zip(other) {
            *o = self.pick(*o, b).0;
        }
    }
}

/// Two fields joined by a [`Combine`]: a [`Field`] whose value is, at every point, one of
/// the two values (negated, for the second field of a difference), and whose gradient is
/// that same field's (negated likewise). So the gradient is exact wherever both fields'
/// are, and the batch and lattice paths are the fields' own (each field is sampled through
/// its own fast path, then the values are combined), with the same values as
/// [`Field::eval`].
pub struct Combined {
    /// The field on the left of the operation (for a difference, what is kept).
    pub first: Arc<dyn Field>,
    /// The field on the right (for a difference, what is cut away).
    pub second: Arc<dyn Field>,
    /// How they are joined.
    pub op: Combine,
}

impl Combined {
    /// `first` and `second` joined by `op`.
    pub fn new(first: Arc<dyn Field>, second: Arc<dyn Field>, op: Combine) -> Self {
        Self { first, second, op }
    }

    /// `eval(field, out)` of both fields, combined into `out`.
    fn pick_all(&self, out: &mut [f64], eval: impl Fn(&dyn Field, &mut [f64])) {
        self.op.pick_all(out, |first, out| {
            eval(if first { &*self.first } else { &*self.second }, out)
        });
    }
}

impl std::fmt::Debug for Combined {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Combined").field("op", &self.op).finish_non_exhaustive()
    }
}

/// [`Combined`]'s sampler: both fields' samplers, combined layer by layer.
struct CombinedSampler<'a> {
    first: Box<dyn LayerSampler + 'a>,
    second: Box<dyn LayerSampler + 'a>,
    op: Combine,
}

impl LayerSampler for CombinedSampler<'_> {
    fn layer(&self, z: f64, rows: Range<usize>, out: &mut [f64]) {
        self.op.pick_all(out, |first, out| {
            let s = if first { &self.first } else { &self.second };
            s.layer(z, rows.clone(), out)
        });
    }
}

impl Field for Combined {
    fn eval(&self, p: DVec3) -> f64 {
        self.op.pick(self.first.eval(p), self.second.eval(p)).0
    }

    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        self.pick_all(out, |f, out| f.eval_many(points, out));
    }

    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        self.pick_all(out, |f, out| f.eval_layer(xs, ys, z, out));
    }

    fn sampler<'a>(&'a self, xs: &[f64], ys: &[f64]) -> Box<dyn LayerSampler + 'a> {
        Box::new(CombinedSampler {
            first: self.first.sampler(xs, ys),
            second: self.second.sampler(xs, ys),
            op: self.op,
        })
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let (a, b) = (self.first.eval(p), self.second.eval(p));
        match self.op.pick(a, b) {
            (_, true) => self.first.gradient(p),
            (_, false) if self.op == Combine::Difference => -self.second.gradient(p),
            _ => self.second.gradient(p),
        }
    }

    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        let n = points.len();
        let (mut bv, mut bg) = (vec![0.0; n], vec![DVec3::ZERO; n]);
        self.first.eval_grad_many(points, values, grads);
        self.second.eval_grad_many(points, &mut bv, &mut bg);
        for i in 0..n {
            let (v, from_first) = self.op.pick(values[i], bv[i]);
            values[i] = v;
            if !from_first {
                grads[i] = if self.op == Combine::Difference { -bg[i] } else { bg[i] };
            }
        }
    }

    /// The finer of the two fields' steps.
    fn gradient_step(&self) -> f64 {
        self.first.gradient_step().min(self.second.gradient_step())
    }

    fn has_exact_gradient(&self) -> bool {
        self.first.has_exact_gradient() && self.second.has_exact_gradient()
    }

    /// The first field's bounds for an intersection or a difference (the result lies inside
    /// the first field); none for a union.
    fn bounds(&self) -> Option<Aabb> {
        match self.op {
            Combine::Union => None,
            Combine::Intersection | Combine::Difference => self.first.bounds(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FnField;

    fn pair(op: Combine) -> Combined {
        let ball = Arc::new(FnField(|p: DVec3| p.length() - 1.0));
        let plane = Arc::new(FnField(|p: DVec3| p.z));
        Combined::new(ball, plane, op)
    }

    #[test]
    fn values_come_from_one_field_and_ties_from_the_first() {
        assert_eq!(Combine::Union.pick(1.0, -2.0), (-2.0, false));
        assert_eq!(Combine::Intersection.pick(1.0, -2.0), (1.0, true));
        assert_eq!(Combine::Difference.pick(1.0, -2.0), (2.0, false));
        for op in [Combine::Union, Combine::Intersection] {
            assert_eq!(op.pick(0.5, 0.5), (0.5, true));
            assert_eq!(op.pick(0.5, f64::NAN), (0.5, true));
        }
    }

    #[test]
    fn batches_and_layers_match_points() {
        let (xs, ys) = ([-0.5, 0.0, 0.75], [-1.0, 0.25]);
        let points: Vec<DVec3> =
            ys.iter().flat_map(|&y| xs.iter().map(move |&x| DVec3::new(x, y, 0.3))).collect();
        for op in [Combine::Union, Combine::Intersection, Combine::Difference] {
            let f = pair(op);
            let want: Vec<f64> = points.iter().map(|&p| f.eval(p)).collect();
            let mut got = vec![0.0; points.len()];
            f.eval_many(&points, &mut got);
            assert_eq!(got, want);
            f.eval_layer(&xs, &ys, 0.3, &mut got);
            assert_eq!(got, want);
            f.sampler(&xs, &ys).layer(0.3, 0..2, &mut got);
            assert_eq!(got, want);
            let mut grads = vec![DVec3::ZERO; points.len()];
            f.eval_grad_many(&points, &mut got, &mut grads);
            assert_eq!(got, want);
            for (p, g) in points.iter().zip(&grads) {
                assert_eq!(*g, f.gradient(*p));
            }
        }
    }

    #[test]
    fn a_difference_turns_the_second_gradient_around() {
        let f = pair(Combine::Difference);
        // Below the plane, far from the ball's surface: the plane's side, negated.
        let p = DVec3::new(0.0, 0.0, -0.9);
        assert!((f.gradient(p) + DVec3::Z).length() < 1e-6);
    }
}
