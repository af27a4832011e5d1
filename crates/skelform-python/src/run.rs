//! Running long work from Python: off the GIL, on a thread of its own, with Ctrl-C and the
//! caller's progress callback both served on the caller's thread.
//!
//! Why a second thread: while Rust code runs, Python cannot deliver a signal (its handler
//! runs only between bytecodes of the main thread). The caller's thread therefore waits in
//! short slices with the GIL released, and between slices checks for signals and reports
//! progress; a signal or a callback that asks to stop cancels the work through its
//! [`Control`], and the work is always waited for to the end, so that nothing it borrows
//! outlives the call and no worker is left holding (or waiting for) the GIL.

use std::ops::ControlFlow;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread;
use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
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

    /// Runs `work` on a thread of its own with the GIL released, and returns what it
    /// returned. A signal (Ctrl-C: `KeyboardInterrupt`), an exception from the progress
    /// callback, or `False` from it ([`Cancelled`]) cancels the work, waits for it to stop and
    /// raises.
    pub(crate) fn run<T: Send>(
        &self,
        py: Python<'_>,
        work: impl FnOnce() -> T + Send,
    ) -> PyResult<T> {
        let mut failure: Option<PyErr> = None;
        let result = thread::scope(|s| {
            let waiter = thread::current();
            let worker = s.spawn(move || {
                let out = work();
                waiter.unpark();
                out
            });
            while !worker.is_finished() {
                py.detach(|| thread::park_timeout(SLICE));
                if failure.is_some() {
                    continue;
                }
                if let Err(e) = py.check_signals().and_then(|()| self.report(py)) {
                    self.control.cancel();
                    failure = Some(e);
                }
            }
            worker.join()
        });
        if let Some(e) = failure {
            return Err(e);
        }
        let out = result.map_err(|_| {
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

/// The rayon pool for `threads`: `None` for the global one (a thread per core). Pools are
/// kept by size for the calls that follow: starting threads for every call would cost the
/// threads' start and the working memory the extractor keeps per thread.
pub(crate) fn pool(threads: Option<usize>) -> PyResult<Option<Arc<rayon::ThreadPool>>> {
    /// Pools of the sizes asked for so far (a few, in practice).
    static POOLS: Mutex<Vec<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(Vec::new());
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
    let p = rayon::ThreadPoolBuilder::new().num_threads(n).build().map(Arc::new).map_err(|e| {
        pyo3::exceptions::PyRuntimeError::new_err(format!("cannot start {n} threads: {e}"))
    })?;
    if pools.len() == KEPT {
        pools.remove(0);
    }
    pools.push((n, p.clone()));
    Ok(Some(p))
}
