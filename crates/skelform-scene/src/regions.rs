//! `[regions]`: space divided into numbered regions for the non-manifold polygonizer.
//!
//! ```toml
//! [regions]
//! default = 3                      # a point in no listed region is in this one
//! interest = [[1, 2], [1, 3], [2, 3]]   # the surfaces to make (default: every pair)
//! parameters = { s = 1.0 }         # numbers every region formula may use
//! full_grid = false                # true: visit every cube instead of propagating
//! loops = false                    # true: keep looped crossings (beyond the chapter)
//! [[regions.region]]               # in order: a point is in the first region whose
//! id = 0                           # formula is negative there
//! formula = "s - max(abs(x), abs(y), abs(z))"   # (any formula; negative = inside)
//! [[regions.gradient]]             # optional, per pair: a function whose gradient is
//! pair = [2, 3]                    # normal to that surface, for vertex normals
//! formula = "z"
//! ```
//!
//! In place of `default`, a built-in region function may take the points that no formula
//! claims: `[regions.patch_blend]` (see `crate::patch_blend`).

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::Deserialize;
use skelform_field::region::{OrderedRegions, Otherwise};
use skelform_mesh::{RegionPair, RegionTriple};
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RegionsSection {
    default: Option<Spanned<i64>>,
    interest: Option<Spanned<Vec<[i64; 2]>>>,
    curves: Option<Spanned<Vec<[i64; 3]>>>,
    parameters: Option<Spanned<BTreeMap<String, f64>>>,
    full_grid: Option<bool>,
    loops: Option<bool>,
    #[serde(default)]
    region: Vec<RegionEntry>,
    gradient: Option<Vec<GradientEntry>>,
    /// The chapter's blend to a bicubic patch, for the points no formula claims.
    patch_blend: Option<Spanned<crate::patch_blend::PatchBlendSection>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GradientEntry {
    pair: Spanned<[i64; 2]>,
    formula: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionEntry {
    id: Spanned<i64>,
    formula: Spanned<String>,
}

/// The largest region id a scene may use: labels are written as 32-bit signed integers (PLY
/// `int region_a`), so a larger id would be accepted here and fail only when writing.
pub const MAX_REGION_ID: u32 = i32::MAX as u32;

/// A scene's regions, ready for the non-manifold polygonizer.
#[derive(Clone)]
pub struct Regions {
    /// The region formulas in order, with the default region or the patch blend behind
    /// them and the per-pair gradient formulas.
    pub field: Arc<OrderedRegions>,
    /// The region pairs to polygonize; empty means every pair that occurs.
    pub interest: Vec<RegionPair>,
    /// The intersection curves to output; empty means every one that occurs.
    pub curves: Vec<RegionTriple>,
    /// `[regions] full_grid`: visit every cube instead of propagating from seeds.
    pub full_grid: bool,
    /// Keep looped crossings instead of the chapter's truncation (see
    /// `skelform_polygonize::nonmanifold::Options::loops`).
    pub loops: bool,
}

impl std::fmt::Debug for Regions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Regions")
            .field("regions", &self.field.regions.iter().map(|(id, _)| *id).collect::<Vec<_>>())
            .field("default", &self.field.default)
            .field("interest", &self.interest)
            .finish()
    }
}

/// Compiles one region formula with the shared parameters (and where they are written).
pub(crate) type Compile<'a> = dyn Fn(
        &Spanned<String>,
        &[(String, f64)],
        Option<usize>,
    ) -> Result<skelform_field::formula::Formula, SceneError>
    + 'a;

/// Checks the section and compiles its formulas; `at(offset, message)` makes a positioned
/// error, `compile` compiles one formula with the parameters.
pub(crate) fn build(
    section: &Spanned<RegionsSection>,
    at: At,
    compile: &Compile<'_>,
) -> Result<Regions, SceneError> {
    let sec = section.get_ref();
    let id = |v: &Spanned<i64>, what: &str| -> Result<u32, SceneError> {
        u32::try_from(*v.get_ref()).ok().filter(|&r| r <= MAX_REGION_ID).ok_or_else(|| {
            at(
                v.span().start,
                format!(
                    "{what} must be a whole number from 0 to {MAX_REGION_ID} (got {})",
                    v.get_ref()
                ),
            )
        })
    };
    // Where a point that no formula claims goes: the default region or the built-in.
    let (default, mut ids) = match (&sec.default, &sec.patch_blend) {
        (Some(d), Some(_)) => {
            return Err(at(
                d.span().start,
                "'default' is never used with [regions.patch_blend]: a point that no \
                 [[regions.region]] claims is in the patch blend's region (0 beyond, 1 bump, \
                 2 above, 3 below)"
                    .into(),
            ));
        }
        (None, Some(p)) => (
            Otherwise::Regions(Box::new(crate::patch_blend::build(p.get_ref(), at)?)),
            crate::patch_blend::IDS.to_vec(),
        ),
        (Some(d), None) => {
            let default = id(d, "the default region")?;
            if sec.region.is_empty() {
                return Err(at(
                    d.span().start,
                    "[regions] lists no [[regions.region]]: a scene with one region has no \
                     surface"
                        .into(),
                ));
            }
            (Otherwise::Region(default), vec![default])
        }
        (None, None) => {
            return Err(at(
                section.span().start,
                "[regions] needs a 'default' region (for the points no [[regions.region]] \
                 claims) or a [regions.patch_blend]"
                    .into(),
            ));
        }
    };
    let builtin = sec.patch_blend.is_some();
    let params: Vec<(String, f64)> = match &sec.parameters {
        Some(p) => p.get_ref().iter().map(|(k, v)| (k.clone(), *v)).collect(),
        None => Vec::new(),
    };
    let mut regions = Vec::with_capacity(sec.region.len());
    let mut listed = Vec::new();
    for r in &sec.region {
        let rid = id(&r.id, "a region id")?;
        // A formula may add to a built-in's region (its points are claimed first).
        if listed.contains(&rid) || (!builtin && ids.contains(&rid)) {
            return Err(at(
                r.id.span().start,
                format!("region {rid} is given twice (or is the default region)"),
            ));
        }
        listed.push(rid);
        ids.push(rid);
        let formula =
            compile(&r.formula, &params, sec.parameters.as_ref().map(|p| p.span().start))?;
        regions.push((rid, Box::new(formula) as Box<dyn skelform_field::Field>));
    }
    ids.sort_unstable();
    ids.dedup();
    let pair = |[a, b]: [i64; 2], offset: usize| -> Result<RegionPair, SceneError> {
        let known = |r: i64| u32::try_from(r).ok().filter(|r| ids.contains(r));
        match (known(a), known(b)) {
            (Some(x), Some(y)) if x != y => Ok(RegionPair::new(x, y)),
            (Some(_), Some(_)) => {
                Err(at(offset, format!("the pair [{a}, {b}] names one region twice")))
            }
            _ => {
                let missing = if known(a).is_none() { a } else { b };
                Err(at(
                    offset,
                    format!(
                        "the pair [{a}, {b}] names region {missing}, which is not declared (regions: {ids:?})"
                    ),
                ))
            }
        }
    };
    let mut interest = Vec::new();
    if let Some(list) = &sec.interest {
        for p in list.get_ref() {
            interest.push(pair(*p, list.span().start)?);
        }
    }
    let mut curves = Vec::new();
    if let Some(list) = &sec.curves {
        let offset = list.span().start;
        for &[a, b, c] in list.get_ref() {
            if a == b || b == c || a == c {
                return Err(at(
                    offset,
                    format!("the curve [{a}, {b}, {c}] names one region twice"),
                ));
            }
            // Each region declared (the pairs' checks say which is not).
            pair([a, b], offset)?;
            pair([b, c], offset)?;
            curves.push(RegionTriple::new([a, b, c].map(|r| r as u32)));
        }
    }
    curves.sort_unstable();
    curves.dedup();
    let mut gradients: Vec<((u32, u32), Box<dyn skelform_field::Field>)> = Vec::new();
    for g in sec.gradient.iter().flatten() {
        let p = pair(*g.pair.get_ref(), g.pair.span().start)?;
        if gradients.iter().any(|(q, _)| *q == (p.0, p.1)) {
            return Err(at(
                g.pair.span().start,
                format!("the pair [{}, {}] has a gradient already", p.0, p.1),
            ));
        }
        let formula =
            compile(&g.formula, &params, sec.parameters.as_ref().map(|p| p.span().start))?;
        gradients.push(((p.0, p.1), Box::new(formula)));
    }
    if builtin && sec.interest.is_none() {
        interest = crate::patch_blend::INTEREST.to_vec();
    }
    interest.sort_unstable();
    interest.dedup();
    Ok(Regions {
        field: Arc::new(OrderedRegions { regions, default, gradients }),
        interest,
        curves,
        full_grid: sec.full_grid.unwrap_or(false),
        loops: sec.loops.unwrap_or(false),
    })
}
