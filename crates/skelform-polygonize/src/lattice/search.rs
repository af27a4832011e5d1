//! The coarse search of the domain for a surface when no seed is given: sample every
//! `stride`-th lattice point and report the coarse edges whose ends differ. Shared by the
//! propagating polygonizers, which differ only in what "differ" means (a sign change of the
//! field, or a pair of regions of interest).

use glam::DVec3;
use skelform_field::grid::Grid;

/// A lattice of every `stride`-th point of a grid, the last point of each axis included.
pub(crate) struct CoarseSearch {
    /// The stride, in cells (at least 1).
    pub stride: usize,
    /// Coarse points per axis.
    pub dims: [usize; 3],
    /// The coarse points' positions, `x` fastest.
    pub points: Vec<DVec3>,
}

impl CoarseSearch {
    /// Bytes the search's points (and a value of `value_bytes` each) take; `u64::MAX` when
    /// that does not fit in a `u64`.
    pub fn need(grid: &Grid, stride: usize, value_bytes: u64) -> u64 {
        let stride = stride.max(1);
        let per_point = size_of::<DVec3>() as u64 + value_bytes;
        grid.dims
            .iter()
            .try_fold(per_point, |n, &d| n.checked_mul(((d - 1).div_ceil(stride) + 1) as u64))
            .unwrap_or(u64::MAX)
    }

    /// The coarse lattice of `grid` at `stride` cells (0 is taken as 1).
    pub fn new(grid: &Grid, stride: usize) -> Self {
        let stride = stride.max(1);
        let dims = grid.dims.map(|d| (d - 1).div_ceil(stride) + 1);
        let mut points = Vec::with_capacity(dims.iter().product());
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    // The last coarse point of an axis is the grid's last, not beyond it.
                    let p = [i, j, k].map(|x| x * stride);
                    let p: [usize; 3] = std::array::from_fn(|a| p[a].min(grid.dims[a] - 1));
                    points.push(grid.point(p[0], p[1], p[2]));
                }
            }
        }
        CoarseSearch { stride, dims, points }
    }

    /// Calls `edge(a, b)` for every coarse edge (point indices, `a` the lower end), in
    /// lattice order and, at each point, `x`, `y`, `z`.
    pub fn edges(&self, mut edge: impl FnMut(usize, usize)) {
        let dims = self.dims;
        let idx = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    for (di, dj, dk) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                        let (ni, nj, nk) = (i + di, j + dj, k + dk);
                        if ni < dims[0] && nj < dims[1] && nk < dims[2] {
                            edge(idx(i, j, k), idx(ni, nj, nk));
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::Aabb;

    #[test]
    fn the_last_coarse_point_is_the_grids_last() {
        let grid = Grid::with_cell(&Aabb::cube(1.0), 0.2).unwrap();
        let s = CoarseSearch::new(&grid, 4);
        assert_eq!(s.dims, [4, 4, 4]);
        assert_eq!(*s.points.last().unwrap(), grid.bounds().max);
        let mut n = 0;
        s.edges(|a, b| {
            assert!(a < b);
            n += 1;
        });
        assert_eq!(n, 3 * 4 * 4 * 3);
    }
}
