//! Tertiary venation as a surface texture (dissertation §7.4).
//!
//! The dissertation's leaf was rendered without texture, and §7.4 proposes one: "if, when
//! converting the polygonal web to the polygonal mesh, the subdividing lines are themselves
//! recursively subdivided with slight perturbations applied to their midpoints", a pattern of
//! fine veins emerges (fig. 7.14). That is what [`TertiaryVenation`] does: every cut the
//! web's refinement made ([`Web::cuts`]) becomes a polyline whose pieces (between the points
//! where later cuts end on it, which stay put so that the lines still meet) are split at
//! their midpoints `levels` times, each midpoint moved across its piece by up to
//! `roughness` × the piece's length. The regions the lines enclose together with the veins
//! and the margin are the refined web's polygons: the *areoles* of the texture.
//!
//! [`LeafTexture`] turns the lines into colour: a point of the blade, found in the leaf's
//! plane through its nearest blade triangle (the same barycentric coordinates in the flat
//! web), is blade green, lighter near a tertiary line (within `width`) and palest on a
//! primary or secondary vein (within its radius). The colours go to the mesh's vertices
//! (`Mesh::colors`), so `skelform render` draws them and glTF carries them as `COLOR_0`; a
//! line is as sharp as the mesh's vertex spacing allows, which is why `width` defaults to
//! about half a cell of the example scenes.
//!
//! Deterministic: the perturbations come from [`TextureParams::seed`] alone, in the order
//! the cuts were made, and colouring a point reads only the finished lines.

use glam::{DVec2, DVec3};

use crate::LeafError;
use crate::blade::{Blade, Side};
use crate::rng::Rng;
use crate::web::{Web, contains};

/// How the tertiary venation is grown and drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureParams {
    /// Midpoint subdivisions of each piece of a cut (1 to 8): a piece becomes `2^levels`
    /// segments.
    pub levels: u32,
    /// Largest midpoint perturbation, as a fraction of the piece's length (0 to 0.5): 0
    /// keeps the straight cuts.
    pub roughness: f64,
    /// Seed of the perturbations.
    pub seed: u64,
    /// Half-width of a drawn tertiary vein, in scene units (more than 0).
    pub width: f64,
    /// Colour of the blade between the veins (sRGB, 0 to 1).
    pub blade: [f32; 3],
    /// Colour on a tertiary vein.
    pub tertiary: [f32; 3],
    /// Colour on a primary or secondary vein.
    pub vein: [f32; 3],
}

impl Default for TextureParams {
    fn default() -> Self {
        TextureParams {
            levels: 4,
            roughness: 0.2,
            seed: 1,
            width: 0.008,
            blade: [0.20, 0.42, 0.12],
            tertiary: [0.52, 0.68, 0.26],
            vein: [0.78, 0.84, 0.50],
        }
    }
}

impl TextureParams {
    /// Checks every parameter; the error names the first bad one (by its scene key).
    pub fn check(&self) -> Result<(), LeafError> {
        if !(1..=8).contains(&self.levels) {
            return Err(LeafError::BadParameter {
                name: "tertiary_levels",
                value: f64::from(self.levels),
                expected: "a whole number from 1 to 8",
            });
        }
        if !(0.0..=0.5).contains(&self.roughness) {
            return Err(LeafError::BadParameter {
                name: "tertiary_roughness",
                value: self.roughness,
                expected: "from 0 to 0.5",
            });
        }
        if !(self.width.is_finite() && self.width > 0.0) {
            return Err(LeafError::BadParameter {
                name: "tertiary_width",
                value: self.width,
                expected: "a length of more than 0",
            });
        }
        Ok(())
    }
}

/// The tertiary veins: the web's cuts, recursively subdivided with perturbed midpoints.
#[derive(Clone, Debug, PartialEq)]
pub struct TertiaryVenation {
    /// One polyline per cut, in the leaf's plane, from one end of the cut to the other.
    pub lines: Vec<Vec<DVec2>>,
    /// The regions the tertiary lines, the veins and the margin enclose: the refined web's
    /// polygons.
    pub areoles: usize,
}

impl TertiaryVenation {
    /// The tertiary venation of a refined web.
    pub fn new(web: &Web, p: &TextureParams) -> Result<TertiaryVenation, LeafError> {
        p.check()?;
        let mut rng = Rng::new(p.seed);
        let mut lines = Vec::with_capacity(web.cuts.len());
        for &(a, b) in &web.cuts {
            let chain = web.refined_chain(&[a, b]);
            let mut line = vec![web.points[chain[0]]];
            for w in chain.windows(2) {
                let (pa, pb) = (web.points[w[0]], web.points[w[1]]);
                subdivide(pa, pb, p.levels, p.roughness, &web.outline, &mut rng, &mut line);
            }
            lines.push(line);
        }
        Ok(TertiaryVenation { lines, areoles: web.polygons.len() })
    }
}

/// Appends the points after `a` up to `b` of the piece `a`–`b` subdivided `level` times. A
/// midpoint the perturbation would move out of the blade stays on the piece (the cut itself
/// lies inside).
fn subdivide(
    a: DVec2,
    b: DVec2,
    level: u32,
    roughness: f64,
    outline: &[DVec2],
    rng: &mut Rng,
    out: &mut Vec<DVec2>,
) {
    if level == 0 {
        out.push(b);
        return;
    }
    let mid = (a + b) * 0.5;
    let moved = mid + (b - a).perp() * (roughness * rng.symmetric());
    let m = if outline.len() < 3 || contains(outline, moved) { moved } else { mid };
    subdivide(a, m, level - 1, roughness, outline, rng, out);
    subdivide(m, b, level - 1, roughness, outline, rng, out);
}

/// A segment to draw: ends in the plane, half-width, and whether it is a major vein.
#[derive(Clone, Copy, Debug)]
struct Stroke {
    a: DVec2,
    b: DVec2,
    width: f64,
    vein: bool,
}

/// The blade's colours from its tertiary venation and veins (see the module documentation).
#[derive(Clone, Debug)]
pub struct LeafTexture {
    /// The tertiary veins drawn.
    pub tertiary: TertiaryVenation,
    params: TextureParams,
    /// Per blade vertex, its point in the leaf's plane.
    plane: Vec<DVec2>,
    strokes: Vec<Stroke>,
    /// Uniform bins over the strokes' reach: each lists the strokes that can colour a point
    /// in it.
    lo: DVec2,
    cell: f64,
    dims: (usize, usize),
    bins: Vec<Vec<u32>>,
}

/// Most bins along a side of the stroke grid.
const MAX_BINS: usize = 512;

impl LeafTexture {
    /// The texture of a blade whose vertices lie at `plane` in the leaf's plane, with its
    /// tertiary venation and its major veins (polylines in the plane, a radius per point).
    pub fn new(
        tertiary: TertiaryVenation,
        plane: Vec<DVec2>,
        veins: &[(Vec<DVec2>, Vec<f64>)],
        params: &TextureParams,
    ) -> Result<LeafTexture, LeafError> {
        params.check()?;
        let mut strokes = Vec::new();
        for line in &tertiary.lines {
            for w in line.windows(2) {
                strokes.push(Stroke { a: w[0], b: w[1], width: params.width, vein: false });
            }
        }
        for (pts, radii) in veins {
            for (w, r) in pts.windows(2).zip(radii.windows(2)) {
                let width = 0.5 * (r[0] + r[1]);
                if width > 0.0 && width.is_finite() {
                    strokes.push(Stroke { a: w[0], b: w[1], width, vein: true });
                }
            }
        }
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for s in &strokes {
            lo = lo.min(s.a.min(s.b) - DVec2::splat(s.width));
            hi = hi.max(s.a.max(s.b) + DVec2::splat(s.width));
        }
        let mut tex = LeafTexture {
            tertiary,
            params: params.clone(),
            plane,
            strokes,
            lo: DVec2::ZERO,
            cell: 1.0,
            dims: (0, 0),
            bins: Vec::new(),
        };
        if tex.strokes.is_empty() {
            return Ok(tex);
        }
        let extent = (hi - lo).max_element().max(1e-12);
        let cell = (4.0 * params.width).max(extent / MAX_BINS as f64);
        let dims = (
            (((hi.x - lo.x) / cell).ceil() as usize).clamp(1, MAX_BINS),
            (((hi.y - lo.y) / cell).ceil() as usize).clamp(1, MAX_BINS),
        );
        let mut bins = vec![Vec::new(); dims.0 * dims.1];
        let bin = |v: f64, n: usize| ((v / cell).floor().max(0.0) as usize).min(n - 1);
        for (i, s) in tex.strokes.iter().enumerate() {
            let (a, b) = (s.a.min(s.b) - lo - s.width, s.a.max(s.b) - lo + s.width);
            for y in bin(a.y, dims.1)..=bin(b.y, dims.1) {
                for x in bin(a.x, dims.0)..=bin(b.x, dims.0) {
                    bins[y * dims.0 + x].push(i as u32);
                }
            }
        }
        (tex.lo, tex.cell, tex.dims, tex.bins) = (lo, cell, dims, bins);
        Ok(tex)
    }

    /// The colour (sRGB, 0 to 1) at a point of the leaf's plane.
    pub fn colour(&self, q: DVec2) -> [f32; 3] {
        let (mut tertiary, mut vein) = (0.0f64, 0.0f64);
        let r = q - self.lo;
        if self.dims.0 > 0 && r.x >= 0.0 && r.y >= 0.0 {
            let (x, y) = ((r.x / self.cell) as usize, (r.y / self.cell) as usize);
            if x < self.dims.0 && y < self.dims.1 {
                for &i in &self.bins[y * self.dims.0 + x] {
                    let s = self.strokes[i as usize];
                    let d = segment_distance(q, s.a, s.b);
                    if s.vein {
                        // Solid across the vein, fading over its last third.
                        vein = vein.max(1.0 - smoothstep((d / s.width - 0.67) / 0.33));
                    } else {
                        tertiary = tertiary.max(1.0 - smoothstep(d / s.width));
                    }
                }
            }
        }
        let p = &self.params;
        std::array::from_fn(|k| {
            let c = f64::from(p.blade[k]) * (1.0 - tertiary) + f64::from(p.tertiary[k]) * tertiary;
            (c * (1.0 - vein) + f64::from(p.vein[k]) * vein) as f32
        })
    }

    /// The point of the leaf's plane under `p`: `p`'s nearest point on its nearest blade
    /// triangle, carried into the flat web by barycentric coordinates. `blade` must be the
    /// blade this texture was made for.
    pub fn plane_point(&self, blade: &Blade, p: DVec3) -> DVec2 {
        self.plane_point_of(blade, p, blade.distance(p).triangle)
    }

    /// [`LeafTexture::plane_point`] through blade triangle `t`.
    fn plane_point_of(&self, blade: &Blade, p: DVec3, t: usize) -> DVec2 {
        let Some(tri) = blade.triangles.get(t) else { return DVec2::ZERO };
        let [a, b, c] = tri.map(|i| blade.vertices[i as usize]);
        let [pa, pb, pc] = tri.map(|i| self.plane.get(i as usize).copied().unwrap_or_default());
        let (v0, v1, v2) = (b - a, c - a, p - a);
        let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
        let (d20, d21) = (v2.dot(v0), v2.dot(v1));
        let den = d00 * d11 - d01 * d01;
        if den.abs() < 1e-300 {
            return pa;
        }
        let v = (d11 * d20 - d01 * d21) / den;
        let w = (d00 * d21 - d01 * d20) / den;
        let bary = [1.0 - v - w, v, w].map(|x: f64| x.max(0.0));
        let sum: f64 = bary.iter().sum();
        (pa * bary[0] + pb * bary[1] + pc * bary[2]) / sum.max(1e-300)
    }

    /// The colour of a point in space: the colour at its [`LeafTexture::plane_point`]; a
    /// point beyond the margin by more than `width` (on a vein past the blade: the petiole,
    /// a vein's rounded tip) has the vein colour.
    pub fn colour_at(&self, blade: &Blade, p: DVec3) -> [f32; 3] {
        let d = blade.distance(p);
        if d.side == Side::Beyond && d.distance > self.params.width {
            return self.params.vein;
        }
        self.colour(self.plane_point_of(blade, p, d.triangle))
    }
}

/// 0 below 0, 1 above 1, smooth between.
fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn segment_distance(q: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 { ((q - a).dot(ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
    q.distance(a + ab * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_cut_into_areoles_has_perturbed_lines_that_meet_the_cuts_ends() {
        let sq = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ];
        let mut w = Web::from_outline(&sq).unwrap();
        w.refine(0.05, 40.0);
        let p = TextureParams::default();
        let t = TertiaryVenation::new(&w, &p).unwrap();
        assert_eq!(t.areoles, w.polygons.len());
        // Cutting n − 1 times makes n pieces.
        assert_eq!(t.lines.len(), w.polygons.len() - 1);
        for (line, &(a, b)) in t.lines.iter().zip(&w.cuts) {
            assert_eq!(line[0], w.points[a]);
            assert_eq!(*line.last().unwrap(), w.points[b]);
            assert!(line.len() > 1 << p.levels);
            assert!(line.iter().all(|q| (0.0..=1.0).contains(&q.x) && (0.0..=1.0).contains(&q.y)));
        }
        // Perturbed: most interior points are off their cut's straight line.
        let off = t
            .lines
            .iter()
            .flat_map(|l| {
                let (a, b) = (l[0], *l.last().unwrap());
                l.iter().map(move |q| (*q - a).perp_dot((b - a).normalize()).abs())
            })
            .filter(|d| *d > 1e-6)
            .count();
        assert!(off > t.lines.len() * 8, "{off}");
        let flat = TertiaryVenation::new(&w, &TextureParams { roughness: 0.0, ..p.clone() });
        assert!(flat.unwrap().lines.iter().all(|l| {
            let (a, b) = (l[0], *l.last().unwrap());
            l.iter().all(|q| (*q - a).perp_dot(b - a).abs() < 1e-12)
        }));
        assert!(TertiaryVenation::new(&w, &TextureParams { levels: 0, ..p }).is_err());
    }
}
