//! Binary glTF 2.0 (`.glb`): the format Blender, MeshLab and web viewers open directly.
//!
//! Written: one mesh with one triangle primitive per region pair (one primitive for an
//! unlabelled mesh), each with its own material, and a second mesh of line primitives, one
//! per curve label, when the mesh has curves and `WriteOptions::curves` is on (pymeshlab's
//! reader fails on line primitives: leave them out for it). Every primitive has its own
//! `POSITION` accessor (with the `min` and `max` glTF requires), a `NORMAL` accessor when
//! normals are written (triangles only), a float `COLOR_0` accessor when the mesh has
//! vertex colours (sRGB in [`Mesh::colors`], linear in the file, as glTF defines it; the
//! material's base colour is then white, so the colours show as they are), a float
//! `TEXCOORD_0` accessor when the mesh has texture coordinates ([`Mesh::uvs`], as they
//! are), and 32-bit indices. A mesh with a [`Mesh::texture`] and texture coordinates has
//! it embedded as a PNG (an image in a buffer view, a linear sampler clamped at the edges)
//! and used as every surface material's `baseColorTexture` (`texCoord` 0, base colour
//! factor white); `COLOR_0` is then left out, since glTF multiplies the base colour
//! texture by it (the mesh's vertex colours still go to PLY). A vertex shared by two region
//! pairs is written once for each. Normals are unit length and turned, where needed, to
//! agree with the winding of the primitive's triangles (counter-clockwise from the lesser
//! region, glTF's front face), so viewers light each sheet from its front; meshes without
//! normals get area-weighted ones from the faces. Surface materials are double sided,
//! because the sheets of non-manifold meshes and open surfaces are seen from both sides,
//! and take the shared palette ([`region_colour`], also used by the renderer and the PLY and
//! OBJ writers) in the order of the sorted labels; curves share one near-black material.
//! Labels are kept in each primitive's `extras` (`{"skelform": {"regions": [a, b]}}` and
//! `{"curve": [a, b, c]}`), so skelform reads them back. All little-endian; both chunks
//! padded to 4 bytes (JSON with spaces, BIN with zeros).
//!
//! Read: GLB files with their buffers in the BIN chunk or in base64 `data:` URIs (as
//! Open3D and others write them), float `VEC3` positions, normals and colours and float
//! `VEC2` `TEXCOORD_0` (other colour and texture-coordinate layouts are skipped), the
//! first material's base colour texture when it is a PNG in the file (left out, not
//! refused, when it cannot be decoded or is over [`Texture::MAX_SIDE`] a side, checked
//! from its header before decoding), indices of any
//! unsigned type (or none), triangle and line primitives. The nodes of the default scene
//! are walked (or the root nodes when there is no scene, or every mesh once when there are
//! no nodes), and each node's transform (`matrix`, or `translation`, `rotation`, `scale`),
//! composed down the tree, is applied to its mesh's positions and, by the inverse
//! transpose, to its normals; a mirroring transform reverses the triangles' winding, as
//! glTF's front faces do. A mesh used by two nodes is read twice. Vertices are *not*
//! welded: primitives that share a `POSITION` accessor share vertices, others have their
//! own, as the file stores them, so the region-pair sheets skelform writes stay apart
//! exactly as in the PLY and OBJ of the same mesh (the same components in `check`). Curve
//! vertices are joined to the surface vertex at the same coordinates where there is one.
//! Labels come from the `extras` above when every triangle primitive has them. Everything
//! read is counted against [`limits`] before it is allocated: a file that
//! reuses accessors to expand beyond `MAX_ELEMENTS_PER_BYTE` elements per byte is refused.
//! Sparse accessors, external buffer files, node trees where a node has two parents, and
//! other primitive modes are reported as errors.

use std::io::Write;

use serde_json::{Value, json};

use super::{IoError, WriteOptions, buffered, finish, limits};
use crate::mesh::{CurveEdge, Mesh, RegionPair, RegionTriple, Texture};
use crate::palette::{SURFACE_COLOUR, region_colour};

const MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const MODE_LINES: u32 = 1;
const MODE_TRIANGLES: u32 = 4;
/// The colour of curve lines (sRGB): near black, distinct from every palette colour.
const CURVE_COLOUR: [u8; 3] = [24, 24, 24];

/// An sRGB byte as the linear value glTF's `baseColorFactor` wants.
fn linear(c: u8) -> f64 {
    let s = f64::from(c) / 255.0;
    if s <= 0.04045 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

/// An sRGB component in `[0, 1]` as the linear value glTF's `COLOR_0` holds.
fn srgb_to_linear(c: f32) -> f32 {
    let s = c.clamp(0.0, 1.0);
    if s <= 0.04045 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

/// A linear `COLOR_0` component back to sRGB in `[0, 1]`.
fn linear_to_srgb(c: f32) -> f32 {
    let l = c.clamp(0.0, 1.0);
    if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

/// The binary chunk and the JSON that describes it, built together.
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8], target: u32) -> usize {
        let v = self.raw_view(bytes);
        self.views[v]["target"] = json!(target);
        v
    }

    /// A buffer view without a target (an image's bytes).
    fn raw_view(&mut self, bytes: &[u8]) -> usize {
        debug_assert!(self.bin.len().is_multiple_of(4));
        self.views.push(json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        }));
        self.bin.extend_from_slice(bytes);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.len() - 1
    }

    fn vec3(&mut self, data: &[[f32; 3]], bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        let view = self.view(&bytes, ARRAY_BUFFER);
        let mut a = json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": data.len(),
            "type": "VEC3",
        });
        if bounds {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in data {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            // As f64, the exact values of the f32 components: a reader comparing in either
            // precision finds the same numbers.
            a["min"] = json!(lo.map(f64::from));
            a["max"] = json!(hi.map(f64::from));
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn vec2(&mut self, data: &[[f32; 2]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        let view = self.view(&bytes, ARRAY_BUFFER);
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": data.len(),
            "type": "VEC2",
        }));
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|c| c.to_le_bytes()).collect();
        let view = self.view(&bytes, ELEMENT_ARRAY_BUFFER);
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": UNSIGNED_INT,
            "count": data.len(),
            "type": "SCALAR",
        }));
        self.accessors.len() - 1
    }
}

/// The right-hand normal of a triangle with the length of twice its area.
fn face_normal(mesh: &Mesh, t: [u32; 3]) -> [f64; 3] {
    let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
    let u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
    let v = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

fn unit(n: [f64; 3]) -> Option<[f32; 3]> {
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (l > 0.0 && l.is_finite()).then(|| n.map(|c| (c / l) as f32))
}

/// Renumbers the vertices that `items` use, in order of first use.
fn compact<const N: usize>(items: &[[u32; N]], vertices: usize) -> (Vec<u32>, Vec<u32>) {
    let mut local = vec![u32::MAX; vertices];
    let mut used = Vec::new();
    let mut indices = Vec::with_capacity(items.len() * N);
    for item in items {
        for &v in item {
            let slot = &mut local[v as usize];
            if *slot == u32::MAX {
                *slot = used.len() as u32;
                used.push(v);
            }
            indices.push(*slot);
        }
    }
    (used, indices)
}

/// The whole `.glb` file for `mesh`.
pub fn encode_glb(mesh: &Mesh, opts: &WriteOptions) -> Result<Vec<u8>, IoError> {
    mesh.validate().map_err(IoError::invalid)?;
    if let Some(v) = mesh.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(IoError::unsupported(format!(
            "vertex {v} has a coordinate that is not a finite number, which glTF cannot hold"
        )));
    }
    // Triangles grouped by label, each group in mesh order.
    let groups: Vec<(Option<RegionPair>, Vec<[u32; 3]>)> = if mesh.labels.is_empty() {
        vec![(None, mesh.triangles.clone())]
    } else {
        let mut map = std::collections::BTreeMap::<RegionPair, Vec<[u32; 3]>>::new();
        for (t, l) in mesh.triangles.iter().zip(&mesh.labels) {
            map.entry(*l).or_default().push(*t);
        }
        map.into_iter().map(|(l, t)| (Some(l), t)).collect()
    };
    let groups: Vec<_> = groups.into_iter().filter(|(_, t)| !t.is_empty()).collect();

    let mut b = Builder { bin: Vec::new(), views: Vec::new(), accessors: Vec::new() };
    // A texture with texture coordinates is the surfaces' colour: embedded as PNG, the base
    // colour texture of every surface material; `COLOR_0` is left out, as it would multiply
    // the texture (the vertex colours stay in the mesh for PLY).
    let texture = match &mesh.texture {
        Some(t) if !mesh.uvs.is_empty() => Some(super::texture::encode_png(t)?),
        _ => None,
    };
    let mut materials = Vec::new();
    let mut primitives = Vec::new();
    for (k, (label, tris)) in groups.iter().enumerate() {
        let (used, indices) = compact(tris, mesh.positions.len());
        let positions: Vec<[f32; 3]> =
            used.iter().map(|&v| mesh.positions[v as usize].map(|c| c + 0.0)).collect();
        let mut attributes = json!({ "POSITION": b.vec3(&positions, true) });
        if opts.normals {
            // The group's own area-weighted normals: the fallback, and the side to face.
            let mut local = vec![[0.0f64; 3]; used.len()];
            for t in indices.chunks_exact(3) {
                let n = face_normal(mesh, [0, 1, 2].map(|j| used[t[j] as usize]));
                for &v in t {
                    for c in 0..3 {
                        local[v as usize][c] += n[c];
                    }
                }
            }
            let normals: Vec<[f32; 3]> = used
                .iter()
                .zip(&local)
                .map(|(&v, face)| {
                    let own = mesh.normals.get(v as usize).and_then(|n| unit(n.map(f64::from)));
                    match (own, unit(*face)) {
                        (Some(n), Some(f)) => {
                            let d = n[0] * f[0] + n[1] * f[1] + n[2] * f[2];
                            if d < 0.0 { n.map(|c| -c) } else { n }
                        }
                        (Some(n), None) => n,
                        (None, Some(f)) => f,
                        (None, None) => [0.0, 0.0, 1.0],
                    }
                })
                .collect();
            attributes["NORMAL"] = json!(b.vec3(&normals, false));
        }
        let coloured = !mesh.colors.is_empty() || texture.is_some();
        if !mesh.colors.is_empty() && texture.is_none() {
            let colours: Vec<[f32; 3]> =
                used.iter().map(|&v| mesh.colors[v as usize].map(srgb_to_linear)).collect();
            attributes["COLOR_0"] = json!(b.vec3(&colours, false));
        }
        if !mesh.uvs.is_empty() {
            // glTF's texture space has v down the image: our v (around the section) is
            // written as is, so an image's rows run around the section.
            let uvs: Vec<[f32; 2]> = used.iter().map(|&v| mesh.uvs[v as usize]).collect();
            attributes["TEXCOORD_0"] = json!(b.vec2(&uvs));
        }
        let indices = b.indices(&indices);
        let (name, colour, extras) = match label {
            Some(l) => (
                format!("region {}_{}", l.0, l.1),
                region_colour(k),
                json!({ "skelform": { "regions": [l.0, l.1] } }),
            ),
            None => ("surface".to_string(), SURFACE_COLOUR, json!({})),
        };
        // Vertex colours and textures multiply the base colour: white lets them show as
        // they are.
        let colour = if coloured { [255; 3] } else { colour };
        let mut material = json!({
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [linear(colour[0]), linear(colour[1]), linear(colour[2]), 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.6,
            },
            "doubleSided": true,
        });
        if texture.is_some() {
            material["pbrMetallicRoughness"]["baseColorTexture"] =
                json!({ "index": 0, "texCoord": 0 });
        }
        materials.push(material);
        let mut p = json!({
            "attributes": attributes,
            "indices": indices,
            "material": materials.len() - 1,
            "mode": MODE_TRIANGLES,
        });
        if label.is_some() {
            p["extras"] = extras;
        }
        primitives.push(p);
    }

    let mut curve_primitives = Vec::new();
    if opts.curves && !mesh.curves.is_empty() {
        // One material for every curve: without one, viewers draw lines in their default
        // (three.js: white, invisible on a light background).
        materials.push(json!({
            "name": "curves",
            "pbrMetallicRoughness": {
                "baseColorFactor": [linear(CURVE_COLOUR[0]), linear(CURVE_COLOUR[1]), linear(CURVE_COLOUR[2]), 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            },
        }));
        let curve_material = materials.len() - 1;
        let mut map = std::collections::BTreeMap::<RegionTriple, Vec<[u32; 2]>>::new();
        for c in &mesh.curves {
            map.entry(c.label).or_default().push(c.v);
        }
        for (label, edges) in map {
            let (used, indices) = compact(&edges, mesh.positions.len());
            let positions: Vec<[f32; 3]> =
                used.iter().map(|&v| mesh.positions[v as usize].map(|c| c + 0.0)).collect();
            let pos = b.vec3(&positions, true);
            let ind = b.indices(&indices);
            curve_primitives.push(json!({
                "attributes": { "POSITION": pos },
                "indices": ind,
                "material": curve_material,
                "mode": MODE_LINES,
                "extras": { "skelform": { "curve": label.0 } },
            }));
        }
    }

    let mut doc = json!({
        "asset": { "version": "2.0", "generator": concat!("skelform ", env!("CARGO_PKG_VERSION")) },
    });
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    if !primitives.is_empty() {
        meshes.push(json!({ "name": "surfaces", "primitives": primitives }));
        nodes.push(json!({ "name": "surfaces", "mesh": meshes.len() - 1 }));
    }
    if !curve_primitives.is_empty() {
        meshes.push(json!({ "name": "curves", "primitives": curve_primitives }));
        nodes.push(json!({ "name": "curves", "mesh": meshes.len() - 1 }));
    }
    if !nodes.is_empty() {
        doc["scene"] = json!(0);
        doc["scenes"] = json!([{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }]);
        doc["nodes"] = json!(nodes);
        doc["meshes"] = json!(meshes);
        doc["materials"] = json!(materials);
        if let Some(png) = &texture
            && !primitives.is_empty()
        {
            let view = b.raw_view(png);
            doc["images"] = json!([{ "bufferView": view, "mimeType": "image/png" }]);
            // Linear filtering with mipmaps, clamped at the edges: texture coordinates run
            // from 0 to 1 across the image and never wrap.
            doc["samplers"] = json!([{
                "magFilter": 9729,
                "minFilter": 9987,
                "wrapS": 33071,
                "wrapT": 33071,
            }]);
            doc["textures"] = json!([{ "sampler": 0, "source": 0 }]);
        }
        doc["accessors"] = json!(b.accessors);
        doc["bufferViews"] = json!(b.views);
        doc["buffers"] = json!([{ "byteLength": b.bin.len() }]);
    }
    if materials.is_empty()
        && let Some(d) = doc.as_object_mut()
    {
        d.remove("materials");
    }

    let mut text = serde_json::to_vec(&doc)
        .map_err(|e| IoError::unsupported(format!("cannot serialise the glTF JSON: {e}")))?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let bin_chunk = if b.bin.is_empty() { 0 } else { 8 + b.bin.len() };
    let total = 12 + 8 + text.len() + bin_chunk;
    let total = u32::try_from(total)
        .map_err(|_| IoError::unsupported("the mesh is too large for a .glb file (over 4 GiB)"))?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(&MAGIC.to_le_bytes());
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&text);
    if !b.bin.is_empty() {
        out.extend_from_slice(&(b.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&b.bin);
    }
    Ok(out)
}

/// Writes `mesh` as binary glTF. Nothing is written for an invalid mesh.
pub fn write_glb(w: &mut impl Write, mesh: &Mesh, opts: &WriteOptions) -> Result<(), IoError> {
    let bytes = encode_glb(mesh, opts)?;
    let mut w = buffered(w);
    w.write_all(&bytes).map_err(IoError::write)?;
    finish(w)
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(*bytes.get(at..)?.first_chunk::<4>()?))
}

/// Reads a `.glb` file from its whole contents (see the module documentation for what is
/// accepted).
pub fn read_glb(bytes: &[u8]) -> Result<Mesh, IoError> {
    let len = bytes.len();
    let bad = |at: usize, msg: String| IoError::binary(at as u64, msg);
    let (Some(magic), Some(version), Some(total)) =
        (u32_at(bytes, 0), u32_at(bytes, 4), u32_at(bytes, 8))
    else {
        return Err(bad(len, format!("truncated glTF header: expected 12 bytes, found {len}")));
    };
    if magic != MAGIC {
        return Err(bad(0, "not a binary glTF file: it does not start with 'glTF'".into()));
    }
    if version != 2 {
        return Err(bad(4, format!("glTF version {version}; only version 2 is supported")));
    }
    if total as usize != len {
        return Err(bad(
            8,
            format!("the header gives a length of {total} bytes, the file has {len}"),
        ));
    }
    let (Some(json_len), Some(json_type)) = (u32_at(bytes, 12), u32_at(bytes, 16)) else {
        return Err(bad(len, "truncated glTF file: no JSON chunk".into()));
    };
    if json_type != CHUNK_JSON {
        return Err(bad(16, "the first chunk is not the JSON chunk".into()));
    }
    let json_end =
        20usize.checked_add(json_len as usize).filter(|&e| e <= len).ok_or_else(|| {
            bad(12, format!("the JSON chunk of {json_len} bytes runs past the end of the file"))
        })?;
    let doc: Value = serde_json::from_slice(&bytes[20..json_end])
        .map_err(|e| bad(20, format!("the JSON chunk is not valid JSON: {e}")))?;
    let mut bin: &[u8] = &[];
    let mut at = json_end;
    while at < len {
        let (Some(clen), Some(ctype)) = (u32_at(bytes, at), u32_at(bytes, at + 4)) else {
            return Err(bad(at, "truncated chunk header".into()));
        };
        let end = (at + 8).checked_add(clen as usize).filter(|&e| e <= len).ok_or_else(|| {
            bad(at, format!("a chunk of {clen} bytes runs past the end of the file"))
        })?;
        if ctype == CHUNK_BIN && bin.is_empty() {
            bin = &bytes[at + 8..end];
        }
        at = end;
    }
    let budget = limits::MAX_ELEMENTS_PER_BYTE
        .saturating_mul(len as u64)
        .saturating_add(limits::MIN_ELEMENTS);
    let reader = Reader::new(&doc, bin, budget);
    reader.mesh()
}

fn json_err(msg: String) -> IoError {
    IoError::binary(20, msg)
}

/// Decodes standard base64 (`A–Z a–z 0–9 + /`, `=` padding optional; the URL-safe `-` and
/// `_` are accepted too), or says what is wrong.
fn base64_decode(text: &[u8]) -> Result<Vec<u8>, String> {
    let text = text.strip_suffix(b"==").or_else(|| text.strip_suffix(b"=")).unwrap_or(text);
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for (k, &c) in text.iter().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return Err(format!("character {k} of the base64 data is not base64")),
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 {
        return Err("the base64 data ends in the middle of a byte".into());
    }
    Ok(out)
}

/// A 4×4 matrix, column-major as glTF stores it.
type Matrix = [f64; 16];

const IDENTITY: Matrix = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.];

fn multiply(a: &Matrix, b: &Matrix) -> Matrix {
    std::array::from_fn(|i| {
        let (col, row) = (i / 4, i % 4);
        (0..4).map(|k| a[k * 4 + row] * b[col * 4 + k]).sum()
    })
}

/// The node's local transform: its `matrix`, or `translation · rotation · scale`.
fn local_transform(node: &Value, k: usize) -> Result<Matrix, IoError> {
    let numbers = |key: &str, n: usize| -> Result<Option<Vec<f64>>, IoError> {
        let Some(v) = node.get(key) else { return Ok(None) };
        let got: Option<Vec<f64>> =
            v.as_array().and_then(|a| a.iter().map(Value::as_f64).collect());
        match got {
            Some(g) if g.len() == n && g.iter().all(|x| x.is_finite()) => Ok(Some(g)),
            _ => Err(json_err(format!("node {k}: {key} must be {n} finite numbers"))),
        }
    };
    if let Some(m) = numbers("matrix", 16)? {
        return Ok(std::array::from_fn(|i| m[i]));
    }
    let t = numbers("translation", 3)?.unwrap_or(vec![0.0; 3]);
    let q = numbers("rotation", 4)?.unwrap_or(vec![0.0, 0.0, 0.0, 1.0]);
    let s = numbers("scale", 3)?.unwrap_or(vec![1.0; 3]);
    let n = (q.iter().map(|c| c * c).sum::<f64>()).sqrt();
    if n == 0.0 {
        return Err(json_err(format!("node {k}: the rotation quaternion is zero")));
    }
    let [x, y, z, w] = [q[0] / n, q[1] / n, q[2] / n, q[3] / n];
    // Columns of the rotation, each scaled by its axis's scale.
    let r = [
        [1. - 2. * (y * y + z * z), 2. * (x * y + z * w), 2. * (x * z - y * w)],
        [2. * (x * y - z * w), 1. - 2. * (x * x + z * z), 2. * (y * z + x * w)],
        [2. * (x * z + y * w), 2. * (y * z - x * w), 1. - 2. * (x * x + y * y)],
    ];
    let mut m = IDENTITY;
    for c in 0..3 {
        for row in 0..3 {
            m[c * 4 + row] = r[c][row] * s[c];
        }
        m[12 + c] = t[c];
    }
    Ok(m)
}

/// How one instance of a mesh is placed: the matrix for positions, the one for normals
/// (the cofactor matrix of the upper 3×3, the inverse transpose up to a positive factor)
/// and whether it mirrors (then the winding is reversed to keep the front faces).
struct Placement {
    m: Matrix,
    normal: [[f64; 3]; 3],
    mirrors: bool,
    identity: bool,
}

impl Placement {
    fn new(m: Matrix) -> Self {
        let a = |r: usize, c: usize| m[c * 4 + r];
        let cof = |r: usize, c: usize| {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
            a(r1, c1) * a(r2, c2) - a(r1, c2) * a(r2, c1)
        };
        let det = a(0, 0) * cof(0, 0) + a(0, 1) * cof(0, 1) + a(0, 2) * cof(0, 2);
        let sign = if det < 0.0 { -1.0 } else { 1.0 };
        let normal = std::array::from_fn(|r| std::array::from_fn(|c| sign * cof(r, c)));
        Placement { m, normal, mirrors: det < 0.0, identity: m == IDENTITY }
    }

    fn point(&self, p: [f32; 3]) -> [f32; 3] {
        if self.identity {
            return p;
        }
        let p = p.map(f64::from);
        std::array::from_fn(|r| {
            (self.m[r] * p[0] + self.m[4 + r] * p[1] + self.m[8 + r] * p[2] + self.m[12 + r]) as f32
        })
    }

    fn normal(&self, n: [f32; 3]) -> [f32; 3] {
        if self.identity {
            return n;
        }
        let n = n.map(f64::from);
        let v: [f64; 3] = std::array::from_fn(|r| (0..3).map(|c| self.normal[r][c] * n[c]).sum());
        unit(v).unwrap_or([0.0; 3])
    }
}

/// A line primitive read but not yet joined: its placed positions, indices and label.
type Lines = (Vec<[f32; 3]>, Vec<u32>, [u32; 3]);

struct Reader<'a> {
    doc: &'a Value,
    /// Each buffer's bytes, or why it cannot be used (reported when an accessor needs it).
    buffers: Vec<Result<std::borrow::Cow<'a, [u8]>, String>>,
    /// Vertices and index entries that may still be read (see [`limits`]).
    budget: std::cell::Cell<u64>,
}

impl<'a> Reader<'a> {
    fn new(doc: &'a Value, bin: &'a [u8], budget: u64) -> Self {
        let list = doc.get("buffers").and_then(Value::as_array).map_or(&[][..], |v| v.as_slice());
        let buffers = list
            .iter()
            .enumerate()
            .map(|(i, b)| match b.get("uri") {
                None if i == 0 => Ok(std::borrow::Cow::Borrowed(bin)),
                None => Err(format!("buffer {i} has no uri and is not the BIN chunk")),
                Some(uri) => {
                    let uri = uri.as_str().unwrap_or("");
                    match uri.strip_prefix("data:").and_then(|r| r.split_once(";base64,")) {
                        Some((_, data)) => base64_decode(data.as_bytes())
                            .map(std::borrow::Cow::Owned)
                            .map_err(|e| format!("buffer {i}: {e}")),
                        None => Err(format!(
                            "buffer {i} is an external file ('{}'); only the BIN chunk and \
                             base64 data: URIs are supported",
                            uri.chars().take(60).collect::<String>()
                        )),
                    }
                }
            })
            .collect();
        Reader { doc, buffers, budget: std::cell::Cell::new(budget) }
    }

    fn list(&self, key: &str) -> &'a [Value] {
        self.doc.get(key).and_then(Value::as_array).map_or(&[], |v| v.as_slice())
    }

    fn index(v: Option<&Value>, what: &str) -> Result<Option<usize>, IoError> {
        match v {
            None => Ok(None),
            Some(v) => v
                .as_u64()
                .and_then(|i| usize::try_from(i).ok())
                .map(Some)
                .ok_or_else(|| json_err(format!("{what} must be a whole number"))),
        }
    }

    /// Takes `n` elements from the budget, or refuses the file before they are allocated.
    fn spend(&self, n: usize) -> Result<(), IoError> {
        let left = self.budget.get();
        match left.checked_sub(n as u64) {
            Some(rest) => {
                self.budget.set(rest);
                Ok(())
            }
            None => Err(json_err(format!(
                "the file expands to more vertices and indices than {} per byte of file \
                 (accessors reused by many primitives or nodes); refused before reading them",
                limits::MAX_ELEMENTS_PER_BYTE
            ))),
        }
    }

    /// The bytes of accessor `i` and its element layout: (data, count, stride, component).
    fn accessor(&self, i: usize, want: &str) -> Result<(&[u8], usize, usize, u32), IoError> {
        let a = self
            .list("accessors")
            .get(i)
            .ok_or_else(|| json_err(format!("accessor {i} does not exist")))?;
        if a.get("sparse").is_some() {
            return Err(json_err(format!("accessor {i} is sparse, which is not supported")));
        }
        let ty = a.get("type").and_then(Value::as_str).unwrap_or("");
        if ty != want {
            return Err(json_err(format!("accessor {i} has type '{ty}', expected {want}")));
        }
        let component = a.get("componentType").and_then(Value::as_u64).unwrap_or(0) as u32;
        let size = match component {
            5121 => 1,
            5123 => 2,
            5125 | 5126 => 4,
            other => {
                return Err(json_err(format!(
                    "accessor {i} has unsupported component type {other}"
                )));
            }
        };
        let count = a
            .get("count")
            .and_then(Value::as_u64)
            .and_then(|c| usize::try_from(c).ok())
            .unwrap_or(0);
        let elem = size
            * match want {
                "VEC3" => 3,
                "VEC2" => 2,
                _ => 1,
            };
        let view_i = Self::index(a.get("bufferView"), "bufferView")?
            .ok_or_else(|| json_err(format!("accessor {i} has no buffer view")))?;
        let view = self
            .list("bufferViews")
            .get(view_i)
            .ok_or_else(|| json_err(format!("buffer view {view_i} does not exist")))?;
        let buffer = Self::index(view.get("buffer"), "buffer")?
            .ok_or_else(|| json_err(format!("buffer view {view_i} names no buffer")))?;
        let bytes: &[u8] = match self.buffers.get(buffer) {
            Some(Ok(b)) => b,
            Some(Err(e)) => return Err(json_err(format!("buffer view {view_i}: {e}"))),
            None => return Err(json_err(format!("buffer {buffer} does not exist"))),
        };
        let number = |v: &Value, key: &str| {
            v.get(key).and_then(Value::as_u64).and_then(|x| usize::try_from(x).ok())
        };
        let v_off = number(view, "byteOffset").unwrap_or(0);
        let v_len = number(view, "byteLength").unwrap_or(0);
        let stride = number(view, "byteStride").unwrap_or(elem);
        let a_off = number(a, "byteOffset").unwrap_or(0);
        let data = v_off
            .checked_add(v_len)
            .and_then(|end| bytes.get(v_off..end))
            .ok_or_else(|| json_err(format!("buffer view {view_i} runs past its buffer")))?;
        // An empty accessor still names an offset, which must lie inside its view: the
        // data is sliced from it (fuzzing found `byteOffset: 4294967295` with `count: 0`).
        let needed = if count == 0 {
            Some(a_off)
        } else {
            (count - 1)
                .checked_mul(stride)
                .and_then(|n| n.checked_add(elem))
                .and_then(|n| n.checked_add(a_off))
        };
        if stride < elem || needed.is_none_or(|n| n > data.len()) {
            return Err(json_err(format!("accessor {i} runs past its buffer view")));
        }
        self.spend(count)?;
        Ok((&data[a_off..], count, stride, component))
    }

    fn vec3(&self, i: usize) -> Result<Vec<[f32; 3]>, IoError> {
        self.floats(i, "VEC3")
    }

    fn vec2(&self, i: usize) -> Result<Vec<[f32; 2]>, IoError> {
        self.floats(i, "VEC2")
    }

    /// A float accessor of `N` components per element (`kind` names it: VEC2, VEC3).
    fn floats<const N: usize>(&self, i: usize, kind: &str) -> Result<Vec<[f32; N]>, IoError> {
        let (data, count, stride, component) = self.accessor(i, kind)?;
        if component != FLOAT {
            return Err(json_err(format!("accessor {i}: only float vectors are supported")));
        }
        Ok((0..count)
            .map(|k| {
                std::array::from_fn(|c| {
                    let at = k * stride + 4 * c;
                    f32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]])
                })
            })
            .collect())
    }

    fn scalars(&self, i: usize) -> Result<Vec<u32>, IoError> {
        let (data, count, stride, component) = self.accessor(i, "SCALAR")?;
        Ok((0..count)
            .map(|k| {
                let at = k * stride;
                match component {
                    5121 => u32::from(data[at]),
                    5123 => u32::from(u16::from_le_bytes([data[at], data[at + 1]])),
                    _ => u32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]]),
                }
            })
            .collect())
    }

    /// The meshes to read and where each instance goes: the nodes of the default scene (or
    /// of the first, or the nodes no node has as a child), walked depth first with their
    /// transforms composed; a file without nodes has every mesh once, untransformed.
    fn instances(&self) -> Result<Vec<(usize, Matrix)>, IoError> {
        let nodes = self.list("nodes");
        if nodes.is_empty() {
            return Ok((0..self.list("meshes").len()).map(|m| (m, IDENTITY)).collect());
        }
        let scenes = self.list("scenes");
        let roots: Vec<usize> = if scenes.is_empty() {
            let mut child = vec![false; nodes.len()];
            for n in nodes {
                for c in n.get("children").and_then(Value::as_array).into_iter().flatten() {
                    if let Some(c) = c.as_u64().and_then(|c| usize::try_from(c).ok())
                        && let Some(slot) = child.get_mut(c)
                    {
                        *slot = true;
                    }
                }
            }
            (0..nodes.len()).filter(|&k| !child[k]).collect()
        } else {
            let s = Self::index(self.doc.get("scene"), "scene")?.unwrap_or(0);
            let scene =
                scenes.get(s).ok_or_else(|| json_err(format!("scene {s} does not exist")))?;
            let list = scene.get("nodes").and_then(Value::as_array).map_or(&[][..], |v| v);
            list.iter()
                .map(|v| Self::index(Some(v), "a scene's node"))
                .map(|r| r.map(Option::unwrap_or_default))
                .collect::<Result<_, _>>()?
        };
        let mut seen = vec![false; nodes.len()];
        let mut out = Vec::new();
        let mut stack: Vec<(usize, Matrix)> =
            roots.into_iter().rev().map(|r| (r, IDENTITY)).collect();
        while let Some((k, parent)) = stack.pop() {
            let node = nodes.get(k).ok_or_else(|| json_err(format!("node {k} does not exist")))?;
            if std::mem::replace(&mut seen[k], true) {
                return Err(json_err(format!(
                    "node {k} is reached twice: glTF nodes form trees (a node has one parent)"
                )));
            }
            let world = multiply(&parent, &local_transform(node, k)?);
            if let Some(m) = Self::index(node.get("mesh"), "mesh")? {
                out.push((m, world));
            }
            let children = node.get("children").and_then(Value::as_array).map_or(&[][..], |v| v);
            for c in children.iter().rev() {
                let c = Self::index(Some(c), "a child node")?.unwrap_or_default();
                stack.push((c, world));
            }
        }
        Ok(out)
    }

    /// The base colour texture of the first material that has one, when its image is a
    /// PNG (or anything the PNG decoder takes) in a buffer view or a base64 `data:` URI. A
    /// texture that cannot be read is left out rather than refused, like colours in other
    /// layouts: the surfaces are what the reader is for.
    fn texture(&self) -> Option<Texture> {
        let index = self.list("materials").iter().find_map(|m| {
            m.get("pbrMetallicRoughness")?.get("baseColorTexture")?.get("index")?.as_u64()
        })?;
        let source = self.list("textures").get(usize::try_from(index).ok()?)?.get("source")?;
        let image = self.list("images").get(usize::try_from(source.as_u64()?).ok()?)?;
        let bytes: std::borrow::Cow<'_, [u8]> = if let Some(v) = image.get("bufferView") {
            let view = self.list("bufferViews").get(usize::try_from(v.as_u64()?).ok()?)?;
            let buffer = usize::try_from(view.get("buffer")?.as_u64()?).ok()?;
            let data: &[u8] = self.buffers.get(buffer)?.as_ref().ok()?;
            let off =
                usize::try_from(view.get("byteOffset").map_or(Some(0), Value::as_u64)?).ok()?;
            let len = usize::try_from(view.get("byteLength")?.as_u64()?).ok()?;
            std::borrow::Cow::Borrowed(data.get(off..off.checked_add(len)?)?)
        } else {
            let uri = image.get("uri")?.as_str()?;
            let (_, data) = uri.strip_prefix("data:")?.split_once(";base64,")?;
            std::borrow::Cow::Owned(base64_decode(data.as_bytes()).ok()?)
        };
        super::texture::decode_png(&bytes).ok()
    }

    fn mesh(&self) -> Result<Mesh, IoError> {
        let mut positions: Vec<[f32; 3]> = Vec::new();
        let mut normals: Vec<Option<[f32; 3]>> = Vec::new();
        let mut colours: Vec<Option<[f32; 3]>> = Vec::new();
        let mut uvs: Vec<Option<[f32; 2]>> = Vec::new();
        let mut mesh = Mesh::default();
        let mut labels: Vec<Option<RegionPair>> = Vec::new();
        // Line primitives wait until every triangle is read, to be joined to the surfaces.
        let mut lines: Vec<Lines> = Vec::new();
        let meshes = self.list("meshes");
        for (mi, matrix) in self.instances()? {
            let place = Placement::new(matrix);
            let m = meshes.get(mi).ok_or_else(|| json_err(format!("mesh {mi} does not exist")))?;
            let prims =
                m.get("primitives").and_then(Value::as_array).map_or(&[][..], |v| v.as_slice());
            // Vertices read once per instance and accessor pair: primitives that share a
            // POSITION accessor share vertices, as the file says; others do not.
            let mut shared = std::collections::HashMap::<(usize, [Option<usize>; 3]), u32>::new();
            for (pi, p) in prims.iter().enumerate() {
                let attrs = p.get("attributes");
                let pos_i = Self::index(attrs.and_then(|a| a.get("POSITION")), "POSITION")?
                    .ok_or_else(|| json_err(format!("mesh {mi} primitive {pi} has no POSITION")))?;
                let nrm_i = Self::index(attrs.and_then(|a| a.get("NORMAL")), "NORMAL")?;
                let col_i = Self::index(attrs.and_then(|a| a.get("COLOR_0")), "COLOR_0")?;
                let uv_i = Self::index(attrs.and_then(|a| a.get("TEXCOORD_0")), "TEXCOORD_0")?;
                let mode =
                    p.get("mode").and_then(Value::as_u64).unwrap_or(u64::from(MODE_TRIANGLES));
                if mode != u64::from(MODE_TRIANGLES) && mode != u64::from(MODE_LINES) {
                    return Err(json_err(format!(
                        "mesh {mi} primitive {pi} has mode {mode}; only triangles (4) and \
                         lines (1) are supported"
                    )));
                }
                let extras = p.get("extras").and_then(|e| e.get("skelform"));
                let ids = |key: &str| -> Option<Vec<u32>> {
                    extras?
                        .get(key)?
                        .as_array()?
                        .iter()
                        .map(|v| v.as_u64().and_then(|x| u32::try_from(x).ok()))
                        .collect()
                };
                let pos = self.vec3(pos_i)?;
                let n = pos.len();
                let index = match Self::index(p.get("indices"), "indices")? {
                    Some(i) => self.scalars(i)?,
                    None => (0..u32::try_from(n).unwrap_or(u32::MAX)).collect(),
                };
                if let Some(&bad) = index.iter().find(|&&v| v as usize >= n) {
                    return Err(json_err(format!(
                        "mesh {mi} primitive {pi} uses vertex {bad} of {n}"
                    )));
                }
                if mode == u64::from(MODE_LINES) {
                    if let Some(label) =
                        ids("curve").as_deref().and_then(|r| <[u32; 3]>::try_from(r).ok())
                    {
                        let pos = pos.into_iter().map(|q| place.point(q)).collect();
                        lines.push((pos, index, label));
                    }
                    continue;
                }
                let base = match shared.get(&(pos_i, [nrm_i, col_i, uv_i])) {
                    Some(&b) => b,
                    None => {
                        let prim_normals = match nrm_i {
                            Some(i) => {
                                let v = self.vec3(i)?;
                                if v.len() != n {
                                    return Err(json_err(format!(
                                        "mesh {mi} primitive {pi}: {} normals for {n} positions",
                                        v.len()
                                    )));
                                }
                                Some(v)
                            }
                            None => None,
                        };
                        let base = positions.len();
                        if base.saturating_add(n) > limits::MAX_VERTICES {
                            return Err(json_err(format!(
                                "more than {} vertices; skelform reads at most that many",
                                limits::MAX_VERTICES
                            )));
                        }
                        positions.extend(pos.iter().map(|&q| place.point(q)));
                        match prim_normals {
                            Some(v) => normals.extend(v.into_iter().map(|q| Some(place.normal(q)))),
                            None => normals.resize(positions.len(), None),
                        }
                        // Float RGB colours are read; other layouts (RGBA, normalized
                        // integers) are left out rather than refused.
                        let prim_colours = match col_i {
                            Some(i) => self.vec3(i).ok().filter(|v| v.len() == n),
                            None => None,
                        };
                        match prim_colours {
                            Some(v) => {
                                colours.extend(v.into_iter().map(|c| Some(c.map(linear_to_srgb))))
                            }
                            None => colours.resize(positions.len(), None),
                        }
                        // Float texture coordinates likewise.
                        let prim_uvs = match uv_i {
                            Some(i) => self.vec2(i).ok().filter(|v| v.len() == n),
                            None => None,
                        };
                        match prim_uvs {
                            Some(v) => uvs.extend(v.into_iter().map(Some)),
                            None => uvs.resize(positions.len(), None),
                        }
                        shared.insert((pos_i, [nrm_i, col_i, uv_i]), base as u32);
                        base as u32
                    }
                };
                let label = ids("regions").and_then(|r| match r[..] {
                    [a, b] if a != b => Some(RegionPair::new(a, b)),
                    _ => None,
                });
                if mesh.triangles.len().saturating_add(index.len() / 3) > limits::MAX_TRIANGLES {
                    return Err(json_err(format!(
                        "more than {} triangles; skelform reads at most that many",
                        limits::MAX_TRIANGLES
                    )));
                }
                for t in index.chunks_exact(3) {
                    let mut t = [t[0], t[1], t[2]].map(|v| base + v);
                    if place.mirrors {
                        t.swap(1, 2);
                    }
                    mesh.triangles.push(t);
                    labels.push(label);
                }
            }
        }
        // Curves lie on the surfaces: a curve vertex at the coordinates of a surface vertex
        // is that vertex (the first such one); others are added.
        let mut at = std::collections::HashMap::<[u32; 3], u32>::new();
        if !lines.is_empty() {
            for (k, p) in positions.iter().enumerate().rev() {
                at.insert(p.map(|c| (c + 0.0).to_bits()), k as u32);
            }
        }
        for (pos, index, label) in lines {
            let global: Vec<u32> = pos
                .iter()
                .map(|q| {
                    *at.entry(q.map(|c| (c + 0.0).to_bits())).or_insert_with(|| {
                        positions.push(*q);
                        normals.push(None);
                        colours.push(None);
                        uvs.push(None);
                        (positions.len() - 1) as u32
                    })
                })
                .collect();
            if positions.len() > limits::MAX_VERTICES {
                return Err(json_err(format!(
                    "more than {} vertices; skelform reads at most that many",
                    limits::MAX_VERTICES
                )));
            }
            for e in index.chunks_exact(2) {
                mesh.curves.push(CurveEdge {
                    v: [global[e[0] as usize], global[e[1] as usize]],
                    label: RegionTriple::new(label),
                });
            }
        }
        mesh.positions = positions;
        let with_normals: Vec<bool> = {
            let mut used = vec![false; mesh.positions.len()];
            mesh.triangles.iter().flatten().for_each(|&v| used[v as usize] = true);
            used
        };
        // Normals when every vertex a triangle uses has one; curve-only vertices get zero.
        if !normals.is_empty()
            && normals.iter().zip(&with_normals).all(|(n, &used)| n.is_some() || !used)
            && normals.iter().any(Option::is_some)
        {
            mesh.normals = normals.into_iter().map(|n| n.unwrap_or([0.0; 3])).collect();
        }
        // Colours likewise: when every vertex a triangle uses has one.
        if colours.iter().zip(&with_normals).all(|(c, &used)| c.is_some() || !used)
            && colours.iter().any(Option::is_some)
        {
            mesh.colors = colours.into_iter().map(|c| c.unwrap_or([0.0; 3])).collect();
        }
        if uvs.iter().zip(&with_normals).all(|(c, &used)| c.is_some() || !used)
            && uvs.iter().any(Option::is_some)
        {
            mesh.uvs = uvs.into_iter().map(|c| c.unwrap_or([0.0; 2])).collect();
        }
        if !labels.is_empty() && labels.iter().all(Option::is_some) {
            mesh.labels = labels.into_iter().flatten().collect();
        }
        if !mesh.uvs.is_empty() {
            mesh.texture = self.texture().map(std::sync::Arc::new);
        }
        Ok(mesh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_colours() {
        assert_eq!(linear(0), 0.0);
        assert_eq!(linear(255), 1.0);
        assert!((linear(188) - 0.5).abs() < 0.01);
    }

    /// A tetrahedron split among three region pairs, with normals and a curve: the
    /// synthetic stand-in for the saucer-and-square scene (three surfaces, one curve).
    fn three_pairs() -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [-0.5, 2.0, 0.25],
            ],
            normals: vec![
                [0.0, 0.0, -2.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.0; 3],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [2, 4, 3]],
            labels: vec![
                RegionPair(1, 2),
                RegionPair(1, 3),
                RegionPair(1, 2),
                RegionPair(2, 3),
                RegionPair(1, 2),
            ],
            curves: vec![
                CurveEdge { v: [0, 1], label: RegionTriple([1, 2, 3]) },
                CurveEdge { v: [1, 3], label: RegionTriple([1, 2, 3]) },
            ],
            colors: Vec::new(),
            uvs: Vec::new(),
            texture: None,
        }
    }

    fn chunks(glb: &[u8]) -> (Value, &[u8]) {
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32_at(glb, 4), Some(2));
        assert_eq!(u32_at(glb, 8), Some(glb.len() as u32));
        let jl = u32_at(glb, 12).unwrap() as usize;
        assert_eq!(&glb[16..20], b"JSON");
        assert_eq!(jl % 4, 0);
        let doc: Value = serde_json::from_slice(&glb[20..20 + jl]).unwrap();
        let bl = u32_at(glb, 20 + jl).unwrap() as usize;
        assert_eq!(&glb[24 + jl..28 + jl], b"BIN\0");
        assert_eq!(bl % 4, 0);
        assert_eq!(28 + jl + bl, glb.len());
        (doc, &glb[28 + jl..])
    }

    #[test]
    fn one_primitive_and_material_per_region_pair() {
        let m = three_pairs();
        let glb = encode_glb(&m, &WriteOptions::default()).unwrap();
        let (doc, bin) = chunks(&glb);
        assert_eq!(doc["buffers"][0]["byteLength"].as_u64(), Some(bin.len() as u64));
        let materials = doc["materials"].as_array().unwrap();
        assert_eq!(materials.len(), 4);
        assert_eq!(materials[0]["name"], "region 1_2");
        assert_eq!(materials[2]["name"], "region 2_3");
        assert_eq!(materials[3]["name"], "curves");
        let prims = doc["meshes"][0]["primitives"].as_array().unwrap();
        let counts: Vec<u64> = prims
            .iter()
            .map(|p| {
                doc["accessors"][p["indices"].as_u64().unwrap() as usize]["count"].as_u64().unwrap()
                    / 3
            })
            .collect();
        assert_eq!(counts, vec![3, 1, 1]);
        assert_eq!(prims[1]["extras"]["skelform"]["regions"], json!([1, 3]));
        // Every buffer view lies in the BIN chunk, 4-byte aligned; every accessor in its view.
        for v in doc["bufferViews"].as_array().unwrap() {
            let (off, len) = (v["byteOffset"].as_u64().unwrap(), v["byteLength"].as_u64().unwrap());
            assert_eq!(off % 4, 0);
            assert!(off + len <= bin.len() as u64);
        }
        for a in doc["accessors"].as_array().unwrap() {
            let v = &doc["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
            let per = if a["type"] == "VEC3" { 12 } else { 4 };
            assert_eq!(a["count"].as_u64().unwrap() * per, v["byteLength"].as_u64().unwrap());
        }
        // POSITION min and max are the exact bounds of what is stored.
        let reader = Reader::new(&doc, bin, u64::MAX);
        for p in prims {
            let i = p["attributes"]["POSITION"].as_u64().unwrap() as usize;
            let pos = reader.vec3(i).unwrap();
            for k in 0..3 {
                let lo = pos.iter().map(|q| q[k]).fold(f32::INFINITY, f32::min);
                let hi = pos.iter().map(|q| q[k]).fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(doc["accessors"][i]["min"][k].as_f64(), Some(f64::from(lo)));
                assert_eq!(doc["accessors"][i]["max"][k].as_f64(), Some(f64::from(hi)));
            }
            // Normals are unit length (the zero normal replaced from the faces).
            let n = reader.vec3(p["attributes"]["NORMAL"].as_u64().unwrap() as usize).unwrap();
            assert_eq!(n.len(), pos.len());
            for v in n {
                assert!((v.iter().map(|c| c * c).sum::<f32>() - 1.0).abs() < 1e-5, "{v:?}");
            }
        }
        // The curve is a line primitive with the curves' material.
        let curves = &doc["meshes"][1]["primitives"][0];
        assert_eq!(curves["mode"], 1);
        assert_eq!(curves["material"], 3);
        // Without curves: no line primitive, no curve material.
        let opts = WriteOptions { curves: false, ..WriteOptions::default() };
        let (doc, _) = chunks(&encode_glb(&m, &opts).unwrap());
        assert_eq!(doc["meshes"].as_array().unwrap().len(), 1);
        assert_eq!(doc["materials"].as_array().unwrap().len(), 3);
        assert!(read_glb(&encode_glb(&m, &opts).unwrap()).unwrap().curves.is_empty());
    }

    #[test]
    fn normals_face_the_winding() {
        // Vertex 0's normal points down (−z) but its (1, 2) faces [0, 2, 1] wind towards −z
        // while [0, 3, 2] winds towards −x: the written normal agrees with their sum.
        let m = three_pairs();
        let glb = encode_glb(&m, &WriteOptions::default()).unwrap();
        let (doc, bin) = chunks(&glb);
        let reader = Reader::new(&doc, bin, u64::MAX);
        let p = &doc["meshes"][0]["primitives"][0];
        let n = reader.vec3(p["attributes"]["NORMAL"].as_u64().unwrap() as usize).unwrap();
        assert_eq!(n[0], [0.0, 0.0, -1.0]);
        let mut flipped = m.clone();
        flipped.normals[0] = [0.0, 0.0, 3.0];
        let glb = encode_glb(&flipped, &WriteOptions::default()).unwrap();
        let (doc, bin) = chunks(&glb);
        let n = Reader::new(&doc, bin, u64::MAX)
            .vec3(p["attributes"]["NORMAL"].as_u64().unwrap() as usize)
            .unwrap();
        assert_eq!(n[0], [0.0, 0.0, -1.0]);
    }

    #[test]
    fn round_trip_keeps_triangles_labels_and_curves() {
        let m = three_pairs();
        let back = read_glb(&encode_glb(&m, &WriteOptions::default()).unwrap()).unwrap();
        // Not welded: each region pair's primitive has its own vertices (5 + 3 + 3), and the
        // curve's vertices are the surface vertices at the same places.
        assert_eq!(back.positions.len(), 11);
        for c in &back.curves {
            assert!(back.triangles.iter().flatten().any(|&v| v == c.v[0]));
        }
        assert_eq!(back.label_counts(), m.label_counts());
        assert_eq!(back.curves.len(), 2);
        assert_eq!(back.normals.len(), back.positions.len());
        let corners = |mesh: &Mesh| {
            let mut v: Vec<_> = mesh
                .triangles
                .iter()
                .zip(&mesh.labels)
                .map(|(t, l)| (t.map(|i| mesh.positions[i as usize].map(f32::to_bits)), *l))
                .collect();
            v.sort();
            v
        };
        assert_eq!(corners(&back), corners(&m));
        // Unlabelled, without normals.
        let plain = Mesh { labels: Vec::new(), curves: Vec::new(), ..m.clone() };
        let opts = WriteOptions { normals: false, ..Default::default() };
        let glb = encode_glb(&plain, &opts).unwrap();
        let (doc, _) = chunks(&glb);
        assert_eq!(doc["materials"].as_array().unwrap().len(), 1);
        assert!(doc["meshes"][0]["primitives"][0]["attributes"].get("NORMAL").is_none());
        let back = read_glb(&glb).unwrap();
        assert!(back.labels.is_empty() && back.normals.is_empty());
        assert_eq!(back.triangles.len(), 5);
    }

    #[test]
    fn a_texture_is_embedded_as_the_base_colour_and_read_back() {
        let mut m = three_pairs();
        m.uvs = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]];
        m.colors = vec![[0.5, 0.2, 0.1]; 5];
        let rgba: Vec<u8> = (0..5 * 3 * 4).map(|k| (k * 7 % 256) as u8).collect();
        m.texture = Some(std::sync::Arc::new(Texture { width: 5, height: 3, rgba }));
        let glb = encode_glb(&m, &WriteOptions::default()).unwrap();
        let (doc, bin) = chunks(&glb);
        assert_eq!(doc["images"][0]["mimeType"], "image/png");
        assert_eq!(doc["textures"][0]["source"], 0);
        let view = &doc["bufferViews"][doc["images"][0]["bufferView"].as_u64().unwrap() as usize];
        assert!(view.get("target").is_none());
        let off = view["byteOffset"].as_u64().unwrap() as usize;
        assert_eq!(&bin[off + 1..off + 4], b"PNG");
        // Every surface material takes the texture, white; no COLOR_0 to multiply it.
        for (k, mat) in doc["materials"].as_array().unwrap().iter().enumerate().take(3) {
            let pbr = &mat["pbrMetallicRoughness"];
            assert_eq!(pbr["baseColorTexture"]["index"], 0, "material {k}");
            assert_eq!(pbr["baseColorFactor"], json!([1.0, 1.0, 1.0, 1.0]));
        }
        assert!(doc["materials"][3]["pbrMetallicRoughness"].get("baseColorTexture").is_none());
        for p in doc["meshes"][0]["primitives"].as_array().unwrap() {
            assert!(p["attributes"].get("COLOR_0").is_none());
            assert!(p["attributes"].get("TEXCOORD_0").is_some());
        }
        let back = read_glb(&glb).unwrap();
        assert_eq!(back.texture, m.texture);
        assert!(back.colors.is_empty());
        // Without texture coordinates the texture has nothing to map: not written.
        let bare = Mesh { uvs: Vec::new(), ..m.clone() };
        let (doc, _) = chunks(&encode_glb(&bare, &WriteOptions::default()).unwrap());
        assert!(doc.get("images").is_none());
        assert!(doc["meshes"][0]["primitives"][0]["attributes"].get("COLOR_0").is_some());
        // A texture whose PNG is damaged is left out; the surfaces are still read.
        let mut broken = glb.clone();
        let at = 28 + u32_at(&glb, 12).unwrap() as usize + off + 40;
        for b in &mut broken[at..at + 16] {
            *b ^= 0xFF;
        }
        let back = read_glb(&broken).unwrap();
        assert!(back.texture.is_none());
        assert_eq!(back.triangles.len(), 5);
    }

    #[test]
    fn an_empty_mesh_is_a_valid_empty_file() {
        let glb = encode_glb(&Mesh::default(), &WriteOptions::default()).unwrap();
        assert_eq!(u32_at(&glb, 8), Some(glb.len() as u32));
        let doc: Value = serde_json::from_slice(&glb[20..]).unwrap();
        assert!(doc.get("meshes").is_none() && doc.get("buffers").is_none());
        assert!(read_glb(&glb).unwrap().triangles.is_empty());
    }

    #[test]
    fn bad_meshes_and_bad_files_are_errors() {
        let mut m = three_pairs();
        m.positions[4][0] = f32::NAN;
        assert!(
            encode_glb(&m, &WriteOptions::default()).unwrap_err().to_string().contains("vertex 4")
        );
        let good = encode_glb(&three_pairs(), &WriteOptions::default()).unwrap();
        let e = read_glb(&good[..good.len() - 4]).unwrap_err();
        assert!(e.to_string().contains("length"), "{e}");
        let e = read_glb(b"glTF").unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
        let mut wrong = good.clone();
        wrong[0] = b'x';
        assert!(read_glb(&wrong).unwrap_err().to_string().contains("does not start with"));
        // Every truncation and every flipped byte gives an error or a valid mesh, never a panic.
        for n in 0..good.len() {
            if let Ok(m) = read_glb(&good[..n]) {
                assert!(m.validate().is_ok());
            }
        }
        for k in (0..good.len()).step_by(3) {
            let mut b = good.clone();
            b[k] ^= 0x5A;
            if let Ok(m) = read_glb(&b) {
                assert!(m.validate().is_ok());
            }
        }
    }

    #[test]
    fn compact_numbers_vertices_by_first_use() {
        let (used, idx) = compact(&[[5, 2, 9], [2, 9, 7]], 10);
        assert_eq!(used, vec![5, 2, 9, 7]);
        assert_eq!(idx, vec![0, 1, 2, 1, 2, 3]);
    }
}
