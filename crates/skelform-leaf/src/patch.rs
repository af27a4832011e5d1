//! A bicubic patch and the chapter's blend of a bump to it (dissertation §4.8.4), as a
//! region function for the non-manifold polygonizer.
//!
//! Why here: the patch blend is a *form* made of a sheet, not a field. Its regions (beyond
//! the border, the bump, the two sides) are decided by the nearest point on a parametric
//! sheet, exactly as the leaf's blade decides beyond, above and below
//! ([`crate::regions`] is the chapter 7 descendant of this blend). So it sits with the
//! leaf, beside the other built-in region function, and `skelform-field` keeps only what
//! every region function shares ([`RegionField`], `OrderedRegions`, which may put a
//! [`PatchBlend`] behind a scene's region formulas).
//!
//! ```
//! use skelform_field::{DVec3, RegionField};
//! use skelform_leaf::patch::{BicubicPatch, PatchBlend};
//!
//! let patch = BicubicPatch::over_square(|x, y| 0.15 * (x * x - y * y));
//! let blend = PatchBlend { centre: patch.centre(), patch, radius: 0.7, height: 0.35 };
//! assert_eq!(blend.region(DVec3::new(0.0, 0.0, 0.1)), 1); // in the bump
//! assert_eq!(blend.region(DVec3::new(0.8, 0.0, 0.5)), 2); // above the patch
//! assert_eq!(blend.region(DVec3::new(2.0, 0.0, 0.0)), 0); // beyond its border
//! ```

use glam::DVec3;
use skelform_field::RegionField;

/// A bicubic Bézier (tensor-product) patch, `P(s, t) = Σ Bᵢ(s) Bⱼ(t) Pᵢⱼ` over
/// `[0, 1]²`, with the nearest point to a point of space (dissertation §4.8.4).
#[derive(Clone, Debug, PartialEq)]
pub struct BicubicPatch {
    /// `control[i][j]` multiplies `Bᵢ(s) Bⱼ(t)`.
    pub control: [[DVec3; 4]; 4],
    /// The start points of the nearest-point search: `P` at `(i/n, j/n)`, the vertices of
    /// the chapter's approximating mesh (n = 7: 98 triangles).
    starts: Vec<(f64, f64, DVec3)>,
}

/// Where a point projects onto a [`BicubicPatch`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// The nearest point's first parameter, in `[0, 1]`; at an end when `p` lies beyond
    /// that edge of the patch.
    pub s: f64,
    /// The second parameter, likewise.
    pub t: f64,
    /// The nearest point `P(s, t)`.
    pub point: DVec3,
    /// The unit normal `Pₛ × Pₜ` there.
    pub normal: DVec3,
    /// Signed distance from the nearest point along the normal.
    pub distance: f64,
}

impl BicubicPatch {
    /// The patch with these control points (rows along `s`, points in a row along `t`);
    /// also tabulates the start points of [`BicubicPatch::project`].
    pub fn new(control: [[DVec3; 4]; 4]) -> Self {
        let mut patch = BicubicPatch { control, starts: Vec::new() };
        let n = 7;
        for i in 0..=n {
            for j in 0..=n {
                let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
                let p = patch.eval(s, t)[0];
                patch.starts.push((s, t, p));
            }
        }
        patch
    }

    /// The patch whose control points are `(x, y, height(x, y))` on the 4 × 4 lattice over
    /// [-1, 1]² (s along x, t along y): a height field, the usual way to write one down.
    pub fn over_square(height: impl Fn(f64, f64) -> f64) -> Self {
        let at = |k: usize| -1.0 + 2.0 * k as f64 / 3.0;
        BicubicPatch::new(std::array::from_fn(|i| {
            std::array::from_fn(|j| DVec3::new(at(i), at(j), height(at(i), at(j))))
        }))
    }

    /// The patch's centre, `P(½, ½)`: where the bump of a [`PatchBlend`] sits by default.
    pub fn centre(&self) -> DVec3 {
        self.eval(0.5, 0.5)[0]
    }

    /// `[P, Pₛ, Pₜ]` at `(s, t)`.
    pub fn eval(&self, s: f64, t: f64) -> [DVec3; 3] {
        let basis = |u: f64| {
            let v = 1.0 - u;
            (
                [v * v * v, 3.0 * u * v * v, 3.0 * u * u * v, u * u * u],
                [-3.0 * v * v, 3.0 * v * v - 6.0 * u * v, 6.0 * u * v - 3.0 * u * u, 3.0 * u * u],
            )
        };
        let ((bs, ds), (bt, dt)) = (basis(s), basis(t));
        let mut out = [DVec3::ZERO; 3];
        for i in 0..4 {
            for j in 0..4 {
                let c = self.control[i][j];
                out[0] += c * (bs[i] * bt[j]);
                out[1] += c * (ds[i] * bt[j]);
                out[2] += c * (bs[i] * dt[j]);
            }
        }
        out
    }

    /// The nearest point of the patch to `p`: from the nearest vertex of the approximating
    /// mesh, the vector from `P(s, t)` to `p` is projected onto the tangent plane (a
    /// Gauss-Newton step in `s, t`) until the step is below `1e-9` (the chapter stops at
    /// `1e-3`; the polygonizer's ε needs more), with `s, t` kept in `[0, 1]`.
    pub fn project(&self, p: DVec3) -> Projection {
        let (mut s, mut t, _) = self
            .starts
            .iter()
            .copied()
            .min_by(|a, b| a.2.distance_squared(p).total_cmp(&b.2.distance_squared(p)))
            .unwrap_or((0.5, 0.5, DVec3::ZERO));
        for _ in 0..32 {
            let [q, ps, pt] = self.eval(s, t);
            let d = p - q;
            let (a, b, c) = (ps.dot(ps), ps.dot(pt), pt.dot(pt));
            let det = a * c - b * b;
            if det.abs() < 1e-300 {
                break;
            }
            let (rs, rt) = (d.dot(ps), d.dot(pt));
            let ds = (c * rs - b * rt) / det;
            let dt = (a * rt - b * rs) / det;
            let (ns, nt) = ((s + ds).clamp(0.0, 1.0), (t + dt).clamp(0.0, 1.0));
            let done = (ns - s).abs() < 1e-9 && (nt - t).abs() < 1e-9;
            (s, t) = (ns, nt);
            if done {
                break;
            }
        }
        let [q, ps, pt] = self.eval(s, t);
        let normal = ps.cross(pt).normalize_or_zero();
        Projection { s, t, point: q, normal, distance: (p - q).dot(normal) }
    }
}

/// The chapter's blend of a sphere to a bicubic patch (§4.8.4), a variation on the saucer:
/// region 0 beyond the patch (the nearest point has `s` or `t` within `.001` of its ends),
/// 1 where `bump(p) = height · Sigmoid(|p − centre| / radius) > |distance to the patch|`, 2
/// on the normal's side of the patch, 3 on the other. `Sigmoid(d) = 1 − (4d⁶ − 17d⁴ +
/// 22d²)/9` for `|d| ≤ 1`, else 0 (the saucer's, from Wyvill et al.). Per-pair gradients:
/// `(2, 3)` the patch normal, `(1, 2)` that of `distance − bump`, `(1, 3)` that of
/// `−distance − bump`.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchBlend {
    /// The sheet the bump sits on; its normal side is region 2.
    pub patch: BicubicPatch,
    /// Where the bump is highest (usually [`BicubicPatch::centre`]).
    pub centre: DVec3,
    /// How far from `centre` the bump reaches: beyond it the sigmoid is 0 and only the
    /// patch separates regions 2 and 3.
    pub radius: f64,
    /// The bump's height at `centre`, in the distance to the patch it claims.
    pub height: f64,
}

impl PatchBlend {
    fn sigmoid(d: f64) -> (f64, f64) {
        if d.abs() > 1.0 {
            (0.0, 0.0)
        } else {
            let (d2, d4) = (d * d, d.powi(4));
            (
                1.0 - (4.0 * d4 * d2 - 17.0 * d4 + 22.0 * d2) / 9.0,
                -(24.0 * d4 * d - 68.0 * d2 * d + 44.0 * d) / 9.0,
            )
        }
    }

    /// The bump's height and gradient at `p`.
    pub fn bump(&self, p: DVec3) -> (f64, DVec3) {
        let r = p - self.centre;
        let len = r.length();
        let (v, dv) = Self::sigmoid(len / self.radius);
        let grad = if len > 0.0 { r / len * (self.height * dv / self.radius) } else { DVec3::ZERO };
        (self.height * v, grad)
    }
}

impl RegionField for PatchBlend {
    fn region(&self, p: DVec3) -> u32 {
        let pr = self.patch.project(p);
        let beyond = |u: f64| !(0.001..=0.999).contains(&u);
        if beyond(pr.s) || beyond(pr.t) {
            0
        } else if self.bump(p).0 > pr.distance.abs() {
            1
        } else if pr.distance > 0.0 {
            2
        } else {
            3
        }
    }

    fn region_ids(&self) -> Option<Vec<u32>> {
        Some(vec![0, 1, 2, 3])
    }

    fn gradient(&self, p: DVec3, pair: (u32, u32)) -> Option<DVec3> {
        let n = self.patch.project(p).normal;
        let (_, db) = self.bump(p);
        match pair {
            (2, 3) => Some(n),
            (1, 2) => Some(n - db),
            (1, 3) => Some(-n - db),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flat patch z = 0 over [-1, 1]², with the saucer's bump at its centre.
    fn flat_blend() -> PatchBlend {
        let patch = BicubicPatch::over_square(|_, _| 0.0);
        assert!(patch.centre().length() < 1e-12, "{}", patch.centre());
        PatchBlend { patch, centre: DVec3::ZERO, radius: 0.5, height: 0.3 }
    }

    #[test]
    fn a_patch_blend_has_the_chapters_four_regions() {
        let b = flat_blend();
        assert_eq!(b.region(DVec3::new(0.0, 0.0, 0.1)), 1, "inside the bump");
        assert_eq!(b.region(DVec3::new(0.0, 0.0, -0.1)), 1, "the bump is on both sides");
        assert_eq!(b.region(DVec3::new(0.7, 0.0, 0.1)), 2, "above, past the bump");
        assert_eq!(b.region(DVec3::new(0.7, 0.0, -0.1)), 3, "below");
        assert_eq!(b.region(DVec3::new(1.2, 0.0, 0.1)), 0, "beyond the border");
        // The normal is +z (Pₛ × Pₜ with s along x, t along y): region 2 is on its side.
        assert_eq!(b.gradient(DVec3::new(0.7, 0.2, 0.1), (2, 3)), Some(DVec3::Z));
        assert_eq!(b.gradient(DVec3::new(0.7, 0.2, 0.1), (0, 2)), None);
    }

    #[test]
    fn the_nearest_point_on_a_patch_is_where_the_offset_is_normal() {
        // A curved patch over [-1, 1]²: the offset from the nearest point is along the normal
        // and no sample of the patch is nearer.
        let control = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let (x, y) = (-1.0 + 2.0 * i as f64 / 3.0, -1.0 + 2.0 * j as f64 / 3.0);
                DVec3::new(x, y, 0.3 * (x * x - y * y) + 0.1 * x)
            })
        });
        let patch = BicubicPatch::new(control);
        for k in 0..50 {
            let p = DVec3::new(
                (k as f64 * 0.37).sin() * 0.8,
                (k as f64 * 0.71).cos() * 0.8,
                (k as f64 * 0.13).sin() * 0.5,
            );
            let pr = patch.project(p);
            let [_, ps, pt] = patch.eval(pr.s, pr.t);
            let off = p - pr.point;
            if (0.01..0.99).contains(&pr.s) && (0.01..0.99).contains(&pr.t) {
                assert!(off.dot(ps).abs() < 1e-7 && off.dot(pt).abs() < 1e-7, "{k}: {pr:?}");
                assert!((off.length() - pr.distance.abs()).abs() < 1e-9);
            }
            for i in 0..=40 {
                for j in 0..=40 {
                    let q = patch.eval(i as f64 / 40.0, j as f64 / 40.0)[0];
                    assert!(q.distance(p) >= off.length() - 1e-9, "{k}: nearer sample");
                }
            }
        }
    }
}
