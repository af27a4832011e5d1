//! From a scene and overrides to a polygonizer call: the one place that knows which
//! polygonizer each [`Method`] is and how a scene's settings map onto its options.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use skelform_field::{DVec3, RegionField};
use skelform_mesh::Mesh;
use skelform_polygonize::{LatticeOptions, MemoryNeed, Resolution, grid};
use skelform_polygonize::{continuation, healed, nonmanifold};
use skelform_scene::Method;

use crate::overrides::DEFAULT_MAX_MEMORY;
use crate::{Error, Overrides, Scene, Stats};

/// A mesh and what it took to make it.
#[derive(Clone, Debug)]
pub struct Meshed {
    /// The triangles, with normals unless they were turned off, region labels and curves
    /// where the method makes them. Empty when the scene has no surface in its domain (see
    /// [`Meshed::no_surface`]).
    pub mesh: Mesh,
    /// The method's statistics.
    pub stats: Stats,
    /// The method that ran (the scene's, or the override).
    pub method: Method,
    /// Wall time of the polygonizer call, painting included.
    pub elapsed: Duration,
    /// Of `elapsed`, the wall time of painting the vertices (element colours blended at
    /// each vertex, texture coordinates): zero for a scene without colours or sweeps.
    pub painting: Duration,
}

impl Meshed {
    /// When the mesh is empty, why, and what to check (the scene's name in front).
    pub fn no_surface(&self, scene: &Scene) -> Option<String> {
        self.mesh.is_empty().then(|| format!("{}: {}", scene.origin, self.stats.no_surface()))
    }
}

fn invalid(scene: &Scene, message: impl Into<String>) -> Error {
    Error::Invalid { origin: scene.origin.clone(), message: message.into() }
}

/// The resolution after the override, checked.
fn resolution(scene: &Scene, o: &Overrides) -> Result<Resolution, Error> {
    match o.resolution {
        Some(Resolution::Samples(n)) if n < 2 => {
            Err(invalid(scene, "the resolution must be at least 2 samples"))
        }
        Some(Resolution::Cell(c)) if !(c.is_finite() && c > 0.0) => {
            Err(invalid(scene, "the cell size must be a positive length"))
        }
        Some(r) => Ok(r),
        None => Ok(scene.resolution),
    }
}

fn seeds(scene: &Scene, o: &Overrides) -> Vec<DVec3> {
    o.seeds.clone().unwrap_or_else(|| scene.continuation.seeds.clone())
}

/// The lattice a run would use, known before any work: what `skelform info` shows and what
/// limits are checked against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// Samples along x, y and z.
    pub dims: [usize; 3],
    /// Cell side.
    pub cell: f64,
    /// The method the run would use (the scene's, or the override).
    pub method: Method,
    /// What that method holds before it has made any of the surface; the run is refused up
    /// front when this is over the memory limit.
    pub need: MemoryNeed,
}

impl Lattice {
    /// Bytes needed up front ([`MemoryNeed::bytes`]).
    pub fn memory(&self) -> u64 {
        self.need.bytes()
    }

    /// Whether the grid method would stream the volume slab by slab.
    pub fn streamed(&self) -> bool {
        matches!(self.need, MemoryNeed::Lattice { streamed: true, .. })
    }
}

/// A method with its options, ready to run: what a scene and overrides come to.
pub(crate) enum Plan {
    Grid(grid::Options),
    NonManifold(Arc<dyn RegionField>, nonmanifold::Options),
    Continuation(continuation::Options),
    Healed(healed::Options),
}

impl Plan {
    fn lattice(&self) -> &LatticeOptions {
        match self {
            Plan::Grid(o) => &o.lattice,
            Plan::NonManifold(_, o) => &o.lattice,
            Plan::Continuation(o) => &o.lattice,
            Plan::Healed(o) => &o.lattice,
        }
    }
}

impl Scene {
    /// The lattice that meshing with `overrides` would use (the grid method's; the
    /// continuation methods visit part of the same lattice), with what the method needs up
    /// front. An error when the overrides are invalid or the lattice too large.
    pub fn lattice(&self, overrides: &Overrides) -> Result<Lattice, Error> {
        let (method, plan) = self.plan(overrides)?;
        let g = plan
            .lattice()
            .grid()
            .map_err(|e| Error::Polygonize { origin: self.origin.clone(), source: e.into() })?;
        let need = match &plan {
            Plan::Grid(o) => grid::memory_need(&g, o),
            Plan::NonManifold(_, o) => nonmanifold::memory_need(&g, o),
            Plan::Continuation(o) => continuation::memory_need(&g, o),
            Plan::Healed(_) => healed::memory_need(&g),
        };
        Ok(Lattice { dims: g.dims, cell: g.cell, method, need })
    }

    /// Meshes the scene with its own settings, as changed by `overrides`.
    ///
    /// The method decides what the mesh guarantees: grid and continuation give closed,
    /// manifold, consistently oriented surfaces where the surface lies inside the domain;
    /// tetra may join thin walls that cubes keep apart; healed gives sheets that cross along
    /// self-intersection curves; non-manifold gives labelled surfaces that meet along
    /// intersection curves. The same scene and overrides give the same mesh on any number of
    /// threads.
    pub fn mesh(&self, overrides: &Overrides) -> Result<Meshed, Error> {
        if let Some(pose) = &overrides.pose {
            let posed = self.posed(pose)?;
            let plain = Overrides { pose: None, ..overrides.clone() };
            return posed.mesh(&plain);
        }
        self.mesh_here(overrides)
    }

    /// The one place that knows which polygonizer each [`Method`] is and how the scene's
    /// settings and the overrides map onto its options.
    pub(crate) fn plan(&self, o: &Overrides) -> Result<(Method, Plan), Error> {
        let method = o.method.unwrap_or(self.method);
        let resolution = resolution(self, o)?;
        let tolerance = match o.tolerance {
            Some(t) if !(t > 0.0 && t < 1.0) => {
                return Err(invalid(
                    self,
                    "the root-finding tolerance is a fraction of the cell, between 0 and 1",
                ));
            }
            Some(t) => t,
            None => self.tolerance,
        };
        if self.regions_only && method != Method::NonManifold {
            return Err(invalid(
                self,
                "the scene has [regions] and no [field]: mesh it with method = \"nonmanifold\"",
            ));
        }
        let lattice = LatticeOptions {
            domain: self.domain,
            resolution,
            refine: o.refine.unwrap_or(self.refine),
            tolerance,
            normals: o.normals.unwrap_or(self.output.normals),
            max_memory: o.max_memory.unwrap_or(DEFAULT_MAX_MEMORY),
            control: o.control.clone(),
            threads: o.threads.clone().unwrap_or_default(),
        };
        let plan = match method {
            Method::Grid => {
                let options = grid::Options {
                    lattice,
                    streaming: o.streaming.unwrap_or_default(),
                    workspace: o.workspace.clone(),
                };
                Plan::Grid(options)
            }
            Method::NonManifold => {
                let Some(setup) = self.nonmanifold_regions() else {
                    return Err(invalid(
                        self,
                        "the non-manifold method needs [regions] or [leaf] in the scene",
                    ));
                };
                let defaults = nonmanifold::Options::default();
                let options = nonmanifold::Options {
                    lattice,
                    seeds: seeds(self, o),
                    search_stride: self
                        .continuation
                        .search_stride
                        .unwrap_or(defaults.search_stride),
                    full_grid: setup.full_grid,
                    loops: setup.loops,
                    interest: setup.interest,
                    curves: setup.curves,
                    max_cells: o
                        .max_cells
                        .or(self.continuation.max_cells)
                        .unwrap_or(defaults.max_cells),
                    ..defaults
                };
                Plan::NonManifold(setup.field, options)
            }
            Method::Continuation | Method::Tetra => {
                let c = &self.continuation;
                let defaults = continuation::Options::default();
                let options = continuation::Options {
                    lattice,
                    seeds: seeds(self, o),
                    search_stride: c.search_stride.unwrap_or(defaults.search_stride),
                    cells: if method == Method::Tetra {
                        continuation::Cells::Tetrahedra
                    } else {
                        continuation::Cells::Cubes
                    },
                    root: o.root.unwrap_or(c.root),
                    max_cells: o.max_cells.or(c.max_cells).unwrap_or(defaults.max_cells),
                    limit: o.limit.or(c.limit),
                };
                Plan::Continuation(options)
            }
            Method::Healed => {
                let h = &self.healed;
                let options = healed::Options {
                    lattice,
                    epsilon: match (h.epsilon, h.critical_cells, h.healing) {
                        (Some(e), _, _) => healed::Epsilon::Absolute(e),
                        (None, Some(c), _) => healed::Epsilon::Cells(c),
                        // The thesis's own test and tolerance (its fig. 4.3).
                        (None, None, healed::Healing::Thesis) => healed::Epsilon::Absolute(0.2),
                        (None, None, healed::Healing::Zone) => healed::Options::default().epsilon,
                    },
                    split_sheets: h.split_sheets,
                    healing: h.healing,
                    ..healed::Options::default()
                };
                Plan::Healed(options)
            }
        };
        Ok((method, plan))
    }

    fn mesh_here(&self, o: &Overrides) -> Result<Meshed, Error> {
        let (method, plan) = self.plan(o)?;
        let field = self.field.as_ref();
        let started = Instant::now();
        let result = match plan {
            Plan::Grid(o) => grid::polygonize(field, &o).map(|(m, s)| (m, Stats::Grid(s))),
            Plan::NonManifold(regions, o) => nonmanifold::polygonize(regions.as_ref(), &o)
                .map(|(m, s)| (m, Stats::NonManifold(Box::new(s)))),
            Plan::Continuation(o) => {
                continuation::polygonize(field, &o).map(|(m, s)| (m, Stats::Continuation(s)))
            }
            Plan::Healed(o) => {
                healed::polygonize(field, &o).map(|(m, s)| (m, Stats::Healed(Box::new(s))))
            }
        };
        let (mut mesh, stats) =
            result.map_err(|source| Error::Polygonize { origin: self.origin.clone(), source })?;
        let painted = Instant::now();
        self.paint(&mut mesh, method, o);
        let painting = painted.elapsed();
        Ok(Meshed { mesh, stats, method, elapsed: started.elapsed(), painting })
    }

    /// Element colours blended at the vertices (DIS ch. 6), and texture coordinates from the
    /// sweeps ([`texture_coordinates`]), for surfaces of the field; the
    /// non-manifold method's surfaces are labelled by region instead. Every path that makes
    /// a mesh of the scene ([`Scene::mesh`], [`crate::Live`]) calls this, so they agree.
    pub(crate) fn paint(&self, mesh: &mut Mesh, method: Method, overrides: &Overrides) {
        self.paint_with(mesh, method, overrides, |_, _| None);
    }

    /// [`Scene::paint`], taking the colour of each vertex (by its number and position) for
    /// which `known` has one instead of computing it ([`crate::Live`]: vertices an edit did
    /// not reach).
    pub(crate) fn paint_with(
        &self,
        mesh: &mut Mesh,
        method: Method,
        overrides: &Overrides,
        known: impl Fn(usize, &[f32; 3]) -> Option<[f32; 3]> + Sync,
    ) {
        if overrides.colors == Some(false) {
            // Colours a polygonizer gave with its evaluations (continuation on a coloured
            // skeleton), not wanted.
            mesh.colors.clear();
        }
        // A polygonizer that evaluates the field next to every vertex anyway colours the
        // vertices in those evaluations (`Field::eval_grad_color_many`; continuation with
        // root finding): the scene's field is then the skeleton itself (with sweeps or
        // combinations it has no colours to give), so its colours are these, taken at most
        // a Newton step (a thousandth of a cell or so) from each vertex, and need no second
        // pass.
        let coloured = !mesh.colors.is_empty() && mesh.colors.len() == mesh.vertex_count();
        if method != Method::NonManifold
            && overrides.colors != Some(false)
            && !coloured
            && let Some(skeleton) = &self.skeleton
            && skeleton.colors(&[]).is_some()
        {
            let known: Vec<Option<[f32; 3]>> =
                mesh.positions.par_iter().enumerate().map(|(i, p)| known(i, p)).collect();
            let points: Vec<DVec3> = mesh
                .positions
                .iter()
                .zip(&known)
                .filter(|(_, k)| k.is_none())
                .map(|(p, _)| DVec3::from_array(p.map(f64::from)))
                .collect();
            // Each vertex's colour is its own sum (the triangle integrals make it costly:
            // about 17 µs a vertex on the hand), so chunks in parallel give the same colours.
            let chunks: Option<Vec<Vec<[f32; 3]>>> =
                points.par_chunks(1024).map(|chunk| skeleton.colors(chunk)).collect();
            let mut fresh = chunks.unwrap_or_default().into_iter().flatten();
            mesh.colors =
                known.iter().map(|k| k.or_else(|| fresh.next()).unwrap_or_default()).collect();
        }
        // The leaf's tertiary venation texture (§7.4, `[leaf] texture = true`): each vertex
        // takes the colour under it in the leaf's plane, a pure function of its position.
        if method == Method::NonManifold
            && overrides.colors != Some(false)
            && let Some(leaf) = &self.leaf
            && leaf.texture.is_some()
        {
            mesh.colors = mesh
                .positions
                .par_iter()
                .enumerate()
                .map(|(i, p)| {
                    known(i, p)
                        .or_else(|| leaf.colour(DVec3::from_array(p.map(f64::from))))
                        .unwrap_or_default()
                })
                .collect();
            // And the texture image with each vertex's place in it, so that the lines are
            // sharp at any mesh resolution where the image is used (glb, `skelform render`);
            // the vertex colours stay for PLY.
            if let Some(image) = &leaf.image {
                mesh.uvs = mesh
                    .positions
                    .par_iter()
                    .map(|p| leaf.uv(DVec3::from_array(p.map(f64::from))).unwrap_or_default())
                    .collect();
                mesh.texture = Some(image.clone());
            }
        }
        if method != Method::NonManifold
            && let Some(swept) = &self.sweeps
        {
            mesh.uvs = texture_coordinates(swept, &mesh.positions);
        }
    }
}

/// Texture coordinates (DIS §5.7) for the vertices of a scene with sweeps: each vertex takes
/// the `[u, v]` of the sweep whose normalised distance `ρ` is least there (the sweep whose
/// surface it is on, or nearest to, in that sweep's radii; [`SweptField::uv`]): `u` the
/// arc-length fraction at the nearest curve point, `v` the angle around the section as a
/// fraction of a turn. A vertex beyond the reach of every sweep (on a skeleton element away
/// from them) gets `[0, 0]`.
///
/// [`SweptField::uv`]: skelform_skeleton::SweptField::uv
pub(crate) fn texture_coordinates(
    swept: &skelform_skeleton::SweptField,
    positions: &[[f32; 3]],
) -> Vec<[f32; 2]> {
    positions
        .par_chunks(1024)
        .flat_map_iter(|chunk| {
            chunk.iter().map(|p| {
                let uv = swept.uv(DVec3::from_array(p.map(f64::from))).unwrap_or([0.0; 2]);
                uv.map(|c| c as f32)
            })
        })
        .collect()
}
