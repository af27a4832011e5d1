//! Healed marching cubes (Nguyen 2016, "Triangulation of non-manifold implicit surfaces using
//! healing techniques"): marching cubes for surfaces that cross themselves.
//!
//! Where `f = 0` crosses itself (`xyz = 0`, a plane through a sphere, the Whitney umbrella),
//! `f` changes sign across each sheet, so near the crossing its signs form a checkerboard and
//! marching cubes joins the sheets wrongly: ragged tubes and caps instead of two sheets
//! passing through each other. Healing finds the crossings and re-triangulates the cubes
//! around them so that the sheets meet along the self-intersection curve.
//!
//! # The pipeline
//!
//! 1. Marching cubes on the lattice, exactly as [`crate::grid`] does it.
//! 2. **Critical vertices** (thesis eq. 4.1): marching-cubes vertices where the gradient is
//!    small, `|f_x| + |f_y| + |f_z| < ε` ([`Epsilon::Absolute`]), or, by default,
//!    `|∇f| < ρ · cell · ‖H‖` ([`Epsilon::Cells`]): a Newton step for `∇f = 0` would be
//!    shorter than `ρ` cells, which does not depend on how `f` is scaled. Their cubes are the
//!    critical cubes, counted by the thesis's classes 10, 12 and 13 (see [`config`]).
//! 3. **Self-intersection points**: on each face of a critical class 10/12/13 cube whose four
//!    edges all cross the surface, the thesis's point (where the two segments joining
//!    opposite edge points meet) seeds a Gauss–Newton solve on that face for `∇f = 0, f = 0`;
//!    every critical vertex seeds the same solve in space. A sample-based scan adds seeds
//!    where `|f|` has a local minimum among same-signed samples (surfaces that never change
//!    sign, which no two-point method sees).
//! 4. **Curves and points**: each singular point found is classified by its Hessian: on a
//!    crossing curve (two sheets), on a bare line (a "handle"), a cone apex, an isolated
//!    point, or degenerate. Curves are traced by predictor–corrector continuation (the
//!    thesis's future work) and cut at lattice faces (the thesis's face points), triple
//!    points (its class-13 interior points) and pinch points.
//! 5. **Healing**: the marching-cubes triangles of the cubes round the curves are replaced.
//!    The region grows until marching cubes is right on its boundary; the segments marching
//!    cubes leaves there (the traces of the sheet pieces leaving the curves) are each zipped
//!    onto the curve they follow, and each nappe round a cone apex is fanned to the apex (see
//!    `zone`). The thesis fans each piece of one cube onto that cube's segment; along a
//!    straight crossing the bands make exactly its triangles (8 per class-10 cube, 24 in the
//!    class-13 cube of a triple point), so its Xano counts come out exactly.
//! 6. **Normals** from the gradient. On a self-intersection the gradient vanishes, so the
//!    normal of a curve vertex is taken just off the curve, into one piece. By default
//!    ([`Options::split_sheets`]) every sheet gets its own copy of each curve vertex with
//!    its own normal; with it off the sheets share the vertex, which then carries one
//!    sheet's normal.
//!
//! # The thesis's own healing
//!
//! [`Healing::Thesis`] (`healing = "thesis"` in a scene) runs the thesis's algorithm as it
//! stands instead: standard marching cubes, then each critical cube of class 10, 12 or 13
//! replaced by its fixed pattern (figs. 4.5, 4.7, 4.8), nothing traced or checked. On the
//! thesis's lattice it reproduces every count of its table (Xano, plane-and-ball, Zeppelin,
//! Diabolo). It is not the default: a crossing heals only where the faces of class
//! 10/12/13 cubes show its four crossings, and the patterns need not meet their
//! neighbours, so a crossing off the lattice's symmetry keeps marching cubes' joined sheets
//! with holes round the few patterns (see `thesis`'s module text and docs/SCENES.md).
//!
//! # Beyond the thesis
//!
//! - **More than one cell can resolve.** The thesis heals cube by cube with patterns for one
//!   self-intersection segment (classes 10, 12) or one triple point (13) and assumes the
//!   rest hold at most one self-intersection point (§4.2, §5.3). Its future work proposes
//!   subdividing critical cubes. We do not subdivide: new vertices on a subdivided face would
//!   have to be shared with the neighbouring cube, and no subdivision of lattice faces shows
//!   a crossing whose sheets are symmetric about the lattice axes (the Whitney umbrella's:
//!   no axis-aligned square has one corner in each of its four wedges, at any size).
//!   Instead, what subdivision is for is done directly: the curves are followed at a quarter
//!   of a cell by continuation (so one cell may hold several segments, a turn, a triple or a
//!   pinch point), every lattice edge on the healed region's boundary is searched for
//!   crossings its samples miss (the extremum of `f` along it, by bisection on the
//!   derivative), every boundary face with four crossings has its saddle found on the field
//!   (or, with none there, its contour followed across it), and the region grows until both
//!   agree with marching cubes. What the bands still cannot
//!   explain keeps the marching-cubes triangles and is reported ([`Stats::unresolved`]).
//! - **Point singularities** are found by minimising `|∇f|` and `|f|` (Gauss–Newton from
//!   the critical vertices) and classified by the Hessian. A cone apex (the double cone)
//!   is healed: marching cubes leaves the two nappes apart with blunt tips, here each nappe
//!   is fanned to the apex, which becomes a vertex shared by both (a non-manifold vertex;
//!   every edge has two triangles). Isolated points and degenerate points are reported.
//! - **Bare lines**: the Whitney umbrella's handle (`z < 0`), where `f ≥ 0` touches zero
//!   along a line without changing sign, is traced through the pinch point and reported as a
//!   singular line; no triangle is made there.
//!
//! # What is guaranteed
//!
//! - Every triangle edge inside the domain has two triangles, except the edges of the
//!   self-intersection curves, which have four (two sheets crossing): the output is **not** a
//!   manifold, by design. This is the topology with `split_sheets` off; by default (on)
//!   each sheet has its own copies of the curve vertices, so a curve edge is there once per
//!   sheet with two triangles each, and welding vertices by position (`skelform check
//!   --weld`) gives back the four. The copies have the same position, bit for bit.
//! - A healed region is used only when every curve edge in it got exactly four triangles and
//!   every boundary segment was explained; otherwise its marching-cubes triangles are kept
//!   and it is reported in [`Stats::unresolved`]. So the mesh never has a hole that marching
//!   cubes would not have (boundary edges only where the surface leaves the domain).
//! - A crossing that ends in a pinch point (the Whitney umbrella, the cross-cap) is healed up
//!   to it: the bands fold round the pinch point, which is one vertex of both sheets (they
//!   become one there), while every curve vertex before it has one copy per sheet.
//! - Self-intersection curves are in [`Mesh::curves`] with the label `RegionTriple([0, 0,
//!   0])`: PLY writes them as the `edge` element, OBJ as `l` lines.
//! - Bare lines and points (a handle, an isolated point) are reported in
//!   [`Stats::singular_lines`] and [`Stats::singular_points`], never meshed: a surface that
//!   does not change sign has no sheets to mesh.
//! - The output does not depend on the number of threads.
//!
//! Not guaranteed: that every self-intersection is found (a curve no seed comes near, one
//! much thinner than a cell); triangle orientation is towards `f > 0`, which changes from one
//! side of a crossing to the other, so sheets are not consistently oriented across curves.

pub mod config;
mod local;
mod network;
mod thesis;
mod trace;
mod zone;

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_field::Field;
use skelform_field::control::{Control, Progress};
use skelform_field::grid::{Grid, Volume, sample};
use skelform_mesh::{CurveEdge, Mesh, RegionTriple};

use crate::grid::cell::case_of;
use crate::grid::cube::{EDGES, FACES, edge_between, other_axes};
use crate::grid::table::table;
use crate::grid::{self, GridVertex, Place, extract};
use crate::refine::face_normals;
use crate::{Error, LatticeOptions};
use config::ThesisClass;
use local::{Probe, sym_eigen};
use trace::{TraceOptions, Tracer};
use zone::{Lattice, Outcome};

pub use trace::{PointKind, SingularPoint};
pub use zone::Unresolved;

/// The label of self-intersection curves in [`Mesh::curves`].
pub const SELF_INTERSECTION: RegionTriple = RegionTriple([0, 0, 0]);

/// When a marching-cubes vertex counts as critical (thesis eq. 4.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Epsilon {
    /// `|f_x| + |f_y| + |f_z| < ε`, the thesis's test (it uses ε = 0.2 at cell 0.15). Depends
    /// on how the field is scaled.
    Absolute(f64),
    /// `|∇f| < ρ · cell · ‖H‖`: one Newton step for `∇f = 0` from the vertex is shorter than
    /// `ρ` cells. Does not depend on the field's scale.
    Cells(f64),
}

/// Which healing replaces the marching-cubes triangles round self-intersections.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum Healing {
    /// The default: the self-intersection curves are found and traced, and the cubes round
    /// them are re-triangulated as regions that grow until marching cubes is right on their
    /// boundary, so the healed mesh has no holes that marching cubes would not have.
    #[default]
    Zone,
    /// The thesis's own algorithm (§4.3), cube by cube: standard marching cubes, then every
    /// critical cube of class 10, 12 or 13 replaced by its fixed pattern (figs. 4.5, 4.7,
    /// 4.8). Reproduces the thesis's triangle counts; where a crossing does not show its
    /// four crossings on the faces of class 10/12/13 cubes (most crossings off the
    /// lattice's symmetry) the mesh has holes there. [`Options::epsilon`] is its critical
    /// test (the thesis's: `Epsilon::Absolute(0.2)`).
    Thesis,
}

/// Settings of the healed polygonizer.
#[derive(Clone, Debug)]
pub struct Options {
    /// The lattice, refinement, normals, memory limit, progress and threads, as for the grid
    /// polygonizer. There is no streaming: healing looks at the samples around every
    /// critical cube, so the whole volume is kept.
    pub lattice: LatticeOptions,
    /// The critical-vertex test.
    pub epsilon: Epsilon,
    /// Give each sheet its own copy of each self-intersection vertex (its own normal), so that
    /// each sheet shades smoothly; the curve edges stay on the first copy. On by default: a
    /// vertex shared by two crossing sheets can carry only one sheet's normal, which is
    /// wrong for the other by up to a right angle, and smooth shading then shows a speckled
    /// seam along the crossing. Off gives the shared vertices (one connected non-manifold
    /// surface, four triangles on each curve edge), which is what a tool that reads the
    /// crossing from the connectivity wants; welding the default's copies by position gives
    /// the same triangles.
    pub split_sheets: bool,
    /// Most cubes all healed regions together may have; beyond it nothing is healed (and the
    /// regions are reported).
    pub max_healed_cubes: usize,
    /// Which healing: the zone healing (default) or the thesis's per-cube patterns.
    pub healing: Healing,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            healing: Healing::Zone,
            lattice: LatticeOptions::default(),
            epsilon: Epsilon::Cells(2.0),
            split_sheets: true,
            max_healed_cubes: 1_000_000,
        }
    }
}

/// Critical cubes by the thesis's classes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct CriticalCubes {
    /// Class 10: two opposite ambiguous faces, a self-intersection line straight through
    /// the cube.
    pub class10: usize,
    /// Class 12: two adjacent ambiguous faces, a line turning round an edge of the cube.
    pub class12: usize,
    /// Class 13: six ambiguous faces, a triple point inside the cube.
    pub class13: usize,
    /// Critical cubes of other configurations (the thesis leaves them; here they are healed
    /// like any other when a curve passes through them).
    pub other: usize,
}

impl CriticalCubes {
    /// Critical cubes of every class: what the thesis's tables count as the cubes to heal.
    pub fn total(&self) -> usize {
        self.class10 + self.class12 + self.class13 + self.other
    }
}

/// A traced self-intersection curve.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct SelfIntersection {
    /// Points along it, about a quarter of a cell apart.
    pub points: Vec<DVec3>,
    /// Whether it is a loop (its last point joins its first) rather than a path between
    /// the domain's boundary, pinch points and triple points.
    pub closed: bool,
    /// Its length along `points` (closing segment included for a loop).
    pub length: f64,
    /// Whether it is meshed (its region was healed).
    pub healed: bool,
}

/// A line where the zero set is the line alone (the Whitney umbrella's handle): reported, not
/// meshed.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct SingularLine {
    /// Points along it, as traced.
    pub points: Vec<DVec3>,
    /// Its length along `points`.
    pub length: f64,
}

/// What a run did, for `--stats`.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Stats {
    /// Which healing made the mesh.
    pub mode: Healing,
    /// Samples along x, y and z of the lattice that covered the domain.
    pub grid_dims: [usize; 3],
    /// Side of the lattice's cubic cells.
    pub cell: f64,
    /// Field evaluations made to sample the lattice (the whole volume is kept for healing).
    pub samples: u64,
    /// Samples that were NaN or infinite (treated as far outside / inside).
    pub non_finite_samples: u64,
    /// The smallest sampled value (of the sanitized samples): a surface needs one of each sign.
    pub min_sample: f32,
    /// The largest sampled value.
    pub max_sample: f32,
    /// Field evaluations for root finding along crossed edges.
    pub refine_evaluations: u64,
    /// Field gradients taken for vertex normals.
    pub normal_evaluations: u64,
    /// Gradients for the critical-vertex test (and its Hessians).
    pub critical_evaluations: u64,
    /// Evaluations of the singular-point search, tracing and zone checks.
    pub search_evaluations: u64,
    /// Triangles of plain marching cubes on the same lattice.
    pub mc_triangles: usize,
    /// Marching-cubes triangles kept (outside healed regions).
    pub kept_mc_triangles: usize,
    /// Triangles made by healing.
    pub healing_triangles: usize,
    /// Thesis healing: pattern triangles left out because two of their vertices are one
    /// point (a self-intersection point on a cube edge, thesis fig. 4.8).
    pub skipped_triangles: usize,
    /// Triangles in the healed mesh (the thesis's "triangles by HMC").
    pub triangles: usize,
    /// Vertices in the healed mesh.
    pub vertices: usize,
    /// Marching-cubes vertices where the gradient nearly vanishes (thesis eq. 4.1): where
    /// sheets may cross.
    pub critical_vertices: usize,
    /// Cubes holding critical vertices, by the thesis's classes.
    pub critical_cubes: CriticalCubes,
    /// The thesis's face points: where the segments joining opposite crossings meet, on the
    /// faces with four crossings of critical class 10/12/13 cubes (seeds for the search).
    pub face_points: usize,
    /// Seeds given to the singular-point search (after skipping those near what was found).
    pub seeds_tried: u64,
    /// Healed regions, and their cubes.
    pub zones: usize,
    /// Cubes re-triangulated by healing, over all zones.
    pub healed_cubes: usize,
    /// Regions left as marching cubes made them, and why.
    pub unresolved: Vec<Unresolved>,
    /// Lattice edges and faces checked on the field while growing healed regions.
    pub edges_checked: usize,
    /// See `edges_checked`.
    pub faces_checked: usize,
    /// Edges of self-intersection curves in the mesh.
    pub curve_edges: usize,
    /// The self-intersection curves traced, meshed or not.
    pub curves: Vec<SelfIntersection>,
    /// Isolated singular points found (cone apexes, pinch and triple points, …).
    pub singular_points: Vec<SingularPoint>,
    /// Lines where the zero set is the line alone: reported, not meshed.
    pub singular_lines: Vec<SingularLine>,
    /// Wall time of sampling the field on the lattice.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub sampling: Duration,
    /// Wall time of plain marching cubes.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub extraction: Duration,
    /// Wall time of root finding on crossed edges.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub refinement: Duration,
    /// Wall time of the critical-vertex test and the singular-point search and tracing.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub search: Duration,
    /// Wall time of growing zones and re-triangulating them.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub healing: Duration,
    /// Wall time of computing vertex normals.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub normals: Duration,
}

impl Stats {
    /// Every field evaluation the run made.
    pub fn evaluations(&self) -> u64 {
        self.samples
            + self.refine_evaluations
            + self.normal_evaluations
            + self.critical_evaluations
            + self.search_evaluations
    }
}

const CHUNK: usize = 1024;

fn report(control: &Control, phase: &'static str, done: u64, total: u64) -> Result<(), Error> {
    match control.report(Progress { phase, done, total: Some(total) }) {
        std::ops::ControlFlow::Continue(()) => Ok(()),
        std::ops::ControlFlow::Break(()) => Err(Error::Cancelled),
    }
}

/// Refuses to go on healing when what healing adds to the grid's run (`grid_bytes`, the
/// volume and extraction buffers, still held) would pass `max_memory`: per marching-cubes
/// vertex its `f64` position, gradient, critical flag, the positions and normals of the
/// healed mesh and the output mesh's arrays; per triangle the cube it lies in, the kept copy
/// and the output's. Known once the marching-cubes mesh is, so checked then: a failure of
/// the run ([`Error::MemoryLimit`]), not of its input.
fn check_added(
    grid: &Grid,
    grid_bytes: u64,
    vertices: &Vec<grid::GridVertex>,
    triangles: &Vec<[u32; 3]>,
    max_memory: u64,
) -> Result<(), Error> {
    use crate::lattice::memory::{check, vec_bytes};
    let per_vertex =
        (4 * size_of::<DVec3>() + 1 + size_of::<DVec3>() + 2 * size_of::<[f32; 3]>()) as u64;
    let per_triangle = (size_of::<Option<usize>>() + 2 * size_of::<[u32; 3]>()) as u64;
    let held = grid_bytes
        + vec_bytes(vertices)
        + vec_bytes(triangles)
        + vertices.len() as u64 * per_vertex
        + triangles.len() as u64 * per_triangle;
    let cubes = grid.dims.iter().map(|&d| d as u64 - 1).product();
    check("healed", held, max_memory, cubes)
}

/// Polygonizes `field` (zero set, inside negative), healing its self-intersections.
///
/// ```
/// use skelform_field::{Aabb, FnField, DVec3};
/// use skelform_polygonize::{LatticeOptions, Resolution};
/// use skelform_polygonize::healed::{polygonize, Options};
/// // Two planes crossing along the x axis.
/// let f = FnField(|p: DVec3| p.y * p.z);
/// let lattice = LatticeOptions { domain: Aabb::cube(1.0), resolution: Resolution::Samples(12), ..Default::default() };
/// let opts = Options { lattice, ..Options::default() };
/// let (mesh, stats) = polygonize(&f, &opts).unwrap();
/// assert!(stats.curve_edges > 0);
/// assert_eq!(mesh.curves.len(), stats.curve_edges);
/// ```
pub fn polygonize(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    options.lattice.threads.install(|| polygonize_here(field, options))
}

/// The mesh's normals from the gradients at its vertices; a vertex where the gradient
/// vanishes or is not finite (on a self-intersection curve, at a singular point) takes its
/// triangles' mean normal instead.
fn vertex_normals(
    mut normals: Vec<DVec3>,
    positions: &[DVec3],
    triangles: &[[u32; 3]],
) -> Vec<[f32; 3]> {
    let bad = |n: &DVec3| *n == DVec3::ZERO || !n.is_finite();
    if normals.iter().any(bad) {
        let face = face_normals(positions, triangles);
        for (n, f) in normals.iter_mut().zip(face) {
            if bad(n) {
                *n = DVec3::from_array(f.map(f64::from));
            }
        }
    }
    normals.iter().map(|n| n.as_vec3().to_array()).collect()
}

/// What a healed run on `grid` holds before any triangle: the whole sampled volume (healing
/// looks back at it), never streamed.
pub fn memory_need(grid: &Grid) -> crate::MemoryNeed {
    crate::MemoryNeed::Lattice { bytes: grid::memory_needed(grid, false), streamed: false }
}

/// The lattice of a healed run, sampled whole after its memory was checked, and the stats
/// that both healings begin with.
struct Sampled {
    grid: Grid,
    volume: skelform_field::grid::Volume,
    /// Bytes the lattice holds, to which each later stage adds its own.
    needed: u64,
    stats: Stats,
}

fn sample_lattice(field: &dyn Field, options: &Options) -> Result<Sampled, Error> {
    let lattice = &options.lattice;
    let grid = lattice.grid()?;
    let need = memory_need(&grid);
    crate::lattice::memory::refuse(need, lattice.max_memory, &grid)?;
    let mut stats =
        Stats { grid_dims: grid.dims, cell: grid.cell, mode: options.healing, ..Stats::default() };
    let t = Instant::now();
    let volume = sample(field, &grid, &lattice.control)?;
    stats.sampling = t.elapsed();
    stats.samples = grid.sample_count();
    stats.non_finite_samples = volume.non_finite;
    (stats.min_sample, stats.max_sample) = volume.value_range();
    Ok(Sampled { grid, volume, needed: need.bytes(), stats })
}

/// [`polygonize`] on the current thread pool.
fn polygonize_here(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    check_options(options)?;
    if options.healing == Healing::Thesis {
        return thesis::polygonize(field, options);
    }
    let lattice = &options.lattice;
    let control = &lattice.control;
    let Sampled { grid, volume, needed, mut stats } = sample_lattice(field, options)?;
    let h = grid.cell;

    // 1. Marching cubes.
    let t = Instant::now();
    let ex = extract(&volume, control)?;
    stats.extraction = t.elapsed();
    stats.mc_triangles = ex.triangles.len();

    let t = Instant::now();
    let (positions, evals) =
        grid::place_extracted(field, &volume, &ex, lattice.refine, lattice.tolerance);
    stats.refine_evaluations = evals;
    stats.refinement = t.elapsed();
    if control.is_cancelled() {
        return Err(Error::Cancelled);
    }
    check_added(&grid, needed, &ex.vertices, &ex.triangles, lattice.max_memory)?;

    // 2. Gradients everywhere (normals and the critical test).
    let t = Instant::now();
    let lat = Lattice::new(grid);
    let grads = gradients(field, &positions);
    stats.normal_evaluations = positions.len() as u64;
    let critical = critical_vertices(field, &positions, &grads, options.epsilon, h, &mut stats);
    stats.critical_vertices = critical.iter().filter(|&&c| c).count();
    let cube_of_tri: Vec<Option<usize>> =
        ex.triangles.par_iter().map(|t| triangle_cube(&lat, &ex.vertices, t)).collect();
    let mut critical_cubes: Vec<usize> = ex
        .triangles
        .iter()
        .zip(&cube_of_tri)
        .filter(|(t, _)| t.iter().any(|&v| critical[v as usize]))
        .filter_map(|(_, c)| *c)
        .collect();
    critical_cubes.sort_unstable();
    critical_cubes.dedup();
    let critical_set: FxHashSet<usize> = critical_cubes.iter().copied().collect();
    let edge_vertex =
        zone::edge_vertices(&lat, &ex.vertices, &ex.triangles, &cube_of_tri, &critical_set);

    // 3–4. Seeds, singular points and curves.
    let mut tracer = Tracer::new(
        Probe::new(field, h),
        grid,
        TraceOptions { step: 0.25, max_steps: 64 * (grid.dims.iter().sum::<usize>() + 16) },
    );
    let tbl = table();
    let mut face_seeds: Vec<(DVec3, usize)> = Vec::new();
    for &ci in &critical_cubes {
        let c = lat.coords(ci);
        let v = lat.corner_values(&volume, c);
        let case = case_of(&v);
        match config::thesis_class(case as u8) {
            Some(ThesisClass::Ten) => stats.critical_cubes.class10 += 1,
            Some(ThesisClass::Twelve) => stats.critical_cubes.class12 += 1,
            Some(ThesisClass::Thirteen) => stats.critical_cubes.class13 += 1,
            None => {
                stats.critical_cubes.other += 1;
                continue;
            }
        }
        let amb = tbl.ambiguous[case];
        for f in 0..6 {
            if amb & (1 << f) != 0
                && let Some(p) = face_point(&lat, &edge_vertex, &positions, c, f)
            {
                face_seeds.push((p, f / 2));
            }
        }
    }
    let scan = scan_seeds(&volume);
    let total = (face_seeds.len() + stats.critical_vertices + scan.len()) as u64;
    let mut done = 0u64;
    stats.face_points = face_seeds.len();
    for &(p, axis) in &face_seeds {
        let (b, c) = other_axes(axis);
        tracer.seed(p, &[unit(b), unit(c)]);
        done += 1;
        if done.is_multiple_of(64) {
            report(control, "searching singular points", done, total)?;
        }
    }
    let all = [DVec3::X, DVec3::Y, DVec3::Z];
    let seeds = critical.iter().enumerate().filter(|(_, c)| **c).map(|(i, _)| positions[i]);
    for p in seeds.chain(scan.iter().copied()) {
        tracer.seed(p, &all);
        done += 1;
        if done.is_multiple_of(64) {
            report(control, "searching singular points", done, total)?;
        }
    }
    stats.search = t.elapsed();

    // 5. Healing, tracing again from any self-intersection found on a region's boundary.
    let t = Instant::now();
    let mut zone_probe = Probe::new(field, h);
    let mut rounds = 0;
    let mut trust_decider = false;
    let (net, healing) = loop {
        rounds += 1;
        let net = network::build(&mut tracer);
        report(control, "healing", 0, 1)?;
        let input = zone::Input {
            grid,
            volume: &volume,
            vertices: &ex.vertices,
            positions: &positions,
            triangles: &ex.triangles,
            cube_of_tri: &cube_of_tri,
            net: &net,
            max_cubes: options.max_healed_cubes,
        };
        if trust_decider {
            let healing = zone::heal_ignoring_seeds(&input, &mut zone_probe);
            break (net, healing);
        }
        match zone::heal(&input, &mut zone_probe) {
            Outcome::Healed(h) => break (net, h),
            Outcome::Seeds(seeds) => {
                let mut new = false;
                for (p, axis) in seeds {
                    let (b, c) = other_axes(axis);
                    new |= tracer.seed(p, &[unit(b), unit(c)]);
                }
                // Nothing new to trace (or enough rounds): heal with what there is, trusting
                // the decider on those faces.
                trust_decider = !new || rounds >= 8;
            }
        }
    };
    stats.seeds_tried = tracer.seeds_tried;
    stats.search_evaluations = tracer.probe.evals + zone_probe.evals;
    stats.healing = t.elapsed();
    report(control, "healing", 1, 1)?;

    // 6. The mesh.
    let t = Instant::now();
    let n_mc = ex.vertices.len() as u32;
    let mut triangles: Vec<[u32; 3]> = ex
        .triangles
        .iter()
        .zip(&cube_of_tri)
        .filter(|(_, c)| c.is_none_or(|c| !healing.cubes.contains(&c)))
        .map(|(t, _)| *t)
        .collect();
    stats.kept_mc_triangles = triangles.len();
    stats.healing_triangles = healing.triangles.len();
    let first_heal = triangles.len();
    triangles.extend_from_slice(&healing.triangles);
    let mut positions_all: Vec<DVec3> = positions.clone();
    positions_all.extend(net.nodes.iter().map(|n| n.p));
    let mut normals_all: Vec<DVec3> = grads.iter().map(|g| g.normalize_or_zero()).collect();
    normals_all.resize(positions_all.len(), DVec3::ZERO);
    let mut probe = Probe::new(field, h);
    // The sheet pieces round each curve vertex (see `sheet_pieces`), and per piece the normal
    // there: the gradient just off the curve, into the piece.
    let piece_of = sheet_pieces(&healing.triangles, &healing.band_of, &healing.curve_edges, n_mc);
    let mut piece_normal: FxHashMap<(u32, Piece), DVec3> = FxHashMap::default();
    for (k, tri) in healing.triangles.iter().enumerate() {
        for (i, &v) in tri.iter().enumerate() {
            let key = (v, piece_of[k][i]);
            if v < n_mc || piece_normal.contains_key(&key) {
                continue;
            }
            let p = positions_all[v as usize];
            let others = (positions_all[tri[(i + 1) % 3] as usize]
                + positions_all[tri[(i + 2) % 3] as usize])
                * 0.5;
            let dir = (others - p).normalize_or_zero();
            let n = probe
                .grad(p + dir * (1e-3 * h))
                .map_or(DVec3::ZERO, |(_, g)| g.normalize_or_zero());
            piece_normal.insert(key, n);
        }
    }
    // Per piece, the plane of its triangles at each curve vertex (which pieces are one sheet).
    let mut piece_plane: FxHashMap<(u32, Piece), DVec3> = FxHashMap::default();
    for (k, tri) in healing.triangles.iter().enumerate() {
        let q = tri.map(|v| positions_all[v as usize]);
        let n = (q[1] - q[0]).cross(q[2] - q[0]);
        for (i, &v) in tri.iter().enumerate().filter(|(_, v)| **v >= n_mc) {
            *piece_plane.entry((v, piece_of[k][i])).or_insert(DVec3::ZERO) += n;
        }
    }
    for n in piece_plane.values_mut() {
        *n = n.normalize_or_zero();
    }
    let mut node_pieces: Vec<(u32, Piece)> = piece_normal.keys().copied().collect();
    node_pieces.sort_unstable();
    for key in &node_pieces {
        if normals_all[key.0 as usize] == DVec3::ZERO {
            normals_all[key.0 as usize] = piece_normal[key];
        }
    }
    // Curve vertices on one curve edge: pinch points and exits from the box.
    let mut curve_degree: FxHashMap<u32, usize> = FxHashMap::default();
    let distinct: FxHashSet<[u32; 2]> =
        healing.curve_edges.iter().map(|&[a, b]| [a.min(b), a.max(b)]).collect();
    for e in &distinct {
        for &v in e {
            *curve_degree.entry(v + n_mc).or_insert(0) += 1;
        }
    }
    let curve_set: FxHashSet<[u32; 2]> = distinct.iter().map(|e| e.map(|v| v + n_mc)).collect();
    let curve_ends: FxHashSet<u32> =
        curve_degree.iter().filter(|x| *x.1 == 1).map(|x| *x.0).collect();
    if options.split_sheets {
        split_sheets(
            &mut triangles[first_heal..],
            &piece_of,
            &node_pieces,
            &piece_normal,
            &piece_plane,
            &curve_set,
            &curve_ends,
            &mut positions_all,
            &mut normals_all,
        );
    }
    stats.normal_evaluations += probe.evals;
    let mut curves: Vec<[u32; 2]> =
        healing.curve_edges.iter().map(|&[a, b]| [a + n_mc, b + n_mc]).collect();
    curves.sort_unstable();
    curves.dedup();

    // Compact: only vertices that a triangle or curve uses, in their order.
    let mut used = vec![false; positions_all.len()];
    for t in &triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    for c in &curves {
        used[c[0] as usize] = true;
        used[c[1] as usize] = true;
    }
    let mut remap = vec![u32::MAX; positions_all.len()];
    let mut mesh = Mesh::default();
    let mut kept_positions = Vec::new();
    for (i, &u) in used.iter().enumerate() {
        if u {
            remap[i] = kept_positions.len() as u32;
            kept_positions.push(positions_all[i]);
        }
    }
    mesh.triangles = triangles.iter().map(|t| t.map(|v| remap[v as usize])).collect();
    mesh.positions = kept_positions.iter().map(|p| p.as_vec3().to_array()).collect();
    mesh.curves = curves
        .iter()
        .map(|c| CurveEdge { v: c.map(|v| remap[v as usize]), label: SELF_INTERSECTION })
        .collect();
    if options.lattice.normals && !mesh.triangles.is_empty() {
        let n: Vec<DVec3> = (0..used.len()).filter(|&i| used[i]).map(|i| normals_all[i]).collect();
        mesh.normals = vertex_normals(n, &kept_positions, &mesh.triangles);
    }
    stats.normals = t.elapsed();

    // Report.
    let healed_edges: FxHashSet<[u32; 2]> = healing.curve_edges.iter().copied().collect();
    stats.curves = net
        .runs
        .iter()
        .map(|r| {
            let n = r.fine.len();
            let mut length: f64 = r.fine.windows(2).map(|w| (w[1] - w[0]).length()).sum();
            if r.closed && n > 1 {
                length += (r.fine[0] - r.fine[n - 1]).length();
            }
            let healed = r
                .nodes
                .windows(2)
                .any(|w| healed_edges.contains(&[w[0].min(w[1]), w[0].max(w[1])]));
            SelfIntersection { points: r.fine.clone(), closed: r.closed, length, healed }
        })
        .collect();
    stats.singular_lines = net
        .lines
        .iter()
        .map(|l| SingularLine {
            points: l.clone(),
            length: l.windows(2).map(|w| (w[1] - w[0]).length()).sum(),
        })
        .collect();
    stats.singular_points = net.points.clone();
    stats.zones = healing.zones;
    stats.healed_cubes = healing.cubes.len();
    stats.unresolved = healing.unresolved;
    stats.edges_checked = healing.edges_checked;
    stats.faces_checked = healing.faces_checked;
    stats.curve_edges = mesh.curves.len();
    stats.triangles = mesh.triangles.len();
    stats.vertices = mesh.positions.len();
    Ok((mesh, stats))
}

fn check_options(o: &Options) -> Result<(), Error> {
    if !(o.lattice.tolerance > 0.0 && o.lattice.tolerance < 1.0) {
        return Err(Error::BadOption(format!(
            "tolerance must be between 0 and 1 (got {})",
            o.lattice.tolerance
        )));
    }
    match o.epsilon {
        Epsilon::Absolute(e) | Epsilon::Cells(e) if !(e.is_finite() && e > 0.0) => {
            Err(Error::BadOption(format!("epsilon must be a positive number (got {e})")))
        }
        _ => Ok(()),
    }
}

fn unit(a: usize) -> DVec3 {
    let mut u = DVec3::ZERO;
    u[a] = 1.0;
    u
}

/// Gradients at every vertex, in fixed chunks (non-finite ones become zero).
fn gradients(field: &dyn Field, positions: &[DVec3]) -> Vec<DVec3> {
    let mut out = vec![DVec3::ZERO; positions.len()];
    out.par_chunks_mut(CHUNK).zip(positions.par_chunks(CHUNK)).for_each(|(o, p)| {
        let mut v = vec![0.0; p.len()];
        field.eval_grad_many(p, &mut v, o);
        for g in o.iter_mut() {
            if !g.is_finite() {
                *g = DVec3::ZERO;
            }
        }
    });
    out
}

/// The thesis's critical test at every vertex.
fn critical_vertices(
    field: &dyn Field,
    positions: &[DVec3],
    grads: &[DVec3],
    eps: Epsilon,
    h: f64,
    stats: &mut Stats,
) -> Vec<bool> {
    match eps {
        Epsilon::Absolute(e) => {
            grads.iter().map(|g| g.x.abs() + g.y.abs() + g.z.abs() < e).collect()
        }
        Epsilon::Cells(rho) => {
            let d = 1e-4 * h;
            stats.critical_evaluations += 3 * positions.len() as u64;
            let mut out = vec![false; positions.len()];
            out.par_chunks_mut(CHUNK)
                .zip(positions.par_chunks(CHUNK).zip(grads.par_chunks(CHUNK)))
                .for_each(|(o, (p, g))| {
                    let mut v = vec![0.0; p.len()];
                    let mut cols = [
                        vec![DVec3::ZERO; p.len()],
                        vec![DVec3::ZERO; p.len()],
                        vec![DVec3::ZERO; p.len()],
                    ];
                    for (a, col) in cols.iter_mut().enumerate() {
                        let q: Vec<DVec3> = p.iter().map(|x| *x + unit(a) * d).collect();
                        field.eval_grad_many(&q, &mut v, col);
                    }
                    for i in 0..p.len() {
                        let m = glam::DMat3::from_cols(
                            (cols[0][i] - g[i]) / d,
                            (cols[1][i] - g[i]) / d,
                            (cols[2][i] - g[i]) / d,
                        );
                        let hm = (m + m.transpose()) * 0.5;
                        if !hm.is_finite() {
                            continue;
                        }
                        let (vals, _) = sym_eigen(hm);
                        o[i] = g[i].length() < rho * h * vals[2].abs();
                    }
                });
            out
        }
    }
}

/// The cube a marching-cubes triangle belongs to.
fn triangle_cube(lat: &Lattice, vertices: &[GridVertex], t: &[u32; 3]) -> Option<usize> {
    let belongs = |v: &GridVertex, c: [usize; 3]| match v.place {
        Place::Cell { .. } => v.base.map(|x| x as usize) == c,
        Place::Edge { dir, .. } => {
            let axis = dir.trailing_zeros() as usize;
            (0..3).all(|a| {
                let b = v.base[a] as usize;
                if a == axis { b == c[a] } else { b == c[a] || b == c[a] + 1 }
            })
        }
    };
    let v0 = &vertices[t[0] as usize];
    let candidates: Vec<usize> = match v0.place {
        Place::Cell { .. } => vec![lat.cube(v0.base.map(|x| x as usize))],
        Place::Edge { dir, .. } => {
            let axis = dir.trailing_zeros() as usize;
            lat.around_edge(v0.base.map(|x| x as usize), axis).iter().flatten().copied().collect()
        }
    };
    candidates.into_iter().find(|&c| {
        let cc = lat.coords(c);
        t.iter().all(|&v| belongs(&vertices[v as usize], cc))
    })
}

/// The thesis's self-intersection estimate on face `f` of cube `c`: where the segments
/// joining the crossings on opposite sides of the face meet.
fn face_point(
    lat: &Lattice,
    edge_vertex: &FxHashMap<u64, u32>,
    positions: &[DVec3],
    c: [usize; 3],
    f: usize,
) -> Option<DVec3> {
    let q = FACES[f];
    let mut pts = [DVec3::ZERO; 4];
    for (k, p) in pts.iter_mut().enumerate() {
        let e = edge_between(q[k], q[(k + 1) % 4]);
        let o = crate::grid::cube::CORNERS[EDGES[e][0]];
        let base = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
        let v = *edge_vertex.get(&lat.edge_key(base, crate::grid::cube::edge_axis(e)))?;
        *p = positions[v as usize];
    }
    let (b, cc) = other_axes(f / 2);
    let two = |p: DVec3| glam::DVec2::new(p[b], p[cc]);
    let (a0, a1, b0, b1) = (two(pts[0]), two(pts[2]), two(pts[1]), two(pts[3]));
    let (da, db) = (a1 - a0, b1 - b0);
    let den = da.perp_dot(db);
    if den.abs() < 1e-300 {
        return None;
    }
    let s = (b0 - a0).perp_dot(db) / den;
    let x = a0 + da * s;
    let mut p = pts[0];
    p[b] = x.x;
    p[cc] = x.y;
    p.is_finite().then_some(p)
}

/// Lattice points where `|f|` is smallest among its 26 neighbours, all 27 of one sign, and
/// well below their largest: where a surface that never changes sign may touch zero.
fn scan_seeds(volume: &Volume) -> Vec<DVec3> {
    let g: &Grid = &volume.grid;
    let [nx, ny, nz] = g.dims;
    if nx < 3 || ny < 3 || nz < 3 {
        return Vec::new();
    }
    let mut out: Vec<(usize, DVec3)> = (1..nz - 1)
        .into_par_iter()
        .flat_map_iter(|k| {
            let mut found = Vec::new();
            for j in 1..ny - 1 {
                for i in 1..nx - 1 {
                    let v = volume.get(i, j, k);
                    let neg = v < 0.0;
                    let a = v.abs();
                    let mut ok = true;
                    let mut top = 0f32;
                    'n: for dz in 0..3 {
                        for dy in 0..3 {
                            for dx in 0..3 {
                                let w = volume.get(i + dx - 1, j + dy - 1, k + dz - 1);
                                if (w < 0.0) != neg || w.abs() < a {
                                    ok = false;
                                    break 'n;
                                }
                                top = top.max(w.abs());
                            }
                        }
                    }
                    if ok && a < 0.25 * top {
                        found.push((g.index(i, j, k), g.point(i, j, k)));
                    }
                }
            }
            found
        })
        .collect();
    out.sort_by_key(|x| x.0);
    out.truncate(10_000);
    out.into_iter().map(|x| x.1).collect()
}

/// Gives each sheet at each curve vertex its own copy of the vertex: the sheet pieces round
/// the vertex ([`sheet_pieces`]) whose planes there are parallel are one sheet (its two
/// halves across the curve).
///
/// The pieces are told apart by `piece_plane`, the (area-weighted) normal of each piece's
/// triangles at the vertex, not by the gradient normals (`piece_normal`, what the copies get
/// for shading): the gradient is taken a thousandth of a cell off the curve towards the
/// piece's triangle, and where that direction leaves the sheet by a few degrees (a chord of a
/// curved sheet) the gradient of `f = a·b`, first-order small in both factors there, tilts
/// by tens of degrees (the plane-and-ball at 32 samples: a sphere band's normal 50° off
/// radial). Four pieces (two sheets crossing) are paired as the one of the three pairings
/// whose pairs are most nearly parallel; a threshold alone split such a vertex three ways,
/// and the copies then changed sheets along the curve (edges with three triangles, holes).
///
/// The pairing is made once per pair of strips, not per vertex: the pieces that follow each
/// other along the curve (across its edges) form strips, each vertex votes for its best
/// pairing, and every vertex takes the pairing of its strips with the most votes. Where the
/// two sheets are nearly parallel (the cross-cap near its pinch point on the box) a vertex's
/// own planes can pair them the other way, and the copies then changed sheets along the
/// curve. The copy that keeps the vertex's id (the one the curve edges use) is the sheet of
/// the strip first in order, the same one at both ends of every curve edge.
#[allow(clippy::too_many_arguments)]
fn split_sheets(
    triangles: &mut [[u32; 3]],
    piece_of: &[[Piece; 3]],
    node_pieces: &[(u32, Piece)],
    piece_normal: &FxHashMap<(u32, Piece), DVec3>,
    piece_plane: &FxHashMap<(u32, Piece), DVec3>,
    curve: &FxHashSet<[u32; 2]>,
    curve_ends: &FxHashSet<u32>,
    positions: &mut Vec<DVec3>,
    normals: &mut Vec<DVec3>,
) {
    let index: FxHashMap<(u32, Piece), usize> =
        node_pieces.iter().enumerate().map(|(k, &x)| (x, k)).collect();
    let mut count: FxHashMap<u32, usize> = FxHashMap::default();
    for &(v, _) in node_pieces {
        *count.entry(v).or_insert(0) += 1;
    }
    // Strips: pieces joined across curve edges between vertices where two sheets cross.
    let mut parent: Vec<usize> = (0..node_pieces.len()).collect();
    fn root(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    let crossing = |v: u32| count.get(&v).copied().unwrap_or(0) >= 4;
    for (t, pc) in triangles.iter().zip(piece_of) {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            if !curve.contains(&[a.min(b), a.max(b)]) || !crossing(a) || !crossing(b) {
                continue;
            }
            if let (Some(&x), Some(&y)) = (index.get(&(a, pc[i])), index.get(&(b, pc[(i + 1) % 3])))
            {
                let (rx, ry) = (root(&mut parent, x), root(&mut parent, y));
                parent[rx.max(ry)] = rx.min(ry);
            }
        }
    }
    // A strip's key: its first piece in order (for pieces that are bands, the band).
    let strip: Vec<usize> = (0..node_pieces.len()).map(|k| root(&mut parent, k)).collect();
    // Each vertex with its pieces: `(v, first, end)`, `node_pieces[first..end]`.
    let mut groups: Vec<(u32, usize, usize)> = Vec::new();
    for (k, &(v, _)) in node_pieces.iter().enumerate() {
        match groups.last_mut() {
            Some(g) if g.0 == v => g.2 = k + 1,
            _ => groups.push((v, k, k + 1)),
        }
    }
    let plane = |v: u32, b: Piece| piece_plane.get(&(v, b)).copied().unwrap_or(DVec3::ZERO);
    let parallel = |v: u32, a: Piece, b: Piece| plane(v, a).dot(plane(v, b)).abs();
    const PAIRINGS: [[usize; 4]; 3] = [[0, 1, 2, 3], [0, 2, 1, 3], [0, 3, 1, 2]];
    let local_best = |v: u32, pieces: &[(u32, Piece)]| {
        let score = |p: &[usize; 4]| {
            parallel(v, pieces[p[0]].1, pieces[p[1]].1)
                + parallel(v, pieces[p[2]].1, pieces[p[3]].1)
        };
        PAIRINGS.iter().max_by(|x, y| score(x).total_cmp(&score(y))).copied().unwrap_or(PAIRINGS[0])
    };
    // Votes for pairs of strips.
    let mut votes: FxHashMap<(usize, usize), u32> = FxHashMap::default();
    let pair = |a: usize, b: usize| (a.min(b), a.max(b));
    for &(v, first, end) in &groups {
        let pieces = &node_pieces[first..end];
        if pieces.len() == 4 {
            let p = local_best(v, pieces);
            let s = |k: usize| strip[first + p[k]];
            *votes.entry(pair(s(0), s(1))).or_insert(0) += 1;
            *votes.entry(pair(s(2), s(3))).or_insert(0) += 1;
        }
    }
    // (vertex, piece) → the vertex id that piece uses.
    let mut use_id: FxHashMap<(u32, Piece), u32> = FxHashMap::default();
    for &(v, first, end) in &groups {
        let pieces = &node_pieces[first..end];
        // The sheet of each piece.
        let sheet_of: Vec<usize> = if pieces.len() == 4 {
            let s = |k: usize| strip[first + k];
            let vote = |a: usize, b: usize| votes.get(&pair(s(a), s(b))).copied().unwrap_or(0);
            let local = local_best(v, pieces);
            let best = PAIRINGS
                .iter()
                .max_by_key(|p| (vote(p[0], p[1]) + vote(p[2], p[3]), **p == local))
                .copied()
                .unwrap_or(local);
            let mut out = vec![1; 4];
            out[best[0]] = 0;
            out[best[1]] = 0;
            // Sheet 0 keeps the id: the sheet of the strip first in order.
            let first_strip = (0..4).min_by_key(|&k| s(k)).unwrap_or(0);
            if out[first_strip] == 1 {
                out.iter_mut().for_each(|x| *x = 1 - *x);
            }
            out
        } else if pieces.len() < 4 && curve_ends.contains(&v) {
            // A pinch point (or one on the box): its pieces are the folds where the two
            // sheets become one, and between them they close round it once the sheets'
            // copies of the next curve vertex are apart; one copy.
            vec![0; pieces.len()]
        } else {
            let mut firsts: Vec<Piece> = Vec::new();
            pieces
                .iter()
                .map(|&(_, b)| match firsts.iter().position(|&f| parallel(v, f, b) > 0.8) {
                    Some(k) => k,
                    None => {
                        firsts.push(b);
                        firsts.len() - 1
                    }
                })
                .collect()
        };
        // Copies in the order of the sheets' first pieces; sheet 0 first (it keeps `v`).
        let mut ids: Vec<Option<u32>> = vec![None; sheet_of.iter().max().map_or(0, |m| m + 1)];
        let order = (0..pieces.len())
            .filter(|&k| sheet_of[k] == 0)
            .chain((0..pieces.len()).filter(|&k| sheet_of[k] != 0));
        for k in order {
            let (sheet, piece) = (sheet_of[k], pieces[k].1);
            let id = *ids[sheet].get_or_insert_with(|| {
                let n = piece_normal[&(v, piece)];
                if sheet == 0 {
                    normals[v as usize] = n;
                    v
                } else {
                    positions.push(positions[v as usize]);
                    normals.push(n);
                    positions.len() as u32 - 1
                }
            });
            use_id.insert((v, piece), id);
        }
    }
    for (t, pieces) in triangles.iter_mut().zip(piece_of) {
        for (v, &piece) in t.iter_mut().zip(pieces) {
            if let Some(&id) = use_id.get(&(*v, piece)) {
                *v = id;
            }
        }
    }
}

/// A sheet piece round a curve vertex: its band, and which of that band's fans round the
/// vertex it is (in the order of their first triangles).
type Piece = (u32, u32);

/// The sheet piece of each corner of each band triangle at a curve vertex (`(u32::MAX, 0)` at
/// marching-cubes vertices): the fans of triangles round the vertex that meet across edges
/// off the curves.
///
/// A band is not a sheet piece everywhere. Along a crossing between two pinch points (the
/// cross-cap) the trace of the zone's boundary is one loop that runs along the curve four
/// times, folding round each pinch point, so one band holds all four pieces of every curve
/// vertex; round the Whitney umbrella's pinch point each band holds the two pieces that fold
/// into one there. Told apart by band alone, those vertices were not split at all. The
/// curve edges cut the triangles round a vertex into its pieces: four where two sheets
/// cross, one per fold at a pinch point (where the sheets do become one).
fn sheet_pieces(
    triangles: &[[u32; 3]],
    band_of: &[u32],
    curve_edges: &[[u32; 2]],
    n_mc: u32,
) -> Vec<[Piece; 3]> {
    let curve: FxHashSet<[u32; 2]> =
        curve_edges.iter().map(|&[a, b]| [a.min(b) + n_mc, a.max(b) + n_mc]).collect();
    // Per curve vertex, its corners in triangle order.
    let mut corners: FxHashMap<u32, Vec<(usize, usize)>> = FxHashMap::default();
    for (k, t) in triangles.iter().enumerate() {
        for (i, &v) in t.iter().enumerate() {
            if v >= n_mc {
                corners.entry(v).or_default().push((k, i));
            }
        }
    }
    let mut out = vec![[(u32::MAX, 0); 3]; triangles.len()];
    let mut vertices: Vec<u32> = corners.keys().copied().collect();
    vertices.sort_unstable();
    for v in vertices {
        let list = &corners[&v];
        // Union-find over the corners: joined across an edge (v, x) off the curves.
        let mut parent: Vec<usize> = (0..list.len()).collect();
        fn root(parent: &mut [usize], mut a: usize) -> usize {
            while parent[a] != a {
                parent[a] = parent[parent[a]];
                a = parent[a];
            }
            a
        }
        let mut first_at: FxHashMap<(u32, u32), usize> = FxHashMap::default();
        for (c, &(k, i)) in list.iter().enumerate() {
            let t = triangles[k];
            for x in [t[(i + 1) % 3], t[(i + 2) % 3]] {
                if curve.contains(&[v.min(x), v.max(x)]) {
                    continue;
                }
                match first_at.get(&(x, band_of[k])) {
                    Some(&d) => {
                        let (ra, rb) = (root(&mut parent, c), root(&mut parent, d));
                        parent[ra.max(rb)] = ra.min(rb);
                    }
                    None => {
                        first_at.insert((x, band_of[k]), c);
                    }
                }
            }
        }
        // Number each band's fans in the order of their first corners.
        let mut number: FxHashMap<usize, u32> = FxHashMap::default();
        let mut count: FxHashMap<u32, u32> = FxHashMap::default();
        for (c, &(k, i)) in list.iter().enumerate() {
            let r = root(&mut parent, c);
            let band = band_of[k];
            let sub = *number.entry(r).or_insert_with(|| {
                let n = count.entry(band).or_insert(0);
                *n += 1;
                *n - 1
            });
            out[k][i] = (band, sub);
        }
    }
    out
}
