//! Polygonizing one lattice cube: the part that every cube-based polygonizer shares.
//!
//! Given the eight corner values, [`polygonize_cube`] looks up the case table, decides the
//! ambiguous faces and the interior, and emits triangles through a [`CubeSink`], which owns
//! the vertices: the grid extractor keys them by lattice edge in dense arrays, the
//! continuation polygonizer in a hash map. Both therefore make exactly the same surface.

use super::cube::{EDGES, FACES, edge_point};
use super::extract::Slide;
use super::interior::{onto_level, trilinear_gradient, tunnel};
use super::table::{CENTER, Entry, table};

/// Where the surface crosses edges whose end values have opposite signs is never closer
/// than this (in cells) to a lattice point, so that a sample that is exactly zero never
/// makes several vertices at one position.
pub const T_MIN: f64 = 1e-4;

/// Receives one cube's vertices and triangles.
pub trait CubeSink {
    /// The vertex on cube edge `e`, whose corner values are `ends` (lower corner first); the
    /// sink returns the one it already has for that lattice edge, or makes it at
    /// [`crossing`]`(ends[0], ends[1])` (computed only then: most edges are shared by four
    /// cubes).
    fn edge_vertex(&mut self, e: usize, ends: [f32; 2]) -> u32;
    /// A new vertex inside the cube, at `offset` (cell units from the lowest corner), on the
    /// trilinear interpolant; refinement on the field moves it along `slide`.
    fn cell_vertex(&mut self, offset: [f64; 3], slide: Slide) -> u32;
    fn triangle(&mut self, t: [u32; 3]);
    /// The triangles `tris` (cube-edge triples) over the cube's vertices `local` (by edge,
    /// masked to four bits): a [`CubeSink::triangle`] each, which a sink that appends to a
    /// vector does in one go (room made once, no check per triangle).
    #[inline]
    fn triangles(&mut self, tris: &[[u8; 3]], local: &[u32; 16]) {
        for tri in tris {
            self.triangle(tri.map(|e| local[usize::from(e) & 15]));
        }
    }
}

/// What one cube needed, for statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CubeOutcome {
    pub ambiguous_faces: u32,
    pub tunnel: bool,
}

/// The sign configuration: bit `c` set when corner `c` is inside (`f < 0`).
#[inline]
pub fn case_of(v: &[f32; 8]) -> usize {
    let mut case = 0usize;
    for (c, &x) in v.iter().enumerate() {
        case |= ((x < 0.0) as usize) << c;
    }
    case
}

/// For each ambiguous face, whether its inside corners are joined across it.
///
/// The asymptotic decider: the bilinear interpolant's saddle is inside exactly when the
/// product of the two inside values exceeds that of the two outside values. Products of
/// `f32` are exact in `f64`, so both cubes that share a face decide alike.
#[inline]
pub fn face_decisions(v: &[f32; 8], ambiguous: u8) -> u8 {
    let mut bits = 0;
    let mut amb = ambiguous;
    while amb != 0 {
        let f = amb.trailing_zeros() as usize;
        amb &= amb - 1;
        let q = FACES[f];
        let d0 = v[q[0]] as f64 * v[q[2]] as f64;
        let d1 = v[q[1]] as f64 * v[q[3]] as f64;
        let (inside, outside) = if v[q[0]] < 0.0 { (d0, d1) } else { (d1, d0) };
        if inside > outside {
            bits |= 1 << f;
        }
    }
    bits
}

/// Where the surface crosses an edge whose end values have opposite signs.
#[inline]
pub fn crossing(v0: f32, v1: f32) -> f64 {
    let (a, b) = (v0 as f64, v1 as f64);
    (a / (a - b)).clamp(T_MIN, 1.0 - T_MIN)
}

/// Where the surface crosses cube edge `e`, in cell units.
pub fn cube_point(e: u8, v: &[f32; 8]) -> [f64; 3] {
    let [c0, c1] = EDGES[e as usize];
    edge_point(e as usize, crossing(v[c0], v[c1]))
}

fn centroid(points: impl ExactSizeIterator<Item = [f64; 3]>) -> [f64; 3] {
    let n = points.len() as f64;
    points.fold([0.0; 3], |c, p| std::array::from_fn(|d| c[d] + p[d] / n))
}

/// A fan centre: the loop's centroid moved along the gradient line onto the interpolant's
/// level set, where the loop's own (edge) vertices are; refinement moves it along the
/// interpolant's normal there, either way, so that it stays over its fan.
fn fan_centre(v: &[f32; 8], edges: &[u8], sink: &mut impl CubeSink) -> u32 {
    let p = onto_level(v, centroid(edges.iter().map(|e| cube_point(*e, v))));
    let g = trilinear_gradient(v, p);
    let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
    let line = if norm > 0.0 && norm.is_finite() { g.map(|x| x / norm) } else { [0.0; 3] };
    sink.cell_vertex(p, Slide { line, ray: false })
}

/// [`EDGES`] as bytes, over sixteen slots (the last four unused): indexed by an edge masked
/// to four bits, with corners below eight, reading them takes no bounds check. (A sink that
/// ignores the ends, as the grid extractor does, leaves the reads out, but not the checks.)
const EDGE_ENDS: [[u8; 2]; 16] = {
    let mut t = [[0u8; 2]; 16];
    let mut e = 0;
    while e < 12 {
        t[e] = [EDGES[e][0] as u8, EDGES[e][1] as u8];
        e += 1;
    }
    t
};

/// Triangulates one cube with corner values `v` (inside negative) into `sink`.
#[inline]
pub fn polygonize_cube(v: &[f32; 8], sink: &mut impl CubeSink) -> CubeOutcome {
    polygonize_case(case_of(v), v, sink)
}

/// [`polygonize_cube`] for a caller that already has the sign configuration
/// ([`case_of`]`(v)`, e.g. from sign bits kept per row).
///
/// Always inlined into the extractor's loop over cubes (in each of the loop's compiled
/// copies, see the extractor's `isa`), with the rare cubes whose configuration can hold a
/// tube (two or three loops) handed to [`polygonize_loops`] out of line: the common path is
/// the table lookup, the edge vertices and the triangles, and stays small.
#[inline(always)]
pub fn polygonize_case(case: usize, v: &[f32; 8], sink: &mut impl CubeSink) -> CubeOutcome {
    debug_assert_eq!(case, case_of(v));
    if case == 0 || case == 255 {
        return CubeOutcome::default();
    }
    let t = table();
    let amb = t.ambiguous[case & 255];
    let decisions = face_decisions(v, amb);
    let entry = t.entry(case & 255, decisions as usize);
    let outcome = CubeOutcome { ambiguous_faces: amb.count_ones(), tunnel: false };
    // Vertices for every crossing edge of the cube, in loop order: the loops lie one after
    // another in the table, so this is one run of edges. (Sixteen slots, indexed by an edge
    // masked to four bits, so that reading them needs no bounds check.)
    let mut local = [0u32; 16];
    let count = entry.loop_len.iter().map(|&l| usize::from(l)).sum::<usize>();
    let start = entry.loop_start as usize;
    for &e in &t.loop_edges[start..start + count] {
        let [c0, c1] = EDGE_ENDS[usize::from(e) & 15];
        local[usize::from(e) & 15] =
            sink.edge_vertex(usize::from(e), [v[usize::from(c0) & 7], v[usize::from(c1) & 7]]);
    }
    if entry.loop_count >= 2 {
        return polygonize_loops(v, entry, &mut local, outcome, sink);
    }
    if let Some(l) = entry.center_loop {
        local[CENTER as usize] = fan_centre(v, t.loop_edges(entry, l as usize), sink);
    }
    sink.triangles(t.triangles(entry), &local);
    outcome
}

/// The rest of [`polygonize_case`] for a configuration of several loops, whose edge
/// vertices are in `local`: a tube through the interior where the interpolant has one,
/// else the table's triangles.
#[cold]
#[inline(never)]
fn polygonize_loops(
    v: &[f32; 8],
    entry: &Entry,
    local: &mut [u32; 16],
    mut outcome: CubeOutcome,
    sink: &mut impl CubeSink,
) -> CubeOutcome {
    let t = table();
    // A tube through the interior, if the interpolant has one: its saddle and the two loops
    // it joins. Two loops join when a saddle joins the caps' side (MC33 4.1.2, 6.1.2, 7.4.2,
    // 10.1.2, 12.1.2); three loops whose corner groups form a path join the two loops
    // around the middle group of one side when a saddle joins the other side's two groups
    // (13.5.2), the third loop staying a disk.
    let tube = match entry.loop_count {
        2 => tunnel(v, entry.caps_inside).map(|s| (s, 0, 1)),
        3 => entry.path_end.and_then(|ends| {
            [true, false].into_iter().zip(ends).find_map(|(side, end)| {
                let mut joined = (0..3).filter(|&l| l != end as usize);
                let (a, b) = (joined.next()?, joined.next()?);
                tunnel(v, side).map(|s| (s, a, b))
            })
        }),
        _ => None,
    };
    let Some((saddle, la, lb)) = tube else {
        if let Some(l) = entry.center_loop {
            local[CENTER as usize] = fan_centre(v, t.loop_edges(entry, l as usize), sink);
        }
        for tri in t.triangles(entry) {
            sink.triangle(tri.map(|e| local[usize::from(e) & 15]));
        }
        return outcome;
    };
    outcome.tunnel = true;
    let at = |e: &u8| (local[usize::from(*e) & 15], cube_point(*e, v));
    let a: Vec<(u32, [f64; 3])> = t.loop_edges(entry, la).iter().map(at).collect();
    let b: Vec<(u32, [f64; 3])> = t.loop_edges(entry, lb).iter().map(at).collect();
    // The tube runs a → ring → b round the saddle, so every rung has one end that only this
    // cube has; its side is the saddle's.
    super::tube::build(v, saddle.p, saddle.value < 0.0, &a, &b, sink);
    // A third loop stays a disk, with the table's triangles over it (each triangle lies on
    // one loop).
    if entry.loop_count == 3 {
        let mut on_tube = [false; 13];
        for l in [la, lb] {
            for &e in t.loop_edges(entry, l) {
                on_tube[e as usize] = true;
            }
        }
        if let Some(l) = entry.center_loop.filter(|&l| l as usize != la && l as usize != lb) {
            local[CENTER as usize] = fan_centre(v, t.loop_edges(entry, l as usize), sink);
        }
        for tri in t.triangles(entry) {
            if !tri.iter().any(|&e| on_tube[e as usize]) {
                sink.triangle(tri.map(|e| local[usize::from(e) & 15]));
            }
        }
    }
    outcome
}
