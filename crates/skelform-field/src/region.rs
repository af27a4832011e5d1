//! Region functions: space divided into numbered regions, for non-manifold polygonization.
//!
//! Where a [`Field`] says inside or outside, a [`RegionField`] says *which*
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
/// region a built-in region function says (such as the patch blend,
/// `skelform_leaf::patch::PatchBlend`, which the formulas then trim or add to). A field that
/// is NaN at a point does not claim it. `gradients` gives, per region pair `(a, b)` with
/// `a < b`, a field whose gradient is normal to the surface between them (see
/// [`RegionField::gradient`]); pairs without one take the built-in's.
pub struct OrderedRegions {
    /// `(region id, field)` in priority order: the first field negative at a point claims
    /// it, so earlier regions cut into later ones. Ids may repeat (a region made of several
    /// pieces).
    pub regions: Vec<(u32, Box<dyn Field>)>,
    /// Where the points that no field claims go.
    pub default: Otherwise,
    /// `((a, b), field)` with `a < b`: the field whose gradient gives vertex normals on the
    /// surface between regions `a` and `b`.
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

    /// A stand-in for a built-in region function with the patch blend's layout (the patch
    /// blend itself is in `skelform-leaf`, which tests it behind formulas too): 0 beyond
    /// `|x|, |y| < 1`, 1 a ball at the origin, 2 above `z = 0`, 3 below, with the plane's
    /// normal as the gradient between 2 and 3.
    struct Layers;

    impl RegionField for Layers {
        fn region(&self, p: DVec3) -> u32 {
            if p.x.abs() >= 1.0 || p.y.abs() >= 1.0 {
                0
            } else if p.length() < 0.3 {
                1
            } else if p.z > 0.0 {
                2
            } else {
                3
            }
        }

        fn region_ids(&self) -> Option<Vec<u32>> {
            Some(vec![0, 1, 2, 3])
        }

        fn gradient(&self, _: DVec3, pair: (u32, u32)) -> Option<DVec3> {
            (pair == (2, 3)).then_some(DVec3::Z)
        }
    }

    /// Formulas in front of a built-in region function: they claim first, the built-in
    /// takes the rest (in batches too), its ids join theirs, and a formula gradient for a
    /// pair replaces the built-in's.
    #[test]
    fn formulas_in_front_of_a_built_in() {
        let ball = |p: DVec3| (p - DVec3::new(0.7, 0.0, 0.0)).length() - 0.2;
        let r = OrderedRegions {
            regions: vec![(4, Box::new(FnField(ball)))],
            default: Otherwise::Regions(Box::new(Layers)),
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
}
