//! What a caller may change about a scene for one run, without editing the scene.

use skelform_field::DVec3;
use skelform_field::control::Control;
use std::sync::Arc;

use skelform_polygonize::grid::{Streaming, Workspace};
use skelform_polygonize::refine::RootMethod;
use skelform_polygonize::{Resolution, Threads};
use skelform_scene::Method;

/// The memory limit when [`Overrides::max_memory`] is not given: 4 GiB, enough for a 512³
/// grid run held whole and well under what a laptop has.
pub const DEFAULT_MAX_MEMORY: u64 = 4 << 30;

/// Choices that replace the scene's own for one run; `None` (and `Default`) keeps the
/// scene's.
///
/// Every front end fills one of these from its own input (arguments, a Python call, an edit
/// in the studio) and gets the same run; none of them picks a polygonizer itself.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// Samples along the domain's longest side, or the cell size.
    pub resolution: Option<Resolution>,
    /// The polygonizer.
    pub method: Option<Method>,
    /// Start points for the continuation, tetra and non-manifold methods (replacing the
    /// scene's seeds); each should lie on or near the surface.
    pub seeds: Option<Vec<DVec3>>,
    /// Build an articulated skeleton in this named pose (`rest`: every joint at its default
    /// angles); a name the scene does not define is an error listing the ones it does.
    pub pose: Option<String>,
    /// Which threads run the polygonizer: `None` or [`Threads::Current`] the caller's rayon
    /// pool (all cores by default), [`Threads::Count`] a pool of its own, [`Threads::Pool`] a
    /// pool the caller keeps from run to run. The mesh is the same on any of them.
    pub threads: Option<Threads>,
    /// Root-finding tolerance as a fraction of the cell, in (0, 1).
    pub tolerance: Option<f64>,
    /// Root finder of the continuation and tetra methods.
    pub root: Option<RootMethod>,
    /// Continuation, tetra and non-manifold: stop after visiting this many cubes.
    pub max_cells: Option<u64>,
    /// Continuation and tetra: stop this many cubes from each start, in every direction.
    pub limit: Option<u32>,
    /// Move vertices onto the surface by root finding (`false`: linear interpolation).
    pub refine: Option<bool>,
    /// Compute vertex normals from the field's gradient.
    pub normals: Option<bool>,
    /// Grid method: hold the sampled volume whole or stream it slab by slab.
    pub streaming: Option<Streaming>,
    /// Hold no more memory than this many bytes (default [`DEFAULT_MAX_MEMORY`]): work known
    /// up front to need more is refused before it starts (an input error), a run whose
    /// account reaches it as it goes stops (a run error); see
    /// [`LatticeOptions::max_memory`](skelform_polygonize::LatticeOptions::max_memory).
    pub max_memory: Option<u64>,
    /// Grid method: the slab buffers to reuse (`None`: the process's shared ones). A front end
    /// that meshes on every edit keeps its own, so its runs neither wait for nor grow the
    /// buffers of other work in the process.
    pub workspace: Option<Arc<Workspace>>,
    /// Blend the skeleton's element colours into vertex colours (`None`: when the scene's
    /// skeleton has colours). Each vertex's colour costs about an evaluation of the field,
    /// so a front end that does not show them (the studio) turns them off.
    pub colors: Option<bool>,
    /// Progress reports and cancellation for the run.
    pub control: Control,
}
