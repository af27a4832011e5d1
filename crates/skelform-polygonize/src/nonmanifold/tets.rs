//! The five-tetrahedron split of a cube, alternating with the cube's parity (ch. 4, fig.
//! 4.16), so that the face diagonals of neighbouring cubes coincide.

/// The five tetrahedra of a cube, as cube corner indices (corner `c` at
/// `(c & 1, c >> 1 & 1, c >> 2 & 1)`), for even (`i + j + k` even) and odd cubes.
pub const EVEN: [[usize; 4]; 5] =
    [[0, 3, 5, 6], [1, 0, 3, 5], [2, 0, 3, 6], [4, 0, 5, 6], [7, 3, 5, 6]];
/// [`EVEN`] mirrored (`x` flipped), for odd cubes: the neighbour across each face then cuts
/// that face along the same diagonal.
pub const ODD: [[usize; 4]; 5] =
    [[1, 2, 4, 7], [0, 1, 2, 4], [3, 1, 2, 7], [5, 1, 4, 7], [6, 2, 4, 7]];

/// The tetrahedra of the cube with lowest corner `(i, j, k)`.
pub fn split(i: u32, j: u32, k: u32) -> &'static [[usize; 4]; 5] {
    if (i + j + k).is_multiple_of(2) { &EVEN } else { &ODD }
}

/// The four faces of a tetrahedron (vertex positions within it).
pub const FACES: [[usize; 3]; 4] = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
/// The six edges of a tetrahedron.
pub const EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::cube::CORNERS;

    fn volume(t: [usize; 4]) -> f64 {
        let p = t.map(|c| CORNERS[c].map(|x| x as f64));
        let e = |i: usize| -> [f64; 3] { std::array::from_fn(|d| p[i][d] - p[0][d]) };
        let (a, b, c) = (e(1), e(2), e(3));
        (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))
            .abs()
            / 6.0
    }

    #[test]
    fn five_tetrahedra_fill_the_cube_and_neighbours_share_face_diagonals() {
        for split in [EVEN, ODD] {
            let v: f64 = split.iter().map(|&t| volume(t)).sum();
            assert!((v - 1.0).abs() < 1e-12);
        }
        // The x = 1 face of an even cube and the x = 0 face of the odd cube beyond it are cut
        // along the same diagonal: global corners (1,1,0)-(1,0,1).
        let diag = |split: &[[usize; 4]; 5], face: &[usize]| -> Vec<[usize; 2]> {
            let mut d = Vec::new();
            for t in split {
                for e in EDGES {
                    let (a, b) = (t[e[0]], t[e[1]]);
                    if face.contains(&a) && face.contains(&b) && (a ^ b).count_ones() == 2 {
                        d.push([a.min(b), a.max(b)]);
                    }
                }
            }
            d.sort();
            d.dedup();
            d
        };
        assert_eq!(diag(&EVEN, &[1, 3, 5, 7]), vec![[3, 5]]);
        // In the odd neighbour, local corners 2 (0,1,0) and 4 (0,0,1) are global (1,1,0), (1,0,1).
        assert_eq!(diag(&ODD, &[0, 2, 4, 6]), vec![[2, 4]]);
    }
}
