//! Slab scheduling: the volume's cube layers are cut into slabs of [`SLAB`] layers (fixed,
//! so results never depend on the thread count); threads claim runs of neighbouring slabs,
//! lowest first, run each slab into a buffer of their own and hand it over, and each slab is
//! placed in the mesh as soon as every slab below it is, by whichever thread completes that
//! chain.

use std::any::Any;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::Instant;

use skelform_field::cpus::Spread;

use super::{BORROWED, Scratch, SlabVertex};
use crate::grid::assembly::Assembly;

/// Vertices and triangles, appended to by [`SlabStore`]: the mesh itself when one thread
/// runs every slab, else a thread's buffer for the slab it is running.
#[derive(Default)]
pub(super) struct Output<V> {
    pub(super) vertices: Vec<V>,
    pub(super) triangles: Vec<[u32; 3]>,
}

impl<V> Output<V> {
    /// How many vertices and triangles it holds room for: what a kept buffer is ranked by,
    /// since growing one writes into memory the system has to supply.
    fn capacity(&self) -> usize {
        self.vertices.capacity() + self.triangles.capacity()
    }
}

/// Makes room for at least `more` elements past the end of `v`, and for a few huge pages'
/// worth: room costs address space only until it is written, and growing by small steps
/// would copy into memory the kernel has not been asked to back with huge pages.
fn make_room<T>(v: &mut Vec<T>, more: usize) {
    if v.capacity() - v.len() < more {
        let step = skelform_field::pages::ROOM / std::mem::size_of::<T>().max(1);
        v.reserve(more.max(v.capacity()).max(step));
        skelform_field::pages::advise_huge(v.as_ptr(), v.capacity());
    }
}

/// What [`run_slabs`] returns: the mesh's vertices and triangles, and each slab's result in
/// slab order.
type Assembled<V, T> = (Vec<V>, Vec<[u32; 3]>, Vec<T>);

/// Runs `slab` on every slab and joins their pieces into one mesh, in slab order.
///
/// On one thread the slabs run in order straight into the mesh's arrays. On more, each
/// thread claims the lowest slabs no one has claimed (a run of them, see `claim`), runs each
/// into a buffer of its own and hands it over; a slab is placed in the mesh (an
/// [`Assembly`]) as soon as every slab below it has been handed over, by the thread that
/// completes that chain, so no thread ever waits for another, and every byte of the mesh is
/// written once. A slab's vertices go after all those of the slabs below it, its triangles'
/// numbers shifted by as many (a reference to the layer above, numbered just past the slab's
/// own vertices, lands on the next slab's first ones).
///
/// On any number of threads the vertices and triangles go into `reuse` (emptied first),
/// whose capacity is kept as it is when it has some: a caller's arrays from its last
/// extraction, already in memory (on more threads the slabs are placed there).
pub(super) fn run_slabs<V, T, E>(
    slabs: usize,
    [nx, ny]: [usize; 2],
    workspace: &Workspace,
    reuse: (Vec<V>, Vec<[u32; 3]>),
    slab: impl Fn(usize, &mut Scratch, &mut SlabStore<V>) -> Result<T, E> + Sync,
) -> Result<Assembled<V, T>, E>
where
    V: SlabVertex,
    T: Send,
    E: Send,
{
    let threads = rayon::current_num_threads().min(slabs);
    if threads <= 1 {
        let reused = [reuse.0.capacity() > 0, reuse.1.capacity() > 0];
        let mut out = Output { vertices: reuse.0, triangles: reuse.1 };
        out.vertices.clear();
        out.triangles.clear();
        let mut scratch = Scratch::new(nx, ny);
        let (mut hint, mut results) = ((0, 0), Vec::with_capacity(slabs));
        for k in 0..slabs {
            let before = (out.vertices.len(), out.triangles.len());
            results.push(slab(k, &mut scratch, &mut SlabStore::new(&mut out, hint))?);
            hint = (out.vertices.len() - before.0, out.triangles.len() - before.1);
        }
        if !reused[0] {
            out.vertices.shrink_to_fit();
        }
        if !reused[1] {
            out.triangles.shrink_to_fit();
        }
        return Ok((out.vertices, out.triangles, results));
    }
    // The mesh goes into the memory of `reuse` where it has some (see `Assembly::from_vec`).
    let reused = [reuse.0.capacity() > 0, reuse.1.capacity() > 0];
    let (vertices, triangles) = (Assembly::from_vec(reuse.0), Assembly::from_vec(reuse.1));
    let ([nv, nt], results) =
        place_slabs(threads, slabs, [nx, ny], workspace, &vertices, &triangles, false, slab)?;
    // SAFETY: every slab was placed (`place_slabs`): slab k wrote vertices and triangles
    // from the ends of slab k − 1's, as many as it has, so together they cover 0..nv and
    // 0..nt.
    let (vertices, triangles) =
        unsafe { (vertices.into_vec(nv, reused[0]), triangles.into_vec(nt, reused[1])) };
    Ok((vertices, triangles, results))
}

/// Where `run_slabs_sunk` puts the mesh's vertices: each slab's, as soon as their numbers
/// in the mesh are known, while the slab's records are still in the cache. A caller that
/// converts the records anyway (into the arrays it hands on) writes them there straight
/// away, with no mesh of records written to memory and read back in between.
pub trait VertexSink<V>: Sync {
    /// Makes room for at least `needed` vertices, for `wanted` if it has to grow (a guess
    /// at the final count).
    fn reserve(&self, needed: usize, wanted: usize);

    /// Takes vertices `first..first + vertices.len()` of the mesh.
    ///
    /// # Safety
    /// Those vertices lie within a size [`reserve`](Self::reserve)d before, and no other
    /// call takes any of them: each slab's range is its own (calls for different slabs may
    /// run at once, on different threads, in any order), and together they cover the mesh.
    unsafe fn place(&self, first: usize, vertices: &[V]);
}

impl<V: Copy + Send + Sync> VertexSink<V> for Assembly<V> {
    fn reserve(&self, needed: usize, wanted: usize) {
        Assembly::reserve(self, needed, wanted);
    }

    unsafe fn place(&self, first: usize, vertices: &[V]) {
        // SAFETY: the trait's contract is `Assembly::place`'s.
        unsafe { Assembly::place(self, first, vertices) }
    }
}

/// What [`run_slabs_sunk`] returns: the mesh's vertex count, its triangles, and each slab's
/// result in slab order.
type Sunk<T> = (usize, Vec<[u32; 3]>, Vec<T>);

/// [`run_slabs`] with the vertices handed to `sink` (see [`VertexSink`]) instead of kept in
/// one vector of records; returns their count, the triangles and each slab's result. The
/// triangles go into `reuse` (emptied first), as in [`run_slabs`]: on one thread the slabs
/// write them there themselves, numbered in the mesh; on more, each slab's are placed there
/// (shifted) as its vertices are. On one thread the records of each slab go to one buffer,
/// which stays in the cache from slab to slab, and on to `sink` when the slab is done.
pub(super) fn run_slabs_sunk<V, T, E>(
    slabs: usize,
    [nx, ny]: [usize; 2],
    workspace: &Workspace,
    sink: &impl VertexSink<V>,
    reuse: Vec<[u32; 3]>,
    slab: impl Fn(usize, &mut Scratch, &mut SlabStore<V>) -> Result<T, E> + Sync,
) -> Result<Sunk<T>, E>
where
    V: SlabVertex,
    T: Send,
    E: Send,
{
    let threads = rayon::current_num_threads().min(slabs);
    let reused = reuse.capacity() > 0;
    if threads <= 1 {
        // A kept buffer's vertices; its triangles (the mesh's go into `reuse`) are set aside
        // and kept with it again, for runs on more threads, which write triangles there.
        let kept = workspace.take::<V>().unwrap_or_default();
        let mut out = Output { vertices: kept.vertices, triangles: reuse };
        out.triangles.clear();
        let mut scratch = Scratch::new(nx, ny);
        let (mut hint, mut results, mut made) = ((0, 0), Vec::with_capacity(slabs), 0usize);
        for k in 0..slabs {
            out.vertices.clear();
            let before = out.triangles.len();
            // The slab's vertices are numbered on from those sunk already.
            let mut store = SlabStore::numbered(&mut out, hint, made as u32);
            results.push(slab(k, &mut scratch, &mut store)?);
            let n = out.vertices.len();
            let end = made + n;
            sink.reserve(end, room_for_all(end, k + 1, slabs));
            // SAFETY: reserved just above; the slabs' ranges follow each other.
            unsafe { sink.place(made, &out.vertices) };
            made = end;
            hint = (n, out.triangles.len() - before);
        }
        if !reused {
            out.triangles.shrink_to_fit();
        }
        let triangles = std::mem::replace(&mut out.triangles, kept.triangles);
        // As many kept as runs on more threads keep (`place_slabs`), so that alternating
        // runs do not drop and remake buffers.
        workspace.keep(vec![out], slabs);
        return Ok((made, triangles, results));
    }
    let triangles = Assembly::from_vec(reuse);
    // Tight buffers, as many as the slabs need: see `place_slabs`.
    let ([nv, nt], results) =
        place_slabs(threads, slabs, [nx, ny], workspace, sink, &triangles, true, slab)?;
    // SAFETY: every slab's triangles were placed (`place_slabs`), together covering 0..nt.
    let triangles = unsafe { triangles.into_vec(nt, reused) };
    Ok((nv, triangles, results))
}

/// The slabs on `threads` (two or more) workers, each slab's vertices handed to `vertices`
/// and its triangles placed in `triangles` (shifted) as soon as every slab below it has been
/// handed over (see [`run_slabs`]); returns the mesh's vertex and triangle counts, which the
/// placed ranges cover, and each slab's result in slab order.
///
/// A slab waits in its buffer until the slabs below it are handed over, so a thread that
/// runs ahead of another (on lighter slabs, or while the other is descheduled) takes a
/// buffer per slab. With `tight`, each buffer makes room for about its thread's last slab
/// only, not for huge pages' worth, and every buffer is kept for the next run: a run that
/// needs many takes kept ones rather than fresh memory that costs page faults (the
/// memory held is about one mesh's). Otherwise two per thread are kept.
#[allow(clippy::too_many_arguments)]
fn place_slabs<V, T, E>(
    threads: usize,
    slabs: usize,
    [nx, ny]: [usize; 2],
    workspace: &Workspace,
    vertices: &impl VertexSink<V>,
    triangles: &Assembly<[u32; 3]>,
    tight: bool,
    slab: impl Fn(usize, &mut Scratch, &mut SlabStore<V>) -> Result<T, E> + Sync,
) -> Result<([usize; 2], Vec<T>), E>
where
    V: SlabVertex,
    T: Send,
    E: Send,
{
    let chain = Mutex::new(Chain::new(slabs));
    let lock = || chain.lock().unwrap_or_else(|e| e.into_inner());
    claim_slabs(threads, slabs, [nx, ny], |k, scratch, hint| {
        let spare = lock().spare.pop();
        let mut out = spare.or_else(|| workspace.take()).unwrap_or_default();
        out.vertices.clear();
        out.triangles.clear();
        let mut store = SlabStore::new(&mut out, *hint);
        store.tight = tight;
        let result = slab(k, scratch, &mut store);
        *hint = (out.vertices.len(), out.triangles.len());
        let (ready, [nv, nt], placed) = match result {
            Ok(r) => lock().hand_over(k, r, out),
            Err(e) => {
                lock().fail(k, e);
                return false;
            }
        };
        if !ready.is_empty() {
            // Growing copies what has been placed, unless the allocator can remap it.
            vertices.reserve(nv, room_for_all(nv, placed, slabs));
            triangles.reserve(nt, room_for_all(nt, placed, slabs));
        }
        for (o, [v0, t0]) in &ready {
            let shift = *v0 as u32;
            // SAFETY: the chain hands each slab over once, with the ends of the slabs below
            // it as its start, so slabs' ranges are disjoint; reserved above up to the end
            // of the last ready slab.
            unsafe {
                vertices.place(*v0, &o.vertices);
                triangles.place_shifted(*t0, &o.triangles, shift);
            }
        }
        lock().spare.extend(ready.into_iter().map(|(o, _)| o));
        true
    });
    let mut chain = chain.into_inner().unwrap_or_else(|e| e.into_inner());
    let most = if tight { slabs } else { 2 * threads };
    workspace.keep(std::mem::take(&mut chain.spare), most);
    if let Some((_, e)) = chain.error {
        return Err(e);
    }
    assert_eq!(chain.placed, slabs, "a slab was never placed");
    let results = chain.results.into_iter().flatten().collect();
    Ok((chain.end, results))
}

/// Room to reserve once `done` of `slabs` slabs have made `n` items: theirs, and the rest's
/// if they are like them, with a margin (saturating: a guess, never a size that overflows).
fn room_for_all(n: usize, done: usize, slabs: usize) -> usize {
    let rest = (n / done.max(1)).saturating_mul(slabs.saturating_sub(done) + 1);
    n.saturating_add(rest.saturating_mul(5) / 4)
}

/// Runs `each` on slabs `0..slabs` on `threads` workers (the calling thread alone for one),
/// each with a [`Scratch`] and a size hint of its own, which `each` updates; workers claim
/// runs of neighbouring slabs, lowest first ([`claim`]), and run a run's slabs in order.
/// `each` returns false to stop every worker from running another slab (an error).
fn claim_slabs(
    threads: usize,
    slabs: usize,
    [nx, ny]: [usize; 2],
    each: impl Fn(usize, &mut Scratch, &mut (usize, usize)) -> bool + Sync,
) {
    let (next, stop) = (AtomicUsize::new(0), AtomicBool::new(false));
    let pace = Pace::default();
    // Workers kept on CPUs of their own (see `Spread`): two sharing one take turns.
    let spread = Spread::new(threads);
    let work = |w: usize| {
        let mut scratch = Scratch::new(nx, ny);
        let mut hint = (0, 0);
        let mut placement = spread.placement(w);
        let mut last = None;
        while !stop.load(Ordering::Relaxed) {
            let Some(run) = claim(&next, slabs, threads, pace.weight(last)) else { break };
            for k in run {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                if threads > 1 {
                    placement.check();
                }
                let started = Instant::now();
                if !each(k, &mut scratch, &mut hint) {
                    stop.store(true, Ordering::Relaxed);
                    break;
                }
                last = Some(pace.ran(started.elapsed()));
            }
        }
    };
    if threads <= 1 {
        work(0);
    } else {
        rayon::scope(|s| {
            for w in 0..threads {
                let work = &work;
                s.spawn(move |_| work(w));
            }
        });
    }
}

/// How long the slabs run so far took, all workers together: what a worker's last slab is
/// weighed against when it claims a run ([`claim`]).
#[derive(Default)]
struct Pace {
    slabs: AtomicUsize,
    nanos: AtomicU64,
}

impl Pace {
    /// Counts a slab that took `took`; returns its time in nanoseconds (at least 1).
    fn ran(&self, took: std::time::Duration) -> u64 {
        let nanos = u64::try_from(took.as_nanos()).unwrap_or(u64::MAX).max(1);
        self.slabs.fetch_add(1, Ordering::Relaxed);
        self.nanos.fetch_add(nanos, Ordering::Relaxed);
        nanos
    }

    /// The weight of a worker's next slabs: its last slab's time (`last`, from [`ran`]) as
    /// a multiple of the mean slab's, at least 1; 1 before it has run one.
    ///
    /// [`ran`]: Pace::ran
    fn weight(&self, last: Option<u64>) -> f64 {
        let Some(last) = last else { return 1.0 };
        let slabs = self.slabs.load(Ordering::Relaxed).max(1);
        let mean = self.nanos.load(Ordering::Relaxed) as f64 / slabs as f64;
        (last as f64 / mean.max(1.0)).max(1.0)
    }
}

/// Claims the next run of slabs for a worker of `threads` whose next slabs weigh `weight`
/// mean slabs each ([`Pace::weight`]): about half of a worker's even share of the work left,
/// reckoned in mean slabs, so a run shrinks as the volume is used up, and is shorter where
/// the surface is heavy (neighbouring slabs of a surface make about as much of it), at least
/// one slab.
///
/// A worker runs neighbouring slabs in a row for most of the volume, each starting on sample
/// layers that the slab before it, ending there, just read or fetched (a slab apart from the
/// last one starts on layers no one has read lately, a few hundred kilobytes from memory
/// before it can go on), while the last claims are single slabs that keep the workers
/// finishing together. Runs counted in slabs alone let a worker take a heavy band of the
/// surface late (a torus lying across the slabs: three slabs, half the work left) and finish
/// a millisecond after the others ran out of empty ones.
fn claim(
    next: &AtomicUsize,
    slabs: usize,
    threads: usize,
    weight: f64,
) -> Option<std::ops::Range<usize>> {
    let mut at = next.load(Ordering::Relaxed);
    loop {
        let left = slabs.checked_sub(at).filter(|&l| l > 0)?;
        let share = left / (2 * threads);
        // `as` saturates and turns NaN into 0; a weight is at least 1, so this is at most
        // `share`.
        let take = ((share as f64 / weight) as usize).clamp(1, share.max(1));
        match next.compare_exchange_weak(at, at + take, Ordering::Relaxed, Ordering::Relaxed) {
            Ok(_) => return Some(at..at + take),
            Err(now) => at = now,
        }
    }
}

/// Slab buffers kept from one extraction to the next, so that a program that extracts again
/// (frames of an animation, a benchmark's runs) does not fault in fresh pages for them every
/// time: memory the size of a few slabs' meshes per thread.
///
/// Extraction without one of its own uses a workspace shared by the whole process, which is
/// right for a command line run; a long-lived program that wants that memory back, or
/// separate runs that should not share it, passes its own (see
/// [`crate::grid::Options::workspace`]) and drops it when done. Buffers are reused only
/// between runs, never by two runs at once, so the mesh never depends on the workspace.
#[derive(Default)]
pub struct Workspace {
    kept: Mutex<Vec<Box<dyn Any + Send>>>,
}

impl std::fmt::Debug for Workspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let held = self.kept.lock().map_or(0, |k| k.len());
        f.debug_struct("Workspace").field("buffers", &held).finish()
    }
}

impl Workspace {
    /// An empty workspace: buffers are allocated by the first run and kept for the next.
    pub const fn new() -> Self {
        Workspace { kept: Mutex::new(Vec::new()) }
    }

    /// The process's workspace, for runs that bring none.
    pub fn shared() -> &'static Workspace {
        static SHARED: Workspace = Workspace::new();
        &SHARED
    }

    /// A kept buffer for vertices of type `V`, the largest, if there is one.
    fn take<V: Send + 'static>(&self) -> Option<Output<V>> {
        let mut kept = self.kept.lock().unwrap_or_else(|e| e.into_inner());
        // The largest (see `Output::capacity`).
        let (at, _) = (kept.iter().enumerate())
            .filter_map(|(i, b)| Some((i, b.downcast_ref::<Output<V>>()?.capacity())))
            .max_by_key(|&(_, room)| room)?;
        kept.swap_remove(at).downcast().ok().map(|b| *b)
    }

    /// Keeps `buffers` for the next extraction, and no more than `most` of their type: the
    /// largest, when there are more.
    fn keep<V: Send + 'static>(&self, mut buffers: Vec<Output<V>>, most: usize) {
        buffers.sort_by_key(|o| std::cmp::Reverse(o.capacity()));
        let mut kept = self.kept.lock().unwrap_or_else(|e| e.into_inner());
        let held = kept.iter().filter(|b| b.is::<Output<V>>()).count();
        let room = most.saturating_sub(held);
        kept.extend(buffers.into_iter().take(room).map(|b| Box::new(b) as Box<dyn Any + Send>));
    }
}

/// Which slabs have been handed over and placed, for [`run_slabs`].
struct Chain<V, T, E> {
    /// The slabs below this one are placed.
    placed: usize,
    /// Where the next slab to place starts: its first vertex and first triangle.
    end: [usize; 2],
    /// Handed-over slabs not yet placed, by index.
    waiting: Vec<Option<Output<V>>>,
    results: Vec<Option<T>>,
    /// The failure of the lowest slab that failed.
    error: Option<(usize, E)>,
    /// Buffers of placed slabs, for the next slabs to run.
    spare: Vec<Output<V>>,
}

/// Slabs ready to be placed: each slab's output, with where its vertices and triangles start.
type Ready<V> = Vec<(Output<V>, [usize; 2])>;

impl<V, T, E> Chain<V, T, E> {
    fn new(slabs: usize) -> Self {
        Chain {
            placed: 0,
            end: [0, 0],
            waiting: (0..slabs).map(|_| None).collect(),
            results: (0..slabs).map(|_| None).collect(),
            error: None,
            spare: Vec::new(),
        }
    }

    /// Takes slab `k`'s output; returns the slabs that can now be placed (`k` and those
    /// after it, if all before it are placed), the end of the last of them, and how many
    /// slabs are then placed.
    fn hand_over(&mut self, k: usize, result: T, out: Output<V>) -> (Ready<V>, [usize; 2], usize) {
        self.results[k] = Some(result);
        self.waiting[k] = Some(out);
        let mut ready = Vec::new();
        while let Some(o) = self.waiting.get_mut(self.placed).and_then(Option::take) {
            let start = self.end;
            self.end = [start[0] + o.vertices.len(), start[1] + o.triangles.len()];
            self.placed += 1;
            ready.push((o, start));
        }
        (ready, self.end, self.placed)
    }

    /// Records slab `k`'s failure; the lowest slab's failure is the one reported.
    fn fail(&mut self, k: usize, e: E) {
        if self.error.as_ref().is_none_or(|(at, _)| k < *at) {
            self.error = Some((k, e));
        }
    }
}

/// Where a slab's vertices and triangles go: the end of an [`Output`]. A vertex's number is
/// its index there; a triangle may name vertex `n` of the layer above, which the next slab
/// makes, as `BORROWED | n` until [`SlabStore::finish`] numbers it.
pub(super) struct SlabStore<'a, V> {
    out: &'a mut Output<V>,
    /// The sizes of the thread's previous slab: neighbouring slabs of a smooth surface make
    /// about as many vertices and triangles.
    hint: (usize, usize),
    /// The first triangle that may refer to the layer above.
    borrowing: usize,
    /// The number of the output's first vertex: the vertices of earlier slabs that are no
    /// longer in it ([`run_slabs_sunk`] on one thread).
    first: u32,
    /// Room made for the hint alone, not for huge pages' worth (see [`place_slabs`]).
    tight: bool,
}

impl<'a, V: SlabVertex> SlabStore<'a, V> {
    pub(super) fn new(out: &'a mut Output<V>, hint: (usize, usize)) -> Self {
        let borrowing = usize::MAX;
        SlabStore { out, hint, borrowing, first: 0, tight: false }
    }

    /// A store whose vertices are numbered from `first` on (see `first`).
    fn numbered(out: &'a mut Output<V>, hint: (usize, usize), first: u32) -> Self {
        SlabStore { first, ..SlabStore::new(out, hint) }
    }

    pub(super) fn begin(&mut self) {
        if self.tight {
            self.out.vertices.reserve(self.hint.0 + self.hint.0 / 4);
            self.out.triangles.reserve(self.hint.1 + self.hint.1 / 4);
            return;
        }
        make_room(&mut self.out.vertices, 2 * self.hint.0);
        make_room(&mut self.out.triangles, 2 * self.hint.1);
        debug_assert!((self.first as usize + self.out.vertices.len()) < BORROWED as usize);
    }

    /// How many vertices and triangles the output holds (a slab's own are the difference
    /// between its end and its start).
    pub(super) fn lens(&self) -> [usize; 2] {
        [self.out.vertices.len(), self.out.triangles.len()]
    }

    /// The number of the next vertex.
    #[inline]
    pub(super) fn made(&self) -> u32 {
        self.first + self.out.vertices.len() as u32
    }

    #[inline]
    pub(super) fn push_vertex(&mut self, v: V) {
        self.out.vertices.push(v);
    }

    #[inline]
    pub(super) fn push_triangle(&mut self, t: [u32; 3]) {
        self.out.triangles.push(t);
    }

    /// Appends the triangles of `ts`, whose length is known ahead (a slice's, mapped): the
    /// vector makes room once and writes them without a check each.
    #[inline]
    pub(super) fn push_triangles(&mut self, ts: impl ExactSizeIterator<Item = [u32; 3]>) {
        self.out.triangles.extend(ts);
    }

    /// Triangles from now on may refer to the layer above.
    pub(super) fn borrow_top(&mut self) {
        self.borrowing = self.out.triangles.len();
    }

    /// Ends the slab: the next slab's vertices will be numbered from here, its bottom
    /// layer's first, so `BORROWED | n` becomes the number `n` past the slab's last vertex.
    pub(super) fn finish(&mut self) {
        let next = self.made();
        if let Some(ts) = self.out.triangles.get_mut(self.borrowing..) {
            for t in ts {
                *t = t.map(|i| if i & BORROWED == 0 { i } else { next + (i & !BORROWED) });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_hands_out_its_largest_buffer_and_keeps_the_largest() {
        let buffer = |v: usize, t: usize| Output::<u8> {
            vertices: Vec::with_capacity(v),
            triangles: Vec::with_capacity(t),
        };
        let ws = Workspace::new();
        ws.keep(vec![buffer(10, 0), buffer(300, 700), buffer(0, 0)], 8);
        let got = ws.take::<u8>().unwrap();
        assert!(got.vertices.capacity() >= 300 && got.triangles.capacity() >= 700);
        assert!(ws.take::<u8>().unwrap().vertices.capacity() >= 10);
        assert!(ws.take::<u16>().is_none(), "buffers of another vertex type are not handed out");
        // Past the most kept, the smallest go.
        let ws = Workspace::new();
        ws.keep(vec![buffer(1, 1), buffer(500, 500), buffer(50, 50)], 2);
        let sizes: Vec<usize> =
            std::iter::from_fn(|| ws.take::<u8>()).map(|o| o.vertices.capacity()).collect();
        assert!(sizes.len() == 2 && sizes[0] >= 500 && sizes[1] >= 50 && sizes[1] < 500);
    }

    #[test]
    fn claimed_runs_cover_every_slab_once_in_order_and_end_single() {
        for slabs in [1, 2, 7, 32, 33, 250] {
            for threads in [2, 3, 8] {
                for weight in [1.0, 1.7, 40.0, f64::INFINITY] {
                    let next = AtomicUsize::new(0);
                    let claims = std::iter::from_fn(|| claim(&next, slabs, threads, weight));
                    let runs: Vec<_> = claims.collect();
                    let covered: Vec<usize> = runs.iter().flat_map(|r| r.clone()).collect();
                    let case = format!("{slabs} slabs, {threads} threads, weight {weight}");
                    assert_eq!(covered, (0..slabs).collect::<Vec<_>>(), "{case}");
                    assert!(runs.windows(2).all(|w| w[1].len() <= w[0].len()), "runs shrink");
                    // The last runs are single slabs, one per worker at least.
                    let tail = runs.iter().rev().take(threads.min(slabs)).all(|r| r.len() == 1);
                    assert!(tail, "{case}: {runs:?}");
                    assert!(claim(&next, slabs, threads, weight).is_none());
                }
            }
        }
    }

    #[test]
    fn a_worker_whose_last_slab_was_heavy_claims_fewer() {
        let first = |weight| claim(&AtomicUsize::new(4), 36, 2, weight).map(|r| r.len());
        // Half of a worker's share of the 32 slabs left; a third of that for slabs three
        // times the mean; one for heavier.
        assert_eq!([first(1.0), first(3.0), first(20.0)], [Some(8), Some(2), Some(1)]);
        let pace = Pace::default();
        assert_eq!(pace.weight(None), 1.0, "no slab run yet");
        let ms = std::time::Duration::from_millis;
        let [light, heavy] = [pace.ran(ms(1)), pace.ran(ms(3))];
        assert_eq!((pace.weight(Some(light)), pace.weight(Some(heavy))), (1.0, 1.5));
    }
}
