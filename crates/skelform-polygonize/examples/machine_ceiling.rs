//! What the machine itself gives to more threads: for `bench/peers`, beside skelform's own
//! speed-up on all cores against one.
//!
//! `cargo run --release -p skelform-polygonize --example machine_ceiling -- [ROUNDS]` prints
//! `{"threads": N, "compute": {…}, "memory": {…}}`: for a loop of arithmetic alone (no memory
//! traffic, no sharing) and for a read through a 256 MiB array (the sign pass of extraction
//! on its own), the speed-up of all N cores over one (median, quartiles and each round's),
//! each round once with one thread and once with all, in turn, as `skelform extract
//! --threads 1,N` measures extraction. A virtual machine's cores may be hyperthreads of one
//! physical core, or be taken by other guests for a while; these figures bound what any
//! program can gain from them in the same minutes.

use std::time::Instant;

use rayon::prelude::*;

/// Work for the arithmetic loop: about 20 ms on one core of a 2020s CPU.
const STEPS: u64 = 40_000_000;
/// Samples in the array read by the memory test: 256 MiB of f32, far past any cache.
const SAMPLES: usize = 64 << 20;

fn main() -> Result<(), String> {
    let rounds: usize = match std::env::args().nth(1) {
        Some(r) => r.parse().map_err(|e| format!("rounds: {e}"))?,
        None => 21,
    };
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let pool =
        |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().map_err(|e| e.to_string());
    let pools = [pool(1)?, pool(all)?];
    // Values of both signs, so that counting them cannot be folded away.
    let samples: Vec<f32> = (0..SAMPLES).map(|i| if i % 3 == 0 { -1.0 } else { 1.0 }).collect();
    let compute = paired(&pools, rounds, |threads| {
        let per = STEPS / threads as u64;
        (0..threads as u64).into_par_iter().map(|t| mix(t, per)).reduce(|| 0, |a, b| a ^ b)
    });
    let memory = paired(&pools, rounds, |threads| {
        let chunk = SAMPLES.div_ceil(threads);
        samples
            .par_chunks(chunk)
            .map(|c| c.iter().filter(|v| **v < 0.0).count() as u64)
            .sum::<u64>()
    });
    println!(r#"{{"threads": {all}, "compute": {compute}, "memory": {memory}}}"#);
    Ok(())
}

/// A chain of `steps` dependent integer mixes (splitmix64's), from `seed`.
fn mix(seed: u64, steps: u64) -> u64 {
    let mut x = seed;
    for _ in 0..steps {
        x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = x;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        x ^= z ^ (z >> 31);
    }
    x
}

/// Runs `work(threads)` on both pools each round, in turn (the order alternating), and
/// returns the median and quartiles of the rounds' speed-ups, and the speed-ups, as JSON.
fn paired(
    pools: &[rayon::ThreadPool; 2],
    rounds: usize,
    work: impl Fn(usize) -> u64 + Sync,
) -> String {
    let mut ratios = Vec::with_capacity(rounds);
    let mut keep = 0u64;
    for r in 0..rounds.max(1) {
        let mut seconds = [0.0; 2];
        for p in [r % 2, 1 - r % 2] {
            let threads = pools[p].current_num_threads();
            let t = Instant::now();
            keep ^= pools[p].install(|| work(threads));
            seconds[p] = t.elapsed().as_secs_f64();
        }
        ratios.push(seconds[0] / seconds[1]);
    }
    std::hint::black_box(keep);
    let each: Vec<String> = ratios.iter().map(|r| format!("{r:.4}")).collect();
    ratios.sort_by(f64::total_cmp);
    let at = |q: usize| ratios[(q * ratios.len() / 4).min(ratios.len() - 1)];
    format!(
        r#"{{"speedup": {:.3}, "q1": {:.3}, "q3": {:.3}, "speedups": [{}]}}"#,
        at(2),
        at(1),
        at(3),
        each.join(", ")
    )
}
