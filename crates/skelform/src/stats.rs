//! The statistics of whichever method ran, behind one type, so that front ends report any
//! run without knowing its method.

use std::fmt;

use skelform_polygonize::{continuation, grid, healed, nonmanifold};

/// What a run did: evaluations, counts, times and notes, of the method that ran.
///
/// With the `serde` feature (on by default) it serializes as that method's statistics,
/// field for field (durations in seconds); [`fmt::Display`] gives the text report that
/// `skelform mesh --stats` prints.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(untagged))]
pub enum Stats {
    /// The grid polygonizer's statistics.
    Grid(grid::Stats),
    /// The continuation polygonizer's, for cubes and tetrahedra alike.
    Continuation(continuation::Stats),
    /// The healed polygonizer's: the grid's, plus the self-intersections found and healed.
    Healed(Box<healed::Stats>),
    /// The non-manifold polygonizer's, with triangles per region pair and curve lengths.
    NonManifold(Box<nonmanifold::Stats>),
}

impl Stats {
    /// Every evaluation of the field (or, for regions, of the region function) the run made:
    /// the measure of cost that does not depend on the machine.
    pub fn evaluations(&self) -> u64 {
        match self {
            Stats::Grid(s) => s.evaluations(),
            Stats::Continuation(s) => s.evaluations(),
            Stats::Healed(s) => s.evaluations(),
            Stats::NonManifold(s) => s.region_evaluations,
        }
    }

    /// Things a user should know even without asking for statistics: open borders, seeds
    /// that found nothing, non-finite samples, self-intersections left unhealed.
    pub fn warnings(&self) -> Vec<String> {
        match self {
            Stats::Grid(s) => s.warnings(),
            Stats::Continuation(s) => s.warnings(),
            Stats::Healed(s) => s.warnings(),
            Stats::NonManifold(s) => s.warnings(),
        }
    }

    /// Why a run made no triangles, and what to check; meaningful when the mesh is empty.
    pub fn no_surface(&self) -> String {
        match self {
            Stats::Grid(s) => s.no_surface(),
            Stats::Continuation(s) => s.no_surface(),
            Stats::Healed(s) => s.no_surface(),
            Stats::NonManifold(s) => s.no_surface(),
        }
    }
}

impl fmt::Display for Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stats::Grid(s) => s.fmt(f),
            Stats::Continuation(s) => s.fmt(f),
            Stats::Healed(s) => s.fmt(f),
            Stats::NonManifold(s) => s.fmt(f),
        }
    }
}
