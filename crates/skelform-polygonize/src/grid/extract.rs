//! Marching cubes over a sampled [`Volume`], in parallel z-slabs with a deterministic merge.
//!
//! Each slab owns the edge vertices on its own sample layers (the last slab also owns the top
//! layer), creates them the first time a cube asks, and refers to the vertices on the layer
//! above it by edge. The merge offsets each slab's vertices by the counts of the slabs before
//! it and resolves the references through the next slab's map of its bottom layer. Slab
//! boundaries depend only on the grid, never on the thread count, so the output is the same
//! bit for bit on any number of threads.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;
use skelform_field::control::{Control, Progress};
use skelform_field::grid::{Grid, Volume};

use super::cell::{CubeSink, case_of, polygonize_cube};
use super::cube::{CORNERS, EDGES, edge_axis};

/// Cube layers per slab. A constant, so that results never depend on the thread count.
const SLAB: usize = 8;

const BORROWED: u32 = 1 << 31;
const NONE: u32 = u32::MAX;

/// Where a mesh vertex lies, relative to lattice point `base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridVertex {
    pub base: [u32; 3],
    pub place: Place,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Place {
    /// On the lattice segment from `base` to `base + dir` (a bit mask: 1 = x, 2 = y, 4 = z;
    /// one bit for a cell edge, more for the face and body diagonals that tetrahedra use), at
    /// fraction `t`. Refinement moves `t` by root finding along the segment.
    Edge { dir: u8, t: f64 },
    /// Inside the cell whose lowest corner is `base`, at `offset` (in cells). Only the few
    /// configurations whose loop cannot be triangulated from its own crossings use one;
    /// refinement projects it onto the surface.
    Cell { offset: [f64; 3] },
}

/// The offset a direction mask stands for.
pub fn dir_vector(dir: u8) -> [u32; 3] {
    [(dir & 1) as u32, ((dir >> 1) & 1) as u32, ((dir >> 2) & 1) as u32]
}

impl GridVertex {
    /// The lattice point at the other end of an edge vertex's segment.
    pub fn tip(&self) -> Option<[u32; 3]> {
        match self.place {
            Place::Edge { dir, .. } => {
                let d = dir_vector(dir);
                Some(std::array::from_fn(|i| self.base[i] + d[i]))
            }
            Place::Cell { .. } => None,
        }
    }

    /// The position, given the lattice.
    pub fn position(&self, grid: &Grid) -> glam::DVec3 {
        let p0 = grid.point(self.base[0] as usize, self.base[1] as usize, self.base[2] as usize);
        let d = match self.place {
            Place::Edge { dir, t } => dir_vector(dir).map(|x| x as f64 * t),
            Place::Cell { offset } => offset,
        };
        p0 + glam::DVec3::from_array(d) * grid.cell
    }
}

/// The raw output of extraction: triangles over edge vertices.
#[derive(Clone, Debug, Default)]
pub struct Extraction {
    pub vertices: Vec<GridVertex>,
    pub triangles: Vec<[u32; 3]>,
    /// Ambiguous faces decided by the asymptotic decider (each counted once per cube).
    pub ambiguous_faces: u64,
    /// Cubes whose interior tunnel test joined two loops.
    pub tunnels: u64,
}

/// Cancellation during extraction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cancelled;

struct Slab {
    vertices: Vec<GridVertex>,
    triangles: Vec<[u32; 3]>,
    /// Edges on the layer above that triangles refer to (index `BORROWED | i`).
    borrowed: Vec<u32>,
    /// Map from edge on this slab's bottom layer to local vertex index.
    bottom: Vec<u32>,
    ambiguous_faces: u64,
    tunnels: u64,
}

/// Runs marching cubes over the whole volume.
pub fn extract(volume: &Volume, control: &Control) -> Result<Extraction, Cancelled> {
    let grid = volume.grid;
    let cube_layers = grid.dims[2] - 1;
    let slabs = cube_layers.div_ceil(SLAB);
    let done = AtomicU64::new(0);
    let outputs: Vec<Slab> = (0..slabs)
        .into_par_iter()
        .map(|s| {
            let z0 = s * SLAB;
            let z1 = (z0 + SLAB).min(cube_layers);
            let slab = extract_slab(volume, z0, z1, control)?;
            let d = done.fetch_add((z1 - z0) as u64, Ordering::Relaxed) + (z1 - z0) as u64;
            let p = Progress { phase: "extracting", done: d, total: Some(cube_layers as u64) };
            match control.report(p) {
                ControlFlow::Continue(()) => Ok(slab),
                ControlFlow::Break(()) => Err(Cancelled),
            }
        })
        .collect::<Result<_, _>>()?;
    Ok(merge(outputs))
}

fn merge(outputs: Vec<Slab>) -> Extraction {
    let mut bases = Vec::with_capacity(outputs.len() + 1);
    let mut total = 0u32;
    for o in &outputs {
        bases.push(total);
        total += o.vertices.len() as u32;
    }
    let mut out = Extraction {
        vertices: Vec::with_capacity(total as usize),
        triangles: Vec::with_capacity(outputs.iter().map(|o| o.triangles.len()).sum()),
        ..Extraction::default()
    };
    for (s, o) in outputs.iter().enumerate() {
        out.vertices.extend_from_slice(&o.vertices);
        out.ambiguous_faces += o.ambiguous_faces;
        out.tunnels += o.tunnels;
        let resolve = |i: u32| {
            if i & BORROWED == 0 {
                bases[s] + i
            } else {
                let edge = o.borrowed[(i & !BORROWED) as usize];
                let next = &outputs[s + 1];
                bases[s + 1] + next.bottom[edge as usize]
            }
        };
        out.triangles.extend(o.triangles.iter().map(|t| t.map(resolve)));
    }
    out
}

/// Edge vertex maps for a run of sample layers: x- and y-edges per layer, z-edges per gap.
struct EdgeMaps {
    nx: usize,
    layer: usize,
    /// `xy[(k - z0) * 2 * layer + axis * layer + i + nx * j]`
    xy: Vec<u32>,
    /// `z[(k - z0) * layer + i + nx * j]`
    z: Vec<u32>,
}

fn extract_slab(
    volume: &Volume,
    z0: usize,
    z1: usize,
    control: &Control,
) -> Result<Slab, Cancelled> {
    let grid: &Grid = &volume.grid;
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let last = z1 == nz - 1;
    // Layers z0..z1 inclusive hold x/y edges the slab's cubes use; z1 is borrowed unless last.
    let mut maps = EdgeMaps {
        nx,
        layer,
        xy: vec![NONE; (z1 - z0 + 1) * 2 * layer],
        z: vec![NONE; (z1 - z0) * layer],
    };
    let mut slab = Slab {
        vertices: Vec::new(),
        triangles: Vec::new(),
        borrowed: Vec::new(),
        bottom: Vec::new(),
        ambiguous_faces: 0,
        tunnels: 0,
    };
    let vals = &volume.values;
    let offsets: [usize; 8] = CORNERS.map(|[x, y, z]| x + nx * y + layer * z);
    for k in z0..z1 {
        if control.is_cancelled() {
            return Err(Cancelled);
        }
        for j in 0..ny - 1 {
            let row = nx * j + layer * k;
            for i in 0..nx - 1 {
                let base = row + i;
                let v: [f32; 8] = offsets.map(|o| vals[base + o]);
                let case = case_of(&v);
                if case == 0 || case == 255 {
                    continue;
                }
                let mut sink =
                    SlabSink { slab: &mut slab, maps: &mut maps, at: [i, j, k], z0, z1, last };
                let outcome = polygonize_cube(&v, &mut sink);
                slab.ambiguous_faces += outcome.ambiguous_faces as u64;
                slab.tunnels += outcome.tunnel as u64;
            }
        }
    }
    slab.bottom = maps.xy[..2 * layer].to_vec();
    Ok(slab)
}

/// The slab's side of [`CubeSink`]: edge vertices keyed by lattice edge in dense maps.
struct SlabSink<'a> {
    slab: &'a mut Slab,
    maps: &'a mut EdgeMaps,
    at: [usize; 3],
    z0: usize,
    z1: usize,
    last: bool,
}

impl CubeSink for SlabSink<'_> {
    #[inline]
    fn edge_vertex(&mut self, e: usize, t: f64) -> u32 {
        let [c0, _] = EDGES[e];
        let [dx, dy, dz] = CORNERS[c0];
        let [i, j, k] = self.at;
        let (bi, bj, bk) = (i + dx, j + dy, k + dz);
        let axis = edge_axis(e);
        let maps = &mut *self.maps;
        let cell = bi + maps.nx * bj;
        let slot = if axis == 2 {
            (bk - self.z0) * maps.layer + cell
        } else {
            (bk - self.z0) * 2 * maps.layer + axis * maps.layer + cell
        };
        let map = if axis == 2 { &mut maps.z } else { &mut maps.xy };
        if map[slot] != NONE {
            return map[slot];
        }
        let id = if axis != 2 && bk == self.z1 && !self.last {
            self.slab.borrowed.push((axis * maps.layer + cell) as u32);
            BORROWED | (self.slab.borrowed.len() as u32 - 1)
        } else {
            self.slab.vertices.push(GridVertex {
                base: [bi as u32, bj as u32, bk as u32],
                place: Place::Edge { dir: 1 << axis, t },
            });
            self.slab.vertices.len() as u32 - 1
        };
        map[slot] = id;
        id
    }

    fn cell_vertex(&mut self, offset: [f64; 3]) -> u32 {
        let [i, j, k] = self.at;
        self.slab.vertices.push(GridVertex {
            base: [i as u32, j as u32, k as u32],
            place: Place::Cell { offset },
        });
        self.slab.vertices.len() as u32 - 1
    }

    fn triangle(&mut self, t: [u32; 3]) {
        self.slab.triangles.push(t);
    }
}
