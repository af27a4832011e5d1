//! Weights that vary over a polygon (DIS §6.4): per-vertex weights and a weight image.
//!
//! The dissertation gives finer control over a convolved polygon by "the association of
//! weights with the skeletal elements": a weight at each polygon vertex, applied when the
//! polygon is rendered into its image, thins the surface where the weight is low (the arm's
//! muscles taper to tendons that way, fig. 6.12); or "the entire polygon image can be scaled
//! by a weight image". Both multiply the element's strength point by point over the
//! polygon, so the density is `∫_P w(u)·k(|p − u|/r) du`.
//!
//! **Per-vertex weights** are interpolated over the fan of triangles from the polygon's
//! vertex average (its [`Polygon::origin`]) to its edges, the weight at the centre being the
//! mean of the vertex weights: linear in each triangle, continuous, and for a triangle (or
//! any polygon whose weights are those of a plane) exactly the linear interpolant. The fan
//! covers the polygon only if the polygon is star-shaped about its vertex average (every
//! convex polygon is), so weights are refused on polygons that are not
//! ([`SkeletonError::WeightsNotStarShaped`]). The exact method integrates a linear weight
//! over each triangle in closed form up to one line integral per edge (see
//! [`crate::convolution`]); the image method rasterizes the weight into the polygon image.
//!
//! A **weight image** spans the polygon's bounding rectangle in the frame of its first
//! edge ([`image_frame`]): the image's columns run along the edge from vertex 0 to vertex
//! 1, its rows across it, row 0 at the top, on the polygon's side of the edge — the image
//! as it looks when the polygon is seen from its normal's side with its first edge at the
//! bottom (a rectangle given counter-clockwise from its lower left corner shows it upright).
//! Its values scale
//! the polygon image pixel by pixel, as in the dissertation, so it needs the image method
//! ([`crate::PolygonMethod::Image`]); an element given one is switched to it.

use glam::DVec2;

use crate::SkeletonError;
use crate::geometry::Polygon;

/// The largest side, in pixels, of a [`WeightImage`].
pub const MAX_WEIGHT_IMAGE_SIDE: usize = 4096;

/// A grid of weights stretched over a polygon's bounding rectangle in its plane, sampled
/// bilinearly between pixel centres (and clamped to the border pixels beyond them).
#[derive(Clone, Debug, PartialEq)]
pub struct WeightImage {
    width: usize,
    height: usize,
    /// Row-major, row 0 at the top.
    values: Vec<f64>,
}

impl WeightImage {
    /// A `width × height` image (each side 1 ..= [`MAX_WEIGHT_IMAGE_SIDE`]) of finite
    /// weights, row-major with row 0 at the top (as a PNG is stored).
    pub fn new(
        width: usize,
        height: usize,
        values: Vec<f64>,
    ) -> Result<WeightImage, SkeletonError> {
        let bad = |m: String| Err(SkeletonError::BadWeightImage(m));
        if !(1..=MAX_WEIGHT_IMAGE_SIDE).contains(&width)
            || !(1..=MAX_WEIGHT_IMAGE_SIDE).contains(&height)
        {
            return bad(format!(
                "the image is {width}x{height} pixels; a weight image is 1 to {MAX_WEIGHT_IMAGE_SIDE} on a side"
            ));
        }
        if values.len() != width * height {
            return bad(format!(
                "{} values for a {width}x{height} image (expected {})",
                values.len(),
                width * height
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return bad(format!("value {i} is not a finite number"));
        }
        Ok(WeightImage { width, height, values })
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The weight at `(s, t)` in `[0, 1]²` (`s` across, `t` down from the top): bilinear
    /// between pixel centres, pixel `(i, j)` centred at `((i + ½)/width, (j + ½)/height)`.
    pub fn sample(&self, s: f64, t: f64) -> f64 {
        let x = (s * self.width as f64 - 0.5).clamp(0.0, (self.width - 1) as f64);
        let y = (t * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (i, j) = (x.floor() as usize, y.floor() as usize);
        let (i1, j1) = ((i + 1).min(self.width - 1), (j + 1).min(self.height - 1));
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |a: usize, b: usize| self.values[b * self.width + a];
        let top = at(i, j) + fx * (at(i1, j) - at(i, j));
        let bottom = at(i, j1) + fx * (at(i1, j1) - at(i, j1));
        top + fy * (bottom - top)
    }
}

/// Checks per-vertex weights for `poly`: one finite weight per vertex, and a polygon
/// star-shaped about its vertex average (every triangle of the fan from it to the edges
/// turns the polygon's way and has area), so that the fan interpolant covers it.
pub(crate) fn check_vertex_weights(poly: &Polygon, weights: &[f64]) -> Result<(), SkeletonError> {
    let flat = poly.flat_vertices();
    if weights.len() != flat.len() {
        return Err(SkeletonError::WeightCount { weights: weights.len(), vertices: flat.len() });
    }
    if let Some(w) = weights.iter().find(|w| !w.is_finite()) {
        return Err(SkeletonError::BadStrength(*w));
    }
    // Flat vertices run counter-clockwise about the origin's normal; each fan triangle
    // must too, with at least a millionth of the polygon's area.
    let area: f64 = fan(flat).map(|(a, b)| 0.5 * a.perp_dot(b)).sum();
    for (i, (a, b)) in fan(flat).enumerate() {
        if 0.5 * a.perp_dot(b) <= 1e-6 * area {
            return Err(SkeletonError::WeightsNotStarShaped { edge: i });
        }
    }
    Ok(())
}

/// The fan's outer edges `(vᵢ, vᵢ₊₁)`.
fn fan(flat: &[DVec2]) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
    (0..flat.len()).map(move |i| (flat[i], flat[(i + 1) % flat.len()]))
}

/// A linear weight `c + g·q` over one fan triangle, in the polygon's plane frame (world
/// units about the vertex average).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LinearPiece {
    pub(crate) c: f64,
    pub(crate) g: DVec2,
}

/// The linear pieces of the fan interpolant, one per edge (the triangle centre, `vᵢ`,
/// `vᵢ₊₁`), for weights already checked by [`check_vertex_weights`].
pub(crate) fn fan_pieces(poly: &Polygon, weights: &[f64]) -> Vec<LinearPiece> {
    let flat = poly.flat_vertices();
    let n = flat.len();
    let centre = weights.iter().sum::<f64>() / n as f64;
    fan(flat)
        .enumerate()
        .map(|(i, (a, b))| {
            let (wa, wb) = (weights[i], weights[(i + 1) % n]);
            // w(q) = centre + g·q with g·a = wa − centre, g·b = wb − centre.
            let det = a.perp_dot(b);
            let (ra, rb) = (wa - centre, wb - centre);
            let g = DVec2::new(ra * b.y - rb * a.y, rb * a.x - ra * b.x) / det;
            LinearPiece { c: centre, g }
        })
        .collect()
}

/// The fan interpolant at `q` (plane frame, world units): the piece of the sector `q` lies
/// in, extended linearly (only points inside the polygon matter).
pub(crate) fn fan_weight(flat: &[DVec2], pieces: &[LinearPiece], q: DVec2) -> f64 {
    let n = flat.len();
    let i = (0..n)
        .find(|&i| flat[i].perp_dot(q) >= 0.0 && q.perp_dot(flat[(i + 1) % n]) >= 0.0)
        .unwrap_or(0);
    pieces[i].c + pieces[i].g.dot(q)
}

/// The weight a polygon's raster samples take at `q` (plane frame, world units): the
/// product of its per-vertex weights' interpolant and its weight image, either optional.
pub(crate) fn raster_weight(
    poly: &Polygon,
    vertex: Option<&[LinearPiece]>,
    image: Option<&WeightImage>,
) -> impl Fn(DVec2) -> f64 {
    let flat = poly.flat_vertices().to_vec();
    let (u, lo, hi) = image_frame(poly);
    let vertex = vertex.map(<[LinearPiece]>::to_vec);
    let image = image.cloned();
    move |q| {
        let mut w = 1.0;
        if let Some(p) = &vertex {
            w *= fan_weight(&flat, p, q);
        }
        if let Some(img) = &image {
            let (x, y) = (q.dot(u), u.perp_dot(q));
            w *= img.sample((x - lo.x) / (hi.x - lo.x), (hi.y - y) / (hi.y - lo.y));
        }
        w
    }
}

/// Where a weight image lies on `poly`, in its plane frame ([`Polygon::flat_vertices`]):
/// the unit direction `u` of the first edge (the image's columns run along it, its rows along
/// `u` turned a quarter counter-clockwise, towards the polygon), and the corners `lo`, `hi`
/// of the vertices' bounding rectangle in those coordinates (`(q·u, u × q)`); image row 0
/// is at `hi.y`.
pub fn image_frame(poly: &Polygon) -> (DVec2, DVec2, DVec2) {
    let flat = poly.flat_vertices();
    let u = (flat[1] - flat[0]).normalize();
    flat.iter().fold(
        (u, DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(u, l, h), v| {
            let c = DVec2::new(v.dot(u), u.perp_dot(*v));
            (u, l.min(c), h.max(c))
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn fan_interpolant_takes_the_vertex_weights_and_reproduces_planes() {
        let sq = Polygon::new(vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ])
        .unwrap();
        let w = [0.2, 1.0, 0.7, 0.4];
        check_vertex_weights(&sq, &w).unwrap();
        let pieces = fan_pieces(&sq, &w);
        for (v, wv) in sq.flat_vertices().iter().zip(w) {
            assert!((fan_weight(sq.flat_vertices(), &pieces, *v) - wv).abs() < 1e-12);
        }
        // Weights of a plane, 1 + x + 2y in world coordinates: reproduced everywhere.
        let plane: Vec<f64> = sq.vertices().iter().map(|v| 1.0 + v.x + 2.0 * v.y).collect();
        let pieces = fan_pieces(&sq, &plane);
        for &(x, y) in &[(0.3, 0.2), (1.7, 0.9), (1.0, 0.5), (0.1, 0.8)] {
            let (q, _) = sq.to_plane(DVec3::new(x, y, 0.0));
            let got = fan_weight(sq.flat_vertices(), &pieces, q);
            assert!((got - (1.0 + x + 2.0 * y)).abs() < 1e-12, "{got} at {x},{y}");
        }
    }

    #[test]
    fn bad_weights_are_refused() {
        let tri = Polygon::triangle(DVec3::ZERO, DVec3::X, DVec3::Y).unwrap();
        assert_eq!(
            check_vertex_weights(&tri, &[1.0, 1.0]),
            Err(SkeletonError::WeightCount { weights: 2, vertices: 3 })
        );
        assert!(check_vertex_weights(&tri, &[1.0, f64::NAN, 1.0]).is_err());
        // An L whose vertex average lies outside it: not star-shaped about it.
        let l = Polygon::new(vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(4.0, 0.2, 0.0),
            DVec3::new(0.2, 0.2, 0.0),
            DVec3::new(0.2, 4.0, 0.0),
            DVec3::new(0.0, 4.0, 0.0),
        ])
        .unwrap();
        assert!(matches!(
            check_vertex_weights(&l, &[1.0; 6]),
            Err(SkeletonError::WeightsNotStarShaped { .. })
        ));
        assert!(WeightImage::new(2, 2, vec![0.0; 3]).is_err());
        assert!(WeightImage::new(0, 2, vec![]).is_err());
        assert!(WeightImage::new(1, 2, vec![0.0, f64::INFINITY]).is_err());
    }

    #[test]
    fn weight_image_is_bilinear_between_pixel_centres() {
        let img = WeightImage::new(2, 1, vec![0.0, 1.0]).unwrap();
        assert_eq!(img.sample(0.0, 0.5), 0.0);
        assert_eq!(img.sample(0.25, 0.5), 0.0);
        assert!((img.sample(0.5, 0.5) - 0.5).abs() < 1e-15);
        assert_eq!(img.sample(1.0, 0.5), 1.0);
    }
}
