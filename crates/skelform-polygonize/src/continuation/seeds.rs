//! Propagation from seeds, component after component, on one thread or several.
//!
//! On one thread each seed in turn is walked from ([`Run::walk`]) and, when the cube it
//! reaches was not visited yet, starts a component, propagated whole before the next seed.
//!
//! On several threads the components are propagated at once, each on its thread's own run
//! (own lattice, vertices and triangles), and the mesh is gathered afterwards in seed order.
//! It is the one thread's mesh, byte for byte, because:
//!
//! - a component is a connected set of cubes joined by crossed faces, and propagation from
//!   any of its cubes visits all of it (no distance limit, no budget: those runs stay on one
//!   thread); a crossed edge or face belongs to that component's cubes alone, so its
//!   vertices and triangles, numbered from its start, do not depend on any other component;
//! - a value depends on its point alone, so which run evaluated it does not matter;
//! - which seed a component is recorded under is decided as on one thread: the first seed
//!   (in the seeds' order) whose walk reaches it. Threads take seeds lowest first and claim
//!   the cubes they visit in a table shared by all ([`Shared`]); an earlier seed's claim
//!   wins over a later one's, and a propagation that meets a cube claimed by an earlier
//!   seed gives up (its component is that seed's). The first seed of a component never
//!   meets an earlier claim in it, so it always finishes, claiming every cube; at the end
//!   the claim on a seed's cube names the seed whose component it is, which is the seed the
//!   one-thread run names in [`SeedNote::SameComponent`].
//!
//! Work a thread did for a seed that turned out not to be first in its component is thrown
//! away. To keep that small (the hand is one component reached from 109 seeds), a thread
//! whose propagation gave up leaves, unless it is the last, and threads are added back
//! whenever a component is finished.
//!
//! Statistics: components, seed notes, stops, cells, vertices, triangles and evaluation
//! counts are the one thread's. The evaluations made are not quite: a thread's walks read
//! only the values its own run holds, so a seed inside a component meshed on another thread
//! costs a few more, a corner shared by two components meshed on two threads is evaluated
//! by both, and work thrown away costs its own; the counts are recounted in seed order from
//! the points each run noted (see [`recount`]), so they are the same on any thread count.
//! (random-1000 at 256 samples, two threads: no work thrown away; the hand at 128: one
//! propagation, 606 of 17 803 cells.)
//!
//! Memory: on several threads each run checks its own holdings and the others' last
//! reported ones against the limit. A run that reaches it (or the cell budget) there is
//! redone on one thread, whose stop is the same on every run; but the several threads'
//! account is not the one thread's, so just under the limit a run on several threads can
//! finish where one thread stops.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::lattice::Fresh;
use super::pipe::{Job, Refined};
use super::{Bisection, Component, Run, SeedNote, search_from};
use crate::Error;
use crate::grid::{GridVertex, Place};
use crate::lattice::propagate::Stops;

/// Cubes per side of a brick of the claims table.
const SHIFT: u32 = 3;
const SIDE: u32 = 1 << SHIFT;
const MASK: u32 = SIDE - 1;
const CELLS: usize = (SIDE * SIDE * SIDE) as usize;

/// What became of one seed.
struct Outcome {
    /// Evaluations of its walk (or march), and corners evaluated to find a crossed cube
    /// after a march, as its run counted them.
    search_evaluations: u64,
    corner_evaluations: u64,
    non_finite: u64,
    /// Evaluations of the march alone (not of lattice points).
    march_evaluations: u64,
    /// On several threads: the lattice points its walk evaluated, and the corners evaluated
    /// after a march (see [`recount`]).
    walk: Vec<Fresh>,
    near: Vec<Fresh>,
    /// Time spent finding its cube.
    search: Duration,
    /// The crossed cube found, and the bisection towards the surface.
    hit: Option<([u32; 3], Bisection)>,
    /// On one thread: the seed whose component held the cube already.
    held_by: Option<usize>,
    /// The component propagated from it, when it was.
    part: Option<Part>,
}

/// A component as propagated on one run: where its vertices and triangles lie in that run's
/// arrays, and its counts.
struct Part {
    run: usize,
    vertices: Range<usize>,
    triangles: Range<usize>,
    cells: u64,
    corner_evaluations: u64,
    non_finite: u64,
    tetra_disagreements: u64,
    first_disagreement: Option<DVec3>,
    stops: Stops,
    /// On several threads: the corners its propagation evaluated.
    fresh: Vec<Fresh>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// What the threads propagating components share: which seed's component claimed each
/// cube (the earliest seed wins), and counts for progress and memory.
pub(super) struct Shared {
    /// Per brick of cubes: 0, or 1 + the index of the earliest seed claiming the cube.
    claims: Mutex<FxHashMap<u64, Box<[u32; CELLS]>>>,
    /// Bricks per axis.
    dims: [u64; 3],
    /// Cubes claimed, for progress.
    claimed: AtomicU64,
    /// Bytes each run held when it last finished a seed.
    held: Vec<AtomicU64>,
}

impl Shared {
    fn new(points: [usize; 3], runs: usize) -> Self {
        Shared {
            claims: Mutex::new(FxHashMap::default()),
            dims: points.map(|n| (n as u64).div_ceil(SIDE as u64)),
            claimed: AtomicU64::new(0),
            held: (0..runs).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    fn key(&self, c: [u32; 3]) -> (u64, usize) {
        let b = c.map(|x| (x >> SHIFT) as u64);
        let slot = (c[0] & MASK) | ((c[1] & MASK) << SHIFT) | ((c[2] & MASK) << (2 * SHIFT));
        (b[0] + self.dims[0] * (b[1] + self.dims[1] * b[2]), slot as usize)
    }

    /// Claims `cube` for `seed`, unless an earlier seed has: then returns that seed.
    fn claim_one(
        &self,
        map: &mut FxHashMap<u64, Box<[u32; CELLS]>>,
        cube: [u32; 3],
        seed: usize,
    ) -> Option<usize> {
        let (key, i) = self.key(cube);
        let slot = &mut map.entry(key).or_insert_with(|| Box::new([0; CELLS]))[i];
        match *slot {
            0 => {
                self.claimed.fetch_add(1, Ordering::Relaxed);
            }
            s if (s as usize) <= seed => return Some(s as usize - 1),
            _ => {}
        }
        *slot = seed as u32 + 1;
        None
    }

    /// Claims a wave of `seed`'s component; false (having claimed some) when a cube of it
    /// was claimed by an earlier seed, whose component this is.
    pub(super) fn claim(&self, cubes: &[[u32; 3]], seed: usize) -> bool {
        let mut map = lock(&self.claims);
        cubes.iter().all(|&c| match self.claim_one(&mut map, c, seed) {
            Some(earlier) => earlier == seed,
            None => true,
        })
    }

    /// Claims the cube a seed's component starts from; the earlier seed holding it, if any.
    fn claim_start(&self, cube: [u32; 3], seed: usize) -> Option<usize> {
        self.claim_one(&mut lock(&self.claims), cube, seed).filter(|&s| s != seed)
    }

    /// The earliest seed claiming `cube`.
    fn owner(&self, cube: [u32; 3]) -> Option<usize> {
        let (key, i) = self.key(cube);
        let s = lock(&self.claims).get(&key)?[i];
        (s != 0).then(|| s as usize - 1)
    }

    /// Cubes claimed so far (by every thread), for progress.
    pub(super) fn cubes_claimed(&self) -> u64 {
        self.claimed.load(Ordering::Relaxed)
    }

    /// Bytes the other runs held when they last reported.
    pub(super) fn held_by_others(&self, me: usize) -> u64 {
        let all: u64 = self.held.iter().map(|h| h.load(Ordering::Relaxed)).sum();
        all - self.held[me].load(Ordering::Relaxed)
    }
}

impl<'a> Run<'a> {
    /// Finds the crossed cube of seed `index` and, unless a component holds it already,
    /// propagates from it; with `shared`, as one of several runs on their own threads. Its
    /// edge vertices go to root finding through `spawn` as they are made.
    fn seed(
        &mut self,
        index: usize,
        shared: Option<(&Shared, usize)>,
        spawn: &dyn Fn(Job<'a>),
    ) -> Result<Outcome, Error> {
        let seed = self.opts.seeds[index];
        let t = Instant::now();
        let before = (self.stats.search_evaluations, self.stats.corner_evaluations);
        let non_finite = self.stats.non_finite;
        let mut hit = self.walk(self.cubes.cube_of_u32(seed));
        let walk = self.lattice.take_fresh();
        let mut march_evaluations = 0;
        if hit.is_none() {
            // No crossing on the axes (a seed outside, looking past a small or far
            // component): the 26-direction march finds the nearest crossing and its cube.
            let (start, evals) = search_from(self.field, &self.grid, &self.cubes, seed)?;
            march_evaluations = evals;
            self.stats.search_evaluations += evals;
            if let Some(start) = start {
                let near = self.surface_cubes_near(std::iter::once(start.point()));
                hit = near[0].map(|cube| (cube, start));
            }
        }
        let mut outcome = Outcome {
            search_evaluations: self.stats.search_evaluations - before.0,
            corner_evaluations: self.stats.corner_evaluations - before.1,
            non_finite: self.stats.non_finite - non_finite,
            march_evaluations,
            walk,
            near: self.lattice.take_fresh(),
            search: t.elapsed(),
            hit,
            held_by: None,
            part: None,
        };
        let Some((cube, _)) = hit else { return Ok(outcome) };
        outcome.held_by = match shared {
            Some((s, _)) => s.claim_start(cube, index),
            None => self.lattice.owner(cube),
        };
        if outcome.held_by.is_some() {
            return Ok(outcome);
        }
        let (cells, vertices, triangles) =
            (self.lattice.visited(), self.vertices.len(), self.triangles.len());
        let (corners, non_finite, tetra) =
            (self.stats.corner_evaluations, self.stats.non_finite, self.stats.tetra_disagreements);
        self.stats.first_disagreement = None;
        let stops = self.propagate_with(cube, index, shared, spawn)?;
        outcome.part = Some(Part {
            run: shared.map_or(0, |s| s.1),
            vertices: vertices..self.vertices.len(),
            triangles: triangles..self.triangles.len(),
            cells: self.lattice.visited() - cells,
            corner_evaluations: self.stats.corner_evaluations - corners,
            non_finite: self.stats.non_finite - non_finite,
            tetra_disagreements: self.stats.tetra_disagreements - tetra,
            first_disagreement: self.stats.first_disagreement,
            stops,
            fresh: self.lattice.take_fresh(),
        });
        Ok(outcome)
    }
}

/// Propagates from each seed (see the module's documentation), on the current thread pool,
/// starting from `run` (fresh); returns the run holding every component's vertices and
/// triangles in seed order, with its statistics.
pub(super) fn propagate(mut run: Run<'_>) -> Result<Run<'_>, Error> {
    let t = Instant::now();
    let (grid, field, opts) = (run.grid, run.field, run.opts);
    let seeds = &opts.seeds;
    if let Some(&seed) = seeds.iter().find(|s| !grid.bounds().contains(**s)) {
        return Err(Error::BadSeed {
            seed: seed.to_array(),
            why: "it is outside the domain".into(),
        });
    }
    let mut values = vec![0.0; seeds.len()];
    field.eval_many(seeds, &mut values);
    if let Some((seed, f)) = seeds.iter().zip(&values).find(|(_, f)| !f.is_finite()) {
        return Err(Error::BadSeed {
            seed: seed.to_array(),
            why: format!("the field is {f} there"),
        });
    }
    let threads = rayon::current_num_threads().min(seeds.len());
    if threads > 1 && run.opts.limit.is_none() {
        match on_threads(&run, threads) {
            Ok((outcomes, mut runs, shared)) => {
                let owner = |cube, _: &Outcome| shared.owner(cube);
                let gathered = commit(&mut runs, outcomes, owner, t, threads)?;
                if let Some(done) = gathered {
                    return Ok(done);
                }
            }
            Err(Error::MemoryLimit { .. }) => {}
            Err(e) => return Err(e),
        }
    }
    let outcomes = rayon::scope(|s| {
        let spawn = super::pipe::spawner(s);
        (0..seeds.len()).map(|k| run.seed(k, None, &spawn)).collect::<Result<Vec<_>, _>>()
    })?;
    let seed_of = |_, o: &Outcome| o.held_by;
    let mut runs = vec![run];
    Ok(commit(&mut runs, outcomes, seed_of, t, 1)?.expect("one thread never falls back"))
}

/// Records the outcomes in seed order into the statistics and gathers the components'
/// vertices and triangles. `held_by` names the seed whose component holds a seed's cube
/// (`None` for the seed itself). On one thread the single run's arrays are the mesh
/// already; on several, they are gathered into a new run, or `None` is returned when the
/// components reached the cell budget (they are then propagated again on one thread).
fn commit<'a>(
    runs: &mut Vec<Run<'a>>,
    outcomes: Vec<Outcome>,
    held_by: impl Fn([u32; 3], &Outcome) -> Option<usize>,
    t: Instant,
    threads: usize,
) -> Result<Option<Run<'a>>, Error> {
    let several = threads > 1;
    let first = &runs[0];
    let (field, opts) = (first.field, first.opts);
    let mut out = Run::new(field, first.grid, opts);
    out.stats.search_evaluations = opts.seeds.len() as u64;
    let mut unfinished = Vec::new();
    let mut parts = Vec::new();
    let mut search = Duration::ZERO;
    let mut known = FxHashMap::default();
    for (k, o) in outcomes.into_iter().enumerate() {
        let (seed, stats) = (opts.seeds[k], &mut out.stats);
        if several {
            let (walk, bad) = recount(&mut known, &o.walk);
            stats.search_evaluations += walk + o.march_evaluations;
            let (near, bad_near) = recount(&mut known, &o.near);
            stats.corner_evaluations += near;
            stats.non_finite += bad + bad_near;
        } else {
            stats.search_evaluations += o.search_evaluations;
            stats.corner_evaluations += o.corner_evaluations;
            stats.non_finite += o.non_finite;
        }
        search += o.search;
        let Some((cube, start)) = o.hit else {
            stats.seed_notes.push(SeedNote::NoSurface { seed });
            continue;
        };
        match held_by(cube, &o).filter(|&s| s != k) {
            Some(as_seed) => stats.seed_notes.push(SeedNote::SameComponent { seed, as_seed }),
            None => {
                let Some(part) = o.part else { unreachable!("a seed first in its component") };
                if several && (part.stops.abandoned || part.stops.budget) {
                    debug_assert!(!part.stops.abandoned, "the first seed of a component finishes");
                    return Ok(None);
                }
                if several {
                    let (corners, bad) = recount(&mut known, &part.fresh);
                    stats.corner_evaluations += corners;
                    stats.non_finite += bad;
                } else {
                    stats.corner_evaluations += part.corner_evaluations;
                    stats.non_finite += part.non_finite;
                }
                stats.tetra_disagreements += part.tetra_disagreements;
                stats.first_disagreement = stats.first_disagreement.or(part.first_disagreement);
                stats.cells_visited += part.cells;
                stats.components.push(Component {
                    seed,
                    start: start.point(),
                    cells: part.cells,
                    triangles: part.triangles.len(),
                });
                out.record_stops(part.stops);
                unfinished.push(start);
                parts.push(part);
            }
        }
    }
    if several && out.stats.cells_visited > opts.max_cells {
        return Ok(None);
    }
    if unfinished.is_empty() {
        return Err(Error::BadSeed {
            seed: opts.seeds[0].to_array(),
            why: "no surface was found from it (or any other seed) along the lattice's axes or 26 directions within the domain".into(),
        });
    }
    let w = Instant::now();
    let finished: Vec<(DVec3, u64)> = unfinished.par_iter().map(|b| b.finish(field)).collect();
    for (c, (p, evals)) in out.stats.components.iter_mut().zip(finished) {
        c.start = p;
        out.stats.search_evaluations += evals;
    }
    // On several threads the walks' time is shared among them.
    out.stats.search = search / threads as u32 + w.elapsed();
    out.stats.propagation = t.elapsed().saturating_sub(out.stats.search);
    if !several {
        let mut run = runs.pop().expect("the one run");
        run.stats = out.stats;
        return Ok(Some(run));
    }
    gather(runs, &parts, &mut out);
    Ok(Some(out))
}

/// The points of `fresh` not in `known` and how many of them had a value that was not
/// finite; adds them to `known`.
///
/// This is how the evaluation counts on several threads come out as on one. One thread
/// evaluates a point the first time a seed's walk, march or component needs it, in seed
/// order. On several, a run evaluates what it needs and does not hold: everything it holds
/// came from earlier seeds (threads take seeds in order, and a component propagated for
/// nothing is an earlier seed's component), so what it evaluates holds every point the one
/// thread would evaluate for that seed, and some the one thread had already. Going through
/// the seeds in order and keeping only points not seen for an earlier seed gives the one
/// thread's counts: a point the one thread evaluates first for a seed is, on several
/// threads, evaluated for that seed too (no run could hold it yet), and so seen first there.
fn recount(known: &mut FxHashMap<u64, [u64; 8]>, fresh: &[Fresh]) -> (u64, u64) {
    let (mut new, mut bad) = (0, 0);
    for f in fresh {
        let k = known.entry(f.key).or_default();
        for ((k, &p), &b) in k.iter_mut().zip(&f.points).zip(&f.bad) {
            let n = p & !*k;
            new += u64::from(n.count_ones());
            bad += u64::from((n & b).count_ones());
            *k |= p;
        }
    }
    (new, bad)
}

/// Copies the components' vertices, segment-end values and triangles from the runs that
/// propagated them into `out`, in seed order, renumbering the triangles' vertices, each
/// component on a thread of its own; and the placed edge vertices of those components,
/// renumbered too (a chunk never spans two components; chunks of components propagated
/// for nothing are dropped, with their evaluations, as on one thread).
fn gather(runs: &mut [Run], parts: &[Part], out: &mut Run) {
    // Per run: its components' vertex ranges and where they start in `out`.
    let mut starts: Vec<Vec<(Range<usize>, usize)>> = runs.iter().map(|_| Vec::new()).collect();
    let mut base = 0;
    for p in parts {
        starts[p.run].push((p.vertices.clone(), base));
        base += p.vertices.len();
    }
    let mut refined: Vec<Refined> = Vec::new();
    for (r, starts) in runs.iter_mut().zip(&mut starts) {
        starts.sort_by_key(|s| s.0.start);
        for mut chunk in r.pipe.take() {
            let Some(&first) = chunk.ids.first() else { continue };
            let first = first as usize;
            let k = starts.partition_point(|s| s.0.start <= first);
            let Some((range, base)) = k.checked_sub(1).map(|k| &starts[k]) else { continue };
            if !range.contains(&first) {
                continue;
            }
            let shift = |i: &mut u32| *i = (*i as usize - range.start + base) as u32;
            chunk.ids.iter_mut().for_each(shift);
            refined.push(chunk);
        }
    }
    out.pipe.put(refined);
    let runs = &*runs;
    let vertices: usize = parts.iter().map(|p| p.vertices.len()).sum();
    let triangles: usize = parts.iter().map(|p| p.triangles.len()).sum();
    let unset = GridVertex { base: [0; 3], place: Place::Edge { dir: 0, t: 0.0 } };
    out.vertices = vec![unset; vertices];
    out.ends = vec![[0.0; 2]; vertices];
    out.triangles = vec![[0; 3]; triangles];
    let Run { vertices: v, ends: e, triangles: t, .. } = out;
    let (mut v, mut e, mut t) = (&mut v[..], &mut e[..], &mut t[..]);
    let mut jobs = Vec::with_capacity(parts.len());
    let mut base = 0;
    for p in parts {
        let n = p.vertices.len();
        let (pv, rest) = std::mem::take(&mut v).split_at_mut(n);
        v = rest;
        let (pe, rest) = std::mem::take(&mut e).split_at_mut(n);
        e = rest;
        let (pt, rest) = std::mem::take(&mut t).split_at_mut(p.triangles.len());
        t = rest;
        jobs.push((p, base, pv, pe, pt));
        base += n as u32;
    }
    jobs.into_par_iter().for_each(|(p, base, pv, pe, pt)| {
        let r = &runs[p.run];
        pv.copy_from_slice(&r.vertices[p.vertices.clone()]);
        pe.copy_from_slice(&r.ends[p.vertices.clone()]);
        let from = p.vertices.start as u32;
        for (o, t) in pt.iter_mut().zip(&r.triangles[p.triangles.clone()]) {
            *o = t.map(|i| i - from + base);
        }
    });
}

/// The loop of one thread and what it shares with the others.
#[derive(Clone, Copy)]
struct Work<'w, 'a> {
    shared: &'w Shared,
    /// Runs not taken by a thread.
    idle: &'w Mutex<Vec<(usize, Run<'a>)>>,
    outcomes: &'w Mutex<Vec<Option<Outcome>>>,
    /// The next seed to take.
    next: &'w AtomicUsize,
    /// Threads working (at most `threads`).
    working: &'w AtomicUsize,
    threads: usize,
    /// The error of the earliest seed that failed.
    failed: &'w Mutex<Option<(usize, Error)>>,
    stop: &'w AtomicBool,
}

impl<'w, 'a> Work<'w, 'a> {
    fn run(self, scope: &rayon::Scope<'w>)
    where
        'a: 'w,
    {
        let seeds = self.outcomes_len();
        let Some((me, mut run)) = lock(self.idle).pop() else { unreachable!("a run per thread") };
        loop {
            if self.stop.load(Ordering::Relaxed) {
                break;
            }
            let k = self.next.fetch_add(1, Ordering::Relaxed);
            if k >= seeds {
                break;
            }
            let spawn = super::pipe::spawner(scope);
            match run.seed(k, Some((self.shared, me)), &spawn) {
                Err(e) => {
                    let mut failed = lock(self.failed);
                    if failed.as_ref().is_none_or(|(j, _)| k < *j) {
                        *failed = Some((k, e));
                    }
                    self.stop.store(true, Ordering::Relaxed);
                    break;
                }
                Ok(o) => {
                    self.shared.held[me].store(run.held(), Ordering::Relaxed);
                    let part = o.part.as_ref().map(|p| p.stops.abandoned);
                    lock(self.outcomes)[k] = Some(o);
                    match part {
                        Some(true) => {
                            // Propagated for nothing: leave, unless the last thread.
                            let mut idle = lock(self.idle);
                            let dec = |n: usize| (n > 1).then(|| n - 1);
                            if self
                                .working
                                .fetch_update(Ordering::SeqCst, Ordering::SeqCst, dec)
                                .is_ok()
                            {
                                idle.push((me, run));
                                return;
                            }
                        }
                        Some(false) => self.add_threads(scope, seeds),
                        None => {}
                    }
                }
            }
        }
        let mut idle = lock(self.idle);
        idle.push((me, run));
        self.working.fetch_sub(1, Ordering::SeqCst);
    }

    fn outcomes_len(&self) -> usize {
        lock(self.outcomes).len()
    }

    /// Brings the threads working back up to `threads` while seeds are left.
    fn add_threads(self, scope: &rayon::Scope<'w>, seeds: usize)
    where
        'a: 'w,
    {
        let inc = |n: usize| (n < self.threads).then_some(n + 1);
        while self.next.load(Ordering::Relaxed) < seeds
            && self.working.fetch_update(Ordering::SeqCst, Ordering::SeqCst, inc).is_ok()
        {
            scope.spawn(move |s| self.run(s));
        }
    }
}

/// The seeds' outcomes with components propagated on `threads` threads at once, the runs
/// that hold them (by number) and the claims.
fn on_threads<'a>(
    first: &Run<'a>,
    threads: usize,
) -> Result<(Vec<Outcome>, Vec<Run<'a>>, Shared), Error> {
    let seeds = first.opts.seeds.len();
    let shared = Shared::new(first.grid.dims, threads);
    let runs = (0..threads).rev().map(|i| {
        let mut run = Run::new(first.field, first.grid, first.opts);
        run.lattice.track();
        (i, run)
    });
    let idle = Mutex::new(runs.collect::<Vec<_>>());
    let outcomes = Mutex::new((0..seeds).map(|_| None).collect::<Vec<_>>());
    let (next, working) = (AtomicUsize::new(0), AtomicUsize::new(threads));
    let (failed, stop) = (Mutex::new(None), AtomicBool::new(false));
    let work = Work {
        shared: &shared,
        idle: &idle,
        outcomes: &outcomes,
        next: &next,
        working: &working,
        threads,
        failed: &failed,
        stop: &stop,
    };
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(move |s| work.run(s));
        }
    });
    if let Some((_, e)) = failed.into_inner().unwrap_or_else(PoisonError::into_inner) {
        return Err(e);
    }
    let outcomes = outcomes.into_inner().unwrap_or_else(PoisonError::into_inner);
    let outcomes = outcomes.into_iter().map(|o| o.expect("every seed taken")).collect();
    let mut runs = idle.into_inner().unwrap_or_else(PoisonError::into_inner);
    runs.sort_by_key(|r| r.0);
    Ok((outcomes, runs.into_iter().map(|r| r.1).collect(), shared))
}
