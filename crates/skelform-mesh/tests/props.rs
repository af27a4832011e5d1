//! Property tests for the readers and writers: random meshes round-trip, and damaged or
//! random bytes give errors, never panics.

use proptest::prelude::*;
use skelform_mesh::io::{Format, WriteOptions, read_mesh_from, write_mesh_to};
use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

fn any_mesh() -> impl Strategy<Value = Mesh> {
    (1usize..10, any::<bool>(), any::<bool>(), 0usize..12, 0usize..4).prop_flat_map(
        |(nv, normals, labelled, nf, nc)| {
            let nv32 = nv as u32;
            let coord = prop_oneof![
                -1.0e6f32..1.0e6,
                Just(0.0f32),
                Just(-0.0f32),
                any::<f32>().prop_filter("finite", |c| c.is_finite()),
            ];
            (
                prop::collection::vec(prop::array::uniform3(coord), nv),
                prop::collection::vec(
                    prop::array::uniform3(-1.0f32..1.0),
                    if normals { nv } else { 0 },
                ),
                prop::collection::vec(prop::array::uniform3(0..nv32), nf),
                prop::collection::vec((0u32..5, 0u32..5), if labelled { nf } else { 0 }),
                prop::collection::vec(
                    (prop::array::uniform2(0..nv32), prop::array::uniform3(0u32..9)),
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

fn write(mesh: &Mesh, format: Format, opts: &WriteOptions) -> Vec<u8> {
    let mut buf = Vec::new();
    write_mesh_to(&mut buf, mesh, format, opts).unwrap();
    buf
}

fn bits(v: &[[f32; 3]]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.map(f32::to_bits)).collect()
}

proptest! {
    #[test]
    fn ply_round_trips_exactly(m in any_mesh(), ascii in any::<bool>()) {
        let opts = WriteOptions { ascii, ply_curves: skelform_mesh::io::PlyCurves::Inline, ..WriteOptions::default() };
        let back = read_mesh_from(&write(&m, Format::Ply, &opts), Format::Ply).unwrap();
        prop_assert_eq!(bits(&back.positions), bits(&m.positions));
        prop_assert_eq!(bits(&back.normals), bits(&m.normals));
        prop_assert_eq!(&back, &m);
    }

    #[test]
    fn obj_round_trips_up_to_grouping(m in any_mesh()) {
        let back = read_mesh_from(&write(&m, Format::Obj, &WriteOptions::default()), Format::Obj).unwrap();
        prop_assert_eq!(bits(&back.positions), bits(&m.positions));
        // Normals survive when every vertex is used by a face; unused ones come back zero.
        if !m.normals.is_empty() && !m.triangles.is_empty() {
            let mut used = vec![false; m.positions.len()];
            m.triangles.iter().flatten().for_each(|&i| used[i as usize] = true);
            for (i, n) in back.normals.iter().enumerate() {
                prop_assert_eq!(*n, if used[i] { m.normals[i] } else { [0.0; 3] });
            }
        } else {
            prop_assert!(back.normals.is_empty());
        }
        let mut order: Vec<usize> = (0..m.triangles.len()).collect();
        if !m.labels.is_empty() {
            order.sort_by_key(|&i| m.labels[i]);
        }
        let triangles: Vec<_> = order.iter().map(|&i| m.triangles[i]).collect();
        let labels: Vec<_> = order.iter().filter_map(|&i| m.labels.get(i).copied()).collect();
        prop_assert_eq!(&back.triangles, &triangles);
        prop_assert_eq!(&back.labels, &labels);
        let mut curves = m.curves.clone();
        curves.sort_by_key(|c| c.label);
        prop_assert_eq!(&back.curves, &curves);
    }

    #[test]
    fn stl_round_trips_as_a_triangle_soup(m in any_mesh()) {
        let back = read_mesh_from(&write(&m, Format::Stl, &WriteOptions::default()), Format::Stl).unwrap();
        let soup = |m: &Mesh| -> Vec<[[f32; 3]; 3]> {
            m.triangles.iter().map(|t| t.map(|i| m.positions[i as usize].map(|c| c + 0.0))).collect()
        };
        prop_assert_eq!(soup(&back), soup(&m));
        prop_assert!(back.positions.len() <= m.positions.len());
    }

    #[test]
    fn damaged_files_give_errors_not_panics(
        m in any_mesh(),
        format in prop::sample::select(vec![0usize, 1, 2, 3]),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
    ) {
        let (f, ascii) = [(Format::Ply, false), (Format::Ply, true), (Format::Obj, false), (Format::Stl, false)][format];
        let mut bytes = write(&m, f, &WriteOptions { ascii, ply_curves: skelform_mesh::io::PlyCurves::Inline, ..WriteOptions::default() });
        for (at, b) in edits {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        let _ = read_mesh_from(&bytes, f);
        let len = cut.index(bytes.len() + 1);
        let _ = read_mesh_from(&bytes[..len], f);
    }

    #[test]
    fn random_bytes_give_errors_not_panics(
        bytes in prop::collection::vec(any::<u8>(), 0..300),
        prefix in prop::sample::select(vec![
            &b""[..],
            b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n",
            b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nelement face 2\nproperty list int uchar vertex_index\nelement edge 1\nproperty uchar vertex1\nproperty short vertex2\nend_header\n",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
            b"v 0 0 0\nv 1 0 0\nf ",
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex ",
        ]),
    ) {
        let mut data = prefix.to_vec();
        data.extend_from_slice(&bytes);
        for f in Format::ALL {
            if let Ok(m) = read_mesh_from(&data, f) {
                prop_assert!(m.validate().is_ok());
            }
        }
    }
}
