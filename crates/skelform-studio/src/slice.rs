//! The field on a plane through the domain, for the page's colour map with the iso contour
//! (the planar display of the function in the dissertation's chapter 3).

use serde::Deserialize;
use skelform::DVec3;

use crate::StudioError;

/// The most samples along a side of a slice.
pub const MAX_SIZE: usize = 512;

/// Which plane: perpendicular to `axis` (0 x, 1 y, 2 z), at fraction `at` (0 to 1) of the
/// domain along it, sampled `size` times along its longer side.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
pub struct SliceSpec {
    /// The axis the plane is perpendicular to.
    pub axis: usize,
    /// Where along it, as a fraction of the domain.
    pub at: f64,
    /// Samples along the plane's longer side (default 160).
    #[serde(default = "default_size")]
    pub size: usize,
}

fn default_size() -> usize {
    160
}

impl SliceSpec {
    /// Refuses an axis other than 0, 1, 2, a position outside the domain, or a size outside
    /// 2 to [`MAX_SIZE`].
    pub fn check(&self) -> Result<(), StudioError> {
        if self.axis > 2 {
            return Err(StudioError::Edit(format!("slice axis {} (0, 1 or 2)", self.axis)));
        }
        if !(0.0..=1.0).contains(&self.at) {
            return Err(StudioError::Edit(format!("slice at {} (a fraction, 0 to 1)", self.at)));
        }
        if !(2..=MAX_SIZE).contains(&self.size) {
            return Err(StudioError::Edit(format!("slice size {} (2 to {MAX_SIZE})", self.size)));
        }
        Ok(())
    }
}

/// The plane's two in-plane axes for a normal axis.
fn plane_axes(axis: usize) -> (usize, usize) {
    match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// Samples the scene's field (the iso value subtracted: negative inside) on the plane and
/// encodes it as a binary frame (little-endian): `SKSL`, version (u32, 1), revision (u64),
/// axis (u32), columns W (u32), rows H (u32), 0 (u32); then f32 position along the axis,
/// f32 u0, u1 (the first in-plane axis's range), v0, v1 (the second's), 0; then W×H f32
/// values, row by row from v0.
pub fn frame(scene: &skelform::Scene, spec: &SliceSpec, revision: u64) -> Vec<u8> {
    let d = scene.domain;
    let (lo, hi) = (d.min.to_array(), d.max.to_array());
    let (ua, va) = plane_axes(spec.axis);
    let position = lo[spec.axis] + spec.at * (hi[spec.axis] - lo[spec.axis]);
    let (du, dv) = (hi[ua] - lo[ua], hi[va] - lo[va]);
    let longest = du.max(dv).max(f64::MIN_POSITIVE);
    let w = ((du / longest * spec.size as f64).round() as usize).clamp(2, MAX_SIZE);
    let h = ((dv / longest * spec.size as f64).round() as usize).clamp(2, MAX_SIZE);
    let mut points = Vec::with_capacity(w * h);
    for j in 0..h {
        for i in 0..w {
            let mut p = [0.0; 3];
            p[spec.axis] = position;
            p[ua] = lo[ua] + du * i as f64 / (w - 1) as f64;
            p[va] = lo[va] + dv * j as f64 / (h - 1) as f64;
            points.push(DVec3::from_array(p));
        }
    }
    let mut values = vec![0.0; points.len()];
    scene.field.eval_many(&points, &mut values);
    let mut out = Vec::with_capacity(56 + 4 * values.len());
    out.extend_from_slice(b"SKSL");
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&revision.to_le_bytes());
    // The sizes are at most MAX_SIZE: they fit u32.
    for n in [spec.axis as u32, w as u32, h as u32, 0] {
        out.extend_from_slice(&n.to_le_bytes());
    }
    for x in [position, lo[ua], hi[ua], lo[va], hi[va], 0.0] {
        out.extend_from_slice(&(x as f32).to_le_bytes());
    }
    for v in values {
        out.extend_from_slice(&(v as f32).to_le_bytes());
    }
    out
}
