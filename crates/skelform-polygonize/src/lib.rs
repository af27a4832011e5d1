//! Polygonizers: from a [`Field`](skelform_field::Field) to a [`Mesh`](skelform_mesh::Mesh).
//!
//! - [`grid`]: sample on a lattice, then marching cubes with a consistent treatment of the
//!   ambiguous faces (asymptotic decider) and interiors (trilinear saddles). Closed surfaces
//!   inside the domain come out closed, manifold and consistently oriented at any
//!   resolution; output is identical on any thread count.
//! - [`healed`]: healed marching cubes for surfaces that cross themselves: the grid
//!   polygonizer, then the cubes round self-intersection curves re-triangulated so that the
//!   sheets cross cleanly (edges of four triangles along the curves, which are output as
//!   polylines); cone apexes fanned; bare lines and points reported.
//! - [`incremental`]: the grid polygonizer again after a local change of the field: samples
//!   again only near the changed boxes, re-extracts only the slabs there and splices the
//!   mesh, bit for bit the fresh run's.
//! - [`refine`]: root finding along edges and gradient normals, shared by all polygonizers.
//!
//! A polygonizer knows nothing of files: it takes a field and options and returns a mesh and
//! statistics. Each has the same [`LatticeOptions`] in its options: the domain and
//! resolution, vertex placement, a [`Control`](skelform_field::control::Control) to report
//! progress and to cancel (a cancelled run returns [`Error::Cancelled`], whatever the method),
//! and the [`Threads`] to run on.
//!
//! ```
//! use skelform_field::{Aabb, formula::Formula};
//! use skelform_polygonize::{LatticeOptions, Resolution};
//! use skelform_polygonize::grid::{polygonize, Options};
//! use skelform_mesh::check::check;
//!
//! let torus = Formula::parse("q = sqrt(x^2 + y^2) - 0.6\nq^2 + z^2 - 0.25^2").unwrap();
//! let lattice = LatticeOptions { domain: Aabb::cube(1.0), resolution: Resolution::Samples(48), ..Default::default() };
//! let opts = Options { lattice, ..Default::default() };
//! let (mesh, _stats) = polygonize(&torus, &opts).unwrap();
//! let report = check(&mesh);
//! assert!(report.is_closed_manifold());
//! assert_eq!(report.components[0].genus, Some(1));
//! ```

#![warn(missing_docs)]

pub mod continuation;
pub mod grid;
pub mod healed;
pub mod incremental;
pub mod lattice;
pub mod nonmanifold;
pub mod refine;
mod summary;

use skelform_field::grid::GridError;

use lattice::memory;

pub use lattice::{LatticeOptions, MAX_THREADS, MemoryNeed, Resolution, Threads};

/// Why a polygonizer could not run.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The lattice cannot be built: an empty or non-finite domain, a resolution below two
    /// samples, a cell that is not a positive length, or more samples per axis than a grid
    /// may have.
    #[error(transparent)]
    Grid(GridError),
    /// A dense run would need more memory than [`LatticeOptions::max_memory`] allows; refused
    /// before anything is allocated, so asking is cheap.
    #[error(
        "the grid of {} × {} × {} samples would need {}, over the limit of {}; \
         use a coarser resolution or raise the limit",
        dims[0], dims[1], dims[2], memory::human(*needed), memory::human(*limit)
    )]
    TooMuchMemory {
        /// Bytes the run would need before its first triangle.
        needed: u64,
        /// The limit it was given.
        limit: u64,
        /// Samples per axis of the lattice asked for.
        dims: [usize; 3],
    },
    /// A propagating run (continuation, tetra, non-manifold) or healing held more memory
    /// than [`LatticeOptions::max_memory`] allows and stopped there. What it holds grows with
    /// the surface, so it is known only as the run goes: its running account (maps of
    /// visited cubes, corner values, edge vertices and faces, and the mesh arrays) is
    /// compared with the limit every 1024 cubes and after each wave, and the run stops at
    /// the same cube on any thread count. Unlike [`Error::TooMuchMemory`] (refused before
    /// anything was allocated), this is a failure of the run, not of its input.
    #[error(
        "the {method} run reached the memory limit of {} after {cells} cubes; \
         use a coarser cell, a smaller domain or fewer cells (max_cells), or raise the limit (--max-memory)",
        memory::human(*limit)
    )]
    MemoryLimit {
        /// The polygonizer (`continuation`, `tetra`, `nonmanifold`, `healed`).
        method: &'static str,
        /// Bytes its account held when it stopped (over `limit`).
        held: u64,
        /// The limit it was given.
        limit: u64,
        /// Cubes it had polygonized (for healing: the cubes of the grid it heals).
        cells: u64,
    },
    /// The run's [`Control`](skelform_field::control::Control) asked it to stop; whatever
    /// phase it was in, and whichever polygonizer, this is the one error a cancelled run
    /// returns.
    #[error("cancelled")]
    Cancelled,
    /// A seed cannot start propagation: it lies outside the domain, the field is not finite
    /// there, or no surface was found from it (or from any seed).
    #[error("seed ({}, {}, {}): {why}", seed[0], seed[1], seed[2])]
    BadSeed {
        /// The seed, as given.
        seed: [f64; 3],
        /// What is wrong with it, in words for the user.
        why: String,
    },
    /// With no seeds, the coarse search of the domain found no crossing to start from: the
    /// surface is absent or smaller than the search stride.
    #[error(
        "no surface found: a search of {samples} points (every {stride} cells) found no sign change (or, for regions, no change between a pair of interest); give a seed near the surface or a smaller search stride"
    )]
    NoSurfaceFound {
        /// Points the search sampled.
        samples: u64,
        /// Its stride, in cells.
        stride: usize,
    },
    /// An option out of its range (a tolerance outside (0, 1), a thread count over
    /// [`MAX_THREADS`], a region the region function does not have, …), with what was wrong.
    #[error("{0}")]
    BadOption(String),
    /// The thread pool asked for in [`LatticeOptions::threads`] could not be started (the
    /// system refused the threads).
    #[error("{0}")]
    ThreadPool(String),
}

impl From<grid::Cancelled> for Error {
    fn from(_: grid::Cancelled) -> Self {
        Error::Cancelled
    }
}

impl From<grid::StreamError<std::convert::Infallible>> for Error {
    fn from(e: grid::StreamError<std::convert::Infallible>) -> Self {
        match e {
            grid::StreamError::Cancelled => Error::Cancelled,
            grid::StreamError::Source(never) => match never {},
        }
    }
}

impl From<GridError> for Error {
    fn from(e: GridError) -> Self {
        match e {
            GridError::Cancelled => Error::Cancelled,
            e => Error::Grid(e),
        }
    }
}
