//! Fuzzing the four mesh readers (PLY ASCII and binary, OBJ, STL, glb) with damaged files.
//!
//! Generators: small random meshes (normals, labels and curves or not) written by skelform's
//! own writers, then damaged: bits flipped, bytes inserted, deleted or cut off, numbers of a
//! text file (PLY header counts, OBJ and ASCII PLY indices, STL coordinates) replaced by
//! extremes (huge counts, indices out of range, NaN, 1e308, −0), 32-bit words of binary
//! data (STL's triangle count, PLY list lengths, glb chunk lengths) overwritten, and the
//! JSON of a glb edited (counts, offsets, strides, indices) and repacked with consistent
//! chunk lengths, so the reader gets past the header; plus random bytes after each format's
//! first bytes.
//!
//! Properties: no panic, no hang (each case within its limit), no allocation past the
//! harness's 1 GiB (a file of a few hundred bytes that declares 4 billion vertices must be
//! refused before anything is allocated); the undamaged file reads back with its triangles;
//! a damaged one gives an error with a one-line message (a PLY or OBJ line at least 1, a
//! byte offset inside the file) or a mesh that passes `Mesh::validate`.
//!
//! CI runs a few hundred cases per format in a few seconds. A longer run:
//! `SKELFORM_FUZZ_SECONDS=3600 cargo test --release -p skelform-mesh --test fuzz_readers -- --nocapture`
//! runs every property for an hour, side by side as the test harness runs them (as many at
//! once as there are cores, or `--test-threads`), with fresh seeds each round
//! (`SKELFORM_FUZZ_CASES=N` sets the cases per round; see `fuzz/harness.rs`).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use std::time::Duration;

use proptest::prelude::*;
use skelform_mesh::io::{Format, IoError, WriteOptions, read_mesh_from, write_mesh_to};
use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

#[global_allocator]
static GUARD: harness::Guard = harness::Guard;

const LIMIT: Duration = Duration::from_secs(10);

fn small_mesh() -> impl Strategy<Value = Mesh> {
    (1usize..9, any::<bool>(), any::<bool>(), 0usize..10, 0usize..4).prop_flat_map(
        |(nv, normals, labelled, nf, nc)| {
            let n = nv as u32;
            let coord = prop_oneof![4 => -2.0f32..2.0, 1 => Just(0.0f32), 1 => Just(-0.0f32)];
            (
                prop::collection::vec(prop::array::uniform3(coord), nv),
                prop::collection::vec(
                    prop::array::uniform3(-1.0f32..1.0),
                    if normals { nv } else { 0 },
                ),
                prop::collection::vec(prop::array::uniform3(0..n), nf),
                prop::collection::vec((0u32..4, 0u32..4), if labelled { nf } else { 0 }),
                prop::collection::vec(
                    (prop::array::uniform2(0..n), prop::array::uniform3(0u32..5)),
                    nc,
                ),
            )
                .prop_map(|(positions, normals, triangles, labels, curves)| Mesh {
                    positions,
                    normals,
                    triangles,
                    labels: labels.into_iter().map(|(a, b)| RegionPair::new(a, b)).collect(),
                    curves: curves
                        .into_iter()
                        .map(|(v, l)| CurveEdge { v, label: RegionTriple::new(l) })
                        .collect(),
                    colors: Vec::new(),
                    uvs: Vec::new(),
                    texture: None,
                })
        },
    )
}

/// The writers' encodings: PLY binary, PLY ASCII, OBJ, STL, glb.
#[derive(Clone, Copy, Debug)]
enum Encoding {
    PlyBinary,
    PlyAscii,
    Obj,
    Stl,
    Glb,
}

impl Encoding {
    fn format(self) -> Format {
        match self {
            Encoding::PlyBinary | Encoding::PlyAscii => Format::Ply,
            Encoding::Obj => Format::Obj,
            Encoding::Stl => Format::Stl,
            Encoding::Glb => Format::Glb,
        }
    }
}

fn write(mesh: &Mesh, e: Encoding, normals: bool) -> Vec<u8> {
    let opts =
        WriteOptions { ascii: matches!(e, Encoding::PlyAscii), normals, ..WriteOptions::default() };
    let mut out = Vec::new();
    if let Err(err) = write_mesh_to(&mut out, mesh, e.format(), &opts) {
        panic!("the writer refused a valid mesh: {err}");
    }
    out
}

/// A damage, at positions given as fractions of the file's length.
#[derive(Clone, Debug)]
enum Damage {
    Flip(f64, u8),
    Cut(f64),
    Delete(f64, usize),
    Insert(f64, Vec<u8>),
    Duplicate(f64, f64),
    /// Replace the number (ASCII digits, signs, dots and exponents) at a position by another.
    Number(f64, &'static str),
    /// Overwrite the 32-bit little-endian word at a position.
    Word(f64, u32),
}

const NUMBERS: &[&str] = &[
    "0",
    "1",
    "2",
    "3",
    "-1",
    "-0",
    "255",
    "256",
    "65536",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "1e308",
    "-1e308",
    "1e309",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1.5",
    "1e-320",
    "0x10",
    "",
    "-2147483649",
    "9223372036854775807",
    "100000000",
];

const WORDS: &[u32] =
    &[0, 1, 2, 3, 0xFF, 0x100, 0xFFFF, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF, 0xFFFF_FFFE, 1 << 24];

fn damage() -> impl Strategy<Value = Damage> {
    let at = 0.0..1.0f64;
    prop_oneof![
        3 => (at.clone(), any::<u8>()).prop_map(|(a, b)| Damage::Flip(a, b)),
        1 => at.clone().prop_map(Damage::Cut),
        1 => (at.clone(), 1usize..16).prop_map(|(a, n)| Damage::Delete(a, n)),
        1 => (at.clone(), prop::collection::vec(any::<u8>(), 1..8)).prop_map(|(a, b)| Damage::Insert(a, b)),
        1 => (at.clone(), at.clone()).prop_map(|(a, b)| Damage::Duplicate(a, b)),
        4 => (at.clone(), prop::sample::select(NUMBERS)).prop_map(|(a, s)| Damage::Number(a, s)),
        3 => (at, prop_oneof![prop::sample::select(WORDS), any::<u32>()]).prop_map(|(a, w)| Damage::Word(a, w)),
    ]
}

fn is_number_byte(b: u8) -> bool {
    b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E')
}

/// Byte ranges of the numbers in `bytes` (runs of number bytes that hold a digit).
fn numbers(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if is_number_byte(bytes[i]) {
            let s = i;
            while i < bytes.len() && is_number_byte(bytes[i]) {
                i += 1;
            }
            if bytes[s..i].iter().any(u8::is_ascii_digit) {
                out.push((s, i));
            }
        } else {
            i += 1;
        }
    }
    out
}

fn apply(bytes: &mut Vec<u8>, d: &Damage) {
    let pos = |f: f64, len: usize| ((f * len as f64) as usize).min(len);
    let len = bytes.len();
    match d {
        Damage::Flip(f, b) => {
            if len > 0 {
                bytes[pos(*f, len - 1)] ^= b | 1;
            }
        }
        Damage::Cut(f) => bytes.truncate(pos(*f, len)),
        Damage::Delete(f, n) => {
            let i = pos(*f, len);
            bytes.drain(i..(i + n).min(len));
        }
        Damage::Insert(f, b) => {
            let i = pos(*f, len);
            bytes.splice(i..i, b.iter().copied());
        }
        Damage::Duplicate(a, b) => {
            let (i, j) = (pos(*a, len), pos(*b, len));
            let (i, j) = (i.min(j), i.max(j).min(i + 256));
            let copy = bytes[i..j].to_vec();
            bytes.splice(j..j, copy);
        }
        Damage::Number(f, s) => {
            let n = numbers(bytes);
            if !n.is_empty() {
                let (i, j) = n[pos(*f, n.len() - 1)];
                bytes.splice(i..j, s.bytes());
            }
        }
        Damage::Word(f, w) => {
            if len >= 4 {
                let i = pos(*f, len - 4);
                bytes[i..i + 4].copy_from_slice(&w.to_le_bytes());
            }
        }
    }
}

/// The chunks of a glb, when it has the layout skelform writes.
fn glb_parts(glb: &[u8]) -> Option<(String, Vec<u8>)> {
    let word = |at: usize| Some(u32::from_le_bytes(*glb.get(at..)?.first_chunk::<4>()?) as usize);
    let jl = word(12)?;
    let json = String::from_utf8(glb.get(20..20 + jl)?.to_vec()).ok()?;
    let bin = match word(20 + jl) {
        Some(bl) => glb.get(28 + jl..28 + jl + bl)?.to_vec(),
        None => Vec::new(),
    };
    Some((json, bin))
}

/// A glb with consistent lengths around `json` and `bin`.
fn glb_pack(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + if b.is_empty() { 0 } else { 8 + b.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    if !b.is_empty() {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    out
}

/// The reader's verdict on `bytes` must be a valid mesh or a well-formed error.
fn verdict(bytes: &[u8], format: Format) -> Result<Option<Mesh>, String> {
    match read_mesh_from(bytes, format) {
        Ok(mesh) => {
            mesh.validate().map_err(|e| format!("the reader returned an invalid mesh: {e}"))?;
            Ok(Some(mesh))
        }
        Err(e) => {
            let text = e.to_string();
            if text.trim().is_empty() || text.contains('\n') {
                return Err(format!("an error message that is empty or not one line: {text:?}"));
            }
            match e {
                IoError::Parse { line: 0, .. } => {
                    return Err(format!("an error at line 0: {text}"));
                }
                IoError::Binary { offset, .. } if offset > bytes.len() as u64 => {
                    return Err(format!("an error past the end of {} bytes: {text}", bytes.len()));
                }
                IoError::Parse { .. } | IoError::Binary { .. } => {}
                other => return Err(format!("an in-memory read failed with {other:?}")),
            }
            Ok(None)
        }
    }
}

fn encoding() -> impl Strategy<Value = Encoding> {
    prop::sample::select(vec![
        Encoding::PlyBinary,
        Encoding::PlyAscii,
        Encoding::Obj,
        Encoding::Stl,
        Encoding::Glb,
    ])
}

#[test]
fn damaged_files_are_errors_or_valid_meshes() {
    let strategy = (small_mesh(), encoding(), any::<bool>(), prop::collection::vec(damage(), 0..5));
    harness::fuzz("mesh readers", 1024, LIMIT, strategy, |(mesh, e, normals, damages)| {
        let mut bytes = write(&mesh, e, normals);
        if damages.is_empty() {
            let back = verdict(&bytes, e.format())?
                .ok_or_else(|| format!("{e:?}: the writer's own file is refused"))?;
            if back.triangles.len() != mesh.triangles.len() {
                return Err(format!(
                    "{e:?}: {} triangles written, {} read",
                    mesh.triangles.len(),
                    back.triangles.len()
                ));
            }
            return Ok(());
        }
        for d in &damages {
            apply(&mut bytes, d);
        }
        verdict(&bytes, e.format()).map(|_| ())
    });
}

/// Edits of a glb's JSON, repacked so that the chunk lengths still agree.
#[derive(Clone, Debug)]
enum JsonEdit {
    Number(f64, &'static str),
    /// Insert `"key": value,` after an opening brace.
    Key(f64, &'static str, &'static str),
    Text(f64, u8),
}

fn json_edit() -> impl Strategy<Value = JsonEdit> {
    let at = 0.0..1.0f64;
    let keys = prop::sample::select(vec![
        "count",
        "byteOffset",
        "byteLength",
        "byteStride",
        "bufferView",
        "buffer",
        "indices",
        "mode",
        "componentType",
        "POSITION",
        "NORMAL",
        "sparse",
        "uri",
        "extras",
        "matrix",
    ]);
    let values = prop::sample::select(vec![
        "0",
        "1",
        "3",
        "4294967295",
        "18446744073709551615",
        "1e300",
        "-1",
        "null",
        "[]",
        "{}",
        "\"VEC3\"",
        "\"x\"",
        "[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]",
        "{\"skelform\":{\"regions\":[0,4294967295]}}",
    ]);
    prop_oneof![
        4 => (at.clone(), prop::sample::select(NUMBERS)).prop_map(|(a, s)| JsonEdit::Number(a, s)),
        2 => (at.clone(), keys, values).prop_map(|(a, k, v)| JsonEdit::Key(a, k, v)),
        1 => (at, any::<u8>()).prop_map(|(a, b)| JsonEdit::Text(a, b)),
    ]
}

#[test]
fn glb_with_edited_json_is_an_error_or_a_valid_mesh() {
    let strategy =
        (small_mesh(), any::<bool>(), prop::collection::vec(json_edit(), 1..5), any::<bool>());
    harness::fuzz("glb json", 384, LIMIT, strategy, |(mesh, normals, edits, cut_bin)| {
        let glb = write(&mesh, Encoding::Glb, normals);
        let Some((json, mut bin)) = glb_parts(&glb) else {
            return Err("cannot find the chunks of the writer's glb".into());
        };
        let mut json = json.into_bytes();
        for e in &edits {
            let pos = |f: f64, len: usize| ((f * len as f64) as usize).min(len);
            match e {
                JsonEdit::Number(f, s) => apply(&mut json, &Damage::Number(*f, s)),
                JsonEdit::Key(f, k, v) => {
                    let braces: Vec<usize> = json
                        .iter()
                        .enumerate()
                        .filter(|(_, b)| **b == b'{')
                        .map(|(i, _)| i)
                        .collect();
                    if !braces.is_empty() {
                        let i = braces[pos(*f, braces.len() - 1)] + 1;
                        let text = format!("\"{k}\": {v},");
                        json.splice(i..i, text.bytes());
                    }
                }
                JsonEdit::Text(f, b) => apply(&mut json, &Damage::Flip(*f, *b)),
            }
        }
        if cut_bin {
            bin.truncate(bin.len() / 2);
        }
        let json = String::from_utf8_lossy(&json).into_owned();
        verdict(&glb_pack(&json, &bin), Format::Glb).map(|_| ())
    });
}

#[test]
fn random_bytes_after_a_magic_are_errors_or_valid_meshes() {
    let magic = prop::sample::select(vec![
        (Format::Ply, &b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"[..]),
        (Format::Ply, &b"ply\nformat ascii 1.0\nelement vertex 4294967295\nproperty float x\nproperty float y\nproperty float z\nelement face 4294967295\nproperty list uint uint vertex_indices\nend_header\n"[..]),
        (Format::Ply, &b"ply\nformat binary_big_endian 1.0\nelement face 18446744073709551615\nproperty list int int vertex_index\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nend_header\n"[..]),
        (Format::Ply, &b"ply\n"[..]),
        (Format::Obj, &b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf "[..]),
        (Format::Obj, &b"l 1 "[..]),
        (Format::Stl, &b"solid x\nfacet normal 0 0 1\nouter loop\nvertex "[..]),
        (Format::Stl, &[0u8; 80][..]),
        (Format::Glb, &b"glTF\x02\0\0\0"[..]),
    ]);
    let strategy = (magic, prop::collection::vec(any::<u8>(), 0..300));
    harness::fuzz("reader bytes", 384, LIMIT, strategy, |((format, head), tail)| {
        let mut bytes = head.to_vec();
        bytes.extend_from_slice(&tail);
        verdict(&bytes, format).map(|_| ())
    });
}

/// Regression (found by fuzzing the glb JSON): primitives that share one accessor each read
/// it again, so a file of about 1 MB could ask for gigabytes of triangles (and minutes of
/// welding) by listing the same primitive thousands of times. The reader now refuses
/// primitives that together read far more values than the BIN chunk holds.
#[test]
fn glb_primitives_sharing_one_accessor_cannot_multiply_the_mesh() {
    let vertices = 30_000usize;
    let primitives = 20_000usize;
    let bin: Vec<u8> = (0..vertices * 3).flat_map(|k| (k as f32).to_le_bytes()).collect();
    let prim = r#"{"attributes":{"POSITION":0}}"#;
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}}}],"bufferViews":[{{"buffer":0,"byteLength":{}}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":{vertices},"type":"VEC3"}}],"meshes":[{{"primitives":[{}]}}]}}"#,
        bin.len(),
        bin.len(),
        vec![prim; primitives].join(",")
    );
    let glb = glb_pack(&json, &bin);
    assert!(glb.len() < 2 << 20);
    let t = std::time::Instant::now();
    let e = read_mesh_from(&glb, Format::Glb).expect_err("20000 copies of one primitive");
    assert!(e.to_string().contains("accessors reused by many primitives"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    // One primitive of the same accessor reads as usual.
    let json = json.replace(&format!(",{prim}"), "");
    let mesh = read_mesh_from(&glb_pack(&json, &bin), Format::Glb).expect("one primitive");
    assert_eq!(mesh.triangles.len(), vertices / 3);
}
