//! Each cube as six tetrahedra around its main diagonal (the Kuhn split).
//!
//! Every tetrahedron has the corners `0, e_a, e_a + e_b, 7` for a permutation `(a, b, c)` of
//! the axes, so every face of the cube is cut along the diagonal from its lowest to its
//! highest corner, in every cube alike: neighbouring cubes' tetrahedra meet face to face, and
//! marching tetrahedra needs no ambiguity rule (the dissertation's fig. 3.6 split).
//!
//! No ambiguity rule also means no say in the topology: within each tetrahedron the surface
//! is linear, so two corners of one sign joined by a tetrahedron's edge are joined by the
//! mesh, whatever the field does between them. The face diagonals and the cube's main
//! diagonal are such edges, and they are long (√2 and √3 cells): a wall thinner than that
//! between two corners of one sign is cut through, where the cube method, whose trilinear
//! interpolant dips across the wall, keeps it. [`disagrees_with_cube`] finds the cubes where
//! the two methods join the corners differently, so that a run can say how often its
//! topology may differ from the cube method's.

use crate::grid::cell::{case_of, face_decisions};
use crate::grid::cube::{CORNERS, EDGES, FACES};
use crate::grid::interior::tunnel;
use crate::grid::table::table;

/// The six tetrahedra, as cube corner indices.
pub const TETRAHEDRA: [[usize; 4]; 6] = {
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut t = [[0; 4]; 6];
    let mut i = 0;
    while i < 6 {
        let [a, b, _] = perms[i];
        t[i] = [0, 1 << a, (1 << a) | (1 << b), 7];
        i += 1;
    }
    t
};

/// Receives one tetrahedron's vertices and triangles.
pub trait TetraSink {
    /// The vertex on the segment from cube corner `c0` to `c1` (`c0`'s coordinates ≤ `c1`'s)
    /// at fraction `t` from `c0`.
    fn segment_vertex(&mut self, c0: usize, c1: usize, t: f64) -> u32;
    /// A triangle of the tetrahedron's surface piece, wound with its normal towards `f > 0`.
    fn triangle(&mut self, t: [u32; 3]);
}

fn corner_pos(c: usize) -> [f64; 3] {
    CORNERS[c].map(|x| x as f64)
}

/// Marching tetrahedra over the six tetrahedra of a cube with corner values `v`.
pub fn polygonize_tetrahedra(v: &[f32; 8], sink: &mut impl TetraSink) {
    for tet in TETRAHEDRA {
        let inside: Vec<usize> = tet.iter().copied().filter(|&c| v[c] < 0.0).collect();
        let outside: Vec<usize> = tet.iter().copied().filter(|&c| v[c] >= 0.0).collect();
        if inside.is_empty() || outside.is_empty() {
            continue;
        }
        // Crossing points, each keyed by its segment with the lower corner first (corners of
        // one tetrahedron are ordered componentwise, so the smaller index is the lower).
        let mut point = |a: usize, b: usize| {
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            let t = crate::grid::cell::crossing(v[lo], v[hi]);
            let p: [f64; 3] = std::array::from_fn(|d| {
                corner_pos(lo)[d] + t * (corner_pos(hi)[d] - corner_pos(lo)[d])
            });
            (sink.segment_vertex(lo, hi, t), p)
        };
        let ring: Vec<(u32, [f64; 3])> = match (inside.len(), outside.len()) {
            (1, 3) => outside.iter().map(|&o| point(inside[0], o)).collect(),
            (3, 1) => inside.iter().map(|&i| point(i, outside[0])).collect(),
            _ => {
                let ([a, b], [c, d]) = ([inside[0], inside[1]], [outside[0], outside[1]]);
                // A quad around the tetrahedron: consecutive crossings share a corner.
                vec![point(a, c), point(a, d), point(b, d), point(b, c)]
            }
        };
        // Orient each triangle so its normal points from the inside corners to the outside.
        let mean = |cs: &[usize]| {
            let n = cs.len() as f64;
            cs.iter().fold([0.0; 3], |m, &c| std::array::from_fn(|d| m[d] + corner_pos(c)[d] / n))
        };
        let (ci, co) = (mean(&inside), mean(&outside));
        let out_dir: [f64; 3] = std::array::from_fn(|d| co[d] - ci[d]);
        for k in 1..ring.len() - 1 {
            let (a, b, c) = (ring[0], ring[k], ring[k + 1]);
            let u: [f64; 3] = std::array::from_fn(|d| b.1[d] - a.1[d]);
            let w: [f64; 3] = std::array::from_fn(|d| c.1[d] - a.1[d]);
            let n =
                [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
            let dot: f64 = (0..3).map(|d| n[d] * out_dir[d]).sum();
            sink.triangle(if dot >= 0.0 { [a.0, b.0, c.0] } else { [a.0, c.0, b.0] });
        }
    }
}

/// Union–find over the eight corners of a cube.
struct Groups([u8; 8]);

impl Groups {
    fn new() -> Self {
        Groups(std::array::from_fn(|c| c as u8))
    }

    fn root(&self, mut c: usize) -> usize {
        while self.0[c] as usize != c {
            c = self.0[c] as usize;
        }
        c
    }

    fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        self.0[ra] = rb as u8;
    }
}

/// Whether the six tetrahedra join the corners of a cube with values `v` differently from
/// the cube method (the grid polygonizer's table, asymptotic decider and interior tunnels,
/// which follow the trilinear interpolant).
///
/// Two things are compared, for each sign: on every ambiguous face, which pair of diagonal
/// corners the face joins (the decider's pair, against the pair the face's diagonal from
/// its lowest to its highest corner joins); and, over the whole cube, which corners are
/// joined (through cube edges, decided faces and a tunnel for the cube method; through the
/// tetrahedra's edges, diagonals included, for the tetrahedra). Within one tetrahedron the
/// corners of one sign are always joined, and every piece of either method's inside or
/// outside within the cube holds a corner, so equal groupings on every face and in the cube
/// mean the same pieces; a difference is where a thin wall is cut through (or a thin tube
/// is pinched off) by one method and not the other.
pub fn disagrees_with_cube(v: &[f32; 8]) -> bool {
    let case = case_of(v);
    if case == 0 || case == 255 {
        return false;
    }
    let inside = |c: usize| v[c] < 0.0;
    let t = table();
    let amb = t.ambiguous[case];
    let decisions = face_decisions(v, amb);
    for (f, q) in FACES.iter().enumerate() {
        if amb & (1 << f) == 0 {
            continue;
        }
        // The tetrahedra cut this face from its lowest corner to its highest, joining that
        // pair's sign; the decider joins the inside pair when its bit is set.
        let lowest = q.iter().copied().min().unwrap_or(0);
        if inside(lowest) != (decisions & (1 << f) != 0) {
            return true;
        }
    }
    let entry = t.entry(case, decisions as usize);
    let tube = entry.loop_count == 2 && tunnel(v, entry.caps_inside).is_some();
    for side in [true, false] {
        let on = |c: usize| inside(c) == side;
        let mut cube = Groups::new();
        for [a, b] in EDGES {
            if on(a) && on(b) {
                cube.join(a, b);
            }
        }
        for (f, q) in FACES.iter().enumerate() {
            if amb & (1 << f) != 0 && (decisions & (1 << f) != 0) == side {
                for k in 0..2 {
                    if on(q[k]) {
                        cube.join(q[k], q[k + 2]);
                    }
                }
            }
        }
        if tube && entry.caps_inside == side {
            // The tube joins the two caps of this side, that is all its corners.
            let mut same = (0..8).filter(|&c| on(c));
            if let Some(first) = same.next() {
                for c in same {
                    cube.join(first, c);
                }
            }
        }
        let mut tets = Groups::new();
        for tet in TETRAHEDRA {
            for i in 0..4 {
                for j in i + 1..4 {
                    if on(tet[i]) && on(tet[j]) {
                        tets.join(tet[i], tet[j]);
                    }
                }
            }
        }
        for a in (0..8).filter(|&c| on(c)) {
            for b in (a + 1..8).filter(|&c| on(c)) {
                if (cube.root(a) == cube.root(b)) != (tets.root(a) == tets.root(b)) {
                    return true;
                }
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::interior::trilinear;

    #[test]
    fn six_tetrahedra_fill_the_cube_and_share_the_diagonal() {
        let mut vol = 0.0;
        for t in TETRAHEDRA {
            let p = t.map(corner_pos);
            let e = |i: usize| -> [f64; 3] { std::array::from_fn(|d| p[i][d] - p[0][d]) };
            let (a, b, c) = (e(1), e(2), e(3));
            let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            vol += det.abs() / 6.0;
            assert_eq!((t[0], t[3]), (0, 7));
        }
        assert!((vol - 1.0).abs() < 1e-12);
    }

    /// The piecewise-linear interpolant over the six tetrahedra at `p`: the tetrahedron
    /// `0, e_a, e_a + e_b, 7` holds the points with `p_a ≥ p_b ≥ p_c`.
    fn linear(v: &[f32; 8], p: [f64; 3]) -> f64 {
        let mut axes = [0, 1, 2];
        axes.sort_by(|&i, &j| p[j].total_cmp(&p[i]));
        let [a, b, c] = axes;
        let path = [0, 1 << a, (1 << a) | (1 << b), 7];
        let w = [1.0 - p[a], p[a] - p[b], p[b] - p[c], p[c]];
        (0..4).map(|k| w[k] * v[path[k]] as f64).sum()
    }

    /// Which of the corners of `side` the function's `side` region joins within the cube,
    /// by flood fill on an n³ lattice, as a label per corner (`u32::MAX`: other side).
    fn flood(v: &[f32; 8], f: fn(&[f32; 8], [f64; 3]) -> f64, side: bool, n: usize) -> [u32; 8] {
        let s = (n - 1) as f64;
        let idx = |i: [usize; 3]| i[0] + n * (i[1] + n * i[2]);
        let on = |i: [usize; 3]| (f(v, i.map(|x| x as f64 / s)) < 0.0) == side;
        let mut label = vec![u32::MAX; n * n * n];
        let mut next = 0;
        for corner in CORNERS {
            let start = corner.map(|x| x * (n - 1));
            if !on(start) || label[idx(start)] != u32::MAX {
                continue;
            }
            label[idx(start)] = next;
            let mut stack = vec![start];
            while let Some(i) = stack.pop() {
                for d in 0..3 {
                    for step in [-1i64, 1] {
                        let x = i[d] as i64 + step;
                        if x < 0 || x >= n as i64 {
                            continue;
                        }
                        let mut j = i;
                        j[d] = x as usize;
                        if label[idx(j)] == u32::MAX && on(j) {
                            label[idx(j)] = next;
                            stack.push(j);
                        }
                    }
                }
            }
            next += 1;
        }
        CORNERS.map(|c| label[idx(c.map(|x| x * (n - 1)))])
    }

    /// Whether two labellings group the corners alike.
    fn same_groups(a: &[u32; 8], b: &[u32; 8]) -> bool {
        (0..8).all(|i| (0..8).all(|j| (a[i] == a[j]) == (b[i] == b[j])))
    }

    /// Whether the pieces of the two interpolants differ within the cube or on one of its
    /// faces (a face's pieces are the cube's when the field off that face is replaced by
    /// the face's: the cube with the face's values copied onto the opposite face), or `None`
    /// when two lattice resolutions disagree about it (a piece thinner than they see).
    fn differ(v: &[f32; 8]) -> Option<bool> {
        let mut cubes = vec![*v];
        for q in FACES {
            // Face q as a cube: each corner takes the value of its projection onto the face.
            let axis = (0..3).find(|&d| q.iter().all(|&c| CORNERS[c][d] == CORNERS[q[0]][d]));
            let axis = axis.expect("a face has one fixed axis");
            let fixed = CORNERS[q[0]][axis];
            cubes.push(std::array::from_fn(|c| v[(c & !(1 << axis)) | (fixed << axis)]));
        }
        let mut out = false;
        for w in &cubes {
            for side in [true, false] {
                let mut answers = [17, 25].map(|n| {
                    !same_groups(&flood(w, trilinear, side, n), &flood(w, linear, side, n))
                });
                answers.sort();
                if answers[0] != answers[1] {
                    return None;
                }
                out |= answers[0];
            }
        }
        Some(out)
    }

    #[test]
    fn a_wall_across_the_main_diagonal_is_cut_through() {
        // Corners 0 and 7 outside, the rest inside: the interpolant is -0.5 at the centre,
        // so the cube method separates 0 from 7; the tetrahedra's shared edge 0–7 joins them.
        let mut v = [-1.0f32; 8];
        v[0] = 1.0;
        v[7] = 1.0;
        assert!(disagrees_with_cube(&v));
        assert_eq!(differ(&v), Some(true));
        // A single corner inside (or outside) is one cap either way.
        let mut one = [1.0f32; 8];
        one[5] = -0.3;
        assert!(!disagrees_with_cube(&one));
        assert!(!disagrees_with_cube(&one.map(|x| -x)));
        // A plane's cube is sliced alike.
        let plane: [f32; 8] = std::array::from_fn(|c| CORNERS[c][0] as f32 - 0.4);
        assert!(!disagrees_with_cube(&plane));
    }

    #[test]
    fn an_ambiguous_face_decided_against_its_diagonal_disagrees() {
        // Face z = 0 is a checkerboard: 0 and 3 inside, 1 and 2 outside. The diagonal 0–3
        // joins the inside pair; the decider joins the outside pair when |v1·v2| > |v0·v3|.
        let mut v = [1.0f32; 8];
        v[0] = -0.1;
        v[3] = -0.1;
        assert!(disagrees_with_cube(&v));
        v[0] = -2.0;
        v[3] = -2.0;
        assert!(!disagrees_with_cube(&v));
    }

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 33) as f64 / (1u64 << 31) as f64 * 2.0 - 1.0) as f32
    }

    /// On random cubes the test flags exactly the cubes where a flood fill of the trilinear
    /// and of the piecewise-linear interpolant finds different pieces (in the cube or on a
    /// face), skipping cubes whose pieces two lattice resolutions do not agree on.
    #[test]
    fn flags_exactly_the_cubes_whose_pieces_differ() {
        let mut seed = 11u64;
        let (mut flagged, mut clean, mut tried) = (0, 0, 0);
        while (flagged < 60 || clean < 150) && tried < 20_000 {
            tried += 1;
            let v: [f32; 8] = std::array::from_fn(|_| lcg(&mut seed));
            let case = case_of(&v);
            if case == 0 || case == 255 {
                continue;
            }
            let Some(truth) = differ(&v) else { continue };
            assert_eq!(disagrees_with_cube(&v), truth, "values {v:?}");
            if truth { flagged += 1 } else { clean += 1 }
        }
        assert!(flagged >= 60 && clean >= 150, "{flagged} flagged, {clean} clean of {tried}");
    }
}
