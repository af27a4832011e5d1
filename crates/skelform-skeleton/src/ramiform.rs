//! Ramiform (branching) skeletons by the recursive maximum of DIS eq. 3.3 and 5.36.
//!
//! A [`Ramiform`] is a tree of limbs (segments); each child starts where its parent ends.
//! Its density is defined recursively, from the leaves up:
//!
//! ```text
//! F(limb) = max(f(limb), Σ_children F(child)),   f(limb) = R² / d²
//! ```
//!
//! with `d` the distance from the point to the limb and `R` its radius, and the surface is
//! where the root's `F` is 1. The limb primitive is the dissertation's `r² ⁄ |p − q|²`
//! (§5.6.14, eq. 5.36, where the scan lost the operator between `r²` and `|p − q|²`; a
//! ratio is the reading that works: with a difference, `r² − d²`, every sibling would add a
//! large negative term and wipe out its neighbours' surfaces). A lone limb's surface is the
//! cylinder of radius `R` with round caps. The children's sum blends them into each other
//! where they leave the joint; the maximum with the parent keeps the parent's own surface
//! where it is the larger.
//!
//! **Radii.** Leaves are given their radius; every limb with children takes its radius
//! from them, as the dissertation asks ("to maintain continuity of radii, the radius of the
//! parent is scaled such that in the plane perpendicular to the parent at its endpoint
//! f_limb(parent) = Σ f_limb(child)"): the parent's radius is the largest distance from the
//! joint, in that plane, at which the children's sum is 1 (found by bisection along
//! [`RamiformOptions::directions`] directions, each local maximum refined by golden-section
//! search). Siblings are not counted: a limb's radius depends on its own subtree only, and
//! its siblings' densities widen its joint section slightly in the whole tree. In the joint plane the parent's
//! term is `R²/ρ²` at distance `ρ` from the joint, at least the children's sum wherever the
//! sum's surface lies, so the surface there is the circle of radius `R`: the parent's radius
//! continues exactly up to the joint and the children grow out of it. As the dissertation
//! notes, the sum makes a parent thicker than each child, as many natural branches are.
//!
//! The field is `F^(−½) − 1` (inside negative): for a lone limb that is `d/R − 1`, the
//! distance in radii, which keeps values and gradients well scaled everywhere (the density
//! itself grows without bound at the skeleton). The maximum leaves a crease where the
//! parent's round cap meets the children, as in the dissertation's fig. 5.59.
//!
//! **Limits.** A tree has at most [`MAX_LIMBS`] limbs, none more than [`MAX_DEPTH`] deep (a
//! root is depth 1), and matching the radii may take at most [`MAX_JOINT_WORK`] limb
//! searches ([`Ramiform::joint_work`]): every evaluation
//! visits every limb, recursing once per level, and each parent's radius search evaluates its
//! whole subtree along every direction, so without them a chain 30,000 limbs deep ran for
//! minutes (and could overflow the stack). [`Ramiform::add_root`] and [`Ramiform::add_child`]
//! refuse a limb over the first two; [`RamiformField::new`] checks the third before it matches
//! any radius.

use glam::DVec3;
use skelform_field::{Aabb, Field};

use crate::SkeletonError;
use crate::geometry::Segment;

/// The most limbs a [`Ramiform`] may have.
pub const MAX_LIMBS: usize = 1024;

/// The deepest a limb may hang below its root (a root is depth 1): the field's evaluation
/// recurses once per level.
pub const MAX_DEPTH: usize = 64;

/// The most radius-matching work [`RamiformField::new`] may take
/// ([`Ramiform::joint_work`]: searches along a direction times the limbs below each parent,
/// summed over the parents; a search is about 90 evaluations of a limb, 2 to 4 µs measured,
/// so the limit is a few seconds of one core: a 64-deep chain at the default 72 directions
/// is 270,000, a binary tree of 1023 limbs 1.6 million).
pub const MAX_JOINT_WORK: u64 = 2_000_000;

/// Searches along a direction that refining one local maximum of a parent's radius takes
/// (golden-section search).
pub const GOLDEN_STEPS: u64 = 62;

/// One limb of a [`Ramiform`] as given.
#[derive(Clone, Debug, PartialEq)]
pub struct Limb {
    /// The segment from the joint it hangs from (its parent's end) to its own end.
    pub segment: Segment,
    /// The limb it hangs from; `None` for a root.
    pub parent: Option<usize>,
    /// The radius of a leaf; `None` for a limb with children, whose radius is computed.
    pub radius: Option<f64>,
}

/// A tree (or several) of limbs, built root first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Ramiform {
    limbs: Vec<Limb>,
    /// Each limb's depth, a root being 1.
    depths: Vec<usize>,
}

/// How a [`RamiformField`] matches radii at joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RamiformOptions {
    /// Directions in each joint plane along which the children's surface is found (at
    /// least 8); each local maximum among them is then refined by golden-section search,
    /// and the parent's radius is the farthest.
    pub directions: usize,
}

impl Default for RamiformOptions {
    fn default() -> Self {
        RamiformOptions { directions: 72 }
    }
}

impl Ramiform {
    /// An empty ramiform.
    pub fn new() -> Ramiform {
        Ramiform::default()
    }

    /// The limbs in the order added (indices are what the `add_` functions return).
    pub fn limbs(&self) -> &[Limb] {
        &self.limbs
    }

    /// A root limb from `a` to `b`; `radius` is required if it gets no children.
    pub fn add_root(
        &mut self,
        a: DVec3,
        b: DVec3,
        radius: Option<f64>,
    ) -> Result<usize, SkeletonError> {
        check_radius(radius)?;
        self.check_count()?;
        self.limbs.push(Limb { segment: Segment::new(a, b)?, parent: None, radius });
        self.depths.push(1);
        Ok(self.limbs.len() - 1)
    }

    /// A limb from the end of `parent` to `b`.
    pub fn add_child(
        &mut self,
        parent: usize,
        b: DVec3,
        radius: Option<f64>,
    ) -> Result<usize, SkeletonError> {
        check_radius(radius)?;
        self.check_count()?;
        let a = self.limbs.get(parent).ok_or(SkeletonError::UnknownLimb(parent))?.segment.b();
        let depth = self.depths[parent] + 1;
        if depth > MAX_DEPTH {
            return Err(SkeletonError::TooDeep { limb: self.limbs.len(), depth });
        }
        self.limbs.push(Limb { segment: Segment::new(a, b)?, parent: Some(parent), radius });
        self.depths.push(depth);
        Ok(self.limbs.len() - 1)
    }

    /// The depth of limb `i` (a root is 1), or `None` when there is no such limb.
    pub fn depth(&self, i: usize) -> Option<usize> {
        self.depths.get(i).copied()
    }

    fn check_count(&self) -> Result<(), SkeletonError> {
        if self.limbs.len() >= MAX_LIMBS {
            return Err(SkeletonError::TooManyLimbs(self.limbs.len() + 1));
        }
        Ok(())
    }

    /// The radius-matching work of [`MAX_JOINT_WORK`] with `directions` directions: for
    /// each parent, the limbs below it times the searches along a direction it may take
    /// (every direction, and [`GOLDEN_STEPS`] more for each local maximum refined, at most
    /// one per child and one per two directions).
    pub fn joint_work(&self, directions: usize) -> u64 {
        let n = self.limbs.len();
        let (mut below, mut children) = (vec![0u64; n], vec![0u64; n]);
        // Children come after their parents: the reverse order sums subtrees bottom up.
        for i in (0..n).rev() {
            if let Some(p) = self.limbs[i].parent {
                below[p] += below[i] + 1;
                children[p] += 1;
            }
        }
        let d = directions as u64;
        (0..n)
            .filter(|&i| children[i] > 0)
            .map(|i| {
                let searches =
                    d.saturating_add(GOLDEN_STEPS.saturating_mul(children[i].min(d / 2)));
                below[i].saturating_mul(searches)
            })
            .fold(0, u64::saturating_add)
    }
}

fn check_radius(radius: Option<f64>) -> Result<(), SkeletonError> {
    match radius {
        Some(r) if !(r.is_finite() && r > 0.0) => Err(SkeletonError::BadRadius(r)),
        _ => Ok(()),
    }
}

/// The field of a [`Ramiform`]: inside negative, exact gradients, deterministic.
#[derive(Clone, Debug)]
pub struct RamiformField {
    segments: Vec<Segment>,
    radii: Vec<f64>,
    children: Vec<Vec<usize>>,
    roots: Vec<usize>,
    bounds: Aabb,
}

/// Squared distances below this fraction of the squared radius count as this: the density
/// stays finite on the skeleton itself.
const MIN_D2: f64 = 1e-24;

impl RamiformField {
    /// Computes every limb's radius (leaves as given, parents matched at their joints) and
    /// the field. Errors: a leaf without a radius, a parent with one, no limbs.
    pub fn new(r: &Ramiform, options: &RamiformOptions) -> Result<RamiformField, SkeletonError> {
        if r.limbs.is_empty() {
            return Err(SkeletonError::Empty);
        }
        if options.directions < 8 {
            return Err(SkeletonError::BadParameter {
                name: "directions",
                value: options.directions as f64,
                expected: "at least 8",
            });
        }
        let work = r.joint_work(options.directions);
        if work > MAX_JOINT_WORK {
            return Err(SkeletonError::JointWorkTooLarge { work });
        }
        let n = r.limbs.len();
        let mut children = vec![Vec::new(); n];
        let mut roots = Vec::new();
        for (i, l) in r.limbs.iter().enumerate() {
            match l.parent {
                Some(p) => children[p].push(i),
                None => roots.push(i),
            }
        }
        let mut field = RamiformField {
            segments: r.limbs.iter().map(|l| l.segment).collect(),
            radii: vec![0.0; n],
            children,
            roots,
            bounds: Aabb { min: DVec3::ZERO, max: DVec3::ZERO },
        };
        // Children come after their parents, so the reverse order visits every child first.
        for i in (0..n).rev() {
            let given = r.limbs[i].radius;
            field.radii[i] = match (given, field.children[i].is_empty()) {
                (Some(radius), true) => radius,
                (None, true) => return Err(SkeletonError::LeafNeedsRadius(i)),
                (Some(_), false) => return Err(SkeletonError::ParentRadiusGiven(i)),
                (None, false) => field.matched_radius(i, options.directions),
            };
        }
        // F > 1 needs Σ Rᵢ²/dᵢ² > 1, so some dᵢ < √(Σ Rᵢ²): the surface lies within that
        // distance of the skeleton.
        let reach = field.radii.iter().map(|r| r * r).sum::<f64>().sqrt();
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for s in &field.segments {
            lo = lo.min(s.a()).min(s.b());
            hi = hi.max(s.a()).max(s.b());
        }
        field.bounds = Aabb { min: lo - DVec3::splat(reach), max: hi + DVec3::splat(reach) };
        Ok(field)
    }

    /// Every limb's radius, leaves as given and parents as matched, by limb index.
    pub fn radii(&self) -> &[f64] {
        &self.radii
    }

    /// One point on each limb, inside the surface, for the continuation polygonizer.
    pub fn seed_points(&self) -> Vec<DVec3> {
        self.segments.iter().map(|s| (s.a() + s.b()) * 0.5).collect()
    }

    /// The radius of limb `i` that makes its surface in the plane perpendicular to it at its
    /// end the circle enclosing its children's: the largest distance from the joint, in
    /// that plane, at which the children's summed density is 1.
    fn matched_radius(&self, i: usize, directions: usize) -> f64 {
        let s = &self.segments[i];
        let joint = s.b();
        let axis = (s.b() - s.a()).normalize();
        let u = axis.any_orthonormal_vector();
        let v = axis.cross(u);
        let sum = |p: DVec3| self.children[i].iter().map(|&c| self.density(c, p, false).0).sum();
        let start = self.children[i].iter().map(|&c| self.radii[c]).fold(0.0, f64::max);
        // The distance to the children's surface along the direction at angle t.
        let reach = |t: f64| -> f64 {
            let dir = u * t.cos() + v * t.sin();
            let at = |rho: f64| -> f64 { sum(joint + dir * rho) };
            // Bracket the crossing: inside near the joint, outside far enough out.
            let (mut lo, mut hi) = (0.0, start);
            let mut steps = 0;
            while at(hi) >= 1.0 && steps < 200 {
                lo = hi;
                hi *= 2.0;
                steps += 1;
            }
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if at(mid) >= 1.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        };
        // Sampled, then every local maximum refined by golden-section search between its
        // neighbours, so that lobes narrower than the sampling are not cut.
        let step = std::f64::consts::TAU / directions as f64;
        let samples: Vec<f64> = (0..directions).map(|k| reach(step * k as f64)).collect();
        let mut widest: f64 = samples.iter().copied().fold(0.0, f64::max);
        let inv_phi = (5f64.sqrt() - 1.0) / 2.0;
        for k in 0..directions {
            let (prev, next) =
                (samples[(k + directions - 1) % directions], samples[(k + 1) % directions]);
            // Not a maximum, or a plateau (a child straight ahead gives the same distance all
            // round, up to rounding): nothing to refine.
            if samples[k] < prev
                || samples[k] < next
                || samples[k] - prev.min(next) <= 1e-9 * samples[k]
            {
                continue;
            }
            let (mut a, mut b) = (step * (k as f64 - 1.0), step * (k as f64 + 1.0));
            let mut c = b - inv_phi * (b - a);
            let mut d = a + inv_phi * (b - a);
            let (mut fc, mut fd) = (reach(c), reach(d));
            for _ in 0..GOLDEN_STEPS - 2 {
                if fc > fd {
                    b = d;
                    d = c;
                    fd = fc;
                    c = b - inv_phi * (b - a);
                    fc = reach(c);
                } else {
                    a = c;
                    c = d;
                    fc = fd;
                    d = a + inv_phi * (b - a);
                    fd = reach(d);
                }
            }
            widest = widest.max(fc).max(fd);
        }
        widest
    }

    /// `F(limb)` of the module documentation at `p`, and its gradient when `grad`.
    fn density(&self, i: usize, p: DVec3, grad: bool) -> (f64, DVec3) {
        let s = &self.segments[i];
        let r = self.radii[i];
        let (q, _) = s.nearest(p);
        let v = p - q;
        let d2 = v.length_squared().max(MIN_D2 * r * r);
        let own = r * r / d2;
        // ∇(R²/d²) = −2R²·(p − q)/d⁴ (the nearest point moves along the segment, orthogonal
        // to p − q, so it adds nothing).
        let own_g = if grad { v * (-2.0 * own / d2) } else { DVec3::ZERO };
        if self.children[i].is_empty() {
            return (own, own_g);
        }
        let (mut sum, mut sum_g) = (0.0, DVec3::ZERO);
        for &c in &self.children[i] {
            let (f, g) = self.density(c, p, grad);
            sum += f;
            sum_g += g;
        }
        if own >= sum { (own, own_g) } else { (sum, sum_g) }
    }

    /// The largest root density at `p`, with its gradient.
    fn total(&self, p: DVec3, grad: bool) -> (f64, DVec3) {
        let mut best = (0.0, DVec3::ZERO);
        for &root in &self.roots {
            let d = self.density(root, p, grad);
            if d.0 > best.0 {
                best = d;
            }
        }
        best
    }
}

impl Field for RamiformField {
    fn eval(&self, p: DVec3) -> f64 {
        let (f, _) = self.total(p, false);
        if f > 0.0 { f.powf(-0.5) - 1.0 } else { f64::MAX }
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let (f, g) = self.total(p, true);
        if f > 0.0 { g * (-0.5 * f.powf(-1.5)) } else { DVec3::ZERO }
    }

    fn has_exact_gradient(&self) -> bool {
        true
    }

    fn bounds(&self) -> Option<Aabb> {
        Some(self.bounds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of `n` limbs up z, the last a leaf.
    fn chain(n: usize) -> Result<Ramiform, SkeletonError> {
        let mut r = Ramiform::new();
        let mut last =
            r.add_root(DVec3::ZERO, DVec3::new(0.0, 0.0, 0.1), (n == 1).then_some(0.02))?;
        for i in 1..n {
            let b = DVec3::new(0.01 * (i % 2) as f64, 0.0, 0.1 * (i + 1) as f64);
            last = r.add_child(last, b, (i + 1 == n).then_some(0.02))?;
        }
        Ok(r)
    }

    #[test]
    fn depth_count_and_work_are_limited() {
        let r = chain(MAX_DEPTH).unwrap();
        assert_eq!(r.depth(MAX_DEPTH - 1), Some(MAX_DEPTH));
        // Each parent has one child: 72 directions and one refinement, times the limbs below.
        let below = (MAX_DEPTH * (MAX_DEPTH - 1) / 2) as u64;
        assert_eq!(r.joint_work(72), below * (72 + GOLDEN_STEPS));
        let f = RamiformField::new(&r, &RamiformOptions::default()).unwrap();
        assert!(f.eval(DVec3::new(0.0, 0.0, 3.0)) < 0.0);
        assert!(matches!(
            chain(MAX_DEPTH + 1),
            Err(SkeletonError::TooDeep { limb, depth }) if limb == MAX_DEPTH && depth == MAX_DEPTH + 1
        ));
        let mut wide = Ramiform::new();
        let root = wide.add_root(DVec3::ZERO, DVec3::Z, None).unwrap();
        for i in 1..MAX_LIMBS {
            let a = i as f64 * 0.01;
            wide.add_child(root, DVec3::new(a.cos(), a.sin(), 1.5), Some(0.01)).unwrap();
        }
        assert_eq!(
            wide.add_child(root, DVec3::new(0.0, 1.0, 1.0), Some(0.01)),
            Err(SkeletonError::TooManyLimbs(MAX_LIMBS + 1))
        );
        let heavy = RamiformOptions { directions: 100_000 };
        assert!(matches!(
            RamiformField::new(&r, &heavy),
            Err(SkeletonError::JointWorkTooLarge { work }) if work > MAX_JOINT_WORK
        ));
    }
}
