//! The `[skeleton]` section: skeletal elements, their blend and groups, checked with
//! positions, and built into a [`SkeletonField`].
//!
//! ```toml
//! [skeleton]
//! blend = "convolution"        # convolution (default), sum, union, elliptic, super-elliptic, combination
//! kernel = "gaussian"          # convolution and sum: gaussian (default), wyvill, triweight, bspline, sinc
//! radius = 0.1                 # default radius of the elements below
//!
//! [skeleton.groups]            # optional: name = [groups it blends with]
//! palm = []
//! finger1 = ["palm"]
//!
//! [[skeleton.segment]]
//! a = [0, 0, 0]
//! b = [0.5, 0, 0]
//! group = "finger1"
//! color = [0.9, 0.7, 0.6]      # optional, on any element; `color` in [skeleton]: the default
//! ```

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::Deserialize;
use skelform_field::DVec3;
use skelform_field::combine::Combine;
use skelform_skeleton::sweep::MAX_SECTION_PIXELS;
use skelform_skeleton::{
    Blend, CubicCurve, DEFAULT_IMAGE_RESOLUTION, Element, Falloff, GroupId, Kernel,
    MAX_IMAGE_RESOLUTION, Polygon, PolygonMethod, Segment, Shape, Skeleton, SkeletonError,
    SkeletonField, SweptField, WeightImage,
};
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SkeletonSection {
    blend: Option<Spanned<String>>,
    kernel: Option<Spanned<String>>,
    iso: Option<Spanned<f64>>,
    radius: Option<Spanned<f64>>,
    range: Option<Spanned<f64>>,
    thumbweight: Option<Spanned<f64>>,
    falloff: Option<Spanned<String>>,
    clamp: Option<Spanned<bool>>,
    /// Super-elliptic ranges scaled by `1 − cos θ` (DIS eq. 5.14).
    angle_scaled: Option<Spanned<bool>>,
    /// Default polygon method: "exact" or "image" (DIS appendix A.3).
    polygon_method: Option<Spanned<String>>,
    image_resolution: Option<Spanned<i64>>,
    /// Junction normals blended as in DIS appendix A.2 (no crease in the shading).
    blended_normals: Option<Spanned<bool>>,
    /// Segments convolved "exact" (default) or by the "separable" approximation (DIS
    /// §5.6.10, figs. 5.52/5.53).
    segment_method: Option<Spanned<String>>,
    /// How the skeleton combines with a `[field]` formula in the same scene.
    combine: Option<Spanned<String>>,
    groups: Option<BTreeMap<String, Spanned<Vec<Spanned<String>>>>>,
    point: Option<Vec<PointSpec>>,
    segment: Option<Vec<SegmentSpec>>,
    polyline: Option<Vec<PolylineSpec>>,
    curve: Option<Vec<CurveSpec>>,
    /// Generalized cylinders (see `crate::sweep`).
    sweep: Option<Vec<crate::sweep::SweepSpec>>,
    triangle: Option<Vec<PolygonSpec>>,
    polygon: Option<Vec<PolygonSpec>>,
    /// Joints and poses (see `crate::pose`).
    joint: Option<Vec<crate::pose::JointSpec>>,
    poses: Option<BTreeMap<Spanned<String>, crate::pose::PoseSpec>>,
    pose: Option<Spanned<String>>,
    junction: Option<Vec<JunctionSpec>>,
    /// Colour of the elements without their own (DIS ch. 6): `[r, g, b]`, each 0 to 1.
    color: Option<Spanned<[f64; 3]>>,
}

/// A joint blended by the joint combination surface (DIS eq. 5.37).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JunctionSpec {
    at: Spanned<[f64; 3]>,
    direction: Option<Spanned<[f64; 3]>>,
}

/// One number, or a list of them (a radius per end or per point).
struct Numbers(Vec<f64>);

impl<'de> Deserialize<'de> for Numbers {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Numbers;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or a list of numbers")
            }
            fn visit_f64<E>(self, v: f64) -> Result<Numbers, E> {
                Ok(Numbers(vec![v]))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Numbers, E> {
                Ok(Numbers(vec![v as f64]))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Numbers, E> {
                Ok(Numbers(vec![v as f64]))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<Numbers, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = a.next_element::<f64>()? {
                    v.push(x);
                }
                Ok(Numbers(v))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PointSpec {
    at: Spanned<[f64; 3]>,
    radius: Option<Spanned<Numbers>>,
    strength: Option<Spanned<Numbers>>,
    group: Option<Spanned<String>>,
    /// The joint whose frame the element is written in.
    joint: Option<Spanned<String>>,
    /// The element's colour, `[r, g, b]` with each component from 0 to 1.
    color: Option<Spanned<[f64; 3]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SegmentSpec {
    a: Spanned<[f64; 3]>,
    b: Spanned<[f64; 3]>,
    radius: Option<Spanned<Numbers>>,
    strength: Option<Spanned<Numbers>>,
    group: Option<Spanned<String>>,
    /// The joint whose frame the element is written in.
    joint: Option<Spanned<String>>,
    /// The element's colour, `[r, g, b]` with each component from 0 to 1.
    color: Option<Spanned<[f64; 3]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PolylineSpec {
    points: Spanned<Vec<[f64; 3]>>,
    radius: Option<Spanned<Numbers>>,
    strength: Option<Spanned<Numbers>>,
    group: Option<Spanned<String>>,
    /// The joint whose frame the element is written in.
    joint: Option<Spanned<String>>,
    /// The element's colour, `[r, g, b]` with each component from 0 to 1.
    color: Option<Spanned<[f64; 3]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CurveSpec {
    /// Bézier control points: the curve starts at the first and ends at the last.
    bezier: Spanned<[[f64; 3]; 4]>,
    /// Largest distance between the curve and its segments; default a tenth of the radius.
    tolerance: Option<Spanned<f64>>,
    radius: Option<Spanned<Numbers>>,
    strength: Option<Spanned<Numbers>>,
    group: Option<Spanned<String>>,
    /// The joint whose frame the element is written in.
    joint: Option<Spanned<String>>,
    /// The element's colour, `[r, g, b]` with each component from 0 to 1.
    color: Option<Spanned<[f64; 3]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PolygonSpec {
    vertices: Spanned<Vec<[f64; 3]>>,
    radius: Option<Spanned<Numbers>>,
    strength: Option<Spanned<Numbers>>,
    group: Option<Spanned<String>>,
    polygon_method: Option<Spanned<String>>,
    image_resolution: Option<Spanned<i64>>,
    /// Per-vertex weights multiplying the strength (DIS §6.4), one per vertex.
    weights: Option<Spanned<Vec<f64>>>,
    /// A grey PNG (relative to the scene's folder) scaling the strength over the polygon's
    /// bounding rectangle (DIS §6.4); implies the image method.
    weight_image: Option<Spanned<String>>,
    /// The joint whose frame the element is written in.
    joint: Option<Spanned<String>>,
    /// The element's colour, `[r, g, b]` with each component from 0 to 1.
    color: Option<Spanned<[f64; 3]>>,
}

/// A skeleton section, built.
pub(crate) struct Built {
    /// The skeleton's field with the sweeps added: the surface.
    pub field: Arc<SweptField>,
    /// The skeleton's field alone (none when the section has only sweeps).
    pub skeleton: Option<Arc<SkeletonField>>,
    pub combine: Option<(Combine, usize)>,
    pub section_at: usize,
    pub articulation: Option<crate::pose::Articulation>,
}

impl Built {
    /// The field the scene's surface is of: the skeleton's own field, shared with
    /// [`Built::skeleton`], when there are no sweeps (the two are then the same values, and a
    /// caller can tell by pointer that the surface is the skeleton alone, as incremental
    /// re-meshing does), else the swept field.
    pub fn surface(&self) -> Arc<dyn skelform_field::Field> {
        match &self.skeleton {
            Some(sk) if self.field.sweeps().is_empty() => sk.clone(),
            _ => self.field.clone(),
        }
    }
}

pub(crate) fn build(
    s: &Spanned<SkeletonSection>,
    at: At,
    choice: crate::pose::Choice,
    base: Option<&std::path::Path>,
) -> Result<Built, SceneError> {
    let section_at = s.span().start;
    let s = s.get_ref();
    let err = |offset: usize, e: SkeletonError| at(offset, e.to_string());

    // The blend and its parameters; a parameter that the blend does not read is an error.
    let blend_name = s.blend.as_ref().map_or("convolution", |b| b.get_ref().as_str());
    let blend_at = s.blend.as_ref().map_or(section_at, |b| b.span().start);
    let kernel = match &s.kernel {
        Some(k) => k.get_ref().parse::<Kernel>().map_err(|e| at(k.span().start, e.to_string()))?,
        None => Kernel::Gaussian,
    };
    let number =
        |v: &Option<Spanned<f64>>, default: f64| v.as_ref().map_or(default, |x| *x.get_ref());
    let blend = match blend_name {
        "convolution" => Blend::Convolution(kernel),
        "sum" => Blend::Sum(kernel),
        "union" => Blend::Union(match &s.falloff {
            None => Falloff::Linear,
            Some(f) => match f.get_ref().as_str() {
                "linear" => Falloff::Linear,
                "squared" => Falloff::Squared,
                other => {
                    return Err(at(
                        f.span().start,
                        format!("unknown falloff '{other}'; expected linear or squared"),
                    ));
                }
            },
        }),
        "elliptic" => Blend::SuperElliptic {
            range: number(&s.range, 1.0),
            thumbweight: 2.0,
            angle_scaled: s.angle_scaled.as_ref().is_some_and(|c| *c.get_ref()),
        },
        "super-elliptic" => Blend::SuperElliptic {
            range: number(&s.range, 1.0),
            thumbweight: number(&s.thumbweight, 3.0),
            angle_scaled: s.angle_scaled.as_ref().is_some_and(|c| *c.get_ref()),
        },
        "combination" => Blend::Combination {
            range: number(&s.range, 1.0),
            clamp: s.clamp.as_ref().is_none_or(|c| *c.get_ref()),
        },
        other => {
            return Err(at(
                blend_at,
                format!(
                    "unknown blend '{other}'; expected one of: convolution, sum, union, elliptic, \
                     super-elliptic, combination"
                ),
            ));
        }
    };
    let not_for = |key: &str, offset: usize, readers: &str| {
        at(offset, format!("'{key}' does not apply to the {blend_name} blend (only to {readers})"))
    };
    if let Some(k) = &s.kernel
        && !matches!(blend, Blend::Convolution(_) | Blend::Sum(_))
    {
        return Err(not_for("kernel", k.span().start, "convolution and sum"));
    }
    if let Some(f) = &s.falloff
        && !matches!(blend, Blend::Union(_))
    {
        return Err(not_for("falloff", f.span().start, "union"));
    }
    if let Some(r) = &s.range
        && !matches!(blend, Blend::SuperElliptic { .. } | Blend::Combination { .. })
    {
        return Err(not_for("range", r.span().start, "elliptic, super-elliptic and combination"));
    }
    if let Some(t) = &s.thumbweight
        && blend_name != "super-elliptic"
    {
        return Err(not_for("thumbweight", t.span().start, "super-elliptic"));
    }
    if let Some(c) = &s.clamp
        && !matches!(blend, Blend::Combination { .. })
    {
        return Err(not_for("clamp", c.span().start, "combination"));
    }
    if let Some(c) = &s.angle_scaled
        && !matches!(blend, Blend::SuperElliptic { .. })
    {
        return Err(not_for("angle_scaled", c.span().start, "elliptic and super-elliptic"));
    }
    let conv_only = |key: &str, offset: usize| -> Result<(), SceneError> {
        if matches!(blend, Blend::Convolution(_)) {
            Ok(())
        } else {
            Err(not_for(key, offset, "convolution"))
        }
    };
    let default_method = polygon_method(&s.polygon_method, &s.image_resolution, None, at)?;
    if let Some(m) = &s.polygon_method {
        conv_only("polygon_method", m.span().start)?;
    }
    if let Some(j) = s.junction.iter().flatten().next() {
        conv_only("[[skeleton.junction]]", j.at.span().start)?;
    }
    if let Some(i) = &s.iso
        && !blend.has_iso()
    {
        return Err(not_for("iso", i.span().start, "convolution, sum and combination"));
    }
    if let Some(r) = &s.radius
        && !(r.get_ref().is_finite() && *r.get_ref() > 0.0)
    {
        return Err(err(r.span().start, SkeletonError::BadRadius(*r.get_ref())));
    }

    // Groups: declared first, then linked.
    let mut skeleton = Skeleton::new();
    if let Some(groups) = &s.groups {
        for name in groups.keys() {
            if name != "default" {
                skeleton.add_group(name).map_err(|e| at(section_at, e.to_string()))?;
            }
        }
        for (name, links) in groups {
            let g = skeleton.group_named(name).unwrap_or(GroupId::DEFAULT);
            for other in links.get_ref() {
                let o = skeleton.group_named(other.get_ref()).ok_or_else(|| {
                    at(other.span().start, unknown_group(other.get_ref(), &skeleton))
                })?;
                skeleton.blend_groups(g, o).map_err(|e| err(other.span().start, e))?;
            }
        }
    }

    // Elements. Each may name its radius (one, or one per end or point where the element
    // tapers), strength and group; the radius defaults to the section's.
    let common = |element_at: usize,
                  radius: &Option<Spanned<Numbers>>,
                  strength: &Option<Spanned<Numbers>>,
                  group: &Option<Spanned<String>>,
                  skeleton: &Skeleton|
     -> Result<(Vec<f64>, Vec<f64>, GroupId), SceneError> {
        let r = match (radius, &s.radius) {
            (Some(r), _) => {
                let v = &r.get_ref().0;
                if v.is_empty() {
                    return Err(at(r.span().start, "radius: the list is empty".into()));
                }
                if let Some(bad) = v.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
                    return Err(err(r.span().start, SkeletonError::BadRadius(*bad)));
                }
                v.clone()
            }
            (None, Some(d)) => vec![*d.get_ref()],
            (None, None) => {
                return Err(at(
                    element_at,
                    "this element needs a radius (or give a default 'radius' in [skeleton])".into(),
                ));
            }
        };
        let w = match strength {
            Some(w) => {
                let v = &w.get_ref().0;
                if v.is_empty() {
                    return Err(at(w.span().start, "strength: the list is empty".into()));
                }
                if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
                    return Err(err(w.span().start, SkeletonError::BadStrength(*bad)));
                }
                v.clone()
            }
            None => vec![1.0],
        };
        let g = match group {
            Some(g) => skeleton
                .group_named(g.get_ref())
                .ok_or_else(|| at(g.span().start, unknown_group(g.get_ref(), skeleton)))?,
            None => GroupId::DEFAULT,
        };
        Ok((r, w, g))
    };
    // How many values a radius or strength list may have: one, or `n` (per end or point).
    let count = |v: &Option<Spanned<Numbers>>, got: usize, n: usize, what: &str, kind: &str| match v
    {
        Some(v) if got != 1 && got != n => Err(at(
            v.span().start,
            if n == 1 {
                format!(
                    "a {kind} takes one {what} (got a list of {got}); only segments, polylines and curves taper"
                )
            } else {
                format!("a {kind} takes one {what} or {n} (got {got})")
            },
        )),
        _ => Ok(()),
    };
    let add = |skeleton: &mut Skeleton, e: Result<Element, SkeletonError>, g, offset: usize| {
        let e = e.map_err(|e| err(offset, e))?;
        skeleton.push(e.in_group(g)).map_err(|e| err(offset, e))
    };
    let v3 = |a: &[f64; 3]| DVec3::from_array(*a);
    let last = |v: &[f64]| v[v.len() - 1];

    // Which elements hang from which joint (see `crate::pose`).
    let mut marks: crate::pose::Marks = Vec::new();
    for p in s.point.iter().flatten() {
        let first = skeleton.len();
        let (r, w, g) = common(p.at.span().start, &p.radius, &p.strength, &p.group, &skeleton)?;
        count(&p.radius, r.len(), 1, "radius", "point")?;
        count(&p.strength, w.len(), 1, "strength", "point")?;
        let at_ = v3(p.at.get_ref());
        if !at_.is_finite() {
            return Err(err(p.at.span().start, SkeletonError::NonFinite));
        }
        let e = Element::new(Shape::Point(at_), r[0]).and_then(|e| e.with_strength(w[0]));
        add(&mut skeleton, e, g, p.at.span().start)?;
        paint(&mut skeleton, first, &p.color, at)?;
        marks.push((first..skeleton.len(), p.joint.as_ref()));
    }
    for sg in s.segment.iter().flatten() {
        let first = skeleton.len();
        let (r, w, g) = common(sg.a.span().start, &sg.radius, &sg.strength, &sg.group, &skeleton)?;
        count(&sg.radius, r.len(), 2, "radius", "segment")?;
        count(&sg.strength, w.len(), 2, "strength", "segment")?;
        let seg = Segment::new(v3(sg.a.get_ref()), v3(sg.b.get_ref()))
            .map_err(|e| err(sg.b.span().start, e))?;
        let e = Element::new(Shape::Segment(seg), r[0])
            .and_then(|e| e.with_end_radius(last(&r)))
            .and_then(|e| e.with_strength(w[0]))
            .and_then(|e| e.with_end_strength(last(&w)));
        add(&mut skeleton, e, g, sg.a.span().start)?;
        paint(&mut skeleton, first, &sg.color, at)?;
        marks.push((first..skeleton.len(), sg.joint.as_ref()));
    }
    for pl in s.polyline.iter().flatten() {
        let first = skeleton.len();
        let pat = pl.points.span().start;
        let (r, w, g) = common(pat, &pl.radius, &pl.strength, &pl.group, &skeleton)?;
        let pts: Vec<DVec3> = pl.points.get_ref().iter().map(v3).collect();
        count(&pl.radius, r.len(), pts.len(), "radius", "polyline (per point)")?;
        count(&pl.strength, w.len(), pts.len(), "strength", "polyline (per point)")?;
        let range = if r.len() == 1 {
            skeleton.add_polyline(&pts, r[0], g)
        } else {
            skeleton.add_tapered_polyline(&pts, &r, g)
        }
        .map_err(|e| err(pat, e))?;
        if w.len() == 1 {
            set_strength(&mut skeleton, range, w[0]).map_err(|e| err(pat, e))?;
        } else {
            for (k, i) in range.enumerate() {
                skeleton.set_end_strengths(i, (w[k], w[k + 1])).map_err(|e| err(pat, e))?;
            }
        }
        paint(&mut skeleton, first, &pl.color, at)?;
        marks.push((first..skeleton.len(), pl.joint.as_ref()));
    }
    for cv in s.curve.iter().flatten() {
        let first = skeleton.len();
        let cat = cv.bezier.span().start;
        let (r, w, g) = common(cat, &cv.radius, &cv.strength, &cv.group, &skeleton)?;
        count(&cv.radius, r.len(), 2, "radius", "curve (start and end)")?;
        count(&cv.strength, w.len(), 1, "strength", "curve")?;
        let tol = match &cv.tolerance {
            Some(t) => {
                let v = *t.get_ref();
                if !(v.is_finite() && v > 0.0) {
                    return Err(at(
                        t.span().start,
                        format!("tolerance must be a positive length (got {v})"),
                    ));
                }
                v
            }
            None => 0.1 * r[0].min(last(&r)),
        };
        let curve = CubicCurve::bezier(cv.bezier.get_ref().map(DVec3::from_array));
        let range = skeleton
            .add_tapered_curve(&curve, tol, (r[0], last(&r)), g)
            .map_err(|e| err(cat, e))?;
        set_strength(&mut skeleton, range, w[0]).map_err(|e| err(cat, e))?;
        paint(&mut skeleton, first, &cv.color, at)?;
        marks.push((first..skeleton.len(), cv.joint.as_ref()));
    }
    for (kind, list) in [("triangle", &s.triangle), ("polygon", &s.polygon)] {
        for pg in list.iter().flatten() {
            let first = skeleton.len();
            let vat = pg.vertices.span().start;
            let (r, w, g) = common(vat, &pg.radius, &pg.strength, &pg.group, &skeleton)?;
            count(&pg.radius, r.len(), 1, "radius", kind)?;
            count(&pg.strength, w.len(), 1, "strength", kind)?;
            let vs: Vec<DVec3> = pg.vertices.get_ref().iter().map(v3).collect();
            if kind == "triangle" && vs.len() != 3 {
                return Err(at(
                    vat,
                    format!(
                        "a triangle has 3 vertices (got {}); use [[skeleton.polygon]] for more",
                        vs.len()
                    ),
                ));
            }
            if let Some(m) = &pg.polygon_method {
                conv_only("polygon_method", m.span().start)?;
            }
            for (key, offset) in [
                ("weights", pg.weights.as_ref().map(|w| w.span().start)),
                ("weight_image", pg.weight_image.as_ref().map(|w| w.span().start)),
            ] {
                if let Some(o) = offset {
                    conv_only(key, o)?;
                }
            }
            // A weight image scales the polygon's raster image (DIS §6.4): without a method
            // of its own the polygon takes the image method, at the resolution given.
            let own_method = match (&pg.weight_image, &pg.polygon_method) {
                (Some(wi), None) => Some(Spanned::new(wi.span(), "image".to_string())),
                (Some(wi), Some(m)) if m.get_ref() == "exact" => {
                    return Err(err(wi.span().start, SkeletonError::WeightImageNeedsImageMethod));
                }
                (_, m) => m.clone(),
            };
            let method =
                polygon_method(&own_method, &pg.image_resolution, Some(default_method), at)?;
            let poly = Polygon::new(vs).map_err(|e| err(vat, e))?;
            let mut e = Element::new(Shape::Polygon(poly), r[0])
                .and_then(|e| e.with_strength(w[0]))
                .and_then(|e| e.with_polygon_method(method))
                .map_err(|e| err(vat, e))?;
            if let Some(ws) = &pg.weights {
                e = e
                    .with_vertex_weights(ws.get_ref().clone())
                    .map_err(|e| err(ws.span().start, e))?;
            }
            if let Some(wi) = &pg.weight_image {
                let image = weight_image(wi.get_ref(), base, at, wi.span().start)?;
                e = e.with_weight_image(Arc::new(image)).map_err(|e| err(wi.span().start, e))?;
            }
            add(&mut skeleton, Ok(e), g, vat)?;
            paint(&mut skeleton, first, &pg.color, at)?;
            marks.push((first..skeleton.len(), pg.joint.as_ref()));
        }
    }
    if let (Some(j), Some(_)) = (s.junction.as_ref().and_then(|j| j.first()), &s.joint) {
        return Err(at(
            j.at.span().start,
            "junctions and joints cannot be combined yet: a junction splits the segments \
             through it, and the pieces would not follow their joint"
                .to_string(),
        ));
    }
    for j in s.junction.iter().flatten() {
        let direction = j.direction.as_ref().map(|d| v3(d.get_ref()));
        skeleton.add_junction(v3(j.at.get_ref()), direction).map_err(|e| {
            let offset = match (&e, &j.direction) {
                (SkeletonError::BadDirection(_), Some(d)) => d.span().start,
                _ => j.at.span().start,
            };
            err(offset, e)
        })?;
    }
    if let Some(c) = &s.color {
        skeleton.set_default_color(*c.get_ref()).map_err(|e| err(c.span().start, e))?;
    }
    let sweeps = crate::sweep::build(s.sweep.as_deref().unwrap_or(&[]), at, base)?;
    if skeleton.is_empty() && sweeps.is_empty() {
        return Err(at(
            section_at,
            "the skeleton has no elements: add [[skeleton.point]], [[skeleton.segment]], \
             [[skeleton.polyline]], [[skeleton.curve]], [[skeleton.triangle]], [[skeleton.polygon]] or [[skeleton.sweep]]"
                .into(),
        ));
    }
    let spec = crate::pose::Spec {
        joints: s.joint.as_deref(),
        poses: s.poses.as_ref(),
        pose: s.pose.as_ref(),
    };
    let (skeleton, articulation) = crate::pose::articulate(&spec, skeleton, &marks, choice, at)?;

    let bad_blend = |e: SkeletonError| {
        let offset = match &e {
            SkeletonError::BadParameter { name: "range", .. } => {
                s.range.as_ref().map(|r| r.span().start)
            }
            SkeletonError::BadParameter { name: "thumbweight", .. } => {
                s.thumbweight.as_ref().map(|r| r.span().start)
            }
            SkeletonError::KernelConvolvesPointsOnly { .. } => {
                s.kernel.as_ref().map(|k| k.span().start)
            }
            _ => None,
        };
        err(offset.unwrap_or(blend_at), e)
    };
    if let Some(b) = &s.blended_normals
        && skeleton.junctions().is_empty()
    {
        return Err(at(
            b.span().start,
            "blended_normals applies to junctions (DIS appendix A.2); this skeleton has none"
                .to_string(),
        ));
    }
    let blended = s.blended_normals.as_ref().is_some_and(|b| *b.get_ref());
    let separable = match &s.segment_method {
        None => false,
        Some(m) => {
            conv_only("segment_method", m.span().start)?;
            match m.get_ref().as_str() {
                "exact" => false,
                "separable" => true,
                other => {
                    return Err(at(
                        m.span().start,
                        format!("unknown segment_method '{other}'; expected exact or separable"),
                    ));
                }
            }
        }
    };
    let skeleton_field = if skeleton.is_empty() {
        None
    } else {
        Some(
            SkeletonField::new(&skeleton, blend)
                .map_err(bad_blend)?
                .with_blended_normals(blended)
                .with_separable_segments(separable),
        )
    };
    let mut field = SweptField::new(skeleton_field, sweeps, blend).map_err(bad_blend)?;
    if let Some(i) = &s.iso {
        field = field.with_iso(*i.get_ref()).map_err(|e| err(i.span().start, e))?;
    }
    let combine = match &s.combine {
        None => None,
        Some(c) => Some((
            match c.get_ref().as_str() {
                "union" => Combine::Union,
                "intersection" => Combine::Intersection,
                "difference" => Combine::Difference,
                other => {
                    return Err(at(
                        c.span().start,
                        format!(
                            "unknown combine '{other}'; expected union, intersection or difference"
                        ),
                    ));
                }
            },
            c.span().start,
        )),
    };
    let skeleton = field.skeleton().cloned().map(Arc::new);
    Ok(Built { field: Arc::new(field), skeleton, combine, section_at, articulation })
}

/// Reads a polygon's weight image: each pixel's lightness times its opacity, from 0 (black
/// or transparent) to 1 (white).
fn weight_image(
    name: &str,
    base: Option<&std::path::Path>,
    at: At,
    offset: usize,
) -> Result<WeightImage, SceneError> {
    let png = crate::sweep::read_png(
        name,
        base,
        at,
        offset,
        crate::sweep::FileKey::WeightImage,
        MAX_SECTION_PIXELS,
    )?;
    let values = png.pixels.iter().map(|&(light, alpha)| light / 255.0 * (alpha / 255.0)).collect();
    WeightImage::new(png.width, png.height, values)
        .map_err(|e| at(offset, format!("weight_image '{name}': {e}")))
}

/// The polygon method from `polygon_method` and `image_resolution` keys (a polygon's own,
/// over the section's `default`).
fn polygon_method(
    method: &Option<Spanned<String>>,
    resolution: &Option<Spanned<i64>>,
    default: Option<PolygonMethod>,
    at: At,
) -> Result<PolygonMethod, SceneError> {
    let res = match resolution {
        Some(r) => {
            let v = *r.get_ref();
            if !(4..=MAX_IMAGE_RESOLUTION as i64).contains(&v) {
                return Err(at(
                    r.span().start,
                    format!(
                        "image_resolution must be between 4 and {MAX_IMAGE_RESOLUTION} pixels (got {v})"
                    ),
                ));
            }
            Some(v as usize)
        }
        None => None,
    };
    let base = default.unwrap_or_default();
    let m = match method.as_ref().map(|m| (m.get_ref().as_str(), m.span().start)) {
        None => match (base, res) {
            (PolygonMethod::Image { .. }, Some(n)) => PolygonMethod::Image { resolution: n },
            (PolygonMethod::Exact, Some(_)) => {
                let r = resolution.as_ref().map_or(0, |r| r.span().start);
                return Err(at(
                    r,
                    "image_resolution applies to polygon_method = \"image\" only".into(),
                ));
            }
            (b, None) => b,
        },
        Some(("exact", offset)) => {
            if res.is_some() {
                return Err(at(
                    offset,
                    "image_resolution applies to polygon_method = \"image\" only".into(),
                ));
            }
            PolygonMethod::Exact
        }
        Some(("image", _)) => PolygonMethod::Image {
            resolution: res.unwrap_or(match base {
                PolygonMethod::Image { resolution } => resolution,
                PolygonMethod::Exact => DEFAULT_IMAGE_RESOLUTION,
            }),
        },
        Some((other, offset)) => {
            return Err(at(
                offset,
                format!("unknown polygon_method '{other}'; expected exact or image"),
            ));
        }
    };
    Ok(m)
}

/// Gives the elements from `first` on (those just added) the colour `color`, if any, checked (each component from 0
/// to 1) and reported at its position.
fn paint(
    skeleton: &mut Skeleton,
    first: usize,
    color: &Option<Spanned<[f64; 3]>>,
    at: At,
) -> Result<(), SceneError> {
    let Some(c) = color else { return Ok(()) };
    for i in first..skeleton.len() {
        skeleton.set_color(i, *c.get_ref()).map_err(|e| at(c.span().start, e.to_string()))?;
    }
    Ok(())
}

fn set_strength(
    skeleton: &mut Skeleton,
    range: std::ops::Range<usize>,
    w: f64,
) -> Result<(), SkeletonError> {
    for i in range {
        skeleton.set_strength(i, w)?;
    }
    Ok(())
}

fn unknown_group(name: &str, skeleton: &Skeleton) -> String {
    let known: Vec<&str> = skeleton.groups().iter().map(|g| g.name.as_str()).collect();
    format!("unknown group '{name}'; declare it in [skeleton.groups] (known: {})", known.join(", "))
}

#[cfg(test)]
mod tests {
    use crate::{Scene, SceneError};
    use skelform_field::{DVec3, Field};

    const HEAD: &str = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n";

    fn parse(body: &str) -> Result<Scene, SceneError> {
        Scene::parse(&format!("{HEAD}{body}"), "s.toml")
    }

    /// The error's line (counting the three lines of HEAD), column and message.
    fn error(body: &str) -> (usize, usize, String) {
        crate::testing::error_position(parse(body), body)
    }

    #[test]
    fn a_skeleton_scene_is_a_skeletal_field_with_seeds() {
        let s = parse(
            "[skeleton]\nradius = 0.2\n[[skeleton.segment]]\na = [-0.5, 0, 0]\nb = [0.5, 0, 0]\n\
             [[skeleton.point]]\nat = [0, 0.6, 0]\nradius = 0.15\n",
        )
        .unwrap();
        let sk = s.skeleton.as_ref().expect("skeleton");
        assert_eq!(sk.element_count(), 2);
        assert!(s.field.eval(DVec3::ZERO) < 0.0);
        assert!(s.field.eval(DVec3::new(0.0, 0.0, 0.2)).abs() < 0.01, "surface one radius out");
        assert!(s.field.eval(DVec3::new(0.0, 0.0, 0.5)) > 0.0);
        assert!(s.field.has_exact_gradient());
        // Points come first, then segments, … (each kind in file order).
        assert_eq!(s.continuation.seeds, vec![DVec3::new(0.0, 0.6, 0.0), DVec3::ZERO]);
        assert_eq!(s.iso, 0.5);
    }

    #[test]
    fn scene_seeds_win_over_skeleton_seeds() {
        let s = parse(
            "[mesh]\nseeds = [[0.1, 0, 0]]\n[skeleton]\nradius = 0.2\n[[skeleton.segment]]\na = [-0.5, 0, 0]\nb = [0.5, 0, 0]\n",
        )
        .unwrap();
        assert_eq!(s.continuation.seeds, vec![DVec3::new(0.1, 0.0, 0.0)]);
    }

    #[test]
    fn every_construct_parses() {
        let s = parse(
            r#"
[skeleton]
blend = "sum"
kernel = "triweight"
iso = 0.4
radius = 0.1
[skeleton.groups]
a = []
b = ["a"]
[[skeleton.point]]
at = [0, 0, 0]
strength = 2
group = "a"
[[skeleton.segment]]
a = [0, 0, 0]
b = [0.3, 0, 0]
group = "b"
[[skeleton.polyline]]
points = [[0, 0, 0], [0, 0.3, 0], [0, 0.3, 0.3]]
strength = 0.5
[[skeleton.curve]]
bezier = [[0, 0, 0], [0, 0, 0.3], [0.3, 0, 0.3], [0.3, 0.3, 0.3]]
[[skeleton.triangle]]
vertices = [[0, 0, 0], [0.2, 0, 0], [0, 0.2, 0]]
[[skeleton.polygon]]
vertices = [[0, 0, 0.5], [0.2, 0, 0.5], [0.2, 0.2, 0.5], [0, 0.2, 0.5]]
radius = 0.05
"#,
        )
        .unwrap();
        let sk = s.skeleton.unwrap();
        assert!(sk.element_count() >= 7);
        assert_eq!(sk.iso(), Some(0.4));
        for (blend, extra) in [
            ("union", "falloff = \"squared\""),
            ("elliptic", "range = 0.5"),
            ("super-elliptic", "thumbweight = 4"),
            ("combination", "clamp = false"),
        ] {
            parse(&format!(
                "[skeleton]\nblend = \"{blend}\"\n{extra}\nradius = 0.1\n[[skeleton.point]]\nat = [0, 0, 0]\n"
            ))
            .unwrap();
        }
    }

    #[test]
    fn bad_input_is_reported_with_its_line_and_column() {
        let seg = "[[skeleton.segment]]\na = [0, 0, 0]\nb = [1, 0, 0]\n";
        // Negative radius: at the value.
        let (l, c, m) = error(&format!("[skeleton]\n{seg}radius = -0.1\n"));
        assert_eq!((l, c), (8, 10), "{m}");
        assert!(m.contains("radius must be a positive length (got -0.1)"), "{m}");
        // Zero-length segment: at the second end.
        let (l, c, m) =
            error("[skeleton]\nradius = 0.1\n[[skeleton.segment]]\na = [0, 0, 0]\nb = [0, 0, 0]\n");
        assert_eq!((l, c), (8, 5), "{m}");
        assert!(m.contains("zero length"), "{m}");
        // Degenerate polygon: at its vertices.
        let (l, _, m) = error(
            "[skeleton]\nradius = 0.1\n[[skeleton.triangle]]\nvertices = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]\n",
        );
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("degenerate"), "{m}");
        // Not planar.
        let (l, _, m) = error(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\nvertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0]]\n",
        );
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("not planar"), "{m}");
        // Unknown kernel: at the name.
        let (l, c, m) = error(&format!("[skeleton]\nkernel = \"gauss\"\nradius = 0.1\n{seg}"));
        assert_eq!((l, c), (5, 10), "{m}");
        assert!(m.contains("unknown kernel 'gauss'") && m.contains("gaussian"), "{m}");
        // The sinc under convolution takes points only: at the kernel.
        let (l, c, m) = error(&format!("[skeleton]\nkernel = \"sinc\"\nradius = 0.1\n{seg}"));
        assert_eq!((l, c), (5, 10), "{m}");
        assert!(m.contains("sinc kernel convolves points only") && m.contains("segment"), "{m}");
        assert!(m.contains("blend = \"sum\""), "{m}");
        // …while the sum blend takes it, and convolution takes it for points.
        let sum =
            parse(&format!("[skeleton]\nblend = \"sum\"\nkernel = \"sinc\"\nradius = 0.1\n{seg}"));
        assert!(sum.is_ok());
        let pt = "[[skeleton.point]]\nat = [0, 0, 0]\n";
        assert!(parse(&format!("[skeleton]\nkernel = \"sinc\"\nradius = 0.1\n{pt}")).is_ok());
        // Unknown group: at the group name.
        let (l, c, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n[skeleton.groups]\npalm = []\n{seg}group = \"plam\"\n"
        ));
        assert_eq!((l, c), (11, 9), "{m}");
        assert!(m.contains("unknown group 'plam'") && m.contains("palm"), "{m}");
        // Unknown group in a blend list.
        let (l, _, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n[skeleton.groups]\npalm = [\"thumb\"]\n{seg}"
        ));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("unknown group 'thumb'"), "{m}");
        // Repeated polyline point.
        let (l, _, m) = error(
            "[skeleton]\nradius = 0.1\n[[skeleton.polyline]]\npoints = [[0, 0, 0], [1, 0, 0], [1, 0, 0]]\n",
        );
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("point 2 repeats"), "{m}");
        // No radius anywhere.
        let (l, _, m) = error(&format!("[skeleton]\n{seg}"));
        assert_eq!(l, 6, "{m}");
        assert!(m.contains("needs a radius"), "{m}");
        // A key the blend does not read.
        let (l, c, m) = error(&format!(
            "[skeleton]\nblend = \"union\"\nkernel = \"wyvill\"\nradius = 0.1\n{seg}"
        ));
        assert_eq!((l, c), (6, 10), "{m}");
        assert!(m.contains("'kernel' does not apply to the union blend"), "{m}");
        // Unknown key in an element.
        let (l, _, m) = error(&format!("[skeleton]\nradius = 0.1\n{seg}raduis = 0.2\n"));
        assert_eq!(l, 9, "{m}");
        assert!(m.contains("raduis"), "{m}");
        // Unknown blend.
        let (_, _, m) = error(&format!("[skeleton]\nblend = \"metaball\"\nradius = 0.1\n{seg}"));
        assert!(m.contains("unknown blend 'metaball'"), "{m}");
        // A bad range.
        let (l, c, m) =
            error(&format!("[skeleton]\nblend = \"elliptic\"\nrange = -1\nradius = 0.1\n{seg}"));
        assert_eq!((l, c), (6, 9), "{m}");
        assert!(m.contains("range must be a positive number"), "{m}");
        // No elements.
        let (_, _, m) = error("[skeleton]\nradius = 0.1\n");
        assert!(m.contains("no elements"), "{m}");
        // Neither field nor skeleton.
        let (_, _, m) = error("");
        assert!(m.contains("a [field] formula, a [skeleton] or [regions]"), "{m}");
        // Both, without saying how to combine.
        let (_, _, m) =
            error(&format!("[field]\nformula = \"z\"\n[skeleton]\nradius = 0.1\n{seg}"));
        assert!(m.contains("combine"), "{m}");
    }

    #[test]
    fn junctions_tapers_angle_scaling_and_polygon_methods_parse() {
        let tee = "[[skeleton.segment]]\na = [-0.6, 0, 0]\nb = [0.6, 0, 0]\n\
                   [[skeleton.segment]]\na = [0, 0, 0]\nb = [0, 0.6, 0]\n";
        let plain = parse(&format!("[skeleton]\nradius = 0.1\n{tee}")).unwrap();
        let joint = parse(&format!(
            "[skeleton]\nradius = 0.1\n{tee}[[skeleton.junction]]\nat = [0, 0, 0]\n"
        ))
        .unwrap();
        let above = DVec3::new(0.0, 0.0, 0.11);
        assert!(plain.field.eval(above) < 0.0, "the plain tee bulges above its junction");
        assert!(joint.field.eval(above) > 0.0, "the junction removes the bulge");
        // The bar was split at the junction: one more element.
        assert_eq!(joint.skeleton.as_ref().unwrap().element_count(), 3);

        // A tapered segment, a tapered polyline, a tapered curve, per-end strengths.
        let s = parse(
            "[skeleton]\n[[skeleton.segment]]\na = [-0.8, 0, 0]\nb = [0.8, 0, 0]\nradius = [0.05, 0.15]\n\
             strength = [1, 1.5]\n[[skeleton.polyline]]\npoints = [[0, 0.5, 0], [0.3, 0.5, 0], [0.6, 0.5, 0]]\n\
             radius = [0.05, 0.08, 0.05]\nstrength = [1, 2, 1]\n[[skeleton.curve]]\nbezier = [[0, -0.5, 0], [0.2, -0.3, 0], [0.4, -0.7, 0], [0.6, -0.5, 0]]\n\
             radius = [0.03, 0.06]\n",
        )
        .unwrap();
        let f = &s.field;
        assert!(f.eval(DVec3::new(-0.4, 0.0, 0.1)) > 0.0, "thin end");
        assert!(f.eval(DVec3::new(0.4, 0.0, 0.1)) < 0.0, "thick end");
        // The polyline's middle point weighs 2: thicker there than at its ends.
        assert!(f.eval(DVec3::new(0.3, 0.5, 0.09)) < 0.0, "heavy middle");
        assert!(f.eval(DVec3::new(0.05, 0.5, 0.09)) > 0.0, "light end");

        let cross = "[[skeleton.segment]]\na = [-1, 0, 0]\nb = [1, 0, 0]\n\
                     [[skeleton.segment]]\na = [0, 0, -1]\nb = [0, 0, 1]\n";
        let bulge = |extra: &str| {
            let s = parse(&format!(
                "[skeleton]\nblend = \"super-elliptic\"\nradius = 0.1\n{extra}{cross}"
            ))
            .unwrap();
            s.field.eval(DVec3::new(0.0, 0.11, 0.0))
        };
        assert!(bulge("") < 0.0 && bulge("angle_scaled = true\n") > 0.0);

        let square = "vertices = [[0, 0, 0], [0.5, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0]]\n";
        let img = parse(&format!(
            "[skeleton]\nradius = 0.1\npolygon_method = \"image\"\nimage_resolution = 60\n\
             [[skeleton.polygon]]\n{square}[[skeleton.polygon]]\n{square}polygon_method = \"exact\"\n"
        ))
        .unwrap();
        let ex = parse(&format!(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\n{square}[[skeleton.polygon]]\n{square}"
        ))
        .unwrap();
        let p = DVec3::new(0.25, 0.3, 0.12);
        let (a, b) = (img.field.eval(p), ex.field.eval(p));
        assert!(a != b && (a - b).abs() < 1e-2, "{a} vs {b}");
    }

    #[test]
    fn bad_junctions_tapers_and_methods_are_reported_with_their_position() {
        let seg = "[[skeleton.segment]]\na = [0, 0, 0]\nb = [1, 0, 0]\n";
        // A junction with a single limb: at its `at`.
        let (l, c, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n{seg}[[skeleton.junction]]\nat = [0, 0, 0]\n"
        ));
        assert_eq!((l, c), (10, 6), "{m}");
        assert!(m.contains("at least 2 limbs"), "{m}");
        // Collinear limbs: fine (any direction across them).
        let two = "[[skeleton.segment]]\na = [0, 0, 0]\nb = [-1, 0, 0]\n";
        parse(&format!(
            "[skeleton]\nradius = 0.1\n{seg}{two}[[skeleton.junction]]\nat = [0, 0, 0]\n"
        ))
        .unwrap();
        // A zero direction: at the direction.
        let (l, c, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n{seg}{two}[[skeleton.junction]]\nat = [0, 0, 0]\ndirection = [0, 0, 0]\n"
        ));
        assert_eq!((l, c), (14, 13), "{m}");
        assert!(m.contains("non-zero"), "{m}");
        // Junctions with another blend.
        let (_, _, m) = error(&format!(
            "[skeleton]\nblend = \"union\"\nradius = 0.1\n{seg}{two}[[skeleton.junction]]\nat = [0, 0, 0]\n"
        ));
        assert!(m.contains("does not apply to the union blend"), "{m}");
        // Three radii on a segment; two on a point; a negative one in a list.
        let (l, c, m) = error(&format!("[skeleton]\n{seg}radius = [0.1, 0.2, 0.3]\n"));
        assert_eq!((l, c), (8, 10), "{m}");
        assert!(m.contains("one radius or 2 (got 3)"), "{m}");
        let (_, _, m) =
            error("[skeleton]\n[[skeleton.point]]\nat = [0, 0, 0]\nradius = [0.1, 0.2]\n");
        assert!(m.contains("only segments, polylines and curves taper"), "{m}");
        let (_, _, m) = error(&format!("[skeleton]\n{seg}radius = [0.1, -0.2]\n"));
        assert!(m.contains("radius must be a positive length (got -0.2)"), "{m}");
        let (_, _, m) = error(
            "[skeleton]\n[[skeleton.polyline]]\npoints = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]\nradius = [0.1, 0.2]\n",
        );
        assert!(m.contains("one radius or 3 (got 2)"), "{m}");
        let (_, _, m) = error(&format!("[skeleton]\n{seg}radius = \"thick\"\n"));
        assert!(m.contains("a number or a list of numbers"), "{m}");
        // Polygon methods.
        let tri = "[[skeleton.triangle]]\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n";
        let (l, c, m) =
            error(&format!("[skeleton]\nradius = 0.1\npolygon_method = \"raster\"\n{tri}"));
        assert_eq!((l, c), (6, 18), "{m}");
        assert!(m.contains("unknown polygon_method 'raster'"), "{m}");
        let (_, _, m) = error(&format!("[skeleton]\nradius = 0.1\nimage_resolution = 40\n{tri}"));
        assert!(m.contains("applies to polygon_method = \"image\" only"), "{m}");
        let (_, _, m) = error(&format!(
            "[skeleton]\nradius = 0.1\npolygon_method = \"image\"\nimage_resolution = 2\n{tri}"
        ));
        assert!(m.contains("between 4 and 1024"), "{m}");
        let (_, _, m) = error(&format!(
            "[skeleton]\nblend = \"sum\"\nradius = 0.1\npolygon_method = \"image\"\n{tri}"
        ));
        assert!(m.contains("'polygon_method' does not apply to the sum blend"), "{m}");
        let (_, _, m) = error(&format!("[skeleton]\nradius = 0.1\nangle_scaled = true\n{tri}"));
        assert!(m.contains("'angle_scaled' does not apply"), "{m}");
    }

    #[test]
    fn a_skeleton_combines_with_a_formula() {
        let seg = "radius = 0.1\n[[skeleton.segment]]\na = [-0.5, 0, 0]\nb = [0.5, 0, 0]\n";
        let s = parse(&format!(
            "[field]\nformula = \"-z\"\n[skeleton]\ncombine = \"difference\"\n{seg}"
        ))
        .unwrap();
        // The formula is inside above z = 0: that half of the tube is removed.
        assert!(s.field.eval(DVec3::new(0.0, 0.0, 0.05)) > 0.0);
        assert!(s.field.eval(DVec3::new(0.0, 0.0, -0.05)) < 0.0);
        let g = s.field.gradient(DVec3::new(0.0, 0.0, 0.05));
        assert!(g.z > 0.0, "{g}");
        let s = parse(&format!("[field]\nformula = \"z\"\n[skeleton]\ncombine = \"union\"\n{seg}"))
            .unwrap();
        assert!(s.field.eval(DVec3::new(0.0, 0.5, -0.5)) < 0.0, "inside the half-space");
        assert!(s.field.eval(DVec3::new(0.0, 0.0, 0.05)) < 0.0, "inside the tube");
        let mut v = [0.0; 2];
        s.field.eval_many(&[DVec3::new(0.0, 0.5, -0.5), DVec3::new(0.0, 0.0, 0.05)], &mut v);
        assert!(v[0] < 0.0 && v[1] < 0.0);
    }

    #[test]
    fn colours_parse_and_bad_ones_are_reported_where_they_are() {
        let seg = "[[skeleton.segment]]\na = [0, 0, 0]\nb = [1, 0, 0]\n";
        let s = parse(&format!(
            "[skeleton]\nradius = 0.1\ncolor = [0, 0, 1]\n{seg}color = [1, 0, 0]\n\
             [[skeleton.polyline]]\npoints = [[0, 1, 0], [1, 1, 0], [2, 1, 0]]\ncolor = [0, 1, 0]\n\
             [[skeleton.point]]\nat = [0, -1, 0]\n"
        ))
        .unwrap();
        let f = s.skeleton.as_ref().unwrap();
        let c = f
            .colors(&[
                DVec3::new(0.5, 0.1, 0.0),
                DVec3::new(1.5, 1.1, 0.0),
                DVec3::new(0.0, -1.1, 0.0),
            ])
            .unwrap();
        assert_eq!(c, vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        // No colour anywhere: no colours.
        let plain = parse(&format!("[skeleton]\nradius = 0.1\n{seg}")).unwrap();
        assert!(plain.skeleton.as_ref().unwrap().colors(&[DVec3::ZERO]).is_none());
        let (l, c, m) = error(&format!("[skeleton]\nradius = 0.1\n{seg}color = [1, 0, 1.5]\n"));
        assert_eq!((l, c), (3 + 6, 9), "{m}");
        assert!(m.contains("colour components must be numbers from 0 to 1"), "{m}");
        let (l, _, m) = error(&format!("[skeleton]\nradius = 0.1\ncolor = [-0.1, 0, 0]\n{seg}"));
        assert_eq!(l, 3 + 3, "{m}");
        let (l, _, m) = error(&format!("[skeleton]\nradius = 0.1\n{seg}color = [1, 0]\n"));
        assert_eq!(l, 3 + 6, "{m}");
        let (_, _, m) = error(&format!("[skeleton]\nradius = 0.1\n{seg}colour = [1, 0, 0]\n"));
        assert!(m.contains("colour"), "{m}");
    }

    #[test]
    fn the_example_skeleton_scenes_load() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/skeleton");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
                assert!(!scene.continuation.seeds.is_empty(), "{}", path.display());
                match scene.skeleton.as_ref() {
                    Some(sk) => {
                        for p in sk.seed_points() {
                            assert!(sk.eval(p) < 0.0, "{}: seed {p} outside", path.display());
                        }
                    }
                    // A ramiform (its own field, seeded from its limbs).
                    None => {
                        for &p in &scene.continuation.seeds {
                            let f = scene.field.eval(p);
                            assert!(f < 0.0, "{}: seed {p} outside", path.display());
                        }
                    }
                }
                n += 1;
            }
        }
        assert!(n >= 8, "found {n} scenes");
    }

    /// A grayscale PNG of `w × h` pixels at a fresh path in the temporary folder.
    fn weight_png(
        name: &str,
        w: u32,
        h: u32,
        value: impl Fn(u32, u32) -> u8,
    ) -> std::path::PathBuf {
        crate::testing::grayscale_png("skelform-weights", name, w, h, value)
    }

    #[test]
    fn polygon_weights_and_weight_images_parse_and_apply() {
        use skelform_skeleton::convolution::convolve_weighted;
        use skelform_skeleton::{Kernel, Polygon};
        let quad = "vertices = [[-0.5, -0.2, 0], [0.5, -0.2, 0], [0.5, 0.2, 0], [-0.5, 0.2, 0]]\n";
        let s = parse(&format!(
            "[skeleton]\nradius = 0.1\nkernel = \"wyvill\"\n[[skeleton.polygon]]\n{quad}\
             weights = [1, 0.4, 0.4, 1]\n"
        ))
        .unwrap();
        let poly = Polygon::new(vec![
            DVec3::new(-0.5, -0.2, 0.0),
            DVec3::new(0.5, -0.2, 0.0),
            DVec3::new(0.5, 0.2, 0.0),
            DVec3::new(-0.5, 0.2, 0.0),
        ])
        .unwrap();
        for p in
            [DVec3::new(-0.3, 0.0, 0.05), DVec3::new(0.3, 0.1, 0.02), DVec3::new(0.0, 0.0, 0.0)]
        {
            let (want, _) =
                convolve_weighted(Kernel::Wyvill, &poly, &[1.0, 0.4, 0.4, 1.0], 0.1, p).unwrap();
            assert!((s.field.eval(p) - (0.5 - want)).abs() < 1e-12);
        }
        // A weight image: white on the left half, black on the right (columns run along e1,
        // from the centre towards vertex 0, i.e. towards -x here): the -x half remains.
        let img = weight_png("half.png", 16, 4, |c, _| if c < 8 { 255 } else { 0 });
        let s = parse(&format!(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\n{quad}weight_image = {:?}\n\
             image_resolution = 60\n",
            img.display().to_string()
        ))
        .unwrap();
        assert!(s.field.eval(DVec3::new(-0.3, 0.0, 0.0)) < 0.0, "inside where the image is white");
        assert!(s.field.eval(DVec3::new(0.3, 0.0, 0.0)) > 0.0, "outside where it is black");
        // Relative to the scene's folder.
        let dir = img.parent().unwrap();
        let scene = dir.join("weighted.toml");
        std::fs::write(
            &scene,
            format!(
                "{HEAD}[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\n{quad}weight_image = \"half.png\"\n"
            ),
        )
        .unwrap();
        assert!(Scene::load(&scene).is_ok());
    }

    #[test]
    fn segment_method_and_blended_normals_parse_and_are_checked() {
        let tee = "[[skeleton.segment]]\na = [-0.5, 0, 0]\nb = [0.5, 0, 0]\n\
                   [[skeleton.segment]]\na = [0, 0, 0]\nb = [0, 0.5, 0]\n";
        let exact =
            parse(&format!("[skeleton]\nradius = 0.1\nkernel = \"wyvill\"\n{tee}")).unwrap();
        let sep = parse(&format!(
            "[skeleton]\nradius = 0.1\nkernel = \"wyvill\"\nsegment_method = \"separable\"\n{tee}"
        ))
        .unwrap();
        // Beyond the bar's end the exact Wyvill convolution still reaches the surface; the
        // separable one ends at the segment's end.
        let p = DVec3::new(0.505, 0.0, 0.0);
        assert!(exact.field.eval(p) < 0.0 && sep.field.eval(p) > 0.0);
        let (l, _, m) =
            error(&format!("[skeleton]\nradius = 0.1\nsegment_method = \"points\"\n{tee}"));
        assert_eq!(l, 6, "{m}");
        assert!(m.contains("unknown segment_method 'points'"), "{m}");
        let (l, _, m) = error(&format!(
            "[skeleton]\nblend = \"union\"\nradius = 0.1\nsegment_method = \"separable\"\n{tee}"
        ));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("does not apply to the union blend"), "{m}");
        // Blended normals: the same values, other gradients near the junction.
        let junction = "[[skeleton.junction]]\nat = [0, 0, 0]\n";
        let plain = parse(&format!("[skeleton]\nradius = 0.1\n{tee}{junction}")).unwrap();
        let blended =
            parse(&format!("[skeleton]\nradius = 0.1\nblended_normals = true\n{tee}{junction}"))
                .unwrap();
        let q = DVec3::new(0.08, 0.05, 0.07);
        assert_eq!(plain.field.eval(q), blended.field.eval(q));
        assert!((plain.field.gradient(q) - blended.field.gradient(q)).length() > 1e-6);
        let (l, _, m) = error(&format!("[skeleton]\nradius = 0.1\nblended_normals = true\n{tee}"));
        assert_eq!(l, 6, "{m}");
        assert!(m.contains("blended_normals applies to junctions"), "{m}");
    }

    #[test]
    fn bad_polygon_weights_are_reported_with_their_position() {
        let quad = "vertices = [[-0.5, -0.2, 0], [0.5, -0.2, 0], [0.5, 0.2, 0], [-0.5, 0.2, 0]]\n";
        let (l, c, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\n{quad}weights = [1, 2]\n"
        ));
        assert_eq!((l, c), (8, 11), "{m}");
        assert!(m.contains("2 per-vertex weights for a polygon of 4 vertices"), "{m}");
        let (l, _, m) = error(&format!(
            "[skeleton]\nblend = \"sum\"\nradius = 0.1\n[[skeleton.polygon]]\n{quad}weights = [1, 1, 1, 1]\n"
        ));
        assert_eq!(l, 9, "{m}");
        assert!(m.contains("'weights' does not apply to the sum blend"), "{m}");
        let (l, _, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\n{quad}polygon_method = \"exact\"\n\
             weight_image = \"w.png\"\n"
        ));
        assert_eq!(l, 9, "{m}");
        assert!(m.contains("cannot use polygon_method = \"exact\""), "{m}");
        let (l, _, m) = error(&format!(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\n{quad}weight_image = \"no-such.png\"\n"
        ));
        assert_eq!(l, 8, "{m}");
        assert!(m.contains("weight_image") && m.contains("cannot open"), "{m}");
        // An L whose vertex average lies outside it.
        let (l, _, m) = error(
            "[skeleton]\nradius = 0.1\n[[skeleton.polygon]]\nvertices = [[0, 0, 0], [0.9, 0, 0], \
             [0.9, 0.05, 0], [0.05, 0.05, 0], [0.05, 0.9, 0], [0, 0.9, 0]]\nweights = [1, 1, 1, 1, 1, 1]\n",
        );
        assert_eq!(l, 8, "{m}");
        assert!(m.contains("star-shaped"), "{m}");
    }
}

#[cfg(test)]
mod example_meshes {
    use crate::Scene;
    use skelform_mesh::check::check;
    use skelform_polygonize::LatticeOptions;
    use skelform_polygonize::grid::{Options, Resolution, polygonize};

    /// Polygonizes each scene (grid method, at the scene's resolution or at `samples` per
    /// axis) and checks that it is closed, manifold, consistently oriented, outward, in the
    /// expected number of pieces.
    fn check_examples(expected: &[(&str, usize)], samples: Option<usize>) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/skeleton");
        for &(file, pieces) in expected {
            let scene = Scene::load(&dir.join(file)).unwrap_or_else(|e| panic!("{e}"));
            let lattice = LatticeOptions {
                domain: scene.domain,
                resolution: samples.map_or(scene.resolution, Resolution::Samples),
                ..Default::default()
            };
            let opts = Options { lattice, ..Default::default() };
            let (mesh, _) =
                polygonize(&*scene.field, &opts).unwrap_or_else(|e| panic!("{file}: {e}"));
            let r = check(&mesh);
            println!("{file}: {} triangles, {} components", r.faces, r.components.len());
            assert_eq!(r.components.len(), pieces, "{file}");
            assert!(
                r.components.iter().all(|c| c.is_closed_manifold() && c.consistently_oriented),
                "{file}"
            );
            assert_eq!(r.outward, Some(true), "{file}");
        }
    }

    /// Every example skeleton scene polygonizes (with the grid method, at the scene's
    /// resolution) into closed, manifold, consistently oriented pieces, as many as its
    /// comment says.
    #[test]
    fn example_skeleton_scenes_make_closed_manifold_meshes() {
        check_examples(
            &[
                ("segment-vs-points.toml", 3),
                ("tee.toml", 1),
                ("starfish.toml", 1),
                ("fingers.toml", 1),
                ("curve.toml", 1),
                ("blade.toml", 1),
                ("elliptic.toml", 1),
                ("combination.toml", 1),
                ("skeleton-and-formula.toml", 1),
                ("trifurcation.toml", 1),
            ],
            None,
        );
    }

    /// The blend-control, taper, kernel and polygon-method examples, on a coarser grid (96
    /// samples across) to keep the debug test suite quick.
    #[test]
    fn blend_control_examples_make_closed_manifold_meshes() {
        check_examples(
            &[
                ("tee-junction.toml", 1),
                ("starfish-junction.toml", 1),
                ("tree-junctions.toml", 1),
                ("crossing-cylinders.toml", 1),
                ("crossing-cylinders-scaled.toml", 1),
                ("tapered.toml", 3),
                ("image-polygons.toml", 1),
                ("muscle-weights.toml", 2),
                ("separable-bspline.toml", 2),
                ("separable-wyvill.toml", 2),
                ("elliptic-segments.toml", 1),
                ("acute-combination.toml", 1),
                ("acute-combination-unclamped.toml", 1),
            ],
            Some(96),
        );
    }

    /// One skeleton under each kernel (fig. 5.54).
    #[test]
    fn kernel_examples_make_three_pieces_each() {
        check_examples(
            &[
                ("kernel-gaussian.toml", 3),
                ("kernel-wyvill.toml", 3),
                ("kernel-triweight.toml", 3),
                ("kernel-bspline.toml", 3),
            ],
            Some(96),
        );
    }

    /// The sinc's ring of 100 sources (fig. 5.49): its tube and a spurious hollow torus
    /// around it, 3.3 to 4.2 radii out — three surfaces, all of genus 1.
    #[test]
    fn the_sinc_ring_has_a_spurious_contour() {
        check_examples(&[("sinc-points.toml", 3)], Some(110));
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/skeleton");
        let scene = Scene::load(&dir.join("sinc-points.toml")).unwrap();
        let lattice = LatticeOptions {
            domain: scene.domain,
            resolution: Resolution::Samples(110),
            ..Default::default()
        };
        let opts = Options { lattice, ..Default::default() };
        let (mesh, _) = polygonize(&*scene.field, &opts).unwrap();
        let r = check(&mesh);
        assert!(r.components.iter().all(|c| c.genus == Some(1)), "{:?}", r.components);
        // 100 sources 0.02 apart make a ring of radius 1/π; the tube lies within 1.1 source
        // radii of it, the band 3.3 to 4.2 radii out.
        let from_ring = |p: &[f32; 3]| {
            let (x, y, z) = (p[0] as f64, p[1] as f64, p[2] as f64);
            (x.hypot(y) - std::f64::consts::FRAC_1_PI).hypot(z) / 0.02
        };
        let tube = mesh.positions.iter().filter(|p| from_ring(p) < 1.3).count();
        let band = mesh.positions.iter().filter(|p| (3.1..4.4).contains(&from_ring(p))).count();
        assert_eq!(tube + band, mesh.positions.len());
        assert!(tube > 1000 && band > 2 * tube, "{tube} {band}");
    }
}
