//! Region functions: space divided into numbered regions, for non-manifold polygonization.
//!
//! Where a [`Field`](crate::Field) says inside or outside, a [`RegionField`] says *which*
//! region a point is in (dissertation ch. 4). The surfaces between chosen pairs of regions
//! meet along curves where three or more regions meet.

use glam::DVec3;

use crate::Field;

/// A map from points to region ids.
///
/// Implementations must be deterministic and thread-safe, like fields.
pub trait RegionField: Send + Sync {
    /// The region of one point.
    fn region(&self, p: DVec3) -> u32;

    /// Regions of many points: `out[i] = region(points[i])`.
    fn region_many(&self, points: &[DVec3], out: &mut [u32]) {
        for (p, o) in points.iter().zip(out.iter_mut()) {
            *o = self.region(*p);
        }
    }

    /// Every region id this function can return, when it knows them (for checking that the
    /// pairs a client asks for exist).
    fn region_ids(&self) -> Option<Vec<u32>> {
        None
    }

    /// The chapter's `Gradient(p, pair)`: the gradient at `p` of a real function that is
    /// continuous near the surface between regions `pair.0 < pair.1` and zero on it (or
    /// any function whose gradient is normal to that surface), for vertex normals. `None`
    /// when this region function has none for the pair; the polygonizer then averages
    /// triangle normals. Only the direction matters: the polygonizer turns it to agree with
    /// the triangles' winding.
    fn gradient(&self, p: DVec3, pair: (u32, u32)) -> Option<DVec3> {
        let _ = (p, pair);
        None
    }
}

/// Regions given in order, each by a field: a point belongs to the first region whose field
/// is negative there, and otherwise to `default` (DESIGN.md, "Regions"): one region, or the
/// region a built-in region function says (such as [`PatchBlend`], which the formulas then
/// trim or add to). A field that is NaN at a point does not claim it. `gradients` gives,
/// per region pair `(a, b)` with `a < b`, a field whose gradient is normal to the surface
/// between them (see [`RegionField::gradient`]); pairs without one take the built-in's.
pub struct OrderedRegions {
    pub regions: Vec<(u32, Box<dyn Field>)>,
    pub default: Otherwise,
    pub gradients: Vec<((u32, u32), Box<dyn Field>)>,
}

/// Where [`OrderedRegions`] puts a point that none of its fields claims.
pub enum Otherwise {
    /// Always this region.
    Region(u32),
    /// Whichever region this region function says.
    Regions(Box<dyn RegionField>),
}

impl From<u32> for Otherwise {
    fn from(id: u32) -> Self {
        Otherwise::Region(id)
    }
}

impl std::fmt::Debug for Otherwise {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Otherwise::Region(id) => write!(f, "Region({id})"),
            Otherwise::Regions(r) => write!(f, "Regions({:?})", r.region_ids()),
        }
    }
}

impl RegionField for OrderedRegions {
    fn region(&self, p: DVec3) -> u32 {
        match self.regions.iter().find(|(_, f)| f.eval(p) < 0.0) {
            Some((id, _)) => *id,
            None => match &self.default {
                Otherwise::Region(id) => *id,
                Otherwise::Regions(r) => r.region(p),
            },
        }
    }

    fn region_many(&self, points: &[DVec3], out: &mut [u32]) {
        const BATCH: usize = 256;
        let mut values = [0.0f64; BATCH];
        let mut rest = [0u32; BATCH];
        for (ps, os) in points.chunks(BATCH).zip(out.chunks_mut(BATCH)) {
            let mut open: Vec<usize> = (0..ps.len()).collect();
            let mut pts = ps.to_vec();
            for (id, field) in &self.regions {
                if open.is_empty() {
                    break;
                }
                let v = &mut values[..pts.len()];
                field.eval_many(&pts, v);
                let mut still = Vec::with_capacity(open.len());
                let mut still_pts = Vec::with_capacity(open.len());
                for ((&i, &val), &p) in open.iter().zip(v.iter()).zip(&pts) {
                    if val < 0.0 {
                        os[i] = *id;
                    } else {
                        still.push(i);
                        still_pts.push(p);
                    }
                }
                open = still;
                pts = still_pts;
            }
            match &self.default {
                Otherwise::Region(id) => open.iter().for_each(|&i| os[i] = *id),
                Otherwise::Regions(r) if !open.is_empty() => {
                    let rest = &mut rest[..open.len()];
                    r.region_many(&pts, rest);
                    open.iter().zip(rest.iter()).for_each(|(&i, &id)| os[i] = id);
                }
                Otherwise::Regions(_) => {}
            }
        }
    }

    fn region_ids(&self) -> Option<Vec<u32>> {
        let mut ids: Vec<u32> = self.regions.iter().map(|(id, _)| *id).collect();
        match &self.default {
            Otherwise::Region(id) => ids.push(*id),
            Otherwise::Regions(r) => ids.extend(r.region_ids()?),
        }
        ids.sort_unstable();
        ids.dedup();
        Some(ids)
    }

    fn gradient(&self, p: DVec3, pair: (u32, u32)) -> Option<DVec3> {
        let Some((_, field)) = self.gradients.iter().find(|(q, _)| *q == pair) else {
            return match &self.default {
                Otherwise::Regions(r) => r.gradient(p, pair),
                Otherwise::Region(_) => None,
            };
        };
        let g = field.gradient(p);
        g.is_finite().then_some(g)
    }
}

/// Regions from a closure, for tests and Rust clients.
pub struct FnRegions<F>(pub F);

impl<F: Fn(DVec3) -> u32 + Send + Sync> RegionField for FnRegions<F> {
    fn region(&self, p: DVec3) -> u32 {
        (self.0)(p)
    }
}

/// The two-region field of an ordinary surface: region 0 inside (`f < 0`), 1 outside, so a
/// manifold surface is the region pair (0, 1).
pub struct InsideOutside<F>(pub F);

impl<F: Field> RegionField for InsideOutside<F> {
    fn region(&self, p: DVec3) -> u32 {
        let v = self.0.eval(p);
        u32::from(v >= 0.0 || v.is_nan())
    }

    fn region_many(&self, points: &[DVec3], out: &mut [u32]) {
        let mut v = vec![0.0; points.len()];
        self.0.eval_many(points, &mut v);
        for (o, x) in out.iter_mut().zip(v) {
            *o = u32::from(x >= 0.0 || x.is_nan());
        }
    }

    fn region_ids(&self) -> Option<Vec<u32>> {
        Some(vec![0, 1])
    }
}

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
    pub s: f64,
    pub t: f64,
    /// The nearest point `P(s, t)`.
    pub point: DVec3,
    /// The unit normal `Pₛ × Pₜ` there.
    pub normal: DVec3,
    /// Signed distance from the nearest point along the normal.
    pub distance: f64,
}

impl BicubicPatch {
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
    pub patch: BicubicPatch,
    pub centre: DVec3,
    pub radius: f64,
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
    use crate::FnField;

    #[test]
    fn first_negative_region_wins_in_batches_too() {
        let r = OrderedRegions {
            regions: vec![
                (1, Box::new(FnField(|p: DVec3| p.length() - 0.5))),
                (2, Box::new(FnField(|p: DVec3| -p.z))),
            ],
            default: 3.into(),
            gradients: vec![((1, 2), Box::new(FnField(|p: DVec3| p.z - p.length())))],
        };
        let pts: Vec<DVec3> = (0..1000)
            .map(|i| {
                DVec3::new(
                    (i % 10) as f64 * 0.2 - 1.0,
                    (i / 10 % 10) as f64 * 0.2 - 1.0,
                    (i / 100) as f64 * 0.2 - 1.0,
                )
            })
            .collect();
        let mut out = vec![0; pts.len()];
        r.region_many(&pts, &mut out);
        for (p, o) in pts.iter().zip(&out) {
            assert_eq!(*o, r.region(*p));
        }
        assert_eq!(r.region(DVec3::ZERO), 1);
        assert_eq!(r.region(DVec3::new(0.0, 0.0, 0.9)), 2);
        assert_eq!(r.region(DVec3::new(0.0, 0.0, -0.9)), 3);
        assert_eq!(r.region_ids(), Some(vec![1, 2, 3]));
        let g = r.gradient(DVec3::new(0.0, 0.6, 0.0), (1, 2)).unwrap();
        assert!((g - DVec3::new(0.0, -1.0, 1.0)).length() < 1e-6, "{g}");
        assert_eq!(r.gradient(DVec3::ZERO, (1, 3)), None);
    }

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

    /// Formulas in front of a built-in region function: they claim first, the built-in
    /// takes the rest (in batches too), its ids join theirs, and a formula gradient for a
    /// pair replaces the built-in's.
    #[test]
    fn formulas_in_front_of_a_built_in() {
        let ball = |p: DVec3| (p - DVec3::new(0.7, 0.0, 0.0)).length() - 0.2;
        let r = OrderedRegions {
            regions: vec![(4, Box::new(FnField(ball)))],
            default: Otherwise::Regions(Box::new(flat_blend())),
            gradients: vec![((3, 4), Box::new(FnField(ball)))],
        };
        assert_eq!(r.region(DVec3::new(0.7, 0.0, 0.1)), 4);
        assert_eq!(r.region(DVec3::new(0.0, 0.0, 0.1)), 1);
        assert_eq!(r.region(DVec3::new(0.0, 0.7, -0.1)), 3);
        let pts: Vec<DVec3> = (0..600)
            .map(|i| {
                DVec3::new(
                    (i % 10) as f64 * 0.27 - 1.3,
                    (i / 10 % 10) as f64 * 0.27 - 1.3,
                    (i / 100) as f64 * 0.1 - 0.3,
                )
            })
            .collect();
        let mut out = vec![99; pts.len()];
        r.region_many(&pts, &mut out);
        for (p, o) in pts.iter().zip(&out) {
            assert_eq!(*o, r.region(*p), "{p}");
        }
        for id in 0..5 {
            assert!(out.contains(&id), "no point in region {id}");
        }
        assert_eq!(r.region_ids(), Some(vec![0, 1, 2, 3, 4]));
        let p = DVec3::new(0.7, 0.3, 0.0);
        assert_eq!(r.gradient(p, (2, 3)), Some(DVec3::Z), "the built-in's");
        let g = r.gradient(p, (3, 4)).unwrap();
        assert!((g - DVec3::Y).length() < 1e-6, "the formula's: {g}");
        assert_eq!(r.gradient(p, (0, 4)), None);
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
