//! Marching cubes over a sampled [`Volume`], in parallel z-slabs joined in a fixed order.
//!
//! Vertices are named as in Flying Edges: the crossed edges of each sample layer, and those
//! between two layers, are numbered in a fixed order computed from the layers' sign bits
//! alone (`numbering`), so a cube finds the vertex on its edge by a
//! population count, with no map to look it up in, and each edge vertex is made once, in
//! number order. Each slab owns the edge vertices on its own sample layers (the last slab
//! also owns the top layer); the slab below refers to the layer it shares with the slab
//! above by those numbers, which land on the next slab's first vertices. The mesh is the
//! slabs in order (`slabs`), each placed as soon as the slabs below it are counted.
//! Slab boundaries depend only on the grid, never on the thread count, so the output is the
//! same bit for bit on any number of threads.
//!
//! The parts: `numbering` names the vertices, `signs` finds the cubes the surface passes
//! through from sign bits, `slabs` schedules the slabs over the threads and joins them, and
//! `streaming` feeds slabs from a [`LayerSource`] instead of a whole volume.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU64, Ordering};

use skelform_field::control::{Control, Progress};
use skelform_field::grid::{Grid, Level, Relative, Volume, VolumeView};

use super::cell::{CubeSink, polygonize_case};
use super::cube::CORNERS;

#[macro_use]
mod isa;
mod numbering;
mod signs;
mod slabs;
mod streaming;

pub use signs::surface_cubes;
pub use slabs::{VertexSink, Workspace};
pub use streaming::{
    LayerSource, StreamError, StreamStats, Streamed, extract_streamed, extract_streamed_with,
};

use numbering::{Counted, LayerNumbering, ZNumbering};
use signs::{Ahead, for_each_mixed_cube, layer_signs, prefetch, row_classes};
use slabs::{SlabStore, run_slabs, run_slabs_sunk};

/// Cube layers per slab. A constant, so that results never depend on the thread count.
pub const SLAB: usize = 8;

/// Marks a vertex number as one of the layer above, which the next slab makes (see
/// `SlabStore::finish`).
const BORROWED: u32 = 1 << 31;

/// Where a mesh vertex lies, relative to lattice point `base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridVertex {
    /// The lattice point the vertex is placed from.
    pub base: [u32; 3],
    /// On which segment or in which cell from `base`.
    pub place: Place,
}

/// Where from its lattice point a vertex lies: kept symbolically (not as a position) so
/// that refinement knows which segment to search and which samples bracket the root.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Place {
    /// On the lattice segment from `base` to `base + dir` (a bit mask: 1 = x, 2 = y, 4 = z;
    /// one bit for a cell edge, more for the face and body diagonals that tetrahedra use), at
    /// fraction `t`. Refinement moves `t` by root finding along the segment.
    Edge {
        /// The segment's direction, as a bit mask.
        dir: u8,
        /// The fraction along it.
        t: f64,
    },
    /// Inside the cell whose lowest corner is `base`, at `offset` (in cells): a fan centre
    /// or a tube's ring vertex (MC33's interior vertices), on the trilinear interpolant.
    /// Refinement moves it onto the field along the line its [`Slide`] gives (see
    /// [`GridVertex::slide`]), never out of the cell.
    Cell {
        /// The position in the cell, in cells from `base`.
        offset: [f64; 3],
        /// [`Slide::line`] in units of [`SLIDE_UNIT`] cells. Why so coarse: with it the
        /// variant is no larger than `offset` alone (the tag, `ray` and these six bytes share
        /// one word), so records of every vertex, mostly edge vertices, stay 48 bytes.
        line: [i16; 3],
        /// [`Slide::ray`].
        ray: bool,
    },
}

/// The unit (in cells) of a cell vertex's stored [`Slide::line`]: 2⁻¹⁴, so components up to
/// two cells fit an `i16`, to 3·10⁻⁵ cells.
pub const SLIDE_UNIT: f64 = 1.0 / 16384.0;

/// The line along which refinement moves an interior vertex onto the field.
///
/// Why a line, not Newton steps along the field's gradient: a tube's ring vertices lie a
/// fraction of a cell apart, and each gradient step, clamped to the cell, can carry several
/// of them onto the same corner, where they coincide and their triangles collapse (issue
/// 18). On the rays from the tube's centre (`grid::tube`) the ring's vertices keep their order
/// around it, stay apart and turn none of the tube's triangles over (seen from the centre,
/// which is what keeps the tube embedded), and the fan centre keeps to its fan's normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slide {
    /// The line's direction (in cells). For a ring vertex, the vector from the tube's centre
    /// to the vertex; for a fan centre, the interpolant's gradient; zero for a vertex that
    /// stays where the interpolant put it.
    pub line: [f64; 3],
    /// Whether the vertex stays on the ray from the centre, `offset − line` (a ring vertex:
    /// not past the centre, where the ring's vertices would meet), rather than moving either
    /// way along the line (a fan centre).
    pub ray: bool,
}

impl Place {
    /// A cell vertex at `offset` that refinement moves along `slide`.
    pub fn cell(offset: [f64; 3], slide: Slide) -> Place {
        let q = |x: f64| (x / SLIDE_UNIT).round().clamp(-32767.0, 32767.0) as i16;
        let line =
            if slide.line.iter().all(|x| x.is_finite()) { slide.line.map(q) } else { [0; 3] };
        Place::Cell { offset, line, ray: slide.ray }
    }
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
            Place::Edge { dir, t } => {
                // Spelled out: made for every vertex, and an array `map` can stay a call.
                let d = dir_vector(dir);
                [d[0] as f64 * t, d[1] as f64 * t, d[2] as f64 * t]
            }
            Place::Cell { offset, .. } => offset,
        };
        p0 + glam::DVec3::from_array(d) * grid.cell
    }

    /// A cell vertex's line of refinement (as stored, to [`SLIDE_UNIT`]); `None` for an edge
    /// vertex.
    pub fn slide(&self) -> Option<Slide> {
        match self.place {
            Place::Cell { line, ray, .. } => {
                Some(Slide { line: line.map(|x| x as f64 * SLIDE_UNIT), ray })
            }
            Place::Edge { .. } => None,
        }
    }
}

/// The raw output of extraction: triangles over edge vertices.
#[derive(Clone, Debug, Default)]
pub struct Extraction {
    /// The vertices, by lattice place (for refinement on the field).
    pub vertices: Vec<GridVertex>,
    /// The triangles, wound with their normals towards `f > 0`.
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
/// refinement on the field) or the interpolated position at once (extraction only), or
/// anything else computed from the samples around the vertex while they are in the cache.
pub trait SlabVertex: Copy + Default + Send + Sync + 'static {
    /// The record of vertex `v`; `ends` are the samples at the two ends of its lattice
    /// segment (zero for vertices inside a cell); `near` reads the samples around it.
    fn make<L: Level>(grid: &Grid, v: GridVertex, ends: [f32; 2], near: &Near<'_, L>) -> Self;

    /// Whether `make` reads the samples around the vertex (up to a lattice step past the
    /// cube's layers): the slab then fetches the layers it will read ahead of time.
    const READS_NEAR: bool = false;

    /// Whether the triangles over these records are wound the other way round (normals
    /// towards `f < 0`): a caller whose convention is that winding (scikit-image's in its
    /// axis order) takes the triangles as they are made, without a pass to rewind them.
    const REWOUND: bool = false;
}

/// The samples a slab can read while it makes a vertex: the whole volume for an extraction
/// over a held volume, the slab's own sample layers for a streamed one.
#[derive(Clone, Copy)]
pub struct Near<'a, L> {
    values: &'a [f32],
    /// The first layer `values` holds, and how many.
    first: usize,
    layers: usize,
    dims: [usize; 3],
    level: L,
}

impl<L: Level> Near<'_, L> {
    /// The sample (relative to the level) at lattice point `(i, j, k)`, which must be in
    /// the grid; `k` is clamped to the layers there are (in a streamed slab, the slab's own:
    /// a record that reads past them sees the slab's first or last layer again).
    #[inline(always)]
    pub fn sample(&self, i: usize, j: usize, k: usize) -> f32 {
        let [nx, ny, _] = self.dims;
        let k = k.clamp(self.first, self.first + self.layers - 1) - self.first;
        self.level.sample(self.values[i + nx * (j + ny * k)])
    }

    /// Samples along x, y, z of the whole lattice.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The whole lattice's raw values (`i + nx·(j + ny·k)`, read through the level) and
    /// the level, when `near` holds every layer (an extraction over a held volume, not a
    /// streamed slab): a record that reads many samples around its vertex can then index
    /// them itself, without [`Near::sample`]'s clamp of `k` on every read.
    #[inline]
    pub fn whole(&self) -> Option<(&[f32], L)> {
        (self.first == 0 && self.layers == self.dims[2]).then_some((self.values, self.level))
    }

    /// Asks the CPU to bring sample layer `k` into its cache, if it is there to read.
    fn prefetch_layer(&self, k: usize) {
        if let Some(layer) = self.layer(k) {
            prefetch(layer);
        }
    }

    /// The raw values of sample layer `k`, if `near` holds it.
    #[inline]
    fn layer(&self, k: usize) -> Option<&[f32]> {
        let size = self.dims[0] * self.dims[1];
        let held = (self.first..self.first + self.layers).contains(&k);
        held.then(|| &self.values[(k - self.first) * size..][..size])
    }
}

impl SlabVertex for GridVertex {
    #[inline]
    fn make<L: Level>(_: &Grid, v: GridVertex, _: [f32; 2], _: &Near<'_, L>) -> Self {
        v
    }
}

impl SlabVertex for [f32; 3] {
    #[inline]
    fn make<L: Level>(grid: &Grid, v: GridVertex, _: [f32; 2], _: &Near<'_, L>) -> Self {
        v.position(grid).as_vec3().to_array()
    }
}

/// A vertex with the samples at its segment's ends: what refinement needs when the volume
/// itself is not kept (streamed extraction).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampledVertex {
    /// Where the vertex lies.
    pub vertex: GridVertex,
    /// The samples at its segment's two ends (zero for a vertex inside a cell): the
    /// bracket refinement starts from, without the volume.
    pub ends: [f32; 2],
}

impl std::borrow::Borrow<GridVertex> for SampledVertex {
    fn borrow(&self) -> &GridVertex {
        &self.vertex
    }
}

impl SlabVertex for SampledVertex {
    #[inline]
    fn make<L: Level>(_: &Grid, vertex: GridVertex, ends: [f32; 2], _: &Near<'_, L>) -> Self {
        SampledVertex { vertex, ends }
    }
}

impl Default for GridVertex {
    fn default() -> Self {
        GridVertex {
            base: [0; 3],
            place: Place::Cell { offset: [0.0; 3], line: [0; 3], ray: false },
        }
    }
}

/// A thread's working memory, reused for every slab it runs: the sign words and edge
/// numberings of the layers it works on, and the sample layers of a streamed slab.
struct Scratch {
    /// Sign words of the sample layers below and above the current layer of cubes.
    below: Vec<u64>,
    above: Vec<u64>,
    /// The classes of those layers' rows (all outside, all inside, mixed).
    below_classes: Vec<u8>,
    above_classes: Vec<u8>,
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
            below_classes: Vec::with_capacity(ny),
            above_classes: Vec::with_capacity(ny),
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
    extract_with(volume, control, Workspace::shared())
}

/// [`extract`] with the slab buffers of `workspace`.
pub fn extract_with(
    volume: &Volume,
    control: &Control,
    workspace: &Workspace,
) -> Result<Extraction, Cancelled> {
    let (vertices, triangles, ambiguous_faces, tunnels) = extract_as::<GridVertex, _>(
        &volume.grid,
        &volume.values,
        Relative,
        control,
        workspace,
        Default::default(),
    )?;
    Ok(Extraction { vertices, triangles, ambiguous_faces, tunnels })
}

/// Runs marching cubes over the whole volume and returns the vertices' interpolated
/// positions (no refinement), without the intermediate [`GridVertex`] records.
pub fn extract_positions(volume: &Volume, control: &Control) -> Result<Positions, Cancelled> {
    extract_volume_records::<[f32; 3]>(volume, control)
}

/// Marching cubes over a held volume with the vertex records of the caller's choice (which
/// may read the samples around each vertex: [`Near`]).
pub fn extract_volume_records<V: SlabVertex>(
    volume: &Volume,
    control: &Control,
) -> Result<(Vec<V>, Vec<[u32; 3]>), Cancelled> {
    extract_volume_records_into(volume, control, Default::default())
}

/// [`extract_volume_records`] that writes the vertices and triangles into `reuse`, as
/// [`extract_view_records_into`] does.
pub fn extract_volume_records_into<V: SlabVertex>(
    volume: &Volume,
    control: &Control,
    reuse: (Vec<V>, Vec<[u32; 3]>),
) -> Result<(Vec<V>, Vec<[u32; 3]>), Cancelled> {
    let (vertices, triangles, _, _) = extract_as::<V, _>(
        &volume.grid,
        &volume.values,
        Relative,
        control,
        Workspace::shared(),
        reuse,
    )?;
    Ok((vertices, triangles))
}

/// [`extract_volume_records`] on raw values read in place at a level.
pub fn extract_view_records<V: SlabVertex>(
    view: &VolumeView<'_>,
    control: &Control,
) -> Result<(Vec<V>, Vec<[u32; 3]>), Cancelled> {
    extract_view_records_into(view, control, Default::default())
}

/// [`extract_view_records`] that writes the vertices and triangles into `reuse` (emptied
/// first): a caller that extracts again and again passes back the arrays of its last call,
/// whose memory is then written without a page fault a page, on one thread as the slabs are
/// made, on more as they are placed. (The mesh does not depend on `reuse`.)
pub fn extract_view_records_into<V: SlabVertex>(
    view: &VolumeView<'_>,
    control: &Control,
    reuse: (Vec<V>, Vec<[u32; 3]>),
) -> Result<(Vec<V>, Vec<[u32; 3]>), Cancelled> {
    let (grid, values, workspace) = (&view.grid, view.values, Workspace::shared());
    // At level +0 the samples are the raw values sanitised: the same, read with less work.
    let (vertices, triangles, _, _) = match view.level.at_zero() {
        Some(zero) => extract_as::<V, _>(grid, values, zero, control, workspace, reuse)?,
        None => extract_as::<V, _>(grid, values, view.level, control, workspace, reuse)?,
    };
    Ok((vertices, triangles))
}

/// [`extract_view_records_into`] with the vertex records handed to `sink` slab by slab (see
/// [`VertexSink`]) rather than kept: returns the vertex count and the triangles, written
/// into `reuse` (emptied first). The records and triangles are those of
/// [`extract_view_records_into`], bit for bit and in the same order, on any number of
/// threads.
pub fn extract_view_sunk<V: SlabVertex>(
    view: &VolumeView<'_>,
    control: &Control,
    sink: &impl VertexSink<V>,
    reuse: Vec<[u32; 3]>,
) -> Result<(usize, Vec<[u32; 3]>), Cancelled> {
    let (grid, values) = (&view.grid, view.values);
    match view.level.at_zero() {
        Some(zero) => extract_sunk(grid, values, zero, control, sink, reuse),
        None => extract_sunk(grid, values, view.level, control, sink, reuse),
    }
}

/// [`extract_view_sunk`] over a held volume.
pub fn extract_volume_sunk<V: SlabVertex>(
    volume: &Volume,
    control: &Control,
    sink: &impl VertexSink<V>,
    reuse: Vec<[u32; 3]>,
) -> Result<(usize, Vec<[u32; 3]>), Cancelled> {
    extract_sunk(&volume.grid, &volume.values, Relative, control, sink, reuse)
}

/// The slabs of the whole lattice, their vertices handed to `sink` (see
/// [`extract_view_sunk`]).
fn extract_sunk<V: SlabVertex, L: Level>(
    grid: &Grid,
    values: &[f32],
    level: L,
    control: &Control,
    sink: &impl VertexSink<V>,
    reuse: Vec<[u32; 3]>,
) -> Result<(usize, Vec<[u32; 3]>), Cancelled> {
    let grid = *grid;
    let slabs = slab_count(&grid);
    if slabs == 0 {
        return Ok((0, Vec::new()));
    }
    let [nx, ny, _] = grid.dims;
    let cube_layers = grid.dims[2] - 1;
    let done = AtomicU64::new(0);
    let workspace = Workspace::shared();
    let (vertices, triangles, _) =
        run_slabs_sunk(slabs, [nx, ny], workspace, sink, reuse, |s, scratch, store| {
            let z0 = s * SLAB;
            let z1 = (z0 + SLAB).min(cube_layers);
            let near = Near { values, first: 0, layers: grid.dims[2], dims: grid.dims, level };
            extract_slab(&grid, &near, (z0, z1), scratch, store, control)?;
            slab_done(control, &done, z1 - z0, cube_layers, "extracting")
        })?;
    Ok((vertices, triangles))
}

/// [`extract_positions`] on raw values read in place at a level: the mesh is the one of the
/// [`Volume`] that converting them would make (bit for bit), without the copy.
pub fn extract_view_positions(
    view: &VolumeView<'_>,
    control: &Control,
) -> Result<Positions, Cancelled> {
    extract_view_records::<[f32; 3]>(view, control)
}

type Extracted<V> = (Vec<V>, Vec<[u32; 3]>, u64, u64);

/// Interpolated vertex positions and triangles.
pub type Positions = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// Whether a lattice has a cube: a [`Grid`] built by hand may have fewer than 2 samples
/// along an axis, and then there is nothing to extract.
pub(crate) fn has_cells(grid: &Grid) -> bool {
    grid.dims.iter().all(|&d| d >= 2)
}

/// Extraction over `values` (`grid.index` order, raw values read through `level`); one
/// thread writes the vertices and triangles into `reuse` (see
/// [`extract_view_records_into`]).
fn extract_as<V: SlabVertex, L: Level>(
    grid: &Grid,
    values: &[f32],
    level: L,
    control: &Control,
    workspace: &Workspace,
    reuse: (Vec<V>, Vec<[u32; 3]>),
) -> Result<Extracted<V>, Cancelled> {
    let slabs = slab_count(grid);
    let (vertices, triangles, counts) =
        extract_slabs(grid, values, level, control, workspace, 0..slabs, reuse)?;
    let (ambiguous_faces, tunnels) =
        counts.iter().fold((0, 0), |(a, t), c| (a + c.ambiguous_faces, t + c.tunnels));
    Ok((vertices, triangles, ambiguous_faces, tunnels))
}

/// How many slabs extraction cuts `grid`'s cube layers into.
pub(crate) fn slab_count(grid: &Grid) -> usize {
    if has_cells(grid) { (grid.dims[2] - 1).div_ceil(SLAB) } else { 0 }
}

/// The vertices and triangles of some slabs, and what each of them made.
pub(crate) type SlabsExtracted<V> = (Vec<V>, Vec<[u32; 3]>, Vec<SlabCounts>);

/// What one slab made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct SlabCounts {
    pub vertices: usize,
    pub triangles: usize,
    pub ambiguous_faces: u64,
    pub tunnels: u64,
}

/// Marching cubes over the slabs `range` alone: their vertices and triangles as a whole
/// extraction would make them, numbered from the range's first vertex (the last slab's
/// references to the layer above land just past the range's own vertices, on the next
/// slab's first ones), and what each slab made. Slab `s` reads the sample layers
/// `s·SLAB ..= (s + 1)·SLAB` only, which is what lets incremental re-meshing splice the
/// slabs an edit touched into the last extraction. On one thread the vertices are written
/// and triangles into `reuse` (emptied first; see [`extract_view_records_into`]).
pub(crate) fn extract_slabs<V: SlabVertex, L: Level>(
    grid: &Grid,
    values: &[f32],
    level: L,
    control: &Control,
    workspace: &Workspace,
    range: std::ops::Range<usize>,
    reuse: (Vec<V>, Vec<[u32; 3]>),
) -> Result<SlabsExtracted<V>, Cancelled> {
    let grid = *grid;
    if !has_cells(&grid) || range.is_empty() {
        return Ok((Vec::new(), Vec::new(), Vec::new()));
    }
    let [nx, ny, _] = grid.dims;
    let cube_layers = grid.dims[2] - 1;
    let done = AtomicU64::new(0);
    let first = range.start;
    let (vertices, triangles, counts) =
        run_slabs(range.len(), [nx, ny], workspace, reuse, |s, scratch, store| {
            let s = s + first;
            let z0 = s * SLAB;
            let z1 = (z0 + SLAB).min(cube_layers);
            let near = Near { values, first: 0, layers: grid.dims[2], dims: grid.dims, level };
            let start = store.lens();
            let (ambiguous_faces, tunnels) =
                extract_slab(&grid, &near, (z0, z1), scratch, store, control)?;
            let end = store.lens();
            let counts = SlabCounts {
                vertices: end[0] - start[0],
                triangles: end[1] - start[1],
                ambiguous_faces,
                tunnels,
            };
            slab_done(control, &done, z1 - z0, cube_layers, "extracting").map(|()| counts)
        })?;
    Ok((vertices, triangles, counts))
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

compiled_twice! {
    /// Marching cubes over the cube layers `z0..z1`; `near` holds the sample layers `z0..=z1`
    /// (and possibly more), as raw values that its level reads (for the inside test by its
    /// threshold, for everything else as samples). The slab's vertices and
    /// triangles go to `store`; returns the ambiguous faces decided and the tunnels made.
    ///
    /// Flying Edges' way of naming vertices: the crossed edges of each sample layer and
    /// between two layers are numbered by counting sign changes, so a cube finds the vertex on
    /// its edge by a population count, and every edge vertex is made once, in number order,
    /// before the cubes that use it. Order in the slab: the bottom layer's x/y-edges, then per
    /// layer of cubes the x/y-edges of the layer above (unless they are the next slab's), the
    /// z-edges, and the vertices inside the cubes.
    ///
    /// The kernel is compiled twice, for the x86-64 baseline the build targets and for the
    /// instructions of x86-64-v3 (AVX2, BMI1/2, LZCNT, FMA, MOVBE: every x86-64 CPU since 2015),
    /// and the second runs where the CPU has them (see `isa`).
    fn extract_slab<V: SlabVertex, L: Level>(
        grid: &Grid,
        near: &Near<'_, L>,
        span: (usize, usize),
        scratch: &mut Scratch,
        store: &mut SlabStore<'_, V>,
        control: &Control,
    ) -> Result<(u64, u64), Cancelled> => extract_slab_v3, slab_kernel
}

/// [`extract_slab`]'s work, inlined into each of its compiled copies. What it calls in
/// the loop over cubes is always inlined too (the numberings' `build`, the case's
/// polygons, the closures below): a call left out of line would run the baseline's code
/// in the faster copy. The numberings' `emit`, which make the vertex records, have copies
/// of their own.
#[inline(always)]
fn slab_kernel<V: SlabVertex, L: Level>(
    grid: &Grid,
    near: &Near<'_, L>,
    (z0, z1): (usize, usize),
    scratch: &mut Scratch,
    store: &mut SlabStore<'_, V>,
    control: &Control,
) -> Result<(u64, u64), Cancelled> {
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let last = z1 == nz - 1;
    let Scratch { below, above, below_classes, above_classes, lower, upper, z, .. } = scratch;
    let level = near.level;
    let vals = &near.values[(z0 - near.first) * layer..];
    let local = |k: usize| &vals[(k - z0) * layer..(k - z0 + 1) * layer];
    let offsets: [usize; 8] = CORNERS.map(|[x, y, z]| x + nx * y + layer * z);
    // Sign bits of the sample layers: a cube has the surface in it when its eight bits are
    // not all equal, which 64 cubes at a time reduce to a few word operations; only those
    // cubes are visited.
    let words = nx.div_ceil(64);
    let threshold = level.threshold();
    layer_signs(local(z0), nx, words, below, threshold, None);
    row_classes(below, nx, words, below_classes);
    lower.build(below, below_classes, nx, ny, words);
    store.begin();
    if V::READS_NEAR {
        // The records of the first layer of cubes read the layers from z0 − 1 to z0 + 2;
        // the cubes of each layer fetch, row by row, the layer the records of the next one
        // reach (below). On one thread the slab below fetched these already, and a fetch
        // of what is in the cache costs next to nothing.
        near.prefetch_layer(z0.wrapping_sub(1));
        near.prefetch_layer(z0 + 1);
        near.prefetch_layer(z0 + 2);
    }
    lower.offset = store.made();
    lower.emit(grid, local(z0), near, z0, store);
    let (mut ambiguous_faces, mut tunnels) = (0, 0);
    for k in z0..z1 {
        if control.is_cancelled() {
            return Err(Cancelled);
        }
        // The layer whose rows the work on this layer of cubes fetches into the cache, ahead
        // of its use: the layer after next, which the next layer's sign pass reads (else
        // it would wait on memory), or, for records that read the samples around their
        // vertex, the one after that, which the records of the next layer reach (the
        // layer before it was fetched by this loop's predecessor). Row by row as the work
        // goes, rather than all at once, which would stall the core on a few thousand
        // outstanding fetches: with the cubes of rows that have some (below), with the
        // sign pass of rows without (a row of cubes where the layer below has two uniform
        // sample rows alike is passed over unless the layer above differs; such rows,
        // thousands around a compact shape, took the cube loop microseconds, so that
        // their fetches went out in one burst).
        let far =
            if V::READS_NEAR { near.layer(k + 3) } else { (k + 2 <= z1).then(|| local(k + 2)) };
        let ahead = far.map(|values| Ahead { values, passed: below_classes });
        layer_signs(local(k + 1), nx, words, above, threshold, ahead);
        row_classes(above, nx, words, above_classes);
        upper.build(above, above_classes, nx, ny, words);
        // The x- and y-edges on the slab's top layer belong to the slab above (except for
        // the last slab, which owns the volume's top): refer to them by number.
        if k + 1 == z1 && !last {
            upper.offset = BORROWED;
            store.borrow_top();
        } else {
            upper.offset = store.made();
            upper.emit(grid, local(k + 1), near, k + 1, store);
        }
        z.build((below, below_classes), (above, above_classes), nx, words);
        z.offset = store.made();
        z.emit(grid, local(k), local(k + 1), near, k, store);
        let mut sink = SlabSink {
            store: &mut *store,
            segments: [&lower.x, &upper.x, &lower.y, &upper.y, &z.edges],
            offsets: [lower.offset, upper.offset, lower.offset, upper.offset, z.offset],
            words: z.words,
            row: None,
            rows: [&[]; 8],
            row_offsets: [0; 8],
            grid,
            near,
            at: [0, 0, k],
            _vertex: std::marker::PhantomData,
        };
        let layers = ((&below[..], &below_classes[..]), (&above[..], &above_classes[..]));
        for_each_mixed_cube(
            layers.0,
            layers.1,
            nx,
            ny,
            #[inline(always)]
            |j: usize| {
                // (The last row of cubes fetches the last sample row too.)
                let end = if j + 2 == ny { ny } else { j + 1 };
                if let Some(far) = far {
                    prefetch(&far[j * nx..end * nx]);
                }
            },
            #[inline(always)]
            |i, j, case| {
                let base = nx * j + layer * (k - z0) + i;
                // One bounds check for the cube's eight samples rather than one each.
                let cube = &vals[base..=base + offsets[7]];
                // Spelled out: an array `map` stays a call here, in the loop over every cube.
                // SAFETY: each corner's offset is a sum of some of 1, nx and nx·ny (its
                // coordinates are 0 or 1), the far corner's of all three: at most `offsets[7]`,
                // within `cube`.
                let at = |c: usize| level.sample(unsafe { *cube.get_unchecked(offsets[c]) });
                let v: [f32; 8] = [at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7)];
                sink.enter_row(j);
                sink.at = [i, j, k];
                let outcome = polygonize_case(case, &v, &mut sink);
                ambiguous_faces += outcome.ambiguous_faces as u64;
                tunnels += outcome.tunnel as u64;
            },
        );
        std::mem::swap(below, above);
        std::mem::swap(below_classes, above_classes);
        std::mem::swap(lower, upper);
    }
    store.finish();
    Ok((ambiguous_faces, tunnels))
}

/// The slab's side of [`CubeSink`]: a cube's edge vertices by their numbers.
struct SlabSink<'a, 's, V, L> {
    store: &'a mut SlabStore<'s, V>,
    /// The numbered edges a cube's edges lie in, by segment: the x-edges of
    /// the sample layers below and above the cube, their y-edges, the z-edges between them.
    segments: [&'a [Counted]; 5],
    /// The output number of each segment's first vertex (`BORROWED` for a layer the next
    /// slab makes).
    offsets: [u32; 5],
    /// Sign words per row (the same in every segment).
    words: usize,
    /// The row of cubes `rows` are for, if any yet.
    row: Option<usize>,
    /// The words of the numbered rows a cube of that row finds its edges in, by
    /// [`EDGE_SLOTS`]' slot, and the output number of each one's segment's first vertex:
    /// set once a row, so that a cube's edge costs a table entry, a word and a count.
    rows: [&'a [Counted]; 8],
    row_offsets: [u32; 8],
    grid: &'a Grid,
    near: &'a Near<'a, L>,
    at: [usize; 3],
    _vertex: std::marker::PhantomData<V>,
}

/// Where cube edge `e` (`4·a + u + 2·v`: along axis `a` at offsets `u`, `v` on the other
/// two) lies among a [`SlabSink`]'s numbered rows for the cube's row `j` (its `rows`): the
/// slot, and the offset from the cube's corner along x of the lattice edge in that row. In
/// one table so that finding an edge's number takes no branch on the edge (which cubes
/// visit in an order the surface decides, so that a branch on it is hard to predict). The
/// slots: 0 to 3 the x-edges of rows `j` and `j + 1` of the sample layer below the cube,
/// then of the layer above; 4 and 5 the y-edges from row `j` of the layer below and above;
/// 6 and 7 the z-edges from rows `j` and `j + 1`.
const EDGE_SLOTS: [(u8, u8); 16] = {
    let mut t = [(0, 0); 16];
    let mut e = 0;
    while e < 12 {
        let (u, v) = ((e & 1) as u8, ((e >> 1) & 1) as u8);
        t[e] = match e >> 2 {
            // An x-edge of the lower (v = 0) or upper layer, in row j + u.
            0 => (2 * v + u, 0),
            // A y-edge of the lower or upper layer, from sample i + u.
            1 => (4 + v, u),
            // A z-edge from sample (i + u, j + v).
            _ => (6 + v, u),
        };
        e += 1;
    }
    t
};

impl<'a, V: SlabVertex, L: Level> SlabSink<'a, '_, V, L> {
    /// Points `rows` at the numbered rows the cubes of row `j` find their edges in, unless
    /// they are there already (cubes come row by row).
    #[inline(always)]
    fn enter_row(&mut self, j: usize) {
        if self.row == Some(j) {
            return;
        }
        self.row = Some(j);
        let words = self.words;
        // (segment, row) of each slot: segments are the lower and upper layers' x-edges,
        // their y-edges, and the z-edges.
        const SLOTS: [(usize, usize); 8] =
            [(0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (3, 0), (4, 0), (4, 1)];
        for (slot, &(segment, dj)) in SLOTS.iter().enumerate() {
            let at = (j + dj) * words;
            self.rows[slot] = &self.segments[segment][at..at + words];
            self.row_offsets[slot] = self.offsets[segment];
        }
    }
}

impl<V: SlabVertex, L: Level> CubeSink for SlabSink<'_, '_, V, L> {
    #[inline]
    fn edge_vertex(&mut self, e: usize, _: [f32; 2]) -> u32 {
        debug_assert_eq!(self.row, Some(self.at[1]));
        let (slot, di) = EDGE_SLOTS[e & 15];
        let (slot, i) = (usize::from(slot) & 7, self.at[0] + usize::from(di));
        let row = self.rows[slot];
        debug_assert!(i / 64 < row.len());
        // SAFETY: `i` is at most the cube's `i + 1 <= nx − 1` (cubes are `i < nx − 1`), so
        // its word `i / 64` is below the row's `words = ceil(nx / 64)`, the length of every
        // row `enter_row` sets.
        self.row_offsets[slot] + unsafe { row.get_unchecked(i / 64) }.number(i)
    }

    fn cell_vertex(&mut self, offset: [f64; 3], slide: Slide) -> u32 {
        let [i, j, k] = self.at;
        let v =
            GridVertex { base: [i as u32, j as u32, k as u32], place: Place::cell(offset, slide) };
        let id = self.store.made();
        self.store.push_vertex(V::make(self.grid, v, [0.0; 2], self.near));
        id
    }

    #[inline]
    fn triangle(&mut self, t: [u32; 3]) {
        let t = if V::REWOUND { [t[0], t[2], t[1]] } else { t };
        self.store.push_triangle(t);
    }

    #[inline]
    fn triangles(&mut self, tris: &[[u8; 3]], local: &[u32; 16]) {
        // (Spelled out, not `map`ped: an array `map` can stay a call, and this runs for
        // every triangle.)
        let at = |e: u8| local[usize::from(e) & 15];
        self.store.push_triangles(tris.iter().map(|&[a, b, c]| {
            if V::REWOUND { [at(a), at(c), at(b)] } else { [at(a), at(b), at(c)] }
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::signs::signs_scalar;
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

    /// A cell vertex's line of refinement takes no room of its own: a vertex record is as
    /// large as before it had one, and the line comes back to its unit.
    #[test]
    fn cell_vertices_keep_their_line_in_the_record() {
        assert_eq!(std::mem::size_of::<GridVertex>(), 48);
        let slide = Slide { line: [0.25, -0.7, 1e-3], ray: true };
        let v = GridVertex { base: [1, 2, 3], place: Place::cell([0.5; 3], slide) };
        let back = v.slide().expect("a cell vertex");
        assert!(back.ray);
        for (a, b) in back.line.iter().zip(slide.line) {
            assert!((a - b).abs() <= 0.5 * SLIDE_UNIT, "{a} {b}");
        }
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
        layer_signs(&values, nx, words, &mut signs, 0.0, None);
        for j in 0..ny {
            for w in 0..words {
                let row = &values[j * nx..(j + 1) * nx];
                let chunk = &row[64 * w..(64 * w + 64).min(nx)];
                assert_eq!(signs[j * words + w], signs_scalar(chunk, 0.0), "row {j}, word {w}");
            }
        }
    }

    /// A layer of `ny` rows of `nx` samples whose rows are, by `pattern` (cycled): `b'o'` all
    /// outside, `b'i'` all inside, `b'n'` noise (both signs, some exact zeros).
    fn patterned(nx: usize, ny: usize, pattern: &[u8], seed: u64) -> Vec<f32> {
        let mut values = noise(nx * ny, seed);
        for (j, row) in values.chunks_mut(nx).enumerate() {
            match pattern[j % pattern.len()] {
                b'o' => row.iter_mut().for_each(|v| *v = 0.5),
                b'i' => row.iter_mut().for_each(|v| *v = -0.5),
                _ => {}
            }
        }
        values
    }

    /// Sign words and row classes of a layer.
    fn signs_of(values: &[f32], nx: usize) -> (Vec<u64>, Vec<u8>) {
        let words = nx.div_ceil(64);
        let mut signs = vec![0; values.len() / nx * words];
        layer_signs(values, nx, words, &mut signs, 0.0, None);
        let mut classes = Vec::new();
        row_classes(&signs, nx, words, &mut classes);
        (signs, classes)
    }

    /// Rows of every kind next to every kind, for rows that end mid-word and rows of whole
    /// words (where the "all inside" test must not look past the row).
    const PATTERNS: [&[u8]; 2] = [b"ooiinoinnniioion", b"ionnoooiii"];

    /// The numbers of a layer's crossed x- and y-edges are their ranks in row order, and the
    /// emit order visits exactly the crossed edges in that order, also when the numbering
    /// held an earlier layer's edges (rows with no crossed edge are passed over, their
    /// words left stale) and rows are all inside or all outside.
    #[test]
    fn layer_numbers_are_the_crossed_edges_in_row_order() {
        let ny = 19;
        for nx in [70usize, 128, 3] {
            for (p, pattern) in PATTERNS.iter().enumerate() {
                let words = nx.div_ceil(64);
                let mut numbers = LayerNumbering::default();
                // First a layer of noise everywhere, whose words the next build leaves
                // where its rows have no crossed edge.
                let (stale, stale_classes) = signs_of(&noise(nx * ny, 11), nx);
                numbers.build(&stale, &stale_classes, nx, ny, words);
                let values = patterned(nx, ny, pattern, 7 + p as u64);
                let (signs, classes) = signs_of(&values, nx);
                numbers.build(&signs, &classes, nx, ny, words);
                let inside = |i: usize, j: usize| values[i + nx * j] < 0.0;
                let mut expected = Vec::new();
                assert_eq!(classes.len(), ny);
                for (j, &got) in classes.iter().enumerate() {
                    let all: Vec<bool> = (0..nx).map(|i| inside(i, j)).collect();
                    let class = if all.iter().all(|&b| b) {
                        signs::ROW_IN
                    } else if all.iter().any(|&b| b) {
                        signs::ROW_MIXED
                    } else {
                        signs::ROW_OUT
                    };
                    assert_eq!(got, class, "class of row {j}, nx {nx}");
                    for i in 0..nx - 1 {
                        if inside(i, j) != inside(i + 1, j) {
                            expected.push((0, i, j));
                        }
                    }
                    if j + 1 < ny {
                        for i in 0..nx {
                            if inside(i, j) != inside(i, j + 1) {
                                expected.push((1, i, j));
                            }
                        }
                    }
                }
                let mut visited = Vec::new();
                numbers.for_each_edge(
                    ny,
                    &mut visited,
                    |v, i, j| v.push((0, i, j)),
                    |v, i, j| v.push((1, i, j)),
                );
                assert_eq!(visited, expected, "nx {nx}, pattern {p}");
                for (n, &(axis, i, j)) in expected.iter().enumerate() {
                    assert_eq!(numbers.number(axis, i, j), n as u32, "edge {axis} ({i}, {j})");
                }
                assert_eq!(numbers.total as usize, expected.len());
            }
        }
    }

    /// The z-edges between two layers with rows all inside or all outside in one or both:
    /// numbered and visited in row order, over stale words of an earlier pair of layers.
    #[test]
    fn z_numbers_are_the_crossed_edges_in_row_order() {
        let ny = 23;
        for nx in [70usize, 128] {
            let words = nx.div_ceil(64);
            let mut numbers = ZNumbering::default();
            let (a, ac) = signs_of(&noise(nx * ny, 1), nx);
            let (b, bc) = signs_of(&noise(nx * ny, 2), nx);
            numbers.build((&a, &ac), (&b, &bc), nx, words);
            let lower = patterned(nx, ny, PATTERNS[0], 3);
            let upper = patterned(nx, ny, PATTERNS[1], 4);
            let ((a, ac), (b, bc)) = (signs_of(&lower, nx), signs_of(&upper, nx));
            numbers.build((&a, &ac), (&b, &bc), nx, words);
            let mut expected = Vec::new();
            for j in 0..ny {
                for i in 0..nx {
                    if (lower[i + nx * j] < 0.0) != (upper[i + nx * j] < 0.0) {
                        expected.push((i, j));
                    }
                }
            }
            let mut visited = Vec::new();
            numbers.for_each_edge(|i, j| visited.push((i, j)));
            assert_eq!(visited, expected, "nx {nx}");
            for (n, &(i, j)) in expected.iter().enumerate() {
                assert_eq!(numbers.number(i, j), n as u32, "z-edge ({i}, {j})");
            }
        }
    }

    /// The cube loop visits exactly the cubes with corners of both signs, in row order,
    /// with their corner cases, when whole rows are all inside or all outside.
    #[test]
    fn mixed_cubes_are_found_past_uniform_rows() {
        let ny = 21;
        for nx in [70usize, 128, 2] {
            let lower = patterned(nx, ny, PATTERNS[0], 5);
            let upper = patterned(nx, ny, PATTERNS[1], 6);
            let (below, upper_layer) = (signs_of(&lower, nx), signs_of(&upper, nx));
            let mut visited = Vec::new();
            let below_layer = (&below.0[..], &below.1[..]);
            let above_layer = (&upper_layer.0[..], &upper_layer.1[..]);
            signs::for_each_mixed_cube(
                below_layer,
                above_layer,
                nx,
                ny,
                |_| {},
                |i, j, case| visited.push((i, j, case)),
            );
            let inside = |i: usize, j: usize, z: usize| {
                (if z == 0 { &lower } else { &upper })[i + nx * j] < 0.0
            };
            let mut expected = Vec::new();
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let case = (0..8usize).fold(0usize, |c, b| {
                        c | (inside(i + (b & 1), j + (b >> 1 & 1), b >> 2) as usize) << b
                    });
                    if case != 0 && case != 255 {
                        expected.push((i, j, case));
                    }
                }
            }
            assert!(!expected.is_empty());
            assert_eq!(visited, expected, "nx {nx}");
        }
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

    /// Raw values read in place at a level make the mesh of the volume their conversion
    /// would be, bit for bit: with NaN and ±∞ among them, at levels between values, on a
    /// value, off `f32`'s grid, and on several threads.
    #[test]
    fn a_view_at_a_level_makes_the_converted_volume_mesh() {
        use skelform_field::grid::{Level, Shifted, VolumeView};
        let dims = [45, 23, 3 * SLAB + 2];
        let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
        let mut raw: Vec<f32> =
            noise(dims.iter().product(), 13).iter().map(|v| 3.0 * v + 2.0).collect();
        for (n, v) in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 2.0, 2.0].into_iter().enumerate()
        {
            for i in (n * 97..raw.len()).step_by(1013) {
                raw[i] = v;
            }
        }
        for level in [2.0, 1.7, 2.0 + 1e-9, -0.5, f64::NAN] {
            let converted: Vec<f32> = raw.iter().map(|&x| (f64::from(x) - level) as f32).collect();
            let volume = Volume::from_values(grid, converted);
            assert!(
                volume.values.iter().zip(&raw).all(|(v, &x)| *v == Shifted::new(level).sample(x))
            );
            let view = VolumeView::new(grid, &raw, level).unwrap_or_else(|| unreachable!());
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
                let pool = pool.unwrap_or_else(|e| panic!("{e}"));
                let (a, b) = pool.install(|| {
                    let control = Control::default();
                    let a = extract_positions(&volume, &control).unwrap_or_else(|_| unreachable!());
                    let b =
                        extract_view_positions(&view, &control).unwrap_or_else(|_| unreachable!());
                    (a, b)
                });
                if level.is_nan() {
                    assert!(a.1.is_empty());
                } else {
                    assert!(a.1.len() > 1000, "level {level}: {} triangles", a.1.len());
                }
                let bits =
                    |p: &[[f32; 3]]| p.iter().map(|v| v.map(f32::to_bits)).collect::<Vec<_>>();
                assert!(bits(&a.0) == bits(&b.0), "positions differ at level {level}");
                assert!(a.1 == b.1, "triangles differ at level {level}");
            }
        }
    }

    /// A position and the differences of the samples about its base: a record that reads
    /// around its vertex in floating point, as the Python module's do.
    #[derive(Clone, Copy, Default, PartialEq, Debug)]
    struct Graded([f32; 3], [f32; 3]);

    impl SlabVertex for Graded {
        const READS_NEAR: bool = true;
        fn make<L: Level>(grid: &Grid, v: GridVertex, e: [f32; 2], n: &Near<'_, L>) -> Self {
            let [i, j, k] = v.base.map(|c| c as usize);
            let d = n.dims();
            let at = |i: usize, j: usize, k: usize| n.sample(i.min(d[0] - 1), j.min(d[1] - 1), k);
            let t = crate::grid::cell::crossing(e[0], e[1]) as f32;
            let g = [
                at(i + 1, j, k) - at(i.saturating_sub(1), j, k) * t,
                at(i, j + 1, k) - at(i, j.saturating_sub(1), k) * t,
                at(i, j, k + 1) - at(i, j, k.saturating_sub(1)) * t,
            ];
            Graded(v.position(grid).as_vec3().to_array(), g)
        }
    }

    /// The kernel's two compiled copies (the build's baseline and x86-64-v3, see `isa`)
    /// make the same mesh bit for bit, positions, records that read around their vertices
    /// and triangles, on one thread and on several. (On a CPU without x86-64-v3 both runs
    /// take the baseline copy.)
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn both_compiled_kernels_make_the_same_mesh() {
        use std::sync::atomic::Ordering;
        let dims = [70, 41, 3 * SLAB + 5];
        let grid = Grid { origin: DVec3::new(-0.5, 0.25, 1.0), cell: 0.37, dims };
        let noisy = noise(dims.iter().product(), 21);
        let smooth: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|n| {
                let [x, y, z] = [n % dims[0], n / dims[0] % dims[1], n / (dims[0] * dims[1])]
                    .map(|c| c as f32 * 0.21);
                x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos()
            })
            .collect();
        for values in [noisy, smooth] {
            let volume = Volume::from_values(grid, values);
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
                let pool = pool.unwrap_or_else(|e| panic!("{e}"));
                let run = |baseline: bool| {
                    isa::tests::BASELINE.store(baseline, Ordering::Relaxed);
                    let control = Control::default();
                    let got = pool.install(|| {
                        let records = extract_volume_records::<Graded>(&volume, &control);
                        let lattice = extract(&volume, &control);
                        (records.unwrap_or_else(|_| unreachable!()), lattice)
                    });
                    isa::tests::BASELINE.store(false, Ordering::Relaxed);
                    let (records, lattice) = got;
                    let lattice = lattice.unwrap_or_else(|_| unreachable!());
                    let bits =
                        records.0.iter().map(|g| (g.0.map(f32::to_bits), g.1.map(f32::to_bits)));
                    (bits.collect::<Vec<_>>(), records.1, lattice.vertices, lattice.triangles)
                };
                let (fast, baseline) = (run(false), run(true));
                assert!(fast.1.len() > 1000, "{} triangles", fast.1.len());
                assert!(fast == baseline, "the copies differ on {threads} threads");
            }
        }
    }

    /// Positions over triangles wound the other way round.
    #[derive(Clone, Copy, Default, PartialEq, Debug)]
    struct Rewound([f32; 3]);

    impl SlabVertex for Rewound {
        const REWOUND: bool = true;
        fn make<L: Level>(grid: &Grid, v: GridVertex, e: [f32; 2], n: &Near<'_, L>) -> Self {
            Rewound(<[f32; 3]>::make(grid, v, e, n))
        }
    }

    /// On one thread and on several, an extraction into the arrays of the last one makes
    /// the mesh a fresh one makes, bit for bit, in the same memory (no new pages); records
    /// that ask for it get every triangle wound the other way round, and nothing else
    /// changes.
    #[test]
    fn reused_arrays_and_rewound_triangles_keep_the_mesh() {
        let dims = [41, 37, 5 * SLAB + 3];
        let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
        let raw = noise(dims.iter().product(), 17);
        let view = VolumeView::new(grid, &raw, 0.0).unwrap_or_else(|| unreachable!());
        let control = Control::default();
        let fresh = extract_view_positions(&view, &control).unwrap_or_else(|_| unreachable!());
        assert!(fresh.1.len() > 10_000);
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let pool = pool.unwrap_or_else(|e| panic!("{e}"));
            pool.install(|| {
                let mut kept = (Vec::<[f32; 3]>::new(), Vec::new());
                for run in 0..4 {
                    let at = (kept.0.as_ptr(), kept.1.as_ptr());
                    let got = extract_view_records_into(&view, &control, kept)
                        .unwrap_or_else(|_| unreachable!());
                    assert!(got == fresh, "run {run} on {threads} threads differs");
                    // (On one thread, the arrays of a fresh run are cut to size, and
                    // the next run grows them once: each slab makes room for twice what
                    // the one before made.)
                    if run > 1 {
                        assert_eq!((got.0.as_ptr(), got.1.as_ptr()), at, "new memory");
                    }
                    kept = got;
                }
                let (v, t) = extract_view_records::<Rewound>(&view, &control)
                    .unwrap_or_else(|_| unreachable!());
                assert!(v.iter().map(|r| r.0).eq(fresh.0.iter().copied()));
                assert!(t.iter().map(|t| [t[0], t[2], t[1]]).eq(fresh.1.iter().copied()));
            });
        }
    }

    /// Vertices handed to a sink slab by slab, with the triangles, are the mesh bit for bit
    /// on any number of threads, into fresh arrays or those of the last run (and over a held
    /// volume as over a view of it); every vertex is handed over once.
    #[test]
    fn sunk_vertices_are_the_mesh() {
        /// An [`Assembly`] that counts the vertices it is given.
        struct Counting(crate::grid::Assembly<[f32; 3]>, AtomicU64);
        impl VertexSink<[f32; 3]> for Counting {
            fn reserve(&self, needed: usize, wanted: usize) {
                self.0.reserve(needed, wanted);
            }
            unsafe fn place(&self, first: usize, vertices: &[[f32; 3]]) {
                self.1.fetch_add(vertices.len() as u64, Ordering::Relaxed);
                // SAFETY: this method's contract.
                unsafe { self.0.place(first, vertices) }
            }
        }
        let dims = [41, 37, 5 * SLAB + 3];
        let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
        let raw = noise(dims.iter().product(), 23);
        let view = VolumeView::new(grid, &raw, 0.0).unwrap_or_else(|| unreachable!());
        let volume = Volume { grid, values: raw.clone(), non_finite: 0 };
        let control = Control::default();
        let fresh = extract_view_positions(&view, &control).unwrap_or_else(|_| unreachable!());
        assert!(fresh.1.len() > 10_000);
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let pool = pool.unwrap_or_else(|e| panic!("{e}"));
            pool.install(|| {
                let mut kept = (Vec::new(), Vec::new());
                for run in 0..4 {
                    let sink = Counting(crate::grid::Assembly::from_vec(kept.0), AtomicU64::new(0));
                    let (n, triangles) = if run == 3 {
                        extract_volume_sunk(&volume, &control, &sink, kept.1)
                    } else {
                        extract_view_sunk(&view, &control, &sink, kept.1)
                    }
                    .unwrap_or_else(|_| unreachable!());
                    assert_eq!(sink.1.load(Ordering::Relaxed), n as u64);
                    // SAFETY: the extractor placed vertices 0..n (checked by their count).
                    let vertices = unsafe { sink.0.into_vec(n, true) };
                    let got = (vertices, triangles);
                    assert!(got == fresh, "run {run} on {threads} threads differs");
                    kept = got;
                }
            });
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
