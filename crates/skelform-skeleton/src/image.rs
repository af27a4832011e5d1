//! The raster-image polygon method of DIS §6.2 and appendix A.3, kept as an option beside
//! the exact integral of [`crate::convolution`].
//!
//! The dissertation convolves a polygon by precomputing, once per polygon, a *convolution
//! image*: the polygon is rasterized in its own plane, the raster is filtered with the
//! kernel's in-plane factor, and a query point `p` is answered by a bilinear lookup at its
//! projection times the kernel of its distance to the plane (eqs. 6.1–6.3):
//! `f = c − h(z)·I(p_xy)`. That is exact for the Gaussian, which is separable; for the
//! other kernels it is the dissertation's separable approximation (§5.6.11). The image box
//! is the polygon's bounds widened by the kernel's support on every side (appendix A.3
//! widens by the filter extent), and `resolution` is the number of pixels across the longer
//! side of that box (default 80, the dissertation's trapezoid-and-rectangle demo; it
//! reports artifacts below 40×40, fig. 6.3).
//!
//! Our raster records each pixel's coverage (4 × 4 samples per pixel rather than one),
//! stores `f64` (the 1991 images were 8-bit and showed steps), and the gradient is the exact
//! derivative of the bilinear interpolant. What remains is the method's own error: the
//! polygon's edges are known only to a fraction of a pixel and the filtered image is
//! interpolated linearly between pixels, so the error falls roughly with the square of the
//! pixel size (measured in `tests/image.rs`).

use glam::{DVec2, DVec3};

use crate::SkeletonError;
use crate::geometry::Polygon;
use crate::kernel::{Kernel, OMEGA};

/// The image method's default resolution: pixels across the longer side of the image box.
pub const DEFAULT_IMAGE_RESOLUTION: usize = 80;

/// The largest resolution accepted: the image and its filter grow with its square (and,
/// for the non-separable kernels, the filter with its fourth power).
pub const MAX_IMAGE_RESOLUTION: usize = 1024;

/// Sub-samples per pixel side when rasterizing.
const SUBSAMPLES: usize = 4;

/// How a polygon's convolution is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum PolygonMethod {
    /// The exact area integral ([`crate::convolution`]): no raster, no artifacts.
    #[default]
    Exact,
    /// The dissertation's filtered raster image, `resolution` pixels across.
    Image {
        /// Pixels across the longer side of the image box (the polygon's bounds widened by
        /// the kernel's support), 4 ..= [`MAX_IMAGE_RESOLUTION`]; cost grows with its
        /// square and the error roughly falls with it squared. Default
        /// [`DEFAULT_IMAGE_RESOLUTION`].
        resolution: usize,
    },
}

impl PolygonMethod {
    pub(crate) fn check(&self) -> Result<(), SkeletonError> {
        match *self {
            PolygonMethod::Image { resolution }
                if !(4..=MAX_IMAGE_RESOLUTION).contains(&resolution) =>
            {
                Err(SkeletonError::BadImageResolution(resolution))
            }
            _ => Ok(()),
        }
    }
}

/// The most pixel operations (rasterizing plus filtering, summed over every image polygon of
/// a skeleton) that building a field may take: about ten seconds of one core. The filter of
/// the non-separable kernels grows with the fourth power of the resolution, so a handful of
/// polygons at the largest resolution would otherwise run for hours before the first sample.
pub const MAX_IMAGE_WORK: u64 = 10_000_000_000;

/// The most bytes of convolution images a field may hold (all image polygons together).
pub const MAX_IMAGE_BYTES: u64 = 1 << 30;

/// Where a polygon's image lies and how finely it is sampled, known before any pixel is
/// touched, so that the cost of the whole skeleton can be refused up front.
struct Raster {
    /// The polygon's vertices in radii, plane frame.
    flat: Vec<DVec2>,
    /// Position of node (0, 0), in radii.
    lo: DVec2,
    /// Pixel size, in radii.
    px: f64,
    nx: usize,
    ny: usize,
    /// The filter's half-width in pixels.
    reach: isize,
}

impl Raster {
    fn new(kernel: Kernel, poly: &Polygon, radius: f64, resolution: usize) -> Raster {
        let flat: Vec<DVec2> = poly.flat_vertices().iter().map(|v| *v / radius).collect();
        let (mut lo, mut hi) = flat
            .iter()
            .fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        let margin = kernel.support();
        lo -= DVec2::splat(margin);
        hi += DVec2::splat(margin);
        let size = hi - lo;
        let px = size.max_element() / resolution as f64;
        // At most resolution + 1 nodes along the longer side, fewer along the other.
        let nx = (size.x / px).ceil() as usize + 1;
        let ny = (size.y / px).ceil() as usize + 1;
        let reach = (kernel.support() / px).ceil() as isize;
        Raster { flat, lo, px, nx, ny, reach }
    }

    /// Pixel operations to build the image: 16 coverage samples per pixel, each testing
    /// every edge, then the filter (two passes of the 1-D kernel for the separable Gaussian,
    /// the 2-D kernel scattered from every pixel otherwise; an upper bound, since empty
    /// pixels are skipped).
    fn work(&self, kernel: Kernel) -> u64 {
        let pixels = (self.nx as u64).saturating_mul(self.ny as u64);
        let side = 2 * self.reach.unsigned_abs() as u64 + 1;
        let cover =
            pixels.saturating_mul((SUBSAMPLES * SUBSAMPLES) as u64 * self.flat.len() as u64);
        let filter = if kernel == Kernel::Gaussian {
            pixels.saturating_mul(2 * side)
        } else {
            pixels.saturating_mul(side.saturating_mul(side))
        };
        cover.saturating_add(filter)
    }

    /// Bytes held while the image is built (coverage, a row pass, the image).
    fn bytes(&self) -> u64 {
        (self.nx as u64).saturating_mul(self.ny as u64).saturating_mul(3 * 8)
    }
}

/// Refuses a skeleton whose image polygons (under `kernel`) would together take more than
/// [`MAX_IMAGE_WORK`] pixel operations or [`MAX_IMAGE_BYTES`] of images to build, before
/// any is built. `polygons` gives each image polygon with its radius and resolution.
pub(crate) fn check_budget<'a>(
    kernel: Kernel,
    polygons: impl Iterator<Item = (&'a Polygon, f64, usize)>,
) -> Result<(), SkeletonError> {
    let (mut work, mut bytes, mut count) = (0u64, 0u64, 0usize);
    for (poly, radius, resolution) in polygons {
        let r = Raster::new(kernel, poly, radius, resolution);
        work = work.saturating_add(r.work(kernel));
        bytes = bytes.saturating_add(r.bytes());
        count += 1;
    }
    if work > MAX_IMAGE_WORK || bytes > MAX_IMAGE_BYTES {
        return Err(SkeletonError::ImageWorkTooLarge { polygons: count, work, bytes });
    }
    Ok(())
}

/// A polygon's convolution image, ready for lookups.
#[derive(Clone, Debug)]
pub(crate) struct ImagePolygon {
    origin: DVec3,
    e1: DVec3,
    e2: DVec3,
    n: DVec3,
    /// Position of node (0, 0), in radii in the plane frame.
    min: DVec2,
    inv_px: f64,
    nx: usize,
    ny: usize,
    /// Filtered image, row-major (`ny` rows of `nx` nodes).
    data: Vec<f64>,
    inv_r: f64,
    /// `strength / ∫_{ℝ²} k`.
    scale: f64,
}

impl ImagePolygon {
    pub(crate) fn new(
        kernel: Kernel,
        poly: &Polygon,
        radius: f64,
        strength: f64,
        resolution: usize,
        weight: Option<&dyn Fn(DVec2) -> f64>,
    ) -> Self {
        let (e1, e2, n) = poly.frame();
        let Raster { flat, lo, px, nx, ny, reach } = Raster::new(kernel, poly, radius, resolution);

        // Coverage of the pixel around each node.
        let mut cover = vec![0.0; nx * ny];
        let step = px / SUBSAMPLES as f64;
        let inv_samples = 1.0 / (SUBSAMPLES * SUBSAMPLES) as f64;
        for j in 0..ny {
            for i in 0..nx {
                let corner = lo + DVec2::new(i as f64 - 0.5, j as f64 - 0.5) * px;
                // Each sample inside counts its weight (DIS §6.4: the polygon is rendered
                // with its weights before it is filtered), 1 without weights.
                let mut inside = 0.0;
                for sj in 0..SUBSAMPLES {
                    for si in 0..SUBSAMPLES {
                        let q = corner + DVec2::new(si as f64 + 0.5, sj as f64 + 0.5) * step;
                        if even_odd(&flat, q) {
                            inside += weight.map_or(1.0, |w| w(q * radius));
                        }
                    }
                }
                cover[j * nx + i] = inside * inv_samples;
            }
        }

        // Filter: the kernel of the in-plane distance, times the pixel's area.
        let mut data = vec![0.0; nx * ny];
        let area = px * px;
        if kernel == Kernel::Gaussian {
            // Separable: rows, then columns.
            let k1: Vec<f64> =
                (0..=reach).map(|d| (-OMEGA * (d as f64 * px).powi(2)).exp()).collect();
            let mut rows = vec![0.0; nx * ny];
            for j in 0..ny {
                for i in 0..nx {
                    let mut s = 0.0;
                    for a in (i as isize - reach).max(0)..=(i as isize + reach).min(nx as isize - 1)
                    {
                        s += cover[j * nx + a as usize] * k1[(a - i as isize).unsigned_abs()];
                    }
                    rows[j * nx + i] = s;
                }
            }
            for j in 0..ny {
                for i in 0..nx {
                    let mut s = 0.0;
                    for b in (j as isize - reach).max(0)..=(j as isize + reach).min(ny as isize - 1)
                    {
                        s += rows[b as usize * nx + i] * k1[(b - j as isize).unsigned_abs()];
                    }
                    data[j * nx + i] = s * area;
                }
            }
        } else {
            let side = 2 * reach as usize + 1;
            let mut k2 = vec![0.0; side * side];
            for dj in -reach..=reach {
                for di in -reach..=reach {
                    let s2 = ((di * di + dj * dj) as f64) * px * px;
                    k2[(dj + reach) as usize * side + (di + reach) as usize] = kernel.value(s2);
                }
            }
            for j in 0..ny {
                for i in 0..nx {
                    let c = cover[j * nx + i];
                    if c == 0.0 {
                        continue;
                    }
                    // Scatter this pixel's coverage onto its neighbours.
                    for dj in -reach..=reach {
                        let b = j as isize + dj;
                        if b < 0 || b >= ny as isize {
                            continue;
                        }
                        let row = &k2[(dj + reach) as usize * side..][..side];
                        for di in -reach..=reach {
                            let a = i as isize + di;
                            if a < 0 || a >= nx as isize {
                                continue;
                            }
                            data[b as usize * nx + a as usize] +=
                                c * row[(di + reach) as usize] * area;
                        }
                    }
                }
            }
        }
        ImagePolygon {
            origin: poly.origin(),
            e1,
            e2,
            n,
            min: lo,
            inv_px: 1.0 / px,
            nx,
            ny,
            data,
            inv_r: 1.0 / radius,
            scale: strength / (std::f64::consts::TAU * kernel.tail(0.0)),
        }
    }

    /// The image's bilinear interpolant at `q` (radii, plane frame) and its gradient; 0
    /// outside the image.
    fn lookup(&self, q: DVec2) -> (f64, DVec2) {
        let u = (q - self.min) * self.inv_px;
        if !(u.x >= 0.0 && u.y >= 0.0) {
            return (0.0, DVec2::ZERO);
        }
        let (i, j) = (u.x.floor() as usize, u.y.floor() as usize);
        if i + 1 >= self.nx || j + 1 >= self.ny {
            return (0.0, DVec2::ZERO);
        }
        let (fx, fy) = (u.x - i as f64, u.y - j as f64);
        let at = |a: usize, b: usize| self.data[b * self.nx + a];
        let (v00, v10, v01, v11) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        let bottom = v00 + fx * (v10 - v00);
        let top = v01 + fx * (v11 - v01);
        let v = bottom + fy * (top - bottom);
        let dx = (v10 - v00) + fy * ((v11 - v01) - (v10 - v00));
        let dy = top - bottom;
        (v, DVec2::new(dx, dy) * self.inv_px)
    }

    pub(crate) fn eval(&self, kernel: Kernel, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        let w = (p - self.origin) * self.inv_r;
        let q = DVec2::new(w.dot(self.e1), w.dot(self.e2));
        let z = w.dot(self.n);
        let (img, dimg) = self.lookup(q);
        if img == 0.0 && dimg == DVec2::ZERO {
            return (0.0, DVec3::ZERO);
        }
        let (kz, dkz) = kernel.value_d(z * z);
        let v = self.scale * kz * img;
        if !want_grad {
            return (v, DVec3::ZERO);
        }
        let gq = dimg * kz;
        let gz = 2.0 * z * dkz * img;
        let g = gq.x * self.e1 + gq.y * self.e2 + gz * self.n;
        (v, g * (self.scale * self.inv_r))
    }
}

/// Whether `q` is inside the polygon `v` (even–odd rule; the polygon is simple).
fn even_odd(v: &[DVec2], q: DVec2) -> bool {
    let mut inside = false;
    let k = v.len();
    for i in 0..k {
        let (a, b) = (v[i], v[(i + 1) % k]);
        if (a.y > q.y) != (b.y > q.y) {
            let x = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if q.x < x {
                inside = !inside;
            }
        }
    }
    inside
}
