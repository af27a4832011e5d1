//! Incremental re-meshing with the grid method: after an edit that changes the field only
//! inside some boxes, redo only the lattice there and splice the mesh.
//!
//! [`polygonize`] is [`grid::polygonize`] that also returns a [`GridState`]: the sampled
//! volume, the extraction's vertices (by lattice edge), their placed positions and their
//! gradient normals. [`GridState::update`] is then given the edited field and the boxes
//! outside which the field did not change (bit for bit: the caller's promise, e.g.
//! `SkeletonField::changes_since` in skelform-skeleton for skeletons), and
//!
//! 1. samples again only the lattice points in those boxes (grown by a rounding guard);
//! 2. runs marching cubes again over the extraction slabs whose sample layers hold a point
//!    within a cell of them (a slab reads its own layers and nothing else; the changed
//!    samples are among those points) and splices them between the
//!    last run's slabs below and above, which gives the fresh run's vertices and triangles,
//!    in its order, since the volume is now the fresh run's volume;
//! 3. takes each vertex whose lattice edge has both ends farther than a cell from the boxes
//!    from the last run (the edge misses them: root finding along it evaluated the field only
//!    where it did not change, from the same end samples, so it would find the same root),
//!    and places the
//!    others (root finding, gradient normals) as a fresh run does.
//!
//! Why the result is the fresh run's mesh, bit for bit: the samples are the same (the
//! unchanged ones because the field is unchanged there, the others because they are
//! computed as [`skelform_field::grid::sample`] computes them); extraction reads nothing but
//! the samples; root finding and gradients are per vertex, whatever else is in the batch.
//! Two things are not per vertex and are redone whole: the few vertices inside a cell
//! (tunnels), whose Newton projection stops when a whole batch has converged, and the
//! face-normal fallback where the gradient vanishes, which reads the neighbouring
//! triangles. The tests compare updates with fresh runs over random edits.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;
use skelform_field::grid::{Grid, Relative, Volume, resample_points, sample};
use skelform_field::{Aabb, Field};
use skelform_mesh::Mesh;

use crate::Error;
use crate::grid::extract::{SLAB, SlabCounts, extract_slabs, slab_count};
use crate::grid::{self, GridVertex, Options, Place, Stats};
use crate::refine::{
    Bracket, RootOptions, fill_from_faces, refine_roots, refine_roots_until, unit_gradients,
};

/// Cells of margin around a changed box for the points sampled again: the field changed only
/// inside the box, so only a guard against rounding in the conversion to indices (the boxes
/// are grown by a hair already).
const SAMPLE_MARGIN: f64 = 0.01;

/// Cells of margin around a changed box for the vertices placed again: root finding along a
/// lattice edge evaluates the field between its ends, so a vertex is taken from the last run
/// only when its edge misses every box, which holds when an end lies farther than a cell
/// from each (an edge spans at most a cell along each axis), plus the rounding guard.
const EDGE_MARGIN: f64 = 1.0 + SAMPLE_MARGIN;

/// What the last grid run keeps for the next (see the module documentation).
#[derive(Clone, Debug)]
pub struct GridState {
    volume: Volume,
    /// What each extraction slab made, in slab order (the mesh's vertices and triangles are
    /// the slabs' one after the other).
    slabs: Vec<Slab>,
    /// The vertices of all slabs.
    vertex_count: usize,
    /// The vertices inside a cell (placed again by every run), ascending.
    cells: Vec<u32>,
    /// How the last update's vertices relate to the run's before it (`None` after a run from
    /// scratch).
    map: Option<VertexMap>,
    /// False while an update replaces vertices: one that failed there leaves a state the
    /// next update must not trust.
    whole: bool,
    /// The changed boxes of updates that were cancelled before they replaced any vertex.
    /// Such an update leaves, within these boxes, samples of a field newer than the
    /// vertices; everywhere else the state is the last finished run's. The next update
    /// samples and places again within them as well as within its own boxes, so a
    /// cancelled edit (a newer one came) does not cost the next a run from scratch.
    pending: Vec<Aabb>,
    refine: bool,
    tolerance: f64,
    normals: bool,
}

/// What one extraction slab made: its vertices (lattice places, positions, gradients) and
/// triangles, which number the vertices from the slab's first (those past its own are the
/// next slab's first ones: the layer they share).
#[derive(Clone, Debug)]
struct Slab {
    counts: SlabCounts,
    vertices: Vec<GridVertex>,
    positions: Vec<DVec3>,
    /// Unit gradient normals, zero where the gradient vanished (empty without normals).
    gradients: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

/// How an update's vertices relate to the last run's: the vertices below `start` kept their
/// numbers, those from `start + added` on are the last run's from `start + removed` on, and
/// `kept` lists the vertices of the range between that were taken from the last run, as
/// (new number, old number), ascending.
#[derive(Clone, Debug, Default)]
struct VertexMap {
    start: usize,
    removed: usize,
    added: usize,
    kept: Vec<(u32, u32)>,
}

/// What an update reused and what it redid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reuse {
    /// Lattice points sampled again.
    pub resampled: u64,
    /// Vertices taken from the last run.
    pub reused_vertices: usize,
    /// Vertices placed again (root finding, projection, normals).
    pub placed_vertices: usize,
    /// Whether the update had to run from scratch (the lattice or the placement settings
    /// differed from the state's).
    pub full: bool,
}

/// The lattice the options describe, with the memory check of a held volume.
fn lattice(options: &Options) -> Result<Grid, Error> {
    let lattice = &options.lattice;
    let grid = lattice.grid()?;
    let needed = grid::memory_needed(&grid, false);
    if needed > lattice.max_memory {
        return Err(Error::TooMuchMemory { needed, limit: lattice.max_memory, dims: grid.dims });
    }
    Ok(grid)
}

/// [`grid::polygonize`], keeping what an [`GridState::update`] needs. The mesh and
/// statistics are the same (the volume is always held whole, never streamed, which makes the
/// same mesh).
pub fn polygonize(field: &dyn Field, options: &Options) -> Result<(Mesh, Stats, GridState), Error> {
    options.lattice.threads.install(|| {
        let grid = lattice(options)?;
        let lattice = &options.lattice;
        let mut stats = Stats { grid_dims: grid.dims, cell: grid.cell, ..Stats::default() };
        let t = Instant::now();
        let volume = sample(field, &grid, &lattice.control)?;
        stats.sampling = t.elapsed();
        stats.samples = grid.sample_count();
        stats.non_finite_samples = volume.non_finite;
        (stats.min_sample, stats.max_sample) = volume.value_range();
        let mut state = GridState {
            volume,
            slabs: Vec::new(),
            vertex_count: 0,
            cells: Vec::new(),
            map: None,
            whole: true,
            pending: Vec::new(),
            refine: lattice.refine,
            tolerance: lattice.tolerance,
            normals: lattice.normals,
        };
        let (mesh, _) = state.finish(field, options, &mut stats, None)?;
        Ok((mesh, stats, state))
    })
}

/// A lattice edge vertex's key: its base point and direction.
fn key(v: &GridVertex) -> Option<([u32; 3], u8)> {
    match v.place {
        Place::Edge { dir, .. } => Some((v.base, dir)),
        Place::Cell { .. } => None,
    }
}

impl GridState {
    /// The lattice the state was sampled on.
    pub fn grid(&self) -> &Grid {
        &self.volume.grid
    }

    /// After an update that re-meshed only the changed part: the number, in the run before,
    /// of this run's vertex `i` when it was taken from that run, at the same place and with
    /// the same normal, on a lattice edge that misses every changed box (so anything
    /// computed from its position alone, outside those boxes, is unchanged too); `None` for
    /// a vertex placed again, and for every vertex after a run from scratch.
    pub fn previous_vertex(&self, i: usize) -> Option<usize> {
        let m = self.map.as_ref()?;
        if i >= self.vertex_count || self.cells.binary_search(&(i as u32)).is_ok() {
            return None;
        }
        if i < m.start {
            Some(i)
        } else if i >= m.start + m.added {
            Some(i - m.added + m.removed)
        } else {
            let k = m.kept.binary_search_by_key(&(i as u32), |&(new, _)| new).ok()?;
            Some(m.kept[k].1 as usize)
        }
    }

    /// Whether a run with `options` can update this state (the same lattice, root finding
    /// and normals, and no update that failed or was cancelled since the last good run);
    /// [`GridState::update`] runs from scratch otherwise.
    pub fn matches(&self, options: &Options) -> bool {
        let l = &options.lattice;
        self.whole
            && options.lattice.grid().is_ok_and(|g| g == self.volume.grid)
            && l.refine == self.refine
            && l.tolerance.to_bits() == self.tolerance.to_bits()
            && l.normals == self.normals
    }

    /// The mesh of `field` (the edited field), which must equal the field of the last run
    /// outside `changed`, bit for bit; the same mesh as [`grid::polygonize`] of `field`
    /// with `options`, bit for bit. Samples only near `changed` and places only the vertices
    /// there. Runs from scratch (and says so in [`Reuse::full`]) when the options do not
    /// [`match`](GridState::matches).
    pub fn update(
        &mut self,
        field: &dyn Field,
        options: &Options,
        changed: &[Aabb],
    ) -> Result<(Mesh, Stats, Reuse), Error> {
        if !self.matches(options) {
            let (mesh, stats, state) = polygonize(field, options)?;
            let placed = state.vertex_count;
            *self = state;
            let reuse = Reuse {
                resampled: stats.samples,
                placed_vertices: placed,
                full: true,
                ..Reuse::default()
            };
            return Ok((mesh, stats, reuse));
        }
        self.pending.extend_from_slice(changed);
        options.lattice.threads.install(|| {
            let grid = self.volume.grid;
            let mut stats = Stats { grid_dims: grid.dims, cell: grid.cell, ..Stats::default() };
            let t = Instant::now();
            let dirty = Dirty::new(&grid, &self.pending);
            let points = dirty.points();
            // Cancellable: the points are within the pending boxes, which the next update
            // samples again.
            stats.non_finite_samples =
                resample_points(field, &mut self.volume, &points, &options.lattice.control)?;
            stats.samples = points.len() as u64;
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for &n in &points {
                lo = lo.min(self.volume.values[n]);
                hi = hi.max(self.volume.values[n]);
            }
            (stats.min_sample, stats.max_sample) = (lo, hi);
            stats.sampling = t.elapsed();
            if options.lattice.control.is_cancelled() {
                return Err(Error::Cancelled);
            }
            let (mesh, reused) = self.finish(field, options, &mut stats, Some(&dirty))?;
            if mesh.is_empty() {
                // What an empty mesh's explanation reads: the range of every sample.
                (stats.min_sample, stats.max_sample) = self.volume.value_range();
            }
            self.pending.clear();
            let reuse = Reuse {
                resampled: stats.samples,
                reused_vertices: reused,
                placed_vertices: mesh.vertex_count() - reused,
                full: false,
            };
            Ok((mesh, stats, reuse))
        })
    }

    /// Extraction over the held volume, vertex placement (reusing the old vertices outside
    /// `dirty` when given), normals; the state takes the new vertices. Returns the mesh and
    /// how many vertices were reused.
    ///
    /// The state is held slab by slab, so an update replaces the slabs it extracted again
    /// and leaves the others where they are: what it does in proportion to the whole mesh is
    /// writing the mesh it returns (positions, normals, triangles renumbered).
    fn finish(
        &mut self,
        field: &dyn Field,
        options: &Options,
        stats: &mut Stats,
        dirty: Option<&Dirty>,
    ) -> Result<(Mesh, usize), Error> {
        let lattice = &options.lattice;
        let workspace = options.workspace.as_deref().unwrap_or(grid::Workspace::shared());
        let grid = self.volume.grid;
        let slab_total = slab_count(&grid);
        // The slabs to extract: all, or those whose sample layers hold a point near the
        // change (slab `s` reads layers `s·SLAB ..= (s + 1)·SLAB`). The others are the last
        // run's.
        let full = dirty.is_none() || self.slabs.len() != slab_total;
        let range = match dirty.map(Dirty::layers) {
            _ if full => 0..slab_total,
            None | Some(None) => 0..0,
            Some(Some((lo, hi))) => {
                lo.div_ceil(SLAB).saturating_sub(1)..(hi / SLAB + 1).min(slab_total)
            }
        };
        let t = Instant::now();
        let (new_vertices, new_triangles, counts) = extract_slabs::<GridVertex, _>(
            &grid,
            &self.volume.values,
            Relative,
            &lattice.control,
            workspace,
            range.clone(),
            Default::default(),
        )?;
        // The new slabs, each numbering its triangles from its own first vertex (a slab refers
        // to nothing below it; its references to the layer above land past its own vertices,
        // on the next slab's first ones, which is what they are in the held slabs too).
        let mut pieces = Vec::with_capacity(counts.len());
        let (mut vo, mut to) = (0, 0);
        for c in &counts {
            let first = vo as u32;
            pieces.push(Slab {
                counts: *c,
                vertices: new_vertices[vo..vo + c.vertices].to_vec(),
                positions: Vec::new(),
                gradients: Vec::new(),
                triangles: new_triangles[to..to + c.triangles]
                    .iter()
                    .map(|t| t.map(|i| i - first))
                    .collect(),
            });
            vo += c.vertices;
            to += c.triangles;
        }
        drop(new_triangles);
        // Where the range starts, and what it held.
        let v0: usize =
            self.slabs[..range.start.min(self.slabs.len())].iter().map(|s| s.counts.vertices).sum();
        let added = new_vertices.len();
        // From here on the slabs are being replaced: not to be trusted until done.
        self.whole = false;
        let old_pieces: Vec<Slab> = if full {
            self.slabs = pieces;
            Vec::new()
        } else {
            self.slabs.splice(range.clone(), pieces).collect()
        };
        let removed: usize = old_pieces.iter().map(|s| s.counts.vertices).sum();
        let v1 = v0 + removed;
        let shift = |i: u32| (i as i64 + added as i64 - removed as i64) as u32;
        // The first vertex of each slab, and the number of vertices.
        let mut starts = Vec::with_capacity(self.slabs.len() + 1);
        let mut n = 0;
        for s in &self.slabs {
            starts.push(n);
            n += s.counts.vertices;
        }
        starts.push(n);
        stats.extraction = t.elapsed();
        stats.ambiguous_faces = self.slabs.iter().map(|c| c.counts.ambiguous_faces).sum();
        stats.tunnels = self.slabs.iter().map(|c| c.counts.tunnels).sum();

        let t = Instant::now();
        let want_normals = lattice.normals;
        // The range's positions and gradients (the others are the held slabs'), by vertex
        // number from `v0`.
        let mut positions: Vec<DVec3> = new_vertices.iter().map(|v| v.position(&grid)).collect();
        let mut gradients = vec![[0f32; 3]; if want_normals { added } else { 0 }];
        // The range's vertices placed here, numbered from `v0`.
        let mut fresh: Vec<usize> = Vec::new();
        let mut reused = 0;
        // The vertices inside a cell: the last run's below and above the range (renumbered)
        // and the range's own, without a pass over every vertex.
        let old_cells = std::mem::take(&mut self.cells);
        let range_cells =
            (v0..).zip(&new_vertices).filter(|(_, v)| key(v).is_none()).map(|(i, _)| i);
        let cells: Vec<usize> = if full {
            range_cells.collect()
        } else {
            let below = old_cells.iter().take_while(|&&i| (i as usize) < v0).map(|&i| i as usize);
            let above = old_cells.iter().filter(|&&i| i as usize >= v1).map(|&i| shift(i) as usize);
            below.chain(range_cells).chain(above).collect()
        };
        let mut vertex_map = None;
        match dirty {
            _ if full => fresh.extend(0..added),
            None => unreachable!("a run without an old state extracts every slab"),
            Some(dirty) => {
                // Outside the range: the last run's vertices, in the same order.
                reused = n - added;
                let old: Vec<&GridVertex> = old_pieces.iter().flat_map(|s| &s.vertices).collect();
                let old_positions: Vec<&DVec3> =
                    old_pieces.iter().flat_map(|s| &s.positions).collect();
                let old_gradients: Vec<&[f32; 3]> =
                    old_pieces.iter().flat_map(|s| &s.gradients).collect();
                let inside = |p: [u32; 3]| dirty.near(p);
                let clean = |v: &GridVertex| match v.tip() {
                    Some(tip) => !inside(v.base) && !inside(tip),
                    None => false,
                };
                let old = &old;
                let mut kept: Vec<(u32, u32)> = Vec::new();
                let mut j = 0;
                let mut map: Option<rustc_hash::FxHashMap<([u32; 3], u8), usize>> = None;
                for (r, v) in new_vertices.iter().enumerate() {
                    if !clean(v) {
                        fresh.push(r);
                        continue;
                    }
                    let k = key(v);
                    // Clean edge vertices come in the same order in both runs (extraction
                    // numbers them in a fixed order of the lattice's edges): walk the old
                    // list alongside, skipping its vertices that are not clean.
                    let found = if let Some(m) = &map {
                        k.and_then(|k| m.get(&k).copied())
                    } else {
                        while j < old.len() && !clean(old[j]) {
                            j += 1;
                        }
                        if j < old.len() && key(old[j]) == k {
                            j += 1;
                            Some(j - 1)
                        } else {
                            // Not the expected order after all: look the rest up.
                            let m: rustc_hash::FxHashMap<_, _> = old
                                .iter()
                                .enumerate()
                                .filter(|(_, o)| clean(o))
                                .filter_map(|(n, o)| key(o).map(|k| (k, n)))
                                .collect();
                            let f = k.and_then(|k| m.get(&k).copied());
                            map = Some(m);
                            f
                        }
                    };
                    match found {
                        Some(o) => {
                            kept.push(((v0 + r) as u32, (v0 + o) as u32));
                            positions[r] = *old_positions[o];
                            if want_normals {
                                gradients[r] = *old_gradients[o];
                            }
                            reused += 1;
                        }
                        None => fresh.push(r),
                    }
                }
                vertex_map = Some(VertexMap { start: v0, removed, added, kept });
            }
        }
        drop(old_pieces);
        // The slab and place in it of vertex `i` outside the range.
        let slab_of = |i: usize| {
            let s = starts.partition_point(|&x| x <= i) - 1;
            (s, i - starts[s])
        };
        let in_range = |i: usize| (v0..v0 + added).contains(&i);

        // Every triangle, numbered over the whole mesh: the mesh's own, and what cell
        // placement and the face-normal fallback read.
        let triangles = gather(
            &self.slabs,
            |s| s.triangles.len(),
            |k, s, out| {
                let first = starts[k] as u32;
                for (o, t) in out.iter_mut().zip(&s.triangles) {
                    *o = t.map(|i| i + first);
                }
            },
        );
        // Every position, over the whole mesh, when something reads the positions around a
        // vertex (cell placement, the face-normal fallback): rare.
        let flat_positions = |range_positions: &[DVec3], slabs: &[Slab]| -> Vec<DVec3> {
            let mut all = Vec::with_capacity(n);
            for (s, slab) in slabs.iter().enumerate() {
                if range.contains(&s) {
                    if s == range.start {
                        all.extend_from_slice(range_positions);
                    }
                } else {
                    all.extend_from_slice(&slab.positions);
                }
            }
            all
        };

        // Root finding for the fresh edge vertices; every cell vertex is placed again, as a
        // fresh run places it (after the edge vertices: whether a ring moves depends on
        // their positions, and the second try's Newton steps stop per batch).
        if lattice.refine {
            let roots = RootOptions {
                tolerance: lattice.tolerance,
                t_min: grid::cell::T_MIN,
                ..RootOptions::default()
            };
            let at = |p: [u32; 3]| grid.point(p[0] as usize, p[1] as usize, p[2] as usize);
            let value =
                |p: [u32; 3]| self.volume.get(p[0] as usize, p[1] as usize, p[2] as usize) as f64;
            let edges: Vec<usize> =
                fresh.iter().copied().filter(|&r| key(&new_vertices[r]).is_some()).collect();
            let mut brackets: Vec<Bracket> = edges
                .iter()
                .map(|&r| {
                    let v = &new_vertices[r];
                    let (tip, t) = match (v.tip(), v.place) {
                        (Some(tip), Place::Edge { t, .. }) => (tip, t),
                        _ => unreachable!("edge vertices have a tip"),
                    };
                    Bracket { p0: at(v.base), p1: at(tip), f0: value(v.base), f1: value(tip), t }
                })
                .collect();
            stats.refine_evaluations = if dirty.is_none() {
                // A run from scratch may stop here: its state is dropped anyway.
                refine_roots_until(field, &mut brackets, &roots, &lattice.control)
                    .ok_or(Error::Cancelled)?
            } else {
                // An update goes on: it has begun to replace the slabs.
                refine_roots(field, &mut brackets, &roots)
            };
            for (&r, b) in edges.iter().zip(&brackets) {
                positions[r] = b.p0.lerp(b.p1, b.t);
            }
            if !cells.is_empty() {
                let mut all = flat_positions(&positions, &self.slabs);
                let slabs = &self.slabs;
                let record = |i: usize| -> &GridVertex {
                    if in_range(i) {
                        &new_vertices[i - v0]
                    } else {
                        let (s, k) = slab_of(i);
                        &slabs[s].vertices[k]
                    }
                };
                stats.refine_evaluations += grid::place_cells(
                    field,
                    &grid,
                    &cells,
                    record,
                    &mut all,
                    &triangles,
                    lattice.tolerance,
                );
                for &i in &cells {
                    if in_range(i) {
                        positions[i - v0] = all[i];
                    } else {
                        let (s, k) = slab_of(i);
                        self.slabs[s].positions[k] = all[i];
                    }
                }
            }
        }
        stats.refinement = t.elapsed();
        // An update goes on to the end from here: what is left is proportional to the
        // vertices it placed, and stopping would cost the next update a run from scratch.
        if dirty.is_none() && lattice.control.is_cancelled() {
            return Err(Error::Cancelled);
        }

        let t = Instant::now();
        if want_normals {
            // Cell vertices were placed again: their gradients too.
            let mut again: Vec<usize> = fresh.iter().map(|&r| v0 + r).collect();
            if dirty.is_some() {
                again.extend(cells.iter().copied());
                again.sort_unstable();
                again.dedup();
            }
            let pts: Vec<DVec3> = again
                .iter()
                .map(|&i| {
                    if in_range(i) {
                        positions[i - v0]
                    } else {
                        let (s, k) = slab_of(i);
                        self.slabs[s].positions[k]
                    }
                })
                .collect();
            let normals = unit_gradients(field, &pts);
            for (&i, g) in again.iter().zip(normals) {
                if in_range(i) {
                    gradients[i - v0] = g;
                } else {
                    let (s, k) = slab_of(i);
                    self.slabs[s].gradients[k] = g;
                }
            }
            stats.normal_evaluations = again.len() as u64;
        }
        // The range's positions and gradients go to its slabs.
        {
            let (mut p, mut g) = (positions.into_iter(), gradients.into_iter());
            for s in &mut self.slabs[range.clone()] {
                s.positions = p.by_ref().take(s.counts.vertices).collect();
                if want_normals {
                    s.gradients = g.by_ref().take(s.counts.vertices).collect();
                }
            }
        }
        let mesh_positions = gather(
            &self.slabs,
            |s| s.positions.len(),
            |_, s, out| {
                for (o, p) in out.iter_mut().zip(&s.positions) {
                    *o = p.as_vec3().to_array();
                }
            },
        );
        let normals = if want_normals && !triangles.is_empty() {
            let mut normals = gather(
                &self.slabs,
                |s| s.gradients.len(),
                |_, s, out| out.copy_from_slice(&s.gradients),
            );
            if normals.contains(&[0.0; 3]) {
                let all: Vec<DVec3> =
                    self.slabs.iter().flat_map(|s| s.positions.iter().copied()).collect();
                fill_from_faces(&mut normals, &all, &triangles);
            }
            normals
        } else {
            Vec::new()
        };
        stats.normals = t.elapsed();
        let mesh = Mesh { positions: mesh_positions, normals, triangles, ..Mesh::default() };
        stats.vertices = mesh.vertex_count();
        stats.triangles = mesh.triangle_count();
        self.vertex_count = n;
        self.cells = cells.iter().map(|&i| i as u32).collect();
        self.map = vertex_map;
        self.whole = true;
        Ok((mesh, reused))
    }
}

/// The lattice points sampled again (those in a changed box, [`SAMPLE_MARGIN`]) and the
/// points near the change (within [`EDGE_MARGIN`] cells of a box: a vertex whose edge has
/// an end among them is placed again), each as one bit per lattice point (boxes of
/// neighbouring elements overlap, and their bounding box would hold far more points than
/// they do).
struct Dirty {
    dims: [usize; 3],
    /// The points sampled again.
    sampled: Vec<u64>,
    /// The points near the change (a superset of `sampled`).
    near: Vec<u64>,
    /// The lowest and highest sample layer with a point near the change.
    layers: Option<(usize, usize)>,
}

impl Dirty {
    fn new(grid: &Grid, changed: &[Aabb]) -> Dirty {
        let dims = grid.dims;
        let count = dims[0] * dims[1] * dims[2];
        let words = count.div_ceil(64);
        let mut d = Dirty { dims, sampled: vec![0; words], near: vec![0; words], layers: None };
        let top = dims.map(|n| n.saturating_sub(1));
        // The points within `margin` cells of `c`, as the lowest and highest index along
        // each axis; `None` when there are none.
        let span = |c: &Aabb, margin: f64| -> Option<([usize; 3], [usize; 3])> {
            let lo = (c.min - grid.origin) / grid.cell - DVec3::splat(margin);
            let hi = (c.max - grid.origin) / grid.cell + DVec3::splat(margin);
            if !(lo.is_finite() && hi.is_finite()) {
                // A box that is not finite covers everything.
                return Some(([0; 3], top));
            }
            if (0..3).any(|i| hi[i] < 0.0 || lo[i] > top[i] as f64) {
                return None;
            }
            let a: [usize; 3] = std::array::from_fn(|i| lo[i].ceil().max(0.0) as usize);
            let b: [usize; 3] = std::array::from_fn(|i| hi[i].floor().min(top[i] as f64) as usize);
            (0..3).all(|i| a[i] <= b[i]).then_some((a, b))
        };
        for c in changed {
            let Some((a, b)) = span(c, EDGE_MARGIN) else {
                continue;
            };
            d.layers = Some(d.layers.map_or((a[2], b[2]), |(lo, hi)| (lo.min(a[2]), hi.max(b[2]))));
            mark_box(&mut d.near, dims, a, b);
            if let Some((a, b)) = span(c, SAMPLE_MARGIN) {
                mark_box(&mut d.sampled, dims, a, b);
            }
        }
        d
    }

    /// The lowest and highest sample layer with a point near the change, if any.
    fn layers(&self) -> Option<(usize, usize)> {
        self.layers
    }

    /// Whether lattice point `p` is near the change (a vertex on an edge from it is placed
    /// again).
    fn near(&self, p: [u32; 3]) -> bool {
        let [i, j, k] = p.map(|x| x as usize);
        let n = i + self.dims[0] * (j + self.dims[1] * k);
        self.near[n / 64] >> (n % 64) & 1 == 1
    }

    /// The indices of the points sampled again, ascending.
    fn points(&self) -> Vec<usize> {
        let mut out = Vec::new();
        // Only the words of the layers near the change can hold one.
        let layer = self.dims[0] * self.dims[1];
        let words = match self.layers {
            Some((lo, hi)) => lo * layer / 64..((hi + 1) * layer).div_ceil(64),
            None => 0..0,
        };
        for (w, &bits) in self.sampled.iter().enumerate().skip(words.start).take(words.len()) {
            let mut b = bits;
            while b != 0 {
                out.push(w * 64 + b.trailing_zeros() as usize);
                b &= b - 1;
            }
        }
        out
    }
}

/// The slabs' items in slab order, in one array: each slab's part (`len` items) written by
/// `fill(slab number, slab, part)`, the slabs on the pool's threads (each part its own, so
/// the array is the same on any number of threads).
fn gather<U: Copy + Default + Send + Sync>(
    slabs: &[Slab],
    len: impl Fn(&Slab) -> usize,
    fill: impl Fn(usize, &Slab, &mut [U]) + Sync + Send,
) -> Vec<U> {
    let total = slabs.iter().map(&len).sum();
    let mut out = vec![U::default(); total];
    let mut parts = Vec::with_capacity(slabs.len());
    let mut rest = out.as_mut_slice();
    for (k, s) in slabs.iter().enumerate() {
        let (part, more) = rest.split_at_mut(len(s));
        parts.push((k, s, part));
        rest = more;
    }
    parts.into_par_iter().for_each(|(k, s, part)| fill(k, s, part));
    out
}

/// Marks the points of the box `a..=b` (lattice indices) in `bits`, a row at a time.
fn mark_box(bits: &mut [u64], dims: [usize; 3], a: [usize; 3], b: [usize; 3]) {
    for k in a[2]..=b[2] {
        for j in a[1]..=b[1] {
            let row = dims[0] * (j + dims[1] * k);
            mark(bits, row + a[0], row + b[0]);
        }
    }
}

/// Marks the points `first..=last` (of one row), a word at a time. Why: an edit of skewed
/// elements gives many small overlapping boxes (`changes_since` covers an element's reach
/// piece by piece), and marking them a bit at a time cost more than the points they spared.
fn mark(bits: &mut [u64], first: usize, last: usize) {
    let (w0, w1) = (first / 64, last / 64);
    let from = u64::MAX << (first % 64);
    let to = u64::MAX >> (63 - last % 64);
    if w0 == w1 {
        bits[w0] |= from & to;
        return;
    }
    bits[w0] |= from;
    for w in &mut bits[w0 + 1..w1] {
        *w = u64::MAX;
    }
    bits[w1] |= to;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Marking a row a word at a time sets exactly the bits a bit at a time would, within a
    /// word, across words and at their edges.
    #[test]
    fn marking_a_row_sets_exactly_its_points() {
        for (first, last) in [(0, 0), (3, 9), (0, 63), (63, 64), (5, 200), (64, 127), (70, 250)] {
            let mut bits = vec![0; 4];
            mark(&mut bits, first, last);
            for n in 0..256 {
                let set = bits[n / 64] >> (n % 64) & 1 == 1;
                assert_eq!(set, (first..=last).contains(&n), "{first}..={last}: point {n}");
            }
        }
    }
}
