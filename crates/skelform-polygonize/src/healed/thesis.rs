//! The thesis's own healing, cube by cube (Nguyen 2016, §4.3; [`Healing::Thesis`](super::Healing::Thesis)).
//!
//! 1. **Standard marching cubes**: each cube's crossings are joined by one fixed rule on
//!    every ambiguous face, with no interior test and no interior vertex (a fan over each
//!    loop), bit 0 for `f ≤ 0` as §3.3.1.1 says. The thesis does not print its table. Ours
//!    joins the corners with `f ≤ 0` across every face with four crossings (as the widely
//!    copied Bourke table does on its class 3 and 6 faces, read with the thesis's bits); it
//!    gives the standard MC counts of all four surfaces exactly. What the counts settle:
//!    Zeppelin's two class-6 cubes have their three lone corners on opposite sides, so a
//!    table that treats a configuration and its complement alike (three triangles for
//!    every class-6 cube) gives 4042, not the thesis's 4044, while one fixed sign joined
//!    (either sign) gives 4044; Diabolo's 9070 needs no interior tunnels (ours, MC33, give
//!    9254). Which sign is joined the counts cannot tell.
//! 2. **Critical cubes** (eq. 4.1): a cube is critical when a vertex of its triangles passes
//!    the critical test ([`Options::epsilon`]; the thesis's is `|f_x| + |f_y| + |f_z| < 0.2`).
//!    Only critical cubes of classes 10, 12 and 13 are healed (§4.2).
//! 3. **Self-intersection points** (§4.3.2): on each face with four crossings, where the two
//!    segments joining opposite crossings meet (the thesis finds it with a secant method; the
//!    segments are straight, so here in closed form). A class-13 cube has one more inside:
//!    where the three segments joining opposite face points meet (the least-squares point of
//!    their lines, which is the thesis's point of "any two" whenever they meet; the thesis
//!    does not say which two).
//! 4. **Pieces** (fig. 4.7): the surface in the cube is cut by the spine (the segment between
//!    the two face points of a class 10 or 12 cube, the six segments from the interior point
//!    to the face points of a class 13 cube) into planar pieces of three, four or five
//!    points. A piece is found by walking from a face point along the cube's boundary: to a
//!    crossing of its face, then from crossing to crossing across faces with two crossings,
//!    to the face point of the next face with four. Each piece is fanned onto the spine:
//!    the first half of its crossings to the spine's first end, the rest to its second (a
//!    class-13 piece is fanned from the interior point). That gives 8 triangles per class
//!    10 or 12 cube and 24 per class 13 cube, the thesis's counts; which crossing goes to
//!    which end (the thesis's "priority by saving order", fig. 4.5) is our reading, and does
//!    not change the counts.
//! 5. **Coincident points** (fig. 4.8): a self-intersection point on a cube edge or corner
//!    is the crossing there; triangles with two equal vertices are skipped
//!    ([`Stats::skipped_triangles`]).
//!
//! What it does not do, as in the thesis: a crossing whose faces do not show four crossings
//! (one off the lattice's symmetry, or a cube of another class) keeps its marching-cubes
//! triangles, so the pieces do not meet the neighbouring cubes' triangles there (holes and
//! stray flaps); there is no search for the curve and no check of the result. The zone
//! healing ([`Healing::Zone`](super::Healing::Zone)) is the default for that reason.

use std::time::Instant;

use glam::{DMat3, DVec2, DVec3};
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_field::Field;
use skelform_mesh::{CurveEdge, Mesh};

use super::config::{self, ThesisClass};
use super::{
    Error, Options, SELF_INTERSECTION, Sampled, Stats, critical_vertices, gradients, report,
    sample_lattice, vertex_normals,
};
use crate::grid::cube::{CORNERS, EDGES, FACES, edge_axis, edge_between, other_axes};
use crate::grid::table::{ambiguous_faces, loops_for};
use crate::lattice::memory::{check, vec_bytes};
use crate::refine::{Bracket, RootOptions, refine_roots};

/// A cube the surface passes through.
struct SurfaceCube {
    /// Lattice coordinates of its lowest corner.
    at: [usize; 3],
    /// Corners with `f ≤ 0` (our corner numbering).
    inside: u8,
    /// Its marching-cubes triangles: `triangles[first..first + count]`.
    first: u32,
    count: u8,
    /// The vertex on each crossed edge (`u32::MAX` where the edge is not crossed).
    ids: [u32; 12],
}

/// The two faces of the cube that hold edge `e`.
fn faces_of_edge(e: usize) -> [usize; 2] {
    let [c0, _] = EDGES[e];
    let (b, c) = other_axes(edge_axis(e));
    [2 * b + CORNERS[c0][b], 2 * c + CORNERS[c0][c]]
}

/// The four edges round face `f`, in its corners' order.
fn face_edges(f: usize) -> [usize; 4] {
    let q = FACES[f];
    std::array::from_fn(|k| edge_between(q[k], q[(k + 1) % 4]))
}

/// Where the segments `a0–a1` and `b0–b1` meet, in the plane of face axis `axis`.
fn segments_meet(axis: usize, a0: DVec3, a1: DVec3, b0: DVec3, b1: DVec3) -> Option<DVec3> {
    let (u, v) = other_axes(axis);
    let two = |p: DVec3| DVec2::new(p[u], p[v]);
    let (da, db) = (two(a1) - two(a0), two(b1) - two(b0));
    let den = da.perp_dot(db);
    if den.abs() <= 1e-300 {
        return None;
    }
    let s = (two(b0) - two(a0)).perp_dot(db) / den;
    let x = two(a0) + da * s;
    let mut p = a0;
    p[u] = x.x;
    p[v] = x.y;
    p.is_finite().then_some(p)
}

/// The point nearest (least squares) to the lines through the given segments.
fn nearest_to_lines(segments: &[(DVec3, DVec3)]) -> Option<DVec3> {
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for &(p, q) in segments {
        let d = (q - p).normalize_or_zero();
        if d == DVec3::ZERO {
            continue;
        }
        // Projection onto the plane across the line.
        let m = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += m;
        b += m * p;
    }
    if a.determinant().abs() <= 1e-12 {
        return None;
    }
    let x = a.inverse() * b;
    x.is_finite().then_some(x)
}

/// Builds positions, vertices and triangles as the thesis does; see the module text.
pub(super) fn polygonize(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    let lattice = &options.lattice;
    let control = &lattice.control;
    let Sampled { grid, volume, needed, mut stats } = sample_lattice(field, options)?;
    let h = grid.cell;

    // 1. Standard marching cubes: the corners with f ≤ 0 joined on every ambiguous face.
    let t = Instant::now();
    let loops: Vec<Vec<Vec<u8>>> =
        (0..=255u8).map(|inside| loops_for(inside, ambiguous_faces(inside))).collect();
    let [nx, ny, nz] = grid.dims;
    let cells = grid.dims.iter().map(|&d| d as u64 - 1).product::<u64>();
    let mut edge_vertex: FxHashMap<u64, u32> = FxHashMap::default();
    let mut brackets: Vec<Bracket> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut cubes: Vec<SurfaceCube> = Vec::new();
    for k in 0..nz - 1 {
        report(control, "marching cubes", k as u64, (nz - 1) as u64)?;
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let at = [i, j, k];
                let corner = |c: usize| {
                    let o = CORNERS[c];
                    [i + o[0], j + o[1], k + o[2]]
                };
                let value = |c: usize| {
                    let p = corner(c);
                    volume.get(p[0], p[1], p[2])
                };
                let mut inside = 0u8;
                for c in 0..8 {
                    if value(c) <= 0.0 {
                        inside |= 1 << c;
                    }
                }
                if inside == 0 || inside == 255 {
                    continue;
                }
                let mut ids = [u32::MAX; 12];
                for (e, &[c0, c1]) in EDGES.iter().enumerate() {
                    if (inside >> c0) & 1 == (inside >> c1) & 1 {
                        continue;
                    }
                    let p0 = corner(c0);
                    let key = grid.index(p0[0], p0[1], p0[2]) as u64 * 3 + edge_axis(e) as u64;
                    let next = brackets.len() as u32;
                    let id = *edge_vertex.entry(key).or_insert(next);
                    if id == next {
                        let p1 = corner(c1);
                        let (f0, f1) = (value(c0) as f64, value(c1) as f64);
                        let t = if f0 == f1 { 0.5 } else { (f0 / (f0 - f1)).clamp(0.0, 1.0) };
                        brackets.push(Bracket {
                            p0: grid.point(p0[0], p0[1], p0[2]),
                            p1: grid.point(p1[0], p1[1], p1[2]),
                            f0,
                            f1,
                            t,
                        });
                    }
                    ids[e] = id;
                }
                let first = triangles.len() as u32;
                for l in &loops[inside as usize] {
                    for m in 1..l.len().saturating_sub(1) {
                        triangles.push([
                            ids[l[0] as usize],
                            ids[l[m] as usize],
                            ids[l[m + 1] as usize],
                        ]);
                    }
                }
                let count = (triangles.len() as u32 - first) as u8;
                cubes.push(SurfaceCube { at, inside, first, count, ids });
            }
        }
        let held = needed
            + vec_bytes(&brackets)
            + vec_bytes(&triangles)
            + vec_bytes(&cubes)
            + crate::lattice::memory::map_bytes(&edge_vertex);
        check("healed", held, lattice.max_memory, cells)?;
    }
    stats.extraction = t.elapsed();
    stats.mc_triangles = triangles.len();

    let t = Instant::now();
    if lattice.refine {
        let roots = RootOptions { tolerance: lattice.tolerance, ..RootOptions::default() };
        stats.refine_evaluations = refine_roots(field, &mut brackets, &roots);
    }
    let mut positions: Vec<DVec3> = brackets.iter().map(|b| b.p0.lerp(b.p1, b.t)).collect();
    drop(brackets);
    stats.refinement = t.elapsed();
    if control.is_cancelled() {
        return Err(Error::Cancelled);
    }

    // 2. Gradients (normals and the critical test) and the critical cubes.
    let t = Instant::now();
    let grads = gradients(field, &positions);
    stats.normal_evaluations = positions.len() as u64;
    let critical = critical_vertices(field, &positions, &grads, options.epsilon, h, &mut stats);
    stats.critical_vertices = critical.iter().filter(|&&c| c).count();
    let mut healed: Vec<(usize, ThesisClass)> = Vec::new();
    for (n, cube) in cubes.iter().enumerate() {
        let tris = &triangles[cube.first as usize..cube.first as usize + cube.count as usize];
        if !tris.iter().flatten().any(|&v| critical[v as usize]) {
            continue;
        }
        match config::thesis_class(cube.inside) {
            Some(class) => {
                match class {
                    ThesisClass::Ten => stats.critical_cubes.class10 += 1,
                    ThesisClass::Twelve => stats.critical_cubes.class12 += 1,
                    ThesisClass::Thirteen => stats.critical_cubes.class13 += 1,
                }
                healed.push((n, class));
            }
            None => stats.critical_cubes.other += 1,
        }
    }
    stats.search = t.elapsed();

    // 3–5. Self-intersection points and the pieces fanned onto the spines.
    let t = Instant::now();
    let n_mc = positions.len() as u32;
    let tol = 1e-9 * h;
    let mut face_vertex: FxHashMap<u64, u32> = FxHashMap::default();
    let mut heal_tris: Vec<[u32; 3]> = Vec::new();
    let mut curve_edges: Vec<[u32; 2]> = Vec::new();
    let mut removed = vec![false; cubes.len()];
    for &(n, class) in &healed {
        let cube = &cubes[n];
        removed[n] = true;
        let ids = cube.ids;
        let amb = ambiguous_faces(cube.inside);
        // The self-intersection point of each ambiguous face (a crossing where it is one).
        let mut face_point = [u32::MAX; 6];
        for f in (0..6).filter(|f| amb & (1 << f) != 0) {
            let (axis, side) = (f / 2, f % 2);
            let mut low = cube.at;
            low[axis] += side;
            let key = grid.index(low[0], low[1], low[2]) as u64 * 3 + axis as u64;
            if let Some(&id) = face_vertex.get(&key) {
                face_point[f] = id;
                continue;
            }
            let e = face_edges(f).map(|e| ids[e]);
            let p = e.map(|v| positions[v as usize]);
            let x = segments_meet(axis, p[0], p[2], p[1], p[3])
                .unwrap_or_else(|| (p[0] + p[1] + p[2] + p[3]) * 0.25);
            let id = match (0..4).find(|&m| (p[m] - x).length() <= tol) {
                Some(m) => e[m],
                None => {
                    positions.push(x);
                    positions.len() as u32 - 1
                }
            };
            face_vertex.insert(key, id);
            face_point[f] = id;
        }
        // Class 13: the point inside where the three face-point segments meet.
        let center = if class == ThesisClass::Thirteen {
            let pf = |f: usize| positions[face_point[f] as usize];
            let segs = [(pf(0), pf(1)), (pf(2), pf(3)), (pf(4), pf(5))];
            let x = nearest_to_lines(&segs).unwrap_or_else(|| (0..6).map(pf).sum::<DVec3>() / 6.0);
            let known = face_point.iter().chain(ids.iter()).filter(|&&v| v != u32::MAX);
            match known.copied().find(|&v| (positions[v as usize] - x).length() <= tol) {
                Some(v) => Some(v),
                None => {
                    positions.push(x);
                    Some(positions.len() as u32 - 1)
                }
            }
        } else {
            None
        };
        // The pieces: walks from a face point to the next, across faces with two crossings.
        let mut used = [false; 12];
        let mut pieces: Vec<(usize, Vec<usize>, usize)> = Vec::new();
        for f in (0..6).filter(|f| amb & (1 << f) != 0) {
            for e0 in face_edges(f) {
                if used[e0] {
                    continue;
                }
                let mut chain = vec![e0];
                let (mut e, mut from) = (e0, f);
                let end = loop {
                    let [a, b] = faces_of_edge(e);
                    let g = if a == from { b } else { a };
                    if amb & (1 << g) != 0 {
                        break g;
                    }
                    let next = face_edges(g).into_iter().find(|&x| x != e && ids[x] != u32::MAX);
                    match next {
                        Some(x) if chain.len() < 12 => {
                            chain.push(x);
                            (e, from) = (x, g);
                        }
                        _ => break usize::MAX,
                    }
                };
                if end == usize::MAX {
                    continue;
                }
                used[e0] = true;
                used[e] = true;
                pieces.push((f, chain, end));
            }
        }
        for (start, chain, end) in pieces {
            let (s, t) = (face_point[start], face_point[end]);
            let v: Vec<u32> = chain.iter().map(|&e| ids[e]).collect();
            let mut tris: Vec<[u32; 3]> = Vec::new();
            match center {
                Some(c) => {
                    tris.push([c, s, v[0]]);
                    for w in v.windows(2) {
                        tris.push([c, w[0], w[1]]);
                    }
                    tris.push([c, v[v.len() - 1], t]);
                }
                None if start == end => {
                    for w in v.windows(2) {
                        tris.push([s, w[0], w[1]]);
                    }
                }
                None => {
                    let m = v.len().div_ceil(2);
                    for i in 0..m - 1 {
                        tris.push([s, v[i], v[i + 1]]);
                    }
                    tris.push([s, v[m - 1], t]);
                    for i in m - 1..v.len() - 1 {
                        tris.push([t, v[i], v[i + 1]]);
                    }
                }
            }
            // Orientation: the piece's normal towards f > 0 (the gradient at its crossings).
            let normal: DVec3 = tris
                .iter()
                .map(|tr| {
                    let q = tr.map(|x| positions[x as usize]);
                    (q[1] - q[0]).cross(q[2] - q[0])
                })
                .sum();
            let grad: DVec3 = v.iter().map(|&x| grads[x as usize]).sum();
            let flip = normal.dot(grad) < 0.0;
            for tr in tris {
                if tr[0] == tr[1] || tr[1] == tr[2] || tr[0] == tr[2] {
                    stats.skipped_triangles += 1;
                    continue;
                }
                heal_tris.push(if flip { [tr[0], tr[2], tr[1]] } else { tr });
            }
        }
        // The spine: the self-intersection segments of this cube.
        match center {
            Some(c) => {
                for &p in &face_point {
                    curve_edges.push([c.min(p), c.max(p)]);
                }
            }
            None => {
                let mut fp = face_point.iter().copied().filter(|&p| p != u32::MAX);
                if let (Some(a), Some(b)) = (fp.next(), fp.next()) {
                    curve_edges.push([a.min(b), a.max(b)]);
                }
            }
        }
    }
    curve_edges.retain(|e| e[0] != e[1]);
    curve_edges.sort_unstable();
    curve_edges.dedup();
    stats.face_points = face_vertex.len();
    stats.healed_cubes = healed.len();
    stats.healing = t.elapsed();

    // The mesh: the kept marching-cubes triangles, then the healing ones.
    let t = Instant::now();
    let mut out: Vec<[u32; 3]> = Vec::with_capacity(triangles.len() + heal_tris.len());
    for (n, cube) in cubes.iter().enumerate() {
        if !removed[n] {
            out.extend_from_slice(
                &triangles[cube.first as usize..cube.first as usize + cube.count as usize],
            );
        }
    }
    drop(triangles);
    stats.kept_mc_triangles = out.len();
    stats.healing_triangles = heal_tris.len();
    out.extend_from_slice(&heal_tris);
    // Compact: only the vertices a triangle or a curve edge uses, in their order.
    let mut used = vec![false; positions.len()];
    for &v in out.iter().flatten().chain(curve_edges.iter().flatten()) {
        used[v as usize] = true;
    }
    let mut remap = vec![u32::MAX; positions.len()];
    let mut kept: Vec<DVec3> = Vec::new();
    let mut normals: Vec<DVec3> = Vec::new();
    // The gradient vanishes on a self-intersection: those vertices (and any other with no
    // gradient) take the mean of their triangles' normals below.
    let spine: FxHashSet<u32> = curve_edges.iter().flatten().copied().collect();
    for (i, &u) in used.iter().enumerate() {
        if u {
            remap[i] = kept.len() as u32;
            kept.push(positions[i]);
            let g = if (i as u32) < n_mc && !spine.contains(&(i as u32)) {
                grads[i].normalize_or_zero()
            } else {
                DVec3::ZERO
            };
            normals.push(g);
        }
    }
    let mut mesh = Mesh {
        triangles: out.iter().map(|t| t.map(|v| remap[v as usize])).collect(),
        positions: kept.iter().map(|p| p.as_vec3().to_array()).collect(),
        curves: curve_edges
            .iter()
            .map(|c| CurveEdge { v: c.map(|v| remap[v as usize]), label: SELF_INTERSECTION })
            .collect(),
        ..Mesh::default()
    };
    if lattice.normals && !mesh.triangles.is_empty() {
        mesh.normals = vertex_normals(normals, &kept, &mesh.triangles);
    }
    stats.normals = t.elapsed();
    stats.curve_edges = mesh.curves.len();
    stats.triangles = mesh.triangles.len();
    stats.vertices = mesh.positions.len();
    Ok((mesh, stats))
}
