//! The geometry of one lattice cube: corners, edges, faces.
//!
//! Corner `c` sits at `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`. Edge `4·a + u + 2·v` runs along
//! axis `a`, where `u`, `v` are the corner's coordinates on the other two axes in increasing
//! axis order. Face `2·a + s` is the face with coordinate `a` equal to `s`.

/// Corner offsets.
pub const CORNERS: [[usize; 3]; 8] = {
    let mut c = [[0; 3]; 8];
    let mut i = 0;
    while i < 8 {
        c[i] = [i & 1, (i >> 1) & 1, (i >> 2) & 1];
        i += 1;
    }
    c
};

/// The two other axes of axis `a`, in increasing order.
pub const fn other_axes(a: usize) -> (usize, usize) {
    match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// The corner with the given coordinates.
pub const fn corner_at(p: [usize; 3]) -> usize {
    p[0] | (p[1] << 1) | (p[2] << 2)
}

/// Edge endpoints: the lower corner first (its coordinate on the edge's axis is 0).
pub const EDGES: [[usize; 2]; 12] = {
    let mut e = [[0; 2]; 12];
    let mut a = 0;
    while a < 3 {
        let (b, c) = other_axes(a);
        let mut uv = 0;
        while uv < 4 {
            let mut p = [0; 3];
            p[b] = uv & 1;
            p[c] = uv >> 1;
            let lo = corner_at(p);
            p[a] = 1;
            e[4 * a + uv] = [lo, corner_at(p)];
            uv += 1;
        }
        a += 1;
    }
    e
};

/// The edge joining two adjacent corners.
pub fn edge_between(c0: usize, c1: usize) -> usize {
    EDGES
        .iter()
        .position(|e| (e[0] == c0 && e[1] == c1) || (e[0] == c1 && e[1] == c0))
        .expect("corners are adjacent")
}

/// The axis an edge runs along.
pub const fn edge_axis(e: usize) -> usize {
    e / 4
}

/// Face corners, counter-clockwise seen from outside the cube.
pub const FACES: [[usize; 4]; 6] = {
    let mut f = [[0; 4]; 6];
    let mut a = 0;
    while a < 3 {
        // (a, b, c) cyclic, so e_b × e_c = e_a: counter-clockwise in (b, c) seen from +a.
        let b = (a + 1) % 3;
        let c = (a + 2) % 3;
        let mut s = 0;
        while s < 2 {
            let square = if s == 1 {
                [[0, 0], [1, 0], [1, 1], [0, 1]]
            } else {
                [[0, 0], [0, 1], [1, 1], [1, 0]]
            };
            let mut k = 0;
            while k < 4 {
                let mut p = [0; 3];
                p[a] = s;
                p[b] = square[k][0];
                p[c] = square[k][1];
                f[2 * a + s][k] = corner_at(p);
                k += 1;
            }
            s += 1;
        }
        a += 1;
    }
    f
};

/// A point on edge `e` of the unit cube at parameter `t` from its lower corner.
pub fn edge_point(e: usize, t: f64) -> [f64; 3] {
    let [c0, _] = EDGES[e];
    let mut p = CORNERS[c0].map(|v| v as f64);
    p[edge_axis(e)] = t;
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_join_adjacent_corners_along_their_axis() {
        for (i, [a, b]) in EDGES.iter().enumerate() {
            let axis = edge_axis(i);
            assert_eq!(a ^ b, 1 << axis);
            assert_eq!(a & (1 << axis), 0);
        }
        let mut seen: Vec<_> = EDGES.iter().map(|&[a, b]| (a, b)).collect();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 12);
    }

    #[test]
    fn faces_are_counter_clockwise_from_outside() {
        for (f, corners) in FACES.iter().enumerate() {
            let (a, s) = (f / 2, f % 2);
            let p = corners.map(|c| CORNERS[c].map(|v| v as f64));
            // Newell normal of the quad.
            let mut n = [0.0; 3];
            for k in 0..4 {
                let (u, v) = (p[k], p[(k + 1) % 4]);
                n[0] += (u[1] - v[1]) * (u[2] + v[2]);
                n[1] += (u[2] - v[2]) * (u[0] + v[0]);
                n[2] += (u[0] - v[0]) * (u[1] + v[1]);
            }
            let outward = if s == 1 { 1.0 } else { -1.0 };
            assert!(n[a] * outward > 0.0, "face {f} normal {n:?}");
            for c in corners {
                assert_eq!(CORNERS[*c][a], s);
            }
        }
    }
}
