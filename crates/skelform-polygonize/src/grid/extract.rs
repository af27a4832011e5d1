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

use super::cell::{CubeSink, polygonize_cube};
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

/// Edge vertex maps for one layer of cubes: x- and y-edges on the layer below and the layer
/// above, z-edges between them. Entries are reset through lists of the slots set, so the
/// cost of clearing follows the number of vertices, not the size of the layer.
struct EdgeMaps {
    nx: usize,
    layer: usize,
    /// `[axis * layer + i + nx * j]` for x (axis 0) and y (axis 1) edges of the lower layer.
    lower: Vec<u32>,
    upper: Vec<u32>,
    /// `[i + nx * j]`
    z: Vec<u32>,
    lower_set: Vec<u32>,
    upper_set: Vec<u32>,
    z_set: Vec<u32>,
}

impl EdgeMaps {
    fn new(nx: usize, ny: usize) -> Self {
        let layer = nx * ny;
        EdgeMaps {
            nx,
            layer,
            lower: vec![NONE; 2 * layer],
            upper: vec![NONE; 2 * layer],
            z: vec![NONE; layer],
            lower_set: Vec::new(),
            upper_set: Vec::new(),
            z_set: Vec::new(),
        }
    }

    /// Moves up one layer: the upper layer becomes the lower, the new upper and the z-edges
    /// are cleared.
    fn advance(&mut self) {
        for &s in &self.lower_set {
            self.lower[s as usize] = NONE;
        }
        for &s in &self.z_set {
            self.z[s as usize] = NONE;
        }
        self.lower_set.clear();
        self.z_set.clear();
        std::mem::swap(&mut self.lower, &mut self.upper);
        std::mem::swap(&mut self.lower_set, &mut self.upper_set);
    }
}

/// Bit `i` of the row words: whether sample `i` of the row is inside (`f < 0`).
fn row_signs(values: &[f32], out: &mut [u64]) {
    for (w, chunk) in out.iter_mut().zip(values.chunks(64)) {
        let mut bits = 0u64;
        for (b, &v) in chunk.iter().enumerate() {
            bits |= ((v < 0.0) as u64) << b;
        }
        *w = bits;
    }
}

/// Sign words of every row of layer `k`: `ny` rows of `words` words.
fn layer_signs(volume: &Volume, k: usize, words: usize, out: &mut [u64]) {
    let [nx, ny, _] = volume.grid.dims;
    let layer = &volume.values[k * nx * ny..(k + 1) * nx * ny];
    for (row, o) in layer.chunks(nx).zip(out.chunks_mut(words)) {
        row_signs(row, o);
    }
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
    let mut maps = EdgeMaps::new(nx, ny);
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
    // Sign bits of the sample layers below and above the current layer of cubes: a cube has
    // the surface in it when its eight bits are not all equal, which 64 cubes at a time
    // reduce to a few word operations; only those cubes are visited.
    let words = nx.div_ceil(64);
    let mut below = vec![0u64; ny * words];
    let mut above = vec![0u64; ny * words];
    layer_signs(volume, z0, words, &mut below);
    // Cubes are i < nx - 1: mask out the last sample's bit and everything past it.
    let valid = |w: usize| -> u64 {
        let first = w * 64;
        let cubes = (nx - 1).saturating_sub(first).min(64);
        if cubes == 64 { u64::MAX } else { (1u64 << cubes) - 1 }
    };
    for k in z0..z1 {
        if control.is_cancelled() {
            return Err(Cancelled);
        }
        layer_signs(volume, k + 1, words, &mut above);
        for j in 0..ny - 1 {
            let rows = [
                &below[j * words..(j + 1) * words],
                &below[(j + 1) * words..(j + 2) * words],
                &above[j * words..(j + 1) * words],
                &above[(j + 1) * words..(j + 2) * words],
            ];
            let any = |w: usize| rows.iter().fold(0u64, |m, r| m | r[w]);
            let all = |w: usize| rows.iter().fold(u64::MAX, |m, r| m & r[w]);
            for w in 0..words {
                let (or, and) = (any(w), all(w));
                let (or_next, and_next) =
                    if w + 1 < words { (any(w + 1) & 1, all(w + 1) & 1) } else { (0, 0) };
                // Cube i spans samples i and i + 1.
                let some_inside = or | (or >> 1) | (or_next << 63);
                let all_inside = and & ((and >> 1) | (and_next << 63));
                let mut mixed = some_inside & !all_inside & valid(w);
                while mixed != 0 {
                    let i = w * 64 + mixed.trailing_zeros() as usize;
                    mixed &= mixed - 1;
                    let base = nx * j + layer * k + i;
                    let v: [f32; 8] = offsets.map(|o| vals[base + o]);
                    let mut sink =
                        SlabSink { slab: &mut slab, maps: &mut maps, at: [i, j, k], z1, last };
                    let outcome = polygonize_cube(&v, &mut sink);
                    slab.ambiguous_faces += outcome.ambiguous_faces as u64;
                    slab.tunnels += outcome.tunnel as u64;
                }
            }
        }
        if k == z0 {
            // Every vertex on the slab's bottom layer is made by its first layer of cubes.
            slab.bottom = maps.lower.clone();
        }
        maps.advance();
        std::mem::swap(&mut below, &mut above);
    }
    Ok(slab)
}

/// The slab's side of [`CubeSink`]: edge vertices keyed by lattice edge in dense maps.
struct SlabSink<'a> {
    slab: &'a mut Slab,
    maps: &'a mut EdgeMaps,
    at: [usize; 3],
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
        let (map, set, slot) = match (axis, dz) {
            (2, _) => (&mut maps.z, &mut maps.z_set, cell),
            (_, 0) => (&mut maps.lower, &mut maps.lower_set, axis * maps.layer + cell),
            _ => (&mut maps.upper, &mut maps.upper_set, axis * maps.layer + cell),
        };
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
        set.push(slot as u32);
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
