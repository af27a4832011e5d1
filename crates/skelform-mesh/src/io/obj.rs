//! Wavefront OBJ.
//!
//! Written: `v x y z`; `vn` lines when normals are written (then faces are `f a//a b//b c//c`,
//! otherwise `f a b c`, 1-based); `vt u v` lines, one per vertex, when the mesh has texture
//! coordinates (then corners are `a/a/a`, or `a/a` without normals); a labelled mesh has one group `g region_A_B` per region
//! pair, its faces sorted by label (stable: the order within a group is kept); curves are
//! `l i j` segments in groups `g curve_A_B_C`, sorted by label the same way.
//!
//! Read: `v` (a 4th `w` or colour components are ignored), `vn`, `vt` (a 3rd `w` ignored), `f` with
//! `v`, `v/vt`, `v//vn` and `v/vt/vn` corners, negative (relative) indices and forward
//! references, polygons fan-triangulated; `l` polylines of two or more vertices become curve
//! segments; `\` line continuations; `#` comments, blank lines, `mtllib`, `usemtl`, `s` and
//! every other keyword are ignored (labels come from the group names alone). Each `g` or `o` line sets the current labels from its
//! names: `region_A_B` labels the following faces `RegionPair::new(A, B)`, `curve_A_B_C`
//! labels the following `l` lines; any other name means no label (curves then get
//! `RegionTriple([0, 0, 0])`).
//!
//! Sizes: at most [`MAX_VERTICES`](super::limits::MAX_VERTICES) vertices and
//! [`MAX_TRIANGLES`](super::limits::MAX_TRIANGLES) triangles (text cannot expand further:
//! every vertex and face takes bytes of the file).
//!
//! Labels: when no face has a label, `labels` is empty. When only some faces have one, the
//! others get `RegionPair(0, 1)`, the label of a plain manifold surface (outside region 0,
//! inside region 1, so that its counter-clockwise winding seen from outside is the winding
//! seen from the lesser region).
//!
//! Normals: OBJ normals belong to face corners; they become per-vertex normals when every
//! face corner has one and each vertex always gets the same normal (the same `vn` index or
//! bit-identical `vn` values). Otherwise, or when no corner has one, `normals` is empty.
//! Vertices that no face uses then get a zero normal. Texture coordinates likewise become
//! per-vertex `uvs` when every corner has one and each vertex always gets the same one.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use super::{IoError, WriteOptions, buffered, finish, limits, three_numbers};
use crate::mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};
use crate::palette::region_colour;

/// No normal index for a corner.
const NONE: u32 = u32::MAX;

#[derive(Default)]
struct Reader {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    /// The normal index of each triangle corner, `NONE` where absent.
    corner_normals: Vec<[u32; 3]>,
    texcoords: Vec<[f32; 2]>,
    /// The texture-coordinate index of each triangle corner, `NONE` where absent.
    corner_uvs: Vec<[u32; 3]>,
    labels: Vec<Option<RegionPair>>,
    curves: Vec<CurveEdge>,
    face_label: Option<RegionPair>,
    curve_label: Option<RegionTriple>,
    /// The largest positive (0-based) vertex and normal indices used, with their lines, to
    /// check forward references once the whole file is read.
    max_vertex: Option<(u32, usize)>,
    max_normal: Option<(u32, usize)>,
    max_uv: Option<(u32, usize)>,
    /// Each corner's vertex, normal and texture-coordinate indices.
    corners: Vec<(u32, u32, u32)>,
}

/// A label name `prefix` followed by `N` numbers separated by `_`.
fn parse_label<const N: usize>(name: &str, prefix: &str) -> Option<[u32; N]> {
    let mut parts = name.strip_prefix(prefix)?.split('_');
    let mut out = [0; N];
    for o in &mut out {
        *o = parts.next()?.parse().ok()?;
    }
    parts.next().is_none().then_some(out)
}

impl Reader {
    /// Resolves a 1-based or negative OBJ index into a 0-based one. `defined` is how many
    /// items are defined so far; positive indices may refer forward and are checked at the
    /// end against `max`.
    fn index(
        word: &str,
        defined: usize,
        line: usize,
        what: &str,
        max: &mut Option<(u32, usize)>,
    ) -> Result<u32, IoError> {
        let i: i64 = word.parse().map_err(|_| {
            IoError::parse(line, format!("expected a {what} index, found '{word}'"))
        })?;
        if i > 0 {
            let i = u32::try_from(i - 1).ok().filter(|&i| i != NONE).ok_or_else(|| {
                IoError::parse(line, format!("{what} index {word} is out of range"))
            })?;
            if max.is_none_or(|(m, _)| i > m) {
                *max = Some((i, line));
            }
            Ok(i)
        } else if i < 0 && i.unsigned_abs() <= defined as u64 {
            Ok((defined as u64 - i.unsigned_abs()) as u32)
        } else if i == 0 {
            Err(IoError::parse(line, format!("{what} index 0 is invalid: OBJ indices start at 1")))
        } else {
            Err(IoError::parse(
                line,
                format!(
                    "relative {what} index {i} refers before the first {what} ({defined} defined so far)"
                ),
            ))
        }
    }

    fn line(&mut self, text: &str, line: usize) -> Result<(), IoError> {
        let text = text.split('#').next().unwrap_or_default();
        let mut words = text.split_whitespace();
        let Some(keyword) = words.next() else { return Ok(()) };
        match keyword {
            "v" => {
                let p = three_numbers(&mut words, line, "v")?;
                if self.positions.len() >= limits::MAX_VERTICES {
                    return Err(IoError::parse(
                        line,
                        format!(
                            "more than {} vertices; skelform reads at most that many",
                            limits::MAX_VERTICES
                        ),
                    ));
                }
                self.positions.push(p);
            }
            "vn" => {
                let n = three_numbers(&mut words, line, "vn")?;
                self.normals.push(n);
            }
            "vt" => {
                let mut uv = [0.0f32; 2];
                for (k, c) in uv.iter_mut().enumerate() {
                    let word = words.next();
                    // `vt u` alone is allowed (v = 0), as the format says.
                    if word.is_none() && k == 1 {
                        break;
                    }
                    *c = word.and_then(|w| w.parse().ok()).ok_or_else(|| {
                        IoError::parse(line, "expected vt followed by one to three numbers")
                    })?;
                }
                if self.texcoords.len() >= limits::MAX_VERTICES {
                    return Err(IoError::parse(
                        line,
                        format!(
                            "more than {} texture coordinates; skelform reads at most that many",
                            limits::MAX_VERTICES
                        ),
                    ));
                }
                self.texcoords.push(uv);
            }
            "f" | "fo" => self.face(words, line)?,
            "l" => self.polyline(words, line)?,
            "g" | "o" => {
                self.face_label = None;
                self.curve_label = None;
                for name in words {
                    if let Some([a, b]) = parse_label::<2>(name, "region_") {
                        self.face_label = Some(RegionPair::new(a, b));
                        break;
                    }
                    if let Some(r) = parse_label::<3>(name, "curve_") {
                        self.curve_label = Some(RegionTriple::new(r));
                        break;
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn face<'a>(
        &mut self,
        words: impl Iterator<Item = &'a str>,
        line: usize,
    ) -> Result<(), IoError> {
        self.corners.clear();
        for word in words {
            let mut parts = word.split('/');
            let v = parts.next().unwrap_or_default();
            let v = Self::index(v, self.positions.len(), line, "vertex", &mut self.max_vertex)?;
            let t = match parts.next() {
                Some(vt) if !vt.is_empty() => {
                    if vt.parse::<i64>().is_err() {
                        return Err(IoError::parse(
                            line,
                            format!("expected a texture index in '{word}', found '{vt}'"),
                        ));
                    }
                    Self::index(vt, self.texcoords.len(), line, "texture", &mut self.max_uv)?
                }
                _ => NONE,
            };
            let n = match parts.next() {
                Some(vn) if !vn.is_empty() => {
                    Self::index(vn, self.normals.len(), line, "normal", &mut self.max_normal)?
                }
                _ => NONE,
            };
            if parts.next().is_some() {
                return Err(IoError::parse(
                    line,
                    format!("expected a face corner v, v/vt, v//vn or v/vt/vn, found '{word}'"),
                ));
            }
            self.corners.push((v, n, t));
        }
        if self.corners.len() < 3 {
            return Err(IoError::parse(
                line,
                format!("a face needs at least 3 vertices, found {}", self.corners.len()),
            ));
        }
        let c = &self.corners;
        if self.triangles.len().saturating_add(c.len() - 2) > limits::MAX_TRIANGLES {
            return Err(IoError::parse(
                line,
                format!(
                    "more than {} triangles; skelform reads at most that many",
                    limits::MAX_TRIANGLES
                ),
            ));
        }
        for k in 2..c.len() {
            self.triangles.push([c[0].0, c[k - 1].0, c[k].0]);
            self.corner_normals.push([c[0].1, c[k - 1].1, c[k].1]);
            self.corner_uvs.push([c[0].2, c[k - 1].2, c[k].2]);
            self.labels.push(self.face_label);
        }
        Ok(())
    }

    fn polyline<'a>(
        &mut self,
        words: impl Iterator<Item = &'a str>,
        line: usize,
    ) -> Result<(), IoError> {
        self.corners.clear();
        for word in words {
            let mut parts = word.split('/');
            let v = parts.next().unwrap_or_default();
            let v = Self::index(v, self.positions.len(), line, "vertex", &mut self.max_vertex)?;
            if parts.nth(1).is_some() {
                return Err(IoError::parse(
                    line,
                    format!("expected a line vertex v or v/vt, found '{word}'"),
                ));
            }
            self.corners.push((v, NONE, NONE));
        }
        if self.corners.len() < 2 {
            return Err(IoError::parse(
                line,
                format!("a line needs at least 2 vertices, found {}", self.corners.len()),
            ));
        }
        let label = self.curve_label.unwrap_or(RegionTriple([0, 0, 0]));
        for pair in self.corners.windows(2) {
            self.curves.push(CurveEdge { v: [pair[0].0, pair[1].0], label });
        }
        Ok(())
    }

    fn finish(self) -> Result<Mesh, IoError> {
        let n = self.positions.len();
        if let Some((i, line)) = self.max_vertex
            && i as usize >= n
        {
            return Err(IoError::parse(
                line,
                format!("vertex index {} is out of range: the file has {n} vertices", i as u64 + 1),
            ));
        }
        if let Some((i, line)) = self.max_normal
            && i as usize >= self.normals.len()
        {
            return Err(IoError::parse(
                line,
                format!(
                    "normal index {} is out of range: the file has {} normals",
                    i as u64 + 1,
                    self.normals.len()
                ),
            ));
        }
        if let Some((i, line)) = self.max_uv
            && i as usize >= self.texcoords.len()
        {
            return Err(IoError::parse(
                line,
                format!(
                    "texture index {} is out of range: the file has {} texture coordinates",
                    i as u64 + 1,
                    self.texcoords.len()
                ),
            ));
        }
        let normals = per_vertex(n, &self.triangles, &self.corner_normals, &self.normals);
        let uvs = per_vertex(n, &self.triangles, &self.corner_uvs, &self.texcoords);
        let labels = if self.labels.iter().any(Option::is_some) {
            self.labels.into_iter().map(|l| l.unwrap_or(RegionPair(0, 1))).collect()
        } else {
            Vec::new()
        };
        Ok(Mesh {
            positions: self.positions,
            normals,
            triangles: self.triangles,
            labels,
            curves: self.curves,
            colors: Vec::new(),
            uvs,
            texture: None,
        })
    }
}

/// Per-vertex normals (or texture coordinates) from per-corner indices, when they agree (see
/// the module docs).
fn per_vertex<const N: usize>(
    vertices: usize,
    triangles: &[[u32; 3]],
    corners: &[[u32; 3]],
    normals: &[[f32; N]],
) -> Vec<[f32; N]> {
    if corners.is_empty() || corners.iter().flatten().any(|&c| c == NONE) {
        return Vec::new();
    }
    let mut chosen = vec![NONE; vertices];
    for (t, c) in triangles.iter().zip(corners) {
        for k in 0..3 {
            let slot = &mut chosen[t[k] as usize];
            if *slot == NONE {
                *slot = c[k];
            } else if *slot != c[k]
                && normals[*slot as usize].map(f32::to_bits)
                    != normals[c[k] as usize].map(f32::to_bits)
            {
                return Vec::new();
            }
        }
    }
    chosen.iter().map(|&c| if c == NONE { [0.0; N] } else { normals[c as usize] }).collect()
}

/// Reads an OBJ file from `r`.
pub fn read_obj(mut r: impl BufRead) -> Result<Mesh, IoError> {
    let mut reader = Reader::default();
    let mut buf = Vec::new();
    let mut logical = String::new();
    let mut line = 0;
    let mut start = 0;
    loop {
        buf.clear();
        let n =
            r.read_until(b'\n', &mut buf).map_err(|source| IoError::Read { path: None, source })?;
        if n == 0 {
            break;
        }
        line += 1;
        if logical.is_empty() {
            start = line;
        }
        let text = String::from_utf8_lossy(&buf);
        let text = text.trim_end_matches(['\n', '\r']);
        if let Some(head) = text.strip_suffix('\\') {
            logical.push_str(head);
            logical.push(' ');
            continue;
        }
        logical.push_str(text);
        reader.line(&logical, start)?;
        logical.clear();
    }
    if !logical.is_empty() {
        reader.line(&logical, start)?;
    }
    reader.finish()
}

/// Writes `mesh` as OBJ (see the module docs for the layout), without a material library.
pub fn write_obj(w: &mut impl Write, mesh: &Mesh, opts: &WriteOptions) -> Result<(), IoError> {
    write_obj_with_mtl(w, mesh, opts, None)
}

/// Writes `mesh` as OBJ naming the material library `mtl` (a file name beside the OBJ, as
/// [`write_mtl`] writes it): a `mtllib` line and a `usemtl` after each group line. With
/// `None`, the same as [`write_obj`].
pub fn write_obj_with_mtl(
    w: &mut impl Write,
    mesh: &Mesh,
    opts: &WriteOptions,
    mtl: Option<&str>,
) -> Result<(), IoError> {
    mesh.validate().map_err(IoError::invalid)?;
    let mut w = buffered(w);
    write_body(&mut w, mesh, opts, mtl).map_err(IoError::write)?;
    finish(w)
}

/// Whether writing `mesh` to a path comes with a material library: it has labels, or curves
/// that are written.
pub(crate) fn wants_mtl(mesh: &Mesh, opts: &WriteOptions) -> bool {
    !mesh.labels.is_empty() || (opts.curves && !mesh.curves.is_empty())
}

/// The material library that goes with the OBJ file `path`: `OUT.mtl` for `OUT.obj`.
pub fn mtl_path(path: &Path) -> PathBuf {
    super::beside(path, "", Some("mtl"))
}

/// The colour of curves in the material library (near black, so they stand out on the
/// palette's colours).
const CURVE_COLOUR: [u8; 3] = [24, 24, 24];

/// The texture image that goes with the OBJ file `path` when its mesh has a texture:
/// `OUT.texture.png` for `OUT.obj` (not `OUT.png`, which a picture of the mesh may be).
pub fn texture_path(path: &Path) -> PathBuf {
    super::beside(path, "texture", Some("png"))
}

/// Writes the material library of `mesh`: `region_A_B` for each distinct label in sorted
/// order with its palette colour, and `curve` when curves are written.
pub fn write_mtl(w: &mut impl Write, mesh: &Mesh, opts: &WriteOptions) -> Result<(), IoError> {
    write_mtl_with_texture(w, mesh, opts, None)
}

/// [`write_mtl`], with every region's material taking the image `texture` (a file name
/// beside the library) as its diffuse map (`map_Kd`, diffuse colour white), as the glb's
/// base colour texture does.
pub fn write_mtl_with_texture(
    w: &mut impl Write,
    mesh: &Mesh,
    opts: &WriteOptions,
    texture: Option<&str>,
) -> Result<(), IoError> {
    let mut distinct = mesh.labels.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let mut w = buffered(w);
    let mut body = || -> std::io::Result<()> {
        writeln!(w, "# generated by skelform: the colours of the region pairs")?;
        let material = |w: &mut dyn Write, name: &str, c: [u8; 3]| {
            let [r, g, b] = c.map(|v| f64::from(v) / 255.0);
            writeln!(
                w,
                "\nnewmtl {name}\nKd {r:.4} {g:.4} {b:.4}\nKa 0 0 0\nKs 0 0 0\nd 1\nillum 1"
            )
        };
        for (k, l) in distinct.iter().enumerate() {
            match texture {
                Some(file) => {
                    material(&mut w, &format!("region_{l}"), [255; 3])?;
                    writeln!(w, "map_Kd {file}")?;
                }
                None => material(&mut w, &format!("region_{l}"), region_colour(k))?,
            }
        }
        if opts.curves && !mesh.curves.is_empty() {
            material(&mut w, "curve", CURVE_COLOUR)?;
        }
        Ok(())
    };
    body().map_err(IoError::write)?;
    finish(w)
}

fn write_body(
    w: &mut impl Write,
    mesh: &Mesh,
    opts: &WriteOptions,
    mtl: Option<&str>,
) -> std::io::Result<()> {
    let normals = opts.normals && !mesh.normals.is_empty();
    let curves: &[CurveEdge] = if opts.curves { &mesh.curves } else { &[] };
    writeln!(w, "# generated by skelform")?;
    writeln!(
        w,
        "# {} vertices, {} triangles, {} curve segments",
        mesh.positions.len(),
        mesh.triangles.len(),
        curves.len()
    )?;
    if let Some(name) = mtl {
        writeln!(w, "mtllib {name}")?;
    }
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
    }
    if normals {
        for n in &mesh.normals {
            writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
        }
    }
    // One `vt` per vertex, at the vertex's own index.
    let uvs = !mesh.uvs.is_empty();
    for t in &mesh.uvs {
        writeln!(w, "vt {} {}", t[0], t[1])?;
    }
    let face = |w: &mut dyn Write, t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| i as u64 + 1);
        match (normals, uvs) {
            (true, true) => writeln!(w, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}"),
            (true, false) => writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}"),
            (false, true) => writeln!(w, "f {a}/{a} {b}/{b} {c}/{c}"),
            (false, false) => writeln!(w, "f {a} {b} {c}"),
        }
    };
    if mesh.labels.is_empty() {
        for t in &mesh.triangles {
            face(w, t)?;
        }
    } else {
        let mut order: Vec<usize> = (0..mesh.triangles.len()).collect();
        order.sort_by_key(|&i| mesh.labels[i]);
        let mut current = None;
        for i in order {
            let label = mesh.labels[i];
            if current != Some(label) {
                writeln!(w, "g region_{label}")?;
                if mtl.is_some() {
                    writeln!(w, "usemtl region_{label}")?;
                }
                current = Some(label);
            }
            face(w, &mesh.triangles[i])?;
        }
    }
    let mut order: Vec<&CurveEdge> = curves.iter().collect();
    order.sort_by_key(|c| c.label);
    let mut current = None;
    for c in order {
        if current != Some(c.label) {
            writeln!(w, "g curve_{}", c.label)?;
            if mtl.is_some() {
                writeln!(w, "usemtl curve")?;
            }
            current = Some(c.label);
        }
        writeln!(w, "l {} {}", c.v[0] as u64 + 1, c.v[1] as u64 + 1)?;
    }
    Ok(())
}
