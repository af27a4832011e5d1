//! The skeleton: elements (shape, radius, strength) in named blend groups.

use std::collections::BTreeSet;
use std::ops::Range;
use std::sync::Arc;

use glam::DVec3;

use crate::SkeletonError;
use crate::curve::CubicCurve;
use crate::geometry::{Polygon, Segment, Shape};
use crate::image::PolygonMethod;
use crate::weights::{WeightImage, check_vertex_weights};

/// A blend group, by index into [`Skeleton::groups`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GroupId(pub(crate) usize);

impl GroupId {
    /// The group every element is in unless put elsewhere.
    pub const DEFAULT: GroupId = GroupId(0);

    /// Position of the group in [`Skeleton::groups`], in the order groups were added; the
    /// default group is 0.
    pub fn index(self) -> usize {
        self.0
    }
}

/// A named set of elements that blend with each other, and the other groups they blend
/// with.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    /// Unique within its skeleton; the name scene files use for the group. The default group is
    /// called `"default"`.
    pub name: String,
    blends_with: BTreeSet<GroupId>,
}

impl Group {
    /// Other groups this one blends with (symmetric; never itself).
    pub fn blends_with(&self) -> impl Iterator<Item = GroupId> + '_ {
        self.blends_with.iter().copied()
    }
}

/// One skeletal element: a shape with a radius (the distance from the skeleton at which a
/// lone element's surface lies) and a strength (a weight on its density; negative
/// strengths carve).
///
/// A segment may be **tapered**: its radius and strength at `b` may differ from those at
/// `a`. At a query point they are interpolated linearly by the parameter `α ∈ [0, 1]` of the
/// point's projection onto the segment (clamped), as the dissertation's appendix A.2 does
/// (`near.radius` from `alpha`, DIS §5.6.7 "radii may differ per endpoint").
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    /// What the element is, in scene units (world coordinates, or its joint's frame in an
    /// [`Articulated`](crate::Articulated) skeleton). Public so that a pose or a caller can move
    /// it; shapes validate themselves on construction, so any `Shape` value is well formed
    /// (keep a tapered element a segment: only segments use the end radius and strength).
    pub shape: Shape,
    radius: f64,
    end_radius: f64,
    strength: f64,
    end_strength: f64,
    group: GroupId,
    polygon_method: PolygonMethod,
    color: Option<[f32; 3]>,
    /// A polygon's per-vertex weights (DIS §6.4), multiplying the strength.
    vertex_weights: Option<Arc<[f64]>>,
    /// A polygon's weight image (DIS §6.4), multiplying the strength.
    weight_image: Option<Arc<WeightImage>>,
}

/// A colour checked for [`Element::with_color`]: three components in `[0, 1]`.
pub fn check_color(c: [f64; 3]) -> Result<[f32; 3], SkeletonError> {
    if c.iter().all(|x| (0.0..=1.0).contains(x)) {
        Ok(c.map(|x| x as f32))
    } else {
        Err(SkeletonError::BadColor(c))
    }
}

impl Element {
    /// An element of strength 1 in the default group. The radius must be positive and
    /// finite.
    pub fn new(shape: Shape, radius: f64) -> Result<Element, SkeletonError> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(SkeletonError::BadRadius(radius));
        }
        Ok(Element {
            shape,
            radius,
            end_radius: radius,
            strength: 1.0,
            end_strength: 1.0,
            group: GroupId::DEFAULT,
            polygon_method: PolygonMethod::Exact,
            color: None,
            vertex_weights: None,
            weight_image: None,
        })
    }

    /// The same element with another strength (any finite number), at both ends.
    pub fn with_strength(mut self, strength: f64) -> Result<Element, SkeletonError> {
        if !strength.is_finite() {
            return Err(SkeletonError::BadStrength(strength));
        }
        self.strength = strength;
        self.end_strength = strength;
        Ok(self)
    }

    /// A tapered segment: radius `radius` at `a` (as given to [`Element::new`]) and
    /// `end_radius` at `b`. Only segments taper; other shapes are an error.
    pub fn with_end_radius(mut self, end_radius: f64) -> Result<Element, SkeletonError> {
        if !(end_radius.is_finite() && end_radius > 0.0) {
            return Err(SkeletonError::BadRadius(end_radius));
        }
        if end_radius != self.radius && !matches!(self.shape, Shape::Segment(_)) {
            return Err(SkeletonError::TaperNeedsSegment);
        }
        self.end_radius = end_radius;
        Ok(self)
    }

    /// A segment whose strength goes from its current value at `a` to `end_strength` at
    /// `b` (per-vertex weights, DIS §6.4). Only segments; other shapes are an error.
    pub fn with_end_strength(mut self, end_strength: f64) -> Result<Element, SkeletonError> {
        if !end_strength.is_finite() {
            return Err(SkeletonError::BadStrength(end_strength));
        }
        if end_strength != self.strength && !matches!(self.shape, Shape::Segment(_)) {
            return Err(SkeletonError::TaperNeedsSegment);
        }
        self.end_strength = end_strength;
        Ok(self)
    }

    /// How a polygon's convolution is computed (ignored for other shapes). A polygon with a
    /// weight image must keep the image method.
    pub fn with_polygon_method(mut self, method: PolygonMethod) -> Result<Element, SkeletonError> {
        method.check()?;
        if self.weight_image.is_some() && method == PolygonMethod::Exact {
            return Err(SkeletonError::WeightImageNeedsImageMethod);
        }
        self.polygon_method = method;
        Ok(self)
    }

    /// A polygon whose strength varies over it: `weights[i]` at vertex `i`, interpolated over
    /// the fan of triangles from the vertex average (DIS §6.4; see [`crate::weights`]), times
    /// the strength. One finite weight per vertex; the polygon must be star-shaped about
    /// its vertex average. Convolution only.
    pub fn with_vertex_weights(mut self, weights: Vec<f64>) -> Result<Element, SkeletonError> {
        let Shape::Polygon(p) = &self.shape else {
            return Err(SkeletonError::WeightsNeedPolygon);
        };
        check_vertex_weights(p, &weights)?;
        self.vertex_weights = Some(weights.into());
        Ok(self)
    }

    /// A polygon whose strength is scaled by `image`, stretched over the polygon's bounding
    /// rectangle in its plane (DIS §6.4; see [`crate::weights`]). The dissertation scales the
    /// polygon's raster image by it, so the element is switched to the image method (at the
    /// default resolution) if it used the exact one. Convolution only.
    pub fn with_weight_image(mut self, image: Arc<WeightImage>) -> Result<Element, SkeletonError> {
        if !matches!(self.shape, Shape::Polygon(_)) {
            return Err(SkeletonError::WeightsNeedPolygon);
        }
        if self.polygon_method == PolygonMethod::Exact {
            self.polygon_method =
                PolygonMethod::Image { resolution: crate::image::DEFAULT_IMAGE_RESOLUTION };
        }
        self.weight_image = Some(image);
        Ok(self)
    }

    /// A polygon's per-vertex weights, if it has them.
    pub fn vertex_weights(&self) -> Option<&[f64]> {
        self.vertex_weights.as_deref()
    }

    /// A polygon's weight image, if it has one.
    pub fn weight_image(&self) -> Option<&Arc<WeightImage>> {
        self.weight_image.as_ref()
    }

    /// Whether the element's strength varies over a polygon (per-vertex weights or a weight
    /// image).
    pub fn is_weighted(&self) -> bool {
        self.vertex_weights.is_some() || self.weight_image.is_some()
    }

    /// The same element with a colour (sRGB, each component in `[0, 1]`): the colour its
    /// part of the surface takes ([`SkeletonField::colors`](crate::SkeletonField::colors),
    /// DIS ch. 6, where the hand's colours come from its elements').
    pub fn with_color(mut self, color: [f64; 3]) -> Result<Element, SkeletonError> {
        self.color = Some(check_color(color)?);
        Ok(self)
    }

    /// The element's own colour, if it has one (otherwise the skeleton's default applies).
    pub fn color(&self) -> Option<[f32; 3]> {
        self.color
    }

    /// The same element in another group.
    pub fn in_group(mut self, group: GroupId) -> Element {
        self.group = group;
        self
    }

    /// The radius (at `a` for a tapered segment).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Radii at the two ends of a segment (equal unless tapered; both the radius for other
    /// shapes).
    pub fn radii(&self) -> (f64, f64) {
        (self.radius, self.end_radius)
    }

    /// The strength (at `a` for a segment with per-end weights).
    pub fn strength(&self) -> f64 {
        self.strength
    }

    /// Strengths at the two ends of a segment.
    pub fn strengths(&self) -> (f64, f64) {
        (self.strength, self.end_strength)
    }

    /// Whether radius or strength vary along the element.
    pub fn is_tapered(&self) -> bool {
        self.radius != self.end_radius || self.strength != self.end_strength
    }

    /// How a polygon's convolution is computed: exactly (the default) or by the
    /// dissertation's raster image. Meaningless for points and segments.
    pub fn polygon_method(&self) -> PolygonMethod {
        self.polygon_method
    }

    /// The blend group the element belongs to: it blends with the elements of this group and of
    /// the groups linked to it, and meets the others in a sharp union.
    pub fn group(&self) -> GroupId {
        self.group
    }
}

/// A skeleton under construction: elements and groups. Build a
/// [`SkeletonField`](crate::SkeletonField) from it to evaluate.
///
/// Groups: every element belongs to one; elements of a group blend with each other, and with
/// elements of the groups linked to it by [`Skeleton::blend_groups`]. Elements of groups that
/// are not linked never blend — their surfaces meet in a sharp union (see
/// [`crate::field`] for how and why).
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    elements: Vec<Element>,
    groups: Vec<Group>,
    junctions: Vec<Junction>,
    default_color: Option<[f32; 3]>,
}

/// Joints where segments (its *limbs*) meet, to be blended by the joint combination surface
/// of DIS eq. 5.37 and appendix A.2 instead of plain convolution (see [`crate::junction`]).
/// Made by [`Skeleton::add_junction`].
///
/// A junction is a connected set of segments — the limbs meeting at its joints and the
/// chains that continue from them — with one or more joints, each with its own direction
/// of convexity; a joint declared on segments already in a junction joins it. The junction
/// refers to its limbs by index, so it follows them when a pose moves them
/// ([`Skeleton::transform_elements`]); default directions are recomputed from the moved
/// limbs, user-given ones stay as given.
#[derive(Clone, Debug, PartialEq)]
pub struct Junction {
    /// The joints.
    pub joints: Vec<JunctionJoint>,
    /// Indices of the limbs: every segment of the connected set.
    pub limbs: Vec<usize>,
    /// For every limb, whether its ends `a` and `b` are free (at no joint and shared with no
    /// other limb): the union pulls free ends inward by their radius.
    pub free_ends: Vec<[bool; 2]>,
}

/// One joint of a [`Junction`].
#[derive(Clone, Debug, PartialEq)]
pub struct JunctionJoint {
    /// Where it was declared.
    pub at: DVec3,
    /// The segments with an end at the joint, and whether that end is their `a`.
    pub direct: Vec<(usize, bool)>,
    /// The user's direction in which no blending happens (unit); `None`: the normal of the
    /// plane of the joint and its direct limbs' far ends.
    pub direction: Option<DVec3>,
}

impl Default for Skeleton {
    fn default() -> Self {
        Self::new()
    }
}

impl Skeleton {
    /// An empty skeleton with one group, `"default"`.
    pub fn new() -> Skeleton {
        Skeleton {
            elements: Vec::new(),
            groups: vec![Group { name: "default".into(), blends_with: BTreeSet::new() }],
            junctions: Vec::new(),
            default_color: None,
        }
    }

    /// Sets the colour of the elements that have none of their own (sRGB, `[0, 1]`).
    pub fn set_default_color(&mut self, color: [f64; 3]) -> Result<(), SkeletonError> {
        self.default_color = Some(check_color(color)?);
        Ok(())
    }

    /// The colour of elements without their own, if set.
    pub fn default_color(&self) -> Option<[f32; 3]> {
        self.default_color
    }

    /// Colours element `index` (e.g. every segment of a polyline); out of range: nothing.
    pub fn set_color(&mut self, index: usize, color: [f64; 3]) -> Result<(), SkeletonError> {
        let c = check_color(color)?;
        if let Some(e) = self.elements.get_mut(index) {
            e.color = Some(c);
        }
        Ok(())
    }

    /// Whether any element, or the skeleton's default, has a colour: only then does a
    /// mesh of it get vertex colours.
    pub fn has_colors(&self) -> bool {
        self.default_color.is_some() || self.elements.iter().any(|e| e.color.is_some())
    }

    /// Adds a group. Names are unique.
    pub fn add_group(&mut self, name: &str) -> Result<GroupId, SkeletonError> {
        if self.group_named(name).is_some() {
            return Err(SkeletonError::DuplicateGroup(name.to_string()));
        }
        self.groups.push(Group { name: name.to_string(), blends_with: BTreeSet::new() });
        Ok(GroupId(self.groups.len() - 1))
    }

    /// Looks a group up by name, as scene files refer to groups; `None` if there is none.
    pub fn group_named(&self, name: &str) -> Option<GroupId> {
        self.groups.iter().position(|g| g.name == name).map(GroupId)
    }

    /// Every group, in the order added, indexed by [`GroupId::index`]; the first is the default
    /// group.
    pub fn groups(&self) -> &[Group] {
        &self.groups
    }

    /// The group `id` stands for. Ids come from this skeleton, so the lookup does not fail;
    /// an id of another skeleton with more groups panics.
    pub fn group(&self, id: GroupId) -> &Group {
        &self.groups[id.0]
    }

    /// Lets groups `a` and `b` blend with each other (not transitively: with `a–b` and
    /// `b–c`, `a` and `c` still do not blend).
    pub fn blend_groups(&mut self, a: GroupId, b: GroupId) -> Result<(), SkeletonError> {
        for g in [a, b] {
            if g.0 >= self.groups.len() {
                return Err(SkeletonError::UnknownGroup(format!("#{}", g.0)));
            }
        }
        if a != b {
            self.groups[a.0].blends_with.insert(b);
            self.groups[b.0].blends_with.insert(a);
        }
        Ok(())
    }

    /// Every element, in the order added: indices into this slice are what
    /// [`Skeleton::push`] returns and junctions refer to.
    pub fn elements(&self) -> &[Element] {
        &self.elements
    }

    /// Whether the skeleton has no element; a field cannot be built from an empty one.
    pub fn is_empty(&self) -> bool {
        self.elements.is_empty()
    }

    /// Number of elements (a polyline or curve counts each of its segments).
    pub fn len(&self) -> usize {
        self.elements.len()
    }

    /// Adds an element; returns its index.
    pub fn push(&mut self, element: Element) -> Result<usize, SkeletonError> {
        if element.group.0 >= self.groups.len() {
            return Err(SkeletonError::UnknownGroup(format!("#{}", element.group.0)));
        }
        self.elements.push(element);
        Ok(self.elements.len() - 1)
    }

    /// Changes the strength of element `index` (e.g. of every segment of a polyline).
    pub fn set_strength(&mut self, index: usize, strength: f64) -> Result<(), SkeletonError> {
        if !strength.is_finite() {
            return Err(SkeletonError::BadStrength(strength));
        }
        if let Some(e) = self.elements.get_mut(index) {
            e.strength = strength;
            e.end_strength = strength;
        }
        Ok(())
    }

    /// Gives segment `index` the strength `wa` at `a` and `wb` at `b` (per-vertex weights,
    /// DIS §6.4); for a polyline, consecutive segments sharing a point should share its
    /// weight. Not a segment: an error unless `wa == wb`.
    pub fn set_end_strengths(
        &mut self,
        index: usize,
        (wa, wb): (f64, f64),
    ) -> Result<(), SkeletonError> {
        if let Some(e) = self.elements.get_mut(index) {
            let updated = e.clone().with_strength(wa)?.with_end_strength(wb)?;
            *e = updated;
        }
        Ok(())
    }

    /// Replaces every element's shape by `f(index, element)` (radius, strength and group
    /// kept): how a pose moves a skeleton.
    pub fn transform_elements(
        &mut self,
        mut f: impl FnMut(usize, &Element) -> Result<Shape, SkeletonError>,
    ) -> Result<(), SkeletonError> {
        for i in 0..self.elements.len() {
            let shape = f(i, &self.elements[i])?;
            self.elements[i].shape = shape;
        }
        Ok(())
    }

    /// A point source.
    pub fn add_point(
        &mut self,
        c: DVec3,
        radius: f64,
        group: GroupId,
    ) -> Result<usize, SkeletonError> {
        if !c.is_finite() {
            return Err(SkeletonError::NonFinite);
        }
        self.push(Element::new(Shape::Point(c), radius)?.in_group(group))
    }

    /// A segment from `a` to `b`.
    pub fn add_segment(
        &mut self,
        a: DVec3,
        b: DVec3,
        radius: f64,
        group: GroupId,
    ) -> Result<usize, SkeletonError> {
        self.push(Element::new(Shape::Segment(Segment::new(a, b)?), radius)?.in_group(group))
    }

    /// A chain of segments through `points`; returns the range of their indices. With
    /// convolution, the chain's field is exactly the sum of its segments' (superposition),
    /// so collinear pieces join without a bulge.
    pub fn add_polyline(
        &mut self,
        points: &[DVec3],
        radius: f64,
        group: GroupId,
    ) -> Result<Range<usize>, SkeletonError> {
        if points.len() < 2 {
            return Err(SkeletonError::ShortPolyline(points.len()));
        }
        let mut segments = Vec::with_capacity(points.len() - 1);
        for (i, w) in points.windows(2).enumerate() {
            let s = Segment::new(w[0], w[1]).map_err(|e| match e {
                SkeletonError::ZeroLengthSegment(p) => {
                    SkeletonError::RepeatedPolylinePoint { index: i + 1, point: p }
                }
                e => e,
            })?;
            segments.push(Element::new(Shape::Segment(s), radius)?.in_group(group));
        }
        let start = self.elements.len();
        for s in segments {
            self.push(s)?;
        }
        Ok(start..self.elements.len())
    }

    /// A tapered segment: radius `ra` at `a`, `rb` at `b`, interpolated along it.
    pub fn add_tapered_segment(
        &mut self,
        a: DVec3,
        b: DVec3,
        (ra, rb): (f64, f64),
        group: GroupId,
    ) -> Result<usize, SkeletonError> {
        let e = Element::new(Shape::Segment(Segment::new(a, b)?), ra)?.with_end_radius(rb)?;
        self.push(e.in_group(group))
    }

    /// A chain of tapered segments: `radii[i]` is the radius at `points[i]`, so consecutive
    /// segments agree where they meet. Returns the range of the segments' indices.
    pub fn add_tapered_polyline(
        &mut self,
        points: &[DVec3],
        radii: &[f64],
        group: GroupId,
    ) -> Result<Range<usize>, SkeletonError> {
        if radii.len() != points.len() {
            return Err(SkeletonError::RadiusCount { points: points.len(), radii: radii.len() });
        }
        if let Some(r) = radii.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
            return Err(SkeletonError::BadRadius(*r));
        }
        let range = self.add_polyline(points, radii[0], group)?;
        for (k, i) in range.clone().enumerate() {
            let e = &mut self.elements[i];
            e.radius = radii[k];
            e.end_radius = radii[k + 1];
        }
        Ok(range)
    }

    /// A cubic curve whose radius goes from `r0` at its start to `r1` at its end, in
    /// proportion to arc length along the segments that approximate it.
    pub fn add_tapered_curve(
        &mut self,
        curve: &CubicCurve,
        tolerance: f64,
        (r0, r1): (f64, f64),
        group: GroupId,
    ) -> Result<Range<usize>, SkeletonError> {
        let points = curve.to_polyline(tolerance, 1024)?;
        let mut arc = vec![0.0];
        for w in points.windows(2) {
            arc.push(arc[arc.len() - 1] + (w[1] - w[0]).length());
        }
        let total = arc[arc.len() - 1].max(f64::MIN_POSITIVE);
        let radii: Vec<f64> = arc.iter().map(|s| r0 + (r1 - r0) * s / total).collect();
        self.add_tapered_polyline(&points, &radii, group)
    }

    /// A planar polygon (a triangle when given three vertices).
    pub fn add_polygon(
        &mut self,
        vertices: Vec<DVec3>,
        radius: f64,
        group: GroupId,
    ) -> Result<usize, SkeletonError> {
        self.push(Element::new(Shape::Polygon(Polygon::new(vertices)?), radius)?.in_group(group))
    }

    /// A cubic curve, as the segments [`CubicCurve::split`] gives for `tolerance`.
    pub fn add_curve(
        &mut self,
        curve: &CubicCurve,
        tolerance: f64,
        radius: f64,
        group: GroupId,
    ) -> Result<Range<usize>, SkeletonError> {
        let points = curve.to_polyline(tolerance, 1024)?;
        self.add_polyline(&points, radius, group)
    }

    /// Declares a joint at `at` whose limbs — every segment with an end there, and the
    /// chains of segments continuing from their far ends — are blended by the joint
    /// combination surface (DIS eq. 5.37) instead of plain convolution. A segment that
    /// passes *through* `at` is split there first (its convolution is unchanged:
    /// superposition), so the bar of a tee need not be drawn in two pieces. Only segments
    /// already in the skeleton are considered. `direction` is the direction in which no
    /// blending happens; by default the normal of the plane of the joint and the limbs' far
    /// ends (appendix A.2's `NormalFromPolygon`). If the limbs are already part of a
    /// junction (a second branch point of the same tree), the joint joins it. Returns the
    /// junction's index.
    pub fn add_junction(
        &mut self,
        at: DVec3,
        direction: Option<DVec3>,
    ) -> Result<usize, SkeletonError> {
        if !at.is_finite() {
            return Err(SkeletonError::NonFinite);
        }
        let direction = match direction {
            Some(d) => {
                if !(d.is_finite() && d.length() > 0.0) {
                    return Err(SkeletonError::BadDirection(d.to_array()));
                }
                Some(d.normalize())
            }
            None => None,
        };
        let near = |p: DVec3, q: DVec3| (p - q).length() <= 1e-9 * p.abs().max_element().max(1.0);
        // Split segments that pass through the joint.
        for i in 0..self.elements.len() {
            let Shape::Segment(s) = &self.elements[i].shape else { continue };
            let (q, alpha) = s.nearest(at);
            if near(at, q) && !near(at, s.a()) && !near(at, s.b()) {
                let (a, b) = (s.a(), s.b());
                let e = self.elements[i].clone();
                let (ra, rb) = e.radii();
                let (wa, wb) = e.strengths();
                let (rm, wm) = (ra + alpha * (rb - ra), wa + alpha * (wb - wa));
                let mut first = e.clone();
                first.shape = Shape::Segment(Segment::new(a, at)?);
                first.end_radius = rm;
                first.end_strength = wm;
                let mut second = e;
                second.shape = Shape::Segment(Segment::new(at, b)?);
                second.radius = rm;
                second.strength = wm;
                self.elements[i] = first;
                self.elements.push(second);
                // A junction holding the split segment now holds both halves.
                let last = self.elements.len() - 1;
                for j in &mut self.junctions {
                    if let Some(k) = j.limbs.iter().position(|&l| l == i) {
                        let free = j.free_ends[k];
                        j.free_ends[k] = [free[0], false];
                        j.limbs.push(last);
                        j.free_ends.push([false, free[1]]);
                    }
                }
            }
        }
        let ends = |i: usize| match &self.elements[i].shape {
            Shape::Segment(s) => Some((s.a(), s.b())),
            _ => None,
        };
        let mut direct = Vec::new();
        for i in 0..self.elements.len() {
            let Some((a, b)) = ends(i) else { continue };
            if near(at, a) {
                direct.push((i, true));
            } else if near(at, b) {
                direct.push((i, false));
            }
        }
        if direct.len() < 2 {
            return Err(SkeletonError::TooFewLimbs { at: at.to_array(), found: direct.len() });
        }
        // The connected set of segments through the joint.
        let mut limbs: Vec<usize> = direct.iter().map(|d| d.0).collect();
        let mut frontier: Vec<DVec3> = direct
            .iter()
            .filter_map(|&(i, at_a)| ends(i).map(|(a, b)| if at_a { b } else { a }))
            .collect();
        while let Some(pt) = frontier.pop() {
            for i in 0..self.elements.len() {
                if limbs.contains(&i) {
                    continue;
                }
                let Some((a, b)) = ends(i) else { continue };
                if near(pt, a) {
                    frontier.push(b);
                } else if near(pt, b) {
                    frontier.push(a);
                } else {
                    continue;
                }
                limbs.push(i);
            }
        }
        // Junctions sharing segments with this set merge into one, with all their joints.
        let joint = JunctionJoint { at, direct, direction };
        let mut joints = vec![joint];
        let mut keep = None;
        let mut k = 0;
        while k < self.junctions.len() {
            if self.junctions[k].limbs.iter().any(|l| limbs.contains(l)) {
                let old = if keep.is_none() {
                    keep = Some(k);
                    k += 1;
                    self.junctions[k - 1].clone()
                } else {
                    self.junctions.remove(k)
                };
                for l in old.limbs {
                    if !limbs.contains(&l) {
                        limbs.push(l);
                    }
                }
                let mut old_joints = old.joints;
                old_joints.append(&mut joints);
                joints = old_joints;
            } else {
                k += 1;
            }
        }
        let group = self.elements[limbs[0]].group;
        if limbs.iter().any(|&i| self.elements[i].group != group) {
            return Err(SkeletonError::LimbsInSeveralGroups(at.to_array()));
        }
        let free_ends = limbs
            .iter()
            .map(|&i| {
                let (a, b) = ends(i).unwrap_or((at, at));
                let free = |e: DVec3| {
                    !joints.iter().any(|j| near(j.at, e))
                        && !limbs.iter().any(|&k| {
                            k != i && ends(k).is_some_and(|(c, d)| near(c, e) || near(d, e))
                        })
                };
                [free(a), free(b)]
            })
            .collect();
        let junction = Junction { joints, limbs, free_ends };
        Ok(match keep {
            Some(k) => {
                self.junctions[k] = junction;
                k
            }
            None => {
                self.junctions.push(junction);
                self.junctions.len() - 1
            }
        })
    }

    /// The direction of convexity of joint `joint` of `junction`: the user's, or the normal
    /// of the plane of the joint and its direct limbs' far ends as the limbs are now (for
    /// collinear limbs, which span no plane and do not bulge, any direction across them).
    pub fn junction_direction(&self, junction: &Junction, joint: usize) -> DVec3 {
        let j = &junction.joints[joint];
        if let Some(d) = j.direction {
            return d;
        }
        let mut far = Vec::new();
        for &(i, at_a) in &j.direct {
            if let Shape::Segment(s) = &self.elements[i].shape {
                let (a, b) = (s.a(), s.b());
                far.push(if at_a { b - a } else { a - b });
            }
        }
        plane_normal(&far).unwrap_or_else(|| {
            far.first().map_or(DVec3::Z, |f| f.normalize().any_orthonormal_vector())
        })
    }

    /// The junctions declared with [`Skeleton::add_junction`], in order of creation; limbs are
    /// indices into [`Skeleton::elements`].
    pub fn junctions(&self) -> &[Junction] {
        &self.junctions
    }

    /// One point on each element that adds to the field (a point, a segment's midpoint, a
    /// point inside a polygon): where the continuation polygonizer starts looking for the
    /// surface.
    pub fn seed_points(&self) -> Vec<DVec3> {
        // An element that carves everywhere (negative strength at both ends) has no
        // surface of its own to start from: its point lies outside (the hand's creases).
        self.elements
            .iter()
            .filter(|e| e.strength > 0.0 || e.end_strength > 0.0)
            .map(|e| e.shape.seed_point())
            .collect()
    }

    /// The groups that blend together, as the maximal cliques of the blend relation (each
    /// group with itself): every pair within a clique blends, and no clique is inside
    /// another. A group linked to nothing is a clique of its own. Sorted, deterministic.
    pub fn blend_cliques(&self) -> Vec<Vec<GroupId>> {
        let n = self.groups.len();
        let adj: Vec<BTreeSet<usize>> =
            self.groups.iter().map(|g| g.blends_with.iter().map(|x| x.0).collect()).collect();
        let mut out = Vec::new();
        bron_kerbosch(&adj, Vec::new(), (0..n).collect(), BTreeSet::new(), &mut out);
        let mut cliques: Vec<Vec<GroupId>> = out
            .into_iter()
            .map(|mut c| {
                c.sort_unstable();
                c.into_iter().map(GroupId).collect()
            })
            .collect();
        cliques.sort();
        cliques
    }
}

/// The normal of the plane through the joint (the origin) and the limbs' far ends `far`:
/// the sum of the cross products of consecutive limbs taken around their mean plane,
/// each flipped to agree with the largest. Exact when the limbs are coplanar; `None` when
/// they are collinear.
fn plane_normal(far: &[DVec3]) -> Option<DVec3> {
    let mut crosses: Vec<DVec3> = Vec::new();
    for i in 0..far.len() {
        for j in i + 1..far.len() {
            crosses.push(far[i].normalize().cross(far[j].normalize()));
        }
    }
    let big =
        crosses.iter().copied().max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
    if big.length() < 1e-9 {
        return None;
    }
    let n: DVec3 = crosses.iter().map(|c| if c.dot(big) < 0.0 { -*c } else { *c }).sum();
    Some(n.normalize())
}

/// Maximal cliques (Bron–Kerbosch with pivoting); groups are few, so plain sets do.
fn bron_kerbosch(
    adj: &[BTreeSet<usize>],
    r: Vec<usize>,
    mut p: BTreeSet<usize>,
    mut x: BTreeSet<usize>,
    out: &mut Vec<Vec<usize>>,
) {
    if p.is_empty() && x.is_empty() {
        out.push(r);
        return;
    }
    let pivot = p.iter().chain(x.iter()).copied().max_by_key(|u| adj[*u].len());
    let candidates: Vec<usize> = match pivot {
        Some(u) => p.iter().copied().filter(|v| !adj[u].contains(v)).collect(),
        None => p.iter().copied().collect(),
    };
    for v in candidates {
        let mut r2 = r.clone();
        r2.push(v);
        let p2 = p.iter().copied().filter(|w| adj[v].contains(w)).collect();
        let x2 = x.iter().copied().filter(|w| adj[v].contains(w)).collect();
        bron_kerbosch(adj, r2, p2, x2, out);
        p.remove(&v);
        x.insert(v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cliques_of_the_dissertations_blend_graph() {
        // Fig. 6.18: a↔b,e; b↔a,c,e; c↔b; d↔e; e↔a,b,d.
        let mut s = Skeleton::new();
        let [a, b, c, d, e] = ["a", "b", "c", "d", "e"].map(|n| s.add_group(n).unwrap());
        for (x, y) in [(a, b), (a, e), (b, c), (b, e), (d, e)] {
            s.blend_groups(x, y).unwrap();
        }
        let names: Vec<Vec<&str>> = s
            .blend_cliques()
            .iter()
            .map(|c| c.iter().map(|g| s.group(*g).name.as_str()).collect())
            .collect();
        assert_eq!(
            names,
            vec![vec!["default"], vec!["a", "b", "e"], vec!["b", "c"], vec!["d", "e"]]
        );
    }

    #[test]
    fn fingers_blend_with_the_palm_but_not_with_each_other() {
        let mut s = Skeleton::new();
        let palm = s.add_group("palm").unwrap();
        let f1 = s.add_group("f1").unwrap();
        let f2 = s.add_group("f2").unwrap();
        s.blend_groups(palm, f1).unwrap();
        s.blend_groups(palm, f2).unwrap();
        let cl = s.blend_cliques();
        assert!(cl.contains(&vec![palm, f1]));
        assert!(cl.contains(&vec![palm, f2]));
        assert!(!cl.iter().any(|c| c.contains(&f1) && c.contains(&f2)));
        assert!(matches!(s.add_group("f1"), Err(SkeletonError::DuplicateGroup(_))));
    }

    #[test]
    fn polyline_reports_the_repeated_point() {
        let mut s = Skeleton::new();
        let r = s.add_polyline(&[DVec3::ZERO, DVec3::X, DVec3::X], 0.1, GroupId::DEFAULT);
        assert!(matches!(r, Err(SkeletonError::RepeatedPolylinePoint { index: 2, .. })));
        assert!(s.is_empty(), "a failed polyline adds nothing");
        assert!(matches!(
            s.add_point(DVec3::ZERO, -1.0, GroupId::DEFAULT),
            Err(SkeletonError::BadRadius(_))
        ));
    }
}
