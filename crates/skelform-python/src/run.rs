//! Running long work from Python: off the GIL, as a job on the rayon pool that does the
//! work, with Ctrl-C and the caller's progress callback both served on the caller's thread.
//!
//! Why the caller's thread waits apart from the work: while Rust code runs, Python cannot
//! deliver a signal (its handler runs only between bytecodes of the main thread). The
//! caller's thread therefore hands the work to the pool and waits in short slices with the
//! GIL released, and between slices checks for signals and reports progress; a signal or a
//! callback that asks to stop cancels the work through its [`Control`], and the work is
//! always waited for to the end, so that nothing it borrows outlives the call and no worker
//! is left holding (or waiting for) the GIL.
//!
//! The work goes to the pool straight from the caller's thread (no thread started per call,
//! no second hand-over from a thread of the call's own to the pool), and says it is done
//! through a flag of its own, set before the waiting thread is woken: a wake-up is never
//! mistaken for the end, nor the end missed until the slice runs out.

use std::ops::ControlFlow;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread;
use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use skelform::field::cpus;
use skelform::{Control, MAX_THREADS, Progress};

use crate::errors::Cancelled;

/// How often the waiting thread wakes to look at signals and progress.
const SLICE: Duration = Duration::from_millis(40);

/// The run's latest progress, written by the workers and read by the caller's thread.
#[derive(Default)]
struct Latest {
    progress: Option<(String, u64, Option<u64>)>,
    reported: bool,
}

/// A [`Control`] for one run, and what the caller's callback needs.
pub(crate) struct Run {
    pub(crate) control: Control,
    latest: Arc<Mutex<Latest>>,
    callback: Option<Py<PyAny>>,
}

impl Run {
    /// A run that reports to `callback(phase, done, total)` (total `None` when unknown);
    /// the callback returns `False` to cancel.
    pub(crate) fn new(callback: Option<Py<PyAny>>) -> Run {
        let latest = Arc::new(Mutex::new(Latest::default()));
        let control = if callback.is_some() {
            let sink = latest.clone();
            Control::with_callback(move |p: &Progress| {
                let mut l = sink.lock().unwrap_or_else(PoisonError::into_inner);
                l.progress = Some((p.phase.to_string(), p.done, p.total));
                l.reported = false;
                ControlFlow::Continue(())
            })
        } else {
            Control::default()
        };
        Run { control, latest, callback }
    }

    /// Runs `work` as a job on `pool` (the global pool for `None`) with the GIL released,
    /// and returns what it returned. A signal (Ctrl-C: `KeyboardInterrupt`), an exception
    /// from the progress callback, or `False` from it ([`Cancelled`]) cancels the work, waits
    /// for it to stop and raises.
    ///
    /// Called on a thread of a rayon pool (Python code that a worker runs, such as a
    /// field given as a callable, meshing again), the work runs there, in `pool`, without the
    /// wait in slices: a worker is never Python's main thread, the only one that signals
    /// reach, and waiting on it for a job of its own pool could wait for ever.
    pub(crate) fn run<T: Send>(
        &self,
        py: Python<'_>,
        pool: Option<&Pool>,
        work: impl FnOnce() -> T + Send,
    ) -> PyResult<T> {
        let outcome = if rayon::current_thread_index().is_some() {
            let threads = pool.map(|p| &*p.threads);
            py.detach(|| catch_unwind(AssertUnwindSafe(|| install(threads, work))))
        } else {
            // The pool's workers, asleep since the last call, each woken on a CPU of its
            // own (see `cpus::pin_apart`), for this call only.
            let _pinned = pool.map(Pool::pin);
            let (done, mut outcome) = (AtomicBool::new(false), None);
            let mut failure: Option<PyErr> = None;
            let mut wait = || {
                while !done.load(Ordering::Acquire) {
                    py.detach(|| thread::park_timeout(SLICE));
                    if failure.is_some() {
                        continue;
                    }
                    if let Err(e) = py.check_signals().and_then(|()| self.report(py)) {
                        self.control.cancel();
                        failure = Some(e);
                    }
                }
            };
            match pool {
                Some(p) => p.threads.in_place_scope(|s| {
                    spawn_job(s, &done, &mut outcome, work);
                    wait();
                }),
                None => rayon::in_place_scope(|s| {
                    spawn_job(s, &done, &mut outcome, work);
                    wait();
                }),
            }
            if let Some(e) = failure {
                return Err(e);
            }
            // The flag is set only after the slot is filled.
            outcome.ok_or_else(|| {
                pyo3::exceptions::PyRuntimeError::new_err("skelform: the work never ran")
            })?
        };
        let out = outcome.map_err(|_| {
            pyo3::exceptions::PyRuntimeError::new_err("skelform: the work panicked")
        })?;
        // The last progress (the end of the last phase) reaches the callback too.
        self.report(py)?;
        Ok(out)
    }

    /// Calls the callback with the latest progress, once per change.
    fn report(&self, py: Python<'_>) -> PyResult<()> {
        let Some(callback) = &self.callback else { return Ok(()) };
        let progress = {
            let mut l = self.latest.lock().unwrap_or_else(PoisonError::into_inner);
            if l.reported {
                return Ok(());
            }
            l.reported = true;
            l.progress.clone()
        };
        let Some((phase, done, total)) = progress else { return Ok(()) };
        let answer = callback.call1(py, (phase, done, total))?;
        if answer.bind(py).is(&*pyo3::types::PyBool::new(py, false)) {
            return Err(Cancelled::new_err("cancelled by the progress callback"));
        }
        Ok(())
    }
}

/// Spawns `work` in scope `s`; its outcome goes to `slot`, and then `done` is set and the
/// calling thread (waiting for it in slices) woken.
fn spawn_job<'scope, T: Send + 'scope>(
    s: &rayon::Scope<'scope>,
    done: &'scope AtomicBool,
    slot: &'scope mut Option<thread::Result<T>>,
    work: impl FnOnce() -> T + Send + 'scope,
) {
    let waiter = thread::current();
    s.spawn(move |_| {
        *slot = Some(catch_unwind(AssertUnwindSafe(work)));
        done.store(true, Ordering::Release);
        waiter.unpark();
    });
}

/// Runs `op` on `pool`, or where it is for `None` (the current pool on a worker).
fn install<R: Send>(pool: Option<&rayon::ThreadPool>, op: impl FnOnce() -> R + Send) -> R {
    match pool {
        Some(p) => p.install(op),
        None => op(),
    }
}

/// A pool of worker threads for calls that ask for a number of them, with the workers'
/// thread ids, by which a call pins them apart while it runs (see `Run::run`).
#[derive(Clone)]
pub(crate) struct Pool {
    pub(crate) threads: Arc<rayon::ThreadPool>,
    /// Each worker's thread id, once it has started (0 before).
    workers: Arc<[AtomicI32]>,
    /// How many calls are running on the pool, and the workers' pins while any is: the
    /// first call in pins them, the last one out lets them go (a call that pinned and
    /// unpinned by itself would, beside another, restore the other's pins for good).
    pinned: Arc<Mutex<(usize, Option<cpus::Pinned>)>>,
}

impl Pool {
    /// The workers' thread ids, if every worker has started and they can be placed.
    fn worker_ids(&self) -> Option<Vec<i32>> {
        self.workers.iter().map(|w| Some(w.load(Ordering::Acquire)).filter(|&t| t > 0)).collect()
    }

    /// The workers pinned apart (see `cpus::pin_apart`) until the guard is dropped.
    fn pin(&self) -> PoolPin<'_> {
        let mut state = self.pinned.lock().unwrap_or_else(PoisonError::into_inner);
        if state.0 == 0 {
            state.1 = self.worker_ids().map(|ids| cpus::pin_apart(&ids));
        }
        state.0 += 1;
        PoolPin(self)
    }
}

/// A call's hold on its pool's pins ([`Pool::pin`]).
struct PoolPin<'a>(&'a Pool);

impl Drop for PoolPin<'_> {
    fn drop(&mut self) {
        let mut state = self.0.pinned.lock().unwrap_or_else(PoisonError::into_inner);
        state.0 -= 1;
        if state.0 == 0 {
            state.1 = None;
        }
    }
}

/// The pool for `threads`: `None` for the global one (a thread per core). Pools are
/// kept by size for the calls that follow: starting threads for every call would cost the
/// threads' start and the working memory the extractor keeps per thread.
pub(crate) fn pool(threads: Option<usize>) -> PyResult<Option<Pool>> {
    /// Pools of the sizes asked for so far (a few, in practice).
    static POOLS: Mutex<Vec<(usize, Pool)>> = Mutex::new(Vec::new());
    /// The most pools kept; past it, the oldest goes.
    const KEPT: usize = 4;
    let Some(n) = threads else { return Ok(None) };
    if !(1..=MAX_THREADS).contains(&n) {
        return Err(PyValueError::new_err(format!(
            "threads must be between 1 and {MAX_THREADS} (got {n})"
        )));
    }
    let mut pools = POOLS.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, p)) = pools.iter().find(|(m, _)| *m == n) {
        return Ok(Some(p.clone()));
    }
    let workers: Arc<[AtomicI32]> = (0..n).map(|_| AtomicI32::new(0)).collect();
    let record = workers.clone();
    let threads = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .start_handler(move |i| {
            record[i].store(cpus::thread_id().unwrap_or(0), Ordering::Release);
        })
        .build()
        .map(Arc::new)
        .map_err(|e| {
            pyo3::exceptions::PyRuntimeError::new_err(format!("cannot start {n} threads: {e}"))
        })?;
    let p = Pool { threads, workers, pinned: Arc::default() };
    if pools.len() == KEPT {
        pools.remove(0);
    }
    pools.push((n, p.clone()));
    Ok(Some(p))
}
