//! Skeletal shapes: points, segments and planar polygons, validated on construction.
//!
//! Polylines and curves are not shapes of their own: they become chains of segments (see
//! [`crate::Skeleton::add_polyline`] and [`crate::curve`]), which is what the dissertation
//! does (§5.5.3: a curve is approximated by segments before its distance or convolution is
//! computed) and what makes superposition exact.

use glam::{DAffine3, DMat3, DVec2, DVec3};

use crate::SkeletonError;

/// A line segment with distinct ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    a: DVec3,
    b: DVec3,
}

impl Segment {
    /// A segment from `a` to `b`. Ends that coincide (to 10⁻¹² of their magnitude) are an
    /// error, not a point: a zero-length segment in a scene is almost always a typo, and a
    /// point source is one line away.
    pub fn new(a: DVec3, b: DVec3) -> Result<Segment, SkeletonError> {
        if !(a.is_finite() && b.is_finite()) {
            return Err(SkeletonError::NonFinite);
        }
        let scale = a.abs().max_element().max(b.abs().max_element()).max(1.0);
        if (b - a).length() <= 1e-12 * scale {
            return Err(SkeletonError::ZeroLengthSegment(a.to_array()));
        }
        Ok(Segment { a, b })
    }

    /// The start: parameter `α = 0` of [`Segment::nearest`], and the end at which a tapered
    /// element has its first radius and strength.
    pub fn a(&self) -> DVec3 {
        self.a
    }

    /// The end: parameter `α = 1`, where a tapered element has its end radius and strength.
    pub fn b(&self) -> DVec3 {
        self.b
    }

    /// Distance from `a` to `b` in scene units; never zero (see [`Segment::new`]).
    pub fn length(&self) -> f64 {
        (self.b - self.a).length()
    }

    /// The unit vector from `a` to `b`.
    pub fn direction(&self) -> DVec3 {
        (self.b - self.a) / self.length()
    }

    /// The point of the segment nearest `p` and its parameter `α ∈ [0, 1]` (DIS eq. 5.11:
    /// `q = a + clamp((p − a)·e, 0, 1)·d` with `e = d/(d·d)`).
    pub fn nearest(&self, p: DVec3) -> (DVec3, f64) {
        let d = self.b - self.a;
        let alpha = ((p - self.a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
        (self.a + alpha * d, alpha)
    }
}

/// A planar polygon: at least three vertices, simple (no two edges cross), with positive
/// area. Its plane and a right-handed frame are computed once; the vertices are kept in the
/// order given, which runs counter-clockwise about [`Polygon::normal`].
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    vertices: Vec<DVec3>,
    origin: DVec3,
    e1: DVec3,
    e2: DVec3,
    normal: DVec3,
    /// Vertices in the plane's frame (`e1`, `e2` about `origin`).
    flat: Vec<DVec2>,
    area: f64,
}

/// How far (relative to the polygon's size) a vertex may lie off the plane.
const PLANAR_TOLERANCE: f64 = 1e-6;

impl Polygon {
    /// A polygon through `vertices` in order. Errors: fewer than three, non-finite, a
    /// zero-length edge, zero area, not planar, or two edges that cross.
    pub fn new(vertices: Vec<DVec3>) -> Result<Polygon, SkeletonError> {
        let n = vertices.len();
        if n < 3 {
            return Err(SkeletonError::TooFewVertices(n));
        }
        if vertices.iter().any(|v| !v.is_finite()) {
            return Err(SkeletonError::NonFinite);
        }
        let origin = vertices.iter().copied().sum::<DVec3>() / n as f64;
        let size = vertices.iter().map(|v| (*v - origin).length()).fold(0.0, f64::max);
        for i in 0..n {
            let (a, b) = (vertices[i], vertices[(i + 1) % n]);
            if (b - a).length() <= 1e-12 * size.max(f64::MIN_POSITIVE) {
                return Err(SkeletonError::ZeroLengthEdge(i));
            }
        }
        // Newell's normal: twice the vector area, robust for any simple polygon.
        let mut newell = DVec3::ZERO;
        for i in 0..n {
            let (a, b) = (vertices[i] - origin, vertices[(i + 1) % n] - origin);
            newell += a.cross(b);
        }
        let area = 0.5 * newell.length();
        if area.is_nan() || area <= 1e-12 * size * size {
            return Err(SkeletonError::DegeneratePolygon { area });
        }
        let normal = newell.normalize();
        for (i, v) in vertices.iter().enumerate() {
            let off = (*v - origin).dot(normal).abs();
            if off > PLANAR_TOLERANCE * size {
                return Err(SkeletonError::NotPlanar { vertex: i, distance: off });
            }
        }
        let e1 = (vertices[0] - origin)
            .reject_from(normal)
            .normalize_or(normal.any_orthonormal_vector());
        let e2 = normal.cross(e1);
        let flat: Vec<DVec2> = vertices
            .iter()
            .map(|v| DVec2::new((*v - origin).dot(e1), (*v - origin).dot(e2)))
            .collect();
        // Simple: no two non-adjacent edges meet.
        for i in 0..n {
            for j in i + 1..n {
                let adjacent = j == i + 1 || (i == 0 && j == n - 1);
                if adjacent {
                    continue;
                }
                if segments_cross(flat[i], flat[(i + 1) % n], flat[j], flat[(j + 1) % n]) {
                    return Err(SkeletonError::SelfIntersecting(i, j));
                }
            }
        }
        Ok(Polygon { vertices, origin, e1, e2, normal, flat, area })
    }

    /// The triangle `a, b, c`.
    pub fn triangle(a: DVec3, b: DVec3, c: DVec3) -> Result<Polygon, SkeletonError> {
        Polygon::new(vec![a, b, c])
    }

    /// The vertices as given, in order: counter-clockwise about [`Polygon::normal`], the first
    /// one fixing the direction of the plane frame's `e1`.
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// Unit normal; the vertices run counter-clockwise about it.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// Area enclosed, in squared scene units (half the length of Newell's vector); always
    /// positive, whichever way the vertices run.
    pub fn area(&self) -> f64 {
        self.area
    }

    /// The centroid of the vertices (a point of the plane; inside for convex polygons).
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    /// The plane frame `(e1, e2, normal)`, right-handed.
    pub fn frame(&self) -> (DVec3, DVec3, DVec3) {
        (self.e1, self.e2, self.normal)
    }

    /// The vertices in the plane frame.
    pub fn flat_vertices(&self) -> &[DVec2] {
        &self.flat
    }

    /// `p` in the plane frame: (in-plane coordinates, height above the plane).
    pub fn to_plane(&self, p: DVec3) -> (DVec2, f64) {
        let w = p - self.origin;
        (DVec2::new(w.dot(self.e1), w.dot(self.e2)), w.dot(self.normal))
    }

    /// Whether an in-plane point is inside (even–odd rule; boundary points may go either
    /// way).
    pub fn contains_flat(&self, q: DVec2) -> bool {
        let n = self.flat.len();
        let mut inside = false;
        for i in 0..n {
            let (a, b) = (self.flat[i], self.flat[(i + 1) % n]);
            if (a.y > q.y) != (b.y > q.y) {
                let x = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
                if q.x < x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// A point inside the polygon: the centroid when it is inside, else the centre of the
    /// first ear-ish triangle that contains its own centroid.
    pub fn interior_point(&self) -> DVec3 {
        let (q, _) = self.to_plane(self.origin);
        if self.contains_flat(q) {
            return self.origin;
        }
        let n = self.flat.len();
        for i in 0..n {
            let c = (self.flat[(i + n - 1) % n] + self.flat[i] + self.flat[(i + 1) % n]) / 3.0;
            if self.contains_flat(c) {
                return self.origin + c.x * self.e1 + c.y * self.e2;
            }
        }
        self.vertices[0]
    }
}

/// Whether closed segments `ab` and `cd` of the plane share a point.
fn segments_cross(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let o = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (d1, d2, d3, d4) = (o(c, d, a), o(c, d, b), o(a, b, c), o(a, b, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2| {
        r.x >= p.x.min(q.x) && r.x <= p.x.max(q.x) && r.y >= p.y.min(q.y) && r.y <= p.y.max(q.y)
    };
    (d1 == 0.0 && on(c, d, a))
        || (d2 == 0.0 && on(c, d, b))
        || (d3 == 0.0 && on(a, b, c))
        || (d4 == 0.0 && on(a, b, d))
}

/// The shape of one skeletal element.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A point source at this position: the convolution of a point is the kernel itself, and its
    /// surface is a sphere of the element's radius.
    Point(DVec3),
    /// A line segment; polylines and cubic curves are chains of these.
    Segment(Segment),
    /// A planar polygon, filled: its surface is a slab of the element's radius around it, with
    /// rounded edges (DIS ch. 6).
    Polygon(Polygon),
}

/// The nearest point of a shape and how it moves with the query point.
#[derive(Clone, Copy, Debug)]
pub struct Nearest {
    /// The point of the shape nearest the query point, in scene units.
    pub point: DVec3,
    /// `∂point/∂p`: zero at a point or a vertex, the projection onto the segment's line or
    /// the polygon's plane in the interior of those.
    pub jacobian: DMat3,
}

impl Shape {
    /// The shape's own bounding box (a point's is empty; callers inflate it).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        match self {
            Shape::Point(c) => (*c, *c),
            Shape::Segment(s) => (s.a.min(s.b), s.a.max(s.b)),
            Shape::Polygon(p) => p.vertices.iter().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), v| (lo.min(*v), hi.max(*v)),
            ),
        }
    }

    /// A point of the shape, central where that makes sense: where the continuation
    /// polygonizer starts looking for the surface.
    pub fn seed_point(&self) -> DVec3 {
        match self {
            Shape::Point(c) => *c,
            Shape::Segment(s) => 0.5 * (s.a + s.b),
            Shape::Polygon(p) => p.interior_point(),
        }
    }

    /// The nearest point of the shape to `p`.
    pub fn nearest(&self, p: DVec3) -> DVec3 {
        self.nearest_with_jacobian(p).point
    }

    /// The nearest point and its derivative with respect to `p`.
    pub fn nearest_with_jacobian(&self, p: DVec3) -> Nearest {
        match self {
            Shape::Point(c) => Nearest { point: *c, jacobian: DMat3::ZERO },
            Shape::Segment(s) => segment_nearest(s.a, s.b, p),
            Shape::Polygon(poly) => {
                let (q, z) = poly.to_plane(p);
                if poly.contains_flat(q) {
                    let n = poly.normal;
                    return Nearest {
                        point: p - z * n,
                        jacobian: DMat3::IDENTITY - DMat3::from_cols(n * n.x, n * n.y, n * n.z),
                    };
                }
                let k = poly.vertices.len();
                let mut best: Option<(f64, Nearest)> = None;
                for i in 0..k {
                    let nr = segment_nearest(poly.vertices[i], poly.vertices[(i + 1) % k], p);
                    let d = (nr.point - p).length_squared();
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, nr));
                    }
                }
                best.map_or(Nearest { point: poly.origin, jacobian: DMat3::ZERO }, |(_, n)| n)
            }
        }
    }

    /// The shape moved by a rigid (or any affine) transform. A transform that collapses the
    /// shape (scale 0) is an error.
    pub fn transformed(&self, t: &DAffine3) -> Result<Shape, SkeletonError> {
        Ok(match self {
            Shape::Point(c) => Shape::Point(t.transform_point3(*c)),
            Shape::Segment(s) => {
                Shape::Segment(Segment::new(t.transform_point3(s.a), t.transform_point3(s.b))?)
            }
            Shape::Polygon(p) => Shape::Polygon(Polygon::new(
                p.vertices.iter().map(|v| t.transform_point3(*v)).collect(),
            )?),
        })
    }
}

fn segment_nearest(a: DVec3, b: DVec3, p: DVec3) -> Nearest {
    let d = b - a;
    let t = (p - a).dot(d) / d.length_squared();
    if t <= 0.0 {
        Nearest { point: a, jacobian: DMat3::ZERO }
    } else if t >= 1.0 {
        Nearest { point: b, jacobian: DMat3::ZERO }
    } else {
        let u = d.normalize();
        Nearest { point: a + t * d, jacobian: DMat3::from_cols(u * u.x, u * u.y, u * u.z) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_rejects_zero_length() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert!(matches!(Segment::new(p, p), Err(SkeletonError::ZeroLengthSegment(_))));
        assert!(Segment::new(p, p + DVec3::X * 1e-6).is_ok());
    }

    #[test]
    fn polygon_validation() {
        let o = DVec3::ZERO;
        assert!(matches!(Polygon::new(vec![o, DVec3::X]), Err(SkeletonError::TooFewVertices(2))));
        assert!(matches!(
            Polygon::triangle(o, DVec3::X, 2.0 * DVec3::X),
            Err(SkeletonError::DegeneratePolygon { .. })
        ));
        assert!(matches!(
            Polygon::new(vec![o, DVec3::X, DVec3::new(1.0, 1.0, 0.5), DVec3::Y]),
            Err(SkeletonError::NotPlanar { .. })
        ));
        // A bow tie: edges 0 and 2 cross.
        assert!(matches!(
            Polygon::new(vec![o, DVec3::new(3.0, 1.0, 0.0), 3.0 * DVec3::X, 2.0 * DVec3::Y]),
            Err(SkeletonError::SelfIntersecting(0, 2))
        ));
        let sq = Polygon::new(vec![o, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y]).unwrap();
        assert!((sq.area() - 1.0).abs() < 1e-15);
        assert!((sq.normal() - DVec3::Z).length() < 1e-15);
        // Clockwise order flips the normal, so the vertices still run counter-clockwise.
        let cw = Polygon::new(vec![o, DVec3::Y, DVec3::new(1.0, 1.0, 0.0), DVec3::X]).unwrap();
        assert!((cw.normal() + DVec3::Z).length() < 1e-15);
    }

    #[test]
    fn nearest_points() {
        let tri = Shape::Polygon(Polygon::triangle(DVec3::ZERO, DVec3::X, DVec3::Y).unwrap());
        let p = DVec3::new(0.2, 0.2, 0.7);
        assert!((tri.nearest(p) - DVec3::new(0.2, 0.2, 0.0)).length() < 1e-15);
        let p = DVec3::new(2.0, -1.0, 0.3);
        assert!((tri.nearest(p) - DVec3::X).length() < 1e-15);
        let seg = Shape::Segment(Segment::new(DVec3::ZERO, DVec3::X).unwrap());
        let n = seg.nearest_with_jacobian(DVec3::new(0.5, 1.0, 0.0));
        assert!((n.point - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
        assert!((n.jacobian * DVec3::new(1.0, 1.0, 1.0) - DVec3::X).length() < 1e-15);
    }
}
