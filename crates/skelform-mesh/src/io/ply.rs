//! Stanford PLY.
//!
//! Written: `format binary_little_endian 1.0` (or `ascii 1.0`); vertex `float x, y, z` and,
//! when normals are written, `float nx, ny, nz`; face `list uchar int vertex_indices` and,
//! for labelled meshes, `int region_a, int region_b` and `uchar red, green, blue` (the
//! pair's palette colour, [`region_colour`] by rank of the sorted labels, as in the glTF
//! writer and the renderer), so MeshLab, Open3D and PyVista show the regions and trimesh and
//! meshio keep the labels as face attributes. Unlabelled meshes have no colours. Curves, as
//! [`PlyCurves`] says: by default in a second file ([`curves_path`], written by
//! [`write_ply_curves`]): `comment skelform curves`, vertex `float x, y, z, int
//! mesh_index` (the vertex's index in the mesh file), `edge` `int vertex1, vertex2` and
//! `curve` `int region_a, region_b, region_c` (one per edge, its label); or inline, in the
//! mesh file, as an `edge` element `int vertex1, vertex2, region_a, region_b, region_c`.
//! The mesh file of the default layout has only `vertex` and `face` elements, which
//! trimesh, meshio and pymeshlab read; the curves file is read by trimesh (as a path) and
//! pymeshlab (as edges), not by meshio, whose PLY reader knows no element but `vertex` and
//! `face`. A mesh with vertex colours ([`Mesh::colors`]) adds `uchar red, green, blue` to
//! its vertices (each `[0, 1]` component times 255, rounded), the layout MeshLab and
//! Open3D read as vertex colours; read back, integer colours are divided by their type's
//! maximum and float ones kept as they are. A mesh with texture coordinates ([`Mesh::uvs`])
//! adds `float u, v` after them (the names trimesh and MeshLab read; `s, t` and
//! `texture_u, texture_v` are read too).
//!
//! Read: `ascii`, `binary_little_endian` and `binary_big_endian`; every scalar type and its
//! sized alias (`char`/`int8` ... `double`/`float64`); extra properties and extra elements
//! (list properties included) are skipped; faces take their corners from a list named
//! `vertex_indices` or `vertex_index` (any count and index type) and polygons are
//! fan-triangulated (a polygon of fewer than 3 corners gives no triangle); normals are read
//! when `nx, ny, nz` are all present, labels when faces have `region_a` and `region_b`
//! (stored as `RegionPair::new(a, b)`), curves from an `edge` element with `vertex1` and
//! `vertex2` (labelled when `region_a, region_b, region_c` are all present, or by a `curve`
//! element of as many labels, otherwise `RegionTriple([0, 0, 0])`). Both layouts are read:
//! [`read_mesh`](super::read_mesh) of a PLY file without curves attaches those of its
//! curves file when there is one ([`attach_curves`]). Header lines may end in CRLF.
//! Truncated data, malformed numbers and out-of-range indices are errors naming the line
//! (ASCII) or byte (binary); so are element counts beyond [`limits`] or, in binary files,
//! beyond what the bytes after the header can hold (checked before reading).

use std::io::{BufRead, Write};

use std::path::{Path, PathBuf};

use super::{IoError, PlyCurves, WriteOptions, buffered, finish, limits};
use crate::mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};
use crate::palette::region_colour;

/// The comment that marks a curves file as skelform's (see [`is_our_curves_file`]).
const CURVES_COMMENT: &str = "comment skelform curves";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    /// The range of an integer type, `None` for floating point.
    fn int_range(self) -> Option<(i64, i64)> {
        Some(match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => return None,
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
    line: usize,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
    line: usize,
}

impl Element {
    fn find(&self, name: &str) -> Option<&Property> {
        self.props.iter().find(|p| p.name == name)
    }

    /// The fewest bytes one instance takes in binary, to bound allocations.
    fn min_binary_size(&self) -> usize {
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => s.size(),
                Kind::List { count, .. } => count.size(),
            })
            .sum()
    }
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Lines in the header, `end_header` included.
    lines: usize,
    /// Bytes in the header, up to and including the newline after `end_header`.
    bytes: usize,
}

fn show(word: Option<&str>) -> String {
    word.map_or_else(|| "nothing".to_string(), |w| format!("'{w}'"))
}

fn read_header(r: &mut impl BufRead) -> Result<Header, IoError> {
    let mut buf = Vec::new();
    let mut line = 0;
    let mut bytes = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        buf.clear();
        let n =
            r.read_until(b'\n', &mut buf).map_err(|source| IoError::Read { path: None, source })?;
        if n == 0 {
            return Err(if line == 0 {
                IoError::parse(1, "empty file: expected a PLY header starting with 'ply'")
            } else {
                IoError::parse(line, "unexpected end of file in the header: expected end_header")
            });
        }
        line += 1;
        bytes += n;
        let Ok(text) = std::str::from_utf8(&buf) else {
            return Err(IoError::parse(
                line,
                if line == 1 {
                    "not a PLY file: expected 'ply' on the first line"
                } else {
                    "the header is not text: expected a header line or end_header"
                },
            ));
        };
        if line == 1 {
            if text.trim() != "ply" {
                return Err(IoError::parse(1, "not a PLY file: expected 'ply' on the first line"));
            }
            continue;
        }
        let mut words = text.split_whitespace();
        let Some(keyword) = words.next() else { continue };
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                if encoding.is_some() {
                    return Err(IoError::parse(line, "a second format line"));
                }
                let e = match words.next() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::LittleEndian,
                    Some("binary_big_endian") => Encoding::BigEndian,
                    other => {
                        return Err(IoError::parse(
                            line,
                            format!(
                                "expected ascii, binary_little_endian or binary_big_endian \
                                 after format, found {}",
                                show(other)
                            ),
                        ));
                    }
                };
                match words.next() {
                    Some(v) if v.starts_with('1') => {}
                    other => {
                        return Err(IoError::parse(
                            line,
                            format!("expected the format version 1.0, found {}", show(other)),
                        ));
                    }
                }
                encoding = Some(e);
            }
            "element" => {
                let Some(name) = words.next() else {
                    return Err(IoError::parse(line, "expected an element name after element"));
                };
                let word = words.next();
                let Some(count) = word.and_then(|w| w.parse::<usize>().ok()) else {
                    return Err(IoError::parse(
                        line,
                        format!("expected the number of '{name}' elements, found {}", show(word)),
                    ));
                };
                elements.push(Element { name: name.to_string(), count, props: Vec::new(), line });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(IoError::parse(line, "a property before any element"));
                };
                let scalar = |word: Option<&str>| {
                    word.and_then(Scalar::parse).ok_or_else(|| {
                        IoError::parse(
                            line,
                            format!(
                                "expected a property type (char, uchar, short, ushort, int, \
                                 uint, float, double or a sized alias), found {}",
                                show(word)
                            ),
                        )
                    })
                };
                let first = words.next();
                let kind = if first == Some("list") {
                    let count = scalar(words.next())?;
                    if count.int_range().is_none() {
                        return Err(IoError::parse(
                            line,
                            format!("a list length must be an integer type, not {}", count.name()),
                        ));
                    }
                    Kind::List { count, item: scalar(words.next())? }
                } else {
                    Kind::Scalar(scalar(first)?)
                };
                let Some(name) = words.next() else {
                    return Err(IoError::parse(line, "expected a property name"));
                };
                element.props.push(Property { name: name.to_string(), kind, line });
            }
            "end_header" => break,
            other => {
                return Err(IoError::parse(
                    line,
                    format!(
                        "unknown header line '{other}': expected format, element, property, \
                         comment, obj_info or end_header"
                    ),
                ));
            }
        }
    }
    let encoding = encoding.ok_or_else(|| IoError::parse(line, "the header has no format line"))?;
    Ok(Header { encoding, elements, lines: line, bytes })
}

/// Why one value could not be read.
enum Fail {
    Eof,
    Syntax(String),
    Range(String),
}

struct AsciiBody<'a> {
    data: &'a [u8],
    pos: usize,
    /// The 1-based line (in the whole file) of the current position.
    line: usize,
}

impl<'a> AsciiBody<'a> {
    fn token(&mut self) -> Option<&'a [u8]> {
        while let Some(&b) = self.data.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self.data.get(self.pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.data[start..self.pos])
    }

    fn value(&mut self, ty: Scalar) -> Result<f64, Fail> {
        let token = self.token().ok_or(Fail::Eof)?;
        let text = || String::from_utf8_lossy(token).into_owned();
        let s = std::str::from_utf8(token).map_err(|_| Fail::Syntax(text()))?;
        match ty.int_range() {
            Some((lo, hi)) => {
                let v: i64 = s.parse().map_err(|_| Fail::Syntax(text()))?;
                if v < lo || v > hi {
                    return Err(Fail::Range(text()));
                }
                Ok(v as f64)
            }
            None if ty == Scalar::F32 => {
                s.parse::<f32>().map(f64::from).map_err(|_| Fail::Syntax(text()))
            }
            None => s.parse::<f64>().map_err(|_| Fail::Syntax(text())),
        }
    }
}

struct BinaryBody<'a> {
    data: &'a [u8],
    pos: usize,
    big: bool,
}

macro_rules! decode {
    ($self:ident, $t:ty) => {{
        let b = $self.take::<{ std::mem::size_of::<$t>() }>()?;
        (if $self.big { <$t>::from_be_bytes(b) } else { <$t>::from_le_bytes(b) }) as f64
    }};
}

impl BinaryBody<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let chunk = self.data.get(self.pos..)?.first_chunk::<N>()?;
        self.pos += N;
        Some(*chunk)
    }

    fn value(&mut self, ty: Scalar) -> Option<f64> {
        Some(match ty {
            Scalar::I8 => decode!(self, i8),
            Scalar::U8 => decode!(self, u8),
            Scalar::I16 => decode!(self, i16),
            Scalar::U16 => decode!(self, u16),
            Scalar::I32 => decode!(self, i32),
            Scalar::U32 => decode!(self, u32),
            Scalar::F32 => decode!(self, f32),
            Scalar::F64 => decode!(self, f64),
        })
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }
}

enum Body<'a> {
    Ascii(AsciiBody<'a>),
    Binary { body: BinaryBody<'a>, base: usize },
}

impl Body<'_> {
    fn value(&mut self, ty: Scalar) -> Result<f64, Fail> {
        match self {
            Body::Ascii(a) => a.value(ty),
            Body::Binary { body, .. } => body.value(ty).ok_or(Fail::Eof),
        }
    }

    /// An error at the current position.
    fn error(&self, msg: String) -> IoError {
        match self {
            Body::Ascii(a) => IoError::parse(a.line, msg),
            Body::Binary { body, base } => IoError::binary((base + body.pos) as u64, msg),
        }
    }

    fn fail(&self, fail: Fail, ty: Scalar, el: &Element, index: usize, prop: &str) -> IoError {
        let ty = ty.name();
        let a = if ty.starts_with('i') { "an" } else { "a" };
        let what = match fail {
            Fail::Eof => {
                format!("unexpected end of file, expected {a} {ty}: the file is truncated")
            }
            Fail::Syntax(t) => format!("expected {a} {ty}, found '{t}'"),
            Fail::Range(t) => format!("{t} is out of range for {a} {ty}"),
        };
        self.error(format!("{} {index} ({prop}): {what}", el.name))
    }

    /// Reads a list length and, for binary data, checks the list fits in what is left.
    fn list_len(
        &mut self,
        count: Scalar,
        item: Scalar,
        el: &Element,
        index: usize,
        prop: &str,
    ) -> Result<usize, IoError> {
        let n = self.value(count).map_err(|f| self.fail(f, count, el, index, prop))?;
        if n < 0.0 {
            return Err(self.error(format!(
                "{} {index} ({prop}): a list length cannot be negative ({n})",
                el.name
            )));
        }
        let n = n as usize;
        if let Body::Binary { body, .. } = self
            && n.saturating_mul(item.size()) > body.remaining()
        {
            return Err(self.error(format!(
                "{} {index} ({prop}): a list of {n} {}s runs past the end of the file: the \
                 file is truncated",
                el.name,
                item.name()
            )));
        }
        Ok(n)
    }

    fn skip_list(&mut self, n: usize, item: Scalar) -> Result<(), Fail> {
        match self {
            Body::Binary { body, .. } => {
                // `list_len` checked that the items fit.
                body.pos += n * item.size();
                Ok(())
            }
            Body::Ascii(_) => {
                for _ in 0..n {
                    self.value(item)?;
                }
                Ok(())
            }
        }
    }

    /// The bytes left, to bound allocations by what the file can hold.
    fn remaining(&self) -> usize {
        match self {
            Body::Ascii(a) => a.data.len().saturating_sub(a.pos),
            Body::Binary { body, .. } => body.remaining(),
        }
    }
}

/// Where a property's value goes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    Skip,
    Slot(usize),
    Indices,
}

const SLOTS: usize = 16;

/// The roles of `el`'s properties for the given slot names (and the index list for faces).
/// Returns the roles and which slots are present.
fn roles(
    el: &Element,
    slots: &[&str],
    want_indices: bool,
) -> Result<(Vec<Role>, [bool; SLOTS]), IoError> {
    let mut present = [false; SLOTS];
    let mut have_indices = false;
    let mut roles = Vec::with_capacity(el.props.len());
    for p in &el.props {
        let role = if let Some(slot) = slots.iter().position(|s| *s == p.name) {
            let Kind::Scalar(_) = p.kind else {
                return Err(IoError::parse(
                    p.line,
                    format!(
                        "property {} of element {} must be a scalar, not a list",
                        p.name, el.name
                    ),
                ));
            };
            if present[slot] {
                Role::Skip
            } else {
                present[slot] = true;
                Role::Slot(slot)
            }
        } else if want_indices
            && !have_indices
            && (p.name == "vertex_indices" || p.name == "vertex_index")
        {
            let Kind::List { .. } = p.kind else {
                return Err(IoError::parse(
                    p.line,
                    format!("property {} of element {} must be a list", p.name, el.name),
                ));
            };
            have_indices = true;
            Role::Indices
        } else {
            Role::Skip
        };
        roles.push(role);
    }
    if want_indices && !have_indices && el.count > 0 {
        return Err(IoError::parse(
            el.line,
            format!("element {} has no vertex_indices list", el.name),
        ));
    }
    Ok((roles, present))
}

/// Reads one instance of `el` into `vals` (by slot) and `poly` (the checked index list).
fn read_instance(
    body: &mut Body,
    el: &Element,
    roles: &[Role],
    index: usize,
    vertices: usize,
    vals: &mut [f64; SLOTS],
    poly: &mut Vec<u32>,
) -> Result<(), IoError> {
    poly.clear();
    for (p, role) in el.props.iter().zip(roles) {
        match p.kind {
            Kind::Scalar(ty) => {
                let v = body.value(ty).map_err(|f| body.fail(f, ty, el, index, &p.name))?;
                if let Role::Slot(s) = *role {
                    vals[s] = v;
                }
            }
            Kind::List { count, item } => {
                let n = body.list_len(count, item, el, index, &p.name)?;
                if *role == Role::Indices {
                    for _ in 0..n {
                        let v =
                            body.value(item).map_err(|f| body.fail(f, item, el, index, &p.name))?;
                        let i = vertex_index(v, vertices).map_err(|msg| {
                            body.error(format!("{} {index} ({}): {msg}", el.name, p.name))
                        })?;
                        poly.push(i);
                    }
                } else {
                    body.skip_list(n, item).map_err(|f| body.fail(f, item, el, index, &p.name))?;
                }
            }
        }
    }
    Ok(())
}

fn vertex_index(v: f64, vertices: usize) -> Result<u32, String> {
    if v.fract() != 0.0 || v < 0.0 {
        return Err(format!("expected a vertex index, found {v}"));
    }
    if v >= vertices as f64 {
        return Err(format!("vertex index {v} is out of range: the file has {vertices} vertices"));
    }
    Ok(v as u32)
}

fn region(v: f64) -> Result<u32, String> {
    if v.fract() != 0.0 || v < 0.0 || v > f64::from(u32::MAX) {
        return Err(format!("expected a region id (a non-negative integer), found {v}"));
    }
    Ok(v as u32)
}

/// What a PLY file holds: the mesh, and for a curves file the `mesh_index` of each vertex.
struct Contents {
    mesh: Mesh,
    mesh_index: Option<Vec<u32>>,
}

/// Refuses an element whose declared count is beyond [`limits`], before anything is
/// allocated or read for it. (Counts the rest of the file cannot hold are refused by
/// reading: allocations are bounded by the bytes left, and the first missing value is
/// reported where it should be.)
fn check_count(el: &Element) -> Result<(), IoError> {
    let cap = match el.name.as_str() {
        "vertex" => limits::MAX_VERTICES,
        "face" => limits::MAX_TRIANGLES,
        _ => usize::MAX,
    };
    if el.count > cap {
        return Err(IoError::parse(
            el.line,
            format!(
                "the header declares {} '{}' elements; skelform reads at most {cap}",
                el.count, el.name
            ),
        ));
    }
    Ok(())
}

fn read_body(header: &Header, body: &mut Body) -> Result<Contents, IoError> {
    let vertices = header.elements.iter().find(|e| e.name == "vertex").map_or(0, |e| e.count);
    let mut mesh = Mesh::default();
    let mut mesh_index = None;
    let (mut seen_vertex, mut seen_face, mut seen_edge, mut seen_curve) =
        (false, false, false, false);
    let mut vals = [0.0; SLOTS];
    let mut poly = Vec::new();
    for el in &header.elements {
        if !el.props.is_empty() {
            check_count(el)?;
        }
        // An upper bound on the instances the rest of the file can hold.
        let min_size = match body {
            Body::Ascii(_) => 2 * el.props.len(),
            Body::Binary { .. } => el.min_binary_size(),
        };
        let capacity = el.count.min(body.remaining() / min_size.max(1));
        let fail =
            |body: &Body, i: usize, msg: String| body.error(format!("{} {i}: {msg}", el.name));
        if el.name == "vertex" && !seen_vertex {
            seen_vertex = true;
            let (roles, has) = roles(
                el,
                &[
                    "x",
                    "y",
                    "z",
                    "nx",
                    "ny",
                    "nz",
                    "mesh_index",
                    "red",
                    "green",
                    "blue",
                    "u",
                    "v",
                    "s",
                    "t",
                    "texture_u",
                    "texture_v",
                ],
                false,
            )?;
            if let Some(missing) = ["x", "y", "z"].iter().zip(has).find(|(_, h)| !h) {
                return Err(IoError::parse(
                    el.line,
                    format!("element vertex has no property {}", missing.0),
                ));
            }
            let normals = has[3] && has[4] && has[5];
            // Integer colours are 0..=max of their type (255 for uchar); floats are 0..1.
            let colours = (has[7] && has[8] && has[9]).then(|| {
                ["red", "green", "blue"].map(|n| match el.find(n).map(|p| p.kind) {
                    Some(Kind::Scalar(t)) => t.int_range().map_or(1.0, |(_, hi)| hi as f64),
                    _ => 1.0,
                })
            });
            mesh.positions.reserve(capacity);
            if normals {
                mesh.normals.reserve(capacity);
            }
            if colours.is_some() {
                mesh.colors.reserve(capacity);
            }
            // The first complete pair of texture-coordinate names.
            let uv = [10, 12, 14].into_iter().find(|&k| has[k] && has[k + 1]);
            if uv.is_some() {
                mesh.uvs.reserve(capacity);
            }
            let mut index = has[6].then(|| Vec::with_capacity(capacity));
            for i in 0..el.count {
                read_instance(body, el, &roles, i, vertices, &mut vals, &mut poly)?;
                mesh.positions.push([vals[0] as f32, vals[1] as f32, vals[2] as f32]);
                if normals {
                    mesh.normals.push([vals[3] as f32, vals[4] as f32, vals[5] as f32]);
                }
                if let Some(scale) = colours {
                    mesh.colors.push([0, 1, 2].map(|k| (vals[7 + k] / scale[k]) as f32));
                }
                if let Some(k) = uv {
                    mesh.uvs.push([vals[k] as f32, vals[k + 1] as f32]);
                }
                if let Some(index) = &mut index {
                    index.push(region(vals[6]).map_err(|_| {
                        fail(body, i, format!("expected a mesh_index, found {}", vals[6]))
                    })?);
                }
            }
            mesh_index = index;
        } else if el.name == "face" && !seen_face {
            seen_face = true;
            let (roles, has) = roles(el, &["region_a", "region_b"], true)?;
            let labelled = has[0] && has[1];
            mesh.triangles.reserve(capacity);
            for i in 0..el.count {
                read_instance(body, el, &roles, i, vertices, &mut vals, &mut poly)?;
                let label = if labelled {
                    let a = region(vals[0]).map_err(|m| fail(body, i, m))?;
                    let b = region(vals[1]).map_err(|m| fail(body, i, m))?;
                    Some(RegionPair::new(a, b))
                } else {
                    None
                };
                if mesh.triangles.len().saturating_add(poly.len()) > limits::MAX_TRIANGLES {
                    return Err(fail(
                        body,
                        i,
                        format!(
                            "more than {} triangles; skelform reads at most that many",
                            limits::MAX_TRIANGLES
                        ),
                    ));
                }
                for k in 2..poly.len() {
                    mesh.triangles.push([poly[0], poly[k - 1], poly[k]]);
                    mesh.labels.extend(label);
                }
            }
        } else if el.name == "edge"
            && !seen_edge
            && el.find("vertex1").is_some()
            && el.find("vertex2").is_some()
        {
            seen_edge = true;
            let slots = ["vertex1", "vertex2", "region_a", "region_b", "region_c"];
            let (roles, has) = roles(el, &slots, false)?;
            let labelled = has[2] && has[3] && has[4];
            mesh.curves.reserve(capacity);
            for i in 0..el.count {
                read_instance(body, el, &roles, i, vertices, &mut vals, &mut poly)?;
                let a = vertex_index(vals[0], vertices).map_err(|m| fail(body, i, m))?;
                let b = vertex_index(vals[1], vertices).map_err(|m| fail(body, i, m))?;
                let mut label = [0; 3];
                if labelled {
                    for (l, v) in label.iter_mut().zip(&vals[2..5]) {
                        *l = region(*v).map_err(|m| fail(body, i, m))?;
                    }
                }
                mesh.curves.push(CurveEdge { v: [a, b], label: RegionTriple::new(label) });
            }
        } else if el.name == "curve"
            && seen_edge
            && !seen_curve
            && ["region_a", "region_b", "region_c"].iter().all(|p| el.find(p).is_some())
        {
            // The labels of the edges before, one per edge (the curves file's layout).
            seen_curve = true;
            if el.count != mesh.curves.len() {
                return Err(IoError::parse(
                    el.line,
                    format!(
                        "{} curve labels for {} edges: expected one label per edge",
                        el.count,
                        mesh.curves.len()
                    ),
                ));
            }
            let (roles, _) = roles(el, &["region_a", "region_b", "region_c"], false)?;
            for i in 0..el.count {
                read_instance(body, el, &roles, i, vertices, &mut vals, &mut poly)?;
                let mut label = [0; 3];
                for (l, v) in label.iter_mut().zip(&vals[0..3]) {
                    *l = region(*v).map_err(|m| fail(body, i, m))?;
                }
                mesh.curves[i].label = RegionTriple::new(label);
            }
        } else if !el.props.is_empty() {
            // (An element without properties holds no data, whatever its count.)
            let roles = vec![Role::Skip; el.props.len()];
            for i in 0..el.count {
                read_instance(body, el, &roles, i, vertices, &mut vals, &mut poly)?;
            }
        }
    }
    if let Body::Ascii(a) = body
        && a.token().is_some()
    {
        return Err(body.error("unexpected data after the last element".to_string()));
    }
    Ok(Contents { mesh, mesh_index })
}

fn read_contents(mut r: impl BufRead) -> Result<Contents, IoError> {
    let header = read_header(&mut r)?;
    let mut data = Vec::new();
    r.read_to_end(&mut data).map_err(|source| IoError::Read { path: None, source })?;
    let mut body = match header.encoding {
        Encoding::Ascii => Body::Ascii(AsciiBody { data: &data, pos: 0, line: header.lines + 1 }),
        e => Body::Binary {
            body: BinaryBody { data: &data, pos: 0, big: e == Encoding::BigEndian },
            base: header.bytes,
        },
    };
    read_body(&header, &mut body)
}

/// The curves file that goes with the PLY file `path`: `OUT.curves.ply` for `OUT.ply`
/// (the extension kept as given).
pub fn curves_path(path: &Path) -> PathBuf {
    super::beside(path, "curves", None)
}

/// Whether `path` is a curves file skelform wrote (its header's comment says so), so that
/// writing a mesh without one may remove it.
pub(crate) fn is_our_curves_file(path: &Path) -> bool {
    let Ok(f) = std::fs::File::open(path) else { return false };
    let mut head = Vec::new();
    use std::io::Read;
    if f.take(256).read_to_end(&mut head).is_err() {
        return false;
    }
    head.starts_with(b"ply\n")
        && head.windows(CURVES_COMMENT.len()).any(|w| w == CURVES_COMMENT.as_bytes())
}

/// Adds the curves of a curves file (the [`PlyCurves::Separate`] layout) to `mesh`. Vertices
/// with a `mesh_index` are the mesh's own vertices and must have the same coordinates
/// there (bit for bit): otherwise the file belongs to another mesh and is refused. A curves
/// file without `mesh_index` (another program's) adds its vertices to the mesh, with zero
/// normals when the mesh has normals.
pub fn attach_curves(mesh: &mut Mesh, r: impl BufRead) -> Result<(), IoError> {
    let Contents { mesh: curves, mesh_index } = read_contents(r)?;
    let map: Vec<u32> = match mesh_index {
        Some(index) => {
            for (k, (&i, p)) in index.iter().zip(&curves.positions).enumerate() {
                let same = mesh
                    .positions
                    .get(i as usize)
                    .is_some_and(|q| q.map(f32::to_bits) == p.map(f32::to_bits));
                if !same {
                    return Err(IoError::parse(
                        1,
                        format!(
                            "curve vertex {k} is not vertex {i} of the mesh: this curves file \
                             belongs to another mesh (remove it, or write the mesh again)"
                        ),
                    ));
                }
            }
            index
        }
        None => {
            let base = mesh.positions.len();
            let total =
                base.checked_add(curves.positions.len()).filter(|&n| n <= limits::MAX_VERTICES);
            if total.is_none() {
                return Err(IoError::parse(1, "too many vertices with the curves file's"));
            }
            mesh.positions.extend_from_slice(&curves.positions);
            if !mesh.normals.is_empty() {
                mesh.normals.resize(mesh.positions.len(), [0.0; 3]);
            }
            if !mesh.colors.is_empty() {
                mesh.colors.resize(mesh.positions.len(), [0.0; 3]);
            }
            if !mesh.uvs.is_empty() {
                mesh.uvs.resize(mesh.positions.len(), [0.0; 2]);
            }
            (0..curves.positions.len()).map(|k| (base + k) as u32).collect()
        }
    };
    mesh.curves.extend(
        curves.curves.iter().map(|c| CurveEdge { v: c.v.map(|v| map[v as usize]), label: c.label }),
    );
    Ok(())
}

/// Reads a PLY file (ASCII or binary of either byte order) from `r`.
pub fn read_ply(r: impl BufRead) -> Result<Mesh, IoError> {
    read_contents(r).map(|c| c.mesh)
}

/// Writes `mesh` as PLY: binary little-endian, or ASCII when `opts.ascii`; normals when the
/// mesh has them and `opts.normals`; curves inline only with [`PlyCurves::Inline`] (the
/// default, [`PlyCurves::Separate`], leaves them to [`write_ply_curves`]).
pub fn write_ply(w: &mut impl Write, mesh: &Mesh, opts: &WriteOptions) -> Result<(), IoError> {
    check_writable(mesh)?;
    let mut w = buffered(w);
    write_body(&mut w, mesh, opts, PIECE_BYTES).map_err(IoError::write)?;
    finish(w)
}

/// Writes the curves file of `mesh` (the [`PlyCurves::Separate`] layout, see the module
/// documentation): the vertices the curves use, each with its `mesh_index`, the segments
/// as an `edge` element and their labels as a `curve` element. ASCII when `opts.ascii`.
pub fn write_ply_curves(
    w: &mut impl Write,
    mesh: &Mesh,
    opts: &WriteOptions,
) -> Result<(), IoError> {
    check_writable(mesh)?;
    let mut w = buffered(w);
    write_curves(&mut w, mesh, opts).map_err(IoError::write)?;
    finish(w)
}

fn check_writable(mesh: &Mesh) -> Result<(), IoError> {
    mesh.validate().map_err(IoError::invalid)?;
    let int_max = i32::MAX as usize;
    if mesh.positions.len() > int_max {
        return Err(IoError::unsupported(format!(
            "{} vertices do not fit PLY int indices",
            mesh.positions.len()
        )));
    }
    let regions = mesh
        .labels
        .iter()
        .flat_map(|l| [l.0, l.1])
        .chain(mesh.curves.iter().flat_map(|c| c.label.0));
    if let Some(r) = regions.into_iter().find(|&r| r as usize > int_max) {
        return Err(IoError::unsupported(format!("region id {r} does not fit a PLY int")));
    }
    Ok(())
}

/// The palette colour of each triangle's label: the rank of the label among the mesh's
/// distinct labels, sorted, picks the colour (as in the glTF writer).
fn face_colours(mesh: &Mesh) -> Vec<[u8; 3]> {
    let mut distinct = mesh.labels.clone();
    distinct.sort_unstable();
    distinct.dedup();
    mesh.labels
        .iter()
        .map(|l| region_colour(distinct.binary_search(l).unwrap_or_default()))
        .collect()
}

/// A colour in `[0, 1]` as PLY's `uchar` (clamped, rounded).
fn colour_byte(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The whole file; a binary body in pieces of about `piece_bytes` (see [`write_binary_body`]).
fn write_body(
    w: &mut impl Write,
    mesh: &Mesh,
    opts: &WriteOptions,
    piece_bytes: usize,
) -> std::io::Result<()> {
    let normals = opts.normals && !mesh.normals.is_empty();
    let vertex_colours = !mesh.colors.is_empty();
    let uvs = !mesh.uvs.is_empty();
    let labelled = !mesh.labels.is_empty();
    let colours = if labelled { face_colours(mesh) } else { Vec::new() };
    let curves = opts.effective_ply_curves() == PlyCurves::Inline && !mesh.curves.is_empty();
    let format = if opts.ascii { "ascii" } else { "binary_little_endian" };
    writeln!(w, "ply\nformat {format} 1.0\ncomment generated by skelform")?;
    writeln!(w, "element vertex {}", mesh.positions.len())?;
    writeln!(w, "property float x\nproperty float y\nproperty float z")?;
    if normals {
        writeln!(w, "property float nx\nproperty float ny\nproperty float nz")?;
    }
    if vertex_colours {
        writeln!(w, "property uchar red\nproperty uchar green\nproperty uchar blue")?;
    }
    if uvs {
        writeln!(w, "property float u\nproperty float v")?;
    }
    writeln!(w, "element face {}", mesh.triangles.len())?;
    writeln!(w, "property list uchar int vertex_indices")?;
    if labelled {
        writeln!(w, "property int region_a\nproperty int region_b")?;
        writeln!(w, "property uchar red\nproperty uchar green\nproperty uchar blue")?;
    }
    if curves {
        writeln!(w, "element edge {}", mesh.curves.len())?;
        writeln!(w, "property int vertex1\nproperty int vertex2")?;
        writeln!(w, "property int region_a\nproperty int region_b\nproperty int region_c")?;
    }
    writeln!(w, "end_header")?;

    if opts.ascii {
        for (i, p) in mesh.positions.iter().enumerate() {
            write!(w, "{} {} {}", p[0], p[1], p[2])?;
            if normals {
                let n = mesh.normals[i];
                write!(w, " {} {} {}", n[0], n[1], n[2])?;
            }
            if vertex_colours {
                let [r, g, b] = mesh.colors[i].map(colour_byte);
                write!(w, " {r} {g} {b}")?;
            }
            if uvs {
                write!(w, " {} {}", mesh.uvs[i][0], mesh.uvs[i][1])?;
            }
            writeln!(w)?;
        }
        for (i, t) in mesh.triangles.iter().enumerate() {
            write!(w, "3 {} {} {}", t[0], t[1], t[2])?;
            if labelled {
                let (l, [r, g, b]) = (mesh.labels[i], colours[i]);
                write!(w, " {} {} {r} {g} {b}", l.0, l.1)?;
            }
            writeln!(w)?;
        }
        if curves {
            for c in &mesh.curves {
                let [a, b, r] = c.label.0;
                writeln!(w, "{} {} {a} {b} {r}", c.v[0], c.v[1])?;
            }
        }
    } else {
        let body = Encoder {
            mesh,
            normals,
            vertex_colours,
            uvs,
            face_colours: &colours,
            inline_curves: curves,
        };
        write_binary_body(w, &body, piece_bytes)?;
    }
    Ok(())
}

/// Bytes of binary body encoded at a time: a piece is one `write` call, big enough that the
/// calls cost nothing next to the copying, small enough to stay in the cache and that the
/// two pieces in flight cost little memory.
const PIECE_BYTES: usize = 1 << 20;

/// The binary body of a mesh file: records of fixed size (vertices, then faces, then the
/// inline curve edges), so that any run of records can be encoded on its own, on any thread,
/// into its own stretch of bytes, and the file is the same however the runs are cut.
struct Encoder<'a> {
    mesh: &'a Mesh,
    normals: bool,
    vertex_colours: bool,
    uvs: bool,
    /// Each triangle's palette colour; empty for an unlabelled mesh.
    face_colours: &'a [[u8; 3]],
    inline_curves: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Section {
    Vertices,
    Faces,
    Edges,
}

/// `count` records of a section from record `first` on.
#[derive(Clone, Copy, Debug)]
struct Piece {
    section: Section,
    first: usize,
    count: usize,
}

/// Fills a record field by field.
struct Put<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Put<'_> {
    fn bytes<const N: usize>(&mut self, b: [u8; N]) {
        self.out[self.at..self.at + N].copy_from_slice(&b);
        self.at += N;
    }

    fn f32s<const N: usize>(&mut self, v: &[f32; N]) {
        v.iter().for_each(|c| self.bytes(c.to_le_bytes()));
    }

    /// Indices and labels as PLY `int`: the same four bytes as the `u32`.
    fn ints<const N: usize>(&mut self, v: &[u32; N]) {
        v.iter().for_each(|&c| self.bytes((c as i32).to_le_bytes()));
    }
}

impl Encoder<'_> {
    fn record_size(&self, section: Section) -> usize {
        match section {
            Section::Vertices => {
                12 + if self.normals { 12 } else { 0 }
                    + if self.vertex_colours { 3 } else { 0 }
                    + if self.uvs { 8 } else { 0 }
            }
            Section::Faces => 13 + if self.face_colours.is_empty() { 0 } else { 11 },
            Section::Edges => 20,
        }
    }

    fn count(&self, section: Section) -> usize {
        match section {
            Section::Vertices => self.mesh.positions.len(),
            Section::Faces => self.mesh.triangles.len(),
            Section::Edges if self.inline_curves => self.mesh.curves.len(),
            Section::Edges => 0,
        }
    }

    /// The body cut into pieces of about `piece_bytes` (whole records, at least one each).
    fn pieces(&self, piece_bytes: usize) -> Vec<Piece> {
        let mut pieces = Vec::new();
        for section in [Section::Vertices, Section::Faces, Section::Edges] {
            let (count, per) =
                (self.count(section), (piece_bytes / self.record_size(section)).max(1));
            pieces.extend((0..count).step_by(per).map(|first| Piece {
                section,
                first,
                count: per.min(count - first),
            }));
        }
        pieces
    }

    /// Encodes `piece` into `out`, exactly its records' bytes long.
    fn encode(&self, piece: Piece, out: &mut [u8]) {
        let m = self.mesh;
        let size = self.record_size(piece.section);
        debug_assert_eq!(out.len(), piece.count * size);
        let records = out.chunks_exact_mut(size).zip(piece.first..);
        match piece.section {
            Section::Vertices => {
                for (out, i) in records {
                    let mut put = Put { out, at: 0 };
                    put.f32s(&m.positions[i]);
                    if self.normals {
                        put.f32s(&m.normals[i]);
                    }
                    if self.vertex_colours {
                        put.bytes(m.colors[i].map(colour_byte));
                    }
                    if self.uvs {
                        put.f32s(&m.uvs[i]);
                    }
                }
            }
            Section::Faces => {
                for (out, i) in records {
                    let mut put = Put { out, at: 0 };
                    put.bytes([3]);
                    put.ints(&m.triangles[i]);
                    if let Some(&colour) = self.face_colours.get(i) {
                        let l = m.labels[i];
                        put.ints(&[l.0, l.1]);
                        put.bytes(colour);
                    }
                }
            }
            Section::Edges => {
                for (out, i) in records {
                    let c = &m.curves[i];
                    let mut put = Put { out, at: 0 };
                    put.ints(&c.v);
                    put.ints(&c.label.0);
                }
            }
        }
    }
}

/// Writes the binary body to `w` piece by piece. A body of four pieces or more is encoded
/// on a helper thread, a piece ahead of the writing, so that the encoding hides behind the
/// copying of the previous piece into the file (the bigger cost); two buffers go back and
/// forth. The bytes are the same as encoding on one thread: each piece is encoded on its
/// own and written in order. Without a thread (none can be started) it encodes in line.
fn write_binary_body(
    w: &mut impl Write,
    body: &Encoder,
    piece_bytes: usize,
) -> std::io::Result<()> {
    let pieces = body.pieces(piece_bytes);
    let fill = |buf: &mut Vec<u8>, piece: Piece| {
        buf.resize(piece.count * body.record_size(piece.section), 0);
        body.encode(piece, buf);
    };
    let in_line = |w: &mut dyn Write| -> std::io::Result<()> {
        let mut buf = Vec::new();
        for &piece in &pieces {
            fill(&mut buf, piece);
            w.write_all(&buf)?;
        }
        Ok(())
    };
    // A thread is worth starting (tens of microseconds, more on a loaded machine) for a
    // body of several pieces; a smaller one encodes in well under a millisecond.
    if pieces.len() < 4 {
        return in_line(w);
    }
    std::thread::scope(|s| {
        use std::sync::mpsc;
        // Encoded pieces to the writer (one waiting at most), and emptied buffers back.
        let (full_tx, full_rx) = mpsc::sync_channel::<Vec<u8>>(1);
        let (empty_tx, empty_rx) = mpsc::channel::<Vec<u8>>();
        let encoder = std::thread::Builder::new().name("ply-encode".into()).spawn_scoped(s, {
            let pieces = &pieces;
            move || {
                let mut spare = Some(Vec::new());
                for &piece in pieces {
                    // The writer gives a buffer back after each piece; it stops taking them
                    // only when it has failed, and then this thread stops too.
                    let Some(mut buf) = spare.take().or_else(|| empty_rx.recv().ok()) else {
                        return;
                    };
                    fill(&mut buf, piece);
                    if full_tx.send(buf).is_err() {
                        return;
                    }
                }
            }
        });
        if encoder.is_err() {
            return in_line(w);
        }
        for _ in 0..pieces.len() {
            // Only a panic of the encoder (which the scope then raises) ends the pieces early.
            let buf = full_rx.recv().map_err(|_| std::io::Error::other("the encoder stopped"))?;
            w.write_all(&buf)?;
            let _ = empty_tx.send(buf);
        }
        Ok(())
    })
}

fn write_curves(w: &mut impl Write, mesh: &Mesh, opts: &WriteOptions) -> std::io::Result<()> {
    // The vertices the curves use, in order of first use, and the segments renumbered.
    let mut local = std::collections::HashMap::new();
    let mut used: Vec<u32> = Vec::new();
    let edges: Vec<[u32; 2]> = mesh
        .curves
        .iter()
        .map(|c| {
            c.v.map(|v| {
                *local.entry(v).or_insert_with(|| {
                    used.push(v);
                    (used.len() - 1) as u32
                })
            })
        })
        .collect();
    let format = if opts.ascii { "ascii" } else { "binary_little_endian" };
    writeln!(w, "ply\nformat {format} 1.0\n{CURVES_COMMENT}")?;
    writeln!(w, "comment mesh_index: the vertex's index in the mesh file beside this one")?;
    writeln!(w, "element vertex {}", used.len())?;
    writeln!(w, "property float x\nproperty float y\nproperty float z\nproperty int mesh_index")?;
    writeln!(w, "element edge {}", edges.len())?;
    writeln!(w, "property int vertex1\nproperty int vertex2")?;
    writeln!(w, "element curve {}", edges.len())?;
    writeln!(w, "property int region_a\nproperty int region_b\nproperty int region_c")?;
    writeln!(w, "end_header")?;
    if opts.ascii {
        for &v in &used {
            let p = mesh.positions[v as usize];
            writeln!(w, "{} {} {} {v}", p[0], p[1], p[2])?;
        }
        for e in &edges {
            writeln!(w, "{} {}", e[0], e[1])?;
        }
        for c in &mesh.curves {
            let [a, b, r] = c.label.0;
            writeln!(w, "{a} {b} {r}")?;
        }
    } else {
        let mut buf = Vec::with_capacity(16);
        for &v in &used {
            buf.clear();
            mesh.positions[v as usize].iter().for_each(|c| buf.extend_from_slice(&c.to_le_bytes()));
            buf.extend_from_slice(&(v as i32).to_le_bytes());
            w.write_all(&buf)?;
        }
        for e in &edges {
            buf.clear();
            e.iter().for_each(|&v| buf.extend_from_slice(&(v as i32).to_le_bytes()));
            w.write_all(&buf)?;
        }
        for c in &mesh.curves {
            buf.clear();
            c.label.0.iter().for_each(|&v| buf.extend_from_slice(&(v as i32).to_le_bytes()));
            w.write_all(&buf)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The writer before the body was encoded in pieces (one `write_all` per record), kept
    /// as the reference the piecewise encoder must match byte for byte.
    fn reference(mesh: &Mesh, opts: &WriteOptions) -> Vec<u8> {
        let mut w = Vec::new();
        let normals = opts.normals && !mesh.normals.is_empty();
        let vertex_colours = !mesh.colors.is_empty();
        let uvs = !mesh.uvs.is_empty();
        let labelled = !mesh.labels.is_empty();
        let colours = if labelled { face_colours(mesh) } else { Vec::new() };
        let curves = opts.effective_ply_curves() == PlyCurves::Inline && !mesh.curves.is_empty();
        let format = if opts.ascii { "ascii" } else { "binary_little_endian" };
        let mut h = format!("ply\nformat {format} 1.0\ncomment generated by skelform\n");
        h += &format!(
            "element vertex {}\nproperty float x\nproperty float y\n",
            mesh.positions.len()
        );
        h += "property float z\n";
        if normals {
            h += "property float nx\nproperty float ny\nproperty float nz\n";
        }
        if vertex_colours {
            h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        }
        if uvs {
            h += "property float u\nproperty float v\n";
        }
        h += &format!(
            "element face {}\nproperty list uchar int vertex_indices\n",
            mesh.triangles.len()
        );
        if labelled {
            h += "property int region_a\nproperty int region_b\n";
            h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        }
        if curves {
            h += &format!(
                "element edge {}\nproperty int vertex1\nproperty int vertex2\n",
                mesh.curves.len()
            );
            h += "property int region_a\nproperty int region_b\nproperty int region_c\n";
        }
        h += "end_header\n";
        w.extend_from_slice(h.as_bytes());
        if opts.ascii {
            for (i, p) in mesh.positions.iter().enumerate() {
                write!(w, "{} {} {}", p[0], p[1], p[2]).unwrap();
                if normals {
                    let n = mesh.normals[i];
                    write!(w, " {} {} {}", n[0], n[1], n[2]).unwrap();
                }
                if vertex_colours {
                    let [r, g, b] = mesh.colors[i].map(colour_byte);
                    write!(w, " {r} {g} {b}").unwrap();
                }
                if uvs {
                    write!(w, " {} {}", mesh.uvs[i][0], mesh.uvs[i][1]).unwrap();
                }
                writeln!(w).unwrap();
            }
            for (i, t) in mesh.triangles.iter().enumerate() {
                write!(w, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
                if labelled {
                    let (l, [r, g, b]) = (mesh.labels[i], colours[i]);
                    write!(w, " {} {} {r} {g} {b}", l.0, l.1).unwrap();
                }
                writeln!(w).unwrap();
            }
            if curves {
                for c in &mesh.curves {
                    let [a, b, r] = c.label.0;
                    writeln!(w, "{} {} {a} {b} {r}", c.v[0], c.v[1]).unwrap();
                }
            }
            return w;
        }
        for (i, p) in mesh.positions.iter().enumerate() {
            p.iter().for_each(|c| w.extend_from_slice(&c.to_le_bytes()));
            if normals {
                mesh.normals[i].iter().for_each(|c| w.extend_from_slice(&c.to_le_bytes()));
            }
            if vertex_colours {
                w.extend_from_slice(&mesh.colors[i].map(colour_byte));
            }
            if uvs {
                mesh.uvs[i].iter().for_each(|c| w.extend_from_slice(&c.to_le_bytes()));
            }
        }
        for (i, t) in mesh.triangles.iter().enumerate() {
            w.push(3);
            t.iter().for_each(|&v| w.extend_from_slice(&(v as i32).to_le_bytes()));
            if labelled {
                let l = mesh.labels[i];
                w.extend_from_slice(&(l.0 as i32).to_le_bytes());
                w.extend_from_slice(&(l.1 as i32).to_le_bytes());
                w.extend_from_slice(&colours[i]);
            }
        }
        if curves {
            for c in &mesh.curves {
                c.v.iter()
                    .chain(&c.label.0)
                    .for_each(|&v| w.extend_from_slice(&(v as i32).to_le_bytes()));
            }
        }
        w
    }

    /// A mesh of `n` vertices with every attribute, from a fixed seed: awkward floats
    /// (negative zero, tiny and huge values), colours outside `[0, 1]`, many labels, large
    /// indices and region ids.
    fn full(n: usize) -> Mesh {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as u32
        };
        let mut float = || match next() % 8 {
            0 => -0.0,
            1 => 1.0e-39,
            2 => 3.4e37,
            _ => (next() as f32 / u32::MAX as f32) * 4.0 - 2.0,
        };
        let positions = (0..n).map(|_| [float(), float(), float()]).collect();
        let normals = (0..n).map(|_| [float(), float(), float()]).collect();
        let colors = (0..n).map(|_| [float(), float(), float()].map(|c| c * 0.75)).collect();
        let uvs = (0..n).map(|_| [float(), float()]).collect();
        let t = 2 * n;
        let triangles: Vec<[u32; 3]> =
            (0..t).map(|_| [next(), next(), next()].map(|v| v % n as u32)).collect();
        let labels = (0..t).map(|_| RegionPair::new(next() % 9, next() % 5 + 1_000_000)).collect();
        let curves = (0..n / 3)
            .map(|_| CurveEdge {
                v: [next() % n as u32, next() % n as u32],
                label: RegionTriple::new([next() % 7, next() % 7 + 7, i32::MAX as u32]),
            })
            .collect();
        Mesh { positions, normals, triangles, labels, curves, colors, uvs, texture: None }
    }

    /// Every combination of attributes (normals, colours, uvs, labels, curves), both
    /// encodings and both curve layouts: the file is the reference's, whether the body is
    /// encoded in one piece or in many (each piece then on the helper thread, cut at every
    /// kind of boundary), and whatever the mesh's size.
    #[test]
    fn the_piecewise_encoder_writes_the_reference_bytes() {
        let cases = [(100, 0..32, &[1 << 20, 997, 37][..]), (60_000, 31..32, &[PIECE_BYTES][..])];
        for (n, masks, pieces) in cases {
            let whole = full(n);
            for mask in masks {
                let mut mesh = whole.clone();
                let has = |bit: u32| mask & (1 << bit) != 0;
                if !has(0) {
                    mesh.normals.clear();
                }
                if !has(1) {
                    mesh.colors.clear();
                }
                if !has(2) {
                    mesh.uvs.clear();
                }
                if !has(3) {
                    mesh.labels.clear();
                }
                if !has(4) {
                    mesh.curves.clear();
                }
                for ascii in [false, n < 10_000] {
                    for ply_curves in [PlyCurves::Inline, PlyCurves::Separate] {
                        let opts = WriteOptions { ascii, ply_curves, ..WriteOptions::default() };
                        let want = reference(&mesh, &opts);
                        let mut got = Vec::new();
                        write_ply(&mut got, &mesh, &opts).unwrap();
                        assert!(got == want, "n {n} mask {mask} ascii {ascii} {ply_curves:?}");
                        for &piece in pieces {
                            let mut got = Vec::new();
                            write_body(&mut got, &mesh, &opts, piece).unwrap();
                            assert!(
                                got == want,
                                "n {n} mask {mask} ascii {ascii} {ply_curves:?} piece {piece}"
                            );
                        }
                    }
                }
            }
            // The large mesh's body takes several pieces of the default size.
            let body = Encoder {
                mesh: &whole,
                normals: true,
                vertex_colours: true,
                uvs: true,
                face_colours: &face_colours(&whole),
                inline_curves: true,
            };
            assert!(n < 10_000 || body.pieces(PIECE_BYTES).len() > 3);
        }
    }

    /// A writer that fails after a few bytes fails the write, encoded in line or on the
    /// helper thread, and the helper thread stops (the test would hang otherwise).
    #[test]
    fn a_failing_writer_stops_the_encoder() {
        struct Fails(usize);
        impl Write for Fails {
            fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
                if self.0 < buf.len() {
                    return Err(std::io::Error::other("disk full"));
                }
                self.0 -= buf.len();
                Ok(buf.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let mesh = full(3000);
        for (limit, piece) in
            [0, 100, 5000, 50_000].into_iter().flat_map(|l| [(l, 64), (l, 1 << 30)])
        {
            let opts = WriteOptions::default();
            let e = write_body(&mut Fails(limit), &mesh, &opts, piece).unwrap_err();
            assert_eq!(e.to_string(), "disk full");
        }
    }
}
