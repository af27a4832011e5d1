//! The running account of memory the propagating polygonizers keep, held to
//! [`LatticeOptions::max_memory`](super::LatticeOptions::max_memory).
//!
//! What they hold grows with the surface (hash maps of visited cubes, corner values, edge
//! vertices, cached faces, and the mesh arrays), so it cannot be refused up front the way a
//! dense grid is. Instead each says what it holds now ([`Cubes::held`]), estimated from the
//! capacities of its maps and vectors and the sizes of their entries, and propagation
//! compares that with the limit every [`CHECK_EVERY`] cubes and after each wave. The
//! estimate is computed from lengths and capacities alone, which depend only on the order of
//! insertions, so a run stops at the same cube on any thread count; under the limit nothing
//! changes (the check reads a handful of lengths).
//!
//! [`Cubes::held`]: super::propagate::Cubes::held

use std::collections::{HashMap, HashSet};
use std::mem::size_of;

use skelform_field::grid::Grid;

use crate::Error;

/// Propagation compares what is held with the limit after this many cubes (and after each
/// wave).
pub(crate) const CHECK_EVERY: u64 = 1024;

/// Buckets a hashbrown table with room for `capacity` entries has (it keeps at most 7/8 of
/// its buckets full, in a power of two of them).
fn buckets(capacity: usize) -> u64 {
    match capacity {
        0 => 0,
        c if c < 8 => (c as u64 + 1).next_power_of_two(),
        c => (c as u64 * 8 / 7).next_power_of_two(),
    }
}

/// Bytes a hash map's table holds: a bucket per entry slot and a control byte each.
pub(crate) fn map_bytes<K, V, S>(m: &HashMap<K, V, S>) -> u64 {
    buckets(m.capacity()) * (size_of::<(K, V)>() as u64 + 1)
}

/// Bytes a hash set's table holds.
pub(crate) fn set_bytes<K, S>(s: &HashSet<K, S>) -> u64 {
    buckets(s.capacity()) * (size_of::<K>() as u64 + 1)
}

/// Bytes a vector's buffer holds.
pub(crate) fn vec_bytes<T>(v: &Vec<T>) -> u64 {
    v.capacity() as u64 * size_of::<T>() as u64
}

/// Bytes a hash map of `entries` entries of type `(K, V)` needs at the least (its buckets
/// full to the brim): for refusing up front what cannot fit, `None` on overflow.
pub(crate) fn entries_bytes<K, V>(entries: u64) -> Option<u64> {
    entries.checked_mul(size_of::<(K, V)>() as u64 + 1)
}

/// Refuses, before anything is allocated, a run whose up-front need is over `limit`.
pub(crate) fn refuse(need: super::MemoryNeed, limit: u64, grid: &Grid) -> Result<(), Error> {
    let needed = need.bytes();
    if needed > limit {
        return Err(Error::TooMuchMemory { needed, limit, dims: grid.dims });
    }
    Ok(())
}

/// The error of a run whose account reached the limit.
pub(crate) fn over(method: &'static str, held: u64, limit: u64, cells: u64) -> Error {
    Error::MemoryLimit { method, held, limit, cells }
}

/// `Err` when `held` is over `limit`.
pub(crate) fn check(method: &'static str, held: u64, limit: u64, cells: u64) -> Result<(), Error> {
    if held > limit { Err(over(method, held, limit, cells)) } else { Ok(()) }
}

/// A byte count for people: B, KiB, MiB or GiB (always GiB from 1 GiB up, as the messages
/// of large grids have said).
pub(crate) fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..1024 => format!("{bytes} B"),
        1024..1_048_576 => format!("{:.1} KiB", b / 1024.0),
        1_048_576..1_073_741_824 => format!("{:.1} MiB", b / 1_048_576.0),
        _ => format!("{:.2} GiB", b / 1_073_741_824.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rustc_hash::FxHashMap;

    #[test]
    fn estimates_follow_capacity_and_entry_size() {
        let mut m: FxHashMap<u64, u32> = FxHashMap::default();
        assert_eq!(map_bytes(&m), 0);
        for i in 0..1000 {
            m.insert(i, 0);
        }
        let b = map_bytes(&m);
        // 1000 entries of 16 bytes and a control byte, in a table at most 7/8 full.
        assert!((1000 * 17..=4 * 1000 * 17).contains(&b), "{b}");
        assert_eq!(vec_bytes(&Vec::<[u32; 3]>::with_capacity(10)), 120);
        assert_eq!(entries_bytes::<u64, u32>(u64::MAX), None);
        assert_eq!(human(1 << 20), "1.0 MiB");
        assert_eq!(human(3 << 30), "3.00 GiB");
    }
}
