//! The continuation polygonizer of the dissertation's chapter 3: start on the surface and
//! propagate cubes across the faces the surface crosses, so that only cells near the surface
//! are ever evaluated. Its cost grows with the surface's area, not the domain's volume.
//!
//! The lattice is the grid polygonizer's (cubes of side `cell` covering the domain), and the
//! cube variant polygonizes each cube with the same case table, decider and interior rules,
//! so for every component it reaches it makes the grid polygonizer's triangles. The
//! tetrahedral variant splits each cube into six tetrahedra (no ambiguity; more triangles).
//!
//! Evaluations: for a field with an exact gradient (as cheap as the value, or nearly) the
//! corners are evaluated with their gradients, and each edge vertex is placed by
//! [`refine_roots_with_gradients`](crate::refine::refine_roots_with_gradients): a Newton
//! step from the root of the edge's cubic model, about one evaluation per vertex, whose
//! gradient is the vertex's normal. Vertex positions then differ from the grid
//! polygonizer's (regula falsi from the corner values) by root finding alone, both well
//! within the tolerance. Other fields keep regula falsi and a gradient per vertex for
//! normals. Seeds are walked from along the lattice's axes (`Run::propagate_seeds`),
//! reading and keeping corner values, so a seed costs a few evaluations. On the hand at 128
//! samples: 7.02 evaluations per vertex before (corners 2.06, search 0.56, roots 3.40,
//! normals 1.00), 3.21 after (corners 1.98, search 0.10, roots 1.13, normals 0). A field
//! with colours (a coloured skeleton) gives each vertex its colour in the same evaluations
//! ([`Field::eval_grad_color_many`]), so the mesh comes out coloured and needs no painting
//! afterwards.
//!
//! Guarantees: each lattice corner is evaluated once (values are kept in sparse bricks) and
//! each edge root is found once and shared; a surface closed inside the domain comes out closed,
//! manifold and consistently oriented; the output does not depend on the thread count.
//!
//! Threads: each wave's new corners are evaluated in one parallel batch, and the wave is
//! then processed in lattice order on one thread, so cubes, vertices and triangles come in
//! the same order on any thread count; a value depends on its point alone, so the mesh is
//! the same, byte for byte. From seeds, components are also propagated several at once,
//! each on its thread's own lattice, and gathered in seed order (the `seeds` module says
//! why the mesh and the statistics are the one thread's). From the domain search,
//! components are propagated one after another. (An evaluation pass walking every component at once, for
//! larger batches where components are small, was tried: it made the same mesh but cost
//! more in lookups than it saved.)
//! With corner gradients, root finding overlaps propagation: each run hands its edge
//! vertices, a chunk at a time as they are made, to jobs on the pool (see `pipe`), so a
//! thread left idle by a serial propagation (the hand: one component) refines them
//! meanwhile; the chunks are a component's own, and each vertex is refined as it would be
//! afterwards, so the mesh is the same, byte for byte.
//!
//! Not guaranteed: components without
//! a seed are found (give seeds, or let the domain search look for them; it can miss
//! components smaller than its stride).

mod lattice;
mod pipe;
mod seeds;
pub mod tetra;

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use skelform_field::Field;
use skelform_field::grid::Grid;
use skelform_mesh::Mesh;

use crate::grid::cell::{CubeSink, case_of, crossing, polygonize_cube};
use crate::grid::cube::{CORNERS, EDGES, FACES};
use crate::grid::{GridVertex, Place, Placement, Slide, dir_vector, place_cells, place_vertices};
use crate::lattice::cubes::CubeLattice;
use crate::lattice::memory::vec_bytes;
use crate::lattice::propagate::{Cubes, Limits, Order, Stops, propagate};
use crate::lattice::search::CoarseSearch;
use crate::refine::{
    GradBracket, RootMethod, RootOptions, fill_from_faces, gradient_normals, unit_gradients,
};
use crate::{Error, LatticeOptions, Resolution};
use lattice::Lattice;
use pipe::{How, Job, Pipe};
use tetra::{TetraSink, polygonize_tetrahedra};

/// How each cube is polygonized.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Cells {
    /// The cube itself, with the grid polygonizer's table.
    #[default]
    Cubes,
    /// Six tetrahedra per cube.
    Tetrahedra,
}

/// Settings of the continuation polygonizer.
#[derive(Clone, Debug)]
pub struct Options {
    /// The lattice (propagation never leaves its domain), vertex placement, progress and
    /// threads. The lattice is the grid polygonizer's for the same domain and resolution,
    /// so a component comes out as the grid polygonizer makes it. Storage grows with the
    /// surface: its running account is held to `max_memory` as propagation goes (a run that
    /// reaches it stops with [`Error::MemoryLimit`]), and `max_cells` bounds it too.
    pub lattice: LatticeOptions,
    /// Points on or near the surface to start from, one or more per component. When empty,
    /// the domain is searched on a coarse lattice (see `search_stride`).
    pub seeds: Vec<DVec3>,
    /// Stride of the domain search, in cells.
    pub search_stride: usize,
    /// Cubes as the grid polygonizer does them, or six tetrahedra per cube.
    pub cells: Cells,
    /// How edge roots are found (bisection is the dissertation's; regula falsi needs fewer
    /// evaluations on smooth fields, and with a field that has an exact gradient it means
    /// the Newton step from the corners' values and gradients instead, see the module's
    /// documentation).
    pub root: RootMethod,
    /// Stop propagating after visiting this many cubes in all.
    pub max_cells: u64,
    /// Stop propagating this many cubes away from each component's starting cube, in every
    /// direction (the chapter's propagation limit for unbounded surfaces).
    pub limit: Option<u32>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            lattice: LatticeOptions {
                resolution: Resolution::Cell(1.0 / 64.0),
                ..LatticeOptions::default()
            },
            seeds: Vec::new(),
            search_stride: 4,
            cells: Cells::Cubes,
            root: RootMethod::RegulaFalsi,
            max_cells: 20_000_000,
            limit: None,
        }
    }
}

/// Why propagation stopped short of closing a surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(rename_all = "snake_case"))]
pub enum Stop {
    /// The surface reached the domain box; the mesh is open there.
    Domain,
    /// The cell budget (`max_cells`) ran out; the mesh is open where propagation stopped.
    Budget,
    /// The propagation limit was reached; the mesh is open there.
    Limit,
}

/// One component found, by the seed that started it.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Component {
    /// The seed (or, with no seeds, the coarse search point) it was found from.
    pub seed: DVec3,
    /// Where the search from the seed met the surface.
    pub start: DVec3,
    /// Cubes its propagation visited.
    pub cells: u64,
    /// Triangles it made.
    pub triangles: usize,
}

/// What happened to a seed that did not start a component.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(rename_all = "snake_case"))]
pub enum SeedNote {
    /// Its surface had been found already from an earlier seed (index given).
    SameComponent {
        /// The seed.
        seed: DVec3,
        /// The index of the earlier seed whose component it reached.
        as_seed: usize,
    },
    /// No surface was found from it within the domain.
    NoSurface {
        /// The seed.
        seed: DVec3,
    },
}

/// What a run did, for `--stats`.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Stats {
    /// Side of the cubes propagated, in the field's units (from the lattice options).
    pub cell: f64,
    /// Field evaluations at lattice corners (each corner once; with its gradient, counted as
    /// one, for a field with an exact gradient).
    pub corner_evaluations: u64,
    /// Field evaluations to find the surface from the seeds (the seeds' values and the
    /// lattice points walked, which corners then reuse) or by searching the domain.
    pub search_evaluations: u64,
    /// Field evaluations for root finding along crossed edges (each with its gradient for
    /// a field with an exact gradient, which then gives the normal too).
    pub refine_evaluations: u64,
    /// Field gradients taken for vertex normals alone (with corner gradients, only at the
    /// rare vertices inside a cell).
    pub normal_evaluations: u64,
    /// Cubes visited by propagation (the cost that grows with the surface's area, not the
    /// volume).
    pub cells_visited: u64,
    /// Corners whose value was NaN or infinite (treated as outside or inside).
    pub non_finite: u64,
    /// With tetrahedra: cubes where the six tetrahedra join the corners differently from
    /// the cube method (see [`tetra::disagrees_with_cube`]), typically where a wall or tube
    /// thinner than a cell's diagonal is cut through or pinched off. Where this is 0 every
    /// cube has the cube method's pieces; otherwise the topology may differ from the
    /// continuation (or grid) method's. Always 0 with cubes.
    pub tetra_disagreements: u64,
    /// The lowest corner of the first such cube, in lattice order of the propagation.
    pub first_disagreement: Option<DVec3>,
    /// The components meshed, each with the seed that reached it.
    pub components: Vec<Component>,
    /// Seeds that did not start a component, and why.
    pub seed_notes: Vec<SeedNote>,
    /// Why propagation stopped short of closing a surface (empty: every component closed).
    pub stops: Vec<Stop>,
    /// Vertices in the mesh.
    pub vertices: usize,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Wall time of finding the surface from the seeds or by searching the domain.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub search: Duration,
    /// Wall time of propagating cubes across the surface and polygonizing them.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub propagation: Duration,
    /// Wall time of root finding on the crossed edges. With corner gradients (a field with
    /// an exact gradient), most of it overlaps propagation (see `pipe`), and this is only
    /// what is left after it: the last chunks, the vertices inside cells and gathering the
    /// positions.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub refinement: Duration,
    /// Wall time of computing vertex normals.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub normals: Duration,
}

impl Stats {
    /// Every field evaluation the run made.
    pub fn evaluations(&self) -> u64 {
        self.corner_evaluations
            + self.search_evaluations
            + self.refine_evaluations
            + self.normal_evaluations
    }
}

/// Polygonizes the components of `field` (zero set, inside negative) that the seeds (or the
/// domain search) reach.
///
/// ```
/// use skelform_field::{Aabb, FnField, DVec3};
/// use skelform_polygonize::{LatticeOptions, Resolution};
/// use skelform_polygonize::continuation::{polygonize, Options};
/// let sphere = FnField(|p: DVec3| p.length() - 0.5);
/// let lattice = LatticeOptions { domain: Aabb::cube(1.0), resolution: Resolution::Cell(0.05), ..Default::default() };
/// let opts = Options { lattice, seeds: vec![DVec3::ZERO], ..Options::default() };
/// let (mesh, stats) = polygonize(&sphere, &opts).unwrap();
/// assert!(mesh.triangle_count() > 0);
/// assert_eq!(stats.components.len(), 1);
/// ```
pub fn polygonize(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    options.lattice.threads.install(|| polygonize_here(field, options))
}

/// What a run with `options` on `grid` holds before it finds the surface: the coarse search
/// (its points and a value each) when no seed is given; then what grows with the surface.
pub fn memory_need(grid: &Grid, options: &Options) -> crate::MemoryNeed {
    if options.seeds.is_empty() {
        crate::MemoryNeed::Search(CoarseSearch::need(grid, options.search_stride, 8))
    } else {
        crate::MemoryNeed::Surface
    }
}

/// [`polygonize`] on the current thread pool.
fn polygonize_here(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats), Error> {
    let grid = options.lattice.grid()?;
    let tolerance = options.lattice.tolerance;
    if tolerance.is_nan() || tolerance <= 0.0 || tolerance >= 1.0 {
        return Err(Error::BadOption(format!(
            "tolerance must be between 0 and 1 (got {tolerance})"
        )));
    }
    let mut run = Run::new(field, grid, options);
    crate::lattice::memory::refuse(memory_need(&grid, options), options.lattice.max_memory, &grid)?;
    if !options.seeds.is_empty() {
        return seeds::propagate(run)?.finish();
    }
    let t = Instant::now();
    let starts = search_domain(&mut run)?;
    run.starts_bytes = vec_bytes(&starts);
    run.stats.search = t.elapsed();

    let t = Instant::now();
    let near = run.surface_cubes_near(starts.iter().map(|s| s.2.point()));
    // The bisections that started a component, finished afterwards (see `Bisection`).
    let mut unfinished = Vec::new();
    rayon::scope(|s| {
        let spawn = pipe::spawner(s);
        for ((seed_index, seed, start), near) in starts.into_iter().zip(near) {
            let Some(cube) = near else {
                run.stats.seed_notes.push(SeedNote::NoSurface { seed });
                continue;
            };
            run.start_component(seed, seed_index, cube, start, &mut unfinished, &spawn)?;
        }
        Ok::<(), Error>(())
    })?;
    run.stats.propagation = t.elapsed();
    let t = Instant::now();
    let field = run.field;
    let finished: Vec<(DVec3, u64)> = unfinished.par_iter().map(|b| b.finish(field)).collect();
    for (c, (p, evals)) in run.stats.components.iter_mut().zip(finished) {
        c.start = p;
        run.stats.search_evaluations += evals;
    }
    run.stats.search += t.elapsed();
    run.stats.cells_visited = run.lattice.visited();
    run.finish()
}

/// The fewest points in a parallel batch of corners. A wave from one seed is small, so that
/// most of the hand's waves are one batch on one thread. 32 was tried: on one thread it
/// cost 2% more instructions on the hand (callgrind, 1.196 → 1.219 billion) and 10% more on
/// random-1000 at 256 samples (5.388 → 5.923 billion: the culling's per-cell groups get
/// small), and the two-thread gain could not be measured on the loaded machine.
const MIN_BATCH: usize = 128;

struct Run<'a> {
    field: &'a dyn Field,
    grid: Grid,
    cubes: CubeLattice,
    opts: &'a Options,
    /// Corner values (each evaluated once) and visited cubes.
    lattice: Lattice,
    /// Values at the two ends of each edge vertex's segment, recorded when it is made.
    ends: Vec<[f32; 2]>,
    vertices: Vec<GridVertex>,
    triangles: Vec<[u32; 3]>,
    stats: Stats,
    /// Bytes of the list of starts, held while the components are propagated.
    starts_bytes: u64,
    /// With corner gradients: the edge vertices waiting for root finding, and those placed
    /// already (see `pipe`).
    pipe: Pipe,
    /// Whether corners are evaluated with their gradients, for root finding from the
    /// segment ends' values and slopes ([`refine_roots_with_gradients`]) and normals from
    /// its gradients: for fields with an exact gradient (about as cheap as the value), with
    /// regula falsi and refinement on.
    gradients: bool,
}

impl<'a> Run<'a> {
    fn new(field: &'a dyn Field, grid: Grid, opts: &'a Options) -> Self {
        Run {
            field,
            grid,
            cubes: CubeLattice::new(grid),
            opts,
            lattice: Lattice::new(grid.dims, if opts.cells == Cells::Tetrahedra { 7 } else { 3 }),
            ends: Vec::new(),
            vertices: Vec::new(),
            triangles: Vec::new(),
            stats: Stats { cell: grid.cell, ..Stats::default() },
            starts_bytes: 0,
            pipe: Pipe::default(),
            gradients: field.has_exact_gradient()
                && opts.lattice.refine
                && matches!(opts.root, RootMethod::RegulaFalsi | RootMethod::Hermite),
        }
    }

    /// For each point, a cube the surface crosses: the one holding the point or, when the
    /// surface slips between its corners there, one of its 26 neighbours (the first in
    /// lattice order). The corners of all the points' cubes are evaluated in one batch.
    fn surface_cubes_near(&mut self, points: impl Iterator<Item = DVec3>) -> Vec<Option<[u32; 3]>> {
        let candidates: Vec<Vec<[u32; 3]>> = points
            .map(|p| {
                let c = self.cubes.cube_of_u32(p);
                std::iter::once(c).chain(self.cubes.around(c)).collect()
            })
            .collect();
        self.evaluate_corners(&candidates.concat());
        candidates
            .into_iter()
            .map(|cubes| {
                cubes.into_iter().find(|&k| {
                    let case = case_of(&self.cube_values(k));
                    case != 0 && case != 255
                })
            })
            .collect()
    }

    /// Evaluates the corners of these cubes that are not known yet, in parallel batches.
    ///
    /// The batches' size depends on the number of points only, never on the thread count:
    /// a value is its point's alone (the [`Field`] contract), and even a field whose batch
    /// values depended on the batch would then still give the same mesh on any thread count.
    /// Batches are small enough (a 16th of the points, at least [`MIN_BATCH`]) that a large wave is
    /// shared among the threads, and large enough that a field which sorts a batch by region
    /// (the skeletons cull elements by cell) keeps its advantage.
    fn evaluate_corners(&mut self, cubes: &[[u32; 3]]) {
        let mut todo: Vec<[u32; 3]> = Vec::new();
        for &b in cubes {
            for o in CORNERS {
                let p = [b[0] + o[0] as u32, b[1] + o[1] as u32, b[2] + o[2] as u32];
                if self.lattice.queue(p) {
                    todo.push(p);
                }
            }
        }
        self.stats.corner_evaluations += self.evaluate(&todo);
    }

    /// Evaluates these lattice points (queued, not known yet) in parallel batches and keeps
    /// their values (and gradients, when the run keeps them); returns how many.
    fn evaluate(&mut self, todo: &[[u32; 3]]) -> u64 {
        if todo.is_empty() {
            return 0;
        }
        let points: Vec<DVec3> = todo.iter().map(|&p| self.cubes.point(p)).collect();
        let mut out = vec![0.0; points.len()];
        let mut grads = vec![DVec3::ZERO; if self.gradients { points.len() } else { 0 }];
        let chunk = (points.len() / 16).clamp(MIN_BATCH, 1024);
        if self.gradients {
            out.par_chunks_mut(chunk)
                .zip(grads.par_chunks_mut(chunk))
                .zip(points.par_chunks(chunk))
                .for_each(|((o, g), p)| self.field.eval_grad_many(p, o, g));
        } else {
            out.par_chunks_mut(chunk)
                .zip(points.par_chunks(chunk))
                .for_each(|(o, p)| self.field.eval_many(p, o));
        }
        let track = self.lattice.tracking();
        for (k, (&p, v)) in todo.iter().zip(out).enumerate() {
            if track {
                self.lattice.note(p, !v.is_finite());
            }
            let v = if v.is_finite() {
                v.clamp(-f32::MAX as f64, f32::MAX as f64) as f32
            } else {
                self.stats.non_finite += 1;
                if v == f64::NEG_INFINITY { -f32::MAX } else { f32::MAX }
            };
            match grads.get(k) {
                Some(g) => self.lattice.set_value_grad(p, v, g.as_vec3().to_array()),
                None => self.lattice.set_value(p, v),
            }
        }
        points.len() as u64
    }

    /// Propagates a component from `cube`, found from seed `seed_index`, unless an earlier
    /// seed's component already holds it (then only noted), records it in the statistics,
    /// and keeps its start's bisection to be finished afterwards (see `Bisection`).
    fn start_component(
        &mut self,
        seed: DVec3,
        seed_index: usize,
        cube: [u32; 3],
        start: Bisection,
        unfinished: &mut Vec<Bisection>,
        spawn: &dyn Fn(Job<'a>),
    ) -> Result<(), Error> {
        if let Some(owner) = self.lattice.owner(cube) {
            self.stats.seed_notes.push(SeedNote::SameComponent { seed, as_seed: owner });
            return Ok(());
        }
        let before = (self.lattice.visited(), self.triangles.len());
        self.propagate(cube, seed_index, spawn)?;
        unfinished.push(start);
        self.stats.components.push(Component {
            seed,
            start: start.point(),
            cells: self.lattice.visited() - before.0,
            triangles: self.triangles.len() - before.1,
        });
        Ok(())
    }

    /// Walks the lattice from point `from` along the six axis directions together, a point
    /// at a time, to the first segment whose ends differ in sign (the lowest step; among
    /// those, the first of +x, −x, +y, −y, +z, −z). Returns a cube holding that segment (the
    /// surface crosses it, so propagation from it meshes the segment's component) and the
    /// bisection of the segment towards the surface; `None` when every direction reaches the
    /// domain's boundary first. Values already known are read, new ones are kept (with their
    /// gradients, as corners are): the points next to the surface are corners propagation
    /// needs anyway.
    fn walk(&mut self, from: [u32; 3]) -> Option<([u32; 3], Bisection)> {
        self.walk_many(&[from]).pop().flatten()
    }

    /// [`Run::walk`] from each of `froms` (its answer for each), the walks stepping together:
    /// each step's new points, of every walk, are one parallel batch. A walk's answer
    /// depends on the values along its axes alone, never on which of them were known, so it
    /// is the walk's own whatever the others. The seeds are now walked each on its own
    /// thread (see [`seeds`]), one walk per call; the batch stays for callers with several.
    fn walk_many(&mut self, froms: &[[u32; 3]]) -> Vec<Option<([u32; 3], Bisection)>> {
        struct Axes {
            last: [[u32; 3]; 6],
            open: [bool; 6],
            done: bool,
        }
        let dims = self.grid.dims;
        let mut walks: Vec<Axes> =
            froms.iter().map(|&f| Axes { last: [f; 6], open: [true; 6], done: false }).collect();
        let mut hits = vec![None; froms.len()];
        let mut todo = Vec::new();
        let mut steps: Vec<(usize, usize, [u32; 3])> = Vec::new();
        for &from in froms {
            if self.lattice.queue(from) {
                todo.push(from);
            }
        }
        loop {
            steps.clear();
            for (w, walk) in walks.iter_mut().enumerate().filter(|(_, w)| !w.done) {
                let before = steps.len();
                for d in 0..6 {
                    let (axis, down) = (d / 2, d % 2 == 1);
                    let p = walk.last[d];
                    if !walk.open[d]
                        || (down && p[axis] == 0)
                        || (!down && p[axis] as usize + 1 >= dims[axis])
                    {
                        walk.open[d] = false;
                        continue;
                    }
                    let mut q = p;
                    q[axis] = if down { p[axis] - 1 } else { p[axis] + 1 };
                    if self.lattice.queue(q) {
                        todo.push(q);
                    }
                    steps.push((w, d, q));
                }
                // Every direction at the domain's boundary: no crossing.
                walk.done = steps.len() == before;
            }
            if steps.is_empty() {
                return hits;
            }
            self.stats.search_evaluations += self.evaluate(&todo);
            todo.clear();
            // Each walk's directions in order; its first crossing ends it.
            for &(w, d, q) in &steps {
                if walks[w].done {
                    continue;
                }
                let p = walks[w].last[d];
                let (fp, fq) = (self.lattice.value(p), self.lattice.value(q));
                if (fp < 0.0) != (fq < 0.0) {
                    let axis = d / 2;
                    let lo = if d % 2 == 1 { q } else { p };
                    let mut cube = lo;
                    for (j, c) in cube.iter_mut().enumerate() {
                        if j != axis && *c as usize + 1 >= dims[j] {
                            *c -= 1;
                        }
                    }
                    let start = Bisection::new(self.cubes.point(p), fp as f64, self.cubes.point(q));
                    hits[w] = Some((cube, start));
                    walks[w].done = true;
                    continue;
                }
                walks[w].last[d] = q;
            }
        }
    }

    fn cube_values(&mut self, base: [u32; 3]) -> [f32; 8] {
        CORNERS.map(|c| {
            self.lattice.value([
                base[0] + c[0] as u32,
                base[1] + c[1] as u32,
                base[2] + c[2] as u32,
            ])
        })
    }

    /// Breadth-first propagation from one cube, in waves processed in lattice order; its
    /// stops are recorded in the statistics.
    fn propagate(
        &mut self,
        start: [u32; 3],
        seed_index: usize,
        spawn: &dyn Fn(Job<'a>),
    ) -> Result<(), Error> {
        let stops = self.propagate_with(start, seed_index, None, spawn)?;
        self.record_stops(stops);
        Ok(())
    }

    /// Records why a component stopped short of closing, each reason once, in the order
    /// first met.
    fn record_stops(&mut self, stops: Stops) {
        let hits = [
            (stops.domain, Stop::Domain),
            (stops.budget, Stop::Budget),
            (stops.limit, Stop::Limit),
        ];
        for (hit, stop) in hits {
            if hit && !self.stats.stops.contains(&stop) {
                self.stats.stops.push(stop);
            }
        }
    }

    /// [`Run::propagate`] returning its stops; with `shared`, one of several runs on their
    /// own threads (see [`seeds`]).
    fn propagate_with(
        &mut self,
        start: [u32; 3],
        seed_index: usize,
        shared: Option<(&seeds::Shared, usize)>,
        spawn: &dyn Fn(Job<'a>),
    ) -> Result<Stops, Error> {
        let limits = Limits {
            max_cells: self.opts.max_cells,
            limit: self.opts.limit,
            origin: start,
            max_memory: self.opts.lattice.max_memory,
            method: self.method(),
        };
        let (lattice, control) = (self.cubes, &self.opts.lattice.control);
        let mut walk = Walk { run: self, seed: seed_index, shared, abandoned: false, spawn };
        let stops = propagate(
            &mut walk,
            &lattice,
            [start],
            &limits,
            Order::Lattice,
            control,
            "propagating",
        );
        // The component's last vertices are its last chunk; a component propagated for
        // nothing, or a failed run, refines no more.
        match &stops {
            Ok(s) if !s.abandoned => self.hand_over(Some(spawn), true),
            _ => self.pipe.discard(),
        }
        stops
    }

    /// What refining a chunk needs (see `pipe`).
    fn how(&self) -> How<'a> {
        let roots = self.root_options();
        How {
            field: self.field,
            roots,
            normals: self.opts.lattice.normals,
            colors: self.field.has_colors() && roots.method != RootMethod::Hermite,
            control: &self.opts.lattice.control,
        }
    }

    /// Hands the edge vertices waiting over to root finding, in full chunks (with `all`, the
    /// rest too).
    fn hand_over(&mut self, spawn: Option<&dyn Fn(Job<'a>)>, all: bool) {
        let how = self.how();
        self.pipe.hand_over(how, spawn, all);
    }

    /// The method's name, for errors.
    fn method(&self) -> &'static str {
        match self.opts.cells {
            Cells::Cubes => "continuation",
            Cells::Tetrahedra => "tetra",
        }
    }

    /// Bytes held: the lattice's bricks, the starts, the vertices and triangles, and what placing the
    /// vertices will add (an `f64` position each, and the mesh's `f32` positions and
    /// normals).
    fn held(&self) -> u64 {
        let placed = (size_of::<DVec3>() + 2 * size_of::<[f32; 3]>()) as u64;
        self.lattice.bytes()
            + self.starts_bytes
            + vec_bytes(&self.ends)
            + vec_bytes(&self.vertices)
            + vec_bytes(&self.triangles)
            + self.pipe.bytes()
            + self.vertices.len() as u64 * placed
    }

    fn polygonize(&mut self, base: [u32; 3], v: &[f32; 8]) {
        let mut sink = RunSink { run: self, base, v: *v };
        match sink.run.opts.cells {
            Cells::Cubes => {
                polygonize_cube(v, &mut sink);
            }
            Cells::Tetrahedra => {
                polygonize_tetrahedra(v, &mut sink);
                if tetra::disagrees_with_cube(v) {
                    let stats = &mut self.stats;
                    stats.tetra_disagreements += 1;
                    if stats.first_disagreement.is_none() {
                        stats.first_disagreement = Some(self.cubes.point(base));
                    }
                }
            }
        }
    }

    /// How edge roots are found, from the options (both ways of finishing).
    fn root_options(&self) -> RootOptions {
        RootOptions {
            method: self.opts.root,
            tolerance: self.opts.lattice.tolerance,
            t_min: crate::grid::cell::T_MIN,
            ..RootOptions::default()
        }
    }

    /// The mesh of the placed vertices and the propagated triangles, with its counts in the
    /// statistics (both ways of finishing).
    fn into_mesh(mut self, positions: &[DVec3], normals: Vec<[f32; 3]>) -> (Mesh, Stats) {
        let mesh = Mesh {
            positions: positions.par_iter().map(|p| p.as_vec3().to_array()).collect(),
            normals,
            triangles: self.triangles,
            ..Mesh::default()
        };
        self.stats.vertices = mesh.vertex_count();
        self.stats.triangles = mesh.triangle_count();
        (mesh, self.stats)
    }

    fn finish(mut self) -> Result<(Mesh, Stats), Error> {
        if self.gradients {
            return self.finish_with_gradients();
        }
        let t = Instant::now();
        let how = Placement {
            refine: self.opts.lattice.refine,
            roots: self.root_options(),
            tolerance: self.opts.lattice.tolerance,
        };
        let ends = &self.ends;
        let (positions, evals) = place_vertices(
            self.field,
            &self.grid,
            &self.vertices,
            &self.triangles,
            |i| ends[i].map(f64::from),
            &how,
        );
        self.stats.refine_evaluations = evals;
        self.stats.refinement = t.elapsed();
        let t = Instant::now();
        let normals = if self.opts.lattice.normals && !self.triangles.is_empty() {
            let (n, evals) = gradient_normals(self.field, &positions, &self.triangles);
            self.stats.normal_evaluations = evals;
            n
        } else {
            Vec::new()
        };
        self.stats.normals = t.elapsed();
        Ok(self.into_mesh(&positions, normals))
    }
}

impl Run<'_> {
    /// [`Run::finish`] where the corners' gradients are known: the edge vertices were
    /// placed by root finding during propagation (see `pipe`), with their normals (and
    /// colours) from its evaluations; the few cell vertices are placed here
    /// (`grid::place_cells`) and take a gradient each, as in the other path.
    fn finish_with_gradients(mut self) -> Result<(Mesh, Stats), Error> {
        let t = Instant::now();
        if self.pipe.skipped() {
            return Err(Error::Cancelled);
        }
        let grid = self.grid;
        let how = self.how();
        let n = self.vertices.len();
        let want_normals = how.normals && !self.triangles.is_empty();
        let mut positions: Vec<DVec3> =
            self.vertices.par_iter().map(|v| v.position(&grid)).collect();
        let mut colors = vec![[0f32; 3]; if how.colors { n } else { 0 }];
        let mut normals = vec![[0f32; 3]; if want_normals { n } else { 0 }];
        let mut evals = 0;
        let mut placed = 0;
        for r in self.pipe.take() {
            for (k, &i) in r.ids.iter().enumerate() {
                let i = i as usize;
                positions[i] = r.positions[k];
                if want_normals {
                    normals[i] = r.normals[k];
                }
                if how.colors {
                    colors[i] = r.colors[k];
                }
            }
            evals += r.evals;
            placed += r.ids.len();
        }
        let cell: Vec<usize> =
            (0..n).filter(|&i| matches!(self.vertices[i].place, Place::Cell { .. })).collect();
        debug_assert_eq!(placed + cell.len(), n, "every edge vertex placed once");
        if !cell.is_empty() {
            evals += place_cells(
                self.field,
                &grid,
                &cell,
                |i| &self.vertices[i],
                &mut positions,
                &self.triangles,
                self.opts.lattice.tolerance,
            );
            let pts: Vec<DVec3> = cell.iter().map(|&i| positions[i]).collect();
            if !colors.is_empty() {
                let mut shades = vec![[0f32; 3]; pts.len()];
                if self.field.colors_many(&pts, &mut shades) {
                    for (&i, c) in cell.iter().zip(shades) {
                        colors[i] = c;
                    }
                } else {
                    colors.clear();
                }
            }
            if want_normals {
                let n = unit_gradients(self.field, &pts);
                self.stats.normal_evaluations = pts.len() as u64;
                for (&i, n) in cell.iter().zip(n) {
                    normals[i] = n;
                }
            }
        }
        self.stats.refine_evaluations = evals;
        self.stats.refinement = t.elapsed();
        let t = Instant::now();
        if want_normals {
            fill_from_faces(&mut normals, &positions, &self.triangles);
        }
        self.stats.normals = t.elapsed();
        let (mut mesh, stats) = self.into_mesh(&positions, normals);
        mesh.colors = colors;
        Ok((mesh, stats))
    }
}

/// One component's propagation: cubes it visits are marked with its seed.
struct Walk<'r, 'a, 's> {
    run: &'r mut Run<'a>,
    seed: usize,
    /// With components propagated on several threads: what the threads share (the cubes'
    /// claims, the counts for memory and progress), and this thread's number.
    shared: Option<(&'s seeds::Shared, usize)>,
    /// A cube of the wave was claimed by an earlier seed's component: this one is the same
    /// component, propagated by that seed.
    abandoned: bool,
    /// Hands a chunk of edge vertices to root finding on the pool (see `pipe`).
    spawn: &'s dyn Fn(Job<'a>),
}

impl Cubes for Walk<'_, '_, '_> {
    fn prepare(&mut self, wave: &[[u32; 3]]) {
        if let Some((shared, _)) = self.shared
            && !shared.claim(wave, self.seed)
        {
            self.abandoned = true;
            return;
        }
        // The last wave's vertices, in full chunks, go to root finding before this wave's
        // corners are evaluated, so that an idle thread takes them up.
        self.run.hand_over(Some(self.spawn), false);
        self.run.evaluate_corners(wave);
    }

    fn abandoned(&self) -> bool {
        self.abandoned
    }

    fn process(&mut self, base: [u32; 3]) -> u8 {
        let v = self.run.cube_values(base);
        let case = case_of(&v);
        if case == 0 || case == 255 {
            return 0;
        }
        self.run.polygonize(base, &v);
        crossed_faces(&v)
    }

    fn is_visited(&mut self, cube: [u32; 3]) -> bool {
        self.run.lattice.owner(cube).is_some()
    }

    fn visit(&mut self, cube: [u32; 3]) {
        self.run.lattice.visit(cube, self.seed);
    }

    fn visited(&self) -> u64 {
        self.run.lattice.visited()
    }

    fn done(&self) -> u64 {
        match self.shared {
            Some((shared, _)) => shared.cubes_claimed(),
            None => self.run.lattice.visited(),
        }
    }

    fn held(&self) -> u64 {
        match self.shared {
            Some((shared, me)) => self.run.held() + shared.held_by_others(me),
            None => self.run.held(),
        }
    }
}

/// The faces of a cube with corner values `v` that the surface crosses (corners of both
/// signs), bit `f` for face `f`.
fn crossed_faces(v: &[f32; 8]) -> u8 {
    let mut faces = 0;
    for (f, q) in FACES.iter().enumerate() {
        let inside = q.iter().filter(|&&c| v[c] < 0.0).count();
        if inside != 0 && inside != 4 {
            faces |= 1 << f;
        }
    }
    faces
}

/// The run's side of the cube and tetrahedron sinks: vertices keyed by lattice segment.
struct RunSink<'r, 'a> {
    run: &'r mut Run<'a>,
    base: [u32; 3],
    v: [f32; 8],
}

impl RunSink<'_, '_> {
    fn segment(&mut self, c0: usize, c1: usize, t: f64, ends: [f32; 2]) -> u32 {
        let o = CORNERS[c0];
        let lo =
            [self.base[0] + o[0] as u32, self.base[1] + o[1] as u32, self.base[2] + o[2] as u32];
        let dir = (c1 ^ c0) as u8;
        let Run { lattice, vertices, ends: all_ends, .. } = &mut *self.run;
        let mut made = false;
        let id = lattice.edge_vertex(lo, dir, || {
            made = true;
            vertices.push(GridVertex { base: lo, place: Place::Edge { dir, t } });
            all_ends.push(ends);
            vertices.len() as u32 - 1
        });
        if made && self.run.gradients {
            // Its bracket is final: the corners' values and gradients are known.
            let run = &mut *self.run;
            let d = dir_vector(dir);
            let hi = [lo[0] + d[0], lo[1] + d[1], lo[2] + d[2]];
            let grid = run.grid;
            let at = |p: [u32; 3]| grid.point(p[0] as usize, p[1] as usize, p[2] as usize);
            let as_d = |g: [f32; 3]| DVec3::from_array(g.map(f64::from));
            let bracket = GradBracket {
                p0: at(lo),
                p1: at(hi),
                f0: f64::from(ends[0]),
                f1: f64::from(ends[1]),
                g0: as_d(run.lattice.grad(lo)),
                g1: as_d(run.lattice.grad(hi)),
                t,
                grad: DVec3::ZERO,
            };
            run.pipe.push(id, bracket);
        }
        id
    }
}

impl CubeSink for RunSink<'_, '_> {
    fn edge_vertex(&mut self, e: usize, ends: [f32; 2]) -> u32 {
        let [c0, c1] = EDGES[e];
        self.segment(c0, c1, crossing(ends[0], ends[1]), ends)
    }

    fn cell_vertex(&mut self, offset: [f64; 3], slide: Slide) -> u32 {
        self.run.ends.push([0.0; 2]);
        self.run.vertices.push(GridVertex { base: self.base, place: Place::cell(offset, slide) });
        self.run.vertices.len() as u32 - 1
    }

    fn triangle(&mut self, t: [u32; 3]) {
        self.run.triangles.push(t);
    }
}

impl TetraSink for RunSink<'_, '_> {
    fn segment_vertex(&mut self, c0: usize, c1: usize, t: f64) -> u32 {
        self.segment(c0, c1, t, [self.v[c0], self.v[c1]])
    }

    fn triangle(&mut self, t: [u32; 3]) {
        self.run.triangles.push(t);
    }
}

/// The 26 directions to the neighbours of a lattice point, axes first.
fn directions() -> Vec<DVec3> {
    let mut d: Vec<DVec3> = Vec::new();
    for x in -1..=1 {
        for y in -1..=1 {
            for z in -1..=1 {
                if (x, y, z) != (0, 0, 0) {
                    d.push(DVec3::new(x as f64, y as f64, z as f64));
                }
            }
        }
    }
    d.sort_by_key(|v| (v.x.abs() + v.y.abs() + v.z.abs()) as i32);
    d
}

/// Marches out from `seed` in 26 directions, a cell at a time, to the first sign change
/// within the domain, and bisects it to the surface. Returns the point (if any) and the
/// evaluations made.
fn search_from(
    field: &dyn Field,
    grid: &Grid,
    cubes: &CubeLattice,
    seed: DVec3,
) -> Result<(Option<Bisection>, u64), Error> {
    let f0 = field.eval(seed);
    let mut evals = 1;
    if !f0.is_finite() {
        return Err(Error::BadSeed {
            seed: seed.to_array(),
            why: format!("the field is {f0} there"),
        });
    }
    if f0 == 0.0 {
        return Ok((Some(Bisection::at(seed)), evals));
    }
    let bounds = grid.bounds();
    let h = grid.cell;
    let longest = bounds.size().max_element();
    let steps = (longest / h).ceil() as usize + 1;
    // Nearest crossing first: walk all directions outward together, a batch of steps at a time.
    let dirs = directions();
    // The value one step back along each direction (the seed's at first): where the sign
    // changes, the bisection starts from it without evaluating it again.
    let mut back = vec![f0; dirs.len()];
    let mut reach = 1usize;
    while reach <= steps {
        let upto = (reach * 2).min(steps);
        let mut pts = Vec::new();
        let mut which = Vec::new();
        for s in reach..=upto {
            for (d, dir) in dirs.iter().enumerate() {
                let p = seed + *dir * (h * s as f64);
                if bounds.contains(p) {
                    pts.push(p);
                    which.push((s, d));
                }
            }
        }
        if pts.is_empty() {
            break;
        }
        let mut vals = vec![0.0; pts.len()];
        field.eval_many(&pts, &mut vals);
        evals += pts.len() as u64;
        if let Some(n) =
            (0..pts.len()).find(|&n| vals[n].is_finite() && (vals[n] < 0.0) != (f0 < 0.0))
        {
            let (s, d) = which[n];
            let prev = seed + dirs[d] * (h * (s - 1) as f64);
            // A domain box is convex, so the step before a point in it is in it too, and was
            // evaluated: in this batch, or last in the one before.
            let fp = if s > reach {
                match (0..n).rev().find(|&m| which[m] == (s - 1, d)) {
                    Some(m) => vals[m],
                    None => {
                        // Only if rounding put the step just outside the box.
                        evals += 1;
                        field.eval(prev)
                    }
                }
            } else {
                back[d]
            };
            let (p, e) = Bisection::new(prev, fp, pts[n]).to_cube(field, cubes);
            return Ok((Some(p), evals + e));
        }
        for (&(s, d), &v) in which.iter().zip(&vals) {
            if s == upto {
                back[d] = v;
            }
        }
        reach = upto + 1;
    }
    Ok((None, evals))
}

/// The bisection of a segment from `a` (value `fa`) to `b` (opposite sign) towards a point
/// on the surface, [`Bisection::STEPS`] halvings in all (a small fraction of a cell).
///
/// Propagation needs only the cube that point is in, and most seeds lead to a component
/// found already: so the halving stops as soon as both ends lie in one cube
/// ([`Bisection::to_cube`]), and only the seeds that start a component finish it
/// ([`Bisection::finish`]) for the point their statistics report. The cube is the finished
/// point's (a cube holds every point between two of its points, and halving never leaves
/// that range), and finishing takes the very halvings an uninterrupted bisection takes, so
/// the mesh and the statistics' points are what bisecting at once to the end gives, with
/// fewer evaluations.
#[derive(Clone, Copy, Debug)]
struct Bisection {
    a: DVec3,
    b: DVec3,
    /// Whether `a` is inside (`f < 0`).
    inside_a: bool,
    /// Halvings done.
    done: u64,
}

impl Bisection {
    /// Halvings in all.
    const STEPS: u64 = 20;

    fn new(a: DVec3, fa: f64, b: DVec3) -> Self {
        Bisection { a, b, inside_a: fa < 0.0, done: 0 }
    }

    /// A point on the surface itself: nothing to halve.
    fn at(p: DVec3) -> Self {
        Bisection { a: p, b: p, inside_a: true, done: Self::STEPS }
    }

    /// The midpoint: the answer once finished, and before that a point of the finished
    /// answer's cube (after [`Bisection::to_cube`]).
    fn point(&self) -> DVec3 {
        (self.a + self.b) * 0.5
    }

    fn halve(&mut self, field: &dyn Field) {
        let m = self.point();
        if (field.eval(m) < 0.0) == self.inside_a {
            self.a = m;
        } else {
            self.b = m;
        }
        self.done += 1;
    }

    /// Halves until both ends are in one cube of `cubes` (or all halvings are done); returns
    /// itself and the evaluations made.
    fn to_cube(mut self, field: &dyn Field, cubes: &CubeLattice) -> (Self, u64) {
        let start = self.done;
        while self.done < Self::STEPS && cubes.cube_of(self.a) != cubes.cube_of(self.b) {
            self.halve(field);
        }
        (self, self.done - start)
    }

    /// The remaining halvings: the point and the evaluations made.
    fn finish(&self, field: &dyn Field) -> (DVec3, u64) {
        let mut b = *self;
        while b.done < Self::STEPS {
            b.halve(field);
        }
        (b.point(), Self::STEPS - self.done)
    }
}

/// With no seeds: sample a coarse lattice and start from every coarse edge with a sign
/// change (each component at least `search_stride` cells across is found). The crossings
/// are bisected in parallel and kept in the coarse edges' order.
fn search_domain(run: &mut Run) -> Result<Vec<(usize, DVec3, Bisection)>, Error> {
    let search = CoarseSearch::new(&run.grid, run.opts.search_stride);
    let pts = &search.points;
    let field = run.field;
    let mut vals = vec![0.0; pts.len()];
    vals.par_chunks_mut(1024).zip(pts.par_chunks(1024)).for_each(|(o, p)| field.eval_many(p, o));
    run.stats.search_evaluations += pts.len() as u64;
    let mut crossed = Vec::new();
    search.edges(|a, b| {
        if vals[a].is_finite() && vals[b].is_finite() && (vals[a] < 0.0) != (vals[b] < 0.0) {
            crossed.push((a, b));
        }
    });
    if crossed.is_empty() {
        return Err(Error::NoSurfaceFound { samples: pts.len() as u64, stride: search.stride });
    }
    let cubes = run.cubes;
    let found: Vec<(Bisection, u64)> = crossed
        .par_iter()
        .map(|&(a, b)| Bisection::new(pts[a], vals[a], pts[b]).to_cube(field, &cubes))
        .collect();
    run.stats.search_evaluations += found.iter().map(|f| f.1).sum::<u64>();
    Ok(crossed.iter().zip(found).enumerate().map(|(i, (&(a, _), (p, _)))| (i, pts[a], p)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stopping at the cube and finishing later gives the uninterrupted bisection's point,
    /// in that point's cube, with the halvings split between the two.
    #[test]
    fn a_bisection_stopped_at_its_cube_finishes_where_an_uninterrupted_one_ends() {
        let sphere = skelform_field::FnField(|p: DVec3| p.length() - 0.4321);
        let grid = Grid::with_cell(&skelform_field::Aabb::cube(1.0), 0.05).unwrap();
        let cubes = CubeLattice::new(grid);
        for dir in directions() {
            let (a, b) = (dir * 0.41, dir * 0.41 + dir * 0.05);
            let whole = Bisection::new(a, sphere.eval(a), b).finish(&sphere);
            let (part, first) = Bisection::new(a, sphere.eval(a), b).to_cube(&sphere, &cubes);
            let (p, rest) = part.finish(&sphere);
            assert_eq!(p, whole.0);
            assert_eq!(first + rest, Bisection::STEPS);
            assert!(first < Bisection::STEPS);
            assert_eq!(cubes.cube_of(part.point()), cubes.cube_of(p));
        }
    }
}
