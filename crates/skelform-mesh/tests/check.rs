//! The topology checker on meshes whose answers are known.

use std::collections::{BTreeSet, HashMap};

use proptest::prelude::*;
use skelform_mesh::check::{Report, check};
use skelform_mesh::{Mesh, RegionPair};

fn mesh(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Mesh {
    Mesh { positions: positions.to_vec(), triangles: triangles.to_vec(), ..Mesh::default() }
}

fn tetrahedron() -> Mesh {
    mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        &[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
}

/// `b`'s vertices and faces appended to `a`'s, with `b`'s indices shifted.
fn union(a: &Mesh, b: &Mesh) -> Mesh {
    let n = a.positions.len() as u32;
    let mut m = a.clone();
    m.positions.extend(&b.positions);
    m.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + n)));
    m
}

fn translated(m: &Mesh, d: [f32; 3]) -> Mesh {
    let mut m = m.clone();
    for p in &mut m.positions {
        *p = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
    }
    m
}

fn cube() -> Mesh {
    let positions: Vec<[f32; 3]> =
        (0..8).map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]).collect();
    // Quads counter-clockwise seen from outside.
    let quads = [
        [0, 2, 3, 1], // z = 0
        [4, 5, 7, 6], // z = 1
        [0, 1, 5, 4], // y = 0
        [2, 6, 7, 3], // y = 1
        [0, 4, 6, 2], // x = 0
        [1, 3, 7, 5], // x = 1
    ];
    let triangles: Vec<[u32; 3]> =
        quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    mesh(&positions, &triangles)
}

/// A torus of `n × m` quads, wrapped in both directions.
fn torus(n: u32, m: u32) -> Mesh {
    let (big, small) = (2.0f64, 0.7f64);
    let mut positions = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let u = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            let v = std::f64::consts::TAU * f64::from(j) / f64::from(m);
            let r = big + small * v.cos();
            positions.push([(r * u.cos()) as f32, (r * u.sin()) as f32, (small * v.sin()) as f32]);
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    let mut triangles = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    mesh(&positions, &triangles)
}

/// The outer surface of a set of unit voxels, wound outward.
fn voxels(cells: &[[i32; 3]]) -> Mesh {
    let filled: BTreeSet<[i32; 3]> = cells.iter().copied().collect();
    let mut index: HashMap<[i32; 3], u32> = HashMap::new();
    let mut m = Mesh::default();
    let mut vertex = |p: [i32; 3], m: &mut Mesh| {
        *index.entry(p).or_insert_with(|| {
            m.positions.push(p.map(|c| c as f32));
            m.positions.len() as u32 - 1
        })
    };
    for &c in &filled {
        for axis in 0..3 {
            for side in [0, 1] {
                let mut neighbour = c;
                neighbour[axis] += if side == 1 { 1 } else { -1 };
                if filled.contains(&neighbour) {
                    continue;
                }
                let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut base = c;
                base[axis] += side;
                let corner = |du: i32, dw: i32| {
                    let mut p = base;
                    p[u] += du;
                    p[w] += dw;
                    p
                };
                // e_u × e_w = e_axis: counter-clockwise seen from +axis.
                let mut q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                if side == 0 {
                    q.reverse();
                }
                let q = q.map(|p| vertex(p, &mut m));
                m.triangles.push([q[0], q[1], q[2]]);
                m.triangles.push([q[0], q[2], q[3]]);
            }
        }
    }
    m
}

fn assert_closed_genus(r: &Report, genus: i64) {
    assert!(r.is_closed_manifold(), "{r}");
    assert_eq!(r.components.len(), 1, "{r}");
    let c = &r.components[0];
    assert!(c.closed && c.orientable && c.consistently_oriented);
    assert_eq!(c.euler, 2 - 2 * genus);
    assert_eq!(c.genus, Some(genus));
    assert_eq!(c.outward, Some(true));
    assert_eq!(r.outward, Some(true));
    assert_eq!(r.edges * 2, r.faces * 3);
    assert_eq!(r.edge_degrees.keys().copied().collect::<Vec<_>>(), [2]);
}

#[test]
fn tetrahedron_is_a_closed_outward_sphere() {
    let r = check(&tetrahedron());
    assert_closed_genus(&r, 0);
    assert_eq!((r.vertices, r.faces, r.edges), (4, 4, 6));
    assert_eq!(r.components[0].euler, 2);
    assert!((r.volume.unwrap() - 1.0 / 6.0).abs() < 1e-12);
    assert!((r.area - (1.5 + 3f64.sqrt() / 2.0)).abs() < 1e-9);
    assert_eq!(r.degenerate_faces + r.duplicate_faces + r.unreferenced_vertices, 0);
}

#[test]
fn inward_tetrahedron() {
    let mut m = tetrahedron();
    for t in &mut m.triangles {
        t.swap(1, 2);
    }
    let r = check(&m);
    assert!(r.is_closed_manifold());
    assert_eq!(r.components[0].outward, Some(false));
    assert!((r.volume.unwrap() + 1.0 / 6.0).abs() < 1e-12);
    assert!(r.to_string().contains("oriented (inward)"), "{r}");
}

#[test]
fn cube_of_twelve_triangles() {
    let r = check(&cube());
    assert_closed_genus(&r, 0);
    assert_eq!((r.vertices, r.faces, r.edges), (8, 12, 18));
    assert!((r.volume.unwrap() - 1.0).abs() < 1e-12);
    assert!((r.area - 6.0).abs() < 1e-12);
    let b = r.bounds.unwrap();
    assert_eq!((b.min, b.max), ([0.0; 3], [1.0; 3]));
}

#[test]
fn torus_has_genus_one() {
    let r = check(&torus(12, 8));
    assert_closed_genus(&r, 1);
    assert_eq!((r.vertices, r.faces, r.edges), (96, 192, 288));
    assert_eq!(r.components[0].euler, 0);
    let exact = 2.0 * std::f64::consts::PI.powi(2) * 2.0 * 0.7 * 0.7;
    let v = r.volume.unwrap();
    assert!(v > 0.7 * exact && v < exact, "{v} vs {exact}");
}

#[test]
fn voxel_surfaces_of_genus_one_and_two() {
    let slab = |w: i32, h: i32, holes: &[[i32; 2]]| -> Vec<[i32; 3]> {
        (0..w)
            .flat_map(|x| (0..h).map(move |y| [x, y, 0]))
            .filter(|c| !holes.contains(&[c[0], c[1]]))
            .collect()
    };
    assert_closed_genus(&check(&voxels(&slab(1, 1, &[]))), 0);
    assert_closed_genus(&check(&voxels(&slab(3, 3, &[[1, 1]]))), 1);
    let r = check(&voxels(&slab(3, 5, &[[1, 1], [1, 3]])));
    assert_closed_genus(&r, 2);
    assert_eq!(r.components[0].euler, -2);
    assert!((r.volume.unwrap() - 13.0).abs() < 1e-9);
    assert!(r.to_string().contains("genus 2  closed, oriented (outward)"), "{r}");
}

#[test]
fn two_disjoint_tetrahedra_are_two_components() {
    let t = tetrahedron();
    let r = check(&union(&t, &translated(&t, [5.0, 0.0, 0.0])));
    assert!(r.is_closed_manifold());
    assert_eq!(r.components.len(), 2);
    for c in &r.components {
        assert_eq!((c.faces, c.vertices, c.edges, c.euler, c.genus), (4, 4, 6, 2, Some(0)));
    }
    assert_eq!(r.components[0].first_face, 0);
    assert_eq!(r.components[1].first_face, 4);
    assert!((r.volume.unwrap() - 2.0 / 6.0).abs() < 1e-12);
}

#[test]
fn open_square() {
    let m = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2], [0, 2, 3]],
    );
    let r = check(&m);
    assert!(!r.is_closed_manifold());
    assert_eq!(r.boundary_edges, 4);
    assert_eq!(r.edge_degrees.get(&1), Some(&4));
    assert_eq!(r.edge_degrees.get(&2), Some(&1));
    assert_eq!(r.non_manifold_vertices, 0);
    let c = &r.components[0];
    assert!(!c.closed && c.consistently_oriented);
    assert_eq!((c.boundary_edges, c.boundary_loops, c.euler, c.genus), (4, 1, 1, None));
    assert_eq!((c.volume, r.volume, r.outward), (None, None, None));
    assert!((r.area - 1.0).abs() < 1e-12);
    let text = r.to_string();
    assert!(text.contains("open (4 boundary edges, 1 loop)"), "{text}");
    assert!(text.contains("verdict       not a closed manifold: 4 boundary edges"), "{text}");
}

#[test]
fn annulus_has_two_boundary_loops() {
    // A 4 × 4 grid of quads without its middle 2 × 2.
    let positions: Vec<[f32; 3]> = (0..25).map(|i| [(i % 5) as f32, (i / 5) as f32, 0.0]).collect();
    let mut triangles = Vec::new();
    for y in 0..4u32 {
        for x in 0..4u32 {
            if (1..3).contains(&x) && (1..3).contains(&y) {
                continue;
            }
            let a = y * 5 + x;
            triangles.push([a, a + 1, a + 6]);
            triangles.push([a, a + 6, a + 5]);
        }
    }
    let r = check(&mesh(&positions, &triangles));
    let c = &r.components[0];
    assert_eq!((c.boundary_loops, c.euler, r.unreferenced_vertices), (2, 0, 1));
}

#[test]
fn flipped_face_is_inconsistent() {
    let mut m = tetrahedron();
    m.triangles[3].swap(0, 1);
    let r = check(&m);
    assert!(!r.is_closed_manifold());
    assert_eq!(r.inconsistent_edges, 3);
    assert!(!r.consistently_oriented && r.orientable);
    let c = &r.components[0];
    assert!(c.closed && !c.consistently_oriented && c.orientable);
    assert_eq!((c.genus, c.volume, c.outward), (Some(0), None, None));
    assert!(r.to_string().contains("orientation   inconsistent (3 edges)"), "{r}");
}

#[test]
fn moebius_strip_is_not_orientable() {
    let n = 8u32;
    let mut positions = Vec::new();
    for i in 0..n {
        let u = std::f32::consts::TAU * i as f32 / n as f32;
        for s in [-0.3f32, 0.3] {
            let r = 1.0 + s * (u / 2.0).cos();
            positions.push([r * u.cos(), r * u.sin(), s * (u / 2.0).sin()]);
        }
    }
    let mut triangles = Vec::new();
    for i in 0..n {
        let (a, b) = (2 * i, 2 * i + 1);
        // The last strip joins the first with a half twist.
        let (c, d) = if i + 1 == n { (1, 0) } else { (2 * i + 2, 2 * i + 3) };
        triangles.push([a, c, d]);
        triangles.push([a, d, b]);
    }
    let r = check(&mesh(&positions, &triangles));
    assert!(!r.orientable && !r.consistently_oriented);
    let c = &r.components[0];
    assert!(!c.orientable && !c.closed);
    assert_eq!((c.euler, c.boundary_loops, c.boundary_edges), (0, 1, 2 * n as usize));
    assert!(r.to_string().contains("non-orientable"), "{r}");
}

#[test]
fn three_triangles_on_one_edge_are_non_manifold() {
    let m = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, -1.0, 0.0], [0.5, 0.0, 1.0]],
        &[[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let r = check(&m);
    assert_eq!(r.edge_degrees.get(&3), Some(&1));
    assert_eq!(r.non_manifold_edges, 1);
    assert_eq!(r.boundary_edges, 6);
    assert_eq!(r.non_manifold_vertices, 2);
    assert_eq!(r.components.len(), 1);
    assert!(!r.components[0].closed);
    assert!(!r.is_closed_manifold());
    assert!(r.to_string().contains("≥3: 1 (3: 1)"), "{r}");
}

#[test]
fn tetrahedra_sharing_a_vertex_make_a_non_manifold_vertex() {
    // The tetrahedron and its mirror image through the origin (re-wound to face outward),
    // sharing vertex 0 only.
    let t = tetrahedron();
    let mut other = t.clone();
    for p in &mut other.positions {
        *p = p.map(|c| -c);
    }
    for tri in &mut other.triangles {
        tri.swap(1, 2);
    }
    let mut m = union(&t, &other);
    for i in m.triangles[4..].iter_mut().flatten() {
        if *i == 4 {
            *i = 0;
        }
    }
    let r = check(&m);
    assert_eq!(r.non_manifold_vertices, 1);
    assert_eq!((r.non_manifold_edges, r.boundary_edges), (0, 0));
    assert_eq!(r.unreferenced_vertices, 1);
    assert_eq!(r.components.len(), 2);
    for c in &r.components {
        assert_eq!(
            (c.euler, c.genus, c.non_manifold_vertices, c.outward),
            (2, Some(0), 0, Some(true))
        );
    }
    assert!(!r.is_closed_manifold());
    assert!(r.consistently_oriented);
    assert!(r.to_string().contains("non-manifold  0 edges, 1 vertices"), "{r}");
}

#[test]
fn pinched_torus_vertex_is_reported_per_component() {
    // Two cones sharing their apex, joined along their rims by a band: a torus pinched at
    // the apex; one component whose apex has two fans.
    let n = 6u32;
    let mut positions = vec![[0.0f32, 0.0, 0.0]];
    for z in [1.0f32, -1.0] {
        for i in 0..n {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            positions.push([a.cos(), a.sin(), z]);
        }
    }
    let top = |i: u32| 1 + i % n;
    let bottom = |i: u32| 1 + n + i % n;
    let mut triangles = Vec::new();
    for i in 0..n {
        triangles.push([0, top(i + 1), top(i)]);
        triangles.push([0, bottom(i), bottom(i + 1)]);
        triangles.push([top(i), top(i + 1), bottom(i + 1)]);
        triangles.push([top(i), bottom(i + 1), bottom(i)]);
    }
    let r = check(&mesh(&positions, &triangles));
    assert_eq!((r.boundary_edges, r.non_manifold_edges, r.non_manifold_vertices), (0, 0, 1));
    assert_eq!(r.components.len(), 1);
    let c = &r.components[0];
    assert!(c.closed && c.consistently_oriented);
    assert_eq!((c.non_manifold_vertices, c.genus, c.euler), (1, None, 1));
    assert!(!c.is_closed_manifold());
}

#[test]
fn duplicate_face_is_counted() {
    let mut m = tetrahedron();
    m.triangles.push([2, 1, 0]);
    m.triangles.push([1, 0, 2]);
    let r = check(&m);
    assert_eq!(r.duplicate_faces, 2);
    assert!(r.to_string().contains("duplicates    2"), "{r}");
}

#[test]
fn degenerate_faces_are_counted_by_kind() {
    let mut m = tetrahedron();
    m.positions.push([0.5, 0.0, 0.0]); // on the edge 0-1
    m.triangles.push([0, 0, 1]);
    m.triangles.push([0, 1, 4]);
    m.triangles.push([4, 4, 4]);
    let r = check(&m);
    assert_eq!(r.faces_with_repeated_vertex, 2);
    assert_eq!(r.zero_area_faces, 1);
    assert_eq!(r.degenerate_faces, 3);
    assert!(!r.is_closed_manifold());
    assert!(r.to_string().contains("degenerate    3 (2 repeated-vertex, 1 zero-area)"), "{r}");
}

#[test]
fn out_of_range_faces_are_counted_not_fatal() {
    let mut m = tetrahedron();
    m.triangles.push([0, 1, 17]);
    let r = check(&m);
    assert_eq!(r.out_of_range_faces, 1);
    assert_eq!(r.components.len(), 1);
    assert!(!r.is_closed_manifold());
    assert_eq!(r.volume, None);
}

#[test]
fn empty_mesh() {
    let r = check(&Mesh::default());
    assert_eq!((r.vertices, r.faces, r.edges, r.components.len()), (0, 0, 0, 0));
    assert!(!r.is_closed_manifold());
    assert_eq!((r.bounds, r.volume), (None, None));
    assert!(r.to_string().contains("no faces"));
}

#[test]
fn labels_and_curves_are_counted() {
    let mut m = cube();
    m.labels = (0..12).map(|i| if i < 4 { RegionPair(1, 2) } else { RegionPair(0, 1) }).collect();
    m.curves.push(skelform_mesh::CurveEdge {
        v: [0, 1],
        label: skelform_mesh::RegionTriple([0, 1, 2]),
    });
    let r = check(&m);
    assert_eq!(r.labels.len(), 2);
    assert_eq!((r.labels[0].label, r.labels[0].triangles), (RegionPair(0, 1), 8));
    assert_eq!((r.labels[1].label, r.labels[1].triangles), (RegionPair(1, 2), 4));
    assert_eq!(r.curves, 1);
    let text = r.to_string();
    assert!(text.contains("labels        0_1: 8  1_2: 4"), "{text}");
    assert!(text.contains("curves        1 segments"), "{text}");
}

#[test]
fn text_and_json_reports() {
    let r = check(&torus(12, 8));
    let text = r.to_string();
    let expected = [
        "vertices      96 (0 unreferenced)",
        "faces         192",
        "edges         288   degree 1: 0  2: 288  ≥3: 0",
        "non-manifold  0 edges, 0 vertices",
        "components    1",
        "  #0  faces 192  V 96  E 288  χ 0  genus 1  closed, oriented (outward)",
        "orientation   consistent, outward",
        "degenerate    0 (0 repeated-vertex, 0 zero-area)",
        "duplicates    0",
        "verdict       closed manifold",
    ];
    for line in expected {
        assert!(text.lines().any(|l| l == line), "missing {line:?} in\n{text}");
    }
    let json: serde_json::Value = serde_json::to_value(&r).unwrap();
    assert_eq!(json["faces"], 192);
    assert_eq!(json["edge_degrees"]["2"], 288);
    assert_eq!(json["components"][0]["genus"], 1);
    assert_eq!(json["components"][0]["euler"], 0);
    assert_eq!(json["consistently_oriented"], true);
    assert_eq!(json["outward"], true);
}

#[test]
fn many_components_are_summarised() {
    let t = tetrahedron();
    let mut m = Mesh::default();
    for i in 0..14 {
        m = union(&m, &translated(&t, [3.0 * i as f32, 0.0, 0.0]));
    }
    let r = check(&m);
    assert_eq!(r.components.len(), 14);
    assert!(r.to_string().contains("  ... and 4 more"), "{r}");
}

#[test]
fn large_mesh_is_checked_correctly() {
    // 2 × 400 × 250 = 200 000 triangles (speed is measured in `benches/mesh.rs`).
    let m = torus(400, 250);
    let r = check(&m);
    assert_closed_genus(&r, 1);
    assert_eq!(r.faces, 200_000);
}

/// The distinct undirected edges of faces with distinct, in-range indices, by brute force.
fn brute_force_edges(m: &Mesh) -> BTreeSet<(u32, u32)> {
    let n = m.positions.len() as u32;
    let mut edges = BTreeSet::new();
    for t in &m.triangles {
        if t.iter().any(|&i| i >= n) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    edges
}

proptest! {
    #[test]
    fn random_meshes_never_panic_and_add_up(
        positions in prop::collection::vec(prop::array::uniform3(-2.0f32..2.0), 0..12),
        triangles in prop::collection::vec(prop::array::uniform3(0u32..14), 0..40),
    ) {
        let m = Mesh { positions, triangles, ..Mesh::default() };
        let r = check(&m);
        prop_assert_eq!(r.edge_degrees.values().sum::<usize>(), r.edges);
        prop_assert_eq!(r.edges, brute_force_edges(&m).len());
        let sides: usize = r.edge_degrees.iter().map(|(d, n)| d * n).sum();
        let valid = r.faces - r.out_of_range_faces - r.faces_with_repeated_vertex;
        prop_assert_eq!(sides, 3 * valid);
        prop_assert_eq!(r.components.iter().map(|c| c.faces).sum::<usize>(), valid);
        prop_assert_eq!(r.components.iter().map(|c| c.edges).sum::<usize>(), r.edges);
        prop_assert_eq!(r.components.iter().map(|c| c.boundary_edges).sum::<usize>(), r.boundary_edges);
        prop_assert_eq!(r.degenerate_faces, r.faces_with_repeated_vertex + r.zero_area_faces);
        for c in &r.components {
            prop_assert_eq!(c.euler, c.vertices as i64 - c.edges as i64 + c.faces as i64);
            prop_assert!(c.genus.is_none() || c.closed);
        }
        let _ = r.to_string();
        let _ = serde_json::to_string(&r).unwrap();
    }
}

/// Three sheets meeting along an edge, with each sheet's vertices duplicated (as the
/// non-manifold polygonizer writes them): welding shows the edge of degree 3.
#[test]
fn welding_joins_duplicated_sheets_along_their_curve() {
    use skelform_mesh::check::{check, check_welded, weld};
    use skelform_mesh::{CurveEdge, RegionPair, RegionTriple};
    let mut m = Mesh::default();
    let apexes = [[1.0, 0.0, 0.0], [-0.5, 0.8, 0.0], [-0.5, -0.8, 0.0]];
    for (i, apex) in apexes.into_iter().enumerate() {
        let base = m.positions.len() as u32;
        m.positions.extend([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], apex]);
        m.triangles.push([base, base + 1, base + 2]);
        m.labels.push(RegionPair(i as u32, 3));
    }
    // The shared edge as a curve, on the first sheet's copies, plus a dangling piece.
    m.curves.push(CurveEdge { v: [0, 1], label: RegionTriple([0, 1, 2]) });
    m.curves.push(CurveEdge { v: [1, 2], label: RegionTriple([0, 1, 3]) });
    let plain = check(&m);
    assert_eq!(plain.edge_degrees.get(&3), None);
    assert_eq!(plain.welded_vertices, None);
    let (w, merged) = weld(&m, 0.0);
    assert_eq!((w.positions.len(), merged), (5, 4));
    let r = check_welded(&m, 1e-6);
    assert_eq!(r.welded_vertices, Some(4));
    assert_eq!(r.edge_degrees.get(&3), Some(&1));
    assert_eq!(r.edge_degrees.get(&1), Some(&6));
    assert_eq!(r.labels.len(), 3);
    assert_eq!(r.curve_labels.len(), 2);
    assert_eq!(r.curve_labels[0].open_ends, 2, "one segment has two ends");
    assert!(r.to_string().contains("welded        4"));
    // A tolerance joins near but not equal points too.
    let mut near = m.clone();
    near.positions[3][0] += 1e-4;
    assert_eq!(weld(&near, 0.0).1, 3);
    assert_eq!(weld(&near, 1e-3).1, 4);
}

#[test]
fn crossing_triangles_are_found_and_neighbours_are_not() {
    use skelform_mesh::check::crossings;
    // Two closed tetrahedra apart, sharing nothing: no crossings; the closed mesh's own
    // neighbours (sharing edges and vertices) never count.
    let t = tetrahedron();
    assert!(crossings(&t, 1e-9).is_empty());
    // A triangle piercing a face of the tetrahedron.
    let mut m = t.clone();
    let n = m.positions.len() as u32;
    m.positions.extend([[0.2, 0.2, -0.5], [0.3, 0.2, 0.5], [0.2, 0.3, 0.5]]);
    m.triangles.push([n, n + 1, n + 2]);
    let c = crossings(&m, 1e-9);
    assert!(c.contains(&(0, 4)), "{c:?}");
    // Touching within the tolerance is not crossing: a triangle lying on the face z = 0.
    let mut m = t.clone();
    m.positions.extend([[0.1, 0.1, 0.0], [0.3, 0.1, 0.0], [0.1, 0.3, 0.0]]);
    m.triangles.push([n, n + 1, n + 2]);
    assert!(crossings(&m, 1e-9).is_empty());
    // Sharing one vertex (as a duplicated copy at the same position) and folding through.
    let mut m = mesh(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]);
    m.positions.extend([[0.0, 0.0, 0.0], [0.4, 0.4, 1.0], [0.4, 0.4, -1.0]]);
    m.triangles.push([3, 4, 5]);
    assert_eq!(crossings(&m, 1e-9), vec![(0, 1)]);
    // The same fold moved off the first triangle does not cross.
    m.positions[4] = [-0.4, -0.4, 1.0];
    m.positions[5] = [-0.4, -0.4, -1.0];
    assert!(crossings(&m, 1e-9).is_empty());
}

#[test]
fn coincident_faces_are_found_by_position_whatever_their_indices_and_winding() {
    // A square sheet, and a copy of it on its own vertices, wound the other way: what a
    // symmetric partition made when two region pairs claimed the same wall. No index is
    // shared, so `duplicate_faces` cannot see it.
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let sheet = mesh(&p, &[[0, 1, 2], [0, 2, 3]]);
    let flipped = mesh(&p, &[[0, 2, 1], [0, 3, 2]]);
    let r = check(&union(&sheet, &flipped));
    assert_eq!(r.duplicate_faces, 0);
    assert_eq!(r.coincident_faces, 2);
    assert!(r.to_string().contains("2 coincident faces"), "{r}");
    // Clean shapes have none, and no folds.
    for m in [cube(), tetrahedron(), torus(12, 8)] {
        let r = check(&m);
        assert_eq!((r.coincident_faces, r.folded_edges), (0, 0), "{r}");
    }
}

#[test]
fn a_surface_that_folds_back_onto_itself_has_folded_edges() {
    // Two triangles sharing the edge 0–1, consistently wound, the second folded over onto
    // the first (its far vertex on the first's side): normals opposite.
    let folded = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, 0.8, 0.0]],
        &[[0, 1, 2], [1, 0, 3]],
    );
    let r = check(&folded);
    assert_eq!(r.folded_edges, 1, "{r}");
    assert!(r.consistently_oriented);
    // Unfolded (the far vertex across the edge) it is a flat sheet; bent by 90° it is a
    // crease, not a fold.
    let flat = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, -0.8, 0.0]],
        &[[0, 1, 2], [1, 0, 3]],
    );
    assert_eq!(check(&flat).folded_edges, 0);
    let bent = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, 0.0, 0.8]],
        &[[0, 1, 2], [1, 0, 3]],
    );
    assert_eq!(check(&bent).folded_edges, 0);
    // Wound inconsistently and folded: still a fold (the winding is compared, not assumed).
    let inconsistent = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, 0.8, 0.0]],
        &[[0, 1, 2], [0, 1, 3]],
    );
    let r = check(&inconsistent);
    assert_eq!(r.folded_edges, 1, "{r}");
    assert!(!r.consistently_oriented);
}
