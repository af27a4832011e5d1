//! Each cube as six tetrahedra around its main diagonal (the Kuhn split).
//!
//! Every tetrahedron has the corners `0, e_a, e_a + e_b, 7` for a permutation `(a, b, c)` of
//! the axes, so every face of the cube is cut along the diagonal from its lowest to its
//! highest corner, in every cube alike: neighbouring cubes' tetrahedra meet face to face, and
//! marching tetrahedra needs no ambiguity rule (the dissertation's fig. 3.6 split).

use crate::grid::cube::CORNERS;

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
