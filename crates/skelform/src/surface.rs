//! How far a mesh's vertices lie from a field's surface: what `skelform check --field`
//! reports, so that a mesh of the right topology but with vertices off the surface (interior
//! fan centres left on the interpolant, say) does not pass as correct.
//!
//! The distance of a vertex `p` is estimated to first order as `|f(p)| / |∇f(p)|`: exact for
//! a signed distance, and within a few percent of the true distance near a smooth surface
//! for any field whose gradient does not vanish there. Where the gradient vanishes (a
//! critical point, a self-intersection of a healed surface) the estimate is unbounded, so
//! such vertices are counted apart rather than reported as far off.

use skelform_field::{DVec3, Field};
use skelform_mesh::Mesh;

/// Vertices are evaluated this many at a time, through the field's batch path.
const BATCH: usize = 4096;

/// Distances from a mesh's vertices to a field's zero set.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct SurfaceDistance {
    /// Vertices measured (those referenced by a face or not: every vertex of the mesh).
    pub vertices: usize,
    /// The largest estimated distance.
    pub max: f64,
    /// The vertex where it is largest.
    pub max_at: Option<usize>,
    /// The mean estimated distance.
    pub mean: f64,
    /// The tolerance the count below is against.
    pub tolerance: f64,
    /// Vertices farther than the tolerance.
    pub over: usize,
    /// Vertices where the field's gradient vanishes or a value is not finite, so that no
    /// distance can be estimated (left out of `max` and `mean`).
    pub unmeasured: usize,
}

/// Measures how far every vertex of `mesh` lies from the zero set of `field`, counting those
/// farther than `tolerance`.
pub fn surface_distance(field: &dyn Field, mesh: &Mesh, tolerance: f64) -> SurfaceDistance {
    let mut r = SurfaceDistance {
        vertices: mesh.positions.len(),
        max: 0.0,
        max_at: None,
        mean: 0.0,
        tolerance,
        over: 0,
        unmeasured: 0,
    };
    let (mut sum, mut measured) = (0.0, 0usize);
    let mut points = Vec::with_capacity(BATCH);
    let mut values = vec![0.0; BATCH];
    let mut grads = vec![DVec3::ZERO; BATCH];
    for (c, chunk) in mesh.positions.chunks(BATCH).enumerate() {
        points.clear();
        points.extend(chunk.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)));
        let n = points.len();
        field.eval_grad_many(&points, &mut values[..n], &mut grads[..n]);
        for (i, (v, g)) in values[..n].iter().zip(&grads[..n]).enumerate() {
            let slope = g.length();
            let d = v.abs() / slope;
            if !(d.is_finite() && slope > 0.0) {
                r.unmeasured += 1;
                continue;
            }
            measured += 1;
            sum += d;
            if d > r.max || r.max_at.is_none() {
                r.max = d;
                r.max_at = Some(c * BATCH + i);
            }
            if d > tolerance {
                r.over += 1;
            }
        }
    }
    if measured > 0 {
        r.mean = sum / measured as f64;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::FnField;

    #[test]
    fn distances_are_exact_for_a_signed_distance_and_vanishing_gradients_are_set_apart() {
        let sphere = FnField(|p: DVec3| p.length() - 1.0);
        let mesh = Mesh {
            positions: vec![[1.0, 0.0, 0.0], [0.0, 1.25, 0.0], [0.0, 0.0, -0.9], [0.0; 3]],
            ..Mesh::default()
        };
        let d = surface_distance(&sphere, &mesh, 0.2);
        assert_eq!(d.vertices, 4);
        // The centre: the central-difference gradient of |p| is zero there.
        assert_eq!(d.unmeasured, 1);
        assert!((d.max - 0.25).abs() < 1e-6, "{d:?}");
        assert_eq!(d.max_at, Some(1));
        assert!((d.mean - 0.35 / 3.0).abs() < 1e-6, "{d:?}");
        assert_eq!(d.over, 1);
    }
}
