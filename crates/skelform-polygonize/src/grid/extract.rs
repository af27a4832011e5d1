//! Marching cubes over a sampled [`Volume`], in parallel z-slabs joined in a fixed order.
//!
//! Vertices are named as in Flying Edges: the crossed edges of each sample layer, and those
//! between two layers, are numbered in a fixed order computed from the layers' sign bits
//! alone ([`LayerNumbering`], [`ZNumbering`]), so a cube finds the vertex on its edge by a
//! population count, with no map to look it up in, and each edge vertex is made once, in
//! number order. Each slab owns the edge vertices on its own sample layers (the last slab
//! also owns the top layer); the slab below refers to the layer it shares with the slab
//! above by those numbers, which land on the next slab's first vertices. The mesh is the
//! slabs in order ([`run_slabs`]), each placed as soon as the slabs below it are counted.
//! Slab boundaries depend only on the grid, never on the thread count, so the output is the
//! same bit for bit on any number of threads.

use std::ops::ControlFlow;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

use rayon::prelude::*;

use skelform_field::control::{Control, Progress};
use skelform_field::grid::{Grid, Volume};

use super::assembly::Assembly;
use super::cell::{CubeSink, crossing, polygonize_case};
use super::cube::CORNERS;

/// Cube layers per slab. A constant, so that results never depend on the thread count.
pub const SLAB: usize = 8;

const BORROWED: u32 = 1 << 31;

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
pub trait SlabVertex: Copy + Default + Send + Sync + 'static {
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

impl std::borrow::Borrow<GridVertex> for SampledVertex {
    fn borrow(&self) -> &GridVertex {
        &self.vertex
    }
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

/// Vertices and triangles, appended to by [`SlabStore`]: the mesh itself when one thread
/// runs every slab, else a thread's buffer for the slab it is running.
#[derive(Default)]
struct Output<V> {
    vertices: Vec<V>,
    triangles: Vec<[u32; 3]>,
}

/// Makes room for at least `more` elements past the end of `v`, and for a few huge pages'
/// worth: room costs address space only until it is written, and growing by small steps
/// would copy into memory the kernel has not been asked to back with huge pages.
fn make_room<T>(v: &mut Vec<T>, more: usize) {
    if v.capacity() - v.len() < more {
        let step = skelform_field::pages::ROOM / std::mem::size_of::<T>().max(1);
        v.reserve(more.max(v.capacity()).max(step));
        skelform_field::pages::advise_huge(v.as_ptr(), v.capacity());
    }
}

/// One word of a row of edges: the crossed ones (bit `i`: the edge from sample `64·w + i`)
/// and how many crossed edges come before the word in their numbering.
#[derive(Clone, Copy, Default)]
struct Counted {
    bits: u64,
    before: u32,
}

impl Counted {
    /// The number of crossed edge `i % 64` of the word.
    #[inline]
    fn number(&self, i: usize) -> u32 {
        debug_assert!(self.bits >> (i % 64) & 1 == 1, "edge {i} is not crossed");
        self.before + (self.bits & ((1u64 << (i % 64)) - 1)).count_ones()
    }
}

/// The crossed x- and y-edges of one sample layer (corners of both signs), numbered row by
/// row: in each row its x-edges, then the y-edges to the next row, each by x. The numbers
/// come from the layer's sign words alone, so the two slabs that share a layer agree on them
/// without looking at each other's work, as Flying Edges numbers its edges by counting.
#[derive(Default)]
struct LayerNumbering {
    words: usize,
    /// Per row and word, the crossed x- and y-edges.
    x: Vec<Counted>,
    y: Vec<Counted>,
    total: u32,
    /// The number of the layer's first vertex in its slab's output, or [`BORROWED`] when
    /// the layer's vertices are the next slab's.
    offset: u32,
}

impl LayerNumbering {
    /// Numbers the edges of a layer of `ny` rows of sign words (see [`layer_signs`]).
    fn build(&mut self, signs: &[u64], nx: usize, ny: usize, words: usize) {
        self.words = words;
        self.x.resize(ny * words, Counted::default());
        self.y.resize(ny * words, Counted::default());
        let (x_last, y_last) = (word_mask(words - 1, nx - 1), word_mask(words - 1, nx));
        let mut count = 0u32;
        for j in 0..ny {
            let row = &signs[j * words..][..words];
            let xs = &mut self.x[j * words..][..words];
            for w in 0..words {
                let (bits, mask) = match row.get(w + 1) {
                    Some(next) => (row[w] ^ ((row[w] >> 1) | (next << 63)), u64::MAX),
                    None => (row[w] ^ (row[w] >> 1), x_last),
                };
                let bits = bits & mask;
                xs[w] = Counted { bits, before: count };
                count += bits.count_ones();
            }
            if j + 1 < ny {
                let up = &signs[(j + 1) * words..][..words];
                count_across(row, up, y_last, &mut self.y[j * words..][..words], &mut count);
            }
        }
        self.total = count;
    }

    /// The output number (or `BORROWED |` number) of the crossed x (`axis` 0) or y edge
    /// from sample `(i, j)`.
    #[inline]
    fn id(&self, axis: usize, i: usize, j: usize) -> u32 {
        self.offset + self.number(axis, i, j)
    }

    /// Makes the layer's vertices in the order of their numbers, from the layer's samples
    /// (`nx·ny`, x fastest); `k` is the layer's index.
    fn emit<V: SlabVertex>(
        &self,
        grid: &Grid,
        vals: &[f32],
        k: usize,
        store: &mut SlabStore<'_, V>,
    ) {
        let [nx, ny, _] = grid.dims;
        for j in 0..ny {
            let row = j * self.words..(j + 1) * self.words;
            for_each_bit(&self.x[row.clone()], |i| {
                let at = i + nx * j;
                store.push_vertex(edge_record(grid, [i, j, k], 0, [vals[at], vals[at + 1]]));
            });
            if j + 1 < ny {
                for_each_bit(&self.y[row], |i| {
                    let at = i + nx * j;
                    store.push_vertex(edge_record(grid, [i, j, k], 1, [vals[at], vals[at + nx]]));
                });
            }
        }
    }

    /// The number of the crossed x (`axis` 0) or y edge from sample `(i, j)`.
    #[inline]
    fn number(&self, axis: usize, i: usize, j: usize) -> u32 {
        let words = if axis == 0 { &self.x } else { &self.y };
        words[j * self.words + i / 64].number(i)
    }
}

/// The crossed z-edges between two sample layers, numbered row by row like
/// [`LayerNumbering`]'s edges.
#[derive(Default)]
struct ZNumbering {
    words: usize,
    edges: Vec<Counted>,
    /// The output number of the first of them.
    offset: u32,
}

impl ZNumbering {
    fn build(&mut self, lower: &[u64], upper: &[u64], nx: usize, words: usize) {
        self.words = words;
        self.edges.resize(lower.len(), Counted::default());
        let last = word_mask(words - 1, nx);
        let mut count = 0u32;
        let rows = lower.chunks_exact(words).zip(upper.chunks_exact(words));
        for ((a, b), out) in rows.zip(self.edges.chunks_exact_mut(words)) {
            count_across(a, b, last, out, &mut count);
        }
    }

    #[inline]
    fn id(&self, i: usize, j: usize) -> u32 {
        self.offset + self.edges[j * self.words + i / 64].number(i)
    }

    /// Makes the vertices in the order of their numbers; `lower` and `upper` are the two
    /// layers' samples, `k` the lower one's index.
    fn emit<V: SlabVertex>(
        &self,
        grid: &Grid,
        lower: &[f32],
        upper: &[f32],
        k: usize,
        store: &mut SlabStore<'_, V>,
    ) {
        let nx = grid.dims[0];
        for (j, row) in self.edges.chunks(self.words).enumerate() {
            for_each_bit(row, |i| {
                let at = i + nx * j;
                store.push_vertex(edge_record(grid, [i, j, k], 2, [lower[at], upper[at]]));
            });
        }
    }
}

/// Numbers the crossed edges from each sample of row `a` to the same sample of row `b` (the
/// next row, or the row above in the next layer) into `out`, continuing from `count`; `last`
/// masks the samples past the row's end in its last word.
#[inline]
fn count_across(a: &[u64], b: &[u64], last: u64, out: &mut [Counted], count: &mut u32) {
    let words = out.len();
    for (w, o) in out.iter_mut().enumerate() {
        let mask = if w + 1 < words { u64::MAX } else { last };
        let bits = (a[w] ^ b[w]) & mask;
        *o = Counted { bits, before: *count };
        *count += bits.count_ones();
    }
}

/// Calls `f(i)` for each crossed edge `i` of a row, in order.
#[inline]
fn for_each_bit(words: &[Counted], mut f: impl FnMut(usize)) {
    for (w, word) in words.iter().enumerate() {
        let mut bits = word.bits;
        while bits != 0 {
            f(w * 64 + bits.trailing_zeros() as usize);
            bits &= bits - 1;
        }
    }
}

/// The record of the vertex where the surface crosses the lattice edge from sample `base`
/// along `axis`, whose end samples are `ends`.
#[inline]
fn edge_record<V: SlabVertex>(grid: &Grid, base: [usize; 3], axis: usize, ends: [f32; 2]) -> V {
    let v = GridVertex {
        base: base.map(|x| x as u32),
        place: Place::Edge { dir: 1 << axis, t: crossing(ends[0], ends[1]) },
    };
    V::make(grid, v, ends)
}

/// A thread's working memory, reused for every slab it runs: the sign words and edge
/// numberings of the layers it works on, and the sample layers of a streamed slab.
struct Scratch {
    /// Sign words of the sample layers below and above the current layer of cubes.
    below: Vec<u64>,
    above: Vec<u64>,
    /// The numbered x/y-edges of those two layers, and the z-edges between them.
    lower: LayerNumbering,
    upper: LayerNumbering,
    z: ZNumbering,
    /// The sample layers of the slab, when they are streamed from a [`LayerSource`].
    layers: Vec<f32>,
    /// Which layer the last of `layers` is, and how many of its samples were not finite:
    /// the next slab starts with it, if this thread runs that slab.
    top: Option<(usize, u64)>,
}

impl Scratch {
    fn new(nx: usize, ny: usize) -> Self {
        let words = nx.div_ceil(64);
        Scratch {
            below: vec![0; ny * words],
            above: vec![0; ny * words],
            lower: LayerNumbering::default(),
            upper: LayerNumbering::default(),
            z: ZNumbering::default(),
            layers: Vec::new(),
            top: None,
        }
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

/// Whether a lattice has a cube: a [`Grid`] built by hand may have fewer than 2 samples
/// along an axis, and then there is nothing to extract.
fn has_cells(grid: &Grid) -> bool {
    grid.dims.iter().all(|&d| d >= 2)
}

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
    if !has_cells(&grid) {
        return Ok((Vec::new(), Vec::new(), 0, 0));
    }
    let [nx, ny, _] = grid.dims;
    let cube_layers = grid.dims[2] - 1;
    let done = AtomicU64::new(0);
    let (vertices, triangles, counts) =
        run_slabs(cube_layers.div_ceil(SLAB), [nx, ny], |s, scratch, store| {
            let z0 = s * SLAB;
            let z1 = (z0 + SLAB).min(cube_layers);
            let vals = &volume.values[z0 * nx * ny..];
            let counts = extract_slab(&grid, vals, (z0, z1), scratch, store, control)?;
            slab_done(control, &done, z1 - z0, cube_layers, "extracting").map(|()| counts)
        })?;
    let (ambiguous_faces, tunnels) = counts.iter().fold((0, 0), |(a, t), c| (a + c.0, t + c.1));
    Ok((vertices, triangles, ambiguous_faces, tunnels))
}

/// Adds a slab's `layers` cube layers to the progress count and reports it.
fn slab_done(
    control: &Control,
    done: &AtomicU64,
    layers: usize,
    total: usize,
    phase: &'static str,
) -> Result<(), Cancelled> {
    let d = done.fetch_add(layers as u64, Ordering::Relaxed) + layers as u64;
    match control.report(Progress { phase, done: d, total: Some(total as u64) }) {
        ControlFlow::Continue(()) => Ok(()),
        ControlFlow::Break(()) => Err(Cancelled),
    }
}

/// Where streamed extraction gets its samples from, one `z` layer at a time (`nx·ny` values,
/// x fastest), already relative to the iso value (inside negative) and finite.
pub trait LayerSource: Sync {
    type Error: Send;
    /// Fills `out` with sample layer `k`; returns how many of its samples were not finite
    /// (NaN, ±∞) and were replaced as [`skelform_field::grid::sanitize`] does.
    fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, Self::Error>;

    /// Fills `out` with layers `first..first + bad.len()`, one after the other, and `bad[n]`
    /// with the count [`LayerSource::layer`] returns for the `n`-th. The default fetches one
    /// layer at a time; a source that shares work between layers can do better.
    fn layers(&self, first: usize, out: &mut [f32], bad: &mut [u64]) -> Result<(), Self::Error> {
        let layer = out.len() / bad.len().max(1);
        for (n, (out, bad)) in out.chunks_mut(layer.max(1)).zip(bad).enumerate() {
            *bad = self.layer(first + n, out)?;
        }
        Ok(())
    }
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
    /// Samples read (or evaluated): each layer once, and a layer that two slabs share twice
    /// when they ran on different threads.
    pub samples_read: u64,
    /// Time spent in the source and in extraction, summed over the workers.
    pub source_time: std::time::Duration,
    pub extract_time: std::time::Duration,
}

/// Marching cubes over a volume that is never held whole: each worker fetches the `SLAB + 1`
/// sample layers of one slab from `source`, extracts it and drops them, so memory follows the
/// number of threads, not the volume. The layer between two slabs is fetched once when one
/// thread runs both (on one thread, always), by each otherwise. The mesh is identical to
/// [`extract`]'s on the same samples, on any number of threads.
pub fn extract_streamed<V: SlabVertex, S: LayerSource>(
    source: &S,
    grid: &Grid,
    control: &Control,
) -> Result<Streamed<V>, StreamError<S::Error>> {
    use std::time::Instant;
    if !has_cells(grid) {
        return Ok(Streamed {
            vertices: Vec::new(),
            triangles: Vec::new(),
            stats: StreamStats::default(),
        });
    }
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let cube_layers = nz - 1;
    let slabs = cube_layers.div_ceil(SLAB);
    let done = AtomicU64::new(0);
    type Part = ((u64, u64), u64, (f32, f32), u64, std::time::Duration, std::time::Duration);
    let (vertices, triangles, parts) =
        run_slabs(slabs, [nx, ny], |s, scratch, store| -> Result<Part, _> {
            let z0 = s * SLAB;
            let z1 = (z0 + SLAB).min(cube_layers);
            let last = z1 == cube_layers;
            let t = Instant::now();
            if control.is_cancelled() {
                return Err(StreamError::Cancelled);
            }
            let mut layers = std::mem::take(&mut scratch.layers);
            let mut bad = [0; SLAB + 1];
            let bad = &mut bad[..=z1 - z0];
            // The slab below's top layer is this slab's first: when this thread ran that
            // slab, the layer is still here (always so on one thread).
            let first = match scratch.top.take() {
                Some((z, b)) if z == z0 => {
                    let len = layers.len();
                    layers.copy_within(len - layer.., 0);
                    bad[0] = b;
                    1
                }
                _ => 0,
            };
            layers.resize((z1 - z0 + 1) * layer, 0.0);
            source
                .layers(z0 + first, &mut layers[first * layer..], &mut bad[first..])
                .map_err(StreamError::Source)?;
            scratch.top = Some((z1, bad[z1 - z0]));
            // The top layer is counted by the slab above, unless there is none.
            let non_finite: u64 = bad[..z1 - z0 + usize::from(last)].iter().sum();
            let fetched = (z1 - z0 + 1 - first) as u64;
            let range = skelform_field::grid::value_range(&layers);
            let sourced = t.elapsed();
            let t = Instant::now();
            let counts = extract_slab(grid, &layers, (z0, z1), scratch, store, control)
                .map_err(|_| StreamError::Cancelled)?;
            scratch.layers = layers;
            let extracted = t.elapsed();
            slab_done(control, &done, z1 - z0, cube_layers, "sampling and extracting")
                .map_err(|_| StreamError::Cancelled)?;
            Ok((counts, non_finite, range, fetched, sourced, extracted))
        })?;
    let mut stats = StreamStats {
        min_sample: f32::INFINITY,
        max_sample: f32::NEG_INFINITY,
        ..StreamStats::default()
    };
    for ((ambiguous_faces, tunnels), non_finite, (lo, hi), fetched, sourced, extracted) in parts {
        stats.samples_read += fetched * layer as u64;
        stats.non_finite += non_finite;
        stats.min_sample = stats.min_sample.min(lo);
        stats.max_sample = stats.max_sample.max(hi);
        stats.source_time += sourced;
        stats.extract_time += extracted;
        stats.ambiguous_faces += ambiguous_faces;
        stats.tunnels += tunnels;
    }
    Ok(Streamed { vertices, triangles, stats })
}

/// What [`run_slabs`] returns: the mesh's vertices and triangles, and each slab's result in
/// slab order.
type Assembled<V, T> = (Vec<V>, Vec<[u32; 3]>, Vec<T>);

/// Runs `slab` on every slab and joins their pieces into one mesh, in slab order.
///
/// On one thread the slabs run in order straight into the mesh's arrays. On more, each
/// thread claims the lowest slab no one has claimed, runs it into a buffer of its own and
/// hands it over; a slab is placed in the mesh (an [`Assembly`]) as soon as every slab below
/// it has been handed over, by the thread that completes that chain, so no thread ever waits
/// for another, and every byte of the mesh is written once into fresh memory. A slab's
/// vertices go after all those of the slabs below it, its triangles' numbers shifted by as
/// many (a reference to the layer above, numbered just past the slab's own vertices, lands on
/// the next slab's first ones).
fn run_slabs<V, T, E>(
    slabs: usize,
    [nx, ny]: [usize; 2],
    slab: impl Fn(usize, &mut Scratch, &mut SlabStore<V>) -> Result<T, E> + Sync,
) -> Result<Assembled<V, T>, E>
where
    V: SlabVertex,
    T: Send,
    E: Send,
{
    let threads = rayon::current_num_threads().min(slabs);
    if threads <= 1 {
        let (mut out, mut scratch) = (Output::default(), Scratch::new(nx, ny));
        let (mut hint, mut results) = ((0, 0), Vec::with_capacity(slabs));
        for k in 0..slabs {
            let before = (out.vertices.len(), out.triangles.len());
            results.push(slab(k, &mut scratch, &mut SlabStore::new(&mut out, hint))?);
            hint = (out.vertices.len() - before.0, out.triangles.len() - before.1);
        }
        out.vertices.shrink_to_fit();
        out.triangles.shrink_to_fit();
        return Ok((out.vertices, out.triangles, results));
    }
    let chain = Mutex::new(Chain::new(slabs));
    let lock = || chain.lock().unwrap_or_else(|e| e.into_inner());
    let (next, stop) = (AtomicUsize::new(0), AtomicBool::new(false));
    let (vertices, triangles) = (Assembly::new(), Assembly::new());
    let work = || {
        let mut scratch = Scratch::new(nx, ny);
        let mut hint = (0, 0);
        while !stop.load(Ordering::Relaxed) {
            let k = next.fetch_add(1, Ordering::Relaxed);
            if k >= slabs {
                break;
            }
            let spare = lock().spare.pop();
            let mut out = spare.or_else(kept::take).unwrap_or_default();
            out.vertices.clear();
            out.triangles.clear();
            let result = slab(k, &mut scratch, &mut SlabStore::new(&mut out, hint));
            hint = (out.vertices.len(), out.triangles.len());
            let (ready, [nv, nt], placed) = match result {
                Ok(r) => lock().hand_over(k, r, out),
                Err(e) => {
                    lock().fail(k, e);
                    stop.store(true, Ordering::Relaxed);
                    break;
                }
            };
            if !ready.is_empty() {
                // Room for the placed slabs, and for the rest if they are like them, with a
                // margin: growing copies what has been placed, unless the allocator can
                // remap it.
                let guess = |n: usize| n + n / placed * (slabs - placed + 1) * 5 / 4;
                vertices.reserve(nv, guess(nv));
                triangles.reserve(nt, guess(nt));
            }
            for (o, [v0, t0]) in &ready {
                vertices.place(*v0, &o.vertices, |v| v);
                let shift = *v0 as u32;
                triangles.place(*t0, &o.triangles, |t| t.map(|i| i + shift));
            }
            lock().spare.extend(ready.into_iter().map(|(o, _)| o));
        }
    };
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| work());
        }
    });
    let mut chain = chain.into_inner().unwrap_or_else(|e| e.into_inner());
    kept::keep(std::mem::take(&mut chain.spare), 2 * threads);
    if let Some((_, e)) = chain.error {
        return Err(e);
    }
    assert_eq!(chain.placed, slabs, "a slab was never placed");
    let [nv, nt] = chain.end;
    // SAFETY: every slab was placed: slab k wrote vertices and triangles from the ends of
    // slab k − 1's, as many as it has, so together they cover 0..nv and 0..nt.
    let (vertices, triangles) = unsafe { (vertices.into_vec(nv), triangles.into_vec(nt)) };
    let results = chain.results.into_iter().flatten().collect();
    Ok((vertices, triangles, results))
}

/// Slab buffers kept from one extraction to the next, so that a program that extracts again
/// (frames of an animation, a benchmark's runs) does not fault in fresh pages for them every
/// time: memory the size of a few slabs' meshes per thread.
mod kept {
    use super::Output;
    use std::any::Any;
    use std::sync::Mutex;

    static KEPT: Mutex<Vec<Box<dyn Any + Send>>> = Mutex::new(Vec::new());

    /// A kept buffer for vertices of type `V`, if there is one.
    pub(super) fn take<V: Send + 'static>() -> Option<Output<V>> {
        let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
        let at = kept.iter().position(|b| b.is::<Output<V>>())?;
        kept.swap_remove(at).downcast().ok().map(|b| *b)
    }

    /// Keeps `buffers` for the next extraction, and no more than `most` of their type.
    pub(super) fn keep<V: Send + 'static>(buffers: Vec<Output<V>>, most: usize) {
        let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
        let held = kept.iter().filter(|b| b.is::<Output<V>>()).count();
        let room = most.saturating_sub(held);
        kept.extend(buffers.into_iter().take(room).map(|b| Box::new(b) as Box<dyn Any + Send>));
    }
}

/// Which slabs have been handed over and placed, for [`run_slabs`].
struct Chain<V, T, E> {
    /// The slabs below this one are placed.
    placed: usize,
    /// Where the next slab to place starts: its first vertex and first triangle.
    end: [usize; 2],
    /// Handed-over slabs not yet placed, by index.
    waiting: Vec<Option<Output<V>>>,
    results: Vec<Option<T>>,
    /// The failure of the lowest slab that failed.
    error: Option<(usize, E)>,
    /// Buffers of placed slabs, for the next slabs to run.
    spare: Vec<Output<V>>,
}

/// Slabs ready to be placed: each slab's output, with where its vertices and triangles start.
type Ready<V> = Vec<(Output<V>, [usize; 2])>;

impl<V, T, E> Chain<V, T, E> {
    fn new(slabs: usize) -> Self {
        Chain {
            placed: 0,
            end: [0, 0],
            waiting: (0..slabs).map(|_| None).collect(),
            results: (0..slabs).map(|_| None).collect(),
            error: None,
            spare: Vec::new(),
        }
    }

    /// Takes slab `k`'s output; returns the slabs that can now be placed (`k` and those
    /// after it, if all before it are placed), the end of the last of them, and how many
    /// slabs are then placed.
    fn hand_over(&mut self, k: usize, result: T, out: Output<V>) -> (Ready<V>, [usize; 2], usize) {
        self.results[k] = Some(result);
        self.waiting[k] = Some(out);
        let mut ready = Vec::new();
        while let Some(o) = self.waiting.get_mut(self.placed).and_then(Option::take) {
            let start = self.end;
            self.end = [start[0] + o.vertices.len(), start[1] + o.triangles.len()];
            self.placed += 1;
            ready.push((o, start));
        }
        (ready, self.end, self.placed)
    }

    /// Records slab `k`'s failure; the lowest slab's failure is the one reported.
    fn fail(&mut self, k: usize, e: E) {
        if self.error.as_ref().is_none_or(|(at, _)| k < *at) {
            self.error = Some((k, e));
        }
    }
}

/// The bits of word `w` of a row that stand for the items `0..count` of the row (samples,
/// or cubes and x-edges, which are one fewer).
#[inline]
fn word_mask(w: usize, count: usize) -> u64 {
    let n = count.saturating_sub(w * 64).min(64);
    if n == 64 { u64::MAX } else { (1u64 << n) - 1 }
}

/// Bit `i` of the row words: whether sample `i` of the row is inside (`f < 0`), with
/// `signs64` for each whole word.
#[inline(always)]
fn row_signs(values: &[f32], out: &mut [u64], signs64: impl Fn(&[f32]) -> u64) {
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
#[inline(always)]
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

/// Sign words with AVX2 where the CPU has it: eight samples per compare. The sign pass
/// reads every sample of the volume, so its instruction count matters as much as memory.
#[cfg(target_arch = "x86_64")]
mod wide {
    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    /// [`super::signs64`] eight samples at a time (`_CMP_LT_OQ`: false for NaN and −0, as
    /// `v < 0`).
    ///
    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    unsafe fn signs64(chunk: &[f32]) -> u64 {
        use std::arch::x86_64::{
            _CMP_LT_OQ, _mm256_cmp_ps, _mm256_loadu_ps, _mm256_movemask_ps, _mm256_setzero_ps,
        };
        assert_eq!(chunk.len(), 64);
        let mut bits = 0u64;
        for q in 0..8 {
            // SAFETY: AVX2 is there (the caller's promise), and `8 * q + 7 < 64 ==
            // chunk.len()` (asserted above), so the unaligned load reads inside the slice.
            let m = unsafe {
                let v = _mm256_loadu_ps(chunk.as_ptr().add(8 * q));
                _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(v, _mm256_setzero_ps()))
            };
            bits |= (m as u32 as u64) << (8 * q);
        }
        bits
    }

    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn layer_signs(layer: &[f32], nx: usize, words: usize, out: &mut [u64]) {
        for (row, o) in layer.chunks(nx).zip(out.chunks_mut(words)) {
            // SAFETY: AVX2 is there: the caller's promise.
            super::row_signs(row, o, |c| unsafe { signs64(c) });
        }
    }
}

/// Sign words of every row of layer `k`: `ny` rows of `words` words.
fn layer_signs(layer: &[f32], nx: usize, words: usize, out: &mut [u64]) {
    #[cfg(target_arch = "x86_64")]
    if wide::available() {
        // SAFETY: AVX2 was detected at run time.
        unsafe { wide::layer_signs(layer, nx, words, out) };
        return;
    }
    for (row, o) in layer.chunks(nx).zip(out.chunks_mut(words)) {
        row_signs(row, o, signs64);
    }
}

/// Asks the CPU to bring `values` into its cache ahead of use: a hint, with no effect on
/// the values or on correctness.
#[inline]
fn prefetch(values: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    for line in values.chunks(16) {
        use std::arch::x86_64::{_MM_HINT_T1, _mm_prefetch};
        // SAFETY: a prefetch never faults or changes memory, whatever the address; SSE is in
        // the x86-64 baseline.
        unsafe { _mm_prefetch::<_MM_HINT_T1>(line.as_ptr().cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = values;
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

/// Calls `f(i, j, case)` for every cube of a layer of cubes whose corners have both signs,
/// in row order, given the sign words of the sample layers below and above it; `row(j)`
/// before the cubes of row `j`.
#[inline(always)]
fn for_each_mixed_cube(
    below: &[u64],
    above: &[u64],
    nx: usize,
    ny: usize,
    mut row: impl FnMut(usize),
    mut f: impl FnMut(usize, usize, usize),
) {
    let words = nx.div_ceil(64);
    for j in 0..ny - 1 {
        row(j);
        let rows = cube_rows(below, above, j, words);
        for w in 0..words {
            // Cubes are i < nx - 1: the last sample's bit and those past it are masked out.
            let mut mixed = mixed_cubes(&rows, w) & word_mask(w, nx - 1);
            while mixed != 0 {
                let i = w * 64 + mixed.trailing_zeros() as usize;
                mixed &= mixed - 1;
                let case = two_bits(rows[0], i)
                    | two_bits(rows[1], i) << 2
                    | two_bits(rows[2], i) << 4
                    | two_bits(rows[3], i) << 6;
                f(i, j, case);
            }
        }
    }
}

/// Marching cubes over the cube layers `z0..z1`; `vals` holds the sample layers
/// `z0..=z1` (and possibly more), starting with layer `z0`. The slab's vertices and
/// triangles go to `store`; returns the ambiguous faces decided and the tunnels made.
///
/// Flying Edges' way of naming vertices: the crossed edges of each sample layer and
/// between two layers are numbered by counting sign changes, so a cube finds the vertex on
/// its edge by a population count, and every edge vertex is made once, in number order,
/// before the cubes that use it. Order in the slab: the bottom layer's x/y-edges, then per
/// layer of cubes the x/y-edges of the layer above (unless they are the next slab's), the
/// z-edges, and the vertices inside the cubes.
fn extract_slab<V: SlabVertex>(
    grid: &Grid,
    vals: &[f32],
    (z0, z1): (usize, usize),
    scratch: &mut Scratch,
    store: &mut SlabStore<'_, V>,
    control: &Control,
) -> Result<(u64, u64), Cancelled> {
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let last = z1 == nz - 1;
    let Scratch { below, above, lower, upper, z, .. } = scratch;
    let local = |k: usize| &vals[(k - z0) * layer..(k - z0 + 1) * layer];
    let offsets: [usize; 8] = CORNERS.map(|[x, y, z]| x + nx * y + layer * z);
    // Sign bits of the sample layers: a cube has the surface in it when its eight bits are
    // not all equal, which 64 cubes at a time reduce to a few word operations; only those
    // cubes are visited.
    let words = nx.div_ceil(64);
    layer_signs(local(z0), nx, words, below);
    lower.build(below, nx, ny, words);
    store.begin();
    lower.offset = store.made();
    lower.emit(grid, local(z0), z0, store);
    let (mut ambiguous_faces, mut tunnels) = (0, 0);
    for k in z0..z1 {
        if control.is_cancelled() {
            return Err(Cancelled);
        }
        layer_signs(local(k + 1), nx, words, above);
        upper.build(above, nx, ny, words);
        // The x- and y-edges on the slab's top layer belong to the slab above (except for
        // the last slab, which owns the volume's top): refer to them by number.
        if k + 1 == z1 && !last {
            upper.offset = BORROWED;
            store.borrow_top();
        } else {
            upper.offset = store.made();
            upper.emit(grid, local(k + 1), k + 1, store);
        }
        z.build(below, above, nx, words);
        z.offset = store.made();
        z.emit(grid, local(k), local(k + 1), k, store);
        let mut sink = SlabSink {
            store: &mut *store,
            lower: &*lower,
            upper: &*upper,
            z: &*z,
            grid,
            at: [0, 0, k],
            _vertex: std::marker::PhantomData,
        };
        // The samples of the layer after next, row by row with the rows of cubes: fetched
        // while the cubes are worked on, they are in the cache when the next layer's sign
        // pass reads them, instead of that pass waiting on memory.
        let ahead = (k + 2 <= z1).then(|| local(k + 2));
        let fetch = |j: usize| {
            if let Some(next) = ahead {
                let end = if j + 2 == ny { ny } else { j + 1 };
                prefetch(&next[j * nx..end * nx]);
            }
        };
        for_each_mixed_cube(below, above, nx, ny, fetch, |i, j, case| {
            let base = nx * j + layer * (k - z0) + i;
            let v: [f32; 8] = offsets.map(|o| vals[base + o]);
            sink.at = [i, j, k];
            let outcome = polygonize_case(case, &v, &mut sink);
            ambiguous_faces += outcome.ambiguous_faces as u64;
            tunnels += outcome.tunnel as u64;
        });
        std::mem::swap(below, above);
        std::mem::swap(lower, upper);
    }
    store.finish();
    Ok((ambiguous_faces, tunnels))
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

/// Where a slab's vertices and triangles go: the end of an [`Output`]. A vertex's number is
/// its index there; a triangle may name vertex `n` of the layer above, which the next slab
/// makes, as `BORROWED | n` until [`SlabStore::finish`] numbers it.
struct SlabStore<'a, V> {
    out: &'a mut Output<V>,
    /// The sizes of the thread's previous slab: neighbouring slabs of a smooth surface make
    /// about as many vertices and triangles.
    hint: (usize, usize),
    /// The first triangle that may refer to the layer above.
    borrowing: usize,
}

impl<'a, V: SlabVertex> SlabStore<'a, V> {
    fn new(out: &'a mut Output<V>, hint: (usize, usize)) -> Self {
        let borrowing = usize::MAX;
        SlabStore { out, hint, borrowing }
    }

    fn begin(&mut self) {
        make_room(&mut self.out.vertices, 2 * self.hint.0);
        make_room(&mut self.out.triangles, 2 * self.hint.1);
        debug_assert!(self.out.vertices.len() < BORROWED as usize);
    }

    /// The number of the next vertex.
    #[inline]
    fn made(&self) -> u32 {
        self.out.vertices.len() as u32
    }

    #[inline]
    fn push_vertex(&mut self, v: V) {
        self.out.vertices.push(v);
    }

    #[inline]
    fn push_triangle(&mut self, t: [u32; 3]) {
        self.out.triangles.push(t);
    }

    /// Triangles from now on may refer to the layer above.
    fn borrow_top(&mut self) {
        self.borrowing = self.out.triangles.len();
    }

    /// Ends the slab: the next slab's vertices will be numbered from here, its bottom
    /// layer's first, so `BORROWED | n` becomes the number `n` past the slab's last vertex.
    fn finish(&mut self) {
        let next = self.made();
        if let Some(ts) = self.out.triangles.get_mut(self.borrowing..) {
            for t in ts {
                *t = t.map(|i| if i & BORROWED == 0 { i } else { next + (i & !BORROWED) });
            }
        }
    }
}

/// The slab's side of [`CubeSink`]: a cube's edge vertices by their numbers.
struct SlabSink<'a, 's, V> {
    store: &'a mut SlabStore<'s, V>,
    /// The numbered edges of the sample layers below and above the cube, and between them.
    lower: &'a LayerNumbering,
    upper: &'a LayerNumbering,
    z: &'a ZNumbering,
    grid: &'a Grid,
    at: [usize; 3],
    _vertex: std::marker::PhantomData<V>,
}

impl<V: SlabVertex> CubeSink for SlabSink<'_, '_, V> {
    #[inline]
    fn edge_vertex(&mut self, e: usize, _: [f32; 2]) -> u32 {
        // Edge 4·a + u + 2·v runs along axis a at offsets u, v on the other two axes.
        let [i, j, _] = self.at;
        let (u, v) = (e & 1, (e >> 1) & 1);
        let side = if v == 0 { self.lower } else { self.upper };
        match e >> 2 {
            0 => side.id(0, i, j + u),
            1 => side.id(1, i + u, j),
            _ => self.z.id(i + u, j + v),
        }
    }

    fn cell_vertex(&mut self, offset: [f64; 3]) -> u32 {
        let [i, j, k] = self.at;
        let v = GridVertex { base: [i as u32, j as u32, k as u32], place: Place::Cell { offset } };
        let id = self.store.made();
        self.store.push_vertex(V::make(self.grid, v, [0.0; 2]));
        id
    }

    fn triangle(&mut self, t: [u32; 3]) {
        self.store.push_triangle(t);
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

    /// The vector sign words (AVX2 where the CPU has it, else SSE2) say `v < 0` exactly as
    /// the scalar form, for rows that end mid-word and for −0, NaN and infinities.
    #[test]
    fn sign_words_match_the_scalar_test() {
        let (nx, ny) = (141, 3);
        let mut values = noise(nx * ny, 3);
        for (i, v) in [-0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::MIN_POSITIVE]
            .into_iter()
            .enumerate()
        {
            values[17 * i + 5] = v;
        }
        let words = nx.div_ceil(64);
        let mut signs = vec![0; ny * words];
        layer_signs(&values, nx, words, &mut signs);
        for j in 0..ny {
            for w in 0..words {
                let row = &values[j * nx..(j + 1) * nx];
                let chunk = &row[64 * w..(64 * w + 64).min(nx)];
                assert_eq!(signs[j * words + w], signs_scalar(chunk), "row {j}, word {w}");
            }
        }
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

    /// Slabs of very different sizes (empty ones, then dense noise) finish out of order on
    /// several threads and are placed by whichever thread completes the chain; the mesh is
    /// the one thread's, bit for bit, also when the threads extract again.
    #[test]
    fn slabs_placed_out_of_order_make_the_one_thread_mesh() {
        let dims = [40, 30, 9 * SLAB + 3];
        let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
        let mut values = noise(dims.iter().product(), 5);
        let empty = dims[0] * dims[1] * 4 * SLAB;
        values[..empty].iter_mut().for_each(|v| *v = 1.0);
        let volume = Volume::from_values(grid, values);
        // Twice on each pool: the second run reuses the slab buffers its threads kept.
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let pool = pool.unwrap_or_else(|e| panic!("{e}"));
            let once = || extract(&volume, &Control::default()).unwrap_or_else(|_| unreachable!());
            pool.install(|| [once(), once()])
        };
        let [one, _] = run(1);
        assert!(one.triangles.len() > 10_000);
        for threads in [2, 4] {
            for (n, many) in run(threads).iter().enumerate() {
                let what = format!("run {n} on {threads} threads");
                assert!(many.vertices == one.vertices, "vertices differ, {what}");
                assert!(many.triangles == one.triangles, "triangles differ, {what}");
                assert_eq!(many.tunnels, one.tunnels);
            }
        }
    }

    /// A source that fails part way stops every thread and its error comes back.
    #[test]
    fn a_failing_source_stops_the_run() {
        struct Failing;
        impl LayerSource for Failing {
            type Error = usize;
            fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, usize> {
                if k >= 20 {
                    return Err(k);
                }
                out.iter_mut().enumerate().for_each(|(i, v)| *v = (i % 7) as f32 - 3.5);
                Ok(0)
            }
        }
        let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims: [9, 8, 6 * SLAB] };
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let pool = pool.unwrap_or_else(|e| panic!("{e}"));
            let run = pool
                .install(|| extract_streamed::<[f32; 3], _>(&Failing, &grid, &Control::default()));
            match run {
                Err(StreamError::Source(k)) => assert!(k >= 20, "layer {k} did not fail"),
                _ => panic!("the source's failure was not reported ({threads} threads)"),
            }
        }
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
