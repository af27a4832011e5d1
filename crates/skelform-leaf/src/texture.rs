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
//! primary or secondary vein (within its radius), and the vein colour beyond the margin.
//! It gives them two ways: [`LeafTexture::image`], an RGBA image of the flat leaf
//! ([`skelform_mesh::Texture`]) with [`LeafTexture::uv`] placing any point of the bent leaf
//! in it, sharp at any mesh resolution (what glb and `skelform render` use); and
//! [`LeafTexture::colour_at`], the colour under a point, for per-vertex colours
//! (`Mesh::colors`, what PLY keeps), as sharp only as the vertex spacing.
//!
//! Deterministic: the perturbations come from [`TextureParams::seed`] alone, in the order
//! the cuts were made, and colouring a point reads only the finished lines.

use glam::{DVec2, DVec3};
use skelform_mesh::Texture;

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
    /// Texels along the longer side of the texture image ([`LeafTexture::image`]), 16 to
    /// [`Texture::MAX_SIDE`]; the shorter side keeps the flat leaf's proportions.
    pub size: u32,
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
            size: 1024,
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
        if !(16..=Texture::MAX_SIDE).contains(&self.size) {
            return Err(LeafError::BadParameter {
                name: "texture_size",
                value: f64::from(self.size),
                expected: "a whole number of texels from 16 to 8192",
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

/// What a stroke is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Tertiary,
    Vein,
    /// A side of the margin: colours nothing, but tells the image which texels outside the
    /// blade are still within `width` of it.
    Margin,
}

/// A segment to draw: ends in the plane, half-width, and what it is.
#[derive(Clone, Copy, Debug)]
struct Stroke {
    a: DVec2,
    b: DVec2,
    width: f64,
    kind: Kind,
}

/// The blade's colours from its tertiary venation and veins (see the module documentation).
#[derive(Clone, Debug)]
pub struct LeafTexture {
    /// The tertiary veins drawn.
    pub tertiary: TertiaryVenation,
    params: TextureParams,
    /// Per blade vertex, its point in the leaf's plane.
    plane: Vec<DVec2>,
    /// The flat blade's margin.
    outline: Vec<DVec2>,
    /// The box of the plane that texture coordinates span: the flat blade's bounding box,
    /// padded (see [`LeafTexture::uv`]).
    box_lo: DVec2,
    box_hi: DVec2,
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
    /// The texture of a blade whose vertices lie at `plane` in the leaf's plane, inside the
    /// margin `outline`, with its tertiary venation and its major veins (polylines in the
    /// plane, a radius per point).
    pub fn new(
        tertiary: TertiaryVenation,
        plane: Vec<DVec2>,
        outline: Vec<DVec2>,
        veins: &[(Vec<DVec2>, Vec<f64>)],
        params: &TextureParams,
    ) -> Result<LeafTexture, LeafError> {
        params.check()?;
        let mut strokes = Vec::new();
        for line in &tertiary.lines {
            for w in line.windows(2) {
                strokes.push(Stroke {
                    a: w[0],
                    b: w[1],
                    width: params.width,
                    kind: Kind::Tertiary,
                });
            }
        }
        for (pts, radii) in veins {
            for (w, r) in pts.windows(2).zip(radii.windows(2)) {
                let width = 0.5 * (r[0] + r[1]);
                if width > 0.0 && width.is_finite() {
                    strokes.push(Stroke { a: w[0], b: w[1], width, kind: Kind::Vein });
                }
            }
        }
        for (k, &a) in outline.iter().enumerate() {
            let b = outline[(k + 1) % outline.len()];
            strokes.push(Stroke { a, b, width: params.width, kind: Kind::Margin });
        }
        // The texture's box: the flat blade's, padded by 2% of its larger side (at least
        // four line widths), so that its border lies outside the margin by more than a
        // line's width and clamped texture coordinates find the vein colour there.
        let (mut box_lo, mut box_hi) =
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for q in plane.iter().chain(&outline) {
            box_lo = box_lo.min(*q);
            box_hi = box_hi.max(*q);
        }
        if !(box_lo.is_finite() && box_hi.is_finite()) {
            (box_lo, box_hi) = (DVec2::ZERO, DVec2::ONE);
        }
        let pad = (0.02 * (box_hi - box_lo).max_element()).max(4.0 * params.width);
        (box_lo, box_hi) = (box_lo - DVec2::splat(pad), box_hi + DVec2::splat(pad));
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for s in &strokes {
            lo = lo.min(s.a.min(s.b) - DVec2::splat(s.width));
            hi = hi.max(s.a.max(s.b) + DVec2::splat(s.width));
        }
        let mut tex = LeafTexture {
            tertiary,
            params: params.clone(),
            plane,
            outline,
            box_lo,
            box_hi,
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
        self.colour_and_margin(q).0
    }

    /// The colour at `q` and whether `q` is within `width` of the margin.
    fn colour_and_margin(&self, q: DVec2) -> ([f32; 3], bool) {
        let (mut tertiary, mut vein, mut margin) = (0.0f64, 0.0f64, false);
        let r = q - self.lo;
        if self.dims.0 > 0 && r.x >= 0.0 && r.y >= 0.0 {
            let (x, y) = ((r.x / self.cell) as usize, (r.y / self.cell) as usize);
            if x < self.dims.0 && y < self.dims.1 {
                for &i in &self.bins[y * self.dims.0 + x] {
                    let s = self.strokes[i as usize];
                    let d = segment_distance(q, s.a, s.b);
                    match s.kind {
                        // Solid across the vein, fading over its last third.
                        Kind::Vein => {
                            vein = vein.max(1.0 - smoothstep((d / s.width - 0.67) / 0.33));
                        }
                        Kind::Tertiary => tertiary = tertiary.max(1.0 - smoothstep(d / s.width)),
                        Kind::Margin => margin |= d <= s.width,
                    }
                }
            }
        }
        let p = &self.params;
        let c = std::array::from_fn(|k| {
            let c = f64::from(p.blade[k]) * (1.0 - tertiary) + f64::from(p.tertiary[k]) * tertiary;
            (c * (1.0 - vein) + f64::from(p.vein[k]) * vein) as f32
        });
        (c, margin)
    }

    /// The texture coordinates `[u, v]` of a point in space, for [`LeafTexture::image`]:
    /// its point in the flat leaf, found through its nearest blade triangle as in
    /// [`LeafTexture::plane_point`] but with the triangle's barycentric coordinates *not*
    /// clamped, so that a point beyond the margin (a vein's rounded tip, the petiole) lands
    /// beyond it in the plane too, where the image has the vein colour; then normalised to
    /// the padded flat bounding box, `u` along the leaf's x, `v` down its y (glTF's image
    /// rows from the top, so the image shows the leaf from above, tip up), and clamped to
    /// `[0, 1]` (the petiole reaches past the box: it takes the border's vein colour). On
    /// the blade the coordinates are those of its flat point, so a picture of the texture
    /// maps onto the bent leaf without seams.
    pub fn uv(&self, blade: &Blade, p: DVec3) -> [f32; 2] {
        let t = blade.distance(p).triangle;
        let q = self.plane_point_unclamped(blade, p, t);
        let e = (self.box_hi - self.box_lo).max(DVec2::splat(1e-300));
        let u = (q.x - self.box_lo.x) / e.x;
        let v = (self.box_hi.y - q.y) / e.y;
        [u, v].map(|c| if c.is_finite() { c.clamp(0.0, 1.0) as f32 } else { 0.0 })
    }

    /// The image's size: [`TextureParams::size`] along the box's longer side, the other in
    /// proportion (at least one texel), so texels are square.
    pub fn image_size(&self) -> (u32, u32) {
        let e = self.box_hi - self.box_lo;
        let n = self.params.size;
        let short = |a: f64, b: f64| ((f64::from(n) * a / b).round() as u32).clamp(1, n);
        if e.x >= e.y { (n, short(e.y, e.x)) } else { (short(e.x, e.y), n) }
    }

    /// The venation as an RGBA image over the padded flat box (opaque, sRGB; see
    /// [`LeafTexture::uv`] for its orientation): each texel the colour at its centre, the
    /// blade's colours inside the margin and within `width` of it, the vein colour beyond
    /// (where only veins and the petiole reach). A pure function of the texture: the same
    /// bytes on every run.
    pub fn image(&self) -> Texture {
        let (w, h) = self.image_size();
        let e = self.box_hi - self.box_lo;
        let vein = self.params.vein.map(to_byte);
        let mut rgba = Vec::with_capacity(w as usize * h as usize * 4);
        let mut crossings = Vec::new();
        for y in 0..h {
            let qy = self.box_hi.y - (f64::from(y) + 0.5) / f64::from(h) * e.y;
            // The margin's crossings of this row, sorted: inside between odd and even ones.
            crossings.clear();
            let n = self.outline.len();
            for k in 0..n {
                let (a, b) = (self.outline[k], self.outline[(k + 1) % n]);
                if (a.y > qy) != (b.y > qy) {
                    crossings.push(a.x + (qy - a.y) / (b.y - a.y) * (b.x - a.x));
                }
            }
            crossings.sort_by(f64::total_cmp);
            for x in 0..w {
                let qx = self.box_lo.x + (f64::from(x) + 0.5) / f64::from(w) * e.x;
                let inside = crossings.iter().take_while(|&&c| c <= qx).count() % 2 == 1;
                let (c, near) = self.colour_and_margin(DVec2::new(qx, qy));
                let c = if inside || near { c.map(to_byte) } else { vein };
                rgba.extend_from_slice(&[c[0], c[1], c[2], 255]);
            }
        }
        Texture { width: w, height: h, rgba }
    }

    /// The point of the leaf's plane under `p`: `p`'s nearest point on its nearest blade
    /// triangle, carried into the flat web by barycentric coordinates. `blade` must be the
    /// blade this texture was made for.
    pub fn plane_point(&self, blade: &Blade, p: DVec3) -> DVec2 {
        self.plane_point_of(blade, p, blade.distance(p).triangle)
    }

    /// [`LeafTexture::plane_point`] through blade triangle `t`.
    fn plane_point_of(&self, blade: &Blade, p: DVec3, t: usize) -> DVec2 {
        self.plane_point_through(blade, p, t, true)
    }

    /// `p` carried into the plane by its barycentric coordinates in blade triangle `t`,
    /// unclamped: beyond the triangle, the affine map of the triangle extended.
    fn plane_point_unclamped(&self, blade: &Blade, p: DVec3, t: usize) -> DVec2 {
        self.plane_point_through(blade, p, t, false)
    }

    fn plane_point_through(&self, blade: &Blade, p: DVec3, t: usize, clamp: bool) -> DVec2 {
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
        let bary = [1.0 - v - w, v, w].map(|x: f64| if clamp { x.max(0.0) } else { x });
        let sum: f64 = if clamp { bary.iter().sum() } else { 1.0 };
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

/// An sRGB component in `[0, 1]` as a byte.
fn to_byte(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
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
