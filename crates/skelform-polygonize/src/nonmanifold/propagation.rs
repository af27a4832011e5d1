//! Propagation: the start cubes (from the seeds, or the coarse search of the domain) and the
//! breadth-first walk across cube faces that hold a surface of interest (or every cube,
//! with `Options::full_grid`), through the shared [`crate::lattice::propagate`].

use skelform_mesh::RegionPair;

use super::Run;
use crate::Error;
use crate::lattice::propagate::{Cubes, Limits, Order, propagate};
use crate::lattice::search::CoarseSearch;

impl Run<'_> {
    pub(super) fn all_cubes(&self) -> Vec<[u32; 3]> {
        // The caller has refused lattices whose cube list cannot fit, so the product fits.
        let [nx, ny, nz] = self.grid.dims.map(|d| d as u32 - 1);
        let mut v = Vec::with_capacity(nx as usize * ny as usize * nz as usize);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    v.push([i, j, k]);
                }
            }
        }
        v
    }

    /// Start cubes: from the seeds, or from a coarse search of the domain.
    pub(super) fn starts(&mut self) -> Result<Vec<[u32; 3]>, Error> {
        let mut points = self.opts.seeds.clone();
        if points.is_empty() {
            let search = CoarseSearch::new(&self.grid, self.opts.search_stride);
            let (pts, stride) = (&search.points, search.stride);
            let r = self.regions_of(pts);
            search.edges(|a, b| {
                if self.interesting(RegionPair::new(r[a], r[b])) {
                    // Every cube along the coarse edge is a candidate start.
                    for s in 0..=stride {
                        points.push(pts[a].lerp(pts[b], s as f64 / stride as f64));
                    }
                }
            });
            if points.is_empty() {
                return Err(Error::NoSurfaceFound { samples: pts.len() as u64, stride });
            }
        }
        let seeded = !self.opts.seeds.is_empty();
        let mut cubes: Vec<[u32; 3]> = Vec::new();
        for p in points.iter().filter(|p| self.grid.bounds().contains(**p)) {
            let c = self.cubes.cube_of_u32(*p);
            cubes.push(c);
            if seeded {
                // A seed within half a cell of the surface may sit on a lattice point or in a
                // cube the surface misses: its 26 neighbours start too.
                cubes.extend(self.cubes.around(c));
            }
        }
        if cubes.is_empty() {
            return Err(Error::BadSeed {
                seed: points[0].to_array(),
                why: "it is outside the domain".into(),
            });
        }
        cubes.sort_unstable();
        cubes.dedup();
        Ok(cubes)
    }

    pub(super) fn propagate(&mut self, starts: Vec<[u32; 3]>) -> Result<(), Error> {
        let limits = Limits {
            max_cells: self.opts.max_cells,
            limit: None,
            origin: [0; 3],
            max_memory: self.opts.lattice.max_memory,
            method: "nonmanifold",
        };
        let (lattice, control) = (self.cubes, &self.opts.lattice.control);
        let stops = propagate(
            self,
            &lattice,
            starts,
            &limits,
            Order::Coordinates,
            control,
            "non-manifold",
        )?;
        self.stats.reached_domain |= stops.domain;
        self.stats.reached_budget |= stops.budget;
        self.stats.cells_visited = self.visited.len() as u64;
        Ok(())
    }
}

impl Cubes for Run<'_> {
    fn process(&mut self, c: [u32; 3]) -> u8 {
        let open = self.cube(c);
        if self.opts.full_grid {
            // Every cube is a start already.
            return 0;
        }
        open.iter().fold(0, |m, &(axis, side)| m | 1 << (2 * axis + side))
    }

    fn is_visited(&mut self, c: [u32; 3]) -> bool {
        self.visited.contains(&self.key(c))
    }

    fn visit(&mut self, c: [u32; 3]) {
        let k = self.key(c);
        self.visited.insert(k);
    }

    fn visited(&self) -> u64 {
        self.visited.len() as u64
    }

    fn held(&self) -> u64 {
        Run::held(self)
    }
}
