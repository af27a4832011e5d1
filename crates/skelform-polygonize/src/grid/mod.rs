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
pub use assembly::{Assembly, stream_rows};
pub(crate) mod cell;
pub(crate) mod cube;
pub(crate) mod extract;
pub(crate) mod interior;
pub(crate) mod table;
pub(crate) mod tube;

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
use crate::refine::{
    Bracket, Line, RootOptions, gradient_normals, project_to_surface, refine_roots, roots_on_lines,
};
pub use extract::{
    Cancelled, Extraction, GridVertex, LayerSource, Near, Place, Positions, SLAB, SLIDE_UNIT,
    SampledVertex, SlabVertex, Slide, StreamError, StreamStats, Streamed, VertexSink, Workspace,
    dir_vector, extract, extract_positions, extract_streamed, extract_streamed_with,
    extract_view_positions, extract_view_records, extract_view_records_into, extract_view_sunk,
    extract_volume_records, extract_volume_records_into, extract_volume_sunk, extract_with,
    surface_cubes,
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
    let (positions, evals) = place_vertices(field, grid, &sampled, &triangles, ends, &how);
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
    triangles: &[[u32; 3]],
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
    evals += place_cells(field, grid, &cell, vertex, &mut positions, triangles, how.tolerance);
    (positions, evals)
}

/// How close to its cell's faces refinement may bring an interior vertex (in cells), unless
/// the interpolant put it closer: off the faces, where the neighbours' vertices are.
const CELL_MARGIN: f64 = 1e-3;

/// The least fraction of its distance from the tube's centre that a ring vertex keeps: the ring
/// may shrink onto the field's thinner tube, but not so far that its vertices crowd together
/// at the centre.
const RING_KEEP: f64 = 0.1;

/// The line on which refinement looks for the field's zero for a cell vertex: through its
/// interpolated position along its [`Slide`], within its cell (by [`CELL_MARGIN`]) and, for
/// a ring vertex, not nearer the tube's centre than [`RING_KEEP`] of its distance from it. A vertex
/// without a line gets an empty segment and stays where it is.
pub(crate) fn cell_line(grid: &Grid, v: &GridVertex) -> Line {
    let p = v.position(grid);
    let empty = Line { p, dir: DVec3::X, back: 0.0, ahead: 0.0 };
    let (Place::Cell { offset, .. }, Some(slide)) = (v.place, v.slide()) else {
        return empty;
    };
    let line = DVec3::from_array(slide.line);
    let length = line.length();
    if !(length > 0.0 && length.is_finite()) {
        return empty;
    }
    let dir = line / length;
    let (mut back, mut ahead) = (f64::INFINITY, f64::INFINITY);
    for d in 0..3 {
        let (lo, hi) = (CELL_MARGIN.min(offset[d]), (1.0 - CELL_MARGIN).max(offset[d]));
        let u = dir[d];
        if u > 0.0 {
            ahead = ahead.min((hi - offset[d]) / u);
            back = back.min((offset[d] - lo) / u);
        } else if u < 0.0 {
            ahead = ahead.min((lo - offset[d]) / u);
            back = back.min((offset[d] - hi) / u);
        }
    }
    if slide.ray {
        back = back.min((1.0 - RING_KEEP) * length);
    }
    Line { p, dir, back: back.max(0.0) * grid.cell, ahead: ahead.max(0.0) * grid.cell }
}

/// Places cell vertices (fan centres, tube rings) on the field: each on its [`cell_line`] to
/// `tolerance` cells. `cells` are their indices; `positions` holds every vertex, the edge
/// vertices already placed and the cell vertices where the interpolant put them, and gets
/// the cell vertices' new positions. Returns the field evaluations made.
///
/// A ring moves only as a whole, and no vertex moves where that would turn one of the
/// triangles round it over: where the field has no zero on some ring vertex's line (the
/// lattice does not resolve the field there, and its tube is the interpolant's alone), a
/// ring half on the field and half off it would twist the tube, and a fan centre or ring
/// taken across its loop would fold its triangles over their neighbours. Those stay on the
/// interpolant (where `skelform check --field` sees them off the surface).
pub(crate) fn place_cells<'v>(
    field: &dyn Field,
    grid: &Grid,
    cells: &[usize],
    vertex: impl Fn(usize) -> &'v GridVertex,
    positions: &mut [DVec3],
    triangles: &[[u32; 3]],
    tolerance: f64,
) -> u64 {
    if cells.is_empty() {
        return 0;
    }
    let lines: Vec<Line> = cells.iter().map(|&i| cell_line(grid, vertex(i))).collect();
    let (zeros, evals) = roots_on_lines(field, &lines, grid.cell / 32.0, tolerance * grid.cell);
    // The vertices that move together: one cube's ring, or its fan centre.
    let mut groups: std::collections::BTreeMap<([u32; 3], bool), usize> = Default::default();
    let group: Vec<usize> = cells
        .iter()
        .map(|&i| {
            let v = vertex(i);
            let ray = v.slide().is_some_and(|s| s.ray);
            let next = groups.len();
            *groups.entry((v.base, ray)).or_insert(next)
        })
        .collect();
    // The triangles round the cell vertices, with each cell vertex's place in `cells`.
    let mut slot: rustc_hash::FxHashMap<u32, usize> = Default::default();
    slot.extend(cells.iter().enumerate().map(|(k, &i)| (i as u32, k)));
    let mut bits = vec![0u64; positions.len().div_ceil(64)];
    for &i in cells {
        bits[i / 64] |= 1 << (i % 64);
    }
    let marked = |v: u32| bits[v as usize / 64] >> (v % 64) & 1 == 1;
    let around: Vec<[u32; 3]> =
        triangles.iter().filter(|t| t.iter().any(|&v| marked(v))).copied().collect();
    let mut placed: Vec<DVec3> = lines.iter().map(|l| l.p).collect();
    let mut settle = |cand: &[Option<DVec3>], open: &[bool], turn: f64| {
        let mut moves: Vec<bool> = open.to_vec();
        for (c, &g) in cand.iter().zip(&group) {
            if c.is_none() {
                moves[g] = false;
            }
        }
        let moving = Moving { cand, placed: &placed, lines: &lines, group: &group };
        turn_nothing_over(&around, &slot, positions, &moving, turn, &mut moves);
        for (k, c) in cand.iter().enumerate() {
            if let (Some(c), true) = (c, moves[group[k]]) {
                placed[k] = *c;
            }
        }
        moves
    };
    let moved = settle(&zeros, &vec![true; groups.len()], 0.0);
    // A second try for what stayed: Newton steps along the field's gradient within the cell,
    // kept only where every vertex of the group converged onto the field.
    let again: Vec<usize> = (0..cells.len()).filter(|&k| !moved[group[k]]).collect();
    let mut evals = evals;
    if !again.is_empty() {
        let mut pts: Vec<DVec3> = again.iter().map(|&k| lines[k].p).collect();
        let boxes: Vec<(DVec3, DVec3)> = again
            .iter()
            .map(|&k| {
                let [i, j, l] = vertex(cells[k]).base.map(|x| x as usize);
                let lo = grid.point(i, j, l);
                let m = CELL_MARGIN * grid.cell;
                (lo + DVec3::splat(m), lo + DVec3::splat(grid.cell - m))
            })
            .collect();
        evals += project_to_surface(field, &mut pts, &boxes, tolerance * grid.cell);
        let (mut values, mut grads) = (vec![0.0; pts.len()], vec![DVec3::ZERO; pts.len()]);
        field.eval_grad_many(&pts, &mut values, &mut grads);
        evals += pts.len() as u64;
        let mut cand = vec![None; cells.len()];
        for ((&k, p), (f, g)) in again.iter().zip(&pts).zip(values.iter().zip(&grads)) {
            let off = f.abs() / g.length();
            if off <= tolerance * grid.cell {
                cand[k] = Some(*p);
            }
        }
        let open: Vec<bool> = moved.iter().map(|m| !m).collect();
        settle(&cand, &open, SECOND_TRY_TURN);
    }
    for (k, &i) in cells.iter().enumerate() {
        positions[i] = placed[k];
    }
    evals
}

/// The least cosine of the angle a triangle round a cell vertex may turn through when the
/// vertex moves by the second try (free Newton steps): 60°. Why: unlike the first try's
/// lines, free steps can swing a tube's triangles across their neighbours (a fold, normals
/// nearly opposite across an edge) without turning any one of them over.
const SECOND_TRY_TURN: f64 = 0.5;

/// Where a try would move the cell vertices: `cand[k]` for those of groups that move,
/// `placed[k]` (their place so far) for the others, `lines[k].p` the interpolant's place.
struct Moving<'a> {
    cand: &'a [Option<DVec3>],
    placed: &'a [DVec3],
    lines: &'a [Line],
    group: &'a [usize],
}

/// Clears `moves` for every group that, moved as `m` says, would turn a triangle round a
/// cell vertex through an angle whose cosine is `turn` or less (or collapse it), compared
/// with the cell vertices where the interpolant put them; repeated until none does.
fn turn_nothing_over(
    around: &[[u32; 3]],
    slot: &rustc_hash::FxHashMap<u32, usize>,
    positions: &[DVec3],
    m: &Moving<'_>,
    turn: f64,
    moves: &mut [bool],
) {
    loop {
        let mut changed = false;
        for t in around {
            let at = |after: bool| {
                t.map(|v| match slot.get(&v) {
                    Some(&k) if after && moves[m.group[k]] => m.cand[k].unwrap_or(m.placed[k]),
                    Some(&k) if after => m.placed[k],
                    Some(&k) => m.lines[k].p,
                    None => positions[v as usize],
                })
            };
            let normal = |p: [DVec3; 3]| (p[1] - p[0]).cross(p[2] - p[0]);
            let (before, after) = (normal(at(false)), normal(at(true)));
            let limit = turn * before.length() * after.length();
            if before.dot(after) <= limit && before != DVec3::ZERO {
                for v in t {
                    if let Some(&k) = slot.get(v) {
                        changed |= std::mem::replace(&mut moves[m.group[k]], false);
                    }
                }
            }
        }
        if !changed {
            break;
        }
    }
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
    place_vertices(field, &volume.grid, &ex.vertices, &ex.triangles, ends, &how)
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
