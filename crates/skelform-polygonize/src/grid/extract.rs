//! Marching cubes over a sampled [`Volume`], in parallel z-slabs with a deterministic merge.
//!
//! Each slab owns the edge vertices on its own sample layers (the last slab also owns the top
//! layer) and creates them the first time a cube asks. The crossed edges of the layer two
//! slabs share are numbered in a fixed order computed from that layer's signs alone
//! ([`LayerNumbering`]): the slab above gives its bottom-layer vertices those numbers as local
//! indices, and the slab below refers to them by number. The merge then offsets each slab's
//! vertices by the counts of the slabs before it, and a reference to the layer above by the
//! next slab's offset: no lookup. Slab boundaries depend only on the grid, never on the
//! thread count, so the output is the same bit for bit on any number of threads.

use std::ops::{ControlFlow, Range};
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;
use skelform_field::control::{Control, Progress};
use skelform_field::grid::{Grid, Volume};

use super::cell::{CubeSink, crossing, polygonize_case};
use super::cube::{CORNERS, EDGES, edge_axis};

/// Cube layers per slab. A constant, so that results never depend on the thread count.
pub const SLAB: usize = 8;

const BORROWED: u32 = 1 << 31;
/// An empty edge-map slot. Slots hold `!index` (an index is never `u32::MAX`), so that a
/// new map is zeroed memory, which the system hands out untouched: pages are only made as
/// the surface reaches them.
const NONE: u32 = 0;

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

/// What a slab records for each vertex it makes: the lattice place ([`GridVertex`], for
/// refinement on the field) or the interpolated position at once (extraction only).
pub trait SlabVertex: Copy + Default + Send + Sync {
    /// The record of vertex `v`; `ends` are the samples at the two ends of its lattice
    /// segment (zero for vertices inside a cell).
    fn make(grid: &Grid, v: GridVertex, ends: [f32; 2]) -> Self;
}

impl SlabVertex for GridVertex {
    #[inline]
    fn make(_: &Grid, v: GridVertex, _: [f32; 2]) -> Self {
        v
    }
}

impl SlabVertex for [f32; 3] {
    #[inline]
    fn make(grid: &Grid, v: GridVertex, _: [f32; 2]) -> Self {
        v.position(grid).as_vec3().to_array()
    }
}

/// A vertex with the samples at its segment's ends: what refinement needs when the volume
/// itself is not kept (streamed extraction).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampledVertex {
    pub vertex: GridVertex,
    pub ends: [f32; 2],
}

impl SlabVertex for SampledVertex {
    #[inline]
    fn make(_: &Grid, vertex: GridVertex, ends: [f32; 2]) -> Self {
        SampledVertex { vertex, ends }
    }
}

impl Default for GridVertex {
    fn default() -> Self {
        GridVertex { base: [0; 3], place: Place::Cell { offset: [0.0; 3] } }
    }
}

/// Where one slab's part of the mesh is: ranges of the output arrays of the worker that ran
/// it. Its first vertices are those of its bottom layer's crossed x- and y-edges, at their
/// [`LayerNumbering`] numbers; its triangles index its vertices from 0, and `BORROWED | n` is
/// number `n` of the layer above, that is, a vertex of the next slab.
struct Slab {
    worker: usize,
    vertices: Range<usize>,
    triangles: Range<usize>,
    ambiguous_faces: u64,
    tunnels: u64,
}

/// A worker's output: the vertices and triangles of every slab it ran, one slab after
/// another, in arrays that grow by doubling and are backed by huge pages where the system
/// allows ([`super::pages`]), so that fresh output memory costs few page faults.
struct Output<V> {
    vertices: Vec<V>,
    triangles: Vec<[u32; 3]>,
}

impl<V> Default for Output<V> {
    fn default() -> Self {
        Output { vertices: Vec::new(), triangles: Vec::new() }
    }
}

/// Makes room for at least `more` elements past the end of `v`, and for a few huge pages'
/// worth: room costs address space only until it is written, and growing by small steps
/// would copy into memory the kernel has not been asked to back with huge pages.
fn make_room<T>(v: &mut Vec<T>, more: usize) {
    if v.capacity() - v.len() < more {
        let step = super::pages::ROOM / std::mem::size_of::<T>().max(1);
        v.reserve(more.max(v.capacity()).max(step));
        super::pages::advise_huge(v.spare_capacity_mut());
    }
}

/// The crossed x- and y-edges of one sample layer (corners of both signs), numbered row by
/// row: in each row its x-edges, then the y-edges to the next row, each by x. The numbers
/// come from the layer's sign words alone, so the two slabs that share a layer agree on them
/// without looking at each other's work, as Flying Edges numbers its edges by counting.
#[derive(Default)]
struct LayerNumbering {
    words: usize,
    /// Per row and word: the crossed edges (bit `i`: the edge from sample `64·w + i`) and
    /// how many crossed edges come before the word in the numbering.
    x_bits: Vec<u64>,
    x_before: Vec<u32>,
    y_bits: Vec<u64>,
    y_before: Vec<u32>,
    total: u32,
}

impl LayerNumbering {
    /// Numbers the edges of a layer of `ny` rows of sign words (see [`layer_signs`]).
    fn build(&mut self, signs: &[u64], nx: usize, ny: usize, words: usize) {
        let cells = ny * words;
        for v in [&mut self.x_bits, &mut self.y_bits] {
            v.clear();
            v.resize(cells, 0);
        }
        for v in [&mut self.x_before, &mut self.y_before] {
            v.clear();
            v.resize(cells, 0);
        }
        self.words = words;
        let mut count = 0u32;
        for j in 0..ny {
            let row = &signs[j * words..(j + 1) * words];
            for w in 0..words {
                let next = if w + 1 < words { row[w + 1] & 1 } else { 0 };
                let bits = (row[w] ^ ((row[w] >> 1) | (next << 63))) & word_mask(w, nx - 1);
                self.x_bits[j * words + w] = bits;
                self.x_before[j * words + w] = count;
                count += bits.count_ones();
            }
            if j + 1 < ny {
                let up = &signs[(j + 1) * words..(j + 2) * words];
                for w in 0..words {
                    let bits = (row[w] ^ up[w]) & word_mask(w, nx);
                    self.y_bits[j * words + w] = bits;
                    self.y_before[j * words + w] = count;
                    count += bits.count_ones();
                }
            }
        }
        self.total = count;
    }

    /// The number of the crossed x (`axis` 0) or y edge from sample `(i, j)`.
    #[inline]
    fn number(&self, axis: usize, i: usize, j: usize) -> u32 {
        let (bits, before) =
            if axis == 0 { (&self.x_bits, &self.x_before) } else { (&self.y_bits, &self.y_before) };
        let at = j * self.words + i / 64;
        let below = bits[at] & ((1u64 << (i % 64)) - 1);
        debug_assert!(bits[at] >> (i % 64) & 1 == 1, "edge ({axis}, {i}, {j}) is not crossed");
        before[at] + below.count_ones()
    }
}

/// What a worker keeps from one slab to the next: the edge maps (cleared through their
/// lists of set slots, never reallocated), the sign words and edge numberings of the layers
/// it works on, and the previous slab's output sizes, to reserve.
struct Worker<V> {
    /// The worker's index among the pool's, which [`Slab::worker`] refers to.
    index: usize,
    out: Output<V>,
    maps: EdgeMaps,
    below: Vec<u64>,
    above: Vec<u64>,
    bottom_numbers: LayerNumbering,
    top_numbers: LayerNumbering,
    last_sizes: (usize, usize),
    /// The sample layers of the slab, when they are streamed from a [`LayerSource`].
    layers: Vec<f32>,
}

impl<V> Worker<V> {
    fn new(index: usize, nx: usize, ny: usize) -> Self {
        let words = nx.div_ceil(64);
        Worker {
            index,
            out: Output::default(),
            maps: EdgeMaps::new(nx, ny),
            below: vec![0; ny * words],
            above: vec![0; ny * words],
            bottom_numbers: LayerNumbering::default(),
            top_numbers: LayerNumbering::default(),
            last_sizes: (0, 0),
            layers: Vec::new(),
        }
    }
}

/// One [`Worker`] per thread of the pool, kept for the whole extraction. (Rayon's
/// `map_init` makes one per job, and with a job per slab that would be new edge maps, and
/// new pages to fault in, for every slab.)
struct Workers<V> {
    nx: usize,
    ny: usize,
    slots: Vec<std::sync::Mutex<Option<Worker<V>>>>,
}

impl<V> Workers<V> {
    /// For the current pool (call it inside the pool that runs the slabs).
    fn new(nx: usize, ny: usize) -> Self {
        let slots = (0..rayon::current_num_threads()).map(|_| Default::default()).collect();
        Workers { nx, ny, slots }
    }

    /// Runs `f` with the calling thread's worker. Each thread has its own slot, so the lock
    /// is never contended.
    fn with<R>(&self, f: impl FnOnce(&mut Worker<V>) -> R) -> R {
        let i = rayon::current_thread_index().unwrap_or(0) % self.slots.len();
        let mut slot = self.slots[i].lock().unwrap_or_else(|e| e.into_inner());
        f(slot.get_or_insert_with(|| Worker::new(i, self.nx, self.ny)))
    }

    /// The workers' outputs, by index.
    fn into_outputs(self) -> Vec<Output<V>> {
        let worker = |m: std::sync::Mutex<Option<Worker<V>>>| {
            m.into_inner().unwrap_or_else(|e| e.into_inner())
        };
        self.slots.into_iter().map(|m| worker(m).map(|w| w.out).unwrap_or_default()).collect()
    }
}

/// Runs marching cubes over the whole volume.
pub fn extract(volume: &Volume, control: &Control) -> Result<Extraction, Cancelled> {
    let (vertices, triangles, ambiguous_faces, tunnels) =
        extract_as::<GridVertex>(volume, control)?;
    Ok(Extraction { vertices, triangles, ambiguous_faces, tunnels })
}

/// Runs marching cubes over the whole volume and returns the vertices' interpolated
/// positions (no refinement), without the intermediate [`GridVertex`] records.
pub fn extract_positions(volume: &Volume, control: &Control) -> Result<Positions, Cancelled> {
    let (vertices, triangles, _, _) = extract_as::<[f32; 3]>(volume, control)?;
    Ok((vertices, triangles))
}

type Extracted<V> = (Vec<V>, Vec<[u32; 3]>, u64, u64);

/// Interpolated vertex positions and triangles.
pub type Positions = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// The output of [`extract_streamed`].
#[derive(Clone, Debug)]
pub struct Streamed<V> {
    pub vertices: Vec<V>,
    pub triangles: Vec<[u32; 3]>,
    pub stats: StreamStats,
}

fn extract_as<V: SlabVertex>(
    volume: &Volume,
    control: &Control,
) -> Result<Extracted<V>, Cancelled> {
    let grid = volume.grid;
    let [nx, ny, _] = grid.dims;
    let cube_layers = grid.dims[2] - 1;
    let slabs = cube_layers.div_ceil(SLAB);
    let done = AtomicU64::new(0);
    let workers = Workers::new(nx, ny);
    let outputs: Vec<Slab> = (0..slabs)
        .into_par_iter()
        .with_max_len(1)
        .map(|s| {
            workers.with(|worker| {
                let z0 = s * SLAB;
                let z1 = (z0 + SLAB).min(cube_layers);
                let vals = &volume.values[z0 * nx * ny..];
                let slab = extract_slab(&grid, vals, z0, z1, worker, control)?;
                let d = done.fetch_add((z1 - z0) as u64, Ordering::Relaxed) + (z1 - z0) as u64;
                let p = Progress { phase: "extracting", done: d, total: Some(cube_layers as u64) };
                match control.report(p) {
                    ControlFlow::Continue(()) => Ok(slab),
                    ControlFlow::Break(()) => Err(Cancelled),
                }
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(merge(&outputs, &workers.into_outputs()))
}

/// Where streamed extraction gets its samples from, one `z` layer at a time (`nx·ny` values,
/// x fastest), already relative to the iso value (inside negative) and finite.
pub trait LayerSource: Sync {
    type Error: Send;
    /// Fills `out` with sample layer `k`; returns how many of its samples were not finite
    /// (NaN, ±∞) and were replaced as [`skelform_field::grid::sanitize`] does.
    fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, Self::Error>;
}

/// Why streamed extraction stopped.
#[derive(Debug)]
pub enum StreamError<E> {
    Cancelled,
    Source(E),
}

/// What streamed extraction gives besides the mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamStats {
    pub ambiguous_faces: u64,
    pub tunnels: u64,
    /// Samples that were not finite (each lattice point counted once).
    pub non_finite: u64,
    pub min_sample: f32,
    pub max_sample: f32,
    /// Layer reads (or evaluations) including the layer that two slabs share.
    pub samples_read: u64,
    /// Time spent in the source and in extraction, summed over the workers.
    pub source_time: std::time::Duration,
    pub extract_time: std::time::Duration,
}

/// Marching cubes over a volume that is never held whole: each worker fetches the `SLAB + 1`
/// sample layers of one slab from `source`, extracts it and drops them, so memory follows the
/// number of threads, not the volume. The layer between two slabs is fetched by both (one
/// extra layer per slab). The mesh is identical to [`extract`]'s on the same samples, on any
/// number of threads.
pub fn extract_streamed<V: SlabVertex, S: LayerSource>(
    source: &S,
    grid: &Grid,
    control: &Control,
) -> Result<Streamed<V>, StreamError<S::Error>> {
    use std::time::Instant;
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let cube_layers = nz - 1;
    let slabs = cube_layers.div_ceil(SLAB);
    let done = AtomicU64::new(0);
    type Part = (Slab, u64, (f32, f32), std::time::Duration, std::time::Duration);
    let workers = Workers::new(nx, ny);
    let outputs: Vec<Part> = (0..slabs)
        .into_par_iter()
        .with_max_len(1)
        .map(|s| {
            workers.with(|worker| {
                let z0 = s * SLAB;
                let z1 = (z0 + SLAB).min(cube_layers);
                let last = z1 == cube_layers;
                let t = Instant::now();
                let mut layers = std::mem::take(&mut worker.layers);
                layers.resize((z1 - z0 + 1) * layer, 0.0);
                let mut non_finite = 0;
                for (n, out) in layers.chunks_mut(layer).enumerate() {
                    if control.is_cancelled() {
                        return Err(StreamError::Cancelled);
                    }
                    let bad = source.layer(z0 + n, out).map_err(StreamError::Source)?;
                    // The top layer is counted by the slab above, unless there is none.
                    if z0 + n < z1 || last {
                        non_finite += bad;
                    }
                }
                let range =
                    layers.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                        (lo.min(v), hi.max(v))
                    });
                let sourced = t.elapsed();
                let t = Instant::now();
                let slab = extract_slab(grid, &layers, z0, z1, worker, control)
                    .map_err(|_| StreamError::Cancelled)?;
                worker.layers = layers;
                let extracted = t.elapsed();
                let d = done.fetch_add((z1 - z0) as u64, Ordering::Relaxed) + (z1 - z0) as u64;
                let p = Progress {
                    phase: "sampling and extracting",
                    done: d,
                    total: Some(cube_layers as u64),
                };
                match control.report(p) {
                    ControlFlow::Continue(()) => Ok((slab, non_finite, range, sourced, extracted)),
                    ControlFlow::Break(()) => Err(StreamError::Cancelled),
                }
            })
        })
        .collect::<Result<_, _>>()?;
    let mut stats = StreamStats {
        min_sample: f32::INFINITY,
        max_sample: f32::NEG_INFINITY,
        samples_read: (cube_layers + slabs) as u64 * layer as u64,
        ..StreamStats::default()
    };
    let mut slabs = Vec::with_capacity(outputs.len());
    for (slab, non_finite, (lo, hi), sourced, extracted) in outputs {
        stats.non_finite += non_finite;
        stats.min_sample = stats.min_sample.min(lo);
        stats.max_sample = stats.max_sample.max(hi);
        stats.source_time += sourced;
        stats.extract_time += extracted;
        slabs.push(slab);
    }
    let (vertices, triangles, ambiguous_faces, tunnels) = merge(&slabs, &workers.into_outputs());
    stats.ambiguous_faces = ambiguous_faces;
    stats.tunnels = tunnels;
    Ok(Streamed { vertices, triangles, stats })
}

/// Cuts `all` into consecutive pieces of the given lengths.
fn split_lengths<T>(mut all: &mut [T], lengths: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut pieces = Vec::new();
    for n in lengths {
        let (head, tail) = all.split_at_mut(n);
        pieces.push(head);
        all = tail;
    }
    pieces
}

/// Joins the slabs in order, in parallel: each slab's vertices are offset by the counts of
/// the slabs before it, and its references to the layer above by the next slab's offset.
fn merge<V: SlabVertex>(outputs: &[Slab], arrays: &[Output<V>]) -> Extracted<V> {
    let mut bases = Vec::with_capacity(outputs.len());
    let mut total = 0u32;
    for o in outputs {
        bases.push(total);
        total += o.vertices.len() as u32;
    }
    let mut vertices = super::pages::zeroed_vec::<V>(total as usize);
    let mut triangles =
        super::pages::zeroed_vec::<[u32; 3]>(outputs.iter().map(|o| o.triangles.len()).sum());
    let vertex_pieces = split_lengths(&mut vertices, outputs.iter().map(|o| o.vertices.len()));
    let triangle_pieces = split_lengths(&mut triangles, outputs.iter().map(|o| o.triangles.len()));
    vertex_pieces.into_par_iter().zip(triangle_pieces).enumerate().for_each(|(s, (vs, ts))| {
        let o = &outputs[s];
        let out = &arrays[o.worker];
        vs.copy_from_slice(&out.vertices[o.vertices.clone()]);
        let resolve =
            |i: u32| if i & BORROWED == 0 { bases[s] + i } else { bases[s + 1] + (i & !BORROWED) };
        for (out, t) in ts.iter_mut().zip(&out.triangles[o.triangles.clone()]) {
            *out = t.map(resolve);
        }
    });
    let ambiguous_faces = outputs.iter().map(|o| o.ambiguous_faces).sum();
    let tunnels = outputs.iter().map(|o| o.tunnels).sum();
    (vertices, triangles, ambiguous_faces, tunnels)
}

/// Edge vertex maps for one layer of cubes, in one array of five planes of `nx·ny` slots:
/// the x- and y-edges of the two sample layers (planes 0–1 and 2–3, which swap roles as
/// the layer of cubes moves up) and the z-edges between them (plane 4). A cube's edge `e`
/// is at the cube's cell index plus a per-edge offset that depends only on the layer, so a
/// lookup is one add and one load. Entries are reset through lists of the slots set, so the
/// cost of clearing follows the number of vertices, not the size of the layer.
struct EdgeMaps {
    nx: usize,
    layer: usize,
    slots: Vec<u32>,
    /// Slots set, per plane pair: `[first layer pair, second layer pair, z]`.
    set: [Vec<u32>; 3],
    /// Whether planes 2–3 (rather than 0–1) hold the lower sample layer.
    flipped: bool,
    /// Per cube edge: the slot offset from the cube's cell index, and the set list it goes to.
    offset: [usize; 12],
    list: [u8; 12],
}

impl EdgeMaps {
    fn new(nx: usize, ny: usize) -> Self {
        let layer = nx * ny;
        let mut maps = EdgeMaps {
            nx,
            layer,
            slots: vec![NONE; 5 * layer],
            set: [Vec::new(), Vec::new(), Vec::new()],
            flipped: false,
            offset: [0; 12],
            list: [0; 12],
        };
        maps.place_edges();
        maps
    }

    /// The first plane of the lower (`upper = false`) or upper sample layer's x/y-edges.
    fn pair(&self, upper: bool) -> usize {
        usize::from(upper != self.flipped)
    }

    fn place_edges(&mut self) {
        for (e, &[c0, _]) in EDGES.iter().enumerate() {
            let [dx, dy, dz] = CORNERS[c0];
            let axis = edge_axis(e);
            let (plane, list) = if axis == 2 {
                (4, 2)
            } else {
                let pair = self.pair(dz == 1);
                (2 * pair + axis, pair)
            };
            self.offset[e] = plane * self.layer + dx + self.nx * dy;
            self.list[e] = list as u8;
        }
    }

    fn clear(&mut self, list: usize) {
        for &s in &self.set[list] {
            self.slots[s as usize] = NONE;
        }
        self.set[list].clear();
    }

    /// Clears every map, for the next slab.
    fn reset(&mut self) {
        (0..3).for_each(|l| self.clear(l));
        self.flipped = false;
        self.place_edges();
    }

    /// Moves up one layer: the upper sample layer becomes the lower, the new upper and the
    /// z-edges are cleared.
    fn advance(&mut self) {
        self.clear(self.pair(false));
        self.clear(2);
        self.flipped = !self.flipped;
        self.place_edges();
    }
}

/// The bits of word `w` of a row that stand for the items `0..count` of the row (samples,
/// or cubes and x-edges, which are one fewer).
#[inline]
fn word_mask(w: usize, count: usize) -> u64 {
    let n = count.saturating_sub(w * 64).min(64);
    if n == 64 { u64::MAX } else { (1u64 << n) - 1 }
}

/// Bit `i` of the row words: whether sample `i` of the row is inside (`f < 0`).
fn row_signs(values: &[f32], out: &mut [u64]) {
    for (w, chunk) in out.iter_mut().zip(values.chunks(64)) {
        *w = if chunk.len() == 64 { signs64(chunk) } else { signs_scalar(chunk) };
    }
}

fn signs_scalar(chunk: &[f32]) -> u64 {
    let mut bits = 0u64;
    for (b, &v) in chunk.iter().enumerate() {
        bits |= ((v < 0.0) as u64) << b;
    }
    bits
}

/// [`signs_scalar`] of 64 samples, four at a time with SSE2 (part of every x86-64 CPU):
/// sixteen compares and mask extractions instead of 64 compares, shifts and ors. `v < 0`
/// exactly as the scalar form (false for −0 and NaN).
#[cfg(target_arch = "x86_64")]
fn signs64(chunk: &[f32]) -> u64 {
    use std::arch::x86_64::{_mm_cmplt_ps, _mm_loadu_ps, _mm_movemask_ps, _mm_setzero_ps};
    assert_eq!(chunk.len(), 64);
    let mut bits = 0u64;
    for q in 0..16 {
        // SAFETY: SSE2 is in the x86-64 baseline, and `4 * q + 3 < 64 == chunk.len()`
        // (asserted above), so the unaligned load reads inside the slice.
        let m = unsafe {
            let v = _mm_loadu_ps(chunk.as_ptr().add(4 * q));
            _mm_movemask_ps(_mm_cmplt_ps(v, _mm_setzero_ps()))
        };
        bits |= (m as u64) << (4 * q);
    }
    bits
}

#[cfg(not(target_arch = "x86_64"))]
fn signs64(chunk: &[f32]) -> u64 {
    signs_scalar(chunk)
}

/// Sign words of every row of layer `k`: `ny` rows of `words` words.
fn layer_signs(layer: &[f32], nx: usize, words: usize, out: &mut [u64]) {
    for (row, o) in layer.chunks(nx).zip(out.chunks_mut(words)) {
        row_signs(row, o);
    }
}

/// The sign words of the four sample rows around row `j` of cubes: rows `j` and `j + 1` of
/// the layer below, then of the layer above (corner bit order: y, then z).
#[inline]
fn cube_rows<'a>(below: &'a [u64], above: &'a [u64], j: usize, words: usize) -> [&'a [u64]; 4] {
    let row = |layer: &'a [u64], j: usize| &layer[j * words..(j + 1) * words];
    [row(below, j), row(below, j + 1), row(above, j), row(above, j + 1)]
}

/// Bit `b` of the result: whether cube `64·w + b` of a row of cubes has corners of both
/// signs, from the sign words of the four sample rows around it (bits past the row's last
/// cube are garbage: mask them).
#[inline]
fn mixed_cubes(rows: &[&[u64]; 4], w: usize) -> u64 {
    let any = |w: usize| rows.iter().fold(0u64, |m, r| m | r[w]);
    let all = |w: usize| rows.iter().fold(u64::MAX, |m, r| m & r[w]);
    let (or, and) = (any(w), all(w));
    let words = rows[0].len();
    let (or_next, and_next) = if w + 1 < words { (any(w + 1) & 1, all(w + 1) & 1) } else { (0, 0) };
    // Cube i spans samples i and i + 1.
    let some_inside = or | (or >> 1) | (or_next << 63);
    let all_inside = and & ((and >> 1) | (and_next << 63));
    some_inside & !all_inside
}

/// How many cubes of the volume the surface passes through (corners of both signs): the
/// classification phase of extraction on its own, for statistics and benchmarks.
pub fn surface_cubes(volume: &Volume) -> u64 {
    let [nx, ny, nz] = volume.grid.dims;
    let layer = nx * ny;
    let words = nx.div_ceil(64);
    (0..nz - 1)
        .into_par_iter()
        .map(|k| {
            let (mut below, mut above) = (vec![0u64; ny * words], vec![0u64; ny * words]);
            layer_signs(&volume.values[k * layer..(k + 1) * layer], nx, words, &mut below);
            layer_signs(&volume.values[(k + 1) * layer..(k + 2) * layer], nx, words, &mut above);
            let mut count = 0u64;
            for j in 0..ny - 1 {
                let rows = cube_rows(&below, &above, j, words);
                for w in 0..words {
                    count += (mixed_cubes(&rows, w) & word_mask(w, nx - 1)).count_ones() as u64;
                }
            }
            count
        })
        .sum()
}

/// Marching cubes over the cube layers `z0..z1`; `vals` holds the sample layers
/// `z0..=z1` (and possibly more), starting with layer `z0`.
fn extract_slab<V: SlabVertex>(
    grid: &Grid,
    vals: &[f32],
    z0: usize,
    z1: usize,
    worker: &mut Worker<V>,
    control: &Control,
) -> Result<Slab, Cancelled> {
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let last = z1 == nz - 1;
    let Worker { index, out, maps, below, above, bottom_numbers, top_numbers, last_sizes, .. } =
        worker;
    maps.reset();
    let local = |k: usize| &vals[(k - z0) * layer..(k - z0 + 1) * layer];
    let offsets: [usize; 8] = CORNERS.map(|[x, y, z]| x + nx * y + layer * z);
    // Sign bits of the sample layers below and above the current layer of cubes: a cube has
    // the surface in it when its eight bits are not all equal, which 64 cubes at a time
    // reduce to a few word operations; only those cubes are visited.
    let words = nx.div_ceil(64);
    layer_signs(local(z0), nx, words, below);
    bottom_numbers.build(below, nx, ny, words);
    // Neighbouring slabs of a smooth surface make about as many vertices and triangles. The
    // bottom layer's vertices come first, at their numbers.
    make_room(&mut out.vertices, 2 * last_sizes.0);
    make_room(&mut out.triangles, 2 * last_sizes.1);
    let (first_vertex, first_triangle) = (out.vertices.len(), out.triangles.len());
    out.vertices.resize(first_vertex + bottom_numbers.total as usize, V::default());
    let (mut ambiguous_faces, mut tunnels) = (0, 0);
    for k in z0..z1 {
        if control.is_cancelled() {
            return Err(Cancelled);
        }
        layer_signs(local(k + 1), nx, words, above);
        // The x- and y-edges on the slab's top layer belong to the slab above (except for
        // the last slab, which owns the volume's top): refer to them by number.
        let top_borrows = k + 1 == z1 && !last;
        if top_borrows {
            top_numbers.build(above, nx, ny, words);
        }
        for j in 0..ny - 1 {
            let rows = cube_rows(below, above, j, words);
            for w in 0..words {
                // Cubes are i < nx - 1: the last sample's bit and those past it are masked out.
                let mut mixed = mixed_cubes(&rows, w) & word_mask(w, nx - 1);
                while mixed != 0 {
                    let i = w * 64 + mixed.trailing_zeros() as usize;
                    mixed &= mixed - 1;
                    let base = nx * j + layer * (k - z0) + i;
                    let v: [f32; 8] = offsets.map(|o| vals[base + o]);
                    let case = two_bits(rows[0], i)
                        | two_bits(rows[1], i) << 2
                        | two_bits(rows[2], i) << 4
                        | two_bits(rows[3], i) << 6;
                    let mut sink = SlabSink {
                        out: &mut *out,
                        first_vertex,
                        maps: &mut *maps,
                        grid,
                        at: [i, j, k],
                        cell: i + nx * j,
                        bottom: (k == z0).then_some(&*bottom_numbers),
                        top: top_borrows.then_some(&*top_numbers),
                    };
                    let outcome = polygonize_case(case, &v, &mut sink);
                    ambiguous_faces += outcome.ambiguous_faces as u64;
                    tunnels += outcome.tunnel as u64;
                }
            }
        }
        maps.advance();
        std::mem::swap(below, above);
    }
    let slab = Slab {
        worker: *index,
        vertices: first_vertex..out.vertices.len(),
        triangles: first_triangle..out.triangles.len(),
        ambiguous_faces,
        tunnels,
    };
    *last_sizes = (slab.vertices.len(), slab.triangles.len());
    Ok(slab)
}

/// Bits `i` and `i + 1` of a row of sign words: the inside flags of a cube's two corners
/// on that row.
#[inline]
fn two_bits(row: &[u64], i: usize) -> usize {
    let (w, b) = (i / 64, i % 64);
    let lo = row[w] >> b;
    let bits = if b == 63 { (lo & 1) | ((row[w + 1] & 1) << 1) } else { lo & 3 };
    bits as usize
}

/// The slab's side of [`CubeSink`]: edge vertices keyed by lattice edge in dense maps.
struct SlabSink<'a, V> {
    /// The worker's output, and where the slab's vertices start in it.
    out: &'a mut Output<V>,
    first_vertex: usize,
    maps: &'a mut EdgeMaps,
    grid: &'a Grid,
    at: [usize; 3],
    /// The cube's index within its layer, `i + nx·j`.
    cell: usize,
    /// The numbering of the slab's bottom layer, while the cube is on it.
    bottom: Option<&'a LayerNumbering>,
    /// The numbering of the slab's top layer, while the cube is under it and its x/y-edges
    /// belong to the slab above.
    top: Option<&'a LayerNumbering>,
}

impl<V> SlabSink<'_, V> {
    /// Adds a vertex that is not on the bottom layer; its index within the slab.
    #[inline]
    fn push(&mut self, v: V) -> u32 {
        self.out.vertices.push(v);
        (self.out.vertices.len() - self.first_vertex - 1) as u32
    }
}

impl<V: SlabVertex> CubeSink for SlabSink<'_, V> {
    #[inline]
    fn edge_vertex(&mut self, e: usize, ends: [f32; 2]) -> u32 {
        let slot = self.cell + self.maps.offset[e];
        let known = self.maps.slots[slot];
        if known != NONE {
            return !known;
        }
        let [c0, _] = EDGES[e];
        let [dx, dy, dz] = CORNERS[c0];
        let axis = edge_axis(e);
        let [i, j, k] = self.at;
        let numbering = match (axis, dz) {
            (2, _) => None,
            (_, 0) => self.bottom,
            _ => self.top,
        };
        let id = match numbering {
            Some(top) if dz == 1 => BORROWED | top.number(axis, i + dx, j + dy),
            _ => {
                let v = GridVertex {
                    base: [(i + dx) as u32, (j + dy) as u32, (k + dz) as u32],
                    place: Place::Edge { dir: 1 << axis, t: crossing(ends[0], ends[1]) },
                };
                let v = V::make(self.grid, v, ends);
                match numbering {
                    Some(bottom) => {
                        let n = bottom.number(axis, i + dx, j + dy);
                        self.out.vertices[self.first_vertex + n as usize] = v;
                        n
                    }
                    None => self.push(v),
                }
            }
        };
        let maps = &mut *self.maps;
        maps.slots[slot] = !id;
        maps.set[maps.list[e] as usize].push(slot as u32);
        id
    }

    fn cell_vertex(&mut self, offset: [f64; 3]) -> u32 {
        let [i, j, k] = self.at;
        let v = GridVertex { base: [i as u32, j as u32, k as u32], place: Place::Cell { offset } };
        self.push(V::make(self.grid, v, [0.0; 2]))
    }

    fn triangle(&mut self, t: [u32; 3]) {
        self.out.triangles.push(t);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// Samples in (-1, 1) from a small deterministic generator, with some exact zeros.
    fn noise(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let v = ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
                if v.abs() < 0.05 { 0.0 } else { v }
            })
            .collect()
    }

    #[test]
    fn layer_numbers_are_the_crossed_edges_in_row_order() {
        let (nx, ny) = (70, 5);
        let values = noise(nx * ny, 7);
        let words = nx.div_ceil(64);
        let mut signs = vec![0; ny * words];
        layer_signs(&values, nx, words, &mut signs);
        let mut numbers = LayerNumbering::default();
        numbers.build(&signs, nx, ny, words);
        let inside = |i: usize, j: usize| values[i + nx * j] < 0.0;
        let mut expected = 0;
        for j in 0..ny {
            for i in 0..nx - 1 {
                if inside(i, j) != inside(i + 1, j) {
                    assert_eq!(numbers.number(0, i, j), expected, "x-edge ({i}, {j})");
                    expected += 1;
                }
            }
            if j + 1 == ny {
                continue;
            }
            for i in 0..nx {
                if inside(i, j) != inside(i, j + 1) {
                    assert_eq!(numbers.number(1, i, j), expected, "y-edge ({i}, {j})");
                    expected += 1;
                }
            }
        }
        assert_eq!(numbers.total, expected);
    }

    /// Noise over several slabs: every vertex is used, lies on a crossed lattice edge and is
    /// the only one there, whatever slab made it; no edge has more than two triangles.
    #[test]
    fn slabs_share_their_boundary_vertices() {
        let dims = [67, 6, 3 * SLAB + 4];
        let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
        let volume = Volume::from_values(grid, noise(dims.iter().product(), 11));
        let x = extract(&volume, &Control::default()).unwrap_or_else(|_| unreachable!());
        let mut used = vec![false; x.vertices.len()];
        let mut edges = std::collections::HashMap::new();
        for t in &x.triangles {
            for k in 0..3 {
                used[t[k] as usize] = true;
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                *edges.entry((a, b)).or_insert(0) += 1;
            }
        }
        assert!(used.iter().all(|&u| u), "a vertex no triangle uses");
        assert!(edges.values().all(|&n| n <= 2), "an edge of more than two triangles");
        let mut places = std::collections::HashSet::new();
        let at = |p: [u32; 3]| {
            volume.values[p[0] as usize + dims[0] * (p[1] as usize + dims[1] * p[2] as usize)]
        };
        for v in &x.vertices {
            if let Place::Edge { dir, .. } = v.place {
                let tip = v.tip().unwrap_or_else(|| unreachable!());
                assert_ne!(
                    at(v.base) < 0.0,
                    at(tip) < 0.0,
                    "{v:?} is on an edge the surface does not cross"
                );
                assert!(places.insert((v.base, dir)), "two vertices on the edge of {v:?}");
            }
        }
    }
}
