//! The TOML schema and its translation into a [`Scene`].

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;

use serde::Deserialize;
use skelform_field::combine::Combined;
use skelform_field::formula::Formula;
use skelform_field::{Aabb, DVec3};
use skelform_mesh::io::Format;
use skelform_polygonize::grid::Resolution;
use toml::Spanned;

use crate::diag::Source;
use crate::{Continuation, Healed, Output, Scene, SceneError, iso_field};
use skelform_polygonize::healed::Healing;
use skelform_polygonize::refine::RootMethod;

/// Which polygonizer a scene asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// Sample a lattice, then marching cubes.
    #[default]
    Grid,
    /// Propagate cubes from seeds across the surface (dissertation ch. 3).
    Continuation,
    /// The same, each cube split into six tetrahedra.
    Tetra,
    /// Marching cubes healed along self-intersections (Nguyen 2016): the sheets of a surface
    /// that crosses itself meet along curves instead of being joined wrongly.
    Healed,
    /// Several regions of space at once: labelled surfaces meeting along curves (ch. 4).
    NonManifold,
}

impl Method {
    /// Every method with the name scene files and the command line give it, in the order
    /// messages list them.
    pub const ALL: &'static [(&'static str, Method)] = &[
        ("grid", Method::Grid),
        ("continuation", Method::Continuation),
        ("tetra", Method::Tetra),
        ("healed", Method::Healed),
        ("nonmanifold", Method::NonManifold),
    ];

    /// The method's name in scene files (`"nonmanifold"`, ...), which [`str::parse`] reads
    /// back.
    pub fn name(self) -> &'static str {
        Method::ALL.iter().find(|(_, m)| *m == self).map_or("?", |(n, _)| n)
    }
}

/// A method name that is not one of [`Method::ALL`].
#[derive(Debug, thiserror::Error)]
#[error("unknown method '{0}'; expected one of: {names}", names = method_names())]
pub struct ParseMethodError(pub String);

fn method_names() -> String {
    Method::ALL.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
}

impl FromStr for Method {
    type Err = ParseMethodError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Method::ALL
            .iter()
            .find(|(n, _)| *n == s)
            .map(|(_, m)| *m)
            .ok_or_else(|| ParseMethodError(s.to_string()))
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    scene: Option<SceneInfo>,
    domain: Spanned<Domain>,
    mesh: Option<MeshSection>,
    field: Option<Spanned<FieldSection>>,
    /// Skeletal elements and their blend (see `crate::skeleton`).
    skeleton: Option<Spanned<crate::skeleton::SkeletonSection>>,
    /// Regions of space for the non-manifold polygonizer (see `crate::regions`).
    regions: Option<Spanned<crate::regions::RegionsSection>>,
    /// The leaf of chapter 7 as regions (see `crate::leaf`).
    leaf: Option<Spanned<crate::leaf::LeafSection>>,
    /// A branching skeleton (see `crate::ramiform`).
    ramiform: Option<Spanned<crate::ramiform::RamiformSection>>,
    output: Option<OutputSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneInfo {
    name: Option<String>,
    description: Option<String>,
    /// The figure of the dissertation the scene reproduces, e.g. "3.12" (for the gallery).
    figure: Option<String>,
    /// More pictures of the scene in the gallery, each from its own view (and pose).
    views: Option<Vec<ViewSpec>>,
    /// Frames of a turntable (an animated PNG) in the gallery.
    turntable: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewSpec {
    name: Spanned<String>,
    view: Spanned<[f64; 2]>,
    pose: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Domain {
    min: Spanned<[f64; 3]>,
    max: Spanned<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshSection {
    resolution: Option<Spanned<i64>>,
    cell: Option<Spanned<f64>>,
    method: Option<Spanned<String>>,
    refine: Option<bool>,
    tolerance: Option<Spanned<f64>>,
    /// Continuation: points on or near the surface to start from.
    seeds: Option<Spanned<Vec<[f64; 3]>>>,
    /// Continuation: root finder, "regula-falsi" (default), "bisection" or "hermite".
    root: Option<Spanned<String>>,
    /// Continuation: most cubes to visit.
    max_cells: Option<Spanned<i64>>,
    /// Continuation: most cubes from each starting cube, in every direction.
    limit: Option<Spanned<i64>>,
    /// Continuation without seeds: stride of the domain search, in cells.
    search_stride: Option<Spanned<i64>>,
    /// Healed: the thesis's critical test |fx| + |fy| + |fz| < epsilon (absolute).
    epsilon: Option<Spanned<f64>>,
    /// Healed: the scale-free critical test, |∇f| < critical_cells · cell · |H| (default 2).
    critical_cells: Option<Spanned<f64>>,
    /// Healed: one copy of each self-intersection vertex per sheet, with that sheet's normal.
    split_sheets: Option<bool>,
    /// Healed: "zone" (default) or "thesis" (the thesis's per-cube patterns).
    healing: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FieldSection {
    formula: Spanned<String>,
    iso: Option<Spanned<f64>>,
    parameters: Option<Spanned<BTreeMap<String, f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputSection {
    file: Option<String>,
    format: Option<Spanned<String>>,
    ascii: Option<bool>,
    normals: Option<bool>,
}

/// Default samples along the longest side when a scene states neither resolution nor cell.
pub const DEFAULT_RESOLUTION: usize = 128;

pub(crate) fn build(
    text: &str,
    origin: &str,
    options: &crate::LoadOptions,
) -> Result<Scene, SceneError> {
    let cx = Source { text, origin };
    let file: File = toml::from_str(text).map_err(|e| cx.toml_error(&e))?;

    let d = file.domain.get_ref();
    let (min, max) = (DVec3::from_array(*d.min.get_ref()), DVec3::from_array(*d.max.get_ref()));
    if !(min.is_finite() && max.is_finite()) {
        return Err(cx.at(d.min.span().start, "domain corners must be finite numbers"));
    }
    if !max.cmpgt(min).all() {
        return Err(cx.at(
            d.max.span().start,
            format!(
                "domain max {:?} must exceed min {:?} on every axis",
                max.to_array(),
                min.to_array()
            ),
        ));
    }
    let domain = Aabb::new(min, max);

    let mesh = file.mesh.unwrap_or(MeshSection {
        resolution: None,
        cell: None,
        method: None,
        refine: None,
        tolerance: None,
        seeds: None,
        root: None,
        max_cells: None,
        limit: None,
        search_stride: None,
        epsilon: None,
        critical_cells: None,
        split_sheets: None,
        healing: None,
    });
    let resolution = match (&mesh.resolution, &mesh.cell) {
        (Some(_), Some(c)) => {
            return Err(cx.at(c.span().start, "give either 'resolution' or 'cell', not both"));
        }
        (Some(r), None) => {
            let n = *r.get_ref();
            if !(2..=1 << 15).contains(&n) {
                return Err(cx.at(
                    r.span().start,
                    format!(
                        "resolution must be a whole number of samples from 2 to 32768 (got {n})"
                    ),
                ));
            }
            Resolution::Samples(n as usize)
        }
        (None, Some(c)) => {
            let v = *c.get_ref();
            if !(v.is_finite() && v > 0.0) {
                return Err(
                    cx.at(c.span().start, format!("cell must be a positive length (got {v})"))
                );
            }
            Resolution::Cell(v)
        }
        (None, None) => Resolution::Samples(DEFAULT_RESOLUTION),
    };
    let method = match &mesh.method {
        Some(m) => m
            .get_ref()
            .parse()
            .map_err(|e: ParseMethodError| cx.at(m.span().start, e.to_string()))?,
        None => Method::default(),
    };
    let tolerance = match &mesh.tolerance {
        Some(t) if !(t.get_ref().is_finite() && *t.get_ref() > 0.0 && *t.get_ref() < 1.0) => {
            return Err(
                cx.at(t.span().start, "tolerance is a fraction of the cell, between 0 and 1")
            );
        }
        Some(t) => *t.get_ref(),
        None => 1e-4,
    };

    let mut continuation = continuation_settings(&cx, &mesh, &domain)?;
    let healed = healed_settings(&cx, &mesh)?;

    let skeleton = match &file.skeleton {
        Some(s) => {
            let choice = crate::pose::Choice {
                pose: options.pose.as_deref(),
                toward: options.toward.as_ref(),
                origin,
            };
            Some(crate::skeleton::build(s, &|o, m| cx.at(o, m), choice, options.base.as_deref())?)
        }
        None => {
            if let Some(p) = options.pose.as_ref().or(options.toward.as_ref().map(|b| &b.pose)) {
                return Err(SceneError::Invalid {
                    path: origin.to_string(),
                    message: format!("cannot take pose '{p}': the scene has no [skeleton] joints"),
                });
            }
            None
        }
    };
    let regions = match &file.regions {
        Some(r) => {
            Some(crate::regions::build(r, &|o, m| cx.at(o, m), &|src, params, params_at| {
                compile_formula(&cx, src, params, params_at)
            })?)
        }
        None => None,
    };
    let leaf = match &file.leaf {
        Some(l) if regions.is_some() => {
            return Err(cx.at(l.span().start, "give either [regions] or [leaf], not both"));
        }
        Some(l) => Some(crate::leaf::build(l, &domain, &|o, m| cx.at(o, m))?),
        None => None,
    };
    // A ramiform is a scene's whole field: it neither blends nor combines with the rest.
    let ramiform = match &file.ramiform {
        Some(r) => {
            let others = [
                ("[field]", file.field.as_ref().map(|f| f.span().start)),
                ("[skeleton]", file.skeleton.as_ref().map(|f| f.span().start)),
                ("[regions]", file.regions.as_ref().map(|f| f.span().start)),
                ("[leaf]", file.leaf.as_ref().map(|f| f.span().start)),
            ];
            if let Some((name, Some(offset))) = others.into_iter().find(|(_, o)| o.is_some()) {
                return Err(cx.at(
                    offset,
                    format!(
                        "a scene with [ramiform] cannot also have {name}: the ramiform is its field"
                    ),
                ));
            }
            Some(crate::ramiform::build(r, &|o, m| cx.at(o, m))?)
        }
        None => None,
    };
    let (formula, iso, formula_field) = match &file.field {
        Some(field) => {
            let f = field.get_ref();
            let iso = f.iso.as_ref().map_or(0.0, |s| *s.get_ref());
            if !iso.is_finite() {
                return Err(cx.at(
                    f.iso.as_ref().map_or(0, |s| s.span().start),
                    "iso must be a finite number",
                ));
            }
            let params: Vec<(String, f64)> = match &f.parameters {
                Some(p) => p.get_ref().iter().map(|(k, v)| (k.clone(), *v)).collect(),
                None => Vec::new(),
            };
            let formula = compile_formula(
                &cx,
                &f.formula,
                &params,
                f.parameters.as_ref().map(|p| p.span().start),
            )?;
            let formula = Arc::new(formula);
            let field = iso_field(formula.clone(), iso);
            (formula, iso, Some(field))
        }
        None => {
            let placeholder = Arc::new(Formula::parse("1").map_err(|e| cx.at(0, e.message()))?);
            match (&skeleton, regions.is_some() || leaf.is_some()) {
                // No formula: a constant stands in for `skelform info`.
                (Some(sk), _) => (placeholder, sk.field.iso().unwrap_or(0.0), None),
                (None, false) if ramiform.is_some() => (
                    placeholder,
                    0.0,
                    ramiform.as_ref().map(|(f, _)| f.clone() as Arc<dyn skelform_field::Field>),
                ),
                // Regions alone: the constant is the (unused) field.
                (None, true) => {
                    (placeholder.clone(), 0.0, Some(placeholder as Arc<dyn skelform_field::Field>))
                }
                (None, false) => {
                    return Err(
                        cx.at(0, "a scene needs a [field] formula, a [skeleton] or [regions]")
                    );
                }
            }
        }
    };
    let field: Arc<dyn skelform_field::Field> = match (&skeleton, formula_field) {
        (None, Some(f)) => f,
        (Some(sk), None) => {
            if let Some((_, at)) = sk.combine {
                return Err(
                    cx.at(at, "'combine' needs a [field] formula to combine the skeleton with")
                );
            }
            sk.surface()
        }
        (Some(sk), Some(f)) => match sk.combine {
            Some((op, _)) => Arc::new(Combined::new(sk.surface(), f, op)),
            None => {
                return Err(cx.at(
                    sk.section_at,
                    "the scene has both a [skeleton] and a [field] formula: say how they combine \
                     with combine = \"union\", \"intersection\" or \"difference\" in [skeleton]",
                ));
            }
        },
        (None, None) => {
            return Err(cx.at(0, "a scene needs a [field] formula, a [skeleton] or [regions]"));
        }
    };
    if let Some(l) = &leaf
        && continuation.seeds.is_empty()
    {
        // Seeding from the blade and the veins.
        continuation.seeds = l.seeds.iter().copied().filter(|p| domain.contains(*p)).collect();
    }
    if let Some((_, seeds)) = &ramiform
        && continuation.seeds.is_empty()
    {
        // Seeding from the limbs: their middles are inside.
        continuation.seeds = seeds.iter().copied().filter(|p| domain.contains(*p)).collect();
    }
    if let Some(sk) = &skeleton
        && continuation.seeds.is_empty()
    {
        // Seeding from the skeleton: one point on each element, where the surface is near.
        continuation.seeds =
            sk.field.seed_points().into_iter().filter(|p| domain.contains(*p)).collect();
    }

    let out = file.output.unwrap_or(OutputSection {
        file: None,
        format: None,
        ascii: None,
        normals: None,
    });
    let format = match &out.format {
        Some(s) => Some(parse_format(s.get_ref()).ok_or_else(|| {
            cx.at(
                s.span().start,
                format!("unknown output format '{}'; expected ply, obj or stl", s.get_ref()),
            )
        })?),
        None => None,
    };

    let mut views = Vec::new();
    for v in file.scene.iter().flat_map(|s| s.views.iter().flatten()) {
        let name = v.name.get_ref();
        let plain = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-';
        if name.is_empty()
            || !name.chars().all(plain)
            || views.iter().any(|w: &crate::GalleryView| w.name == *name)
        {
            return Err(cx.at(
                v.name.span().start,
                format!("view name '{name}' must be unique and made of a-z, 0-9 and '-' (it names a picture)"),
            ));
        }
        let [azimuth, elevation] = *v.view.get_ref();
        if !azimuth.is_finite() || !(-90.0..=90.0).contains(&elevation) {
            return Err(cx.at(
                v.view.span().start,
                format!("a view is [azimuth, elevation] in degrees, the elevation from -90 to 90 (got [{azimuth}, {elevation}])"),
            ));
        }
        views.push(crate::GalleryView {
            name: name.clone(),
            azimuth,
            elevation,
            pose: v.pose.clone(),
        });
    }
    let turntable = match file.scene.as_ref().and_then(|s| s.turntable.as_ref()) {
        Some(t) if !(2..=120).contains(t.get_ref()) => {
            return Err(cx.at(
                t.span().start,
                format!("turntable takes 2 to 120 frames (got {})", t.get_ref()),
            ));
        }
        t => t.map(|t| *t.get_ref()),
    };

    Ok(Scene {
        origin: origin.to_string(),
        views,
        turntable,
        name: file.scene.as_ref().and_then(|s| s.name.clone()),
        description: file.scene.as_ref().and_then(|s| s.description.clone()),
        figure: file.scene.as_ref().and_then(|s| s.figure.clone()),
        domain,
        resolution,
        method,
        refine: mesh.refine.unwrap_or(true),
        tolerance,
        continuation,
        healed,
        regions_only: (regions.is_some() || leaf.is_some())
            && file.field.is_none()
            && skeleton.is_none(),
        regions,
        leaf,
        field,
        articulation: skeleton.as_ref().and_then(|s| s.articulation.clone()),
        sweeps: skeleton.as_ref().filter(|s| !s.field.sweeps().is_empty()).map(|s| s.field.clone()),
        skeleton: skeleton.and_then(|s| s.skeleton),
        formula,
        iso,
        output: Output {
            file: out.file.map(PathBuf::from),
            format,
            ascii: out.ascii.unwrap_or(false),
            normals: out.normals.unwrap_or(true),
        },
    })
}

/// The continuation polygonizer's settings, checked.
fn continuation_settings(
    cx: &Source,
    mesh: &MeshSection,
    domain: &Aabb,
) -> Result<Continuation, SceneError> {
    let mut c = Continuation::default();
    if let Some(seeds) = &mesh.seeds {
        for s in seeds.get_ref() {
            let p = DVec3::from_array(*s);
            if !domain.contains(p) {
                return Err(cx.at(seeds.span().start, format!("seed {s:?} is outside the domain")));
            }
            c.seeds.push(p);
        }
    }
    if let Some(r) = &mesh.root {
        c.root = match r.get_ref().as_str() {
            "regula-falsi" => RootMethod::RegulaFalsi,
            "bisection" => RootMethod::Bisection,
            "hermite" => RootMethod::Hermite,
            other => {
                return Err(cx.at(
                    r.span().start,
                    format!(
                        "unknown root finder '{other}'; expected regula-falsi, bisection or hermite"
                    ),
                ));
            }
        };
    }
    let positive = |v: &Option<Spanned<i64>>, what: &str| -> Result<Option<u64>, SceneError> {
        match v {
            Some(n) if *n.get_ref() < 1 => {
                Err(cx.at(n.span().start, format!("{what} must be a whole number of at least 1")))
            }
            Some(n) => Ok(Some(*n.get_ref() as u64)),
            None => Ok(None),
        }
    };
    c.max_cells = positive(&mesh.max_cells, "max_cells")?;
    c.limit = positive(&mesh.limit, "limit")?.map(|l| l.min(u32::MAX as u64) as u32);
    c.search_stride = positive(&mesh.search_stride, "search_stride")?.map(|s| s as usize);
    Ok(c)
}

/// The healed polygonizer's settings, checked.
fn healed_settings(cx: &Source, mesh: &MeshSection) -> Result<Healed, SceneError> {
    let positive = |v: &Option<Spanned<f64>>, what: &str| -> Result<Option<f64>, SceneError> {
        match v {
            Some(x) if !(x.get_ref().is_finite() && *x.get_ref() > 0.0) => Err(cx.at(
                x.span().start,
                format!("{what} must be a positive number (got {})", x.get_ref()),
            )),
            Some(x) => Ok(Some(*x.get_ref())),
            None => Ok(None),
        }
    };
    let epsilon = positive(&mesh.epsilon, "epsilon")?;
    let critical_cells = positive(&mesh.critical_cells, "critical_cells")?;
    if let (Some(_), Some(c)) = (&mesh.epsilon, &mesh.critical_cells) {
        return Err(cx.at(c.span().start, "give either 'epsilon' or 'critical_cells', not both"));
    }
    let healing = match &mesh.healing {
        None => Healing::Zone,
        Some(h) => match h.get_ref().as_str() {
            "zone" => Healing::Zone,
            "thesis" => Healing::Thesis,
            other => {
                return Err(cx.at(
                    h.span().start,
                    format!("unknown healing '{other}'; expected zone or thesis"),
                ));
            }
        },
    };
    Ok(Healed { epsilon, critical_cells, split_sheets: mesh.split_sheets.unwrap_or(true), healing })
}

fn parse_format(s: &str) -> Option<Format> {
    Format::from_path(std::path::Path::new(&format!("x.{s}")))
}

/// Compiles the formula and maps its error position into the scene file.
fn compile_formula(
    cx: &Source,
    src: &Spanned<String>,
    params: &[(String, f64)],
    params_at: Option<usize>,
) -> Result<Formula, SceneError> {
    let constants: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    // Parameters alone first, so that a bad parameter is reported at the parameters table.
    if let Err(e) = Formula::parse_with_constants("0", &constants) {
        return Err(
            cx.at(params_at.unwrap_or(src.span().start), format!("parameters: {}", e.message()))
        );
    }
    Formula::parse_with_constants(src.get_ref(), &constants)
        .map_err(|e| cx.formula_error(src.span().start, &e))
}
