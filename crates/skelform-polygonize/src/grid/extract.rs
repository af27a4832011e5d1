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

use super::cube::{CORNERS, EDGES, FACES, edge_axis, edge_point};
use super::interior::tunnel;
use super::table::{CENTER, table};

/// Cube layers per slab. A constant, so that results never depend on the thread count.
const SLAB: usize = 8;

/// Vertices closer than this (in cells) to a lattice point are moved to it, so that a
/// sample that is exactly zero never makes several vertices at one position.
pub const T_MIN: f64 = 1e-4;

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
    /// On the lattice edge from `base` along `axis`, at fraction `t` of the cell. Refinement
    /// moves `t` by root finding along the edge.
    Edge { axis: u8, t: f64 },
    /// Inside the cell whose lowest corner is `base`, at `offset` (in cells). Only the few
    /// configurations whose loop cannot be triangulated from its own crossings use one;
    /// refinement projects it onto the surface.
    Cell { offset: [f64; 3] },
}

impl GridVertex {
    /// The lattice point at the other end of an edge vertex's edge.
    pub fn tip(&self) -> Option<[u32; 3]> {
        match self.place {
            Place::Edge { axis, .. } => {
                let mut p = self.base;
                p[axis as usize] += 1;
                Some(p)
            }
            Place::Cell { .. } => None,
        }
    }

    /// The position, given the lattice.
    pub fn position(&self, grid: &Grid) -> glam::DVec3 {
        let p0 = grid.point(self.base[0] as usize, self.base[1] as usize, self.base[2] as usize);
        let d = match self.place {
            Place::Edge { axis, t } => {
                let mut d = [0.0; 3];
                d[axis as usize] = t;
                d
            }
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
    let t = table();
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
    let mut local = [0u32; 13];
    for k in z0..z1 {
        if control.is_cancelled() {
            return Err(Cancelled);
        }
        for j in 0..ny - 1 {
            let row = nx * j + layer * k;
            for i in 0..nx - 1 {
                let base = row + i;
                let v: [f32; 8] = offsets.map(|o| vals[base + o]);
                let mut case = 0usize;
                for (c, &x) in v.iter().enumerate() {
                    case |= ((x < 0.0) as usize) << c;
                }
                if case == 0 || case == 255 {
                    continue;
                }
                let amb = t.ambiguous[case];
                let decisions = if amb == 0 { 0 } else { face_decisions(&v, amb) };
                slab.ambiguous_faces += amb.count_ones() as u64;
                let entry = t.entry(case, decisions as usize);
                // Vertices for every crossing edge of the cube.
                for l in 0..entry.loop_count as usize {
                    for &e in t.loop_edges(entry, l) {
                        local[e as usize] =
                            slab.vertex(&mut maps, &v, [i, j, k], e as usize, z0, z1, last);
                    }
                }
                let tube = if entry.loop_count == 2 { tunnel(&v, entry.caps_inside) } else { None };
                if let Some(saddle) = tube {
                    slab.tunnels += 1;
                    let ring_at = |e: u8| (local[e as usize], cube_point(e, &v));
                    let a: Vec<(u32, [f64; 3])> =
                        t.loop_edges(entry, 0).iter().map(|&e| ring_at(e)).collect();
                    let b: Vec<(u32, [f64; 3])> =
                        t.loop_edges(entry, 1).iter().map(|&e| ring_at(e)).collect();
                    // A ring shaped like loop b, half its size, around the saddle: the tube
                    // runs a → ring → b, so every rung has one end that only this cube has.
                    let cb = centroid(b.iter().map(|x| x.1));
                    let ring: Vec<(u32, [f64; 3])> = b
                        .iter()
                        .map(|&(_, p)| {
                            let offset: [f64; 3] = std::array::from_fn(|d| {
                                (saddle.p[d] + 0.5 * (p[d] - cb[d])).clamp(0.0, 1.0)
                            });
                            slab.vertices.push(GridVertex {
                                base: [i as u32, j as u32, k as u32],
                                place: Place::Cell { offset },
                            });
                            (slab.vertices.len() as u32 - 1, offset)
                        })
                        .collect();
                    let mut rev = ring.clone();
                    rev.reverse();
                    zip_loops(&a, &ring, |tri| slab.triangles.push(tri));
                    zip_loops(&rev, &b, |tri| slab.triangles.push(tri));
                } else {
                    if let Some(l) = entry.center_loop {
                        let edges = t.loop_edges(entry, l as usize);
                        local[CENTER as usize] = slab.vertices.len() as u32;
                        slab.vertices.push(GridVertex {
                            base: [i as u32, j as u32, k as u32],
                            place: Place::Cell { offset: loop_centroid(edges, &v) },
                        });
                    }
                    for tri in t.triangles(entry) {
                        slab.triangles.push(tri.map(|e| local[e as usize]));
                    }
                }
            }
        }
    }
    slab.bottom = maps.xy[..2 * layer].to_vec();
    Ok(slab)
}

impl Slab {
    /// The local index of the vertex on cube edge `e` of the cube at `(i, j, k)`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn vertex(
        &mut self,
        maps: &mut EdgeMaps,
        v: &[f32; 8],
        [i, j, k]: [usize; 3],
        e: usize,
        z0: usize,
        z1: usize,
        last: bool,
    ) -> u32 {
        let [c0, c1] = EDGES[e];
        let [dx, dy, dz] = CORNERS[c0];
        let (bi, bj, bk) = (i + dx, j + dy, k + dz);
        let axis = edge_axis(e);
        let cell = bi + maps.nx * bj;
        let slot = if axis == 2 {
            (bk - z0) * maps.layer + cell
        } else {
            (bk - z0) * 2 * maps.layer + axis * maps.layer + cell
        };
        let map = if axis == 2 { &mut maps.z } else { &mut maps.xy };
        if map[slot] != NONE {
            return map[slot];
        }
        let borrowed = axis != 2 && bk == z1 && !last;
        let ev = GridVertex {
            base: [bi as u32, bj as u32, bk as u32],
            place: Place::Edge { axis: axis as u8, t: crossing(v[c0], v[c1]) },
        };
        let id = if borrowed {
            self.borrowed.push((axis * maps.layer + cell) as u32);
            BORROWED | (self.borrowed.len() as u32 - 1)
        } else {
            self.vertices.push(ev);
            self.vertices.len() as u32 - 1
        };
        map[slot] = id;
        id
    }
}

/// Where the surface crosses cube edge `e`, in cell units.
fn cube_point(e: u8, v: &[f32; 8]) -> [f64; 3] {
    let [c0, c1] = EDGES[e as usize];
    edge_point(e as usize, crossing(v[c0], v[c1]))
}

fn centroid(points: impl ExactSizeIterator<Item = [f64; 3]>) -> [f64; 3] {
    let n = points.len() as f64;
    points.fold([0.0; 3], |c, p| std::array::from_fn(|d| c[d] + p[d] / n))
}

/// Where a loop's crossings are, on average, in cell units.
fn loop_centroid(edges: &[u8], v: &[f32; 8]) -> [f64; 3] {
    centroid(edges.iter().map(|&e| cube_point(e, v)))
}

/// Triangles of a band joining two loops of `(vertex, position)`, zipped from their nearest
/// points.
///
/// Both loops are oriented as the boundaries of the disks the band replaces; the band joins
/// `a` to `b` reversed, so every loop edge keeps its direction and the band is oriented like
/// those disks.
pub fn zip_loops(a: &[(u32, [f64; 3])], b: &[(u32, [f64; 3])], mut emit: impl FnMut([u32; 3])) {
    let dist = |p: [f64; 3], q: [f64; 3]| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>();
    let (na, nb) = (a.len(), b.len());
    let rb: Vec<(u32, [f64; 3])> = b.iter().rev().copied().collect();
    let start = (0..nb)
        .min_by(|&x, &y| dist(a[0].1, rb[x].1).total_cmp(&dist(a[0].1, rb[y].1)))
        .unwrap_or(0);
    let bb = |j: usize| rb[(start + j) % nb];
    let aa = |i: usize| a[i % na];
    // The walk goes from rung (0, 0) to (na, nb), which is (0, 0) again. Rungs (0, j) and
    // (na, j) are the same rung, as are (i, 0) and (i, nb); so arriving at i = na while j is
    // still within the walk's opening run along b (or the reverse) would use a rung twice.
    let (mut i, mut j) = (0, 0);
    let (mut run_a, mut run_b) = (0, 0);
    while i < na || j < nb {
        let can_a = i < na && !(i + 1 == na && j <= run_b);
        let can_b = j < nb && !(j + 1 == nb && i <= run_a);
        let advance_a = match (can_a, can_b) {
            (true, false) => true,
            (false, true) => false,
            _ => dist(aa(i + 1).1, bb(j).1) <= dist(aa(i).1, bb(j + 1).1),
        };
        if advance_a {
            run_a += usize::from(j == 0);
            emit([aa(i).0, aa(i + 1).0, bb(j).0]);
            i += 1;
        } else {
            run_b += usize::from(i == 0);
            emit([bb(j + 1).0, bb(j).0, aa(i).0]);
            j += 1;
        }
    }
}
