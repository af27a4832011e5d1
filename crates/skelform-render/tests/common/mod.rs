//! Test meshes made here, so the renderer's tests need no polygonizer.
#![allow(dead_code)]

use std::collections::HashMap;

use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

/// A unit sphere about `centre` scaled by `r`: an icosahedron subdivided `levels` times,
/// wound outward, with exact normals.
pub fn icosphere(levels: u32, centre: [f32; 3], r: f32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let unit = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        p.map(|c| c / l)
    };
    for p in pos.iter_mut() {
        *p = unit(*p);
    }
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut m = |a: u32, b: u32, pos: &mut Vec<[f64; 3]>| {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                let (p, q) = (pos[a as usize], pos[b as usize]);
                pos.push(unit([(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0]));
                (pos.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let ab = m(a, b, &mut pos);
            let bc = m(b, c, &mut pos);
            let ca = m(c, a, &mut pos);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Mesh {
        positions: pos.iter().map(|p| [0, 1, 2].map(|k| centre[k] + r * p[k] as f32)).collect(),
        normals: pos.iter().map(|p| p.map(|c| c as f32)).collect(),
        triangles: tris,
        ..Mesh::default()
    }
}

/// The square `[-1, 1]²` in the plane `z = 0`, `n × n` quads, facing `+z`, labelled (1, 2)
/// where `x < split` and (1, 3) elsewhere (the split on a grid line), with a curve along
/// the split line labelled (1, 2, 3).
pub fn split_square(n: u32, split_column: u32) -> Mesh {
    let mut m = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let x = -1.0 + 2.0 * i as f32 / n as f32;
            let y = -1.0 + 2.0 * j as f32 / n as f32;
            m.positions.push([x, y, 0.0]);
            m.normals.push([0.0, 0.0, 1.0]);
        }
    }
    let v = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let label = if i < split_column { RegionPair(1, 2) } else { RegionPair(1, 3) };
            m.triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            m.triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            m.labels.extend([label, label]);
        }
    }
    for j in 0..n {
        m.curves.push(CurveEdge {
            v: [v(split_column, j), v(split_column, j + 1)],
            label: RegionTriple::new([1, 2, 3]),
        });
    }
    m
}

/// Appends `b` to `a`.
pub fn merge(mut a: Mesh, b: &Mesh) -> Mesh {
    let off = a.positions.len() as u32;
    a.positions.extend_from_slice(&b.positions);
    a.normals.extend_from_slice(&b.normals);
    a.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + off)));
    a.labels.extend_from_slice(&b.labels);
    a.curves.extend(b.curves.iter().map(|c| CurveEdge { v: c.v.map(|i| i + off), label: c.label }));
    a
}

/// Gives every triangle of `m` the label `l`.
pub fn labelled(mut m: Mesh, l: RegionPair) -> Mesh {
    m.labels = vec![l; m.triangles.len()];
    m
}

/// The mean of an sRGB pixel's channels.
pub fn brightness(p: [u8; 3]) -> f64 {
    (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0
}
