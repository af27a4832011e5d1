//! The harness the `fuzz_*` tests share (included by each with `#[path]`): a proptest runner
//! that bounds every case in time and the whole test binary in memory, and the knobs for a
//! longer run.
//!
//! - **Time**: each case runs on its own thread (2 MiB of stack, as a rayon worker has); one
//!   that takes longer than the property's limit fails the property (and is left running:
//!   a hang is reported, not waited for).
//! - **Memory**: the test binary's global allocator ([`Guard`]) refuses any allocation that
//!   would take the live heap past [`LIMIT`] (1 GiB), after printing the case that asked for
//!   it. The process then aborts ("memory allocation of N bytes failed"): code under test
//!   must refuse oversized declarations before it allocates.
//! - **Panics** are failures like any other, shrunk to a small input by proptest.
//!
//! Environment:
//! - `SKELFORM_FUZZ_CASES=N`: cases per property (each property has its own small default,
//!   so that the four fuzz targets take a few seconds in CI); `PROPTEST_CASES` is read when
//!   this is not set.
//! - `SKELFORM_FUZZ_SECONDS=S`: run each property again and again, with a fresh random seed
//!   each round, until `S` seconds have passed (an hour: `SKELFORM_FUZZ_SECONDS=3600`).
//! - `SKELFORM_FUZZ_SEED=U64`: the seed of the first round (default: a fixed seed, so CI runs
//!   are reproducible). A failure prints the seed of its round.
#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::fmt::Debug;
use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use proptest::strategy::Strategy;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestError, TestRng, TestRunner};

/// The most bytes the test binary may hold on its heap at once (all tests together).
pub const LIMIT: usize = 1 << 30;

static LIVE: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// The case the current thread runs, as text, for the allocator's message.
    static CASE: Cell<(*const u8, usize)> = const { Cell::new((std::ptr::null(), 0)) };
}

/// A global allocator that counts live bytes and refuses to go past [`LIMIT`].
pub struct Guard;

fn reserve(size: usize) -> bool {
    let before = LIVE.fetch_add(size, Ordering::Relaxed);
    if before.saturating_add(size) > LIMIT {
        LIVE.fetch_sub(size, Ordering::Relaxed);
        refused(size, before);
        return false;
    }
    true
}

/// Writes a number into `buf` without allocating.
fn digits(mut n: usize, buf: &mut [u8; 24]) -> &[u8] {
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    &buf[i..]
}

/// Says which case asked for too much, without allocating (the allocator is refusing).
fn refused(size: usize, live: usize) {
    let mut e = std::io::stderr().lock();
    let (mut a, mut b) = ([0; 24], [0; 24]);
    let _ = e.write_all(b"\nfuzz: refused an allocation of ");
    let _ = e.write_all(digits(size, &mut a));
    let _ = e.write_all(b" bytes with ");
    let _ = e.write_all(digits(live, &mut b));
    let _ = e.write_all(b" live: the code under test must refuse such a declaration first.\n");
    let (ptr, len) = CASE.with(Cell::get);
    if !ptr.is_null() {
        let _ = e.write_all(b"fuzz: the case: ");
        // SAFETY: `run_case` keeps the text alive while `CASE` points at it.
        let _ = e.write_all(unsafe { std::slice::from_raw_parts(ptr, len) });
        let _ = e.write_all(b"\n");
    }
}

// SAFETY: every call is passed on to `System`; only the count of live bytes is added.
unsafe impl GlobalAlloc for Guard {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !reserve(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller's contract is `System`'s.
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !reserve(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: as above.
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !reserve(new_size - old) {
            return std::ptr::null_mut();
        }
        // SAFETY: as above.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                LIVE.fetch_sub(new_size - old, Ordering::Relaxed);
            }
        } else if new_size < old {
            LIVE.fetch_sub(old - new_size, Ordering::Relaxed);
        }
        p
    }
}

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    let v = std::env::var(name).ok()?;
    match v.trim().parse() {
        Ok(v) => Some(v),
        Err(_) => panic!("{name}={v}: not a number"),
    }
}

/// Cases per property: `SKELFORM_FUZZ_CASES`, else `PROPTEST_CASES`, else `default`.
pub fn cases(default: u32) -> u32 {
    env("SKELFORM_FUZZ_CASES")
        .or_else(|| std::env::var_os("PROPTEST_CASES").map(|_| Config::default().cases))
        .unwrap_or(default)
}

fn rng(seed: u64) -> TestRng {
    let mut bytes = [0u8; 32];
    for (k, chunk) in bytes.chunks_mut(8).enumerate() {
        chunk.copy_from_slice(
            &(seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)).to_le_bytes(),
        );
    }
    TestRng::from_seed(RngAlgorithm::ChaCha, &bytes)
}

/// Runs `check` on one case on its own thread, failing it when it panics or takes longer
/// than `limit`.
fn run_case<T, F>(value: T, limit: Duration, check: &Arc<F>) -> Result<(), TestCaseError>
where
    T: Debug + Send + 'static,
    F: Fn(T) -> Result<(), String> + Send + Sync + 'static,
{
    let mut text = format!("{value:?}");
    text.truncate(text.floor_char_boundary(1 << 16));
    let check = Arc::clone(check);
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = std::thread::Builder::new()
        .name("fuzz case".into())
        .stack_size(2 << 20)
        .spawn(move || {
            CASE.with(|c| c.set((text.as_ptr(), text.len())));
            let result = check(value);
            CASE.with(|c| c.set((std::ptr::null(), 0)));
            drop(text);
            let _ = tx.send(result);
        })
        .map_err(|e| TestCaseError::fail(format!("cannot start a thread: {e}")))?;
    match rx.recv_timeout(limit) {
        Ok(result) => {
            let _ = worker.join();
            result.map_err(TestCaseError::fail)
        }
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            Err(TestCaseError::fail(format!("no answer within {limit:?}: a hang")))
        }
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            let payload = worker.join().err();
            let msg = payload
                .as_ref()
                .and_then(|p| {
                    p.downcast_ref::<String>()
                        .cloned()
                        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                })
                .unwrap_or_else(|| "a panic".into());
            Err(TestCaseError::fail(format!("panicked: {msg}")))
        }
    }
}

/// Checks `check` on `cases(default_cases)` values of `strategy` (each within `limit`),
/// once, or round after round for `SKELFORM_FUZZ_SECONDS`; panics with the smallest failing
/// value proptest finds.
pub fn fuzz<S, F>(name: &str, default_cases: u32, limit: Duration, strategy: S, check: F)
where
    S: Strategy,
    S::Value: Debug + Send + 'static,
    F: Fn(S::Value) -> Result<(), String> + Send + Sync + 'static,
{
    let check = Arc::new(check);
    let cases = cases(default_cases);
    let budget = env::<f64>("SKELFORM_FUZZ_SECONDS").map(Duration::from_secs_f64);
    let mut seed = env::<u64>("SKELFORM_FUZZ_SEED").unwrap_or(0x5EED_F022);
    let start = Instant::now();
    let mut rounds = 0u64;
    loop {
        let config = Config {
            cases,
            failure_persistence: None,
            max_shrink_iters: 512,
            max_shrink_time: 30_000,
            max_global_rejects: cases.saturating_mul(4).max(1024),
            ..Config::default()
        };
        let mut runner = TestRunner::new_with_rng(config, rng(seed));
        match runner.run(&strategy, |v| run_case(v, limit, &check)) {
            Ok(()) => {}
            Err(TestError::Fail(reason, value)) => {
                panic!("{name}: {reason}\nseed {seed}; the smallest failing input:\n{value:#?}")
            }
            Err(TestError::Abort(reason)) => panic!("{name}: aborted: {reason} (seed {seed})"),
        }
        rounds += 1;
        match budget {
            Some(b) if start.elapsed() < b => {
                let now = std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos() as u64);
                seed = now ^ rounds.wrapping_mul(0xD1B5_4A32_D192_ED03);
            }
            _ => break,
        }
    }
    eprintln!(
        "fuzz {name}: {} cases in {rounds} round(s), {:.1} s",
        u64::from(cases) * rounds,
        start.elapsed().as_secs_f64()
    );
}

/// Spans of the tokens of `text` for mutations that swap or replace whole tokens: runs of
/// characters for which `word` holds, and each other character that is not white space.
pub fn tokens(text: &str, word: impl Fn(char) -> bool) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in text.char_indices() {
        let is_word = word(c);
        match (start, is_word) {
            (None, true) => start = Some(i),
            (Some(s), false) => {
                out.push((s, i));
                start = None;
            }
            _ => {}
        }
        if !is_word && !c.is_whitespace() {
            out.push((i, i + c.len_utf8()));
        }
    }
    if let Some(s) = start {
        out.push((s, text.len()));
    }
    out
}

/// Swaps the text of two spans of `text`, `x` before `y` and apart (token spans from
/// [`tokens`]): the later one is replaced first, so the earlier one's offsets still hold.
pub fn swap_spans(text: &mut String, x: (usize, usize), y: (usize, usize)) {
    let (sx, sy) = (text[x.0..x.1].to_string(), text[y.0..y.1].to_string());
    text.replace_range(y.0..y.1, &sx);
    text.replace_range(x.0..x.1, &sy);
}
