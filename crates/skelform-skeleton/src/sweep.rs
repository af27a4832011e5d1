//! Generalized cylinders: a cross-section swept along a cubic curve (DIS §5.3–5.5), as an
//! implicit field that blends with the other skeletal elements, and the texture coordinates
//! of §5.7.
//!
//! The dissertation builds its generalized cylinders parametrically: a cross-section placed
//! in the rotation-minimising frame at each point of the curve (eq. 5.4, `q = qx·n + qy·b +
//! p`), with hemispherical ends (eq. 5.5). Its implicit surfaces are distance surfaces to the
//! skeleton (eq. 5.6). A [`Sweep`] joins the two: for a point `p` it finds the nearest point
//! `C(t)` of the curve, writes `p − C(t)` in the frame there as `(x, y)` across the curve and
//! `s` along it (non-zero only beyond an end), and measures
//!
//! `ρ² = x²/a(t)² + y²/b(t)² + s²/c(t)²`,
//!
//! the distance in "radii" to an ellipse of semi-axes `a` along the normal and `b` along the
//! binormal (a circle when `a = b`); `c = √(ab)` is the cap's depth, so that a circular sweep
//! ends in a hemisphere of its radius (eq. 5.5). The surface is `ρ = 1`. Why a normalised
//! distance rather than the Euclidean distance to the swept surface: the distance to an
//! ellipse has no closed form, while `ρ` is exact on the surface, smooth off the curve, and
//! is what every skeletal blend already consumes as `d/r` — the sum and convolution blends
//! add the density `w·k(ρ²)` (which is ½ on the surface, like a long convolved cylinder's),
//! the union takes `ρ − 1` (eq. 5.6). The radii vary along the curve as a cubic Bernstein
//! blend of one value per Bézier control point, so they vary as smoothly as the curve.
//!
//! The frames are [`CubicCurve::frames`] at evenly spaced parameters; the frame at any `t`
//! is the nearest sampled frame turned by the smallest rotation onto the tangent at `t`
//! (the dissertation's step, fig. 5.7), so the section does not twist, whatever the curve.
//!
//! **Image sections** (§5.3–5.4, where the dissertation's cross-sections are arbitrary
//! planar curves): a [`SectionImage`] replaces the ellipse by a shape given as a grayscale
//! mask over the square `[−1, 1]²` of the section plane, scaled by the semi-axes (`a` along
//! the normal, across the image's columns, `b` along the binormal, up its rows). Its
//! section term is `1 + d`, with `d` the signed distance to the mask's boundary in those
//! normalised units (negative inside), from an exact Euclidean distance transform of the
//! mask interpolated bilinearly between pixel centres (beyond the square, the distance to
//! it is added): 1 on the boundary, less inside, growing like the distance outside, as the
//! ellipse's `ρ` does. The boundary is known to half a pixel.
//!
//! Texture coordinates (§5.7): `u` is the arc-length fraction at the nearest curve point,
//! `v` the angle around the section from the normal toward the binormal, as a fraction of a
//! turn, both in `[0, 1]` ([`Sweep::uv`]).
//!
//! [`SweptField`] adds sweeps to a [`SkeletonField`]. Sweeps blend with every clique of the
//! skeleton (they have no blend group), are culled by their own boxes, not the skeleton's
//! [`crate::field::CullGrid`] (a scene has a few of them), and take their gradient by
//! central differences. Under the super-elliptic and combination blends they join the
//! skeleton by a sharp union (those blends need per-element terms that a sweep does not
//! give); under the sum and convolution blends they blend.

use glam::{DQuat, DVec3};
use skelform_field::{Aabb, Field};

use crate::SkeletonError;
use crate::curve::{CubicCurve, Frame};
use crate::field::{Blend, DEFAULT_ISO, SkeletonField};
use crate::kernel::Kernel;

/// How a sweep is sampled and ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepSettings {
    /// Frames sampled along the curve, at least 2: the start of the nearest-point search
    /// and of the frame at any parameter. 64 keep the rotation between samples small.
    pub samples: usize,
    /// Hemispherical (for an elliptical section, half-ellipsoidal) caps at both ends
    /// (DIS eq. 5.5); without them the ends are flat: the section's disc.
    pub caps: bool,
    /// The first frame's normal (made perpendicular to the tangent); `None` picks one.
    pub initial_normal: Option<DVec3>,
}

impl Default for SweepSettings {
    fn default() -> Self {
        SweepSettings { samples: 64, caps: true, initial_normal: None }
    }
}

/// The largest side, in pixels, of a [`SectionImage`]: the image method's own limit
/// ([`crate::image::MAX_IMAGE_RESOLUTION`]).
pub const MAX_SECTION_PIXELS: usize = crate::image::MAX_IMAGE_RESOLUTION;

/// A cross-section given by a mask image (see the module documentation): a signed distance
/// table over the square `[−1, 1]²`.
#[derive(Clone, Debug, PartialEq)]
pub struct SectionImage {
    width: usize,
    height: usize,
    /// Signed distance (negative inside) at each pixel centre, rows from the top, in the
    /// normalised units of the square.
    distance: Vec<f64>,
    /// The mask as given.
    mask: Vec<bool>,
}

impl SectionImage {
    /// A section from a `width × height` mask, rows from the top: `inside[r * width + c]`
    /// says whether pixel `(c, r)` is inside. Errors: a side under 2 or over
    /// [`MAX_SECTION_PIXELS`], a mask of another length, or no pixel inside.
    pub fn from_mask(
        width: usize,
        height: usize,
        inside: &[bool],
    ) -> Result<SectionImage, SkeletonError> {
        let bad = |reason: String| SkeletonError::BadSectionImage(reason);
        for side in [width, height] {
            if !(2..=MAX_SECTION_PIXELS).contains(&side) {
                return Err(bad(format!(
                    "a section image is 2 to {MAX_SECTION_PIXELS} pixels on a side (got                      {width}x{height})"
                )));
            }
        }
        if inside.len() != width * height {
            return Err(bad(format!("{} mask values for {width}x{height} pixels", inside.len())));
        }
        if !inside.iter().any(|&b| b) {
            return Err(bad(
                "the section image has no pixel inside (none lighter than half)".into()
            ));
        }
        // Pixel size in normalised units: the square's side, 2, over the pixels across.
        let (px, py) = (2.0 / width as f64, 2.0 / height as f64);
        let to_in = edt(width, height, px, py, |i| inside[i]);
        let to_out = edt(width, height, px, py, |i| !inside[i]);
        // Between centres the boundary lies half a pixel from each: the distance to the
        // nearest centre of the other kind, less half the pixel (the smaller side).
        let half = 0.5 * px.min(py);
        let distance: Vec<f64> = (0..width * height)
            .map(|i| if inside[i] { -(to_out[i] - half) } else { to_in[i] - half })
            .collect();
        // One pass of the [1 2 1]/4 filter each way takes the edge off the mask's pixel
        // steps (it moves the boundary by less than half a pixel).
        let distance = smooth(width, height, &distance);
        Ok(SectionImage { width, height, distance, mask: inside.to_vec() })
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The signed distance (negative inside) from the section's boundary at `(x, y)` in the
    /// square's units (`x` right across the columns, `y` up the rows).
    pub fn distance(&self, x: f64, y: f64) -> f64 {
        let (cx, cy) = (x.clamp(-1.0, 1.0), y.clamp(-1.0, 1.0));
        let beyond = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
        // Pixel-centre coordinates: column c's centre is at x = −1 + (c + ½)·2/width.
        let fx = ((cx + 1.0) * 0.5 * self.width as f64 - 0.5).clamp(0.0, (self.width - 1) as f64);
        let fy = ((1.0 - cy) * 0.5 * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (c0, r0) =
            ((fx.floor() as usize).min(self.width - 2), (fy.floor() as usize).min(self.height - 2));
        let (tx, ty) = (fx - c0 as f64, fy - r0 as f64);
        // Catmull-Rom in both directions (C¹, so normals by differences are smooth),
        // neighbours beyond the border clamped to it.
        let at = |c: isize, r: isize| {
            let c = c.clamp(0, self.width as isize - 1) as usize;
            let r = r.clamp(0, self.height as isize - 1) as usize;
            self.distance[r * self.width + c]
        };
        let (wx, wy) = (catmull_rom(tx), catmull_rom(ty));
        let mut sum = 0.0;
        for (j, wyj) in wy.iter().enumerate() {
            let r = r0 as isize - 1 + j as isize;
            let row: f64 =
                wx.iter().enumerate().map(|(i, w)| w * at(c0 as isize - 1 + i as isize, r)).sum();
            sum += wyj * row;
        }
        sum + beyond
    }

    /// Whether pixel `(c, r)` (rows from the top) is inside the mask as given.
    pub fn inside(&self, c: usize, r: usize) -> bool {
        self.mask[r * self.width + c]
    }
}

/// The weights of the four Catmull-Rom nodes around a point a fraction `t` past the second.
fn catmull_rom(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// One pass of the `[1 2 1] / 4` filter along rows and columns, borders clamped.
fn smooth(width: usize, height: usize, d: &[f64]) -> Vec<f64> {
    let mut rows = vec![0.0; d.len()];
    for r in 0..height {
        for c in 0..width {
            let at = |c: usize| d[r * width + c];
            rows[r * width + c] =
                0.25 * at(c.saturating_sub(1)) + 0.5 * at(c) + 0.25 * at((c + 1).min(width - 1));
        }
    }
    let mut out = vec![0.0; d.len()];
    for r in 0..height {
        for c in 0..width {
            let at = |r: usize| rows[r * width + c];
            out[r * width + c] =
                0.25 * at(r.saturating_sub(1)) + 0.5 * at(r) + 0.25 * at((r + 1).min(height - 1));
        }
    }
    out
}

/// Euclidean distance from each pixel centre to the nearest centre where `target` holds,
/// pixels `px × py` (Felzenszwalb and Huttenlocher's two passes of lower parabolas).
fn edt(width: usize, height: usize, px: f64, py: f64, target: impl Fn(usize) -> bool) -> Vec<f64> {
    const FAR: f64 = 1e20;
    let mut d2: Vec<f64> = (0..width * height).map(|i| if target(i) { 0.0 } else { FAR }).collect();
    let mut line = Vec::new();
    let mut out = Vec::new();
    // Columns (along y), then rows (along x).
    for c in 0..width {
        line.clear();
        line.extend((0..height).map(|r| d2[r * width + c]));
        lower_envelope(&line, py, &mut out);
        for r in 0..height {
            d2[r * width + c] = out[r];
        }
    }
    for r in 0..height {
        line.clear();
        line.extend_from_slice(&d2[r * width..(r + 1) * width]);
        lower_envelope(&line, px, &mut out);
        d2[r * width..(r + 1) * width].copy_from_slice(&out);
    }
    d2.into_iter().map(f64::sqrt).collect()
}

/// `out[q] = min_p (f[p] + ((q − p)·step)²)`: the 1-D squared distance transform.
fn lower_envelope(f: &[f64], step: f64, out: &mut Vec<f64>) {
    let n = f.len();
    out.clear();
    out.resize(n, 0.0);
    let s2 = step * step;
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let cross = |q: usize, p: usize| -> f64 {
        let (q, p) = (q as f64, p as f64);
        ((f[q as usize] / s2 + q * q) - (f[p as usize] / s2 + p * p)) / (2.0 * (q - p))
    };
    for q in 1..n {
        let mut s = cross(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = cross(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let d = (q as f64 - v[k] as f64) * step;
        *o = d * d + f[v[k]];
    }
}

/// A cross-section swept along a cubic Bézier curve (see the module documentation).
#[derive(Clone, Debug)]
pub struct Sweep {
    curve: CubicCurve,
    /// Semi-axes `(a, b)` at each control point: `a` along the frame's normal, `b` along
    /// its binormal.
    radii: [[f64; 2]; 4],
    strength: f64,
    settings: SweepSettings,
    ts: Vec<f64>,
    frames: Vec<Frame>,
    /// Arc length at each sampled parameter.
    arc: Vec<f64>,
    lo: DVec3,
    hi: DVec3,
    max_radius: f64,
    /// The section's shape when it is an image; an ellipse otherwise.
    image: Option<std::sync::Arc<SectionImage>>,
}

/// Where a point lies relative to a sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepLocal {
    /// The curve parameter of the nearest point, in `[0, 1]`.
    pub t: f64,
    /// The frame at `t`.
    pub frame: Frame,
    /// Offset along the frame's normal.
    pub x: f64,
    /// Offset along the frame's binormal.
    pub y: f64,
    /// Offset along the tangent beyond an end (0 between the ends).
    pub s: f64,
    /// The section's semi-axes at `t`.
    pub radii: [f64; 2],
    /// The normalised distance `ρ` (1 on the surface).
    pub rho: f64,
}

impl Sweep {
    /// A sweep of an elliptical section with semi-axes `radii[i] = [a, b]` at Bézier control
    /// point `i` (`a` along the normal, `b` along the binormal); a circle when `a = b`.
    pub fn new(
        control: [DVec3; 4],
        radii: [[f64; 2]; 4],
        strength: f64,
        settings: SweepSettings,
    ) -> Result<Sweep, SkeletonError> {
        if control.iter().any(|c| !c.is_finite()) {
            return Err(SkeletonError::NonFinite);
        }
        for r in radii.iter().flatten() {
            if !(r.is_finite() && *r > 0.0) {
                return Err(SkeletonError::BadRadius(*r));
            }
        }
        if !(strength.is_finite() && strength > 0.0) {
            return Err(SkeletonError::BadStrength(strength));
        }
        if !(2..=1 << 16).contains(&settings.samples) {
            return Err(SkeletonError::BadParameter {
                name: "samples",
                value: settings.samples as f64,
                expected: "from 2 to 65536",
            });
        }
        if (control[3] - control[0]).length() + (control[1] - control[0]).length() == 0.0
            && (control[2] - control[0]).length() == 0.0
        {
            return Err(SkeletonError::ZeroLengthSegment(control[0].to_array()));
        }
        let curve = CubicCurve::bezier(control);
        let n = settings.samples;
        let ts: Vec<f64> = (0..n).map(|i| i as f64 / (n - 1) as f64).collect();
        let frames = curve.frames(&ts, settings.initial_normal);
        let mut arc = Vec::with_capacity(n);
        let mut len = 0.0;
        // Each interval's length by 8 chords, so the table is finer than the frames.
        for (i, &t) in ts.iter().enumerate() {
            if i > 0 {
                let t0 = ts[i - 1];
                let mut prev = curve.point(t0);
                for k in 1..=8 {
                    let q = curve.point(t0 + (t - t0) * k as f64 / 8.0);
                    len += (q - prev).length();
                    prev = q;
                }
            }
            arc.push(len);
        }
        if len <= 0.0 {
            return Err(SkeletonError::ZeroLengthSegment(control[0].to_array()));
        }
        let max_radius = radii.iter().flatten().fold(0.0_f64, |m, r| m.max(*r));
        // A Bézier curve lies in its control points' hull; a Bernstein blend of radii lies
        // within their range.
        let lo = control.iter().fold(control[0], |m, c| m.min(*c));
        let hi = control.iter().fold(control[0], |m, c| m.max(*c));
        Ok(Sweep {
            curve,
            radii,
            strength,
            settings,
            ts,
            frames,
            arc,
            lo,
            hi,
            max_radius,
            image: None,
        })
    }

    /// The same sweep with the section `image` in place of the ellipse, scaled by the
    /// semi-axes (see the module documentation).
    pub fn with_image(mut self, image: std::sync::Arc<SectionImage>) -> Sweep {
        self.image = Some(image);
        self
    }

    /// The section image, when the section is one.
    pub fn image(&self) -> Option<&SectionImage> {
        self.image.as_deref()
    }

    /// A circular section of radius `radii[i]` at control point `i`.
    pub fn circular(
        control: [DVec3; 4],
        radii: [f64; 4],
        strength: f64,
        settings: SweepSettings,
    ) -> Result<Sweep, SkeletonError> {
        Sweep::new(control, radii.map(|r| [r, r]), strength, settings)
    }

    /// The curve swept along.
    pub fn curve(&self) -> &CubicCurve {
        &self.curve
    }

    /// The settings it was built with.
    pub fn settings(&self) -> SweepSettings {
        self.settings
    }

    /// The largest semi-axis anywhere along the sweep.
    pub fn max_radius(&self) -> f64 {
        self.max_radius
    }

    /// The smallest semi-axis anywhere along the sweep.
    pub fn min_radius(&self) -> f64 {
        self.radii.iter().flatten().fold(f64::INFINITY, |m, r| m.min(*r))
    }

    /// The box of the curve widened by `reach` radii: outside it `ρ > reach`.
    pub fn bounds(&self, reach: f64) -> (DVec3, DVec3) {
        // An image's shape reaches the square's corners, √2 radii out, where the ellipse
        // reaches 1: `ρ = 1 + d` exceeds `reach` only beyond `reach + √2 − 1` radii.
        let reach =
            if self.image.is_some() { reach + std::f64::consts::SQRT_2 - 1.0 } else { reach };
        let w = DVec3::splat(reach * self.max_radius);
        (self.lo - w, self.hi + w)
    }

    /// The semi-axes at parameter `t`: the Bernstein blend of the control points' radii.
    pub fn radii_at(&self, t: f64) -> [f64; 2] {
        let u = 1.0 - t;
        let w = [u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t];
        let mut r = [0.0; 2];
        for (wi, ri) in w.iter().zip(&self.radii) {
            r[0] += wi * ri[0];
            r[1] += wi * ri[1];
        }
        r
    }

    /// The rotation-minimising frame at `t`: the sampled frames on either side turned onto
    /// the tangent at `t` by the smallest rotation, their normals then blended by angle
    /// about the tangent, so that the frame turns continuously with `t` (taking the nearer
    /// sample alone would twist the section by a step half-way between samples, which an
    /// image section's sharp corners show as slivers).
    pub fn frame_at(&self, t: f64) -> Frame {
        let t = t.clamp(0.0, 1.0);
        let x = t * (self.ts.len() - 1) as f64;
        let i = (x.floor() as usize).min(self.ts.len() - 2);
        let w = (x - i as f64).clamp(0.0, 1.0);
        let near = self.frames[if w < 0.5 { i } else { i + 1 }];
        let origin = self.curve.point(t);
        match self.curve.velocity(t).try_normalize() {
            Some(tangent) => {
                let turned = |f: &Frame| {
                    let rot = DQuat::from_rotation_arc(f.tangent, tangent);
                    (rot * f.normal).reject_from(tangent).try_normalize()
                };
                let normal = match (turned(&self.frames[i]), turned(&self.frames[i + 1])) {
                    (Some(n0), Some(n1)) => {
                        let angle = n0.cross(n1).dot(tangent).atan2(n0.dot(n1));
                        DQuat::from_axis_angle(tangent, w * angle) * n0
                    }
                    (Some(n), None) | (None, Some(n)) => n,
                    (None, None) => tangent.any_orthonormal_vector(),
                };
                Frame { origin, tangent, normal, binormal: tangent.cross(normal) }
            }
            None => Frame { origin, ..near },
        }
    }

    /// The arc-length fraction at `t`, in `[0, 1]`, increasing with `t`.
    pub fn arc_fraction(&self, t: f64) -> f64 {
        let t = t.clamp(0.0, 1.0);
        let x = t * (self.ts.len() - 1) as f64;
        let i = (x.floor() as usize).min(self.ts.len() - 2);
        let f = x - i as f64;
        let total = self.arc[self.arc.len() - 1];
        ((self.arc[i] + f * (self.arc[i + 1] - self.arc[i])) / total).clamp(0.0, 1.0)
    }

    /// The parameter of the curve point nearest `p`: the nearest sample, refined by Newton's
    /// method on `(C(t) − p)·C′(t) = 0` (kept only if it comes closer).
    pub fn nearest_t(&self, p: DVec3) -> f64 {
        let mut best = (f64::INFINITY, 0.0);
        for (f, &t) in self.frames.iter().zip(&self.ts) {
            let d2 = (f.origin - p).length_squared();
            if d2 < best.0 {
                best = (d2, t);
            }
        }
        let mut t = best.1;
        for _ in 0..8 {
            let d = self.curve.point(t) - p;
            let v = self.curve.velocity(t);
            let a = 6.0 * self.curve.c[0] * t + 2.0 * self.curve.c[1];
            let g = d.dot(v);
            let dg = v.length_squared() + d.dot(a);
            if dg <= 0.0 {
                break;
            }
            let next = (t - g / dg).clamp(0.0, 1.0);
            if (next - t).abs() < 1e-14 {
                t = next;
                break;
            }
            t = next;
        }
        if (self.curve.point(t) - p).length_squared() <= best.0 { t } else { best.1 }
    }

    /// `p` in the sweep's local coordinates (see the module documentation).
    pub fn locate(&self, p: DVec3) -> SweepLocal {
        let t = self.nearest_t(p);
        let frame = self.frame_at(t);
        let d = p - frame.origin;
        let along = d.dot(frame.tangent);
        let s = if (t <= 0.0 && along < 0.0) || (t >= 1.0 && along > 0.0) { along } else { 0.0 };
        let x = d.dot(frame.normal);
        let y = d.dot(frame.binormal);
        let radii = self.radii_at(t);
        let c = (radii[0] * radii[1]).sqrt();
        let section = match &self.image {
            None => ((x / radii[0]).powi(2) + (y / radii[1]).powi(2)).sqrt(),
            Some(im) => (1.0 + im.distance(x / radii[0], y / radii[1])).max(0.0),
        };
        let rho = if s == 0.0 {
            section
        } else if self.settings.caps {
            (section * section + (s / c).powi(2)).sqrt()
        } else {
            // Flat end: the intersection with the half-space beyond the end disc.
            1.0 + (section - 1.0).max(s.abs() / c)
        };
        SweepLocal { t, frame, x, y, s, radii, rho }
    }

    /// The normalised distance `ρ` at `p` (1 on the surface, less inside).
    pub fn rho(&self, p: DVec3) -> f64 {
        self.locate(p).rho
    }

    /// Texture coordinates (DIS §5.7) of `p` from the nearest curve point: `u` the arc-length
    /// fraction, `v` the angle around the section (from the normal toward the binormal, in
    /// the section's own ellipse parameter) as a fraction of a turn; both in `[0, 1]`.
    pub fn uv(&self, p: DVec3) -> [f64; 2] {
        let l = self.locate(p);
        let angle = (l.y / l.radii[1]).atan2(l.x / l.radii[0]);
        let v = (angle / std::f64::consts::TAU).rem_euclid(1.0);
        [self.arc_fraction(l.t), v.clamp(0.0, 1.0)]
    }

    /// A point inside the sweep, where a continuation polygonizer can start.
    pub fn seed_point(&self) -> DVec3 {
        self.curve.point(0.5)
    }
}

/// How a [`SweptField`] combines its sweeps with the skeleton.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// Add `w·k(ρ²)` to the density.
    Density(Kernel),
    /// Take `min(f, ρ − 1)`, `ρ` capped at `cap`.
    Union(f64),
}

/// A [`SkeletonField`] (or none) with [`Sweep`]s added (see the module documentation).
#[derive(Clone, Debug)]
pub struct SweptField {
    skeleton: Option<SkeletonField>,
    sweeps: Vec<Sweep>,
    boxes: Vec<(DVec3, DVec3)>,
    mode: Mode,
    blend: Blend,
    iso: f64,
    bounds: Aabb,
    step: f64,
}

/// Distance, in radii, beyond which a sweep is left out of a union (the skeleton's own cap).
const UNION_CAP: f64 = 2.0;

impl SweptField {
    /// `skeleton`'s field with `sweeps` added under `blend` (the skeleton's own blend when
    /// there is one; its iso value is kept).
    pub fn new(
        skeleton: Option<SkeletonField>,
        sweeps: Vec<Sweep>,
        blend: Blend,
    ) -> Result<SweptField, SkeletonError> {
        let blend = skeleton.as_ref().map_or(blend, |s| s.blend());
        blend.check()?;
        let iso = skeleton.as_ref().and_then(|s| s.iso()).unwrap_or(DEFAULT_ISO);
        if skeleton.is_none() && sweeps.is_empty() {
            return Err(SkeletonError::Empty);
        }
        let mode = match blend {
            Blend::Convolution(k) | Blend::Sum(k) => Mode::Density(k),
            _ => Mode::Union(UNION_CAP),
        };
        let reach = match mode {
            Mode::Density(k) => k.support(),
            Mode::Union(cap) => cap,
        };
        let boxes: Vec<(DVec3, DVec3)> = sweeps.iter().map(|s| s.bounds(reach)).collect();
        let mut bounds = skeleton.as_ref().and_then(|s| s.bounds());
        for &(min, max) in &boxes {
            let b = Aabb { min, max };
            bounds = Some(bounds.map_or(b, |x| x.union(&b)));
        }
        let step = sweeps
            .iter()
            .map(|s| 1e-4 * s.min_radius())
            .chain(skeleton.as_ref().map(|s| s.gradient_step()))
            .fold(f64::INFINITY, f64::min);
        Ok(SweptField {
            skeleton,
            sweeps,
            boxes,
            mode,
            blend,
            iso,
            bounds: bounds.ok_or(SkeletonError::Empty)?,
            step,
        })
    }

    /// The same field with another iso value (density blends; see
    /// [`SkeletonField::with_iso`]).
    pub fn with_iso(mut self, iso: f64) -> Result<SweptField, SkeletonError> {
        if let Some(s) = self.skeleton.take() {
            self.skeleton = Some(s.with_iso(iso)?);
        } else if !self.blend.has_iso() {
            return Err(SkeletonError::IsoNotApplicable(self.blend.name()));
        } else {
            crate::field::check_iso(iso)?;
        }
        self.iso = iso;
        Ok(self)
    }

    /// The iso value of a density blend, `None` for the distance blends.
    pub fn iso(&self) -> Option<f64> {
        match &self.skeleton {
            Some(s) => s.iso(),
            None => self.blend.has_iso().then_some(self.iso),
        }
    }

    /// The skeleton's field, without the sweeps.
    pub fn skeleton(&self) -> Option<&SkeletonField> {
        self.skeleton.as_ref()
    }

    /// The sweeps.
    pub fn sweeps(&self) -> &[Sweep] {
        &self.sweeps
    }

    /// Start points: the skeleton's, then one per sweep.
    pub fn seed_points(&self) -> Vec<DVec3> {
        let mut seeds = self.skeleton.as_ref().map_or_else(Vec::new, |s| s.seed_points());
        seeds.extend(self.sweeps.iter().map(Sweep::seed_point));
        seeds
    }

    /// Texture coordinates at `p` from the sweep whose surface is nearest (smallest `ρ`);
    /// `None` when no sweep reaches `p`.
    pub fn uv(&self, p: DVec3) -> Option<[f64; 2]> {
        let mut best: Option<(f64, usize)> = None;
        for (i, (s, b)) in self.sweeps.iter().zip(&self.boxes).enumerate() {
            if inside(b, p) {
                let rho = s.rho(p);
                if best.is_none_or(|(r, _)| rho < r) {
                    best = Some((rho, i));
                }
            }
        }
        best.map(|(_, i)| self.sweeps[i].uv(p))
    }
}

fn inside(b: &(DVec3, DVec3), p: DVec3) -> bool {
    p.cmpge(b.0).all() && p.cmple(b.1).all()
}

impl SweptField {
    /// Changes skeleton values `out` at `points` into the values with the sweeps added.
    fn add_sweeps(&self, points: &[DVec3], out: &mut [f64]) {
        for (p, o) in points.iter().zip(out.iter_mut()) {
            for (s, b) in self.sweeps.iter().zip(&self.boxes) {
                if !inside(b, *p) {
                    continue;
                }
                let rho = s.rho(*p);
                match self.mode {
                    Mode::Density(k) => *o -= s.strength * k.value(rho * rho),
                    Mode::Union(cap) => *o = o.min(rho.min(cap) - 1.0),
                }
            }
        }
    }

    /// The value far from everything: the iso value (density), or the union's cap.
    fn empty_value(&self) -> f64 {
        match self.mode {
            Mode::Density(_) => self.iso,
            Mode::Union(cap) => cap - 1.0,
        }
    }
}

/// Without sweeps every call goes to the skeleton's field (its culled batches and exact
/// gradients); with sweeps the skeleton's batch is taken first and the sweeps added to it.
impl Field for SweptField {
    fn eval(&self, p: DVec3) -> f64 {
        let mut v = [0.0];
        self.eval_many(&[p], &mut v);
        v[0]
    }

    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        match &self.skeleton {
            Some(s) => s.eval_many(points, out),
            None => out.fill(self.empty_value()),
        }
        self.add_sweeps(points, out);
    }

    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        match &self.skeleton {
            Some(s) => s.eval_layer(xs, ys, z, out),
            None => out.fill(self.empty_value()),
        }
        if !self.sweeps.is_empty() {
            let points: Vec<DVec3> =
                ys.iter().flat_map(|&y| xs.iter().map(move |&x| DVec3::new(x, y, z))).collect();
            self.add_sweeps(&points, out);
        }
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        match &self.skeleton {
            Some(s) if self.sweeps.is_empty() => s.gradient(p),
            _ => {
                let h = self.step;
                let d = |e: DVec3| (self.eval(p + e * h) - self.eval(p - e * h)) / (2.0 * h);
                DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z))
            }
        }
    }

    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        match &self.skeleton {
            Some(s) if self.sweeps.is_empty() => s.eval_grad_many(points, values, grads),
            _ => {
                self.eval_many(points, values);
                for (p, g) in points.iter().zip(grads.iter_mut()) {
                    *g = self.gradient(*p);
                }
            }
        }
    }

    fn gradient_step(&self) -> f64 {
        self.step
    }

    fn has_exact_gradient(&self) -> bool {
        self.sweeps.is_empty() && self.skeleton.as_ref().is_some_and(|s| s.has_exact_gradient())
    }

    fn bounds(&self) -> Option<Aabb> {
        Some(self.bounds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn horn() -> [DVec3; 4] {
        [
            DVec3::ZERO,
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 1.5, 0.5),
            DVec3::new(1.5, 0.5, 1.0),
        ]
    }

    #[test]
    fn circular_surface_is_one_radius_from_the_curve() {
        let r = [0.3, 0.25, 0.2, 0.1];
        let s = Sweep::circular(horn(), r, 1.0, SweepSettings::default()).unwrap();
        for i in 1..20 {
            let t = i as f64 / 20.0;
            let f = s.frame_at(t);
            let rt = s.radii_at(t)[0];
            for k in 0..8 {
                let a = k as f64 * std::f64::consts::TAU / 8.0;
                let dir = a.cos() * f.normal + a.sin() * f.binormal;
                let p = f.origin + rt * dir;
                assert!((s.rho(p) - 1.0).abs() < 1e-6, "t {t} angle {a}: {}", s.rho(p));
                assert!(s.rho(f.origin + 0.5 * rt * dir) < 1.0);
                assert!(s.rho(f.origin + 1.5 * rt * dir) > 1.0);
            }
        }
        // The hemispherical cap: one end radius beyond each end, along the tangent.
        let f0 = s.frame_at(0.0);
        assert!((s.rho(f0.origin - 0.3 * f0.tangent) - 1.0).abs() < 1e-9);
        let f1 = s.frame_at(1.0);
        assert!((s.rho(f1.origin + 0.1 * f1.tangent) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn ellipse_radii_lie_along_normal_and_binormal() {
        let radii = [[0.3, 0.1], [0.3, 0.1], [0.2, 0.08], [0.1, 0.05]];
        let s = Sweep::new(horn(), radii, 1.0, SweepSettings::default()).unwrap();
        for i in 1..10 {
            let t = i as f64 / 10.0;
            let f = s.frame_at(t);
            let [a, b] = s.radii_at(t);
            assert!((s.rho(f.origin + a * f.normal) - 1.0).abs() < 1e-6);
            assert!((s.rho(f.origin - b * f.binormal) - 1.0).abs() < 1e-6);
            assert!(s.rho(f.origin + a * f.binormal) > 1.5);
        }
    }

    #[test]
    fn frames_do_not_twist_on_a_planar_curve() {
        // An S-curve in the xy plane (with an inflection): the normal starting along z stays
        // along z, where a Frenet frame would flip.
        let c = [
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
        ];
        let settings = SweepSettings { initial_normal: Some(DVec3::Z), ..Default::default() };
        let s = Sweep::circular(c, [0.1; 4], 1.0, settings).unwrap();
        for i in 0..=100 {
            let f = s.frame_at(i as f64 / 100.0);
            assert!((f.normal - DVec3::Z).length() < 1e-9, "{:?}", f.normal);
            assert!(f.binormal.z.abs() < 1e-9);
        }
    }

    #[test]
    fn uv_in_range_and_u_monotone_along_the_curve() {
        let s = Sweep::circular(horn(), [0.2; 4], 1.0, SweepSettings::default()).unwrap();
        let mut last = -1.0;
        for i in 0..=50 {
            let t = i as f64 / 50.0;
            let f = s.frame_at(t);
            let [u, v] = s.uv(f.origin + 0.2 * f.binormal);
            assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v));
            assert!(u >= last, "u decreased at t {t}");
            assert!((v - 0.25).abs() < 1e-6, "v {v}");
            last = u;
        }
        assert!(last > 0.999);
        let f = s.frame_at(0.5);
        assert!(
            s.uv(f.origin + 0.2 * f.normal)[1].min(1.0 - s.uv(f.origin + 0.2 * f.normal)[1]) < 1e-6
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        let st = SweepSettings::default();
        assert!(Sweep::circular(horn(), [0.1, 0.0, 0.1, 0.1], 1.0, st).is_err());
        assert!(Sweep::circular(horn(), [0.1; 4], f64::NAN, st).is_err());
        assert!(Sweep::circular([DVec3::ONE; 4], [0.1; 4], 1.0, st).is_err());
        let few = SweepSettings { samples: 1, ..st };
        assert!(Sweep::circular(horn(), [0.1; 4], 1.0, few).is_err());
    }

    #[test]
    fn sweeps_blend_with_the_skeleton_under_convolution() {
        use crate::{GroupId, Kernel, Skeleton};
        let mut sk = Skeleton::new();
        sk.add_point(DVec3::new(1.5, 0.5, 1.0), 0.3, GroupId::DEFAULT).unwrap();
        let blend = Blend::Convolution(Kernel::Gaussian);
        let skf = SkeletonField::new(&sk, blend).unwrap();
        let s = Sweep::circular(horn(), [0.2; 4], 1.0, SweepSettings::default()).unwrap();
        let f = SweptField::new(Some(skf.clone()), vec![s.clone()], blend).unwrap();
        // Far from the point, the sweep alone: its surface at one radius.
        let fr = s.frame_at(0.2);
        assert!(f.eval(fr.origin + 0.2 * fr.normal).abs() < 1e-9);
        // At the point, the densities add.
        let p = DVec3::new(1.5, 0.5, 1.0) + DVec3::new(0.0, 0.0, 0.3);
        assert!(f.eval(p) < skf.eval(p) - 0.1);
        assert_eq!(f.seed_points().len(), 2);
        // Sweeps alone under a blend with a bad parameter are refused like a skeleton.
        let bad = Blend::SuperElliptic { range: -1.0, thumbweight: 2.0, angle_scaled: false };
        assert!(SweptField::new(None, vec![s.clone()], bad).is_err());
        // Under the union the value is the sweep's `ρ − 1`.
        let u = SweptField::new(None, vec![s], Blend::Union(crate::Falloff::Linear)).unwrap();
        assert!(u.eval(fr.origin + 0.2 * fr.normal).abs() < 1e-9);
        assert!((u.eval(fr.origin) + 1.0).abs() < 1e-9);
        assert!(u.iso().is_none());
    }
}
