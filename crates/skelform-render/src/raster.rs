//! The rasterizer: vertices projected once, triangles binned into square tiles, and each
//! tile rasterized, shaded, overlaid with curves and reduced to final pixels on its own.
//!
//! Determinism: tiles are fixed squares of the image, every tile processes its triangles in
//! mesh order, and bins are built in fixed chunks of triangles concatenated in order. A
//! pixel's colour therefore depends only on the mesh and the settings, never on which
//! thread ran which tile, and no floating-point sum crosses a tile.
//!
//! Coverage is exact: vertices are snapped to 1/256 pixel and edge functions evaluated in
//! 64-bit integers with a top-left rule, so two triangles sharing an edge never both cover a
//! pixel centre on it, nor both miss it. That matters for transparency, where a doubly
//! covered pixel would show as a seam.

use rayon::prelude::*;
use skelform_mesh::Mesh;

use crate::Settings;
use crate::camera::{Camera, Projection};
use crate::image::{Image, Rgb, to_linear, to_srgb};

/// Side of a tile in final pixels.
const TILE: u32 = 32;
/// Sub-pixel precision of snapped vertices: 1/256 pixel.
const SUB: i64 = 256;
/// Triangles per binning chunk.
const CHUNK: usize = 1 << 15;

type V3 = [f32; 3];

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn normalize(a: V3) -> Option<V3> {
    let l = dot(a, a).sqrt();
    (l > 0.0 && l.is_finite()).then(|| [a[0] / l, a[1] / l, a[2] / l])
}

/// What the renderer keeps of a mesh between views.
pub(crate) struct Prepared<'m> {
    pub mesh: &'m Mesh,
    /// Unit vertex normals: the mesh's own, or area-weighted face normals when it has none.
    pub normals: Vec<V3>,
    /// Unit face normals from the winding (zero for degenerate faces).
    pub face_normals: Vec<V3>,
    /// Per triangle, the index of its label in `pairs` (0 for unlabelled meshes).
    pub colour_of: Vec<u16>,
    /// The distinct labels, sorted; empty for an unlabelled mesh.
    pub pairs: Vec<skelform_mesh::RegionPair>,
    /// The mesh's vertex colours in linear light, or empty.
    pub vertex_colours: Vec<V3>,
    /// The mesh's texture in linear light, when it has one and texture coordinates.
    pub texture: Option<Texels>,
    /// Bounds of the vertices that triangles use.
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

/// A texture's texels in linear light, rows from the top (as [`skelform_mesh::Texture`]).
pub(crate) struct Texels {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<V3>,
}

impl Texels {
    /// The texels of `t`, converted once (alpha is ignored: surfaces are opaque).
    pub fn new(t: &skelform_mesh::Texture) -> Option<Texels> {
        t.validate().ok()?;
        let table: Vec<f32> = (0..=255u8).map(crate::image::to_linear).collect();
        let texels =
            t.rgba.chunks_exact(4).map(|c| [0, 1, 2].map(|k| table[c[k] as usize])).collect();
        Some(Texels { width: t.width, height: t.height, texels })
    }

    /// The bilinear sample at `[u, v]` (texel centres at `(i + ½) / width`), clamped at the
    /// edges as the glb's sampler is.
    pub fn sample(&self, uv: [f32; 2]) -> V3 {
        let (w, h) = (self.width as usize, self.height as usize);
        let axis = |c: f32, n: usize| {
            let x = if c.is_finite() { c * n as f32 - 0.5 } else { 0.0 };
            let x = x.clamp(0.0, (n - 1) as f32);
            let i = (x.floor() as usize).min(n - 1);
            (i, (i + 1).min(n - 1), x - i as f32)
        };
        let (x0, x1, fx) = axis(uv[0], w);
        let (y0, y1, fy) = axis(uv[1], h);
        let t = |x: usize, y: usize| self.texels[y * w + x];
        let (a, b, c, d) = (t(x0, y0), t(x1, y0), t(x0, y1), t(x1, y1));
        std::array::from_fn(|k| {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (d[k] - c[k]) * fx;
            top + (bottom - top) * fy
        })
    }
}

/// Colours and lights of one render, in linear light.
pub(crate) struct Look {
    /// Front colour of each entry of `Prepared::pairs` (or one entry for unlabelled).
    pub front: Vec<V3>,
    pub back: Vec<V3>,
    pub background: V3,
    pub light: V3,
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
    pub curve: V3,
    pub wire: V3,
}

pub(crate) fn lin(c: Rgb) -> V3 {
    c.map(to_linear)
}

/// A projected vertex.
#[derive(Clone, Copy, Default)]
struct Sv {
    /// Snapped position in 1/256 pixels.
    fx: i64,
    fy: i64,
    /// Depth key, affine in screen space, larger is nearer: 1/z (perspective) or −z.
    key: f32,
    /// Perspective weight 1/z (1 for orthographic).
    pw: f32,
    ok: bool,
}

/// One view of a prepared mesh at the internal (supersampled) resolution.
struct View<'a> {
    p: &'a Prepared<'a>,
    s: &'a Settings,
    look: &'a Look,
    /// The camera at internal resolution.
    cam: Camera,
    ss: u32,
    verts: Vec<Sv>,
    /// Triangle indices per tile, in mesh order.
    bins: Vec<Vec<u32>>,
    /// Curve edges per tile.
    curve_bins: Vec<Vec<u32>>,
    tiles_x: u32,
    tiles_y: u32,
    light: V3,
    radius: f32,
}

fn key_depth(cam: &Camera, key: f32) -> f32 {
    match cam.projection {
        Projection::Perspective { .. } => 1.0 / key,
        Projection::Orthographic => -key,
    }
}

/// The fixed-point triangle of face `t` and whether it faces the camera, or `None` when it
/// has a vertex behind the eye or no area.
struct Tri {
    v: [(i64, i64); 3],
    /// Original vertex index of each (possibly reordered) corner.
    order: [usize; 3],
    area: i64,
}

fn setup(verts: &[Sv], t: [u32; 3]) -> Option<Tri> {
    let a = verts[t[0] as usize];
    let b = verts[t[1] as usize];
    let c = verts[t[2] as usize];
    if !(a.ok && b.ok && c.ok) {
        return None;
    }
    let mut v = [(a.fx, a.fy), (b.fx, b.fy), (c.fx, c.fy)];
    let mut order = [0, 1, 2];
    let mut area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[1].1 - v[0].1) * (v[2].0 - v[0].0);
    if area == 0 {
        return None;
    }
    if area < 0 {
        v.swap(1, 2);
        order.swap(1, 2);
        area = -area;
    }
    Some(Tri { v, order, area })
}

/// The range of pixel indices whose centres (`i·SUB + SUB/2`) lie in `[lo, hi]`.
fn pixel_range(lo: i64, hi: i64) -> (i64, i64) {
    let first = (lo - SUB / 2 + SUB - 1).div_euclid(SUB);
    let last = (hi - SUB / 2).div_euclid(SUB);
    (first, last)
}

/// Whether an edge with direction `(dx, dy)` is a top or left edge: pixel centres exactly
/// on it belong to the triangle. For the opposite direction the answer is the opposite.
fn top_left(dx: i64, dy: i64) -> bool {
    dy < 0 || (dy == 0 && dx > 0)
}

/// A fragment of a triangle at a pixel.
#[derive(Clone, Copy)]
struct Frag {
    key: f32,
    tri: u32,
    /// Perspective-correct barycentrics of the triangle's 2nd and 3rd vertices.
    b1: f32,
    b2: f32,
}

impl<'a> View<'a> {
    fn new(p: &'a Prepared<'a>, s: &'a Settings, look: &'a Look, cam: Camera) -> View<'a> {
        let ss = s.supersample;
        let cam = cam.scaled(ss);
        let mesh = p.mesh;
        let (wi, hi) = (i64::from(cam.width), i64::from(cam.height));
        let verts: Vec<Sv> = mesh
            .positions
            .par_iter()
            .map(|q| {
                let Some([x, y, z]) = cam.project(q.map(f64::from)) else {
                    return Sv::default();
                };
                let (fx, fy) = ((x * SUB as f64).round(), (y * SUB as f64).round());
                // Far outside the image (only for points behind or beside a close camera):
                // leave the triangle out rather than overflow the edge functions.
                let guard = 4.0 * (wi.max(hi) as f64 + 16.0) * SUB as f64;
                if !(fx.abs() < guard && fy.abs() < guard) {
                    return Sv::default();
                }
                let (key, pw) = match cam.projection {
                    Projection::Perspective { .. } => ((1.0 / z) as f32, (1.0 / z) as f32),
                    Projection::Orthographic => ((-z) as f32, 1.0),
                };
                Sv { fx: fx as i64, fy: fy as i64, key, pw, ok: true }
            })
            .collect();

        let tile_px = i64::from(TILE * ss);
        let tiles_x = cam.width.div_ceil(TILE * ss);
        let tiles_y = cam.height.div_ceil(TILE * ss);
        let ntiles = (tiles_x * tiles_y) as usize;
        let per_chunk: Vec<Vec<Vec<u32>>> = mesh
            .triangles
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(ci, chunk)| {
                let mut bins = vec![Vec::new(); ntiles];
                for (k, t) in chunk.iter().enumerate() {
                    let Some(tri) = setup(&verts, *t) else { continue };
                    let (x0, x1) = pixel_range(
                        tri.v.iter().map(|v| v.0).min().unwrap_or(0),
                        tri.v.iter().map(|v| v.0).max().unwrap_or(0),
                    );
                    let (y0, y1) = pixel_range(
                        tri.v.iter().map(|v| v.1).min().unwrap_or(0),
                        tri.v.iter().map(|v| v.1).max().unwrap_or(0),
                    );
                    let (x0, x1, y0, y1) = (x0.max(0), x1.min(wi - 1), y0.max(0), y1.min(hi - 1));
                    if x0 > x1 || y0 > y1 {
                        continue;
                    }
                    let id = (ci * CHUNK + k) as u32;
                    for ty in y0 / tile_px..=y1 / tile_px {
                        for tx in x0 / tile_px..=x1 / tile_px {
                            bins[(ty * i64::from(tiles_x) + tx) as usize].push(id);
                        }
                    }
                }
                bins
            })
            .collect();
        let bins: Vec<Vec<u32>> = (0..ntiles)
            .into_par_iter()
            .map(|t| {
                let mut v = Vec::with_capacity(per_chunk.iter().map(|c| c[t].len()).sum());
                for c in &per_chunk {
                    v.extend_from_slice(&c[t]);
                }
                v
            })
            .collect();
        drop(per_chunk);

        let mut curve_bins = vec![Vec::new(); ntiles];
        if s.curves {
            let reach = (f64::from(s.curve_width) * f64::from(ss) / 2.0 + 1.0) * SUB as f64;
            for (e, c) in mesh.curves.iter().enumerate() {
                let (a, b) = (verts[c.v[0] as usize], verts[c.v[1] as usize]);
                if !(a.ok && b.ok) {
                    continue;
                }
                let r = reach as i64;
                let (x0, _) = pixel_range(a.fx.min(b.fx) - r, 0);
                let (_, x1) = pixel_range(0, a.fx.max(b.fx) + r);
                let (y0, _) = pixel_range(a.fy.min(b.fy) - r, 0);
                let (_, y1) = pixel_range(0, a.fy.max(b.fy) + r);
                let (x0, x1, y0, y1) = (x0.max(0), x1.min(wi - 1), y0.max(0), y1.min(hi - 1));
                if x0 > x1 || y0 > y1 {
                    continue;
                }
                for ty in y0 / tile_px..=y1 / tile_px {
                    for tx in x0 / tile_px..=x1 / tile_px {
                        curve_bins[(ty * i64::from(tiles_x) + tx) as usize].push(e as u32);
                    }
                }
            }
        }
        let l = look.light;
        let world = |v: [f64; 3]| v.map(|c| c as f32);
        let (r, u, f) = (world(cam.right), world(cam.up), world(cam.forward));
        let light = normalize([
            l[0] * r[0] + l[1] * u[0] - l[2] * f[0],
            l[0] * r[1] + l[1] * u[1] - l[2] * f[1],
            l[0] * r[2] + l[1] * u[2] - l[2] * f[2],
        ])
        .unwrap_or([-f[0], -f[1], -f[2]]);
        let d: Vec<f32> = (0..3).map(|k| p.hi[k] - p.lo[k]).collect();
        let radius = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() / 2.0;
        View { p, s, look, cam, ss, verts, bins, curve_bins, tiles_x, tiles_y, light, radius }
    }

    /// The picture: every tile in parallel, then the tiles copied into place in order.
    fn render(&self) -> Image {
        let (w, h) = (self.cam.width / self.ss, self.cam.height / self.ss);
        let tiles: Vec<(u32, u32, Vec<Rgb>)> = (0..self.tiles_x * self.tiles_y)
            .into_par_iter()
            .map(|t| {
                let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
                (tx, ty, self.tile(tx, ty))
            })
            .collect();
        let mut img = Image::new(w, h, [0; 3]);
        for (tx, ty, px) in tiles {
            let (x0, y0) = (tx * TILE, ty * TILE);
            let tw = TILE.min(w - x0);
            for (k, c) in px.into_iter().enumerate() {
                let (x, y) = (x0 + k as u32 % tw, y0 + k as u32 / tw);
                img.pixels[(y * w + x) as usize] = c;
            }
        }
        img
    }

    /// One tile: rasterize, shade, draw curves, reduce to final pixels.
    fn tile(&self, tx: u32, ty: u32) -> Vec<Rgb> {
        let ss = self.ss;
        let (wi, hi) = (self.cam.width, self.cam.height);
        let x0 = tx * TILE * ss;
        let y0 = ty * TILE * ss;
        let tw = (TILE * ss).min(wi - x0);
        let th = (TILE * ss).min(hi - y0);
        let n = (tw * th) as usize;
        let tile = (ty * self.tiles_x + tx) as usize;

        // Colour and the depth of the nearest surface, per internal pixel.
        let mut colour = vec![self.look.background; n];
        let mut front_key = vec![f32::NEG_INFINITY; n];
        if self.s.transparent {
            let mut frags: Vec<(u32, Frag)> = Vec::new();
            self.rasterize(tile, x0, y0, tw, th, |pix, f| frags.push((pix, f)));
            // Front to back per pixel; ties broken by triangle order so the result is fixed.
            frags.sort_unstable_by(|a, b| {
                a.0.cmp(&b.0).then(b.1.key.total_cmp(&a.1.key)).then(a.1.tri.cmp(&b.1.tri))
            });
            let mut i = 0;
            while i < frags.len() {
                let pix = frags[i].0;
                let mut j = i;
                let mut acc = [0.0f32; 3];
                let mut through = 1.0f32;
                front_key[pix as usize] = frags[i].1.key;
                let (px, py) = (x0 + pix % tw, y0 + pix / tw);
                while j < frags.len() && frags[j].0 == pix {
                    if through > 1.0 / 1024.0 {
                        let (c, facing) = self.shade(frags[j].1, px, py);
                        // Sheets seen edge-on are more opaque, which outlines each sheet.
                        let rim = (1.0 - facing.abs()).powi(3);
                        let a = self.s.opacity + (1.0 - self.s.opacity) * 0.6 * rim;
                        for k in 0..3 {
                            acc[k] += through * a * c[k];
                        }
                        through *= 1.0 - a;
                    }
                    j += 1;
                }
                for k in 0..3 {
                    colour[pix as usize][k] = acc[k] + through * self.look.background[k];
                }
                i = j;
            }
        } else {
            let mut best: Vec<Option<Frag>> = vec![None; n];
            self.rasterize(tile, x0, y0, tw, th, |pix, f| {
                let slot = &mut best[pix as usize];
                if slot.is_none_or(|b| f.key > b.key) {
                    *slot = Some(f);
                }
            });
            for (pix, f) in best.iter().enumerate() {
                if let Some(f) = f {
                    let (px, py) = (x0 + pix as u32 % tw, y0 + pix as u32 / tw);
                    colour[pix] = self.shade(*f, px, py).0;
                    front_key[pix] = f.key;
                }
            }
        }
        if self.s.curves && !self.curve_bins[tile].is_empty() {
            self.draw_curves(tile, x0, y0, tw, th, &front_key, &mut colour);
        }

        // Reduce: the mean of the ss × ss samples of each final pixel, in linear light.
        let (fw, fh) = (tw / ss, th / ss);
        let mut out = Vec::with_capacity((fw * fh) as usize);
        let inv = 1.0 / (ss * ss) as f32;
        for fy in 0..fh {
            for fx in 0..fw {
                let mut sum = [0.0f32; 3];
                for sy in 0..ss {
                    for sx in 0..ss {
                        let c = colour[((fy * ss + sy) * tw + fx * ss + sx) as usize];
                        for k in 0..3 {
                            sum[k] += c[k];
                        }
                    }
                }
                out.push(sum.map(|v| to_srgb(v * inv)));
            }
        }
        out
    }

    /// Calls `emit(pixel index in tile, fragment)` for every pixel centre in the tile that
    /// a triangle of the tile's bin covers, triangles in mesh order.
    fn rasterize(
        &self,
        tile: usize,
        x0: u32,
        y0: u32,
        tw: u32,
        th: u32,
        mut emit: impl FnMut(u32, Frag),
    ) {
        let tris = &self.p.mesh.triangles;
        let (tx0, ty0) = (i64::from(x0), i64::from(y0));
        let (tx1, ty1) = (tx0 + i64::from(tw) - 1, ty0 + i64::from(th) - 1);
        for &id in &self.bins[tile] {
            let t = tris[id as usize];
            let Some(tri) = setup(&self.verts, t) else { continue };
            let [a, b, c] = tri.v;
            let (xa, xb) = pixel_range(a.0.min(b.0).min(c.0), a.0.max(b.0).max(c.0));
            let (ya, yb) = pixel_range(a.1.min(b.1).min(c.1), a.1.max(b.1).max(c.1));
            let (xa, xb, ya, yb) = (xa.max(tx0), xb.min(tx1), ya.max(ty0), yb.min(ty1));
            if xa > xb || ya > yb {
                continue;
            }
            // Edge k is opposite corner k: e0 = b→c, e1 = c→a, e2 = a→b.
            let edges = [(b, c), (c, a), (a, b)];
            let mut start = [0i64; 3];
            let mut step_x = [0i64; 3];
            let mut step_y = [0i64; 3];
            let (px, py) = (xa * SUB + SUB / 2, ya * SUB + SUB / 2);
            for (k, (p, q)) in edges.iter().enumerate() {
                let (dx, dy) = (q.0 - p.0, q.1 - p.1);
                let bias = if top_left(dx, dy) { 0 } else { -1 };
                start[k] = dx * (py - p.1) - dy * (px - p.0) + bias;
                step_x[k] = -dy * SUB;
                step_y[k] = dx * SUB;
            }
            let sv = [
                self.verts[t[tri.order[0]] as usize],
                self.verts[t[tri.order[1]] as usize],
                self.verts[t[tri.order[2]] as usize],
            ];
            let inv_area = 1.0 / tri.area as f64;
            let mut row = start;
            for y in ya..=yb {
                let mut e = row;
                for x in xa..=xb {
                    if e[0] >= 0 && e[1] >= 0 && e[2] >= 0 {
                        // Remove the bias again for the weights.
                        let w: [f32; 3] = std::array::from_fn(|k| {
                            let (p, q) = edges[k];
                            let unbiased =
                                e[k] + if top_left(q.0 - p.0, q.1 - p.1) { 0 } else { 1 };
                            (unbiased as f64 * inv_area) as f32
                        });
                        let key = w[0] * sv[0].key + w[1] * sv[1].key + w[2] * sv[2].key;
                        let pw = [w[0] * sv[0].pw, w[1] * sv[1].pw, w[2] * sv[2].pw];
                        let sum = pw[0] + pw[1] + pw[2];
                        // Back to the triangle's own vertex order.
                        let mut bary = [0.0f32; 3];
                        for k in 0..3 {
                            bary[tri.order[k]] = pw[k] / sum;
                        }
                        let pix = ((y - ty0) * i64::from(tw) + (x - tx0)) as u32;
                        emit(pix, Frag { key, tri: id, b1: bary[1], b2: bary[2] });
                    }
                    for k in 0..3 {
                        e[k] += step_x[k];
                    }
                }
                for k in 0..3 {
                    row[k] += step_y[k];
                }
            }
        }
    }

    /// The colour of a fragment at internal pixel `(x, y)` in linear light, and the cosine
    /// between its normal and the direction to the eye.
    fn shade(&self, f: Frag, x: u32, y: u32) -> (V3, f32) {
        let p = self.p;
        let t = p.mesh.triangles[f.tri as usize];
        let b = [1.0 - f.b1 - f.b2, f.b1, f.b2];
        let g = p.face_normals[f.tri as usize];
        let mut n = [0.0f32; 3];
        for (k, &vi) in t.iter().enumerate() {
            let vn = p.normals[vi as usize];
            for c in 0..3 {
                n[c] += b[k] * vn[c];
            }
        }
        let mut n = normalize(n).unwrap_or(g);
        // Normals that disagree with the winding (inward normals, a non-manifold vertex
        // shared by sheets) are turned to the winding's side, so shading follows the face.
        if dot(n, g) < 0.0 {
            n = n.map(|c| -c);
        }
        let ray = self.cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5).map(|c| c as f32);
        let to_eye = ray.map(|c| -c);
        let ci = p.colour_of[f.tri as usize] as usize;
        // The mesh's own colours: its texture sampled per pixel at the interpolated texture
        // coordinates (perspective-correct: `b` is), else its vertex colours interpolated.
        let vertex = if !self.s.vertex_colours {
            None
        } else if let Some(tex) = &p.texture {
            let mut uv = [0.0f32; 2];
            for (k, &vi) in t.iter().enumerate() {
                let w = p.mesh.uvs[vi as usize];
                uv[0] += b[k] * w[0];
                uv[1] += b[k] * w[1];
            }
            Some(tex.sample(uv))
        } else {
            (!p.vertex_colours.is_empty()).then(|| {
                let mut c = [0.0f32; 3];
                for (k, &vi) in t.iter().enumerate() {
                    let vc = p.vertex_colours[vi as usize];
                    for j in 0..3 {
                        c[j] += b[k] * vc[j];
                    }
                }
                c
            })
        };
        let albedo = if dot(g, to_eye) >= 0.0 {
            vertex.unwrap_or(self.look.front[ci])
        } else {
            // The back of the face: light it as its own side, in the back colour.
            n = n.map(|c| -c);
            vertex.map_or(self.look.back[ci], |c| c.map(|v| v * 0.55))
        };
        let l = self.light;
        let lk = self.look;
        let diffuse = dot(n, l).max(0.0);
        let h = normalize([l[0] + to_eye[0], l[1] + to_eye[1], l[2] + to_eye[2]]).unwrap_or(n);
        let spec = if diffuse > 0.0 { dot(n, h).max(0.0).powf(lk.shininess) } else { 0.0 };
        let mut c: V3 = std::array::from_fn(|k| {
            albedo[k] * (lk.ambient + lk.diffuse * diffuse) + lk.specular * spec
        });
        if self.s.wireframe {
            let cover = self.wire_cover(t, x, y);
            if cover > 0.0 {
                for (ck, wk) in c.iter_mut().zip(lk.wire) {
                    *ck += (wk - *ck) * cover;
                }
            }
        }
        (c, dot(n, to_eye))
    }

    /// How much of internal pixel `(x, y)` the edges of triangle `t` cover as lines of the
    /// wireframe's width.
    fn wire_cover(&self, t: [u32; 3], x: u32, y: u32) -> f32 {
        let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        let v: Vec<(f64, f64)> = t
            .iter()
            .map(|&i| {
                let s = self.verts[i as usize];
                (s.fx as f64 / SUB as f64, s.fy as f64 / SUB as f64)
            })
            .collect();
        let mut d = f64::INFINITY;
        for k in 0..3 {
            d = d.min(segment_distance(v[k], v[(k + 1) % 3], (px, py)).0);
        }
        let half = f64::from(self.s.wire_width) * f64::from(self.ss) / 2.0;
        ((half + 0.5 - d).clamp(0.0, 1.0) * f64::from(self.s.wire_opacity)) as f32
    }

    /// Thick curves over the surface, hidden where the surface is in front of them (in
    /// transparent pictures hidden parts show faintly).
    #[allow(clippy::too_many_arguments)]
    fn draw_curves(
        &self,
        tile: usize,
        x0: u32,
        y0: u32,
        tw: u32,
        th: u32,
        front_key: &[f32],
        colour: &mut [V3],
    ) {
        let half = f64::from(self.s.curve_width) * f64::from(self.ss) / 2.0;
        let mut cover = vec![0.0f32; (tw * th) as usize];
        let px_size = |z: f32| match self.cam.projection {
            Projection::Perspective { .. } => z / self.cam.scale as f32,
            Projection::Orthographic => 1.0 / self.cam.scale as f32,
        };
        for &e in &self.curve_bins[tile] {
            let c = self.p.mesh.curves[e as usize];
            let (a, b) = (self.verts[c.v[0] as usize], self.verts[c.v[1] as usize]);
            let pa = (a.fx as f64 / SUB as f64, a.fy as f64 / SUB as f64);
            let pb = (b.fx as f64 / SUB as f64, b.fy as f64 / SUB as f64);
            let xa = ((pa.0.min(pb.0) - half - 1.0).floor() as i64).max(i64::from(x0));
            let xb = ((pa.0.max(pb.0) + half + 1.0).ceil() as i64).min(i64::from(x0 + tw) - 1);
            let ya = ((pa.1.min(pb.1) - half - 1.0).floor() as i64).max(i64::from(y0));
            let yb = ((pa.1.max(pb.1) + half + 1.0).ceil() as i64).min(i64::from(y0 + th) - 1);
            for y in ya..=yb {
                for x in xa..=xb {
                    let (d, s) = segment_distance(pa, pb, (x as f64 + 0.5, y as f64 + 0.5));
                    let cv = (half + 0.5 - d).clamp(0.0, 1.0) as f32;
                    if cv <= 0.0 {
                        continue;
                    }
                    let pix = ((y - i64::from(y0)) * i64::from(tw) + (x - i64::from(x0))) as usize;
                    // The key is affine along the projected segment.
                    let key = a.key + (b.key - a.key) * s as f32;
                    let fk = front_key[pix];
                    let visible = if fk == f32::NEG_INFINITY {
                        true
                    } else {
                        let (zc, zs) = (key_depth(&self.cam, key), key_depth(&self.cam, fk));
                        let tol = 0.01 * self.radius + 2.0 * half as f32 * px_size(zc);
                        zc <= zs + tol
                    };
                    let cv = if visible {
                        cv
                    } else if self.s.transparent {
                        cv * 0.35
                    } else {
                        0.0
                    };
                    cover[pix] = cover[pix].max(cv);
                }
            }
        }
        let cc = self.look.curve;
        for (c, &a) in colour.iter_mut().zip(&cover) {
            if a > 0.0 {
                for k in 0..3 {
                    c[k] += (cc[k] - c[k]) * a;
                }
            }
        }
    }
}

/// Distance from `p` to the segment `a–b`, and the parameter of the nearest point.
fn segment_distance(a: (f64, f64), b: (f64, f64), p: (f64, f64)) -> (f64, f64) {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let s = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (qx, qy) = (a.0 + s * dx - p.0, a.1 + s * dy - p.1);
    ((qx * qx + qy * qy).sqrt(), s)
}

/// Renders one view.
pub(crate) fn render_view(p: &Prepared<'_>, s: &Settings, look: &Look, cam: Camera) -> Image {
    View::new(p, s, look, cam).render()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_sample_bilinearly_and_clamp_at_the_edges() {
        // 2 x 1: black, white.
        let t = skelform_mesh::Texture {
            width: 2,
            height: 1,
            rgba: vec![0, 0, 0, 255, 255, 255, 255, 255],
        };
        let t = Texels::new(&t).unwrap();
        // Texel centres at u = 1/4 and 3/4; halfway between, half of each (in linear light).
        assert_eq!(t.sample([0.25, 0.5]), [0.0; 3]);
        assert_eq!(t.sample([0.75, 0.5]), [1.0; 3]);
        assert!((t.sample([0.5, 0.5])[0] - 0.5).abs() < 1e-6);
        // Beyond the centres of the edge texels, and outside [0, 1]: the edge texel.
        assert_eq!(t.sample([-3.0, 7.0]), [0.0; 3]);
        assert_eq!(t.sample([0.9, 0.0]), [1.0; 3]);
        assert_eq!(t.sample([f32::NAN, 0.5]), [0.0; 3]);
        assert!(
            Texels::new(&skelform_mesh::Texture { width: 2, height: 2, rgba: vec![0; 4] })
                .is_none()
        );
    }

    #[test]
    fn pixel_range_takes_centres_inside() {
        // Centres at 128, 384, 640 …: [100, 400] holds pixels 0 and 1.
        assert_eq!(pixel_range(100, 400), (0, 1));
        assert_eq!(pixel_range(128, 128), (0, 0));
        assert_eq!(pixel_range(129, 383), (1, 0));
        assert_eq!(pixel_range(-300, -10), (-1, -1));
    }

    #[test]
    fn top_left_is_antisymmetric() {
        for (dx, dy) in [(1, 0), (0, 1), (3, -2), (-5, 7), (4, 4)] {
            assert_ne!(top_left(dx, dy), top_left(-dx, -dy));
        }
    }
}
