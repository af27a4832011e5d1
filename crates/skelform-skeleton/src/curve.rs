//! Cubic curves as skeletal elements: approximated by segments (DIS §5.5.3), with
//! rotation-minimising reference frames along them (DIS §5.3).
//!
//! The dissertation computes the distance to a cubic by the roots of a quintic (eq. 5.8) but
//! prefers segments: three segments look better than nine points and cost about as much
//! (§5.5.3), and convolution needs segments anyway. The splitting rule is the
//! dissertation's: start with the chord, and repeatedly split the segment whose midpoint
//! deviates most from the curve, at the curve's arc-length midpoint, until every deviation is
//! within the tolerance.

use glam::DVec3;

use crate::SkeletonError;

/// `p(t) = c1·t³ + c2·t² + c3·t + c4`, `t ∈ [0, 1]` (DIS eq. 5.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubicCurve {
    /// The coefficients `[c1, c2, c3, c4]` of eq. 5.1, in scene units: `c4 = p(0)` is the start,
    /// `c1 + c2 + c3 + c4 = p(1)` the end. [`CubicCurve::bezier`] converts control points.
    pub c: [DVec3; 4],
}

/// A reference frame along a curve: `tangent`, `normal`, `binormal` orthonormal and
/// right-handed (`tangent × normal = binormal`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The curve point `p(t)` the frame sits at.
    pub origin: DVec3,
    /// Unit `p′(t)`, the direction of travel.
    pub tangent: DVec3,
    /// Unit vector across the curve, carried along by rotation minimisation (DIS §5.3) rather
    /// than the Frenet normal, so it neither flips at inflections nor vanishes on straight parts.
    pub normal: DVec3,
    /// `tangent × normal`; with `normal`, spans the plane of the cross-section (DIS eq. 5.4).
    pub binormal: DVec3,
}

/// Samples of the arc-length table (the dissertation sums 100 segments).
const ARC_SAMPLES: usize = 256;

impl CubicCurve {
    /// The Bézier curve with control points `p0 … p3` (ends at `p0` and `p3`).
    pub fn bezier(p: [DVec3; 4]) -> CubicCurve {
        CubicCurve {
            c: [
                -p[0] + 3.0 * p[1] - 3.0 * p[2] + p[3],
                3.0 * p[0] - 6.0 * p[1] + 3.0 * p[2],
                -3.0 * p[0] + 3.0 * p[1],
                p[0],
            ],
        }
    }

    /// `p(t)`.
    pub fn point(&self, t: f64) -> DVec3 {
        ((self.c[0] * t + self.c[1]) * t + self.c[2]) * t + self.c[3]
    }

    /// `p′(t) = 3c1 t² + 2c2 t + c3` (DIS eq. 5.2).
    pub fn velocity(&self, t: f64) -> DVec3 {
        (3.0 * self.c[0] * t + 2.0 * self.c[1]) * t + self.c[2]
    }

    /// `(t, cumulative length)` at evenly spaced parameters.
    fn arc_table(&self) -> Vec<(f64, f64)> {
        let mut table = Vec::with_capacity(ARC_SAMPLES + 1);
        let mut len = 0.0;
        let mut prev = self.point(0.0);
        table.push((0.0, 0.0));
        for i in 1..=ARC_SAMPLES {
            let t = i as f64 / ARC_SAMPLES as f64;
            let p = self.point(t);
            len += (p - prev).length();
            prev = p;
            table.push((t, len));
        }
        table
    }

    /// The parameter half-way in arc length between `t0` and `t1`.
    fn arc_midpoint(table: &[(f64, f64)], t0: f64, t1: f64) -> f64 {
        let s_at = |t: f64| {
            let x = t * ARC_SAMPLES as f64;
            let i = (x.floor() as usize).min(ARC_SAMPLES - 1);
            let f = x - i as f64;
            table[i].1 + f * (table[i + 1].1 - table[i].1)
        };
        let target = 0.5 * (s_at(t0) + s_at(t1));
        // Invert the piecewise-linear table.
        let i = table.partition_point(|&(_, s)| s < target).clamp(1, ARC_SAMPLES);
        let ((ta, sa), (tb, sb)) = (table[i - 1], table[i]);
        let t = if sb > sa { ta + (target - sa) / (sb - sa) * (tb - ta) } else { 0.5 * (t0 + t1) };
        if t > t0 && t < t1 { t } else { 0.5 * (t0 + t1) }
    }

    /// The parameters of a polyline that follows the curve within `tolerance` (largest
    /// distance from a segment's midpoint to the curve's arc-length midpoint between its
    /// ends), at most `max_segments` segments.
    pub fn split(&self, tolerance: f64, max_segments: usize) -> Result<Vec<f64>, SkeletonError> {
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(SkeletonError::BadParameter {
                name: "tolerance",
                value: tolerance,
                expected: "a positive length",
            });
        }
        if self.c.iter().any(|c| !c.is_finite()) {
            return Err(SkeletonError::NonFinite);
        }
        let table = self.arc_table();
        let deviation = |t0: f64, t1: f64| {
            let tm = Self::arc_midpoint(&table, t0, t1);
            let mid = 0.5 * (self.point(t0) + self.point(t1));
            ((mid - self.point(tm)).length(), tm)
        };
        let mut params = vec![0.0, 1.0];
        let mut dev = vec![deviation(0.0, 1.0)];
        while params.len() - 1 < max_segments.max(1) {
            let (worst, &(d, tm)) = dev
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.0.total_cmp(&b.1.0))
                .expect("at least one segment");
            if d <= tolerance {
                break;
            }
            params.insert(worst + 1, tm);
            let left = deviation(params[worst], tm);
            let right = deviation(tm, params[worst + 2]);
            dev[worst] = left;
            dev.insert(worst + 1, right);
        }
        Ok(params)
    }

    /// The curve's points at [`CubicCurve::split`]'s parameters.
    pub fn to_polyline(
        &self,
        tolerance: f64,
        max_segments: usize,
    ) -> Result<Vec<DVec3>, SkeletonError> {
        Ok(self.split(tolerance, max_segments)?.into_iter().map(|t| self.point(t)).collect())
    }

    /// Rotation-minimising frames at parameters `ts` (increasing): each frame is the previous
    /// one rotated about `v_prev × v` so that its tangent follows the curve (DIS §5.3), which
    /// avoids the Frenet frame's flips at inflections and its absence on straight parts. The
    /// first normal is any vector perpendicular to the first tangent, or `initial_normal`
    /// made perpendicular. A point where the velocity vanishes keeps the previous frame.
    pub fn frames(&self, ts: &[f64], initial_normal: Option<DVec3>) -> Vec<Frame> {
        let mut out: Vec<Frame> = Vec::with_capacity(ts.len());
        for &t in ts {
            let origin = self.point(t);
            let v = self.velocity(t);
            let frame = match out.last() {
                None => {
                    let tangent = v.try_normalize().unwrap_or(DVec3::X);
                    let normal = initial_normal
                        .and_then(|n| n.reject_from(tangent).try_normalize())
                        .unwrap_or_else(|| tangent.any_orthonormal_vector());
                    Frame { origin, tangent, normal, binormal: tangent.cross(normal) }
                }
                Some(prev) => match v.try_normalize() {
                    None => Frame { origin, ..*prev },
                    Some(tangent) => {
                        let rot = glam::DQuat::from_rotation_arc(prev.tangent, tangent);
                        let normal = (rot * prev.normal).reject_from(tangent).normalize();
                        Frame { origin, tangent, normal, binormal: tangent.cross(normal) }
                    }
                },
            };
            out.push(frame);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arc() -> CubicCurve {
        CubicCurve::bezier([
            DVec3::ZERO,
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.5),
            DVec3::new(1.0, 0.0, 1.0),
        ])
    }

    #[test]
    fn bezier_ends_and_polynomial_agree() {
        let c = arc();
        assert!((c.point(0.0) - DVec3::ZERO).length() < 1e-15);
        assert!((c.point(1.0) - DVec3::new(1.0, 0.0, 1.0)).length() < 1e-15);
        // Bézier tangent at the start is 3(p1 − p0).
        assert!((c.velocity(0.0) - DVec3::new(0.0, 3.0, 0.0)).length() < 1e-15);
    }

    #[test]
    fn splitting_meets_the_tolerance_everywhere() {
        let c = arc();
        for tol in [0.1, 0.01, 0.001] {
            let ts = c.split(tol, 1000).unwrap();
            assert!(ts.windows(2).all(|w| w[0] < w[1]));
            // Check densely: every curve point is within about the tolerance of the polyline.
            for w in ts.windows(2) {
                let (a, b) = (c.point(w[0]), c.point(w[1]));
                for i in 0..=20 {
                    let t = w[0] + (w[1] - w[0]) * i as f64 / 20.0;
                    let p = c.point(t);
                    let d = b - a;
                    let s = ((p - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                    assert!((a + s * d - p).length() < 1.5 * tol, "tol {tol}");
                }
            }
        }
        assert!(c.split(0.001, 1000).unwrap().len() > c.split(0.1, 1000).unwrap().len());
        // A straight curve needs one segment.
        let line = CubicCurve::bezier([DVec3::ZERO, DVec3::X, 2.0 * DVec3::X, 3.0 * DVec3::X]);
        assert_eq!(line.split(1e-9, 100).unwrap().len(), 2);
    }

    #[test]
    fn frames_are_orthonormal_and_follow_the_tangent() {
        let c = arc();
        let ts: Vec<f64> = (0..=50).map(|i| i as f64 / 50.0).collect();
        let frames = c.frames(&ts, Some(DVec3::Z));
        for (f, &t) in frames.iter().zip(&ts) {
            assert!((f.tangent - c.velocity(t).normalize()).length() < 1e-12);
            assert!(f.tangent.dot(f.normal).abs() < 1e-12);
            assert!((f.normal.length() - 1.0).abs() < 1e-12);
            assert!((f.tangent.cross(f.normal) - f.binormal).length() < 1e-12);
        }
        // Rotation-minimising: consecutive normals turn little.
        for w in frames.windows(2) {
            assert!(w[0].normal.dot(w[1].normal) > 0.9);
        }
    }
}
