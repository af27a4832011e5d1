//! Veins as convolution surfaces of line segments (dissertation §7.3).
//!
//! The sum of the vein primitives is the skeletal convolution of [`skelform_skeleton`]: a
//! density that is 1 on a long vein's axis and ½ at one radius from it. Veins taper: each
//! segment has its own radius (the mean of its ends'), decreasing from a vein's base to its
//! tip. The region rule also needs the radius of the nearest vein, found among the segments
//! whose reach contains the point.

use glam::DVec3;
use skelform_field::Field;
use skelform_skeleton::{Blend, GroupId, Kernel, Skeleton, SkeletonField};

use crate::LeafError;

/// One piece of vein.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VeinSegment {
    /// One end, in scene units: the one toward the vein's base when the segment comes from a
    /// base-first polyline ([`Veins::segments_of`]).
    pub a: DVec3,
    /// The other end; must differ from `a`.
    pub b: DVec3,
    /// The convolution radius, in scene units: a long lone segment's surface lies this far from
    /// it (where the density is ½), and it is the `r` of the region rule.
    pub radius: f64,
}

#[derive(Clone, Debug)]
struct Reach {
    a: DVec3,
    b: DVec3,
    radius: f64,
    lo: DVec3,
    hi: DVec3,
}

/// The vein primitives, summed.
#[derive(Clone, Debug)]
pub struct Veins {
    field: SkeletonField,
    reach: Vec<Reach>,
    /// The segments as given. Changing them does not rebuild the field: build new `Veins`.
    pub segments: Vec<VeinSegment>,
    /// The kernel the segments are convolved with; its support sets how far each vein reaches.
    pub kernel: Kernel,
}

impl Veins {
    /// Segments of polylines whose points carry radii (tapered veins).
    pub fn segments_of(points: &[DVec3], radii: &[f64]) -> Vec<VeinSegment> {
        points
            .windows(2)
            .zip(radii.windows(2))
            .filter(|(p, _)| p[0] != p[1])
            .map(|(p, r)| VeinSegment { a: p[0], b: p[1], radius: 0.5 * (r[0] + r[1]) })
            .collect()
    }

    /// The convolution surface of `segments` under `kernel` (all in one blend group, so veins
    /// blend where they branch). Errors if there are no segments, if a segment has zero
    /// length or a radius that is not positive, or if the kernel does not convolve segments
    /// (the sinc).
    pub fn new(segments: Vec<VeinSegment>, kernel: Kernel) -> Result<Veins, LeafError> {
        let mut s = Skeleton::new();
        for seg in &segments {
            s.add_segment(seg.a, seg.b, seg.radius, GroupId::DEFAULT)?;
        }
        let field = SkeletonField::new(&s, Blend::Convolution(kernel))?;
        let reach = segments
            .iter()
            .map(|seg| {
                let r = DVec3::splat(seg.radius * kernel.support());
                Reach {
                    a: seg.a,
                    b: seg.b,
                    radius: seg.radius,
                    lo: seg.a.min(seg.b) - r,
                    hi: seg.a.max(seg.b) + r,
                }
            })
            .collect();
        Ok(Veins { field, reach, segments, kernel })
    }

    /// The sum of the vein primitives at `p` and the radius of the nearest vein segment
    /// (`(0, 0)` where no vein reaches).
    pub fn density(&self, p: DVec3) -> (f64, f64) {
        let mut nearest = (f64::INFINITY, 0.0);
        for r in &self.reach {
            if p.cmpge(r.lo).all() && p.cmple(r.hi).all() {
                let ab = r.b - r.a;
                let t = ((p - r.a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                let d2 = p.distance_squared(r.a + ab * t);
                if d2 < nearest.0 {
                    nearest = (d2, r.radius);
                }
            }
        }
        if nearest.1 == 0.0 {
            return (0.0, 0.0);
        }
        // The skeletal field is iso − Σ with iso ½.
        let sum = skelform_skeleton::DEFAULT_ISO - self.field.eval(p);
        (sum.max(0.0), nearest.1)
    }

    /// The gradient of the summed vein density at `p` (exact: the convolution's own).
    pub fn density_gradient(&self, p: DVec3) -> DVec3 {
        -self.field.gradient(p)
    }

    /// Bounding box of everything the veins reach.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.reach
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), r| (l.min(r.lo), h.max(r.hi)))
    }
}
