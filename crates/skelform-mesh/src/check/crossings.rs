//! Triangles that pass through each other: what a polygonizer must never make, and what the
//! topology counts cannot see (a crossing leaves every edge with two faces).

use super::weld::weld;
use super::{V3, cross, dot, sub};
use crate::mesh::Mesh;

/// Pairs of triangles `(i, j)`, `i < j`, that cross each other: an edge of one passes
/// through the inside of the other, farther than `tolerance` from its plane on both sides and
/// from its sides. Triangles that share vertices (after welding coincident positions, so a
/// non-manifold mesh's per-sheet copies count as shared) are tested only away from what they
/// share: the edge opposite a shared vertex, none for a shared edge. Coplanar overlaps are not
/// reported. A uniform grid of about two mean edge lengths limits the tests to neighbours.
pub fn crossings(mesh: &Mesh, tolerance: f64) -> Vec<(u32, u32)> {
    let (welded, _) = weld(mesh, 0.0);
    let pos = |i: u32| welded.positions[i as usize].map(f64::from);
    let tris: Vec<(u32, [u32; 3])> = welded
        .triangles
        .iter()
        .enumerate()
        .filter(|(_, t)| {
            t.iter().all(|&v| (v as usize) < welded.positions.len())
                && t[0] != t[1]
                && t[1] != t[2]
                && t[0] != t[2]
        })
        .map(|(i, t)| (i as u32, *t))
        .collect();
    if tris.len() < 2 {
        return Vec::new();
    }
    let mut edge_sum = 0.0;
    for (_, t) in &tris {
        for k in 0..3 {
            let d = sub(pos(t[k]), pos(t[(k + 1) % 3]));
            edge_sum += dot(d, d).sqrt();
        }
    }
    let cell = (2.0 * edge_sum / (3.0 * tris.len() as f64)).max(f64::MIN_POSITIVE);
    let range = |t: &[u32; 3]| {
        let p = t.map(pos);
        let lo: [i64; 3] = std::array::from_fn(|a| {
            ((p[0][a].min(p[1][a]).min(p[2][a]) - tolerance) / cell).floor() as i64
        });
        let hi: [i64; 3] = std::array::from_fn(|a| {
            ((p[0][a].max(p[1][a]).max(p[2][a]) + tolerance) / cell).floor() as i64
        });
        (lo, hi)
    };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> =
        std::collections::HashMap::new();
    let ranges: Vec<([i64; 3], [i64; 3])> = tris.iter().map(|(_, t)| range(t)).collect();
    for (k, (lo, hi)) in ranges.iter().enumerate() {
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    grid.entry([x, y, z]).or_default().push(k);
                }
            }
        }
    }
    let mut out = Vec::new();
    let mut cells: Vec<(&[i64; 3], &Vec<usize>)> = grid.iter().collect();
    cells.sort_unstable_by_key(|(c, _)| **c);
    for (c, list) in cells {
        for (n, &i) in list.iter().enumerate() {
            for &j in &list[n + 1..] {
                // Test each pair once: in the lowest cell both ranges share.
                let (ri, rj) = (ranges[i], ranges[j]);
                let first: [i64; 3] = std::array::from_fn(|a| ri.0[a].max(rj.0[a]));
                if first != *c {
                    continue;
                }
                let (ti, tj) = (tris[i].1, tris[j].1);
                if triangles_cross(ti, tj, &pos, tolerance) {
                    let (a, b) = (tris[i].0, tris[j].0);
                    out.push((a.min(b), a.max(b)));
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// Whether two triangles (vertex ids, positions through `pos`) cross, away from what they
/// share.
fn triangles_cross(s: [u32; 3], t: [u32; 3], pos: &dyn Fn(u32) -> V3, tol: f64) -> bool {
    let shared = s.iter().filter(|v| t.contains(v)).count();
    let edges = |a: [u32; 3], other: [u32; 3]| -> Vec<(u32, u32)> {
        (0..3)
            .map(|k| (a[k], a[(k + 1) % 3]))
            .filter(|(u, v)| match shared {
                0 => true,
                // Only the edge opposite the shared vertex.
                1 => !other.contains(u) && !other.contains(v),
                _ => false,
            })
            .collect()
    };
    let crosses = |edges: Vec<(u32, u32)>, tri: [u32; 3]| {
        let [a, b, c] = tri.map(pos);
        edges.into_iter().any(|(u, v)| segment_crosses_triangle(pos(u), pos(v), a, b, c, tol))
    };
    crosses(edges(s, t), t) || crosses(edges(t, s), s)
}

/// Whether the segment `p q` passes through the triangle `a b c`: its ends farther than `tol`
/// from the plane on opposite sides, and the crossing point farther than `tol` inside each
/// side.
fn segment_crosses_triangle(p: V3, q: V3, a: V3, b: V3, c: V3, tol: f64) -> bool {
    let n = cross(sub(b, a), sub(c, a));
    let len = dot(n, n).sqrt();
    if len == 0.0 {
        return false;
    }
    let n = n.map(|x| x / len);
    let (dp, dq) = (dot(sub(p, a), n), dot(sub(q, a), n));
    if !((dp > tol && dq < -tol) || (dp < -tol && dq > tol)) {
        return false;
    }
    let s = dp / (dp - dq);
    let x = [0, 1, 2].map(|i| p[i] + (q[i] - p[i]) * s);
    [(a, b), (b, c), (c, a)].iter().all(|&(u, v)| {
        let e = sub(v, u);
        let el = dot(e, e).sqrt();
        el > 0.0 && dot(cross(e, sub(x, u)), n) / el > tol
    })
}
