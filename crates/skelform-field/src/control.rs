//! Progress reports and cancellation for long work.
//!
//! Every long-running algorithm in skelform takes a [`Control`] in its options. The callback
//! is called from worker threads now and then with how far the work has come; returning
//! [`ControlFlow::Break`] stops the work as soon as the workers notice, and the algorithm
//! returns its `Cancelled` error. The dissertation asks that a polygonization can be aborted
//! at any time (ch. 3, interactivity); this is how.

use std::fmt;
use std::ops::ControlFlow;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// How far a phase of work has come.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// The phase's name, e.g. `"sampling"` or `"extracting"`.
    pub phase: &'static str,
    /// Units done so far (layers, cells, …).
    pub done: u64,
    /// Units in all, when known in advance.
    pub total: Option<u64>,
}

type Callback = dyn Fn(&Progress) -> ControlFlow<()> + Send + Sync;

/// A progress callback and a cancellation flag; `Default` is neither.
#[derive(Clone, Default)]
pub struct Control {
    callback: Option<Arc<Callback>>,
    cancelled: Arc<AtomicBool>,
}

impl fmt::Debug for Control {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Control")
            .field("callback", &self.callback.is_some())
            .field("cancelled", &self.is_cancelled())
            .finish()
    }
}

impl Control {
    /// A control that calls `f` with progress; `f` returns `Break` to cancel.
    pub fn with_callback(f: impl Fn(&Progress) -> ControlFlow<()> + Send + Sync + 'static) -> Self {
        Self { callback: Some(Arc::new(f)), cancelled: Arc::default() }
    }

    /// Asks the work to stop; safe from any thread (e.g. a Ctrl-C handler).
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }

    /// Whether [`Control::cancel`] was called or a callback returned `Break`, for work that
    /// wants to stop without reporting progress (before a phase starts, say). Clones of a
    /// control share the flag, so a clone kept by a signal handler cancels the original.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }

    /// Reports progress; returns `Break` when the work should stop.
    pub fn report(&self, progress: Progress) -> ControlFlow<()> {
        if self.is_cancelled() {
            return ControlFlow::Break(());
        }
        if self.callback.as_ref().is_some_and(|cb| cb(&progress).is_break()) {
            self.cancel();
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn callback_break_cancels() {
        let c = Control::with_callback(|p| {
            if p.done >= 3 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
        });
        let p = |done| Progress { phase: "t", done, total: None };
        assert!(c.report(p(1)).is_continue());
        assert!(c.report(p(3)).is_break());
        assert!(c.is_cancelled());
        assert!(c.report(p(0)).is_break());
        assert!(Control::default().report(p(100)).is_continue());
    }
}
