//! Welding coincident vertices: the non-manifold polygonizer gives each sheet its own copy of
//! a vertex (for its own normal), so topology is only seen after copies are identified.

use std::collections::HashMap;

use crate::mesh::{CurveEdge, Mesh};

/// Identifies vertices closer than `tolerance` (coincident copies: the non-manifold
/// polygonizer duplicates vertices per region pair, so each sheet has its own normal) and
/// returns the welded mesh and how many vertices were merged away. Triangles that collapse
/// are kept (the checker counts them as degenerate); normals are dropped (a welded vertex
/// has one per sheet). Deterministic: each vertex joins the lowest-numbered vertex within the
/// tolerance that is not itself joined to another.
///
/// Linear in the vertex count for any tolerance: vertices are hashed into cells of at least
/// the tolerance and at least 2⁻²⁰ of the mesh's extent, so a tiny (or zero) tolerance
/// cannot put every vertex into one cell, and only the 27 cells round a vertex are searched.
pub fn weld(mesh: &Mesh, tolerance: f32) -> (Mesh, usize) {
    let tol = f64::from(tolerance.max(0.0));
    let finite = || mesh.positions.iter().flatten().copied().filter(|x| x.is_finite());
    let lo = finite().fold(f32::INFINITY, f32::min);
    let hi = finite().fold(f32::NEG_INFINITY, f32::max);
    let (lo, extent) =
        if lo <= hi { (f64::from(lo), f64::from(hi) - f64::from(lo)) } else { (0.0, 0.0) };
    let cell = tol.max(extent * (-20f64).exp2()).max(f64::from(f32::MIN_POSITIVE));
    // Within ±2²⁰ (+1) cells of `lo` for finite coordinates; the rest share the edge cells.
    let key = |p: [f32; 3]| {
        p.map(|x| ((f64::from(x) - lo) / cell).floor().clamp(-1.0, f64::from(1 << 21)) as i64)
    };
    let mut buckets: HashMap<[i64; 3], Vec<u32>> = HashMap::with_capacity(mesh.positions.len());
    let mut rep: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let mut merged = 0;
    for (i, p) in mesh.positions.iter().enumerate() {
        let k = key(*p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = buckets.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                        continue;
                    };
                    for &j in list {
                        let q = mesh.positions[j as usize];
                        let d2: f64 =
                            (0..3).map(|a| (f64::from(p[a]) - f64::from(q[a])).powi(2)).sum();
                        if d2 <= tol * tol && found.is_none_or(|f| j < f) {
                            found = Some(j);
                        }
                    }
                    if tol == 0.0 && found.is_some() {
                        break 'search;
                    }
                }
            }
        }
        match found {
            Some(j) => {
                rep[i] = j;
                merged += 1;
            }
            None => buckets.entry(k).or_default().push(i as u32),
        }
    }
    // Renumber the kept vertices in order.
    let mut new_id = vec![u32::MAX; mesh.positions.len()];
    let mut out = Mesh::default();
    for (i, p) in mesh.positions.iter().enumerate() {
        if rep[i] == i as u32 {
            new_id[i] = out.positions.len() as u32;
            out.positions.push(*p);
        }
    }
    let map = |v: u32| new_id.get(v as usize).and_then(|_| new_id.get(rep[v as usize] as usize));
    for (f, t) in mesh.triangles.iter().enumerate() {
        // Out-of-range indices stay out of range, so the checker still counts them.
        let t = t.map(|v| map(v).copied().unwrap_or(u32::MAX));
        out.triangles.push(t);
        if let Some(l) = mesh.labels.get(f) {
            out.labels.push(*l);
        }
    }
    for c in &mesh.curves {
        if let (Some(&a), Some(&b)) = (map(c.v[0]), map(c.v[1])) {
            out.curves.push(CurveEdge { v: [a, b], label: c.label });
        }
    }
    (out, merged)
}
