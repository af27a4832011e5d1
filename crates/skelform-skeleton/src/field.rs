//! [`SkeletonField`]: a skeleton, a blend and an iso value as a [`Field`].
//!
//! ## Blends
//!
//! | [`Blend`] | field (inside negative) | dissertation |
//! |---|---|---|
//! | `Convolution(k)` | `c − Σ wᵢ·(k ⊗ elementᵢ)` | §5.6, eq. 5.30; ch. 6 for polygons |
//! | `Sum(k)` | `c − Σ wᵢ·k(dᵢ/rᵢ)` (soft objects on distances) | §5.6.1 (5.19) applied to distances; bulges where elements meet |
//! | `Union(Linear)` | `min dᵢ/rᵢ − 1` | eqs. 5.6, 5.9, 5.10 |
//! | `Union(Squared)` | `min dᵢ²/rᵢ² − 1` | eq. 5.7 (no square root) |
//! | `SuperElliptic { range, thumbweight: t, .. }` | `1 − Σ [1 − Pᵢ/Rᵢ]₊ᵗ`, `Pᵢ = dᵢ − rᵢ`, `Rᵢ = range·rᵢ` (times `1 − cos θ` with `angle_scaled`) | eqs. 5.12 (`t = 2`, elliptic), 5.13, 5.14 |
//! | `Combination { range, clamp }` | `c − (B + [cos θ]₊·(U − B))`, `B = 1 − Π(1 − Pᵢ)`, `U = max Pᵢ` | eqs. 5.15–5.17 |
//!
//! `dᵢ` is the distance from `p` to element `i`, `rᵢ` its radius, `wᵢ` its strength, `c` the
//! iso value (default ½). In the combination surface `Pᵢ = h(½ + (dᵢ − rᵢ)/Rᵢ)` with `h` the
//! Wyvill decay (1 at 0, 0 at 1, flat at both), the dissertation's `h((d − radius)/range)`
//! shifted by half the range so that a lone element's surface is at its radius; `θ` is the
//! angle between the vectors from `p` to the nearest points of the two most influential
//! elements (DIS fig. 5.30), and `[·]₊` is applied when `clamp` (eq. 5.17; unclamped is eq.
//! 5.15, which leaves a protuberance at acute angles). The super-elliptic sum over all
//! elements is the natural extension of the two-primitive formula: on a lone element's
//! surface it is 0, and beyond every element's range it is 1.
//!
//! `Convolution(Kernel::Sinc)` takes points only (see [`Kernel::convolves_extended`]); a
//! skeleton with a segment or polygon is refused with
//! [`SkeletonError::KernelConvolvesPointsOnly`]. `Sum(Kernel::Sinc)` takes every element.
//!
//! A tapered segment's radius and strength are interpolated along it by the parameter of the
//! point's projection, clamped (appendix A.2), in every blend; their gradients enter the
//! field's gradient. A junction's limbs ([`Skeleton::add_junction`]) are taken out of the
//! plain sum and added as one joint combination density ([`crate::junction`]).
//!
//! Every element has a box outside which it contributes nothing (the dissertation's speed-up,
//! §3.7 and §7.4): the kernel's support for density blends, the range for the super-elliptic
//! and combination blends. The union blend is capped at `d/r = 2` (value 1, or 3 squared) so
//! that it can be culled too; the zero set is unchanged. Kernels without finite support are
//! cut off where they are negligible ([`crate::kernel::GAUSSIAN_CUTOFF`], [`crate::kernel::SINC_CUTOFF`]), so
//! their boxes are finite too.
//!
//! ## Culling
//!
//! A uniform grid over those boxes ([`CullGrid`]) lists, for each of its cells, the elements
//! whose boxes meet the cell, in element order. A batch of points is sorted by cell and each
//! cell's points are evaluated against that cell's elements only (each point still tests the
//! element's box). Why the element order matters: the sum then adds exactly the same terms in
//! exactly the same order as a visit of every element would, so the values are bit-identical
//! to the unculled ones (the unit tests compare them) and meshes do not change; the order of
//! the points in a batch never mattered, each point has its own accumulator.
//!
//! ## Blend control
//!
//! Elements blend with the elements of their own group and of groups linked to it
//! ([`Skeleton::blend_groups`]). The field is evaluated once per maximal clique of that
//! relation ([`Skeleton::blend_cliques`]) and the cliques are combined by a **sharp union**,
//! `f = min over cliques`. Why: grouping is the dissertation's first answer to unwanted
//! blending (§6.7, after Beier and Opalach; it was not implemented there), and the union is
//! the only combination that guarantees two groups that must not blend never affect each
//! other's surface — each clique's surface is exactly what it would be alone, so fingers 0.2
//! radius apart stay apart. Cliques rather than groups make non-transitive relations work:
//! with fingers linked to the palm but not to each other, the cliques are `{palm, finger1}`,
//! `{palm, finger2}`, …, so each finger blends into the palm and no two fingers blend. Where
//! the surfaces of two cliques do meet, the union leaves a crease, as it should.

use glam::{DMat3, DVec2, DVec3};
use skelform_field::{Aabb, Field};

use crate::SkeletonError;
use crate::convolution::{PreparedPolygon, PreparedSegment, PreparedWeighted};
use crate::geometry::{Nearest, Shape};
use crate::image::{ImagePolygon, PolygonMethod};
use crate::junction::PreparedJunction;
use crate::kernel::Kernel;
use crate::skeleton::{Element, Skeleton};

/// How a distance surface measures distance (DIS eqs. 5.6 and 5.7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Falloff {
    /// `d/r − 1`: a signed distance in radii.
    #[default]
    Linear,
    /// `d²/r² − 1`: avoids the square root; same zero set.
    Squared,
}

/// How the elements of a clique combine into one field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Blend {
    /// Convolution surface with this kernel (DIS §5.6).
    Convolution(Kernel),
    /// Sum of the kernel applied to each element's distance: "soft objects" on skeletal
    /// distances. Smooth, but it bulges where elements meet.
    Sum(Kernel),
    /// Union of distance surfaces (DIS eqs. 5.6, 5.7, 5.9, 5.10): no blending at all.
    Union(Falloff),
    /// Rockwood's super-elliptic blend (DIS eq. 5.13; `thumbweight = 2` is the elliptic
    /// blend 5.12). `range` is each element's range of influence beyond its surface, in
    /// multiples of its radius. With `angle_scaled`, every range is multiplied by
    /// `1 − cos θ`, `θ` the angle between the gradients of the two elements nearest `p` (in
    /// units of their ranges): eq. 5.14, full blend where the primitives meet at right
    /// angles, the union where their gradients agree, which removes the blend's bulge.
    SuperElliptic {
        /// Reach of each element's influence beyond its surface, in multiples of its
        /// radius (`Rᵢ = range·rᵢ`); positive. Beyond it an element does not blend.
        range: f64,
        /// The exponent `t` of eq. 5.13, at least 1: 2 is the elliptic blend, larger values
        /// a tighter fillet that approaches the union.
        thumbweight: f64,
        /// Scale every range by `1 − cos θ` (eq. 5.14), removing the bulge where primitives
        /// cross: no blend where their gradients agree, the full blend at right angles.
        angle_scaled: bool,
    },
    /// The combination surface (DIS eqs. 5.15–5.17): a product blend where the skeleton is
    /// concave, the union where it is convex. `range` is the width of the blend zone, in
    /// multiples of the radius.
    Combination {
        /// Width of the blend zone around each element's surface, in multiples of its
        /// radius (`Rᵢ` in `Pᵢ = h(½ + (dᵢ − rᵢ)/Rᵢ)`); positive.
        range: f64,
        /// Clamp `cos θ` at 0 (eq. 5.17); without it (eq. 5.15) acute angles between
        /// elements leave a protuberance.
        clamp: bool,
    },
}

impl Blend {
    /// The scene-file name of the blend's kind.
    pub fn name(&self) -> &'static str {
        match self {
            Blend::Convolution(_) => "convolution",
            Blend::Sum(_) => "sum",
            Blend::Union(_) => "union",
            Blend::SuperElliptic { .. } => "super-elliptic",
            Blend::Combination { .. } => "combination",
        }
    }

    /// Whether the field is a density compared with an iso value.
    pub fn has_iso(&self) -> bool {
        matches!(self, Blend::Convolution(_) | Blend::Sum(_) | Blend::Combination { .. })
    }

    pub(crate) fn check(&self) -> Result<(), SkeletonError> {
        let positive = |name, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(SkeletonError::BadParameter { name, value: v, expected: "a positive number" })
            }
        };
        match *self {
            Blend::SuperElliptic { range, thumbweight, .. } => {
                positive("range", range)?;
                if !(thumbweight.is_finite() && thumbweight >= 1.0) {
                    return Err(SkeletonError::BadParameter {
                        name: "thumbweight",
                        value: thumbweight,
                        expected: "a number of at least 1",
                    });
                }
                Ok(())
            }
            Blend::Combination { range, .. } => positive("range", range),
            _ => Ok(()),
        }
    }
}

/// The default iso value of density blends: a lone element's surface at its radius (DIS eq.
/// 5.30, `f = ½ − h⊗s`).
pub const DEFAULT_ISO: f64 = 0.5;

/// The union blend's cap, in radii: beyond `d = 2r` an element is culled.
const UNION_CAP: f64 = 2.0;

/// The smallest range factor `1 − cos θ` of the angle-scaled super-elliptic blend: where
/// the two gradients agree the blend is 1 % of its range wide (a union to the eye) rather
/// than zero, which would send the field to −∞ inside.
const MIN_ANGLE_SCALE: f64 = 0.01;

/// Points per inner batch: accumulators live on the stack.
const CHUNK: usize = 64;

#[derive(Clone, Debug)]
enum Prepared {
    Point { c: DVec3, inv_r: f64, strength: f64 },
    Segment(PreparedSegment),
    Polygon(PreparedPolygon),
    Weighted(PreparedWeighted),
    Image(ImagePolygon),
}

/// Radius and strength varying linearly along a segment, by the parameter of the point's
/// projection, clamped to the segment.
#[derive(Clone, Copy, Debug)]
struct Taper {
    a: DVec3,
    /// `(b − a)/|b − a|²`: `∇α`.
    grad_alpha: DVec3,
    ra: f64,
    dr: f64,
    wa: f64,
    dw: f64,
}

impl Taper {
    /// Radius, its gradient, strength, its gradient at `p`.
    #[inline]
    fn at(&self, p: DVec3) -> (f64, DVec3, f64, DVec3) {
        let t = (p - self.a).dot(self.grad_alpha);
        if t <= 0.0 {
            (self.ra, DVec3::ZERO, self.wa, DVec3::ZERO)
        } else if t >= 1.0 {
            (self.ra + self.dr, DVec3::ZERO, self.wa + self.dw, DVec3::ZERO)
        } else {
            (
                self.ra + self.dr * t,
                self.grad_alpha * self.dr,
                self.wa + self.dw * t,
                self.grad_alpha * self.dw,
            )
        }
    }
}

/// Whether the rectangle `lo..hi` may meet the polygon `flat` (both in the polygon's plane):
/// its centre is inside the polygon or within half its diagonal (and a hair) of an edge. A
/// rectangle that meets the polygon passes (if its centre is outside, the way from the
/// centre to a common point crosses an edge inside the rectangle); some that do not pass
/// too, which only costs a box.
fn meets_polygon(flat: &[DVec2], lo: DVec2, hi: DVec2) -> bool {
    let c = (lo + hi) * 0.5;
    let reach = (hi - lo).length() * 0.5 * (1.0 + 1e-9) + 1e-12;
    let mut inside = false;
    for (k, &a) in flat.iter().enumerate() {
        let b = flat[(k + 1) % flat.len()];
        let ab = b - a;
        let t = ((c - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        if !t.is_finite() || (a + ab * t - c).length() <= reach {
            return true;
        }
        if (a.y > c.y) != (b.y > c.y) && c.x < a.x + (c.y - a.y) / (b.y - a.y) * ab.x {
            inside = !inside;
        }
    }
    inside
}

#[derive(Clone, Debug)]
struct Item {
    lo: DVec3,
    hi: DVec3,
    /// How far from its shape the element reaches (its box is the shape's grown by this).
    reach: f64,
    shape: Shape,
    radius: f64,
    strength: f64,
    taper: Option<Taper>,
    conv: Prepared,
}

impl Item {
    #[inline]
    fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// Radius, its gradient, strength, its gradient at `p`.
    #[inline]
    fn radius_strength(&self, p: DVec3) -> (f64, DVec3, f64, DVec3) {
        match &self.taper {
            Some(t) => t.at(p),
            None => (self.radius, DVec3::ZERO, self.strength, DVec3::ZERO),
        }
    }

    /// The element's signed distance from `p` in ranges, `a = (d − r)/(range·r)` (`d` the
    /// distance, `r` the radius there), its gradient, and the nearest point (with its
    /// Jacobian when `jac`).
    #[inline]
    fn in_ranges(&self, p: DVec3, range: f64, jac: bool) -> (f64, DVec3, Nearest) {
        let nearest = if jac {
            self.shape.nearest_with_jacobian(p)
        } else {
            Nearest { point: self.shape.nearest(p), jacobian: DMat3::ZERO }
        };
        let v = p - nearest.point;
        let d = v.length();
        let (r, gr, _, _) = self.radius_strength(p);
        let rr = range * r;
        let a = (d - r) / rr;
        let gd = if d > 0.0 { v / d } else { DVec3::ZERO };
        // a = d/(range·r) − 1/range.
        let ga = gd / rr - gr * (d / (rr * r));
        (a, ga, nearest)
    }
}

/// One element's influence on a point, kept for the combination blend.
#[derive(Clone, Copy, Debug)]
struct Influence {
    p: f64,
    grad: DVec3,
    nearest: Nearest,
}

const NO_INFLUENCE: Influence = Influence {
    p: 0.0,
    grad: DVec3::ZERO,
    nearest: Nearest { point: DVec3::ZERO, jacobian: DMat3::ZERO },
};

/// Per-point running state of one clique's blend.
#[derive(Clone, Copy, Debug)]
struct Acc {
    v: f64,
    g: DVec3,
    prod: f64,
    prod_g: DVec3,
    best: [Influence; 2],
    /// The angle-scaled super-elliptic blend's range factor `1 − cos θ` and its gradient.
    scale: f64,
    scale_g: DVec3,
}

/// The elements of one clique: those evaluated one by one, and junctions.
#[derive(Clone, Debug)]
struct Clique {
    plain: Vec<usize>,
    junctions: Vec<usize>,
    /// With a shared sum ([`SharedSums`]): the groups whose sums make up `plain`.
    parts: Vec<usize>,
}

/// For additive blends (convolution, sum) with several cliques: each group's elements are
/// summed once per point and each clique adds up its groups' sums, instead of evaluating a
/// group once for every clique it belongs to (the hand's palm and tendons are in six).
#[derive(Clone, Debug)]
struct SharedSums {
    /// The plain elements of each group that has any.
    groups: Vec<Vec<usize>>,
}

/// A skeleton's field: inside negative, exact gradients, deterministic.
///
/// ```
/// use skelform_skeleton::{Blend, Kernel, Skeleton, SkeletonField, GroupId};
/// use skelform_field::Field;
/// use glam::DVec3;
/// let mut s = Skeleton::new();
/// s.add_segment(DVec3::ZERO, DVec3::X, 0.2, GroupId::DEFAULT).unwrap();
/// let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
/// assert!(f.eval(DVec3::new(0.5, 0.0, 0.0)) < 0.0); // on the skeleton: inside
/// assert!(f.eval(DVec3::new(0.5, 0.2, 0.0)).abs() < 0.01); // one radius away: the surface
/// ```
#[derive(Clone, Debug)]
pub struct SkeletonField {
    blend: Blend,
    iso: f64,
    items: Vec<Item>,
    cliques: Vec<Clique>,
    shared: Option<SharedSums>,
    junctions: Vec<PreparedJunction>,
    bounds: Aabb,
    seeds: Vec<DVec3>,
    min_radius: f64,
    cull: CullGrid,
    /// What the field was built from, for [`SkeletonField::changes_since`].
    source: Source,
    /// Each element's colour (its own, or the skeleton's default, or [`NEUTRAL_COLOR`]);
    /// `None` when the skeleton has no colour at all.
    colors: Option<Vec<[f32; 3]>>,
    /// Junction gradients along the appendix's blended normals
    /// ([`SkeletonField::with_blended_normals`]).
    blended_normals: bool,
    /// Segments by the separable approximation ([`SkeletonField::with_separable_segments`]).
    separable: bool,
}

/// The parts of the skeleton a field depends on, kept to compare two fields.
#[derive(Clone, Debug, PartialEq)]
struct Source {
    elements: Vec<Element>,
    groups: Vec<crate::skeleton::Group>,
    junctions: usize,
}

/// Why two skeletal fields cannot be compared element by element: something that every
/// point's value depends on changed ([`SkeletonField::changes_since`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GlobalChange {
    /// The blend, its parameters (the segment method included) or the iso value.
    Blend,
    /// The blend groups, their links, or which groups have elements (the cliques).
    Groups,
    /// A junction (its density is not one element's; see [`crate::junction`]).
    Junctions,
}

impl std::fmt::Display for GlobalChange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            GlobalChange::Blend => "the blend or the iso value changed",
            GlobalChange::Groups => "the blend groups changed",
            GlobalChange::Junctions => "the skeleton has junctions",
        })
    }
}

/// A density blend's iso value must be positive: far from the skeleton the density is 0, and
/// that must be outside.
pub(crate) fn check_iso(iso: f64) -> Result<(), SkeletonError> {
    if iso.is_finite() && iso > 0.0 {
        Ok(())
    } else {
        Err(SkeletonError::BadParameter { name: "iso", value: iso, expected: "a positive number" })
    }
}

/// The colour of elements that have none when others do and the skeleton sets no default:
/// the renderer's plain surface colour (sRGB 176, 192, 214).
pub const NEUTRAL_COLOR: [f32; 3] = [176.0 / 255.0, 192.0 / 255.0, 214.0 / 255.0];

impl SkeletonField {
    /// The field of `skeleton` under `blend`, with the iso value [`DEFAULT_ISO`] for density
    /// blends.
    pub fn new(skeleton: &Skeleton, blend: Blend) -> Result<SkeletonField, SkeletonError> {
        blend.check()?;
        if skeleton.is_empty() {
            return Err(SkeletonError::Empty);
        }
        if !skeleton.junctions().is_empty() && !matches!(blend, Blend::Convolution(_)) {
            return Err(SkeletonError::JunctionNeedsConvolution(blend.name()));
        }
        for e in skeleton.elements() {
            if !e.is_weighted() {
                continue;
            }
            if !matches!(blend, Blend::Convolution(_)) {
                return Err(SkeletonError::WeightsNeedConvolution(blend.name()));
            }
            // A pose or caller may have replaced the shape since the weights were checked.
            match (&e.shape, e.vertex_weights()) {
                (Shape::Polygon(p), Some(w)) => crate::weights::check_vertex_weights(p, w)?,
                (Shape::Polygon(_), None) => {}
                _ => return Err(SkeletonError::WeightsNeedPolygon),
            }
        }
        if let Blend::Convolution(k) = blend
            && !k.convolves_extended()
            && let Some((element, e)) = skeleton
                .elements()
                .iter()
                .enumerate()
                .find(|(_, e)| !matches!(e.shape, Shape::Point(_)))
        {
            let shape = if matches!(e.shape, Shape::Segment(_)) { "segment" } else { "polygon" };
            return Err(SkeletonError::KernelConvolvesPointsOnly {
                kernel: k.name(),
                shape,
                element,
            });
        }
        // Image polygons are built here, before any sample: refuse a skeleton of them that
        // would take hours or gigabytes to build.
        crate::image::check_budget(
            match blend {
                Blend::Convolution(k) => k,
                _ => Kernel::Gaussian,
            },
            skeleton.elements().iter().filter_map(|e| match (&e.shape, e.polygon_method()) {
                (Shape::Polygon(p), PolygonMethod::Image { resolution }) => {
                    Some((p, e.radii().0, resolution))
                }
                _ => None,
            }),
        )?;
        let mut items = Vec::with_capacity(skeleton.len());
        let mut bounds: Option<Aabb> = None;
        let mut min_radius = f64::INFINITY;
        for e in skeleton.elements() {
            let item = Self::item(e, blend);
            min_radius = min_radius.min(e.radii().0).min(e.radii().1);
            let b = Aabb { min: item.lo, max: item.hi };
            bounds = Some(bounds.map_or(b, |x| x.union(&b)));
            items.push(item);
        }
        let boxes: Vec<(DVec3, DVec3)> = items.iter().map(|it| (it.lo, it.hi)).collect();
        let junctions: Vec<PreparedJunction> = skeleton
            .junctions()
            .iter()
            .map(|j| PreparedJunction::new(j, skeleton, &boxes))
            .collect::<Result<_, _>>()?;
        let mut limb_of = vec![None; items.len()];
        for (j, pj) in junctions.iter().enumerate() {
            for l in &pj.limbs {
                limb_of[l.element] = Some(j);
            }
        }
        // The plain (non-limb) elements of each group, in element order.
        let mut by_group: std::collections::BTreeMap<crate::GroupId, Vec<usize>> =
            Default::default();
        for (i, e) in skeleton.elements().iter().enumerate() {
            if limb_of[i].is_none() {
                by_group.entry(e.group()).or_default().push(i);
            }
        }
        let part_of: std::collections::BTreeMap<crate::GroupId, usize> =
            by_group.keys().enumerate().map(|(n, g)| (*g, n)).collect();
        let mut cliques: Vec<Clique> = skeleton
            .blend_cliques()
            .into_iter()
            .map(|groups| {
                let members: Vec<usize> = (0..skeleton.len())
                    .filter(|&i| groups.contains(&skeleton.elements()[i].group()))
                    .collect();
                let plain = members.iter().copied().filter(|&i| limb_of[i].is_none()).collect();
                let mut js: Vec<usize> = members.iter().filter_map(|&i| limb_of[i]).collect();
                js.sort_unstable();
                js.dedup();
                let parts = groups.iter().filter_map(|g| part_of.get(g).copied()).collect();
                Clique { plain, junctions: js, parts }
            })
            .filter(|c| !(c.plain.is_empty() && c.junctions.is_empty()))
            .collect();
        let additive = matches!(blend, Blend::Convolution(_) | Blend::Sum(_));
        let shared = (additive && cliques.len() > 1)
            .then(|| SharedSums { groups: by_group.into_values().collect() });
        if shared.is_none() {
            cliques.iter_mut().for_each(|c| c.parts.clear());
        }
        let cull = CullGrid::new(&items);
        let colors = skeleton.has_colors().then(|| {
            let default = skeleton.default_color().unwrap_or(NEUTRAL_COLOR);
            skeleton.elements().iter().map(|e| e.color().unwrap_or(default)).collect()
        });
        Ok(SkeletonField {
            blend,
            iso: DEFAULT_ISO,
            items,
            cliques,
            shared,
            junctions,
            bounds: bounds.ok_or(SkeletonError::Empty)?,
            seeds: skeleton.seed_points(),
            min_radius,
            cull,
            source: Source {
                elements: skeleton.elements().to_vec(),
                groups: skeleton.groups().to_vec(),
                junctions: skeleton.junctions().len(),
            },
            colors,
            blended_normals: false,
            separable: false,
        })
    }

    /// Where this field's values may differ from `old`'s: boxes covering the reach (old and
    /// new) of every element that was moved, reshaped, given another radius, strength or
    /// group, added or removed; empty when the fields are the same. Outside these boxes the
    /// two fields are equal **bit for bit**, which is what incremental re-meshing relies
    /// on. Why that holds: a point's value is the elements whose boxes of influence hold
    /// it, summed (or blended) in element order within each clique, then the least clique;
    /// an element outside its box is skipped, never added as zero, so an unchanged
    /// sequence of elements around a point gives the same value. Where an element's
    /// contribution is exactly zero beyond its reach (see `reach_boxes`), its box is
    /// replaced by smaller boxes round pieces of its shape: inside its box but beyond its
    /// reach it adds `+0` or `−0`, which changes no sum started at `+0`. It needs the same cliques, blend
    /// and iso value; otherwise (or with junctions, whose density couples their limbs) the
    /// answer is the [`GlobalChange`] that breaks it.
    ///
    /// Elements are matched by position in the list when the count is the same; otherwise
    /// the common beginning and end of the two lists are kept and everything between them
    /// counts as changed (one element added or removed anywhere is found exactly).
    pub fn changes_since(&self, old: &SkeletonField) -> Result<Vec<Aabb>, GlobalChange> {
        if self.blend != old.blend
            || self.iso.to_bits() != old.iso.to_bits()
            || self.separable != old.separable
        {
            return Err(GlobalChange::Blend);
        }
        if self.source.junctions > 0 || old.source.junctions > 0 {
            return Err(GlobalChange::Junctions);
        }
        let used = |s: &Source| {
            let mut g: Vec<crate::GroupId> = s.elements.iter().map(|e| e.group()).collect();
            g.sort_unstable();
            g.dedup();
            g
        };
        if self.source.groups != old.source.groups || used(&self.source) != used(&old.source) {
            return Err(GlobalChange::Groups);
        }
        let (a, b) = (&old.source.elements, &self.source.elements);
        let mut boxes = Vec::new();
        if a.len() == b.len() {
            for (i, (x, y)) in a.iter().zip(b).enumerate() {
                if x != y {
                    old.reach_boxes(i, &mut boxes);
                    self.reach_boxes(i, &mut boxes);
                }
            }
        } else {
            let head = a.iter().zip(b).take_while(|(x, y)| x == y).count();
            let rest = a.len().min(b.len()) - head;
            let tail = a.iter().rev().zip(b.iter().rev()).take(rest).take_while(|(x, y)| x == y);
            let tail = tail.count();
            for i in head..a.len() - tail {
                old.reach_boxes(i, &mut boxes);
            }
            for i in head..b.len() - tail {
                self.reach_boxes(i, &mut boxes);
            }
        }
        Ok(boxes)
    }

    /// Boxes that together hold every point where element `i` may add anything but zero:
    /// its box of influence, or, where the element's contribution is exactly zero farther
    /// than its reach from its shape, boxes round pieces of the shape (a segment's pieces,
    /// cells of a rectangle round a polygon in its plane), each grown by the reach (and a
    /// hair, against rounding). Why: a finger's bones lie askew, so the boxes round their
    /// whole shapes hold far more lattice points than their reach does, and an edit samples
    /// every point in them again (the hand's finger bend: 42 700 points before).
    ///
    /// Exactly zero beyond the reach: convolution with the Wyvill or triweight kernel
    /// (polynomials that vanish at their support, whose line and wedge integrals skip every
    /// part beyond it: a point's value depends on its distances to the shape's points only),
    /// not separable (the separable approximation's support is a cylinder with flat ends,
    /// whose rims reach farther), and polygons in closed form (not rasterised). Anything
    /// else keeps the whole box, whose outside the field skips.
    fn reach_boxes(&self, i: usize, out: &mut Vec<Aabb>) {
        let it = &self.items[i];
        let whole = Aabb { min: it.lo, max: it.hi };
        let exact = matches!(self.blend, Blend::Convolution(Kernel::Wyvill | Kernel::Triweight))
            && !self.separable
            && !matches!(it.conv, Prepared::Image(_));
        if !(exact && it.reach > 0.0 && it.reach.is_finite()) {
            out.push(whole);
            return;
        }
        let reach = it.reach * (1.0 + 1e-9);
        // Pieces at most half a reach long (at most 32 along a side): finer pieces hug a
        // skewed shape more closely, each box being a piece's grown by the whole reach.
        let pieces = |length: f64| ((2.0 * length / reach).ceil() as usize).clamp(1, 32);
        let grown = |points: &[DVec3]| {
            let lo = points.iter().fold(DVec3::INFINITY, |m, p| m.min(*p));
            let hi = points.iter().fold(DVec3::NEG_INFINITY, |m, p| m.max(*p));
            let hair = DVec3::splat(reach + 1e-9 * (1.0 + lo.abs().max(hi.abs()).max_element()));
            // Never larger than the whole box (which holds every piece).
            Aabb { min: (lo - hair).max(whole.min), max: (hi + hair).min(whole.max) }
        };
        match &it.shape {
            Shape::Point(_) => out.push(whole),
            Shape::Segment(s) => {
                let (a, b) = (s.a(), s.b());
                let n = pieces((b - a).length());
                let at = |k: usize| if k == n { b } else { a.lerp(b, k as f64 / n as f64) };
                out.extend((0..n).map(|k| grown(&[at(k), at(k + 1)])));
            }
            Shape::Polygon(p) => {
                let (e1, e2, _) = p.frame();
                let o = p.origin();
                let flat = p.flat_vertices();
                let lo = flat.iter().fold(DVec2::INFINITY, |m, v| m.min(*v));
                let hi = flat.iter().fold(DVec2::NEG_INFINITY, |m, v| m.max(*v));
                let (nx, ny) = (pieces(hi.x - lo.x), pieces(hi.y - lo.y));
                let x = |k: usize| {
                    if k == nx { hi.x } else { lo.x + (hi.x - lo.x) * k as f64 / nx as f64 }
                };
                let y = |k: usize| {
                    if k == ny { hi.y } else { lo.y + (hi.y - lo.y) * k as f64 / ny as f64 }
                };
                let at = |i: usize, j: usize| o + e1 * x(i) + e2 * y(j);
                for j in 0..ny {
                    for i in 0..nx {
                        let (c0, c1) = (DVec2::new(x(i), y(j)), DVec2::new(x(i + 1), y(j + 1)));
                        if meets_polygon(flat, c0, c1) {
                            out.push(grown(&[
                                at(i, j),
                                at(i + 1, j),
                                at(i, j + 1),
                                at(i + 1, j + 1),
                            ]));
                        }
                    }
                }
            }
        }
    }

    fn item(e: &Element, blend: Blend) -> Item {
        let (ra, rb) = e.radii();
        let (wa, wb) = e.strengths();
        let r = ra.max(rb);
        let reach = r * match blend {
            Blend::Convolution(k) | Blend::Sum(k) => k.support(),
            Blend::Union(_) => UNION_CAP,
            Blend::SuperElliptic { range, .. } => 1.0 + range,
            Blend::Combination { range, .. } => 1.0 + 0.5 * range,
        };
        let kernel = match blend {
            Blend::Convolution(k) => k,
            _ => Kernel::Gaussian,
        };
        let taper = match &e.shape {
            Shape::Segment(s) if e.is_tapered() => Some(Taper {
                a: s.a(),
                grad_alpha: (s.b() - s.a()) / (s.b() - s.a()).length_squared(),
                ra,
                dr: rb - ra,
                wa,
                dw: wb - wa,
            }),
            _ => None,
        };
        let conv = match &e.shape {
            Shape::Point(c) => Prepared::Point { c: *c, inv_r: 1.0 / ra, strength: wa },
            Shape::Segment(s) => Prepared::Segment(PreparedSegment::new(
                kernel,
                s,
                ra,
                if taper.is_some() { 1.0 } else { wa },
            )),
            Shape::Polygon(p) => match (e.polygon_method(), e.vertex_weights()) {
                (PolygonMethod::Exact, None) => {
                    Prepared::Polygon(PreparedPolygon::new(kernel, p, ra, e.strength()))
                }
                (PolygonMethod::Exact, Some(w)) => {
                    Prepared::Weighted(PreparedWeighted::new(kernel, p, w, ra, e.strength()))
                }
                (PolygonMethod::Image { resolution }, w) => {
                    let pieces = w.map(|w| crate::weights::fan_pieces(p, w));
                    let weight = e.is_weighted().then(|| {
                        crate::weights::raster_weight(
                            p,
                            pieces.as_deref(),
                            e.weight_image().map(|i| &**i),
                        )
                    });
                    Prepared::Image(ImagePolygon::new(
                        kernel,
                        p,
                        ra,
                        e.strength(),
                        resolution,
                        weight.as_ref().map(|f| f as &dyn Fn(DVec2) -> f64),
                    ))
                }
            },
        };
        let (lo, hi) = e.shape.bounds();
        Item {
            lo: lo - DVec3::splat(reach),
            hi: hi + DVec3::splat(reach),
            reach,
            shape: e.shape.clone(),
            radius: ra,
            strength: wa,
            taper,
            conv,
        }
    }

    /// The same field with another iso value (density blends only; must be positive, since
    /// far from the skeleton the density is 0 and that must be outside).
    pub fn with_iso(mut self, iso: f64) -> Result<SkeletonField, SkeletonError> {
        if !self.blend.has_iso() {
            return Err(SkeletonError::IsoNotApplicable(self.blend.name()));
        }
        check_iso(iso)?;
        self.iso = iso;
        Ok(self)
    }

    /// The same field with the junctions' gradients turned along the blended normals of DIS
    /// appendix A.2 (see [`crate::junction`]): the joint combination surface's own gradient
    /// creases where two limbs' union terms meet out of the joint's plane (the starfish's
    /// webbing); the blended normal is smooth there, so the shading shows no crease. The
    /// gradient keeps its length (the values are unchanged), only its direction near a
    /// junction changes, so it is no longer exactly the field's derivative there; without
    /// junctions this changes nothing.
    pub fn with_blended_normals(mut self, on: bool) -> SkeletonField {
        self.blended_normals = on;
        self
    }

    /// The same field with every segment convolved by the dissertation's separable
    /// approximation (DIS §5.6.10, figs. 5.52 and 5.53) instead of the exact line integral:
    /// the kernel of the distance to the segment's line times the kernel integrated along
    /// it, as the dissertation convolved the B-spline and Wyvill kernels. The same for the
    /// Gaussian, which is separable; for the others it shows how little the approximation
    /// changes (`tests/separable.rs` measures it). Convolution only; `false` restores the
    /// exact integral.
    pub fn with_separable_segments(mut self, on: bool) -> SkeletonField {
        let Blend::Convolution(kernel) = self.blend else {
            return self;
        };
        self.separable = on;
        for it in &mut self.items {
            if let Prepared::Segment(s) = &mut it.conv {
                s.set_separable(kernel, on);
            }
        }
        self
    }

    /// Whether segments use the separable approximation
    /// ([`SkeletonField::with_separable_segments`]).
    pub fn separable_segments(&self) -> bool {
        self.separable
    }

    /// Whether junction gradients follow the blended normals
    /// ([`SkeletonField::with_blended_normals`]).
    pub fn blended_normals(&self) -> bool {
        self.blended_normals
    }

    /// The blend the field was built with; its parameters as given, already validated.
    pub fn blend(&self) -> Blend {
        self.blend
    }

    /// The iso value of a density blend; `None` for the distance blends, whose surface is
    /// where their value is 0.
    pub fn iso(&self) -> Option<f64> {
        self.blend.has_iso().then_some(self.iso)
    }

    /// Elements the field evaluates, junction limbs included: one per element of the
    /// skeleton it was built from (a polyline or curve counts each of its segments).
    pub fn element_count(&self) -> usize {
        self.items.len()
    }

    /// Sets of elements that blend (see the module documentation).
    pub fn clique_count(&self) -> usize {
        self.cliques.len()
    }

    /// One point on each element, where the continuation polygonizer should start.
    pub fn seed_points(&self) -> Vec<DVec3> {
        self.seeds.clone()
    }

    /// The grid that culls elements by their boxes of influence (see the module
    /// documentation), for statistics.
    pub fn cull_grid(&self) -> &CullGrid {
        &self.cull
    }

    /// Whether the skeleton had colours, so that [`SkeletonField::colors`] gives some.
    pub fn has_colors(&self) -> bool {
        self.colors.is_some()
    }

    /// The surface colour at each of `points` (sRGB in `[0, 1]`), or `None` when the
    /// skeleton has no colours.
    ///
    /// As in DIS ch. 6, where the hand's colours are "derived from colors assigned to the
    /// skeletal elements", a point's colour is the average of the element colours weighted
    /// by each element's contribution to the field there, so a surface is its element's
    /// colour where one element dominates and blends smoothly where elements blend. Only the
    /// blend set (clique) whose surface the point is on counts: a finger kept apart from its
    /// neighbour by blend groups does not take the neighbour's colour. The weight is the
    /// element's density for convolution (its convolution, strength included) and the sum
    /// blend (`w·k(d²/r²)`); the distance blends (union, super-elliptic, combination) have
    /// no density, so their weight is the Gaussian kernel of the element's distance in radii,
    /// `k(d²/r²)`, what the sum blend would give. Elements with negative strength carve and give no colour. A point no
    /// element reaches takes its nearest element's colour (in radii). Each point is
    /// independent, so the result does not depend on how the points are batched or on
    /// threads.
    pub fn colors(&self, points: &[DVec3]) -> Option<Vec<[f32; 3]>> {
        let colors = self.colors.as_ref()?;
        let mut selected = Vec::new();
        if matches!(self.blend, Blend::Convolution(_) | Blend::Sum(_)) {
            let mut known = Densities {
                point: 0,
                stamp: vec![0; self.items.len()],
                density: vec![0.0; self.items.len()],
            };
            return Some(
                points
                    .iter()
                    .map(|&p| self.additive_color_at(colors, p, &mut selected, &mut known))
                    .collect(),
            );
        }
        Some(points.iter().map(|&p| self.color_at(colors, p, &mut selected)).collect())
    }

    /// [`SkeletonField::color_at`] for the additive blends (convolution, sum), where an
    /// element's weight in the colour is its share of the field, `max(0, density)`: each
    /// element's density at `p` is computed once and serves every clique's value (the palm
    /// of the hand is in six cliques) and the weights, instead of once per clique and again
    /// per weight. The sums are made in the same order as there, so the colours are the same
    /// bit for bit; the cost is about one value evaluation a point instead of two or more.
    fn additive_color_at(
        &self,
        colors: &[[f32; 3]],
        p: DVec3,
        selected: &mut Vec<usize>,
        known: &mut Densities,
    ) -> [f32; 3] {
        known.point += 1;
        let cell = self.cull.cell_of(p);
        let candidates = self.cull.elements(cell);
        let clique = if self.cliques.len() == 1 {
            &self.cliques[0]
        } else {
            // As `clique_value` sums: the plain elements in order, then the junctions.
            let mut best = (f64::INFINITY, 0);
            for (k, c) in self.cliques.iter().enumerate() {
                let mut v = self.acc_init().v;
                for &e in select(&c.plain, Some(candidates), selected) {
                    if self.items[e].contains(p) {
                        v += self.density(e, p, known);
                    }
                }
                if let Blend::Convolution(k) = self.blend {
                    for &j in &c.junctions {
                        let junction = &self.junctions[j];
                        if junction.contains(p) {
                            v += self.junction_density(junction, k, p);
                        }
                    }
                }
                let v = self.iso - v;
                if v < best.0 {
                    best = (v, k);
                }
            }
            &self.cliques[best.1]
        };
        let plain = select(&clique.plain, Some(candidates), selected);
        let limbs = clique
            .junctions
            .iter()
            .flat_map(|&j| self.junctions[j].limbs.iter().map(|l| l.element));
        let (mut sum, mut total) = ([0.0f64; 3], 0.0f64);
        for e in plain.iter().copied().chain(limbs) {
            if !self.items[e].contains(p) {
                continue;
            }
            let w = self.density(e, p, known).max(0.0);
            if w > 0.0 {
                total += w;
                for k in 0..3 {
                    sum[k] += w * f64::from(colors[e][k]);
                }
            }
        }
        if total > 0.0 {
            return sum.map(|c| (c / total) as f32);
        }
        self.nearest_color(colors, clique, p)
    }

    /// Element `e`'s density at the point `known` is for (its share of an additive blend,
    /// [`SkeletonField::additive`]), computed at most once per point.
    fn density(&self, e: usize, p: DVec3, known: &mut Densities) -> f64 {
        if known.stamp[e] != known.point {
            known.stamp[e] = known.point;
            known.density[e] = self.additive(&self.items[e], p, false).0;
        }
        known.density[e]
    }

    /// Each element's colour, in element order, when any element has one: what
    /// [`SkeletonField::colors`] blends. Two fields with the same elements and the same
    /// colours colour a point the same where no changed element reaches.
    pub fn element_colors(&self) -> Option<&[[f32; 3]]> {
        self.colors.as_deref()
    }

    fn color_at(&self, colors: &[[f32; 3]], p: DVec3, selected: &mut Vec<usize>) -> [f32; 3] {
        let cell = self.cull.cell_of(p);
        let candidates = self.cull.elements(cell);
        // The clique whose field is least at p: the surface p lies on.
        let clique = if self.cliques.len() == 1 {
            &self.cliques[0]
        } else {
            let mut best = (f64::INFINITY, 0);
            for (k, c) in self.cliques.iter().enumerate() {
                let v = self.clique_value(c, p, candidates, selected);
                if v < best.0 {
                    best = (v, k);
                }
            }
            &self.cliques[best.1]
        };
        let mut members: Vec<usize> = select(&clique.plain, Some(candidates), selected).to_vec();
        for &j in &clique.junctions {
            members.extend(self.junctions[j].limbs.iter().map(|l| l.element));
        }
        // Where every element whose box holds p has one colour (skin over most of the hand),
        // the weighted average is that colour whatever the weights: `Σ wᵢc / Σ wᵢ` in `f64`
        // is within a few hundred units of its last place of `c` (one per element summed),
        // far less than half an `f32` unit, so it rounds back to `c`, an `f32`, exactly. Only whether some weight is positive matters then, and the weights are
        // taken in turn until one is (each is an element's convolution, the cost of a field
        // evaluation for a polygon), instead of all of them.
        let mut reaching = members.iter().copied().filter(|&e| self.items[e].contains(p));
        if let Some(first) = reaching.next() {
            let c = colors[first];
            if reaching.all(|e| colors[e] == c) {
                let reaches = members.iter().any(|&e| {
                    let it = &self.items[e];
                    it.contains(p) && self.color_weight(it, p) > 0.0
                });
                if reaches {
                    return c;
                }
                return self.nearest_color(colors, clique, p);
            }
        }
        self.weighted_color(colors, members.iter().copied(), p)
            .unwrap_or_else(|| self.nearest_color(colors, clique, p))
    }

    /// The average of the colours of `members` at `p`, each weighted by its element's
    /// colour weight there (its convolution), every weight taken; `None` where no member
    /// reaches `p`.
    fn weighted_color(
        &self,
        colors: &[[f32; 3]],
        members: impl Iterator<Item = usize>,
        p: DVec3,
    ) -> Option<[f32; 3]> {
        let (mut sum, mut total) = ([0.0f64; 3], 0.0f64);
        for e in members {
            let it = &self.items[e];
            if !it.contains(p) {
                continue;
            }
            let w = self.color_weight(it, p);
            if w > 0.0 {
                total += w;
                for k in 0..3 {
                    sum[k] += w * f64::from(colors[e][k]);
                }
            }
        }
        (total > 0.0).then(|| sum.map(|c| (c / total) as f32))
    }

    /// The colour at a point no element of `clique` reaches: its nearest element's,
    /// measured in radii.
    fn nearest_color(&self, colors: &[[f32; 3]], clique: &Clique, p: DVec3) -> [f32; 3] {
        let all = clique.plain.iter().copied().chain(
            clique
                .junctions
                .iter()
                .flat_map(|&j| self.junctions[j].limbs.iter().map(|l| l.element)),
        );
        let mut nearest = (f64::INFINITY, None);
        for e in all {
            let it = &self.items[e];
            let (r, _, _, _) = it.radius_strength(p);
            let d = (p - it.shape.nearest(p)).length() / r;
            if d < nearest.0 {
                nearest = (d, Some(e));
            }
        }
        nearest.1.map_or(NEUTRAL_COLOR, |e| colors[e])
    }

    /// An element's weight in the colour at `p` (see [`SkeletonField::colors`]).
    fn color_weight(&self, it: &Item, p: DVec3) -> f64 {
        match self.blend {
            Blend::Convolution(k) => self.convolve(k, it, p, false).0.max(0.0),
            Blend::Sum(k) => {
                let (r, _, w, _) = it.radius_strength(p);
                let d2 = (p - it.shape.nearest(p)).length_squared();
                (w * k.value_d(d2 / (r * r)).0).max(0.0)
            }
            _ => {
                let (r, _, w, _) = it.radius_strength(p);
                if w <= 0.0 {
                    return 0.0;
                }
                let d2 = (p - it.shape.nearest(p)).length_squared();
                Kernel::Gaussian.value_d(d2 / (r * r)).0
            }
        }
    }

    /// One clique's field value at `p` (as [`SkeletonField::eval_chunk`] computes it for a
    /// batch), with `candidates` the culling cell's elements.
    fn clique_value(
        &self,
        clique: &Clique,
        p: DVec3,
        candidates: &[u32],
        selected: &mut Vec<usize>,
    ) -> f64 {
        let mut acc = self.acc_init();
        let plain = select(&clique.plain, Some(candidates), selected);
        if let Blend::SuperElliptic { range, angle_scaled: true, .. } = self.blend {
            self.angle_scale(plain, range, p, &mut acc);
        }
        for &e in plain {
            let it = &self.items[e];
            if it.contains(p) {
                self.accumulate(it, p, &mut acc, false);
            }
        }
        if let Blend::Convolution(k) = self.blend {
            for &j in &clique.junctions {
                let junction = &self.junctions[j];
                if junction.contains(p) {
                    acc.v += self.junction_density(junction, k, p);
                }
            }
        }
        self.finish(&acc, p).0
    }

    fn acc_init(&self) -> Acc {
        let v = match self.blend {
            Blend::Union(Falloff::Linear) => UNION_CAP,
            Blend::Union(Falloff::Squared) => UNION_CAP * UNION_CAP,
            _ => 0.0,
        };
        Acc {
            v,
            g: DVec3::ZERO,
            prod: 1.0,
            prod_g: DVec3::ZERO,
            best: [NO_INFLUENCE; 2],
            scale: 1.0,
            scale_g: DVec3::ZERO,
        }
    }

    /// One element's convolution with kernel `k` at `p` (strength included).
    #[inline]
    fn convolve(&self, k: Kernel, it: &Item, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        match &it.conv {
            Prepared::Point { c, inv_r, strength } => {
                let w = (p - *c) * *inv_r;
                let (kv, dk) = k.value_d(w.length_squared());
                (
                    strength * kv,
                    if want_grad { w * (2.0 * strength * dk * inv_r) } else { DVec3::ZERO },
                )
            }
            Prepared::Segment(s) => match &it.taper {
                None => s.eval(k, p, want_grad),
                Some(t) => {
                    let (r, gr, w, gw) = t.at(p);
                    let (v, g, dv_dr) = s.eval_at(k, p, 1.0 / r, want_grad);
                    (w * v, if want_grad { w * (g + dv_dr * gr) + v * gw } else { DVec3::ZERO })
                }
            },
            Prepared::Polygon(poly) => poly.eval(k, p, want_grad),
            Prepared::Weighted(poly) => poly.eval(k, p, want_grad),
            Prepared::Image(img) => img.eval(k, p, want_grad),
        }
    }

    /// Adds one element's influence at `p` (already known to be inside its box).
    #[inline]
    /// One element's share of an additive blend (convolution, sum) at `p`, and its gradient
    /// (zero without `want_grad`); zero for the other blends.
    fn additive(&self, it: &Item, p: DVec3, want_grad: bool) -> (f64, DVec3) {
        match self.blend {
            Blend::Convolution(k) => self.convolve(k, it, p, want_grad),
            Blend::Sum(k) => {
                let v = p - it.shape.nearest(p);
                let (r, gr, w, gw) = it.radius_strength(p);
                let d2 = v.length_squared();
                let (kv, dk) = k.value_d(d2 / (r * r));
                let g = if want_grad {
                    (v - gr * (d2 / r)) * (2.0 * w * dk / (r * r)) + gw * kv
                } else {
                    DVec3::ZERO
                };
                (w * kv, g)
            }
            _ => (0.0, DVec3::ZERO),
        }
    }

    fn accumulate(&self, it: &Item, p: DVec3, acc: &mut Acc, want_grad: bool) {
        match self.blend {
            Blend::Convolution(_) | Blend::Sum(_) => {
                let (v, g) = self.additive(it, p, want_grad);
                acc.v += v;
                acc.g += g;
            }
            Blend::Union(falloff) => {
                let v = p - it.shape.nearest(p);
                let d = v.length();
                let (r, gr, _, _) = it.radius_strength(p);
                let (x, g) = match falloff {
                    Falloff::Linear => (
                        d / r,
                        if d > 0.0 { v / (d * r) } else { DVec3::ZERO } - gr * (d / (r * r)),
                    ),
                    Falloff::Squared => {
                        let r2 = r * r;
                        (d * d / r2, v * (2.0 / r2) - gr * (2.0 * d * d / (r2 * r)))
                    }
                };
                if x < acc.v {
                    acc.v = x;
                    acc.g = g;
                }
            }
            Blend::SuperElliptic { range, thumbweight, .. } => {
                let (a, ga, _) = it.in_ranges(p, range, false);
                let x = 1.0 - a / acc.scale;
                if x > 0.0 {
                    acc.v += x.powf(thumbweight);
                    if want_grad {
                        let gx = (a * acc.scale_g / acc.scale - ga) / acc.scale;
                        acc.g += gx * (thumbweight * x.powf(thumbweight - 1.0));
                    }
                }
            }
            Blend::Combination { range, .. } => {
                let (a, ga, nearest) = it.in_ranges(p, range, true);
                let (h, dh) = decay(0.5 + a);
                if h > 0.0 {
                    let grad = ga * dh;
                    acc.prod_g = acc.prod_g * (1.0 - h) - acc.prod * grad;
                    acc.prod *= 1.0 - h;
                    let inf = Influence { p: h, grad, nearest };
                    if h > acc.best[0].p {
                        acc.best[1] = acc.best[0];
                        acc.best[0] = inf;
                    } else if h > acc.best[1].p {
                        acc.best[1] = inf;
                    }
                }
            }
        }
    }

    /// For the angle-scaled super-elliptic blend: finds the two elements nearest `p` in
    /// units of their ranges and sets the range factor `1 − cos θ` from their gradients.
    fn angle_scale(&self, elements: &[usize], range: f64, p: DVec3, acc: &mut Acc) {
        let mut best: [(f64, Option<Nearest>); 2] = [(f64::INFINITY, None), (f64::INFINITY, None)];
        for &e in elements {
            let it = &self.items[e];
            if !it.contains(p) {
                continue;
            }
            let (a, _, n) = it.in_ranges(p, range, true);
            if a < best[0].0 {
                best[1] = best[0];
                best[0] = (a, Some(n));
            } else if a < best[1].0 {
                best[1] = (a, Some(n));
            }
        }
        if let (Some(n0), Some(n1)) = (best[0].1, best[1].1) {
            // cos θ between the gradients p − nᵢ equals that between the vectors p → nᵢ.
            let (c, gc) = convexity(p, &n0, &n1);
            let s = 1.0 - c;
            if s > MIN_ANGLE_SCALE {
                acc.scale = s;
                acc.scale_g = -gc;
            } else {
                acc.scale = MIN_ANGLE_SCALE;
                acc.scale_g = DVec3::ZERO;
            }
        }
    }

    /// A junction's density at `p` and, with `want_grad`, its gradient by central
    /// differences (zero without).
    fn junction_share(
        &self,
        junction: &PreparedJunction,
        k: Kernel,
        p: DVec3,
        want_grad: bool,
    ) -> (f64, DVec3) {
        let v = self.junction_density(junction, k, p);
        let mut g = DVec3::ZERO;
        if want_grad {
            let h = junction.step;
            for axis in 0..3 {
                let mut dp = DVec3::ZERO;
                dp[axis] = h;
                g[axis] = (self.junction_density(junction, k, p + dp)
                    - self.junction_density(junction, k, p - dp))
                    / (2.0 * h);
            }
            if self.blended_normals
                && let Some(n) = junction.blended_normal(k, p, |e, p| self.limb_at(e, k, p))
            {
                // The density falls outward: its gradient points along −n.
                g = -g.length() * n;
            }
        }
        (v, g)
    }

    /// One junction limb's convolution (value, gradient), radius and strength at `p`.
    fn limb_at(&self, e: usize, k: Kernel, p: DVec3) -> (f64, DVec3, f64, f64) {
        let it = &self.items[e];
        if !it.contains(p) {
            return (0.0, DVec3::ZERO, it.radius, 0.0);
        }
        let (v, g) = self.convolve(k, it, p, true);
        let (r, _, w, _) = it.radius_strength(p);
        (v, g, r, w)
    }

    /// A junction's combined density at `p` (see [`crate::junction`]).
    fn junction_density(&self, j: &PreparedJunction, k: Kernel, p: DVec3) -> f64 {
        j.density(k, p, |e, p| self.limb_at(e, k, p))
    }

    /// The clique's field value (inside negative) and gradient from its accumulator.
    #[inline]
    fn finish(&self, acc: &Acc, p: DVec3) -> (f64, DVec3) {
        match self.blend {
            Blend::Convolution(_) | Blend::Sum(_) => (self.iso - acc.v, -acc.g),
            Blend::Union(_) => (acc.v - 1.0, acc.g),
            Blend::SuperElliptic { .. } => (1.0 - acc.v, -acc.g),
            Blend::Combination { clamp, .. } => {
                let b = 1.0 - acc.prod;
                let gb = -acc.prod_g;
                let u = acc.best[0].p;
                let gu = acc.best[0].grad;
                let (mut c, mut gc) = if acc.best[1].p > 0.0 {
                    convexity(p, &acc.best[0].nearest, &acc.best[1].nearest)
                } else {
                    (0.0, DVec3::ZERO)
                };
                if clamp && c < 0.0 {
                    c = 0.0;
                    gc = DVec3::ZERO;
                }
                let density = b + c * (u - b);
                let g = gb + gc * (u - b) + c * (gu - gb);
                (self.iso - density, -g)
            }
        }
    }

    /// Adds the influence of `elements` at each point to its accumulator.
    fn accumulate_elements(
        &self,
        elements: &[usize],
        pts: &[DVec3],
        accs: &mut [Acc],
        want_grad: bool,
    ) {
        for &e in elements {
            let it = &self.items[e];
            for (p, acc) in pts.iter().zip(accs.iter_mut()) {
                if it.contains(*p) {
                    self.accumulate(it, *p, acc, want_grad);
                }
            }
        }
    }

    /// Evaluates a batch; gradients too when `grads` is given. The points are sorted by
    /// culling cell and each cell's points are evaluated against its elements only (see the
    /// module documentation): the values are those of [`SkeletonField::eval_batch_unculled`].
    fn eval_batch(&self, points: &[DVec3], values: &mut [f64], mut grads: Option<&mut [DVec3]>) {
        debug_assert_eq!(points.len(), values.len());
        let mut scratch = Scratch::default();
        if points.len() == 1 {
            let cell = self.cull.cell_of(points[0]);
            let (v, g) = (&mut values[..1], grads.as_deref_mut().map(|g| &mut g[..1]));
            self.eval_chunk(points, Some(self.cull.elements(cell)), v, g, &mut scratch);
            return;
        }
        let mut vals = [0.0; CHUNK];
        let mut gs = [DVec3::ZERO; CHUNK];
        self.by_cell(points, |pts, candidates, indices| {
            let n = pts.len();
            let g = grads.is_some().then_some(&mut gs[..n]);
            self.eval_chunk(pts, Some(candidates), &mut vals[..n], g, &mut scratch);
            for (k, &i) in indices.iter().enumerate() {
                values[i as usize] = vals[k];
                if let Some(g) = grads.as_deref_mut() {
                    g[i as usize] = gs[k];
                }
            }
        });
    }

    /// Calls `chunk` with the points of `points` grouped by culling cell, at most [`CHUNK`]
    /// at a time: the group's points, its cell's candidate elements and the points' indices
    /// in `points`. Sorting by (cell, index) keeps each cell's points in their batch order,
    /// so a point's group, and with it its value, depends on its cell alone.
    fn by_cell(&self, points: &[DVec3], mut chunk: impl FnMut(&[DVec3], &[u32], &[u32])) {
        let mut order: Vec<(u32, u32)> =
            (0..points.len()).map(|i| (self.cull.cell_of(points[i]) as u32, i as u32)).collect();
        order.sort_unstable();
        let mut pts = [DVec3::ZERO; CHUNK];
        let mut indices = [0u32; CHUNK];
        let mut start = 0;
        while start < order.len() {
            let cell = order[start].0;
            let mut end = start + 1;
            while end < order.len() && end - start < CHUNK && order[end].0 == cell {
                end += 1;
            }
            let n = end - start;
            for (k, &(_, i)) in order[start..end].iter().enumerate() {
                pts[k] = points[i as usize];
                indices[k] = i;
            }
            chunk(&pts[..n], self.cull.elements(cell as usize), &indices[..n]);
            start = end;
        }
    }

    /// Evaluates a batch visiting every element at every point: the reference the culled
    /// [`SkeletonField::eval_batch`] must equal bit for bit.
    #[cfg(test)]
    fn eval_batch_unculled(
        &self,
        points: &[DVec3],
        values: &mut [f64],
        mut grads: Option<&mut [DVec3]>,
    ) {
        let mut scratch = Scratch::default();
        for start in (0..points.len()).step_by(CHUNK) {
            let end = (start + CHUNK).min(points.len());
            let g = grads.as_deref_mut().map(|g| &mut g[start..end]);
            self.eval_chunk(&points[start..end], None, &mut values[start..end], g, &mut scratch);
        }
    }

    /// [`SkeletonField::eval_chunk`] for the additive blends (convolution, sum), whose
    /// running state is a value and a gradient: the general accumulator carries every
    /// blend's state (some 350 bytes), and filling it for every point, group and clique cost
    /// more than the elements themselves where few reach. The sums are added in the same
    /// order as there, so the values are the same to the bit.
    fn eval_chunk_additive(
        &self,
        pts: &[DVec3],
        candidates: Option<&[u32]>,
        values: &mut [f64],
        mut grads: Option<&mut [DVec3]>,
        scratch: &mut Scratch,
    ) {
        let want_grad = grads.is_some();
        let n = pts.len();
        let Scratch { group_sums, sums, best, selected, .. } = scratch;
        let zero = (0.0, DVec3::ZERO);
        let add = |elements: &[usize], sums: &mut [(f64, DVec3)]| {
            for &e in elements {
                let it = &self.items[e];
                for (p, s) in pts.iter().zip(sums.iter_mut()) {
                    if it.contains(*p) {
                        let (v, g) = self.additive(it, *p, want_grad);
                        s.0 += v;
                        s.1 += g;
                    }
                }
            }
        };
        if let Some(shared) = &self.shared {
            group_sums.resize(shared.groups.len(), vec![zero; CHUNK]);
            for (elements, sums) in shared.groups.iter().zip(group_sums.iter_mut()) {
                sums[..n].fill(zero);
                add(select(elements, candidates, selected), &mut sums[..n]);
            }
        }
        sums.resize(CHUNK, zero);
        best.resize(CHUNK, zero);
        let (sums, best) = (&mut sums[..n], &mut best[..n]);
        best.fill((f64::INFINITY, DVec3::ZERO));
        for clique in &self.cliques {
            sums.fill(zero);
            if self.shared.is_some() {
                for &part in &clique.parts {
                    for (s, g) in sums.iter_mut().zip(&group_sums[part][..n]) {
                        s.0 += g.0;
                        s.1 += g.1;
                    }
                }
            } else {
                add(select(&clique.plain, candidates, selected), sums);
            }
            if let Blend::Convolution(k) = self.blend {
                for &j in &clique.junctions {
                    let junction = &self.junctions[j];
                    for (p, s) in pts.iter().zip(sums.iter_mut()) {
                        if junction.contains(*p) {
                            let (v, g) = self.junction_share(junction, k, *p, want_grad);
                            s.0 += v;
                            s.1 += g;
                        }
                    }
                }
            }
            for (s, b) in sums.iter().zip(best.iter_mut()) {
                // `finish` of an additive blend.
                let f = self.iso - s.0;
                if f < b.0 {
                    *b = (f, -s.1);
                }
            }
        }
        for (i, b) in best.iter().enumerate() {
            values[i] = b.0;
            if let Some(g) = grads.as_deref_mut() {
                g[i] = b.1;
            }
        }
    }

    /// [`SkeletonField::eval_batch`] with gradients and, for the additive blends, each
    /// point's colour from the densities the value sums anyway ([`Field::eval_grad_color_many`]):
    /// painting a vertex then costs almost nothing beyond the evaluation root finding makes
    /// next to it. The points are grouped by culling cell as there; a point's value, gradient
    /// and colour depend on its cell alone, not on the batch.
    fn eval_batch_colored(
        &self,
        palette: &[[f32; 3]],
        points: &[DVec3],
        values: &mut [f64],
        grads: &mut [DVec3],
        colors: &mut [[f32; 3]],
    ) {
        debug_assert_eq!(points.len(), values.len());
        let mut scratch = ColorScratch::default();
        let mut vals = [0.0; CHUNK];
        let mut gs = [DVec3::ZERO; CHUNK];
        let mut cs = [[0f32; 3]; CHUNK];
        self.by_cell(points, |pts, candidates, indices| {
            let n = pts.len();
            let out = (&mut vals[..n], &mut gs[..n], &mut cs[..n]);
            self.eval_chunk_colored(palette, pts, candidates, out, &mut scratch);
            for (k, &i) in indices.iter().enumerate() {
                values[i as usize] = vals[k];
                grads[i as usize] = gs[k];
                colors[i as usize] = cs[k];
            }
        });
    }

    /// [`SkeletonField::eval_chunk_additive`] with gradients, summing each element's colour
    /// weighted by `max(0, density)` beside its density: the value and gradient are summed
    /// over the same elements in the same order, so they are that function's bit for bit (a
    /// test holds the two together), and the colour is [`SkeletonField::colors`]'s (the
    /// least clique's members, limbs of its junctions included; the nearest element's where
    /// none reaches), up to the order of its weighted sum.
    fn eval_chunk_colored(
        &self,
        palette: &[[f32; 3]],
        pts: &[DVec3],
        candidates: &[u32],
        (values, grads, colors): (&mut [f64], &mut [DVec3], &mut [[f32; 3]]),
        scratch: &mut ColorScratch,
    ) {
        let n = pts.len();
        let ColorScratch { group_sums, sums, best, selected } = scratch;
        let zero = ColorSum::default();
        let add = |elements: &[usize], sums: &mut [ColorSum]| {
            for &e in elements {
                let it = &self.items[e];
                let c = palette[e].map(f64::from);
                for (p, s) in pts.iter().zip(sums.iter_mut()) {
                    if it.contains(*p) {
                        let (v, g) = self.additive(it, *p, true);
                        s.v += v;
                        s.g += g;
                        if v > 0.0 {
                            s.add_color(v, c);
                        }
                    }
                }
            }
        };
        if let Some(shared) = &self.shared {
            group_sums.resize(shared.groups.len(), vec![zero; CHUNK]);
            for (elements, sums) in shared.groups.iter().zip(group_sums.iter_mut()) {
                sums[..n].fill(zero);
                add(select(elements, Some(candidates), selected), &mut sums[..n]);
            }
        }
        sums.resize(CHUNK, zero);
        best.resize(CHUNK, (f64::INFINITY, 0, zero));
        let (sums, best) = (&mut sums[..n], &mut best[..n]);
        best.fill((f64::INFINITY, 0, zero));
        for (k, clique) in self.cliques.iter().enumerate() {
            sums.fill(zero);
            if self.shared.is_some() {
                for &part in &clique.parts {
                    for (s, g) in sums.iter_mut().zip(&group_sums[part][..n]) {
                        s.v += g.v;
                        s.g += g.g;
                        for (a, b) in s.color.iter_mut().zip(g.color) {
                            *a += b;
                        }
                    }
                }
            } else {
                add(select(&clique.plain, Some(candidates), selected), sums);
            }
            if let Blend::Convolution(kernel) = self.blend {
                for &j in &clique.junctions {
                    let junction = &self.junctions[j];
                    for (p, s) in pts.iter().zip(sums.iter_mut()) {
                        if junction.contains(*p) {
                            let (v, g) = self.junction_share(junction, kernel, *p, true);
                            s.v += v;
                            s.g += g;
                        }
                    }
                }
            }
            for (s, b) in sums.iter().zip(best.iter_mut()) {
                // `finish` of an additive blend.
                let f = self.iso - s.v;
                if f < b.0 {
                    *b = (f, k, ColorSum { g: -s.g, ..*s });
                }
            }
        }
        for (i, (f, k, s)) in best.iter_mut().enumerate() {
            values[i] = *f;
            grads[i] = s.g;
            let (p, clique) = (pts[i], &self.cliques[*k]);
            // The limbs of the clique's junctions weigh in by their own densities.
            for &j in &clique.junctions {
                for limb in &self.junctions[j].limbs {
                    let it = &self.items[limb.element];
                    if it.contains(p) {
                        let w = self.additive(it, p, false).0;
                        if w > 0.0 {
                            s.add_color(w, palette[limb.element].map(f64::from));
                        }
                    }
                }
            }
            let [r, g, b, total] = s.color;
            colors[i] = if total > 0.0 {
                [r, g, b].map(|c| (c / total) as f32)
            } else {
                self.nearest_color(palette, clique, p)
            };
        }
    }

    /// Evaluates at most [`CHUNK`] points. With `candidates` (ascending element indices, a
    /// culling cell's), only those elements are visited: the caller guarantees that every
    /// other element's box misses every point.
    fn eval_chunk(
        &self,
        pts: &[DVec3],
        candidates: Option<&[u32]>,
        values: &mut [f64],
        mut grads: Option<&mut [DVec3]>,
        scratch: &mut Scratch,
    ) {
        debug_assert!(pts.len() <= CHUNK);
        if matches!(self.blend, Blend::Convolution(_) | Blend::Sum(_)) {
            self.eval_chunk_additive(pts, candidates, values, grads, scratch);
            return;
        }
        let want_grad = grads.is_some();
        let init = self.acc_init();
        {
            let n = pts.len();
            let Scratch { group_accs, selected, accs, best, .. } = scratch;
            // Only the first `n` of each are used: a chunk of a culling cell is often short,
            // and the accumulators are large.
            accs.resize(CHUNK, init);
            best.resize(CHUNK, (0.0, DVec3::ZERO));
            let (accs, best) = (&mut accs[..n], &mut best[..n]);
            best.fill((f64::INFINITY, DVec3::ZERO));
            // Each group's sum once, when the cliques share them.
            if let Some(shared) = &self.shared {
                group_accs.resize(shared.groups.len(), vec![init; CHUNK]);
                for (elements, accs) in shared.groups.iter().zip(group_accs.iter_mut()) {
                    accs[..n].fill(init);
                    let elements = select(elements, candidates, selected);
                    self.accumulate_elements(elements, pts, &mut accs[..n], want_grad);
                }
            }
            for clique in &self.cliques {
                accs.fill(init);
                // Shared sums (additive blends only) need not visit the clique's elements.
                let plain =
                    self.shared.is_none().then(|| select(&clique.plain, candidates, selected));
                if let Blend::SuperElliptic { range, angle_scaled: true, .. } = self.blend {
                    let plain = plain.unwrap_or(&clique.plain);
                    for (p, acc) in pts.iter().zip(accs.iter_mut()) {
                        self.angle_scale(plain, range, *p, acc);
                    }
                }
                if self.shared.is_some() {
                    for &part in &clique.parts {
                        for (acc, g) in accs.iter_mut().zip(&group_accs[part][..pts.len()]) {
                            acc.v += g.v;
                            acc.g += g.g;
                        }
                    }
                } else {
                    let plain = plain.unwrap_or(&clique.plain);
                    self.accumulate_elements(plain, pts, accs, want_grad);
                }
                if let Blend::Convolution(k) = self.blend {
                    for &j in &clique.junctions {
                        let junction = &self.junctions[j];
                        for (p, acc) in pts.iter().zip(accs.iter_mut()) {
                            if !junction.contains(*p) {
                                continue;
                            }
                            let (v, g) = self.junction_share(junction, k, *p, want_grad);
                            acc.v += v;
                            if want_grad {
                                acc.g += g;
                            }
                        }
                    }
                }
                for ((p, acc), b) in pts.iter().zip(accs.iter()).zip(best.iter_mut()) {
                    let (f, g) = self.finish(acc, *p);
                    if f < b.0 {
                        *b = (f, g);
                    }
                }
            }
            for (i, b) in best[..pts.len()].iter().enumerate() {
                values[i] = b.0;
                if let Some(g) = grads.as_deref_mut() {
                    g[i] = b.1;
                }
            }
        }
    }
}

/// One point's running sum for [`SkeletonField::eval_chunk_colored`]: density, its
/// gradient, and `Σ w·colour` (three channels) with `Σ w` over the positive densities `w`.
#[derive(Clone, Copy, Default)]
struct ColorSum {
    v: f64,
    g: DVec3,
    color: [f64; 4],
}

impl ColorSum {
    #[inline]
    fn add_color(&mut self, w: f64, c: [f64; 3]) {
        for (sum, channel) in self.color.iter_mut().zip(c) {
            *sum += w * channel;
        }
        self.color[3] += w;
    }
}

/// Buffers of [`SkeletonField::eval_batch_colored`].
#[derive(Default)]
struct ColorScratch {
    group_sums: Vec<Vec<ColorSum>>,
    sums: Vec<ColorSum>,
    /// Each point's least clique value so far, that clique, and its sums.
    best: Vec<(f64, usize, ColorSum)>,
    selected: Vec<usize>,
}

/// Buffers one batch evaluation reuses across its chunks.
#[derive(Default)]
struct Scratch {
    /// Each shared group's sums (additive blends).
    group_sums: Vec<Vec<(f64, DVec3)>>,
    /// One clique's sums (additive blends).
    sums: Vec<(f64, DVec3)>,
    /// Each shared group's accumulators.
    group_accs: Vec<Vec<Acc>>,
    /// One clique's accumulators.
    accs: Vec<Acc>,
    /// Each point's least clique value so far, with its gradient.
    best: Vec<(f64, DVec3)>,
    /// The elements of one list that a culling cell keeps.
    selected: Vec<usize>,
}

/// The elements of `list` that are also in `candidates` (both ascending), in order; all of
/// `list` without candidates.
///
/// Why not a plain merge: a culling cell lists a few dozen elements, a clique may list
/// thousands (random-1000's one clique is every element), and walking the whole list for
/// every chunk of points was a seventh of meshing random-1000. A list that is every
/// element from 0 on (a distinct ascending list whose last entry is its length less one)
/// holds every candidate below its length; any other list is searched from each candidate
/// by galloping (steps doubling, then a binary search), so its long runs between candidates
/// are skipped in a few steps; a list at most eight times as long as the candidates (the
/// hand's groups) is merged with them.
#[inline]
fn select<'a>(
    list: &'a [usize],
    candidates: Option<&[u32]>,
    out: &'a mut Vec<usize>,
) -> &'a [usize] {
    let Some(cand) = candidates else { return list };
    out.clear();
    if list.last().is_some_and(|&l| l + 1 == list.len()) {
        out.extend(cand.iter().map(|&c| c as usize).take_while(|&c| c < list.len()));
        return out;
    }
    let mut i = 0;
    if list.len() <= 8 * cand.len() {
        // Short lists (the hand's groups): a plain merge is cheaper than searching.
        let mut j = 0;
        while i < list.len() && j < cand.len() {
            let c = cand[j] as usize;
            match list[i].cmp(&c) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    out.push(c);
                    i += 1;
                    j += 1;
                }
            }
        }
        return out;
    }
    for &c in cand {
        let c = c as usize;
        let rest = &list[i..];
        // rest[..lo] < c; rest[hi] ≥ c or hi is past the end.
        let mut hi = 1;
        while hi < rest.len() && rest[hi] < c {
            hi *= 2;
        }
        let lo = hi / 2;
        let hi = hi.min(rest.len());
        i += lo + rest[lo..hi].partition_point(|&x| x < c);
        if i == list.len() {
            break;
        }
        if list[i] == c {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// Element densities known at one point ([`SkeletonField::additive_color_at`]): an
/// element's is current where its stamp is the point's number.
struct Densities {
    point: u64,
    stamp: Vec<u64>,
    density: Vec<f64>,
}

/// The most cells a culling grid has per element (and at least [`CULL_MIN_CELLS`]).
const CULL_CELLS_PER_ELEMENT: usize = 8;
/// The fewest cells a culling grid aims at.
const CULL_MIN_CELLS: usize = 64;
/// The most cells a culling grid has.
const CULL_MAX_CELLS: usize = 1 << 18;
/// The most (cell, element) entries per element, on average, before the grid is coarsened:
/// elements with boxes far larger than a cell would otherwise be listed in very many cells.
const CULL_ENTRIES_PER_ELEMENT: usize = 64;

/// A uniform grid over the elements' boxes of influence: for each cell, the elements whose
/// boxes meet it, in ascending element order (the dissertation's bounding boxes, §3.7, with a
/// spatial index so that a point need not test every box).
///
/// A point's cell is found by the same monotone function of its coordinates as each box's
/// range of cells, so a point inside a box always lies in one of the box's cells, whatever
/// the rounding; points outside the grid (or NaN) are clamped to a border cell, where every
/// element's box test still rejects them.
#[derive(Clone, Debug)]
pub struct CullGrid {
    origin: DVec3,
    /// Cells per unit length along each axis.
    scale: DVec3,
    dims: [usize; 3],
    /// `elements[start[c]..start[c + 1]]` are cell `c`'s elements.
    start: Vec<u32>,
    elements: Vec<u32>,
}

impl CullGrid {
    fn new(items: &[Item]) -> CullGrid {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for it in items {
            lo = lo.min(it.lo);
            hi = hi.max(it.hi);
        }
        let size = (hi - lo).max(DVec3::ZERO);
        let target = (CULL_CELLS_PER_ELEMENT * items.len()).clamp(CULL_MIN_CELLS, CULL_MAX_CELLS);
        // Cubic cells, about `target` of them; thin axes get one cell.
        let longest = size.max_element();
        let volume =
            size.x.max(longest * 1e-3) * size.y.max(longest * 1e-3) * size.z.max(longest * 1e-3);
        let mut edge = (volume / target as f64).cbrt();
        let limit = (CULL_ENTRIES_PER_ELEMENT * items.len()) as u64;
        loop {
            // Coarsened until the entries fit, counted before anything is allocated: a
            // scene of many elements with large boxes would otherwise list every element in
            // every cell (gigabytes) before the first coarsening.
            if let Some(grid) = Self::build(items, lo, size, edge, limit) {
                return grid;
            }
            edge *= 1.5;
        }
    }

    /// The grid of cells of side `edge`, or `None` when it would hold more than `limit`
    /// (cell, element) entries and can still be coarsened.
    fn build(
        items: &[Item],
        origin: DVec3,
        size: DVec3,
        edge: f64,
        limit: u64,
    ) -> Option<CullGrid> {
        let mut dims = [1usize; 3];
        let mut scale = DVec3::ZERO;
        for a in 0..3 {
            let n = (size[a] / edge).ceil();
            if n.is_finite() && n > 1.0 {
                dims[a] = (n as usize).min(CULL_MAX_CELLS);
                scale[a] = dims[a] as f64 / size[a];
            }
        }
        let mut grid = CullGrid { origin, scale, dims, start: Vec::new(), elements: Vec::new() };
        let cells = dims[0] * dims[1] * dims[2];
        // Count, then fill: cells are listed in element order because elements are visited
        // in order.
        let mut count = vec![0u32; cells + 1];
        let ranges: Vec<([usize; 3], [usize; 3])> =
            items.iter().map(|it| (grid.coords(it.lo), grid.coords(it.hi))).collect();
        let entries = ranges.iter().fold(0u64, |n, (a, b)| {
            let span =
                (0..3).fold(1u64, |m, k| m.saturating_mul((b[k].saturating_sub(a[k]) + 1) as u64));
            n.saturating_add(span)
        });
        if entries > limit && dims.iter().any(|&d| d > 1) && edge.is_finite() {
            return None;
        }
        let each = |(a, b): &([usize; 3], [usize; 3]), f: &mut dyn FnMut(usize)| {
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        f(x + dims[0] * (y + dims[1] * z));
                    }
                }
            }
        };
        for r in &ranges {
            each(r, &mut |c| count[c + 1] += 1);
        }
        for c in 0..cells {
            count[c + 1] += count[c];
        }
        let mut next = count.clone();
        grid.elements = vec![0; count[cells] as usize];
        for (e, r) in ranges.iter().enumerate() {
            each(r, &mut |c| {
                grid.elements[next[c] as usize] = e as u32;
                next[c] += 1;
            });
        }
        grid.start = count;
        Some(grid)
    }

    /// The cell coordinates of `p`, clamped to the grid; monotone in each coordinate.
    #[inline]
    fn coords(&self, p: DVec3) -> [usize; 3] {
        let c = (p - self.origin) * self.scale;
        // `max` sends NaN to 0; the cast saturates and truncates (a floor, being ≥ 0).
        [0, 1, 2].map(|a| (c[a].max(0.0) as usize).min(self.dims[a] - 1))
    }

    /// The index of `p`'s cell.
    #[inline]
    fn cell_of(&self, p: DVec3) -> usize {
        let [x, y, z] = self.coords(p);
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// The elements whose boxes meet cell `cell`, ascending.
    #[inline]
    fn elements(&self, cell: usize) -> &[u32] {
        &self.elements[self.start[cell] as usize..self.start[cell + 1] as usize]
    }

    /// Cells along x, y and z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The mean number of elements listed per cell: what a point visits instead of every
    /// element.
    pub fn mean_elements_per_cell(&self) -> f64 {
        self.elements.len() as f64 / (self.start.len() - 1) as f64
    }
}

/// Wyvill's decay `h(x)`: 1 for `x ≤ 0`, `(1 − x²)²(9 − 4x²)/9` on `[0, 1]`, 0 beyond; and
/// `dh/dx`. Flat at both ends, ½ at `x = ½` (DIS fig. 5.31 asks for exactly these).
fn decay(x: f64) -> (f64, f64) {
    if x <= 0.0 {
        (1.0, 0.0)
    } else if x >= 1.0 {
        (0.0, 0.0)
    } else {
        let x2 = x * x;
        let a = 1.0 - x2;
        (a * a * (9.0 - 4.0 * x2) / 9.0, (-4.0 * x * a * (9.0 - 4.0 * x2) - 8.0 * x * a * a) / 9.0)
    }
}

/// `cos θ` between the vectors from `p` to two nearest points (DIS eq. 5.15's
/// ConvexityMeasure) and its gradient; 0 where either vector vanishes.
fn convexity(p: DVec3, n1: &Nearest, n2: &Nearest) -> (f64, DVec3) {
    let v1 = n1.point - p;
    let v2 = n2.point - p;
    let (l1, l2) = (v1.length(), v2.length());
    if l1 == 0.0 || l2 == 0.0 {
        return (0.0, DVec3::ZERO);
    }
    let (u1, u2) = (v1 / l1, v2 / l2);
    let c = u1.dot(u2);
    // ∂v/∂p = J − I (J symmetric), ∂c/∂v1 = (u2 − c·u1)/|v1|.
    let m1 = n1.jacobian - DMat3::IDENTITY;
    let m2 = n2.jacobian - DMat3::IDENTITY;
    let g = m1.transpose() * ((u2 - c * u1) / l1) + m2.transpose() * ((u1 - c * u2) / l2);
    (c, g)
}

impl Field for SkeletonField {
    fn eval(&self, p: DVec3) -> f64 {
        let mut v = [0.0];
        self.eval_batch(&[p], &mut v, None);
        v[0]
    }

    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        self.eval_batch(points, out, None);
    }

    /// The whole layer as one batch, so that culling sorts all of its points by cell
    /// (rows alone would give each cell only a few points).
    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        debug_assert_eq!(xs.len() * ys.len(), out.len());
        let points: Vec<DVec3> =
            ys.iter().flat_map(|&y| xs.iter().map(move |&x| DVec3::new(x, y, z))).collect();
        self.eval_batch(&points, out, None);
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let mut v = [0.0];
        let mut g = [DVec3::ZERO];
        self.eval_batch(&[p], &mut v, Some(&mut g));
        g[0]
    }

    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        self.eval_batch(points, values, Some(grads));
    }

    fn has_colors(&self) -> bool {
        self.colors.is_some()
    }

    fn colors_many(&self, points: &[DVec3], colors: &mut [[f32; 3]]) -> bool {
        match self.colors(points) {
            Some(c) => {
                colors.copy_from_slice(&c);
                true
            }
            None => false,
        }
    }

    /// For the additive blends, the colours from the densities the values sum
    /// (`eval_batch_colored`); otherwise the two calls.
    fn eval_grad_color_many(
        &self,
        points: &[DVec3],
        values: &mut [f64],
        grads: &mut [DVec3],
        colors: &mut [[f32; 3]],
    ) -> bool {
        match (&self.colors, self.blend) {
            (Some(palette), Blend::Convolution(_) | Blend::Sum(_)) => {
                self.eval_batch_colored(palette, points, values, grads, colors);
                true
            }
            _ => {
                self.eval_batch(points, values, Some(grads));
                self.colors_many(points, colors)
            }
        }
    }

    fn gradient_step(&self) -> f64 {
        1e-4 * self.min_radius
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
    use crate::GroupId;

    /// `select` keeps exactly the candidates in the list, in order: lists that are every
    /// element from 0 (its shortcut), lists with gaps, short and long, empty lists and
    /// candidates, candidates beyond the list's end.
    #[test]
    fn select_keeps_the_candidates_in_the_list() {
        let mut seed = 0x1234_5678_9abc_def1_u64;
        let mut next = |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
        let mut out = Vec::new();
        for case in 0..3000 {
            let n = next(300) as usize;
            // Every element below `n`, or each with a chance that varies by case.
            let keep = if case % 4 == 0 { 100 } else { next(101) };
            let list: Vec<usize> = (0..n).filter(|_| next(100) < keep).collect();
            let take = next(101);
            let cand: Vec<u32> = (0..n as u32 + 20).filter(|_| next(100) < take).collect();
            let want: Vec<usize> =
                cand.iter().map(|&c| c as usize).filter(|c| list.contains(c)).collect();
            assert_eq!(select(&list, Some(&cand), &mut out), &want[..], "{list:?} {cand:?}");
            assert_eq!(select(&list, None, &mut out), &list[..]);
        }
    }

    /// The colour the documentation of [`SkeletonField::colors`] defines, every weight
    /// taken: what `color_at` must give, bit for bit, also where it takes a single weight
    /// (every element whose box holds the point has one colour).
    fn color_by_every_weight(f: &SkeletonField, p: DVec3) -> [f32; 3] {
        let colors = f.colors.as_ref().unwrap();
        let candidates = f.cull.elements(f.cull.cell_of(p));
        let mut best = (f64::INFINITY, 0);
        for (k, c) in f.cliques.iter().enumerate() {
            let v = f.clique_value(c, p, candidates, &mut Vec::new());
            if v < best.0 {
                best = (v, k);
            }
        }
        let clique = &f.cliques[best.1];
        let members = clique.plain.iter().copied().chain(
            clique.junctions.iter().flat_map(|&j| f.junctions[j].limbs.iter().map(|l| l.element)),
        );
        f.weighted_color(colors, members, p).unwrap_or_else(|| f.nearest_color(colors, clique, p))
    }

    /// Twelve segments in a zigzag, coloured `skin` but for two of `nail`, in three groups: a
    /// palm blending with two fingers that do not blend with each other (two cliques).
    fn coloured_zigzag(blend: Blend, skin: [f64; 3], nail: [f64; 3]) -> SkeletonField {
        let mut s = Skeleton::new();
        let palm = s.add_group("palm").unwrap();
        let fingers = [s.add_group("a").unwrap(), s.add_group("b").unwrap()];
        for g in fingers {
            s.blend_groups(palm, g).unwrap();
        }
        for i in 0..12 {
            let x = i as f64 * 0.3;
            let (a, b) = (DVec3::new(x, 0.0, 0.0), DVec3::new(x + 0.3, 0.1 * (i % 2) as f64, 0.05));
            let segment = Shape::Segment(crate::Segment::new(a, b).unwrap());
            let color = if i == 4 || i == 9 { nail } else { skin };
            let group = if i < 6 { palm } else { fingers[(i / 3) % 2] };
            let e = Element::new(segment, 0.17).unwrap().with_color(color).unwrap();
            s.push(e.in_group(group)).unwrap();
        }
        SkeletonField::new(&s, blend).unwrap()
    }

    /// A zigzag of skin-coloured segments with two of another colour in it, the colours of
    /// `examples/skeleton/hand.toml`, in three groups (a palm blending with two fingers that
    /// do not blend with each other: two cliques): the colours at points near and far, on
    /// single-coloured and mixed ground, are the full weighted average's, bit for bit, for
    /// each blend.
    #[test]
    fn single_coloured_ground_takes_one_weight_and_the_full_average_colour() {
        let skin = [0.88, 0.67, 0.56];
        let nail = [0.96, 0.83, 0.8];
        for blend in [
            Blend::Convolution(Kernel::Wyvill),
            Blend::Convolution(Kernel::Gaussian),
            Blend::Sum(Kernel::Wyvill),
            Blend::SuperElliptic { range: 1.0, thumbweight: 2.0, angle_scaled: false },
        ] {
            let f = coloured_zigzag(blend, skin, nail);
            assert_eq!(f.cliques.len(), 2);
            let mut points = Vec::new();
            for i in 0..60 {
                for j in 0..9 {
                    for k in 0..5 {
                        points.push(DVec3::new(
                            -0.5 + 0.08 * i as f64,
                            -0.6 + 0.15 * j as f64,
                            -0.3 + 0.15 * k as f64,
                        ));
                    }
                }
            }
            let got = f.colors(&points).unwrap();
            let (mut skin_seen, mut mixed_seen) = (0, 0);
            for (p, c) in points.iter().zip(&got) {
                let want = color_by_every_weight(&f, *p);
                assert_eq!(c.map(f32::to_bits), want.map(f32::to_bits), "{blend:?} at {p}");
                if *c == skin.map(|v| v as f32) {
                    skin_seen += 1;
                } else if *c != nail.map(|v| v as f32) {
                    mixed_seen += 1;
                }
            }
            assert!(skin_seen > 100 && mixed_seen > 10, "{blend:?}: {skin_seen} {mixed_seen}");
        }
    }

    /// Colours asked for with the values ([`Field::eval_grad_color_many`]) leave the values
    /// and gradients bit for bit what [`Field::eval_grad_many`] gives (asking for colours
    /// must never move a vertex), and are [`SkeletonField::colors`]'s (up to the order of
    /// the weighted sum), for the additive blends (fused) and another (two calls), on the
    /// zigzag of two cliques with shared sums and mixed colours, in batches of any size.
    #[test]
    fn colours_with_the_values_are_the_painted_colours_and_keep_the_values() {
        let skin = [0.88, 0.67, 0.56];
        let nail = [0.96, 0.83, 0.8];
        for blend in [
            Blend::Convolution(Kernel::Wyvill),
            Blend::Sum(Kernel::Wyvill),
            Blend::SuperElliptic { range: 1.0, thumbweight: 2.0, angle_scaled: false },
        ] {
            let f = coloured_zigzag(blend, skin, nail);
            assert!(f.has_colors());
            let additive = matches!(blend, Blend::Convolution(_) | Blend::Sum(_));
            assert_eq!(f.shared.is_some(), additive, "{blend:?}");
            let mut rng = Rng(11);
            let points: Vec<DVec3> = (0..3000)
                .map(|_| {
                    DVec3::new(rng.range(-0.5, 4.2), rng.range(-0.6, 0.7), rng.range(-0.3, 0.3))
                })
                .collect();
            let n = points.len();
            let (mut v, mut g) = (vec![0.0; n], vec![DVec3::ZERO; n]);
            f.eval_grad_many(&points, &mut v, &mut g);
            let want = f.colors(&points).unwrap();
            for size in [1, 7, n] {
                let (mut vc, mut gc, mut c) =
                    (vec![0.0; n], vec![DVec3::ZERO; n], vec![[0.0; 3]; n]);
                for (((p, v), g), c) in points
                    .chunks(size)
                    .zip(vc.chunks_mut(size))
                    .zip(gc.chunks_mut(size))
                    .zip(c.chunks_mut(size))
                {
                    assert!(f.eval_grad_color_many(p, v, g, c));
                }
                for i in 0..n {
                    assert_eq!(v[i].to_bits(), vc[i].to_bits(), "{blend:?} value at {}", points[i]);
                    assert_eq!(g[i], gc[i], "{blend:?} gradient at {}", points[i]);
                    for k in 0..3 {
                        assert!(
                            (want[i][k] - c[i][k]).abs() <= 1e-6,
                            "{blend:?} colour at {}",
                            points[i]
                        );
                    }
                }
            }
            let mixed = want.iter().filter(|c| **c != skin.map(|v| v as f32)).count();
            assert!(mixed > 100, "{blend:?}: {mixed} mixed or nail");
        }
    }

    /// `changes_since` names exactly the boxes of the elements that differ, old and new, and
    /// refuses changes that every point depends on.
    #[test]
    fn changes_are_the_changed_elements_boxes() {
        let blend = Blend::Convolution(Kernel::Wyvill);
        let build = |points: &[DVec3]| {
            let mut s = Skeleton::new();
            for &p in points {
                s.add_point(p, 0.2, GroupId::DEFAULT).unwrap();
            }
            SkeletonField::new(&s, blend).unwrap()
        };
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let old = build(&[a, b, c]);
        let moved = build(&[a, b + DVec3::Z, c]);
        let boxes = moved.changes_since(&old).unwrap();
        assert_eq!(boxes.len(), 2);
        assert!(boxes[0].contains(b) && boxes[1].contains(b + DVec3::Z));
        assert!(!boxes.iter().any(|x| x.contains(a) || x.contains(c)));
        assert_eq!(old.changes_since(&old).unwrap(), []);
        // One element inserted in the middle: its box alone.
        let more = build(&[a, DVec3::splat(5.0), b, c]);
        let boxes = more.changes_since(&old).unwrap();
        assert_eq!(boxes.len(), 1);
        assert!(boxes[0].contains(DVec3::splat(5.0)) && !boxes[0].contains(b));
        // Removed: the old box.
        let fewer = build(&[a, c]);
        let boxes = fewer.changes_since(&old).unwrap();
        assert_eq!(boxes.len(), 1);
        assert!(boxes[0].contains(b));
        // Another iso value or blend: global.
        let iso = build(&[a, b, c]).with_iso(0.4).unwrap();
        assert_eq!(iso.changes_since(&old), Err(GlobalChange::Blend));
        // A new group: global.
        let mut s = Skeleton::new();
        let g = s.add_group("other").unwrap();
        s.add_point(a, 0.2, GroupId::DEFAULT).unwrap();
        s.add_point(b, 0.2, g).unwrap();
        s.add_point(c, 0.2, GroupId::DEFAULT).unwrap();
        let grouped = SkeletonField::new(&s, blend).unwrap();
        assert_eq!(grouped.changes_since(&old), Err(GlobalChange::Groups));
    }

    /// An element's reach boxes hold every point where it changes the field (a skeleton with
    /// it against one without it, bit for bit), for a skewed segment, a tapered one and a
    /// skewed triangle, with the Wyvill and triweight kernels; together they hold well under
    /// its box of influence (under two thirds of it); and with a kernel whose contribution is not cut
    /// at the reach (the Gaussian's segments) the box of influence is kept.
    #[test]
    fn reach_boxes_hold_every_point_an_element_changes_and_are_tighter_than_its_box() {
        let base = DVec3::new(0.05, -0.1, 0.02);
        let shapes = |s: &mut Skeleton, k: usize| match k {
            0 => s.add_segment(base, base + DVec3::new(0.9, 0.7, 0.5), 0.1, GroupId::DEFAULT),
            1 => s.add_tapered_segment(
                base,
                base + DVec3::new(-0.6, 0.8, 0.4),
                (0.05, 0.12),
                GroupId::DEFAULT,
            ),
            _ => s.add_polygon(
                vec![base, base + DVec3::new(0.8, 0.1, 0.6), base + DVec3::new(0.1, 0.9, 0.3)],
                0.1,
                GroupId::DEFAULT,
            ),
        };
        let mut rng = Rng(7);
        for kernel in [Kernel::Wyvill, Kernel::Triweight] {
            for k in 0..3 {
                let mut with = Skeleton::new();
                with.add_point(DVec3::new(0.3, 0.2, 0.1), 0.3, GroupId::DEFAULT).unwrap();
                let without = SkeletonField::new(&with, Blend::Convolution(kernel)).unwrap();
                shapes(&mut with, k).unwrap();
                let with = SkeletonField::new(&with, Blend::Convolution(kernel)).unwrap();
                let boxes = with.changes_since(&without).unwrap();
                let whole = Aabb { min: with.items[1].lo, max: with.items[1].hi };
                assert!(boxes.len() > 1, "{kernel:?} {k}: split");
                let (mut changed, mut inside_whole, mut inside_boxes) = (0, 0, 0);
                for _ in 0..40_000 {
                    let p = DVec3::new(
                        rng.range(whole.min.x, whole.max.x),
                        rng.range(whole.min.y, whole.max.y),
                        rng.range(whole.min.z, whole.max.z),
                    );
                    inside_whole += 1;
                    let held = boxes.iter().any(|b| b.contains(p));
                    inside_boxes += usize::from(held);
                    let (mut a, mut b) = ([0.0], [0.0]);
                    let (mut ga, mut gb) = ([DVec3::ZERO], [DVec3::ZERO]);
                    with.eval_grad_many(&[p], &mut a, &mut ga);
                    without.eval_grad_many(&[p], &mut b, &mut gb);
                    if a[0].to_bits() != b[0].to_bits() || ga[0] != gb[0] {
                        changed += 1;
                        assert!(held, "{kernel:?} {k}: {p} changed outside every box");
                    }
                }
                assert!(changed > 1000, "{kernel:?} {k}: {changed} changed");
                assert!(
                    inside_boxes * 3 < inside_whole * 2,
                    "{kernel:?} {k}: the boxes hold {inside_boxes} of {inside_whole}"
                );
            }
        }
        let mut s = Skeleton::new();
        s.add_segment(base, base + DVec3::new(0.9, 0.7, 0.5), 0.1, GroupId::DEFAULT).unwrap();
        let gauss = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
        let mut t = Skeleton::new();
        t.add_segment(base, base + DVec3::new(0.9, 0.7, 0.6), 0.1, GroupId::DEFAULT).unwrap();
        let moved = SkeletonField::new(&t, Blend::Convolution(Kernel::Gaussian)).unwrap();
        assert_eq!(moved.changes_since(&gauss).unwrap().len(), 2);
    }

    /// A small deterministic generator (xorshift64*), so the random skeletons are the same on
    /// every run.
    struct Rng(u64);

    impl Rng {
        fn unit(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit()
        }
        fn point(&mut self, h: f64) -> DVec3 {
            DVec3::new(self.range(-h, h), self.range(-h, h), self.range(-h, h))
        }
    }

    /// Random points, segments (some tapered), polygons in three groups, the first linked to
    /// the other two (two cliques, shared sums); `points_only` for the convolved sinc.
    fn random_skeleton(rng: &mut Rng, n: usize, points_only: bool) -> Skeleton {
        let mut s = Skeleton::new();
        let a = s.add_group("a").unwrap();
        let b = s.add_group("b").unwrap();
        let c = s.add_group("c").unwrap();
        s.blend_groups(a, b).unwrap();
        s.blend_groups(a, c).unwrap();
        let groups = [GroupId::DEFAULT, a, b, c];
        for i in 0..n {
            let g = groups[i % groups.len()];
            let p = rng.point(2.0);
            let r = rng.range(0.05, 0.3);
            let kind = if points_only { 0 } else { i % 4 };
            match kind {
                0 => s.add_point(p, r, g).map(|_| ()),
                1 => s.add_segment(p, p + rng.point(0.7), r, g).map(|_| ()),
                2 => s.add_tapered_segment(p, p + rng.point(0.7), (r, 0.5 * r), g).map(|_| ()),
                _ => {
                    s.add_polygon(vec![p, p + rng.point(0.5), p + rng.point(0.5)], r, g).map(|_| ())
                }
            }
            .unwrap();
        }
        s
    }

    fn blends() -> Vec<(Blend, bool)> {
        let kernels =
            [Kernel::Gaussian, Kernel::Wyvill, Kernel::Triweight, Kernel::BSpline, Kernel::Sinc];
        let mut v = Vec::new();
        for k in kernels {
            v.push((Blend::Convolution(k), k == Kernel::Sinc));
            v.push((Blend::Sum(k), false));
        }
        v.push((Blend::Union(Falloff::Linear), false));
        v.push((Blend::Union(Falloff::Squared), false));
        for angle_scaled in [false, true] {
            v.push((Blend::SuperElliptic { range: 1.5, thumbweight: 2.5, angle_scaled }, false));
        }
        for clamp in [false, true] {
            v.push((Blend::Combination { range: 1.0, clamp }, false));
        }
        v
    }

    /// Culling changes nothing: on random skeletons, under every blend and kernel (the
    /// Gaussian and the sinc at their documented cut-offs, `GAUSSIAN_CUTOFF` and
    /// `SINC_CUTOFF`, which the unculled sum also applies), values and gradients are
    /// bit-identical to a visit of every element — at random points, at the corners of the
    /// elements' boxes (where the grid's rounding is tested), and outside the grid.
    #[test]
    fn culled_equals_unculled_bit_for_bit() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for (blend, points_only) in blends() {
            for n in [1, 7, 40] {
                let s = random_skeleton(&mut rng, n, points_only);
                let f = SkeletonField::new(&s, blend).unwrap();
                let mut pts: Vec<DVec3> = (0..2000).map(|_| rng.point(3.5)).collect();
                for it in &f.items {
                    pts.extend([it.lo, it.hi, DVec3::new(it.lo.x, it.hi.y, it.lo.z)]);
                }
                pts.push(DVec3::splat(1e6));
                let m = pts.len();
                let (mut v1, mut g1) = (vec![0.0; m], vec![DVec3::ZERO; m]);
                let (mut v2, mut g2) = (vec![0.0; m], vec![DVec3::ZERO; m]);
                f.eval_grad_many(&pts, &mut v1, &mut g1);
                f.eval_batch_unculled(&pts, &mut v2, Some(&mut g2));
                let mut inside = 0;
                for i in 0..m {
                    assert_eq!(v1[i].to_bits(), v2[i].to_bits(), "{blend:?} n={n} {}", pts[i]);
                    assert_eq!(
                        g1[i].to_array().map(f64::to_bits),
                        g2[i].to_array().map(f64::to_bits)
                    );
                    inside += (v1[i] < 0.0) as usize;
                }
                // Values alone, and one point at a time, agree too.
                let mut v3 = vec![0.0; m];
                f.eval_many(&pts, &mut v3);
                assert!(v3.iter().zip(&v2).all(|(a, b)| a.to_bits() == b.to_bits()));
                assert!(
                    pts.iter()
                        .zip(&v2)
                        .step_by(37)
                        .all(|(p, b)| f.eval(*p).to_bits() == b.to_bits())
                );
                if n == 40 {
                    assert!(inside > 0, "{blend:?}: no point inside, the test would be vacuous");
                }
            }
        }
    }

    /// The layer path (the whole layer in one batch) gives the values of single evaluations.
    #[test]
    fn layer_equals_points() {
        let mut rng = Rng(7);
        let s = random_skeleton(&mut rng, 30, false);
        let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Wyvill)).unwrap();
        let xs: Vec<f64> = (0..41).map(|i| -2.5 + 0.125 * i as f64).collect();
        let ys: Vec<f64> = (0..33).map(|i| -2.0 + 0.125 * i as f64).collect();
        let mut out = vec![0.0; xs.len() * ys.len()];
        f.eval_layer(&xs, &ys, 0.3, &mut out);
        for (j, &y) in ys.iter().enumerate() {
            for (i, &x) in xs.iter().enumerate() {
                let v = f.eval(DVec3::new(x, y, 0.3));
                assert_eq!(out[i + xs.len() * j].to_bits(), v.to_bits());
            }
        }
    }

    /// The grid culls: a point visits far fewer elements than there are, and every element
    /// whose box holds a point is listed in that point's cell.
    #[test]
    fn grid_lists_every_box_holding_a_point() {
        let mut rng = Rng(11);
        let s = random_skeleton(&mut rng, 400, false);
        let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Wyvill)).unwrap();
        let grid = f.cull_grid();
        assert!(grid.mean_elements_per_cell() < 0.25 * f.element_count() as f64);
        for _ in 0..5000 {
            let p = rng.point(3.0);
            let listed = grid.elements(grid.cell_of(p));
            for (e, it) in f.items.iter().enumerate() {
                if it.contains(p) {
                    assert!(listed.contains(&(e as u32)), "element {e} missing at {p}");
                }
            }
        }
    }

    /// Many elements whose boxes each cover the whole skeleton: the first grid tried would
    /// list every element in every cell (20,000 × 160,000 entries, 12 GiB), so it is
    /// coarsened from a count made before anything is allocated, down to at most 64 entries
    /// an element.
    #[test]
    fn overlapping_boxes_coarsen_the_grid_before_it_is_filled() {
        let mut s = Skeleton::new();
        for i in 0..20_000 {
            let p = DVec3::new((i % 37) as f64, (i % 41) as f64, (i % 43) as f64) * 0.01;
            s.push(Element::new(Shape::Point(p), 50.0).unwrap()).unwrap();
        }
        let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Wyvill)).unwrap();
        let grid = f.cull_grid();
        assert!(grid.elements.len() <= 64 * 20_000, "{} entries", grid.elements.len());
        assert_eq!(grid.elements(grid.cell_of(DVec3::splat(0.2))).len(), 20_000);
    }
}
