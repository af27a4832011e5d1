//! On which threads a polygonizer runs. One place builds or picks the pool, so that every
//! polygonizer bounds the thread count the same way and none can be asked to start a
//! machine-stalling number of threads.

use std::sync::Arc;

use crate::Error;

/// The most threads [`Threads::Count`] may ask for. A count far beyond the cores only costs
/// memory and start-up time (each thread has its own stack and per-thread buffers), and a
/// mistyped `--threads 100000` once hung a machine starting them.
pub const MAX_THREADS: usize = 256;

/// Which threads run a polygonizer. The mesh is the same on any of them.
#[derive(Clone, Debug, Default)]
pub enum Threads {
    /// The caller's rayon pool: the one the call is made from, else the global pool (which
    /// by default has a thread per core).
    #[default]
    Current,
    /// A pool of this many threads (1 to [`MAX_THREADS`]), built for the run and dropped
    /// after it.
    Count(usize),
    /// The caller's own pool, reused from run to run (an interactive front end that meshes
    /// on every edit need not start threads each time).
    Pool(Arc<rayon::ThreadPool>),
}

impl Threads {
    /// Runs `op` on the chosen threads. Everything a polygonizer does, including the rayon
    /// thread count it reads to size its buffers, must happen inside `op`.
    pub(crate) fn install<R: Send>(
        &self,
        op: impl FnOnce() -> Result<R, Error> + Send,
    ) -> Result<R, Error> {
        match self {
            Threads::Current => op(),
            Threads::Count(n) => {
                let n = *n;
                if !(1..=MAX_THREADS).contains(&n) {
                    return Err(Error::BadOption(format!(
                        "threads must be between 1 and {MAX_THREADS} (got {n})"
                    )));
                }
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| Error::ThreadPool(format!("cannot start {n} threads: {e}")))?;
                pool.install(op)
            }
            Threads::Pool(pool) => pool.install(op),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_out_of_range_are_refused_before_any_thread_starts() {
        for n in [0, MAX_THREADS + 1, 100_000] {
            let r = Threads::Count(n).install(|| Ok(()));
            assert!(matches!(r, Err(Error::BadOption(_))), "{n}: {r:?}");
        }
    }

    #[test]
    fn the_run_sees_the_pool_it_asked_for() {
        assert_eq!(Threads::Count(3).install(|| Ok(rayon::current_num_threads())), Ok(3));
        let pool = Arc::new(rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap());
        assert_eq!(Threads::Pool(pool).install(|| Ok(rayon::current_num_threads())), Ok(2));
    }
}
