//! Naming the points and cubes of a lattice, and moving between neighbouring cubes. The
//! propagating polygonizers and healing all walk the same lattice; one indexing keeps their
//! keys, clamping and face numbering in agreement (a cube reached by two of them is the same
//! cube).

use glam::DVec3;
use skelform_field::grid::Grid;

/// A lattice point (or the cube whose lowest corner it is) as one integer: `i` fastest, then
/// `j`, then `k`, so that sorting keys visits the lattice layer by layer.
pub(crate) type Key = u64;

/// The points and cubes of a grid. Cube `[i, j, k]` has lowest corner point `[i, j, k]`;
/// face `f` of a cube is `2 · axis + side` (side 0 towards lower coordinates), the order of
/// [`crate::grid::cube::FACES`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct CubeLattice {
    /// The grid whose points these are.
    pub grid: Grid,
    /// Cubes per axis (one fewer than the points).
    pub cubes: [usize; 3],
}

impl CubeLattice {
    /// The cubes of `grid` (which has at least two points per axis).
    pub fn new(grid: Grid) -> Self {
        CubeLattice { grid, cubes: grid.dims.map(|d| d - 1) }
    }

    /// The key of a lattice point.
    #[inline]
    pub fn key(&self, p: [u32; 3]) -> Key {
        let [nx, ny, _] = self.grid.dims;
        p[0] as u64 + nx as u64 * (p[1] as u64 + ny as u64 * p[2] as u64)
    }

    /// The lattice point of a key.
    #[inline]
    pub fn unkey(&self, key: Key) -> [u32; 3] {
        let [nx, ny, _] = self.grid.dims.map(|d| d as u64);
        [(key % nx) as u32, ((key / nx) % ny) as u32, (key / (nx * ny)) as u32]
    }

    /// The position of a lattice point.
    #[inline]
    pub fn point(&self, p: [u32; 3]) -> DVec3 {
        self.grid.point(p[0] as usize, p[1] as usize, p[2] as usize)
    }

    /// The index of a cube among the cubes alone (dense, for cube-sized tables).
    #[inline]
    pub fn cube(&self, c: [usize; 3]) -> usize {
        c[0] + self.cubes[0] * (c[1] + self.cubes[1] * c[2])
    }

    /// The cube of a dense cube index.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        let [cx, cy, _] = self.cubes;
        [i % cx, (i / cx) % cy, i / (cx * cy)]
    }

    /// The highest cube along each axis.
    pub fn last_cube(&self) -> [u32; 3] {
        self.cubes.map(|c| c as u32 - 1)
    }

    /// The cube holding a point, clamped into the lattice: a point on or beyond the domain's
    /// boundary belongs to the cube at that boundary.
    pub fn cube_of(&self, p: DVec3) -> [usize; 3] {
        let r = (p - self.grid.origin) / self.grid.cell;
        std::array::from_fn(|a| (r[a].floor().max(0.0) as usize).min(self.cubes[a] - 1))
    }

    /// [`Self::cube_of`] in the propagating polygonizers' coordinates.
    pub fn cube_of_u32(&self, p: DVec3) -> [u32; 3] {
        self.cube_of(p).map(|x| x as u32)
    }

    /// The cube across face `f` of cube `c`, or `None` where that face is on the domain's
    /// boundary.
    #[inline]
    pub fn across(&self, c: [u32; 3], f: usize) -> Option<[u32; 3]> {
        let (axis, side) = (f / 2, f % 2);
        let mut n = c;
        if side == 0 {
            n[axis] = n[axis].checked_sub(1)?;
        } else {
            if n[axis] as usize + 1 >= self.cubes[axis] {
                return None;
            }
            n[axis] += 1;
        }
        Some(n)
    }

    /// The dense index of the cube across face `f` of cube `c` (see [`Self::across`]).
    pub fn neighbour(&self, c: [usize; 3], f: usize) -> Option<usize> {
        let n = self.across(c.map(|x| x as u32), f)?;
        Some(self.cube(n.map(|x| x as usize)))
    }

    /// The up to 26 cubes round cube `c` (not `c` itself), `x` fastest: where a start point
    /// may lie when the surface slips between the corners of its own cube.
    pub fn around(&self, c: [u32; 3]) -> impl Iterator<Item = [u32; 3]> + use<> {
        let last = self.last_cube();
        (0..27i64).filter(|&d| d != 13).filter_map(move |d| {
            let off = [d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1];
            let q: [i64; 3] = std::array::from_fn(|a| c[a] as i64 + off[a]);
            q.iter()
                .zip(last)
                .all(|(&x, m)| (0..=m as i64).contains(&x))
                .then(|| q.map(|x| x as u32))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::Aabb;

    #[test]
    fn keys_cubes_and_neighbours_round_trip() {
        let grid = Grid::with_cell(&Aabb::cube(1.0), 0.25).unwrap();
        let lat = CubeLattice::new(grid);
        assert_eq!(lat.cubes, [8, 8, 8]);
        assert_eq!(lat.unkey(lat.key([3, 4, 5])), [3, 4, 5]);
        assert_eq!(lat.coords(lat.cube([7, 0, 6])), [7, 0, 6]);
        assert_eq!(lat.across([0, 0, 0], 0), None);
        assert_eq!(lat.across([0, 0, 0], 1), Some([1, 0, 0]));
        assert_eq!(lat.across([7, 7, 7], 5), None);
        assert_eq!(lat.cube_of(DVec3::splat(5.0)), [7, 7, 7]);
        assert_eq!(lat.cube_of(DVec3::splat(-5.0)), [0, 0, 0]);
        assert_eq!(lat.around([0, 0, 0]).count(), 7);
        assert_eq!(lat.around([3, 3, 3]).count(), 26);
        let first: Vec<_> = lat.around([3, 3, 3]).take(2).collect();
        assert_eq!(first, vec![[2, 2, 2], [3, 2, 2]]);
    }
}
