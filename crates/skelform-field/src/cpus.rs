//! Keeping the workers of a parallel run on different CPUs.
//!
//! A run that splits its work between `n` workers is `n` times as fast only while they run
//! on `n` CPUs. Some kernels place a woken thread beside a busy one rather than on an idle
//! CPU: guests of virtual machines that pack their threads onto few virtual CPUs so that the
//! host can take the others back (seen on the 2-CPU machines these benchmarks run on, where
//! the two workers of a two-thread extraction shared one CPU, taking turns, in half the runs
//! after the process had been idle). The load balancer may leave them there for the whole
//! run.
//!
//! [`Spread`] undoes that and nothing else: each worker looks, before each piece of its
//! work, at the CPU it is on; one that finds a worker of lower number on the same CPU moves
//! to a CPU of the process's that no worker of the run is on, by pinning itself there, and
//! takes its pin off when its part of the run ends ([`Placement`]'s drop). Workers that the
//! kernel spreads itself (the usual case) are never pinned, and nothing is pinned between
//! runs. Where threads cannot be placed (other systems than Linux), all of this does
//! nothing. Placement changes the speed only: which worker runs which piece of work, and so
//! the result, never depends on it.

use std::sync::atomic::{AtomicI32, Ordering};

/// The CPUs the workers of one run were last seen on, by worker.
#[derive(Debug)]
pub struct Spread {
    /// A CPU number, or [`NOWHERE`] for a worker not (or no longer) at work.
    seen: Vec<AtomicI32>,
}

/// No CPU.
const NOWHERE: i32 = -1;

impl Spread {
    /// For a run of `workers` workers, numbered `0..workers`.
    pub fn new(workers: usize) -> Self {
        Spread { seen: (0..workers).map(|_| AtomicI32::new(NOWHERE)).collect() }
    }

    /// Worker `w`'s placement for its part of the run, which starts unpinned.
    pub fn placement(&self, w: usize) -> Placement<'_> {
        Placement { spread: self, worker: w, pinned: None }
    }
}

/// Where one worker of a [`Spread`] run may run: its pin, if it was moved, which comes off
/// (the CPUs it was allowed before are allowed again) when this is dropped, and its mark in
/// the run's record, which is cleared then.
#[derive(Debug)]
pub struct Placement<'a> {
    spread: &'a Spread,
    worker: usize,
    /// The CPUs the thread was allowed before it was pinned.
    pinned: Option<Cpus>,
}

impl Placement<'_> {
    /// Called by the worker before each piece of its work (cheap: where the system says so
    /// without a system call, as on x86-64 Linux, a few nanoseconds): notes the CPU it is
    /// on, and when a worker of lower number was last seen there, moves it to another
    /// (see the module's documentation).
    pub fn check(&mut self) {
        let seen = &self.spread.seen;
        let Some(mine) = seen.get(self.worker) else { return };
        let Some(cpu) = current_cpu() else { return };
        let crowded = seen[..self.worker].iter().any(|s| s.load(Ordering::Relaxed) == cpu);
        let at = if crowded { self.move_off(cpu).unwrap_or(cpu) } else { cpu };
        mine.store(at, Ordering::Relaxed);
    }

    /// Pins the thread to a CPU it is allowed on that no worker of the run was last seen
    /// on, other than `cpu`; returns that CPU, or `None` when there is none or the system
    /// refuses.
    fn move_off(&mut self, cpu: i32) -> Option<i32> {
        let allowed = match &self.pinned {
            Some(before) => before.clone(),
            None => Cpus::of_this_thread()?,
        };
        let seen = &self.spread.seen;
        let taken = |c: i32| c == cpu || seen.iter().any(|s| s.load(Ordering::Relaxed) == c);
        let free = allowed.iter().find(|&c| !taken(c))?;
        if !Cpus::only(free).apply() {
            return None;
        }
        self.pinned.get_or_insert(allowed);
        Some(free)
    }
}

impl Drop for Placement<'_> {
    fn drop(&mut self) {
        if let Some(mine) = self.spread.seen.get(self.worker) {
            mine.store(NOWHERE, Ordering::Relaxed);
        }
        if let Some(before) = self.pinned.take() {
            before.apply();
        }
    }
}

/// The id of the calling thread, for [`pin_apart`] (`None` where threads cannot be placed).
pub fn thread_id() -> Option<i32> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: gettid only returns the calling thread's id.
        Some(unsafe { libc::gettid() })
    }
    #[cfg(not(target_os = "linux"))]
    None
}

/// Pins the threads `tids` (of this process: a pool's workers, from [`thread_id`]) to
/// CPUs of their own for as long as the returned guard lives; dropping it lets each run
/// where it could before. The CPUs are those the calling thread may run on, taken in turn
/// from the one it is on now (so that processes calling from different CPUs pin to
/// different ones); with fewer than two of them, or fewer CPUs than threads, nothing is
/// pinned.
///
/// For a pool whose workers are all asleep when work comes (a library called now and then):
/// each worker a job wakes goes where its pin says, on an idle CPU if there is one, rather
/// than where a kernel that packs threads would queue it, behind a busy worker, for a tick
/// or for the whole job (see the module's documentation, which [`Spread`] can undo only
/// once the worker runs).
pub fn pin_apart(tids: &[i32]) -> Pinned {
    let mut pinned = Pinned { before: Vec::new() };
    let Some(allowed) = Cpus::of_this_thread() else { return pinned };
    let cpus: Vec<i32> = allowed.iter().collect();
    if tids.len() < 2 || cpus.len() < tids.len() {
        return pinned;
    }
    let start = current_cpu().and_then(|c| cpus.iter().position(|&x| x == c)).unwrap_or(0);
    for (i, &tid) in tids.iter().enumerate() {
        let Some(before) = Cpus::of(tid) else { continue };
        if Cpus::only(cpus[(start + i) % cpus.len()]).apply_to(tid) {
            pinned.before.push((tid, before));
        }
    }
    pinned
}

/// Threads pinned by [`pin_apart`], with the CPUs each could run on before.
#[derive(Debug)]
#[must_use = "the threads are unpinned when this is dropped"]
pub struct Pinned {
    before: Vec<(i32, Cpus)>,
}

impl Drop for Pinned {
    fn drop(&mut self) {
        for (tid, before) in self.before.drain(..) {
            before.apply_to(tid);
        }
    }
}

/// The CPU the calling thread is on.
fn current_cpu() -> Option<i32> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: sched_getcpu reads where the thread runs and changes nothing.
        let cpu = unsafe { libc::sched_getcpu() };
        (cpu >= 0).then_some(cpu)
    }
    #[cfg(not(target_os = "linux"))]
    None
}

/// A set of CPUs a thread may run on.
#[derive(Clone)]
struct Cpus {
    #[cfg(target_os = "linux")]
    set: libc::cpu_set_t,
}

impl std::fmt::Debug for Cpus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl Cpus {
    /// The CPUs the calling thread may run on now.
    fn of_this_thread() -> Option<Cpus> {
        Cpus::of(0)
    }

    /// The CPUs thread `tid` (0: the calling thread) may run on now.
    fn of(tid: i32) -> Option<Cpus> {
        #[cfg(target_os = "linux")]
        {
            // SAFETY: an all-zero cpu_set_t is the empty set; sched_getaffinity writes at
            // most the size given into it.
            let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
            let size = std::mem::size_of::<libc::cpu_set_t>();
            let done = unsafe { libc::sched_getaffinity(tid, size, &mut set) };
            (done == 0).then_some(Cpus { set })
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = tid;
            None
        }
    }

    /// The set of `cpu` alone.
    fn only(cpu: i32) -> Cpus {
        #[cfg(target_os = "linux")]
        {
            // SAFETY: as in `of_this_thread`; `cpu` comes from a set of this size.
            let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
            unsafe { libc::CPU_SET(cpu as usize, &mut set) };
            Cpus { set }
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = cpu;
            Cpus {}
        }
    }

    /// The CPUs of the set, in increasing order.
    fn iter(&self) -> impl Iterator<Item = i32> + '_ {
        #[cfg(target_os = "linux")]
        let count = 8 * std::mem::size_of::<libc::cpu_set_t>();
        #[cfg(not(target_os = "linux"))]
        let count = 0;
        // SAFETY: CPU_ISSET reads one bit of the set, below its size.
        #[cfg(target_os = "linux")]
        let has = |c: usize| unsafe { libc::CPU_ISSET(c, &self.set) };
        #[cfg(not(target_os = "linux"))]
        let has = |_: usize| false;
        (0..count).filter(move |&c| has(c)).map(|c| c as i32)
    }

    /// Lets the calling thread run on these CPUs only; false when the system refuses.
    fn apply(&self) -> bool {
        self.apply_to(0)
    }

    /// Lets thread `tid` (0: the calling thread) run on these CPUs only; false when the
    /// system refuses (the thread has ended, say).
    fn apply_to(&self, tid: i32) -> bool {
        #[cfg(target_os = "linux")]
        {
            let size = std::mem::size_of::<libc::cpu_set_t>();
            // SAFETY: sched_setaffinity reads `size` bytes of the set.
            unsafe { libc::sched_setaffinity(tid, size, &self.set) == 0 }
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = tid;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_worker_alone_is_never_pinned() {
        let spread = Spread::new(1);
        let mut p = spread.placement(0);
        for _ in 0..100 {
            p.check();
            assert!(p.pinned.is_none());
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_worker_on_the_cpu_of_a_lower_one_moves_off_it_and_back_when_done() {
        let Some(allowed) = Cpus::of_this_thread() else { return };
        if allowed.iter().count() < 2 {
            return;
        }
        let before: Vec<i32> = allowed.iter().collect();
        let spread = Spread::new(2);
        // Worker 0 is said to be where this thread is, which makes this thread (worker 1)
        // crowd it.
        let here = current_cpu().unwrap();
        spread.seen[0].store(here, Ordering::Relaxed);
        {
            let mut p = spread.placement(1);
            p.check();
            let now = Cpus::of_this_thread().unwrap().iter().collect::<Vec<_>>();
            assert_eq!(now.len(), 1, "pinned to one CPU");
            assert_ne!(now[0], here, "moved off the crowded CPU");
            assert_eq!(spread.seen[1].load(Ordering::Relaxed), now[0]);
            assert_eq!(current_cpu(), Some(now[0]));
        }
        // Dropping the placement takes the pin off and the worker's mark out.
        assert_eq!(Cpus::of_this_thread().unwrap().iter().collect::<Vec<_>>(), before);
        assert_eq!(spread.seen[1].load(Ordering::Relaxed), NOWHERE);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn threads_pinned_apart_run_on_cpus_of_their_own_until_let_go() {
        let Some(allowed) = Cpus::of_this_thread() else { return };
        let cpus: Vec<i32> = allowed.iter().collect();
        if cpus.len() < 2 {
            return;
        }
        // Two threads that report their id, then wait to be asked where they run.
        let (ids, asked) = (std::sync::mpsc::channel(), std::sync::Barrier::new(3));
        let (done, finished) = (std::sync::Barrier::new(3), std::sync::Barrier::new(3));
        std::thread::scope(|s| {
            let (asked, done, finished) = (&asked, &done, &finished);
            let mut seen = Vec::new();
            let (report, cpus_of) = (ids.0, std::sync::mpsc::channel());
            for _ in 0..2 {
                let (report, cpus_of) = (report.clone(), cpus_of.0.clone());
                s.spawn(move || {
                    report.send(thread_id().unwrap()).unwrap();
                    asked.wait();
                    cpus_of
                        .send(Cpus::of_this_thread().unwrap().iter().collect::<Vec<_>>())
                        .unwrap();
                    done.wait();
                    finished.wait();
                    cpus_of
                        .send(Cpus::of_this_thread().unwrap().iter().collect::<Vec<_>>())
                        .unwrap();
                });
            }
            let tids = [ids.1.recv().unwrap(), ids.1.recv().unwrap()];
            let guard = pin_apart(&tids);
            asked.wait();
            for _ in 0..2 {
                seen.push(cpus_of.1.recv().unwrap());
            }
            done.wait();
            assert!(seen.iter().all(|c| c.len() == 1), "each pinned to one CPU: {seen:?}");
            assert_ne!(seen[0], seen[1], "on different CPUs");
            drop(guard);
            finished.wait();
            for _ in 0..2 {
                assert_eq!(cpus_of.1.recv().unwrap(), cpus, "unpinned when let go");
            }
        });
    }

    #[test]
    fn one_thread_is_not_pinned() {
        let Some(me) = thread_id() else { return };
        let guard = pin_apart(&[me]);
        assert!(guard.before.is_empty());
    }
}
