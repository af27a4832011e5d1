//! Root finding overlapped with propagation, for runs that keep corner gradients.
//!
//! An edge vertex's bracket (its segment's ends, their values and gradients) is final as
//! soon as the vertex is made, and its root depends on nothing else (a value depends on its
//! point alone). So while a thread propagates (one wave after another, mostly serial), the
//! vertices it has made are refined on the pool: each full chunk of [`CHUNK`] edge
//! vertices, in the order they were made, is spawned as a job on the run's scope as soon as
//! the wave that completes it is processed, and at the end of a component the rest of its
//! vertices is one last, shorter chunk. Why: on the hand (one component) the second core
//! was mostly idle during propagation, and root finding, run after it, was a third of the
//! run's wall time.
//!
//! Chunks never span two components, so they are the same on any thread count (a component
//! is propagated whole by one run, its vertices numbered from its start, see `seeds`), and
//! a component propagated for nothing (an earlier seed's) takes its chunks with it when it
//! is dropped. Each vertex is refined as `refine_roots_with_gradients` refines it, so the
//! mesh is the one refining after propagation gives, byte for byte.
//!
//! A job that starts after the run's control was cancelled refines nothing and says so; the
//! run then ends with [`crate::Error::Cancelled`] rather than a mesh with vertices left out.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use glam::DVec3;
use skelform_field::Field;
use skelform_field::control::Control;

use crate::lattice::memory::vec_bytes;
// Edge vertices per job are `refine`'s chunk (`CHUNK`), so that a job is one batch per
// iteration.
use crate::refine::{
    CHUNK, GradBracket, RootMethod, RootOptions, hermite_roots, refine_roots_with_gradients,
    unit_normal,
};

/// What refining needs, the same for every job of a run.
#[derive(Clone, Copy)]
pub(super) struct How<'a> {
    pub field: &'a dyn Field,
    pub roots: RootOptions,
    /// Whether vertex normals are wanted.
    pub normals: bool,
    /// Whether the field's colours are taken in root finding's evaluations (a field with
    /// colours, not with Hermite roots, which evaluate nothing).
    pub colors: bool,
    pub control: &'a Control,
}

/// Edge vertices of one run whose brackets are final, waiting to be handed over, and what
/// the run's jobs have refined.
#[derive(Default)]
pub(super) struct Pipe {
    /// The run's numbers of the vertices waiting, and their brackets.
    ids: Vec<u32>,
    brackets: Vec<GradBracket>,
    done: Arc<Done>,
}

/// What a run's jobs share: their results, and counts for memory and cancellation.
#[derive(Default)]
struct Done {
    refined: Mutex<Vec<Refined>>,
    /// Bytes of the brackets handed over and not refined yet, and of the results.
    bytes: AtomicU64,
    /// Whether a job found the control cancelled and refined nothing.
    skipped: AtomicBool,
}

/// The vertices of one chunk, placed.
pub(super) struct Refined {
    /// The run's numbers of the vertices.
    pub ids: Vec<u32>,
    pub positions: Vec<DVec3>,
    /// Unit normals from the root finding's last gradients (empty without normals).
    pub normals: Vec<[f32; 3]>,
    /// The field's colours (empty without colours).
    pub colors: Vec<[f32; 3]>,
    /// Field evaluations made.
    pub evals: u64,
}

impl Refined {
    fn bytes(&self) -> u64 {
        vec_bytes(&self.ids)
            + vec_bytes(&self.positions)
            + vec_bytes(&self.normals)
            + vec_bytes(&self.colors)
    }
}

/// One chunk to refine, on any thread.
pub(super) struct Job<'a> {
    how: How<'a>,
    ids: Vec<u32>,
    brackets: Vec<GradBracket>,
    done: Arc<Done>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Job<'_> {
    /// Refines the chunk and leaves the result with the run's others.
    pub fn run(self) {
        let Job { how, ids, mut brackets, done } = self;
        let held = vec_bytes(&brackets);
        if how.control.is_cancelled() {
            done.skipped.store(true, Ordering::Relaxed);
            done.bytes.fetch_sub(held, Ordering::Relaxed);
            return;
        }
        let mut colors = vec![[0f32; 3]; if how.colors { brackets.len() } else { 0 }];
        let evals = if how.roots.method == RootMethod::Hermite {
            hermite_roots(&mut brackets, &how.roots);
            0
        } else {
            let shades = how.colors.then_some(&mut colors[..]);
            refine_roots_with_gradients(how.field, &mut brackets, &how.roots, shades)
        };
        let positions = brackets.iter().map(|b| b.p0.lerp(b.p1, b.t)).collect();
        let normals = if how.normals {
            brackets.iter().map(|b| unit_normal(b.grad)).collect()
        } else {
            Vec::new()
        };
        let r = Refined { ids, positions, normals, colors, evals };
        done.bytes.fetch_add(r.bytes(), Ordering::Relaxed);
        done.bytes.fetch_sub(held, Ordering::Relaxed);
        lock(&done.refined).push(r);
    }
}

impl Pipe {
    /// Adds the bracket of vertex `id`, just made.
    pub fn push(&mut self, id: u32, bracket: GradBracket) {
        self.ids.push(id);
        self.brackets.push(bracket);
    }

    /// Hands the waiting vertices over in full chunks (and, with `all`, the rest as one
    /// shorter chunk), each to `spawn`, or refined here and now without one.
    pub fn hand_over<'a>(&mut self, how: How<'a>, spawn: Option<&dyn Fn(Job<'a>)>, all: bool) {
        // Each bracket is copied once, into its job; the waiting ones keep their storage.
        let n = if all { self.ids.len() } else { self.ids.len() / CHUNK * CHUNK };
        if n == 0 {
            return;
        }
        for (ids, brackets) in self.ids[..n].chunks(CHUNK).zip(self.brackets[..n].chunks(CHUNK)) {
            let brackets = brackets.to_vec();
            self.done.bytes.fetch_add(vec_bytes(&brackets), Ordering::Relaxed);
            let job = Job { how, ids: ids.to_vec(), brackets, done: Arc::clone(&self.done) };
            match spawn {
                Some(spawn) => spawn(job),
                None => job.run(),
            }
        }
        self.ids.drain(..n);
        self.brackets.drain(..n);
    }

    /// Drops the waiting vertices (of a component propagated for nothing, or of a failed
    /// run).
    pub fn discard(&mut self) {
        self.ids.clear();
        self.brackets.clear();
    }

    /// Bytes held: the waiting brackets, those handed over and not refined yet, and the
    /// results.
    pub fn bytes(&self) -> u64 {
        vec_bytes(&self.ids) + vec_bytes(&self.brackets) + self.done.bytes.load(Ordering::Relaxed)
    }

    /// Whether a job refined nothing because the run was cancelled.
    pub fn skipped(&self) -> bool {
        self.done.skipped.load(Ordering::Relaxed)
    }

    /// The results so far (every job's, once the scope they were spawned on has ended).
    pub fn take(&mut self) -> Vec<Refined> {
        let r = std::mem::take(&mut *lock(&self.done.refined));
        self.done.bytes.store(0, Ordering::Relaxed);
        r
    }

    /// Adds results (renumbered for this run).
    pub fn put(&mut self, refined: Vec<Refined>) {
        let bytes: u64 = refined.iter().map(Refined::bytes).sum();
        self.done.bytes.fetch_add(bytes, Ordering::Relaxed);
        lock(&self.done.refined).extend(refined);
    }
}

/// Spawns each job on `scope` (whose end waits for them all).
pub(super) fn spawner<'s, 'scope, 'a: 'scope>(
    scope: &'s rayon::Scope<'scope>,
) -> impl Fn(Job<'a>) + 's {
    move |job| scope.spawn(move |_| job.run())
}
