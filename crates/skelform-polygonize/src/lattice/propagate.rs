//! Breadth-first propagation over the cubes of a lattice: from start cubes, across the faces
//! a surface crosses, in waves. The propagating polygonizers share the walk, its stops (the
//! domain's boundary, the cell budget, the distance limit) and its order; they differ in
//! what a cube holds and which of its faces the surface crosses, which the [`Cubes`] they
//! pass decides.
//!
//! Each wave is processed in a fixed order, so the output (vertex numbering included) does
//! not depend on the thread count or on hash order.

use skelform_field::control::{Control, Progress};

use super::cubes::CubeLattice;
use super::memory::{CHECK_EVERY, check, vec_bytes};
use crate::Error;

/// What propagation asks of the polygonizer it walks for.
pub(crate) trait Cubes {
    /// Called with each wave before its cubes are processed (to evaluate their corners in
    /// one parallel batch).
    fn prepare(&mut self, _wave: &[[u32; 3]]) {}
    /// Whether to give up before processing the wave just prepared: a component propagated
    /// on several threads at once that met a cube an earlier seed's component holds (see
    /// the continuation polygonizer's seeds) stops there, its work for nothing.
    fn abandoned(&self) -> bool {
        false
    }
    /// Polygonizes a cube; returns the faces to cross, bit `f` for face `f` (`2 · axis +
    /// side`).
    fn process(&mut self, cube: [u32; 3]) -> u8;
    /// Whether a cube was visited (by this component or an earlier one).
    fn is_visited(&mut self, cube: [u32; 3]) -> bool;
    /// Marks a cube visited.
    fn visit(&mut self, cube: [u32; 3]);
    /// Cubes visited so far, by every component: what the budget counts.
    fn visited(&self) -> u64;
    /// Cubes visited so far, for the progress report: [`Cubes::visited`], unless the
    /// components are propagated on several threads and the budget counts one thread's.
    fn done(&self) -> u64 {
        self.visited()
    }
    /// Bytes held now (see [`super::memory`]): what the memory limit counts. Called every
    /// [`CHECK_EVERY`] cubes, so it must be cheap (lengths and capacities, not a walk).
    fn held(&self) -> u64;
}

/// In which order a wave's cubes are processed. It fixes vertex numbering, so each
/// polygonizer keeps the order its outputs were recorded with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Order {
    /// Lattice order: `x` fastest, then `y`, then `z` (the order of [`super::cubes::Key`]).
    Lattice,
    /// By coordinates: `x` slowest, then `y`, then `z`.
    Coordinates,
}

/// Where propagation stops.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Limits {
    /// Visit no more than this many cubes in all.
    pub max_cells: u64,
    /// Go no farther than this many cubes from `origin` along the axis of a step.
    pub limit: Option<u32>,
    /// The cube distances are measured from (the component's first cube).
    pub origin: [u32; 3],
    /// Hold no more than this many bytes ([`Cubes::held`] and the waves).
    pub max_memory: u64,
    /// The polygonizer, for the error at the memory limit.
    pub method: &'static str,
}

/// Why a propagation left faces uncrossed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Stops {
    /// A face to cross was on the domain's boundary.
    pub domain: bool,
    /// The cell budget ran out with a face still to cross into an unvisited cube.
    pub budget: bool,
    /// A face to cross led beyond the distance limit.
    pub limit: bool,
    /// Propagation gave up ([`Cubes::abandoned`]); the cubes are not all processed.
    pub abandoned: bool,
}

/// Propagates from `starts` (those not yet visited), reporting progress as `phase` after each
/// wave; a cancelled control ends it with [`Error::Cancelled`], and holding more than
/// `limits.max_memory` (checked every [`CHECK_EVERY`] cubes and after each wave) with
/// [`Error::MemoryLimit`].
pub(crate) fn propagate(
    cubes: &mut impl Cubes,
    lattice: &CubeLattice,
    starts: impl IntoIterator<Item = [u32; 3]>,
    limits: &Limits,
    order: Order,
    control: &Control,
    phase: &'static str,
) -> Result<Stops, Error> {
    let mut stops = Stops::default();
    // Cubes polygonized so far: those visited before (each processed by an earlier call)
    // and those processed here. (Visited counts a whole wave as soon as it is found, and in
    // full-grid mode every cube at once.)
    let before = cubes.visited();
    let mut wave: Vec<[u32; 3]> = Vec::new();
    for c in starts {
        if !cubes.is_visited(c) {
            cubes.visit(c);
            wave.push(c);
        }
    }
    let mut processed = 0u64;
    while !wave.is_empty() {
        cubes.prepare(&wave);
        if cubes.abandoned() {
            stops.abandoned = true;
            return Ok(stops);
        }
        let mut next = Vec::new();
        for &cube in &wave {
            processed += 1;
            if processed.is_multiple_of(CHECK_EVERY) {
                let now = cubes.held() + vec_bytes(&wave) + vec_bytes(&next);
                check(limits.method, now, limits.max_memory, before + processed)?;
            }
            let faces = cubes.process(cube);
            for f in (0..6).filter(|f| faces & (1 << f) != 0) {
                let Some(n) = lattice.across(cube, f) else {
                    stops.domain = true;
                    continue;
                };
                let axis = f / 2;
                if let Some(limit) = limits.limit
                    && n[axis].abs_diff(limits.origin[axis]) > limit
                {
                    stops.limit = true;
                    continue;
                }
                if cubes.is_visited(n) {
                    continue;
                }
                if cubes.visited() >= limits.max_cells {
                    stops.budget = true;
                    continue;
                }
                cubes.visit(n);
                next.push(n);
            }
        }
        match order {
            Order::Lattice => next.sort_unstable_by_key(|c| [c[2], c[1], c[0]]),
            Order::Coordinates => next.sort_unstable(),
        }
        let now = cubes.held() + vec_bytes(&wave) + vec_bytes(&next);
        check(limits.method, now, limits.max_memory, before + processed)?;
        wave = next;
        let p = Progress { phase, done: cubes.done(), total: None };
        if control.report(p).is_break() {
            return Err(Error::Cancelled);
        }
    }
    Ok(stops)
}
