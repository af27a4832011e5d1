//! Where the picture is taken from: a view direction, a projection, and a camera fitted so
//! that the mesh's bounding box fills the image.

/// The direction the camera looks from, in degrees, with `+z` up.
///
/// Azimuth 0 puts the camera on the `−y` side looking towards `+y` (`x` to the right, `z`
/// up, like a front view); positive azimuth turns the camera counter-clockwise about the
/// `z` axis seen from above, so azimuth 90 looks from `+x`. Elevation 0 is level, 90
/// looks straight down (then `+y` is up in the picture).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Degrees about `+z`, counter-clockwise seen from above; 0 looks from `−y`, 90 from `+x`.
    /// Any finite value (it wraps every 360).
    pub azimuth: f64,
    /// Degrees above the `xy` plane, −90 to 90: 0 is level, 90 looks straight down, −90 up
    /// from below.
    pub elevation: f64,
}

impl Default for View {
    /// A three-quarter view from the front right and a little above: shows the three axes
    /// of a box-shaped form and the hole of a torus lying in the `xy` plane.
    fn default() -> Self {
        View { azimuth: 30.0, elevation: 25.0 }
    }
}

/// How points are projected onto the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// A pinhole camera; `fov_degrees` is the angle across the shorter side of the image.
    Perspective {
        /// Full angle, in degrees, across the shorter side of the image: more than 0 and
        /// less than 170; smaller is more telephoto (the camera then stands farther back).
        fov_degrees: f64,
    },
    /// Parallel projection: sizes do not shrink with distance.
    Orthographic,
}

impl Default for Projection {
    /// A moderate telephoto: enough perspective to read depth, little distortion.
    fn default() -> Self {
        Projection::Perspective { fov_degrees: 30.0 }
    }
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn normalize(a: V3) -> V3 {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// A camera fitted to a box: an orthonormal frame, a distance, and the scale from camera
/// coordinates to pixels. Image coordinates are pixels, `x` to the right, `y` down, the
/// centre of pixel `(i, j)` at `(i + 0.5, j + 0.5)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The centre of the fitted box: the camera looks at it, and it projects to the centre
    /// of the image.
    pub target: V3,
    /// Unit vector from the camera into the scene.
    pub forward: V3,
    /// Unit vectors along the image's `x` (right) and up (against image `y`).
    pub right: V3,
    /// Unit vector up in the picture (against image `y`), `right × forward`; at elevation 0 it
    /// is `+z`.
    pub up: V3,
    /// Distance from the eye to `target` (perspective); for orthographic cameras, how far
    /// back the (notional) eye stands so that every point is in front of it.
    pub distance: f64,
    /// Perspective: pixels per unit of `x/z`; orthographic: pixels per world unit.
    pub scale: f64,
    /// Image width in pixels the camera was fitted for.
    pub width: u32,
    /// Image height in pixels the camera was fitted for.
    pub height: u32,
    /// The projection `scale` refers to.
    pub projection: Projection,
}

impl Camera {
    /// The frame for a view: `forward` from the eye towards the target, `right` and `up`
    /// spanning the image plane.
    fn frame(view: View) -> (V3, V3, V3) {
        let (az, el) = (view.azimuth.to_radians(), view.elevation.to_radians());
        // From the target towards the eye.
        let back = [az.sin() * el.cos(), -az.cos() * el.cos(), el.sin()];
        let forward = [-back[0], -back[1], -back[2]];
        let world_up = if el.cos().abs() < 1e-6 {
            // Looking straight down (or up): z is along the view; take the azimuth's own
            // "up" in the picture, which is +y at azimuth 0.
            [-az.sin() * el.sin().signum(), az.cos() * el.sin().signum(), 0.0]
        } else {
            [0.0, 0.0, 1.0]
        };
        let right = normalize(cross(forward, world_up));
        let up = cross(right, forward);
        (forward, right, up)
    }

    /// A camera looking from `view` at the box `lo..hi`, as close as it can be while every
    /// corner of the box lies inside the image with `margin` (a fraction of the half-width
    /// and half-height) to spare. The box's centre is the image's centre.
    pub fn fit(
        lo: [f32; 3],
        hi: [f32; 3],
        view: View,
        projection: Projection,
        width: u32,
        height: u32,
        margin: f64,
    ) -> Camera {
        Camera::fit_views(lo, hi, &[view], projection, width, height, margin).0
    }

    /// Cameras for several views of one box at one distance and scale (the largest any view
    /// needs), so that the form keeps its size from frame to frame, as in a turntable.
    pub(crate) fn fit_views(
        lo: [f32; 3],
        hi: [f32; 3],
        views: &[View],
        projection: Projection,
        width: u32,
        height: u32,
        margin: f64,
    ) -> (Camera, Vec<Camera>) {
        let lo = lo.map(f64::from);
        let hi = hi.map(f64::from);
        let target = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, (lo[2] + hi[2]) / 2.0];
        let radius = (dot(sub(hi, lo), sub(hi, lo)).sqrt() / 2.0).max(1e-12);
        let half_w = f64::from(width) / 2.0 * (1.0 - margin);
        let half_h = f64::from(height) / 2.0 * (1.0 - margin);
        let corners: Vec<V3> = (0..8)
            .map(|k| {
                let c = [
                    if k & 1 == 0 { lo[0] } else { hi[0] },
                    if k & 2 == 0 { lo[1] } else { hi[1] },
                    if k & 4 == 0 { lo[2] } else { hi[2] },
                ];
                sub(c, target)
            })
            .collect();
        let frames: Vec<(V3, V3, V3)> = views.iter().map(|v| Camera::frame(*v)).collect();
        let (distance, scale) = match projection {
            Projection::Perspective { fov_degrees } => {
                let short = f64::from(width.min(height)) / 2.0;
                let focal = short / (fov_degrees.to_radians() / 2.0).tan();
                // A corner at lateral offset x and depth offset z (towards the scene) lands
                // at focal·x/(d + z) from the centre; it fits when d ≥ focal·|x|/half − z.
                // The eye also stays a little in front of every corner.
                let mut d: f64 = 0.0;
                for (forward, right, up) in &frames {
                    for c in &corners {
                        let (x, y, z) = (dot(*c, *right), dot(*c, *up), dot(*c, *forward));
                        d = d
                            .max(focal * x.abs() / half_w - z)
                            .max(focal * y.abs() / half_h - z)
                            .max(0.01 * radius - z);
                    }
                }
                (d, focal)
            }
            Projection::Orthographic => {
                let mut s = f64::INFINITY;
                for (_, right, up) in &frames {
                    for c in &corners {
                        let (x, y) = (dot(*c, *right).abs(), dot(*c, *up).abs());
                        if x > 0.0 {
                            s = s.min(half_w / x);
                        }
                        if y > 0.0 {
                            s = s.min(half_h / y);
                        }
                    }
                }
                if !s.is_finite() {
                    s = half_w.min(half_h) / radius;
                }
                (2.0 * radius + 1.0, s)
            }
        };
        let cams: Vec<Camera> = frames
            .iter()
            .map(|&(forward, right, up)| Camera {
                target,
                forward,
                right,
                up,
                distance,
                scale,
                width,
                height,
                projection,
            })
            .collect();
        (cams[0], cams)
    }

    /// Where the eye is.
    pub fn eye(&self) -> V3 {
        let d = self.distance;
        [
            self.target[0] - d * self.forward[0],
            self.target[1] - d * self.forward[1],
            self.target[2] - d * self.forward[2],
        ]
    }

    /// For perspective cameras, the focal length in pixels (pixels per unit of `x/z`).
    pub fn focal_px(&self) -> f64 {
        self.scale
    }

    /// The same view for an image `factor` times larger in each direction (supersampling).
    pub(crate) fn scaled(&self, factor: u32) -> Camera {
        Camera {
            scale: self.scale * f64::from(factor),
            width: self.width * factor,
            height: self.height * factor,
            ..*self
        }
    }

    /// Camera coordinates of a point: `(x right, y up, z depth in front of the eye)`.
    pub fn to_camera(&self, p: V3) -> V3 {
        let q = sub(p, self.eye());
        [dot(q, self.right), dot(q, self.up), dot(q, self.forward)]
    }

    /// Image position `(x, y)` in pixels and depth in front of the eye, or `None` for a
    /// point at or behind the eye (perspective only).
    pub fn project(&self, p: V3) -> Option<[f64; 3]> {
        let [x, y, z] = self.to_camera(p);
        let (cx, cy) = (f64::from(self.width) / 2.0, f64::from(self.height) / 2.0);
        match self.projection {
            Projection::Perspective { .. } => {
                if z <= 0.0 {
                    return None;
                }
                Some([cx + self.scale * x / z, cy - self.scale * y / z, z])
            }
            Projection::Orthographic => Some([cx + self.scale * x, cy - self.scale * y, z]),
        }
    }

    /// The unit direction from the eye through image point `(x, y)`.
    pub fn ray(&self, x: f64, y: f64) -> V3 {
        match self.projection {
            Projection::Perspective { .. } => {
                let u = (x - f64::from(self.width) / 2.0) / self.scale;
                let v = -(y - f64::from(self.height) / 2.0) / self.scale;
                normalize([
                    self.forward[0] + u * self.right[0] + v * self.up[0],
                    self.forward[1] + u * self.right[1] + v * self.up[1],
                    self.forward[2] + u * self.right[2] + v * self.up[2],
                ])
            }
            Projection::Orthographic => self.forward,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_view_has_x_right_and_z_up() {
        let (f, r, u) = Camera::frame(View { azimuth: 0.0, elevation: 0.0 });
        assert!((f[1] - 1.0).abs() < 1e-12);
        assert!((r[0] - 1.0).abs() < 1e-12);
        assert!((u[2] - 1.0).abs() < 1e-12);
        let (f, r, u) = Camera::frame(View { azimuth: 90.0, elevation: 0.0 });
        assert!((f[0] + 1.0).abs() < 1e-12, "{f:?}");
        assert!((r[1] - 1.0).abs() < 1e-12, "{r:?}");
        assert!((u[2] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn top_view_has_y_up() {
        let (f, r, u) = Camera::frame(View { azimuth: 0.0, elevation: 90.0 });
        assert!((f[2] + 1.0).abs() < 1e-12, "{f:?}");
        assert!((r[0] - 1.0).abs() < 1e-9, "{r:?}");
        assert!((u[1] - 1.0).abs() < 1e-9, "{u:?}");
    }

    #[test]
    fn fitted_box_corners_are_inside_the_image() {
        for projection in [Projection::default(), Projection::Orthographic] {
            for az in [0.0, 30.0, 77.0, 200.0] {
                for el in [-60.0, 0.0, 25.0, 90.0] {
                    let (lo, hi) = ([-1.0, -0.5, -0.2], [2.0, 0.5, 0.3]);
                    let view = View { azimuth: az, elevation: el };
                    let cam = Camera::fit(lo, hi, view, projection, 300, 200, 0.1);
                    let mut touches = false;
                    for k in 0..8 {
                        let c = [
                            if k & 1 == 0 { lo[0] } else { hi[0] },
                            if k & 2 == 0 { lo[1] } else { hi[1] },
                            if k & 4 == 0 { lo[2] } else { hi[2] },
                        ]
                        .map(f64::from);
                        let [x, y, z] = cam.project(c).expect("in front");
                        assert!(z > 0.0 || projection == Projection::Orthographic);
                        assert!((15.0 - 1e-6..=285.0 + 1e-6).contains(&x), "{x} at {az},{el}");
                        assert!((10.0 - 1e-6..=190.0 + 1e-6).contains(&y), "{y} at {az},{el}");
                        touches |= (x - 15.0).abs() < 1e-6
                            || (x - 285.0).abs() < 1e-6
                            || (y - 10.0).abs() < 1e-6
                            || (y - 190.0).abs() < 1e-6;
                    }
                    assert!(touches, "the fit is tight at {az},{el}");
                }
            }
        }
    }
}
