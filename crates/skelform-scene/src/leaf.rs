//! `[leaf]`: the leaf of the dissertation's chapter 7 as regions of space (beyond 0, vein 1,
//! above 2, below 3) for the non-manifold polygonizer.
//!
//! ```toml
//! [leaf]                 # a generated maple-like leaf; every key optional
//! lobes = 5
//! lobe_depth = 0.45
//! curvature = 0.6
//! seed = 1
//! fillet = "both"        # or "below": veins fillet into the blade's lower side only
//! vein_rule = "capped"   # or "dissertation" (the default): see skelform_leaf::VeinRule
//! kernel = "wyvill"      # the veins' convolution kernel
//! texture = true         # tertiary venation (§7.4) as a texture image; default false
//! texture_size = 1024    # texels along the image's longer side (16 to 8192)
//! tertiary_levels = 4    # midpoint subdivisions of each cut (1 to 8)
//! tertiary_roughness = 0.2   # midpoint perturbation, a fraction of the piece (0 to 0.5)
//! tertiary_width = 0.008 # half-width of a drawn tertiary vein, scene units
//! ```
//!
//! or a flat blade from an outline, with veins given explicitly:
//!
//! ```toml
//! [leaf]
//! outline = [[-1, -1], [1, -1], [1, 1], [-1, 1]]
//! [[leaf.vein]]
//! points = [[-0.6, 0, 0], [0.6, 0, 0]]
//! radius = 0.1           # or radii = [..], one per point (tapered)
//! ```

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::Deserialize;
use skelform_field::{Aabb, DVec3, RegionField};
use skelform_leaf::{
    BladeRegions, Fillet, Leaf, LeafError, LeafParams, LeafTexture, TextureParams, VeinCurve,
    VeinRule, WebStats,
};
use skelform_mesh::{RegionPair, Texture};
use skelform_skeleton::Kernel;
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LeafSection {
    size: Option<Spanned<f64>>,
    lobes: Option<Spanned<i64>>,
    spread: Option<Spanned<f64>>,
    lobe_depth: Option<Spanned<f64>>,
    outer_shortening: Option<Spanned<f64>>,
    secondaries: Option<Spanned<i64>>,
    branch_angle: Option<Spanned<f64>>,
    petiole: Option<Spanned<f64>>,
    curvature: Option<Spanned<f64>>,
    curvature_jitter: Option<Spanned<f64>>,
    jitter: Option<Spanned<f64>>,
    seed: Option<Spanned<i64>>,
    vein_radius: Option<Spanned<f64>>,
    tip_radius: Option<Spanned<f64>>,
    secondary_radius: Option<Spanned<f64>>,
    smooth_margin: Option<Spanned<bool>>,
    max_area: Option<Spanned<f64>>,
    max_ratio: Option<Spanned<f64>>,
    kernel: Option<Spanned<String>>,
    fillet: Option<Spanned<String>>,
    /// "dissertation" (default, `Σ > |d|/r`) or "capped" (`Σ > min(|d|/r, ½)`).
    vein_rule: Option<Spanned<String>>,
    full_grid: Option<bool>,
    /// Colour the blade with the tertiary venation texture of §7.4.
    texture: Option<Spanned<bool>>,
    tertiary_levels: Option<Spanned<i64>>,
    tertiary_roughness: Option<Spanned<f64>>,
    tertiary_width: Option<Spanned<f64>>,
    texture_size: Option<Spanned<i64>>,
    /// A flat blade instead of the generated leaf.
    outline: Option<Spanned<Vec<[f64; 2]>>>,
    vein: Option<Vec<VeinSpec>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct VeinSpec {
    points: Spanned<Vec<[f64; 3]>>,
    radius: Option<Spanned<f64>>,
    radii: Option<Spanned<Vec<f64>>>,
}

/// A scene's leaf, ready for the non-manifold polygonizer.
#[derive(Clone)]
pub struct LeafRegions {
    /// The blade and veins as regions: beyond 0, vein 1, above 2, below 3.
    pub field: Arc<BladeRegions>,
    /// The surfaces of interest: (0,1), (1,2), (1,3), (2,3) (only (2,3) without veins).
    pub interest: Vec<RegionPair>,
    /// `[leaf] full_grid`: visit every cube instead of propagating from the seeds below.
    pub full_grid: bool,
    /// Web polygons, refined polygons and blade triangles.
    pub stats: WebStats,
    /// Points on the blade and veins to start the polygonizer from.
    pub seeds: Vec<DVec3>,
    /// Everything blade and veins reach.
    pub bounds: Aabb,
    /// `[leaf] texture = true`: the tertiary venation texture (§7.4) that colours the mesh's
    /// vertices ([`LeafRegions::colour`]) and gives them texture coordinates
    /// ([`LeafRegions::uv`]) into its image ([`LeafRegions::image`]).
    pub texture: Option<Arc<LeafTexture>>,
    /// The texture's image, drawn once for every mesh of the scene.
    pub image: Option<Arc<Texture>>,
}

impl std::fmt::Debug for LeafRegions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LeafRegions")
            .field("interest", &self.interest)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl LeafRegions {
    /// The region function as the polygonizer takes it, sharing the blade (its triangles
    /// and their hierarchy are not copied).
    pub fn region_field(&self) -> Arc<dyn RegionField> {
        self.field.clone()
    }

    /// The texture's colour (sRGB, 0 to 1) at a point on the leaf; `None` without
    /// `texture = true`.
    pub fn colour(&self, p: DVec3) -> Option<[f32; 3]> {
        self.texture.as_ref().map(|t| t.colour_at(&self.field.blade, p))
    }

    /// The texture coordinates of a point on the leaf in [`LeafRegions::image`]; `None`
    /// without `texture = true`.
    pub fn uv(&self, p: DVec3) -> Option<[f32; 2]> {
        self.texture.as_ref().map(|t| t.uv(&self.field.blade, p))
    }
}

pub(crate) fn build(
    sec: &Spanned<LeafSection>,
    domain: &Aabb,
    at: At,
) -> Result<LeafRegions, SceneError> {
    let s = sec.get_ref();
    let section_at = sec.span().start;
    let kernel = match &s.kernel {
        Some(k) => {
            let kernel =
                k.get_ref().parse::<Kernel>().map_err(|e| at(k.span().start, e.to_string()))?;
            if !kernel.convolves_extended() {
                return Err(at(
                    k.span().start,
                    format!(
                        "the {} kernel convolves points only, and veins are segments; use \
                         wyvill, gaussian, triweight or bspline",
                        kernel.name()
                    ),
                ));
            }
            kernel
        }
        None => Kernel::Wyvill,
    };
    let fillet = match &s.fillet {
        Some(f) => match f.get_ref().as_str() {
            "both" => Fillet::Both,
            "below" => Fillet::Below,
            other => {
                return Err(at(
                    f.span().start,
                    format!("unknown fillet '{other}'; expected both or below"),
                ));
            }
        },
        None => Fillet::Both,
    };
    let vein_rule = match &s.vein_rule {
        Some(f) => match f.get_ref().as_str() {
            "dissertation" => VeinRule::Dissertation,
            "capped" => VeinRule::Capped,
            other => {
                return Err(at(
                    f.span().start,
                    format!("unknown vein_rule '{other}'; expected dissertation or capped"),
                ));
            }
        },
        None => VeinRule::Dissertation,
    };
    // Where each key is written, for errors about its value.
    let generated_keys: [(&'static str, Option<usize>); 16] = [
        ("size", s.size.as_ref().map(|x| x.span().start)),
        ("lobes", s.lobes.as_ref().map(|x| x.span().start)),
        ("spread", s.spread.as_ref().map(|x| x.span().start)),
        ("lobe_depth", s.lobe_depth.as_ref().map(|x| x.span().start)),
        ("outer_shortening", s.outer_shortening.as_ref().map(|x| x.span().start)),
        ("secondaries", s.secondaries.as_ref().map(|x| x.span().start)),
        ("branch_angle", s.branch_angle.as_ref().map(|x| x.span().start)),
        ("petiole", s.petiole.as_ref().map(|x| x.span().start)),
        ("curvature", s.curvature.as_ref().map(|x| x.span().start)),
        ("curvature_jitter", s.curvature_jitter.as_ref().map(|x| x.span().start)),
        ("jitter", s.jitter.as_ref().map(|x| x.span().start)),
        ("seed", s.seed.as_ref().map(|x| x.span().start)),
        ("vein_radius", s.vein_radius.as_ref().map(|x| x.span().start)),
        ("tip_radius", s.tip_radius.as_ref().map(|x| x.span().start)),
        ("secondary_radius", s.secondary_radius.as_ref().map(|x| x.span().start)),
        ("smooth_margin", s.smooth_margin.as_ref().map(|x| x.span().start)),
    ];
    let mut spans: BTreeMap<&'static str, usize> =
        generated_keys.iter().filter_map(|(k, o)| o.map(|o| (*k, o))).collect();
    for (k, v) in [("max_area", &s.max_area), ("max_ratio", &s.max_ratio)] {
        if let Some(x) = v {
            spans.insert(k, x.span().start);
        }
    }
    let num = |v: &Option<Spanned<f64>>, default: f64| v.as_ref().map_or(default, |x| *x.get_ref());
    let d = LeafParams::default();
    let leaf = if let Some(outline) = &s.outline {
        // Generated-leaf keys make no sense with an outline: say so rather than ignore them.
        if let Some((name, Some(o))) = generated_keys.iter().find(|(_, o)| o.is_some()) {
            return Err(at(
                *o,
                format!(
                    "'{name}' shapes the generated leaf; a leaf with an 'outline' takes its veins from [[leaf.vein]]"
                ),
            ));
        }
        let pts: Vec<glam::DVec2> =
            outline.get_ref().iter().map(|p| glam::DVec2::from_array(*p)).collect();
        if pts.iter().any(|p| !p.is_finite()) {
            return Err(at(outline.span().start, "outline points must be finite numbers".into()));
        }
        let max_area = num(&s.max_area, f64::INFINITY);
        let max_ratio = num(&s.max_ratio, f64::INFINITY);
        for (name, v) in [("max_area", max_area), ("max_ratio", max_ratio)] {
            if v.is_nan() || v <= 0.0 {
                return Err(at(spans[name], format!("{name} must be positive (got {v})")));
            }
        }
        let mut veins = Vec::new();
        for v in s.vein.iter().flatten() {
            let points: Vec<DVec3> =
                v.points.get_ref().iter().map(|p| DVec3::from_array(*p)).collect();
            let radii = match (&v.radius, &v.radii) {
                (Some(_), Some(r)) => {
                    return Err(at(
                        r.span().start,
                        "give either 'radius' or 'radii', not both".into(),
                    ));
                }
                (Some(r), None) => vec![*r.get_ref(); points.len()],
                (None, Some(r)) if r.get_ref().len() != points.len() => {
                    return Err(at(
                        r.span().start,
                        format!(
                            "'radii' has {} numbers for {} points",
                            r.get_ref().len(),
                            points.len()
                        ),
                    ));
                }
                (None, Some(r)) => r.get_ref().clone(),
                (None, None) => {
                    return Err(at(
                        v.points.span().start,
                        "a vein needs a 'radius' (or 'radii')".into(),
                    ));
                }
            };
            if points.iter().any(|p| !p.is_finite()) {
                return Err(at(v.points.span().start, "vein points must be finite numbers".into()));
            }
            veins.push((VeinCurve { points, radii }, v.points.span().start));
        }
        let spans_of: Vec<usize> = veins.iter().map(|v| v.1).collect();
        let curves: Vec<VeinCurve> = veins.into_iter().map(|v| v.0).collect();
        Leaf::from_outline(&pts, curves, max_area, max_ratio).map_err(|e| match e {
            LeafError::BadVein { vein, .. } => at(spans_of[vein], e.to_string()),
            _ => at(outline.span().start, e.to_string()),
        })?
    } else {
        if let Some(v) = s.vein.as_ref().and_then(|v| v.first()) {
            return Err(at(
                v.points.span().start,
                "[[leaf.vein]] needs an 'outline' (the generated leaf grows its own veins)".into(),
            ));
        }
        let whole = |name: &'static str,
                     v: &Option<Spanned<i64>>,
                     default: usize|
         -> Result<usize, SceneError> {
            match v {
                Some(x) => {
                    let n = *x.get_ref();
                    usize::try_from(n).map_err(|_| {
                        at(
                            x.span().start,
                            format!("{name} must be a whole number of at least 0 (got {n})"),
                        )
                    })
                }
                None => Ok(default),
            }
        };
        let lobes = whole("lobes", &s.lobes, d.lobes)?;
        let secondaries = whole("secondaries", &s.secondaries, d.secondaries)?;
        let seed = whole("seed", &s.seed, d.seed as usize)? as u64;
        let p = LeafParams {
            size: num(&s.size, d.size),
            lobes,
            spread: num(&s.spread, d.spread),
            lobe_depth: num(&s.lobe_depth, d.lobe_depth),
            outer_shortening: num(&s.outer_shortening, d.outer_shortening),
            secondaries,
            branch_angle: num(&s.branch_angle, d.branch_angle),
            petiole: num(&s.petiole, d.petiole),
            curvature: num(&s.curvature, d.curvature),
            curvature_jitter: num(&s.curvature_jitter, d.curvature_jitter),
            jitter: num(&s.jitter, d.jitter),
            seed,
            vein_radius: num(&s.vein_radius, d.vein_radius),
            tip_radius: num(&s.tip_radius, d.tip_radius),
            secondary_radius: num(&s.secondary_radius, d.secondary_radius),
            smooth_margin: s.smooth_margin.as_ref().map_or(d.smooth_margin, |b| *b.get_ref()),
            max_area: num(&s.max_area, d.max_area),
            max_ratio: num(&s.max_ratio, d.max_ratio),
        };
        Leaf::maple(&p).map_err(|e| {
            let o = match &e {
                LeafError::BadParameter { name, .. } => {
                    spans.get(name).copied().unwrap_or(section_at)
                }
                _ => section_at,
            };
            at(o, e.to_string())
        })?
    };
    let mut field = leaf.regions(kernel, fillet).map_err(|e| at(section_at, e.to_string()))?;
    field.vein_rule = vein_rule;
    let (lo, hi) = leaf.bounds(kernel);
    if !(domain.contains(lo) && domain.contains(hi)) {
        return Err(at(
            section_at,
            format!(
                "the leaf reaches from {:?} to {:?}, outside the domain: enlarge [domain]",
                lo.to_array().map(|x| (x * 1000.0).round() / 1000.0),
                hi.to_array().map(|x| (x * 1000.0).round() / 1000.0)
            ),
        ));
    }
    let texture = texture_of(s, &leaf, at)?;
    let image = texture.as_ref().map(|t| Arc::new(t.image()));
    let seeds = field.seeds();
    Ok(LeafRegions {
        texture,
        image,
        interest: field.interest(),
        field: Arc::new(field),
        full_grid: s.full_grid.unwrap_or(false),
        stats: leaf.stats.clone(),
        seeds,
        bounds: Aabb::new(lo, hi),
    })
}

/// The `texture` and `tertiary_*` keys: the leaf's tertiary venation texture, if asked for.
fn texture_of(
    s: &LeafSection,
    leaf: &Leaf,
    at: At,
) -> Result<Option<Arc<LeafTexture>>, SceneError> {
    let keys = [
        ("tertiary_levels", s.tertiary_levels.as_ref().map(|x| x.span().start)),
        ("tertiary_roughness", s.tertiary_roughness.as_ref().map(|x| x.span().start)),
        ("tertiary_width", s.tertiary_width.as_ref().map(|x| x.span().start)),
        ("texture_size", s.texture_size.as_ref().map(|x| x.span().start)),
    ];
    let on = s.texture.as_ref().is_some_and(|t| *t.get_ref());
    if !on {
        if let Some((name, Some(o))) = keys.iter().find(|(_, o)| o.is_some()) {
            return Err(at(*o, format!("'{name}' draws the texture; add texture = true")));
        }
        return Ok(None);
    }
    let d = TextureParams::default();
    let levels = match &s.tertiary_levels {
        Some(x) => u32::try_from(*x.get_ref()).map_err(|_| {
            at(
                x.span().start,
                format!("tertiary_levels must be a whole number from 1 to 8 (got {})", x.get_ref()),
            )
        })?,
        None => d.levels,
    };
    let size = match &s.texture_size {
        Some(x) => u32::try_from(*x.get_ref()).map_err(|_| {
            at(
                x.span().start,
                format!(
                    "texture_size must be a whole number of texels from 16 to 8192 (got {})",
                    x.get_ref()
                ),
            )
        })?,
        None => d.size,
    };
    let p = TextureParams {
        levels,
        roughness: s.tertiary_roughness.as_ref().map_or(d.roughness, |x| *x.get_ref()),
        width: s.tertiary_width.as_ref().map_or(d.width, |x| *x.get_ref()),
        size,
        // The leaf's seed (already checked) perturbs its tertiary veins too.
        seed: s.seed.as_ref().and_then(|x| u64::try_from(*x.get_ref()).ok()).unwrap_or(d.seed),
        ..d
    };
    let texture = leaf.texture(&p).map_err(|e| {
        let o = match &e {
            LeafError::BadParameter { name, .. } => {
                keys.iter().find(|(k, _)| k == name).and_then(|(_, o)| *o)
            }
            _ => None,
        };
        at(o.or(s.texture.as_ref().map(|t| t.span().start)).unwrap_or(0), e.to_string())
    })?;
    Ok(Some(Arc::new(texture)))
}
