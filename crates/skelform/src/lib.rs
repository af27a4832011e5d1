//! skelform: model natural forms with implicit surfaces (formulas, skeletons, regions of
//! space) and turn them into meshes.
//!
//! This crate is the front door. Load a [`Scene`] (a TOML file or text), change what you
//! need for one run with [`Overrides`], and [`Scene::mesh`] runs the polygonizer the scene
//! (or the override) names and returns the mesh with the run's [`Stats`]:
//!
//! ```
//! let scene = skelform::Scene::load("../../examples/torus.toml")?;
//! let meshed = scene.mesh(&skelform::Overrides::default())?;
//! let report = skelform::mesh::check::check(&meshed.mesh);
//! assert!(report.is_closed_manifold() && report.components[0].genus == Some(1));
//! # Ok::<(), skelform::Error>(())
//! ```
//!
//! # What a mesh guarantees, by method
//! - [`Method::Grid`] and [`Method::Continuation`]: every component that lies inside the
//!   domain comes out closed, manifold and consistently oriented (outward normals, inside is
//!   `f < 0`), with ambiguous cubes resolved by the topology of the trilinear interpolant,
//!   at any resolution, including samples exactly on the iso value. Where a surface leaves
//!   the domain the mesh is open there (and a warning says so). Continuation meshes only the
//!   components its seeds (or its coarse search) reach.
//! - [`Method::Tetra`]: closed and oriented as well, but the split of each cube into six
//!   tetrahedra can join walls thinner than a cell that cubes keep apart.
//! - [`Method::Healed`]: for surfaces that cross themselves; the sheets meet along
//!   self-intersection curves (edges of four triangles, also given as polylines), so the
//!   mesh is deliberately non-manifold there. Crossings a lattice cannot resolve are
//!   reported in the warnings, not hidden.
//! - [`Method::NonManifold`]: surfaces between labelled regions of space, each triangle
//!   labelled with its [`RegionPair`] and wound counter-clockwise seen from the lower region;
//!   surfaces meet along labelled intersection curves. Vertices are duplicated per region
//!   pair (weld them to see one complex).
//!
//! No method promises a mesh free of self-intersections between distant parts of a surface
//! that pass closer than a cell, nor triangles of good shape (they are marching-cubes
//! triangles, some of them thin). Results are deterministic: the same scene and overrides
//! give the same mesh on any number of threads.
//!
//! # Long runs
//! [`Overrides::control`] carries a progress callback and a cancellation flag
//! ([`Control`]); a cancelled run returns an [`Error`] for which
//! [`Error::is_cancelled`] holds. Limits (grid size, [`Overrides::max_memory`]) are checked
//! before the work starts.
//!
//! # Editing
//! [`Live`] meshes successive versions of a scene (an editor's) and, with the grid method on
//! a skeleton scene, re-meshes only around the elements an edit changed; every mesh it
//! returns is [`Scene::mesh`]'s, bit for bit. [`Live::mesh_progressive`] gives coarse
//! meshes first and stops when the [`Control`] is cancelled.
//!
//! # The parts
//! The pipeline is one crate a stage, re-exported here: [`field`] (fields and the formula
//! language), [`skeleton`] (skeletal primitives, blends, convolution), [`leaf`] (leaf forms),
//! [`scene`] (scene files), [`polygonize`] (the polygonizers), [`mesh`] (meshes, the checker,
//! readers and writers), [`render`] (pictures).
#![warn(missing_docs)]

mod error;
mod live;
mod loaded;
mod meshing;
mod overrides;
mod stats;
mod surface;

pub use error::Error;
pub use live::{Live, LiveRun};
pub use loaded::Scene;
pub use meshing::{Lattice, Meshed};
pub use overrides::{DEFAULT_MAX_MEMORY, Overrides};
pub use stats::Stats;
pub use surface::{SurfaceDistance, surface_distance};

/// Fields: the [`Field`] and [`RegionField`] traits, the formula
/// language, lattices, progress and cancellation.
pub use skelform_field as field;
/// Leaf forms (dissertation ch. 7): venation, the polygonal-web blade, veins as regions.
pub use skelform_leaf as leaf;
/// Meshes: indexed triangles with labels and curves, the topology checker, readers and
/// writers for PLY, OBJ, STL and glTF.
pub use skelform_mesh as mesh;
/// The polygonizers, each with its own options and statistics.
pub use skelform_polygonize as polygonize;
/// The CPU renderer: shaded PNG pictures of meshes.
pub use skelform_render as render;
/// Skeletal primitives, distance and convolution surfaces, blends and blend groups.
pub use skelform_skeleton as skeleton;

pub use skelform_field::control::{Control, Progress};
pub use skelform_field::formula::Formula;
pub use skelform_field::{Aabb, DVec3, Field, RegionField};
pub use skelform_mesh::{Mesh, RegionPair, RegionTriple};
pub use skelform_polygonize::grid::Streaming;
pub use skelform_polygonize::refine::RootMethod;
pub use skelform_polygonize::{LatticeOptions, MAX_THREADS, MemoryNeed, Resolution, Threads};
pub use skelform_scene::{FILE_KEYS, LoadOptions, Method, PoseBlend, SceneError};

/// The scene crate itself: the schema, its checked description and the builders of fields
/// from it.
pub use skelform_scene as scene;

/// Marching cubes on sampled volumes, without a field: the extraction-only path that other
/// isosurface tools offer (a raw file, a NumPy array), with the same topology guarantees as
/// the grid method. Samples are relative to the iso value (inside negative); vertices are
/// placed by linear interpolation; the mesh is the same on any number of threads.
pub mod volume {
    pub use skelform_field::grid::{
        AtZero, Grid, Level, MAX_SAMPLES_PER_AXIS, Relative, Shifted, Volume, VolumeView, sanitize,
        sanitize_sample,
    };
    pub use skelform_polygonize::grid::{
        Assembly, Cancelled, GridVertex, LayerSource, Near, Place, SlabVertex, StreamError,
        Streamed, VertexSink, extract_mesh, extract_streamed, extract_view_mesh,
        extract_view_records, extract_view_records_into, extract_view_sunk, extract_volume_records,
        extract_volume_records_into, extract_volume_sunk, stream_rows,
    };

    /// Builds the marching-cubes case table now (a few milliseconds, once per process), so
    /// that a timed extraction measures the extraction alone.
    pub fn prepare() {
        skelform_polygonize::grid::prepare_tables();
    }
}
