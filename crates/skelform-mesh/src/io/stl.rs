//! STL.
//!
//! Written: binary STL, an 80-byte header naming skelform (never starting with `solid`), the
//! triangle count, and per triangle its unit normal computed from the vertices (zero for a
//! degenerate triangle), the three vertices and a zero attribute. Labels, normals and
//! curves are not written.
//!
//! Read: binary and ASCII STL. A file is read as ASCII when it starts with `solid` and
//! parses as ASCII; otherwise as binary, which needs exactly `84 + 50·n` bytes for its `n`
//! triangles. Vertices with identical coordinates (bit for bit, `-0.0` taken as `0.0`) are
//! welded into one; facet normals are ignored. At most
//! [`MAX_TRIANGLES`](super::limits::MAX_TRIANGLES) triangles (a binary count beyond it is
//! refused before reading).

use std::io::Write;

use super::{IoError, Welder, buffered, finish, limits, three_numbers};
use crate::mesh::Mesh;

const HEADER: &[u8] = b"binary STL written by skelform";

/// Reads a binary or ASCII STL file from its whole contents, welding identical vertices.
pub fn read_stl(bytes: &[u8]) -> Result<Mesh, IoError> {
    let start = bytes.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(bytes.len());
    if bytes[start..].starts_with(b"solid") {
        match read_ascii(bytes) {
            Ok(mesh) => return Ok(mesh),
            // Some binary files start their header with "solid" too.
            Err(e) if binary_size(bytes).is_some_and(|(_, size)| size == bytes.len() as u64) => {
                return read_binary(bytes).map_err(|_| e);
            }
            Err(e) => return Err(e),
        }
    }
    read_binary(bytes)
}

/// The triangle count of a binary file and the size it implies.
fn binary_size(bytes: &[u8]) -> Option<(u32, u64)> {
    let count = u32::from_le_bytes(*bytes.get(80..)?.first_chunk::<4>()?);
    Some((count, 84 + 50 * u64::from(count)))
}

fn read_binary(bytes: &[u8]) -> Result<Mesh, IoError> {
    let len = bytes.len() as u64;
    let Some((count, expected)) = binary_size(bytes) else {
        return Err(IoError::binary(
            len,
            format!(
                "truncated binary STL: expected an 80-byte header and a 4-byte triangle count, \
                 found {len} bytes"
            ),
        ));
    };
    if len < expected {
        let complete = (len - 84) / 50;
        return Err(IoError::binary(
            84 + 50 * complete,
            format!(
                "truncated binary STL: triangle {complete} is incomplete; the header declares \
                 {count} triangles ({expected} bytes), found {len} bytes"
            ),
        ));
    }
    if len > expected {
        return Err(IoError::binary(
            expected,
            format!(
                "{} unexpected bytes after the last of {count} triangles (a binary STL of \
                 {count} triangles has {expected} bytes)",
                len - expected
            ),
        ));
    }
    let mut welder = Welder::new();
    if count as usize > limits::MAX_TRIANGLES {
        return Err(IoError::binary(
            80,
            format!("{count} triangles; skelform reads at most {}", limits::MAX_TRIANGLES),
        ));
    }
    // The size matches the count (checked above), so this is backed by the file's bytes.
    let mut triangles = Vec::with_capacity(count as usize);
    for record in bytes[84..].chunks_exact(50) {
        let mut t = [0u32; 3];
        for (k, corner) in t.iter_mut().enumerate() {
            let mut p = [0f32; 3];
            for (c, out) in p.iter_mut().enumerate() {
                let at = 12 + 12 * k + 4 * c;
                let b = record
                    .get(at..)
                    .and_then(|s| s.first_chunk::<4>())
                    .copied()
                    .unwrap_or_default();
                *out = f32::from_le_bytes(b);
            }
            *corner = welder.index(p);
        }
        triangles.push(t);
    }
    Ok(Mesh { positions: welder.positions, triangles, ..Mesh::default() })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum State {
    Outside,
    InSolid,
    InFacet,
    InLoop,
    AfterLoop,
}

fn read_ascii(bytes: &[u8]) -> Result<Mesh, IoError> {
    let text = String::from_utf8_lossy(bytes);
    let mut welder = Welder::new();
    let mut triangles = Vec::new();
    let mut state = State::Outside;
    let mut polygon: Vec<u32> = Vec::new();
    let mut line = 0;
    let mut solids = 0;
    for raw in text.lines() {
        line += 1;
        let mut words = raw.split_whitespace();
        let Some(keyword) = words.next() else { continue };
        let expect =
            |what: &str| IoError::parse(line, format!("expected {what}, found '{keyword}'"));
        state = match (state, keyword) {
            (State::Outside, "solid") => {
                solids += 1;
                State::InSolid
            }
            (State::Outside, _) => return Err(expect("solid")),
            (State::InSolid, "facet") => {
                let normal = words.next();
                if normal.is_some() {
                    if normal != Some("normal") {
                        return Err(IoError::parse(line, "expected 'facet normal nx ny nz'"));
                    }
                    three_numbers(&mut words, line, "facet normal")?;
                }
                State::InFacet
            }
            (State::InSolid, "endsolid") => State::Outside,
            (State::InSolid, _) => return Err(expect("facet or endsolid")),
            (State::InFacet, "outer") => {
                if words.next() != Some("loop") {
                    return Err(IoError::parse(line, "expected 'outer loop'"));
                }
                polygon.clear();
                State::InLoop
            }
            (State::InFacet, _) => return Err(expect("outer loop")),
            (State::InLoop, "vertex") => {
                let p = three_numbers(&mut words, line, "vertex")?;
                polygon.push(welder.index(p));
                State::InLoop
            }
            (State::InLoop, "endloop") => {
                if polygon.len() < 3 {
                    return Err(IoError::parse(
                        line,
                        format!("a facet needs at least 3 vertices, found {}", polygon.len()),
                    ));
                }
                for k in 2..polygon.len() {
                    triangles.push([polygon[0], polygon[k - 1], polygon[k]]);
                }
                State::AfterLoop
            }
            (State::InLoop, _) => return Err(expect("vertex or endloop")),
            (State::AfterLoop, "endfacet") => State::InSolid,
            (State::AfterLoop, _) => return Err(expect("endfacet")),
        };
    }
    let missing = match state {
        State::Outside if solids > 0 => {
            return Ok(Mesh { positions: welder.positions, triangles, ..Mesh::default() });
        }
        State::Outside => "solid",
        State::InSolid => "facet or endsolid",
        State::InFacet => "outer loop",
        State::InLoop => "vertex or endloop",
        State::AfterLoop => "endfacet",
    };
    Err(IoError::parse(line.max(1), format!("unexpected end of file: expected {missing}")))
}

/// The unit normal of a triangle, or zero when it is degenerate.
fn facet_normal(p: [[f32; 3]; 3]) -> [f32; 3] {
    let d = |a: [f32; 3], b: [f32; 3]| [0, 1, 2].map(|i| f64::from(b[i]) - f64::from(a[i]));
    let (u, v) = (d(p[0], p[1]), d(p[0], p[2]));
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len > 0.0 && len.is_finite() { n.map(|c| (c / len) as f32) } else { [0.0; 3] }
}

/// Writes `mesh` as binary STL (labels, normals and curves are dropped).
pub fn write_stl(w: &mut impl Write, mesh: &Mesh) -> Result<(), IoError> {
    mesh.validate().map_err(IoError::invalid)?;
    let count = u32::try_from(mesh.triangles.len()).map_err(|_| {
        IoError::unsupported(format!(
            "{} triangles are more than a binary STL can hold",
            mesh.triangles.len()
        ))
    })?;
    let mut w = buffered(w);
    let mut header = [0u8; 80];
    header[..HEADER.len()].copy_from_slice(HEADER);
    let result = (|| {
        w.write_all(&header)?;
        w.write_all(&count.to_le_bytes())?;
        let mut record = [0u8; 50];
        for t in &mesh.triangles {
            let p = t.map(|i| mesh.positions[i as usize]);
            let values = std::iter::once(facet_normal(p)).chain(p).flatten();
            for (k, c) in values.enumerate() {
                record[4 * k..4 * k + 4].copy_from_slice(&c.to_le_bytes());
            }
            w.write_all(&record)?;
        }
        Ok(())
    })();
    result.map_err(IoError::write)?;
    finish(w)
}
