//! Files for and from other programs: glTF expansion limits, data-URI buffers and node
//! transforms, unwelded reading (the same components from every format), the PLY curves
//! file and the OBJ material library.

use std::fs;

use serde_json::{Value, json};
use skelform_mesh::check::check;
use skelform_mesh::io::{
    Format, PlyCurves, WriteOptions, ply, read_glb, read_mesh, read_mesh_from, write_mesh,
    write_mesh_to,
};
use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

/// A `.glb` file of `doc` and, when not empty, a BIN chunk of `bin`.
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut text = serde_json::to_vec(doc).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}

/// One triangle's data: three float positions (36 bytes), three normals (36), indices (12).
fn triangle_bin() -> Vec<u8> {
    let floats = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let normals = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut bin: Vec<u8> = floats.iter().chain(&normals).flat_map(|f| f.to_le_bytes()).collect();
    bin.extend([0u32, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    bin
}

fn triangle_doc(buffer: Value) -> Value {
    json!({
        "asset": { "version": "2.0" },
        "buffers": [buffer],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 72, "byteLength": 12 },
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3" },
            { "bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5125, "count": 3, "type": "SCALAR" },
        ],
        "meshes": [{ "primitives": [
            { "attributes": { "POSITION": 0, "NORMAL": 1 }, "indices": 2 }
        ] }],
    })
}

#[test]
fn a_glb_that_reuses_one_accessor_thousands_of_times_is_refused() {
    let bin = triangle_bin();
    let mut doc = triangle_doc(json!({ "byteLength": bin.len() }));
    let prim = doc["meshes"][0]["primitives"][0].clone();
    doc["meshes"][0]["primitives"] = json!(vec![prim.clone(); 3]);
    // A little sharing is fine (three primitives, one triangle each, not welded).
    let m = read_glb(&glb(&doc, &bin)).unwrap();
    assert_eq!(m.triangles.len(), 3);
    // An index accessor of 3M entries (a 12 MB view that the file does not need to back
    // with real data for the count check)... is out of the file; instead reuse: 2000
    // primitives each pointing at a large accessor of a small file.
    let big = 30_000u32;
    let mut bin = triangle_bin();
    let index_start = bin.len();
    bin.extend((0..big).flat_map(|k| (k % 3).to_le_bytes()));
    let mut doc = triangle_doc(json!({ "byteLength": bin.len() }));
    doc["bufferViews"][2] =
        json!({ "buffer": 0, "byteOffset": index_start, "byteLength": 4 * big });
    doc["accessors"][2]["count"] = json!(big);
    doc["meshes"][0]["primitives"] = json!(vec![prim; 2000]);
    let file = glb(&doc, &bin);
    let e = read_glb(&file).unwrap_err();
    let msg = e.to_string();
    assert!(e.is_bad_input() && msg.contains("per byte of file"), "{msg}");
    // Node instancing counts too: one primitive, but the mesh placed by 2000 nodes.
    doc["meshes"][0]["primitives"] = json!([doc["meshes"][0]["primitives"][0].clone()]);
    doc["nodes"] = json!(vec![json!({ "mesh": 0 }); 2000]);
    let e = read_glb(&glb(&doc, &bin)).unwrap_err();
    assert!(e.to_string().contains("per byte of file"), "{e}");
}

#[test]
fn an_empty_accessor_with_an_offset_past_its_view_is_an_error() {
    // Found by fuzzing (`glb json`, seed 17718375055979339359): `count: 0` skipped the
    // bounds check of `byteOffset`, and the reader sliced past the view and panicked.
    let bin = triangle_bin();
    for (accessor, offset) in [(2, 4_294_967_295u64), (0, 40), (2, 13)] {
        let mut doc = triangle_doc(json!({ "byteLength": bin.len() }));
        doc["accessors"][accessor]["count"] = json!(0);
        doc["accessors"][accessor]["byteOffset"] = json!(offset);
        let e = read_glb(&glb(&doc, &bin)).unwrap_err();
        assert!(e.is_bad_input() && e.to_string().contains("runs past"), "{offset}: {e}");
    }
    // An empty accessor at the end of its view is fine (and makes an empty mesh part).
    let mut doc = triangle_doc(json!({ "byteLength": bin.len() }));
    doc["accessors"][2]["count"] = json!(0);
    doc["accessors"][2]["byteOffset"] = json!(12);
    assert!(read_glb(&glb(&doc, &bin)).is_ok());
}

#[test]
fn data_uri_buffers_are_read() {
    let bin = triangle_bin();
    let base64 = encode64(&bin);
    let doc = triangle_doc(json!({
        "byteLength": bin.len(),
        "uri": format!("data:application/octet-stream;base64,{base64}"),
    }));
    let m = read_glb(&glb(&doc, &[])).unwrap();
    assert_eq!(m.positions, vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.normals.len(), 3);
    // Bad base64 and external files are clear errors.
    let doc = triangle_doc(
        json!({ "byteLength": 84, "uri": "data:application/octet-stream;base64,@@@@" }),
    );
    assert!(read_glb(&glb(&doc, &[])).unwrap_err().to_string().contains("base64"));
    let doc = triangle_doc(json!({ "byteLength": 84, "uri": "mesh.bin" }));
    let e = read_glb(&glb(&doc, &[])).unwrap_err();
    assert!(e.to_string().contains("external file ('mesh.bin')"), "{e}");
}

/// Standard base64 with padding (the test's own encoder, to check the reader's decoder).
fn encode64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn node_transforms_move_positions_and_normals() {
    let bin = triangle_bin();
    let mut doc = triangle_doc(json!({ "byteLength": bin.len() }));
    // Parent translates by (10, 0, 0); child turns 90° about z and scales x by 2.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    doc["nodes"] = json!([
        { "translation": [10.0, 0.0, 0.0], "children": [1] },
        { "rotation": [0.0, 0.0, s, s], "scale": [2.0, 1.0, 1.0], "mesh": 0 },
    ]);
    doc["scenes"] = json!([{ "nodes": [0] }]);
    doc["scene"] = json!(0);
    let m = read_glb(&glb(&doc, &bin)).unwrap();
    let near = |a: [f32; 3], b: [f32; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6);
    // x' = R(S x) + t: (1,0,0) → (2,0,0) → (0,2,0) → (10,2,0); (0,1,0) → (-1,0,0) → (9,0,0).
    assert!(near(m.positions[1], [10.0, 2.0, 0.0]), "{:?}", m.positions);
    assert!(near(m.positions[2], [9.0, 0.0, 0.0]), "{:?}", m.positions);
    assert!(near(m.normals[0], [0.0, 0.0, 1.0]));
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    // A mirroring matrix (x → −x) flips the normal's x part and reverses the winding; a
    // node's matrix is column-major.
    doc["nodes"] = json!([{
        "matrix": [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 5.0, 1.0],
        "mesh": 0,
    }]);
    let m = read_glb(&glb(&doc, &bin)).unwrap();
    assert_eq!(m.positions[1], [-1.0, 0.0, 5.0]);
    assert_eq!(m.triangles, vec![[0, 2, 1]]);
    // The winding still agrees with the normals: the face normal points along +z.
    assert!(check(&m).faces == 1);
    // A node with two parents is refused.
    doc["nodes"] = json!([{ "children": [2] }, { "children": [2] }, { "mesh": 0 }]);
    doc["scenes"] = json!([{ "nodes": [0, 1] }]);
    assert!(read_glb(&glb(&doc, &bin)).unwrap_err().to_string().contains("reached twice"));
}

/// Two square sheets, (1, 2) in z = 0 and (1, 3) in x = 0, each with its own copies of
/// the vertices along the line x = z = 0 where they meet, and a curve along that line.
fn two_sheets() -> Mesh {
    let mut m = Mesh::default();
    for (k, label) in [RegionPair(1, 2), RegionPair(1, 3)].into_iter().enumerate() {
        let b = m.positions.len() as u32;
        let corners: [[f32; 3]; 4] = if k == 0 {
            [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0]]
        } else {
            [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]
        };
        m.positions.extend(corners);
        m.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        m.labels.extend([label; 2]);
    }
    m.curves.push(CurveEdge { v: [0, 1], label: RegionTriple([1, 2, 3]) });
    m
}

#[test]
fn every_format_but_stl_reads_the_same_components() {
    let m = two_sheets();
    let want = check(&m);
    assert_eq!(want.components.len(), 2);
    for format in [Format::Ply, Format::Obj, Format::Glb] {
        let opts = WriteOptions { ply_curves: PlyCurves::Inline, ..WriteOptions::default() };
        let mut bytes = Vec::new();
        write_mesh_to(&mut bytes, &m, format, &opts).unwrap();
        let back = read_mesh_from(&bytes, format).unwrap();
        let got = check(&back);
        assert_eq!(got.components.len(), 2, "{format}");
        assert_eq!(got.non_manifold_edges, 0, "{format}");
        assert_eq!(back.curves.len(), 1, "{format}");
        assert_eq!(back.label_counts(), m.label_counts(), "{format}");
    }
}

#[test]
fn ply_curves_go_beside_the_mesh_and_come_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.ply");
    let side = ply::curves_path(&path);
    assert_eq!(side, dir.path().join("m.curves.ply"));
    let m = two_sheets();
    for ascii in [false, true] {
        write_mesh(&path, &m, Format::Ply, &WriteOptions { ascii, ..WriteOptions::default() })
            .unwrap();
        let main = fs::read(&path).unwrap();
        assert!(!String::from_utf8_lossy(&main).contains("element edge"));
        assert!(side.exists());
        assert_eq!(read_mesh(&path).unwrap(), m);
    }
    // A curves file that belongs to another mesh is an error naming it.
    let mut moved = m.clone();
    moved.positions[0][0] = 0.5;
    let opts = WriteOptions { ply_curves: PlyCurves::None, ..WriteOptions::default() };
    let mut bytes = Vec::new();
    write_mesh_to(&mut bytes, &moved, Format::Ply, &opts).unwrap();
    fs::write(&path, &bytes).unwrap();
    let e = read_mesh(&path).unwrap_err();
    assert!(
        e.to_string().contains("m.curves.ply") && e.to_string().contains("another mesh"),
        "{e}"
    );
    // Writing without separate curves removes skelform's stale curves file, not others'.
    write_mesh(&path, &m, Format::Ply, &opts).unwrap();
    assert!(!side.exists());
    assert!(read_mesh(&path).unwrap().curves.is_empty());
    fs::write(&side, b"ply\nformat ascii 1.0\ncomment someone else's\nend_header\n").unwrap();
    write_mesh(&path, &m, Format::Ply, &opts).unwrap();
    assert!(side.exists());
    fs::remove_file(&side).unwrap();
    // curves: false wins over the PLY layout.
    let none = WriteOptions { curves: false, ..WriteOptions::default() };
    write_mesh(&path, &m, Format::Ply, &none).unwrap();
    assert!(!side.exists());
    // Another program's curves file (no mesh_index) adds its vertices.
    write_mesh(&path, &m, Format::Ply, &opts).unwrap();
    fs::write(
        &side,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
         property float z\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n\
         end_header\n0 0 0\n0 0 1\n0 1\n",
    )
    .unwrap();
    let back = read_mesh(&path).unwrap();
    assert_eq!(back.positions.len(), m.positions.len() + 2);
    assert_eq!(back.curves, vec![CurveEdge { v: [8, 9], label: RegionTriple([0, 0, 0]) }]);
}

#[test]
fn obj_regions_get_materials_with_the_palette_colours() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.obj");
    write_mesh(&path, &two_sheets(), Format::Obj, &WriteOptions::default()).unwrap();
    let obj = fs::read_to_string(&path).unwrap();
    assert!(obj.contains("mtllib m.mtl\n"), "{obj}");
    assert!(obj.contains("g region_1_2\nusemtl region_1_2\n"), "{obj}");
    assert!(obj.contains("g curve_1_2_3\nusemtl curve\n"), "{obj}");
    let mtl = fs::read_to_string(dir.path().join("m.mtl")).unwrap();
    // Palette colour 0 is (84, 140, 204).
    assert!(mtl.contains("newmtl region_1_2\nKd 0.3294 0.5490 0.8000\n"), "{mtl}");
    assert!(mtl.contains("newmtl region_1_3\n") && mtl.contains("newmtl curve\n"), "{mtl}");
    assert_eq!(read_mesh(&path).unwrap().label_counts(), two_sheets().label_counts());
    // An unlabelled mesh without curves has no material library.
    let plain = Mesh { labels: Vec::new(), curves: Vec::new(), ..two_sheets() };
    let path = dir.path().join("p.obj");
    write_mesh(&path, &plain, Format::Obj, &WriteOptions::default()).unwrap();
    assert!(!dir.path().join("p.mtl").exists());
    assert!(!fs::read_to_string(&path).unwrap().contains("mtllib"));
}
