//! What every polygonizer shares about its lattice: the options that say which lattice, how
//! its vertices are placed and on which threads the run goes ([`LatticeOptions`]).
//!
//! Each polygonizer's `Options` embeds one of these as its `lattice` field, so that a front
//! end sets the domain, resolution, accuracy and threads once, whatever the method; only
//! what is particular to a method (seeds, streaming, healing thresholds) stays beside it.
//!
//! Inside the crate it also holds what the lattice walkers share: point and cube keys and
//! neighbours (`cubes`), the coarse search of the domain for a surface (`search`) and
//! breadth-first propagation across the faces a surface crosses (`propagate`).

pub(crate) mod cubes;
pub(crate) mod memory;
pub(crate) mod propagate;
pub(crate) mod search;
mod threads;

use skelform_field::Aabb;
use skelform_field::control::Control;
use skelform_field::grid::{Grid, GridError};

pub use threads::{MAX_THREADS, Threads};

/// How fine the lattice is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    /// Samples along the domain's longest side (the cell follows from the domain).
    Samples(usize),
    /// Cell side length (the sample count follows from the domain).
    Cell(f64),
}

/// What a run is known to hold before it starts, by the kind of thing that is held: each
/// method's `memory_need` says it from the lattice and options alone, so that a front end can
/// show it (`skelform info`) and a run refuses it up front when it is over
/// [`LatticeOptions::max_memory`]. Every byte count is `u64::MAX` when it does not fit in a
/// `u64`. Past it, every run holds its mesh, and the propagating methods their maps, which
/// grow with the surface and are counted as the run goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryNeed {
    /// The sampled volume (or, streamed, a few slabs of it) and the extraction buffers: the
    /// grid and healed methods, before any triangle.
    Lattice {
        /// Bytes.
        bytes: u64,
        /// Whether the volume is sampled slab by slab as it is extracted.
        streamed: bool,
    },
    /// The non-manifold full-grid mode's list of every cube, its visited set, the region at
    /// every lattice point and its face and edge caches, at the least.
    FullGrid(u64),
    /// The coarse search of the domain for a surface (propagating methods without seeds).
    Search(u64),
    /// Nothing known up front: a seeded propagating run holds only what grows with the
    /// surface it finds.
    Surface,
}

impl MemoryNeed {
    /// Bytes needed up front (0 for [`MemoryNeed::Surface`]).
    pub fn bytes(&self) -> u64 {
        match *self {
            MemoryNeed::Lattice { bytes, .. } | MemoryNeed::FullGrid(bytes) => bytes,
            MemoryNeed::Search(bytes) => bytes,
            MemoryNeed::Surface => 0,
        }
    }

    /// What the bytes are for, in a few words.
    pub fn what(&self) -> &'static str {
        match self {
            MemoryNeed::Lattice { streamed: false, .. } => "the sampled volume, before triangles",
            MemoryNeed::Lattice { streamed: true, .. } => {
                "slabs of the volume streamed as they are extracted, before triangles"
            }
            MemoryNeed::FullGrid(_) => {
                "every cube, region and cache of the full grid, at the least"
            }
            MemoryNeed::Search(_) => "the coarse search; then what grows with the surface",
            MemoryNeed::Surface => "only what grows with the surface (seeded)",
        }
    }
}

/// The lattice a polygonizer works on and how it places vertices, shared by all of them.
///
/// Not every polygonizer reads every field: the non-manifold polygonizer places vertices by
/// bisection on the region function to its own `epsilon` (so `refine`, `tolerance` and
/// `normals` are not read). Every polygonizer holds to `max_memory`.
#[derive(Clone, Debug)]
pub struct LatticeOptions {
    /// The box to cover; the lattice is grown from it to whole cells, centred on it, and
    /// propagation never leaves it.
    pub domain: Aabb,
    /// How fine the lattice is.
    pub resolution: Resolution,
    /// Move vertices onto the surface by root finding on the field (else linear
    /// interpolation of the samples).
    pub refine: bool,
    /// Root-finding tolerance, as a fraction of the cell (bisection takes
    /// `ceil(log2(1/tolerance))` steps).
    pub tolerance: f64,
    /// Compute per-vertex normals from the field's gradient.
    pub normals: bool,
    /// The most memory a run may hold (bytes). What is known up front is refused before
    /// anything is allocated ([`Error::TooMuchMemory`](crate::Error::TooMuchMemory)): the
    /// grid and healed methods' sampled volume and extraction buffers, the non-manifold
    /// full-grid mode's cube list and caches, the coarse search of the domain. What grows
    /// with the surface (the propagating methods' maps and mesh, what healing adds to the
    /// grid's mesh) is counted as the run goes, and a run that reaches the limit stops with
    /// [`Error::MemoryLimit`](crate::Error::MemoryLimit). The account is an estimate from
    /// the sizes and capacities of what is held, not a measurement: a hash map that grows
    /// briefly holds its old and new tables together, and the field's own storage and the
    /// caller's copy of the mesh are not counted, so the process can peak some tens of
    /// percent above it (measured: a propagating run's peak 0.85–1.15× its final account, a
    /// full-grid run's about 1.5×). Leave that room.
    pub max_memory: u64,
    /// Progress reports and cancellation.
    pub control: Control,
    /// Which threads run the polygonizer.
    pub threads: Threads,
}

impl Default for LatticeOptions {
    fn default() -> Self {
        Self {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Samples(128),
            refine: true,
            tolerance: 1e-4,
            normals: true,
            max_memory: 4 << 30,
            control: Control::default(),
            threads: Threads::Current,
        }
    }
}

impl LatticeOptions {
    /// The lattice these options describe: the same lattice for every polygonizer, so that
    /// the continuation polygonizer reproduces the grid polygonizer's mesh of a component.
    pub fn grid(&self) -> Result<Grid, GridError> {
        match self.resolution {
            Resolution::Samples(n) => Grid::with_resolution(&self.domain, n),
            Resolution::Cell(c) => Grid::with_cell(&self.domain, c),
        }
    }
}
