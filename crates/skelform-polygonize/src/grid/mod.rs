//! The grid polygonizer: sample the field on a lattice, then marching cubes with a
//! topologically consistent case table.
//!
//! Guarantees, for any field and any resolution: every edge of the output is shared by
//! exactly two triangles, except where the surface leaves the sampled box (there the mesh is
//! open); triangles are consistently oriented with normals towards `f > 0`; the output is
//! identical on any number of threads. Ambiguous faces are decided by the asymptotic decider
//! and interior ambiguities by the saddles of the trilinear interpolant, so the topology is
//! that of the trilinear interpolant of the samples. Not guaranteed: features thinner than a
//! cell are found (sampling can miss them), and triangles never intersect (fans over strongly
//! curved loops can fold).

// The per-cube machinery is shared with the other polygonizers inside the crate but is no
// part of the interface: what a caller needs of it is re-exported below.
mod assembly;
pub(crate) mod cell;
pub(crate) mod cube;
pub(crate) mod extract;
pub(crate) mod interior;
pub(crate) mod table;

use std::borrow::Borrow;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use skelform_field::Field;
use skelform_field::control::Control;
use skelform_field::grid::{Grid, GridError, LayerSampling, Volume, sample};
use skelform_mesh::Mesh;

use crate::Error;
use crate::lattice::{LatticeOptions, MemoryNeed};
use crate::refine::{Bracket, RootOptions, gradient_normals, project_to_surface, refine_roots};
pub use extract::{
    Cancelled, Extraction, GridVertex, LayerSource, Near, Place, Positions, SLAB, SampledVertex,
    SlabVertex, StreamError, StreamStats, Streamed, Workspace, dir_vector, extract,
    extract_positions, extract_streamed, extract_streamed_with, extract_view_positions,
    extract_view_records, extract_view_records_into, extract_volume_records,
    extract_volume_records_into, extract_with, surface_cubes,
};

pub use crate::lattice::Resolution;

/// Settings of the grid polygonizer.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// The lattice, vertex placement, memory limit, progress and threads.
    pub lattice: LatticeOptions,
    /// Whether the sampled volume is held whole or streamed slab by slab.
    pub streaming: Streaming,
    /// Where extraction keeps its slab buffers between runs; `None`: the process's shared
    /// [`Workspace`] (what a one-shot program wants; a long-lived one may keep its own, and
    /// drop it to give the memory back).
    pub workspace: Option<Arc<Workspace>>,
}

/// Whether the grid polygonizer keeps the whole sampled volume.
///
/// Streaming samples each slab of [`SLAB`] cube layers as it is extracted, so memory
/// follows the thread count instead of the volume (a 512³ volume is 512 MiB of samples); the
/// layer between two slabs is evaluated twice when the slabs run on different threads (at
/// most one layer in `SLAB` more). The mesh is the same either way, bit for bit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Streaming {
    /// Stream when the volume would take more than [`STREAM_ABOVE`] bytes.
    #[default]
    Auto,
    /// Always stream, whatever the volume's size (memory follows the threads).
    Always,
    /// Never stream: the volume is held whole (a few percent faster when it fits).
    Never,
}

/// Volumes larger than this (bytes) are streamed under [`Streaming::Auto`].
pub const STREAM_ABOVE: u64 = 256 << 20;

impl Streaming {
    /// Whether a run on `grid` streams.
    pub fn streams(self, grid: &Grid) -> bool {
        match self {
            Streaming::Auto => Volume::bytes_for(grid) > STREAM_ABOVE,
            Streaming::Always => true,
            Streaming::Never => false,
        }
    }
}

/// What a run did, for `--stats`.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Stats {
    /// Samples along x, y and z of the lattice that covered the domain.
    pub grid_dims: [usize; 3],
    /// Side of the lattice's cubic cells, in the field's units.
    pub cell: f64,
    /// Field evaluations made to sample the lattice (streamed runs sample a layer between slabs
    /// on different threads twice).
    pub samples: u64,
    /// Samples that were NaN or infinite (treated as far outside / inside).
    pub non_finite_samples: u64,
    /// The smallest and largest sampled values: a surface needs one of each sign.
    pub min_sample: f32,
    /// See `min_sample`; both are of the sanitized samples (non-finite ones stored as
    /// ±`f32::MAX`).
    pub max_sample: f32,
    /// Field evaluations for root finding and for normals.
    pub refine_evaluations: u64,
    /// Field gradients taken for vertex normals (none when normals are off).
    pub normal_evaluations: u64,
    /// Cube faces whose sign pattern is ambiguous, decided by the asymptotic decider.
    pub ambiguous_faces: u64,
    /// Cubes whose trilinear interpolant joins opposite corners through the inside (tubes
    /// built).
    pub tunnels: u64,
    /// Vertices in the mesh (one per crossed lattice edge, plus interior vertices of tunnels).
    pub vertices: usize,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Wall time of sampling the field on the lattice.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub sampling: Duration,
    /// Wall time of marching cubes over the samples.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub extraction: Duration,
    /// Wall time of moving vertices onto the surface by root finding.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub refinement: Duration,
    /// Wall time of computing vertex normals.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub normals: Duration,
    /// Whether the volume was streamed (then `sampling` and `extraction` share the wall time
    /// of the combined phase in proportion to the time the workers spent in each).
    pub streamed: bool,
}

impl Stats {
    /// Every field evaluation the run made.
    pub fn evaluations(&self) -> u64 {
        self.samples + self.refine_evaluations + self.normal_evaluations
    }
}

/// The slab buffers a run uses: its own workspace, else the process's.
fn workspace(options: &Options) -> &Workspace {
    options.workspace.as_deref().unwrap_or(Workspace::shared())
}

/// Builds the marching-cubes case table now (a few milliseconds, once per process), so that
/// a timed extraction measures extraction alone, as a tool with a compiled-in table would.
pub fn prepare_tables() {
    table::table();
}

/// The lattice the options describe (see [`LatticeOptions::grid`]).
pub fn grid_for(options: &Options) -> Result<Grid, GridError> {
    options.lattice.grid()
}

/// Bytes the run needs before any triangle exists: the sampled volume (or, streamed, each
/// thread's slab of layers) and per-thread edge numberings.
pub fn memory_needed(grid: &Grid, streamed: bool) -> u64 {
    let layer = (grid.dims[0] * grid.dims[1]) as u64;
    let threads = rayon::current_num_threads() as u64;
    let samples = if streamed {
        threads * layer * 4 * (extract::SLAB as u64 + 1)
    } else {
        Volume::bytes_for(grid)
    };
    samples + threads * layer * 4 * 30 + layer * 8 * grid.dims[2] as u64 / 8
}

/// What a run with `options` on `grid` holds before any triangle (see [`MemoryNeed`]).
pub fn memory_need(grid: &Grid, options: &Options) -> MemoryNeed {
    let streamed = options.streaming.streams(grid);
    MemoryNeed::Lattice { bytes: memory_needed(grid, streamed), streamed }
}

/// Samples of a field, one layer at a time, for streamed extraction.
struct FieldLayers<'a>(LayerSampling<'a>);

impl LayerSource for FieldLayers<'_> {
    type Error = std::convert::Infallible;
    fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, Self::Error> {
        Ok(self.0.layer(k, out))
    }
    fn layers(&self, first: usize, out: &mut [f32], bad: &mut [u64]) -> Result<(), Self::Error> {
        self.0.layers(first, out, bad);
        Ok(())
    }
}

/// Polygonizes `field` (zero set, inside negative) on a lattice over the domain.
///
/// ```
/// use skelform_field::{Aabb, FnField, DVec3};
/// use skelform_polygonize::{LatticeOptions, Resolution};
/// use skelform_polygonize::grid::{polygonize, Options};
/// let sphere = FnField(|p: DVec3| p.length() - 0.8);
/// let lattice = LatticeOptions { domain: Aabb::cube(1.0), resolution: Resolution::Samples(32), ..Default::default() };
/// let opts = Options { lattice, ..Options::default() };
/// let (mesh, stats) = polygonize(&sphere, &opts).unwrap();
/// assert!(mesh.triangle_count() > 0);
/// assert_eq!(stats.samples, 32 * 32 * 32);
/// ```
pub fn polygonize(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    options.lattice.threads.install(|| polygonize_here(field, options))
}

/// [`polygonize`] on the current thread pool.
fn polygonize_here(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    let lattice = &options.lattice;
    let grid = lattice.grid()?;
    let streamed = options.streaming.streams(&grid);
    let needed = memory_needed(&grid, streamed);
    if needed > lattice.max_memory {
        return Err(Error::TooMuchMemory { needed, limit: lattice.max_memory, dims: grid.dims });
    }
    let mut stats = Stats { grid_dims: grid.dims, cell: grid.cell, streamed, ..Stats::default() };
    if streamed {
        return polygonize_streamed(field, &grid, options, stats);
    }

    let t = Instant::now();
    let volume = sample(field, &grid, &lattice.control)?;
    stats.sampling = t.elapsed();
    stats.samples = grid.sample_count();
    stats.non_finite_samples = volume.non_finite;
    let (lo, hi) = volume.value_range();
    stats.min_sample = lo;
    stats.max_sample = hi;

    let t = Instant::now();
    let ex = extract_with(&volume, &lattice.control, workspace(options))?;
    stats.extraction = t.elapsed();
    stats.ambiguous_faces = ex.ambiguous_faces;
    stats.tunnels = ex.tunnels;

    let t = Instant::now();
    phase(&lattice.control, "refinement", ex.vertices.len())?;
    let (positions, evals) =
        place_extracted(field, &volume, &ex, lattice.refine, lattice.tolerance);
    stats.refine_evaluations = evals;
    stats.refinement = t.elapsed();
    if lattice.control.is_cancelled() {
        return Err(Error::Cancelled);
    }

    finish(field, positions, ex.triangles, options, stats)
}

/// Says that a phase of `items` has begun, so a progress display shows its name instead of
/// the last phase's full bar (root finding and normals have no finer steps to report).
fn phase(control: &Control, name: &'static str, items: usize) -> Result<(), Error> {
    let p = skelform_field::control::Progress { phase: name, done: 0, total: Some(items as u64) };
    match control.report(p) {
        std::ops::ControlFlow::Continue(()) => Ok(()),
        std::ops::ControlFlow::Break(()) => Err(Error::Cancelled),
    }
}

/// Normals, and the mesh.
fn finish(
    field: &dyn Field,
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    options: &Options,
    mut stats: Stats,
) -> Result<(Mesh, Stats), Error> {
    let t = Instant::now();
    let normals = if options.lattice.normals && !triangles.is_empty() {
        phase(&options.lattice.control, "normals", positions.len())?;
        let (n, evals) = gradient_normals(field, &positions, &triangles);
        stats.normal_evaluations = evals;
        n
    } else {
        Vec::new()
    };
    stats.normals = t.elapsed();

    let mesh = Mesh {
        positions: positions.iter().map(|p| p.as_vec3().to_array()).collect(),
        normals,
        triangles,
        ..Mesh::default()
    };
    stats.vertices = mesh.vertex_count();
    stats.triangles = mesh.triangle_count();
    Ok((mesh, stats))
}

/// [`polygonize`] without holding the volume: each slab is sampled, extracted and dropped.
fn polygonize_streamed(
    field: &dyn Field,
    grid: &Grid,
    options: &Options,
    mut stats: Stats,
) -> Result<(Mesh, Stats), Error> {
    let t = Instant::now();
    let source = FieldLayers(LayerSampling::new(field, grid));
    let extract::Streamed { vertices: sampled, triangles, stats: s } =
        extract_streamed_with::<SampledVertex, _>(
            &source,
            grid,
            &options.lattice.control,
            workspace(options),
        )?;
    let wall = t.elapsed();
    let busy = (s.source_time + s.extract_time).as_secs_f64();
    let share = if busy > 0.0 { s.source_time.as_secs_f64() / busy } else { 0.5 };
    stats.sampling = wall.mul_f64(share);
    stats.extraction = wall - stats.sampling;
    stats.samples = s.samples_read;
    stats.non_finite_samples = s.non_finite;
    stats.min_sample = s.min_sample;
    stats.max_sample = s.max_sample;
    stats.ambiguous_faces = s.ambiguous_faces;
    stats.tunnels = s.tunnels;

    let t = Instant::now();
    phase(&options.lattice.control, "refinement", sampled.len())?;
    let how = Placement::for_grid(options.lattice.refine, options.lattice.tolerance);
    let ends = |i: usize| sampled[i].ends.map(f64::from);
    let (positions, evals) = place_vertices(field, grid, &sampled, ends, &how);
    stats.refine_evaluations = evals;
    stats.refinement = t.elapsed();
    if options.lattice.control.is_cancelled() {
        return Err(Error::Cancelled);
    }
    finish(field, positions, triangles, options, stats)
}

/// How vertices are moved onto the surface.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placement {
    pub refine: bool,
    pub roots: RootOptions,
    /// Newton tolerance for interior vertices, as a fraction of the cell.
    pub tolerance: f64,
}

impl Placement {
    /// Refinement of vertices made by marching cubes on a grid, to `tolerance` cells.
    fn for_grid(refine: bool, tolerance: f64) -> Self {
        let roots = RootOptions { tolerance, t_min: cell::T_MIN, ..RootOptions::default() };
        Placement { refine, roots, tolerance }
    }
}

/// Vertex positions: interpolated, then (if asked) refined on the field, edge vertices by
/// root finding between their segment's ends, interior vertices by Newton projection.
/// `ends(i)` gives the sampled values at the two ends of vertex `i`'s segment. Returns the
/// positions and the field evaluations made.
pub(crate) fn place_vertices(
    field: &dyn Field,
    grid: &Grid,
    vertices: &[impl Borrow<GridVertex>],
    ends: impl Fn(usize) -> [f64; 2],
    how: &Placement,
) -> (Vec<DVec3>, u64) {
    let vertex = |i: usize| -> &GridVertex { vertices[i].borrow() };
    let mut positions: Vec<DVec3> = (0..vertices.len()).map(|i| vertex(i).position(grid)).collect();
    if !how.refine {
        return (positions, 0);
    }
    let at = |p: [u32; 3]| grid.point(p[0] as usize, p[1] as usize, p[2] as usize);
    let (mut edge, mut brackets, mut cell) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..vertices.len() {
        let v = vertex(i);
        match (v.place, v.tip()) {
            (Place::Edge { t, .. }, Some(tip)) => {
                edge.push(i);
                let [f0, f1] = ends(i);
                brackets.push(Bracket { p0: at(v.base), p1: at(tip), f0, f1, t });
            }
            _ => cell.push(i),
        }
    }
    let mut evals = refine_roots(field, &mut brackets, &how.roots);
    for (&i, b) in edge.iter().zip(&brackets) {
        positions[i] = b.p0.lerp(b.p1, b.t);
    }
    if !cell.is_empty() {
        let mut pts: Vec<DVec3> = cell.iter().map(|&i| positions[i]).collect();
        let boxes: Vec<(DVec3, DVec3)> = cell
            .iter()
            .map(|&i| {
                let lo = at(vertex(i).base);
                (lo, lo + DVec3::splat(grid.cell))
            })
            .collect();
        evals += project_to_surface(field, &mut pts, &boxes, how.tolerance * grid.cell);
        for (&i, p) in cell.iter().zip(pts) {
            positions[i] = p;
        }
    }
    (positions, evals)
}

/// Positions of an extraction's vertices: interpolated, then refined on the field if asked
/// (root finding to `tolerance` cells, end values read from the volume). Returns the
/// positions and the field evaluations made.
pub(crate) fn place_extracted(
    field: &dyn Field,
    volume: &Volume,
    ex: &Extraction,
    refine: bool,
    tolerance: f64,
) -> (Vec<DVec3>, u64) {
    let how = Placement::for_grid(refine, tolerance);
    let value = |p: [u32; 3]| volume.get(p[0] as usize, p[1] as usize, p[2] as usize) as f64;
    let ends = |i: usize| {
        let v = &ex.vertices[i];
        [value(v.base), v.tip().map_or(0.0, value)]
    };
    place_vertices(field, &volume.grid, &ex.vertices, ends, &how)
}

/// Marching cubes on a volume sampled elsewhere, with vertices interpolated linearly and no
/// normals: the extraction-only path (e.g. for a volume read from a raw file).
pub fn extract_mesh(volume: &Volume, control: &Control) -> Result<Mesh, Error> {
    let (positions, triangles) = extract::extract_positions(volume, control)?;
    Ok(Mesh { positions, triangles, ..Mesh::default() })
}

/// [`extract_mesh`] on raw values read in place at a level (a caller's array): the mesh of
/// the [`Volume`] that converting them would make, without the copy.
pub fn extract_view_mesh(
    view: &skelform_field::grid::VolumeView<'_>,
    control: &Control,
) -> Result<Mesh, Error> {
    let (positions, triangles) = extract::extract_view_positions(view, control)?;
    Ok(Mesh { positions, triangles, ..Mesh::default() })
}
