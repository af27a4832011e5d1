//! A whole leaf: venation, blade and veins, built either from [`LeafParams`] (the generated
//! maple-like leaf) or from a flat outline and explicit veins (test shapes such as the tee
//! embedded in a square of figs. 7.11 and 7.12).

use glam::{DVec2, DVec3};
use skelform_skeleton::Kernel;

use crate::LeafError;
use crate::blade::Blade;
use crate::regions::{BladeRegions, Fillet, VeinRule};
use crate::texture::{LeafTexture, TertiaryVenation, TextureParams};
use crate::veins::{VeinSegment, Veins};
use crate::venation::{LeafParams, VeinKind, Venation, wrap};
use crate::web::{Web, WebStats};

/// A vein in space: points and the radius at each.
#[derive(Clone, Debug, PartialEq)]
pub struct VeinCurve {
    /// Polyline of the vein's axis in space (scene units), base first; a generated leaf's
    /// veins are wrapped with the blade, so they run along its edges.
    pub points: Vec<DVec3>,
    /// The vein's radius at each point (one per point, positive, in scene units); each segment
    /// takes the mean of its ends', so a tapering vein steps down segment by segment.
    pub radii: Vec<f64>,
}

/// A leaf ready to become regions of space.
#[derive(Clone, Debug)]
pub struct Leaf {
    /// The venation, for generated leaves.
    pub venation: Option<Venation>,
    /// How the web was built and refined, and how many triangles the blade has.
    pub stats: WebStats,
    /// The triangulated, wrapped blade whose signed distance the regions use.
    pub blade: Blade,
    /// Veins to be convolved: for generated leaves, the petiole, the primaries and (with a
    /// positive secondary radius) the secondaries.
    pub veins: Vec<VeinCurve>,
    /// The refined web the blade was triangulated from, with its cuts (the tertiary
    /// venation's lines, [`Leaf::texture`]).
    pub web: Web,
    /// Per blade vertex, its point in the leaf's plane (before wrapping).
    pub plane: Vec<DVec2>,
}

impl Leaf {
    /// The generated maple-like leaf (see [`LeafParams`]).
    pub fn maple(p: &LeafParams) -> Result<Leaf, LeafError> {
        let v = Venation::maple(p)?;
        let mut web = if p.smooth_margin {
            // Splines a side's veins would cross are dropped side by side; if the smoothed
            // margin still fails, the straight one is used.
            Web::from_venation_smoothed(&v, 0.5 * (p.max_area * p.size * p.size).sqrt())
                .or_else(|_| Web::from_venation(&v))?
        } else {
            Web::from_venation(&v)?
        };
        let mut stats = WebStats { web_polygons: web.polygons.len(), ..WebStats::default() };
        stats.unsplit = web.refine(p.max_area * p.size * p.size, p.max_ratio / p.size);
        stats.polygons = web.polygons.len();
        let (blade, plane) = blade_of(&web)?;
        stats.triangles = blade.triangles.len();
        let mut veins = Vec::new();
        for vein in &v.veins {
            let (r0, taper) = match vein.kind {
                VeinKind::Petiole => (p.vein_radius, 1.0),
                VeinKind::Primary => (p.vein_radius, p.tip_radius),
                VeinKind::Secondary if p.secondary_radius > 0.0 => {
                    (p.secondary_radius, p.tip_radius)
                }
                VeinKind::Secondary => continue,
            };
            let chain = web.refined_chain(&vein.points);
            let pts2: Vec<DVec2> = chain.iter().map(|&k| web.points[k]).collect();
            let points: Vec<DVec3> =
                chain.iter().map(|&k| wrap(web.points[k], web.curvature[k])).collect();
            let mut along = vec![0.0];
            for w in pts2.windows(2) {
                along.push(along.last().copied().unwrap_or(0.0) + w[0].distance(w[1]));
            }
            let total = along.last().copied().unwrap_or(1.0).max(1e-300);
            let radii = along.iter().map(|s| r0 * (1.0 - (1.0 - taper) * s / total)).collect();
            veins.push(VeinCurve { points, radii });
        }
        Ok(Leaf { venation: Some(v), stats, blade, veins, web, plane })
    }

    /// A flat blade in the plane z = 0 bounded by `outline` (refined so that polygons have
    /// area below `max_area` and perimeter/area below `max_ratio`), with veins given in space.
    pub fn from_outline(
        outline: &[DVec2],
        veins: Vec<VeinCurve>,
        max_area: f64,
        max_ratio: f64,
    ) -> Result<Leaf, LeafError> {
        let mut web = Web::from_outline(outline)?;
        let mut stats = WebStats { web_polygons: 1, ..WebStats::default() };
        stats.unsplit = web.refine(max_area, max_ratio);
        stats.polygons = web.polygons.len();
        let (blade, plane) = blade_of(&web)?;
        stats.triangles = blade.triangles.len();
        for (i, v) in veins.iter().enumerate() {
            if v.points.len() < 2 || v.points.len() != v.radii.len() {
                return Err(LeafError::BadVein {
                    vein: i,
                    why: "needs at least 2 points, each with a radius".into(),
                });
            }
            if let Some(r) = v.radii.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
                return Err(LeafError::BadVein {
                    vein: i,
                    why: format!("has radius {r}; radii must be positive"),
                });
            }
            if let Some(w) = v.points.windows(2).position(|w| w[0] == w[1]) {
                return Err(LeafError::BadVein {
                    vein: i,
                    why: format!("repeats point {} (zero-length segment)", w + 1),
                });
            }
        }
        Ok(Leaf { venation: None, stats, blade, veins, web, plane })
    }

    /// The region function of blade and veins.
    pub fn regions(&self, kernel: Kernel, fillet: Fillet) -> Result<BladeRegions, LeafError> {
        let segments: Vec<VeinSegment> =
            self.veins.iter().flat_map(|v| Veins::segments_of(&v.points, &v.radii)).collect();
        let veins = if segments.is_empty() { None } else { Some(Veins::new(segments, kernel)?) };
        Ok(BladeRegions {
            blade: self.blade.clone(),
            veins,
            fillet,
            vein_rule: VeinRule::default(),
        })
    }

    /// The tertiary venation texture of §7.4 ([`crate::texture`]): the web's cuts grown into
    /// perturbed lines, drawn with the veins (carried into the plane through the blade).
    pub fn texture(&self, p: &TextureParams) -> Result<LeafTexture, LeafError> {
        let tertiary = TertiaryVenation::new(&self.web, p)?;
        let mut tex = LeafTexture::new(tertiary.clone(), self.plane.clone(), Vec::new(), &[], p)?;
        let veins: Vec<(Vec<DVec2>, Vec<f64>)> = self
            .veins
            .iter()
            .map(|v| {
                let pts = v.points.iter().map(|q| tex.plane_point(&self.blade, *q)).collect();
                (pts, v.radii.clone())
            })
            .collect();
        tex = LeafTexture::new(tertiary, self.plane.clone(), self.web.outline.clone(), &veins, p)?;
        Ok(tex)
    }

    /// Bounding box of blade and veins (with the veins' full reach under `kernel`).
    pub fn bounds(&self, kernel: Kernel) -> (DVec3, DVec3) {
        let (mut lo, mut hi) = self.blade.bounds();
        for v in &self.veins {
            for (p, r) in v.points.iter().zip(&v.radii) {
                lo = lo.min(*p - DVec3::splat(r * kernel.support()));
                hi = hi.max(*p + DVec3::splat(r * kernel.support()));
            }
        }
        (lo, hi)
    }
}

/// Triangulates the web and wraps its points into space; also each blade vertex's point in
/// the plane.
fn blade_of(web: &Web) -> Result<(Blade, Vec<DVec2>), LeafError> {
    let tris = web.triangulate()?;
    let mut index = vec![u32::MAX; web.points.len()];
    let mut vertices = Vec::new();
    let mut plane = Vec::new();
    let mut triangles = Vec::with_capacity(tris.len());
    for t in tris {
        triangles.push(t.map(|k| {
            if index[k] == u32::MAX {
                index[k] = vertices.len() as u32;
                vertices.push(wrap(web.points[k], web.curvature[k]));
                plane.push(web.points[k]);
            }
            index[k]
        }));
    }
    Ok((Blade::new(vertices, triangles), plane))
}
