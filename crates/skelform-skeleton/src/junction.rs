//! The joint combination surface (DIS §5.6.14.5, eq. 5.37, appendix A.2): convolution
//! where a point is in the plane of a joint, the union of the limbs where it is out of it.
//!
//! Segments meeting at a joint bulge under convolution: above a tee's junction the
//! densities add to ¾ instead of ½ (§5.6.14). Neither tapering nor point sources cure it
//! (§5.6.14.3–4). The dissertation's answer blends, per joint,
//!
//! `D = conv + Convexity·(union − conv)`
//!
//! where `conv` is the sum of the limbs' convolutions (the segments meeting at the joint and
//! the chains continuing from them), `union = maxᵢ wᵢ·k(d(p, Uᵢ)/rᵢ)` is
//! the union of the limbs' distance surfaces with the limbs' *free* ends pulled inward by
//! their radius (`eUnion`: the union's caps then end where the convolution's do), and
//!
//! `Convexity = 1 − Ease(acos(|n·∇conv/|∇conv||) / (π/2))`,
//! `Ease(x) = (4x⁶ − 17x⁴ + 22x²)/9` clamped to `[0, 1]`,
//!
//! with `n` the joint's direction of convexity (by default the normal of the plane of the
//! joint and its limbs' far ends). A junction may hold several joints (the branch points of
//! one tree), each with its direction; the Convexity is then the joints' Convexities
//! averaged with weights `1/(|p − jointⱼ|² + r²)²`. The appendix instead interpolates each
//! limb's end normals along the limb nearest `p`; that switches direction abruptly where
//! the nearest limb changes, a visible seam, which the smooth weights avoid. Where the gradient of the convolution lies in the plane
//! (`n·∇ = 0`, beside the limbs and in the webbing between them) `Ease = 1`, Convexity 0:
//! pure convolution, smooth webbing. Where it is along `n` (above and below the joint) the
//! union takes over and the bulge goes. Far along a limb both surfaces are cylinders of the
//! limb's radius, so the mix keeps the radius whatever the Convexity.
//!
//! Where two limbs' union terms are equal the union has a crease, and out of the plane so
//! does `D` (the dissertation saw it in the starfish's webbing and hid it in shading with
//! blended normals). By default the field keeps its own gradient, crease and all;
//! [`SkeletonField::with_blended_normals`](crate::SkeletonField::with_blended_normals)
//! turns the junction's gradient towards the appendix's blended normal instead
//! (`PreparedJunction::blended_normal`), which is smooth across the crease.
//!
//! The gradient of `D` involves the Hessian of the convolution (through `Convexity`), so it
//! is taken by central differences of `D` with a step of 10⁻⁴ of the smallest limb radius,
//! as the appendix does (`Gradient(p, ConvolveValue, delta)`); the rest of the field keeps
//! its analytic gradient.

use std::f64::consts::FRAC_PI_2;

use glam::DVec3;

use crate::SkeletonError;
use crate::geometry::Shape;
use crate::kernel::Kernel;
use crate::skeleton::{Junction, Skeleton};

/// `Ease(x) = (4x⁶ − 17x⁴ + 22x²)/9` clamped to `[0, 1]` (appendix A.2): 0 at 0, 1 at 1, flat
/// at both ends.
pub fn ease(x: f64) -> f64 {
    let x2 = x * x;
    ((x2 * (22.0 + x2 * (-17.0 + 4.0 * x2))) / 9.0).clamp(0.0, 1.0)
}

/// `1 − Ease(acos(|n·ĝ|)/(π/2))`: 1 where the convolution's gradient is along the joint's
/// direction, 0 where it is in the joint's plane; 0 where the gradient vanishes.
pub fn convexity(direction: DVec3, gradient: DVec3) -> f64 {
    let len = gradient.length();
    if len == 0.0 || !len.is_finite() {
        return 0.0;
    }
    let c = (direction.dot(gradient) / len).abs().min(1.0);
    1.0 - ease(c.acos() / FRAC_PI_2)
}

/// One limb, as the junction needs it.
#[derive(Clone, Debug)]
pub(crate) struct Limb {
    /// The element's index (its convolution is evaluated by the field).
    pub element: usize,
    /// The union segment: the limb with its free ends pulled inward by their radius.
    ua: DVec3,
    ub: DVec3,
}

/// A junction ready for evaluation.
#[derive(Clone, Debug)]
pub(crate) struct PreparedJunction {
    pub limbs: Vec<Limb>,
    /// Each joint's position and direction of convexity.
    joints: Vec<(DVec3, DVec3)>,
    /// Squared softening length of the joints' weights (the smallest limb radius).
    soft2: f64,
    pub lo: DVec3,
    pub hi: DVec3,
    /// Central-difference step.
    pub step: f64,
}

impl PreparedJunction {
    /// `boxes[i]` is element `i`'s box.
    pub(crate) fn new(
        junction: &Junction,
        skeleton: &Skeleton,
        boxes: &[(DVec3, DVec3)],
    ) -> Result<PreparedJunction, SkeletonError> {
        // Where each joint is now (its direct limbs may have moved) and its direction.
        let joints: Vec<(DVec3, DVec3)> = (0..junction.joints.len())
            .map(|j| {
                let joint = &junction.joints[j];
                let at = joint
                    .direct
                    .first()
                    .and_then(|&(i, at_a)| match &skeleton.elements()[i].shape {
                        Shape::Segment(s) => Some(if at_a { s.a() } else { s.b() }),
                        _ => None,
                    })
                    .unwrap_or(joint.at);
                (at, skeleton.junction_direction(junction, j))
            })
            .collect();
        let mut limbs = Vec::new();
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let mut min_r = f64::INFINITY;
        for (&i, &[free_a, free_b]) in junction.limbs.iter().zip(&junction.free_ends) {
            let e = &skeleton.elements()[i];
            let Shape::Segment(s) = &e.shape else { continue };
            let (ra, rb) = e.radii();
            min_r = min_r.min(ra).min(rb);
            // Pull free ends inward by their radius (appendix A.2's eUnion), never past
            // the middle when both ends are free.
            let (a, b) = (s.a(), s.b());
            let u = (b - a).normalize();
            let room = if free_a && free_b { 0.499 } else { 0.999 } * s.length();
            let ua = if free_a { a + u * ra.min(room) } else { a };
            let ub = if free_b { b - u * rb.min(room) } else { b };
            limbs.push(Limb { element: i, ua, ub });
            lo = lo.min(boxes[i].0);
            hi = hi.max(boxes[i].1);
        }
        Ok(PreparedJunction { limbs, joints, soft2: min_r * min_r, lo, hi, step: 1e-4 * min_r })
    }

    #[inline]
    pub(crate) fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// The combined density `D` at `p`, given each limb's convolution (value and gradient),
    /// radius and strength at `p` through `limb`. With several joints the Convexity is the
    /// joints' Convexities averaged with weights `1/(|p − jointⱼ|² + r²)²`: smooth in `p`,
    /// each joint's own near it.
    pub(crate) fn density(
        &self,
        kernel: Kernel,
        p: DVec3,
        mut limb: impl FnMut(usize, DVec3) -> (f64, DVec3, f64, f64),
    ) -> f64 {
        let mut conv = 0.0;
        let mut grad = DVec3::ZERO;
        let mut union: f64 = 0.0;
        for l in &self.limbs {
            let (v, g, r, w) = limb(l.element, p);
            conv += v;
            grad += g;
            let d2 = (p - nearest_on(l.ua, l.ub, p)).length_squared();
            union = union.max(w * kernel.value(d2 / (r * r)));
        }
        let c = self.convexity_at(p, grad);
        conv + c * (union - conv)
    }

    /// The Convexity at `p` given the convolution's gradient there: the joint's, or the
    /// joints' averaged with weights `1/(|p − jointⱼ|² + r²)²`.
    fn convexity_at(&self, p: DVec3, grad: DVec3) -> f64 {
        match self.joints.as_slice() {
            [(_, n)] => convexity(*n, grad),
            joints => {
                let (mut sum, mut weights) = (0.0, 0.0);
                for (at, n) in joints {
                    let w = 1.0 / ((p - *at).length_squared() + self.soft2).powi(2);
                    sum += w * convexity(*n, grad);
                    weights += w;
                }
                sum / weights
            }
        }
    }

    /// The appendix's vertex normal for the combination surface (DIS appendix A.2,
    /// `Normal`; §5.6.14.5): the outward unit normal `Unit((1 − c)·N_conv + c·N_union)`,
    /// with `c` the Convexity, `N_conv` the convolution's outward unit normal and `N_union`
    /// a smooth stand-in for the union's normal. The union's own normal jumps where the
    /// nearest limb changes, and "even a minor contribution from [it] can exaggerate the
    /// appearance of a crease", so each limb's normal `unit(p − nearest point of its union
    /// segment)` is weighted: with `wᵢ = 2·sᵢ·k(dᵢ/rᵢ)` (1 on the limb's union surface, more
    /// inside), by `wᵢ` among the limbs with `wᵢ > 0.9999` if `p` is on or inside some limb's
    /// union surface, else by `Πⱼ≠ᵢ Ease(1 − wⱼ)`, which fades a limb's normal out as `p`
    /// comes near another limb. `None` where the convolution has no gradient.
    pub(crate) fn blended_normal(
        &self,
        kernel: Kernel,
        p: DVec3,
        mut limb: impl FnMut(usize, DVec3) -> (f64, DVec3, f64, f64),
    ) -> Option<DVec3> {
        let mut grad = DVec3::ZERO;
        let mut normals = Vec::with_capacity(self.limbs.len());
        for l in &self.limbs {
            let (_, g, r, w) = limb(l.element, p);
            grad += g;
            let off = p - nearest_on(l.ua, l.ub, p);
            let d2 = off.length_squared();
            normals.push((off.normalize_or_zero(), 2.0 * w * kernel.value(d2 / (r * r))));
        }
        let conv_normal = (-grad).try_normalize()?;
        let mut union = DVec3::ZERO;
        if normals.iter().any(|(_, w)| *w > 0.9999) {
            for (n, w) in &normals {
                if *w > 0.9999 {
                    union += *n * *w;
                }
            }
        } else {
            for (i, (n, _)) in normals.iter().enumerate() {
                let scale: f64 = normals
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, (_, w))| ease(1.0 - w))
                    .product();
                union += *n * scale;
            }
        }
        let c = self.convexity_at(p, grad);
        let union = union.try_normalize().unwrap_or(conv_normal);
        (conv_normal * (1.0 - c) + union * c).try_normalize().or(Some(conv_normal))
    }
}

fn nearest_on(a: DVec3, b: DVec3, p: DVec3) -> DVec3 {
    let d = b - a;
    let t = ((p - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    a + t * d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ease_runs_from_zero_to_one_flat_at_both_ends() {
        assert_eq!(ease(0.0), 0.0);
        assert!((ease(1.0) - 1.0).abs() < 1e-15);
        assert_eq!(ease(2.0), 1.0);
        let h = 1e-6;
        assert!((ease(h) - ease(0.0)) / h < 1e-4);
        assert!((ease(1.0) - ease(1.0 - h)) / h < 1e-4);
        for i in 1..100 {
            let x = i as f64 / 100.0;
            assert!(ease(x) > ease(x - 0.01), "increasing at {x}");
        }
    }

    #[test]
    fn convexity_is_one_along_the_direction_and_zero_across_it() {
        let n = DVec3::Z;
        assert!((convexity(n, DVec3::new(0.0, 0.0, -3.0)) - 1.0).abs() < 1e-12);
        assert!(convexity(n, DVec3::new(1.0, 2.0, 0.0)).abs() < 1e-12);
        assert_eq!(convexity(n, DVec3::ZERO), 0.0);
        let mid = convexity(n, DVec3::new(1.0, 0.0, 1.0));
        assert!(mid > 0.0 && mid < 1.0);
    }
}
