//! An output array that several threads fill at once, each at places it alone writes.
//!
//! Parallel extraction makes the mesh slab by slab on every thread, but the mesh is one
//! vertex array and one triangle array in slab order. Collecting each thread's slabs in
//! arrays of its own and copying them into the mesh at the end writes every byte twice, into
//! memory that is fresh both times (a page fault per 4 KiB on first touch). An [`Assembly`]
//! lets a finished slab go straight to its final place as soon as the slabs before it have
//! been counted, while other threads go on writing theirs.
//!
//! The array grows when a placed piece would pass its end, under a write lock that waits
//! for the pieces being written to be done, by `realloc`, which keeps every byte written so
//! far; arrays start large enough that the allocator gives them pages of their own, which
//! it moves without copying them (see [`Assembly::reserve`]).

use std::alloc::{Layout, alloc, dealloc, handle_alloc_error, realloc};
use std::mem::MaybeUninit;
use std::ptr::NonNull;
use std::sync::RwLock;

/// A growable array of `T`, written by many threads at disjoint ranges, read once at the end
/// as a `Vec`.
pub struct Assembly<T> {
    memory: RwLock<Block<T>>,
    /// The smallest capacity to allocate.
    least: usize,
}

/// Memory for `capacity` elements from the global allocator (none while the capacity is 0).
struct Block<T> {
    start: NonNull<T>,
    capacity: usize,
}

// SAFETY: a Block owns its memory like a `Vec<T>` does; what threads may do with it is
// governed by the lock around it and by `Assembly::place`'s contract.
unsafe impl<T: Send> Send for Block<T> {}
unsafe impl<T: Send + Sync> Sync for Block<T> {}

impl<T> Block<T> {
    fn layout(capacity: usize) -> Layout {
        Layout::array::<T>(capacity).unwrap_or_else(|_| panic!("capacity overflow"))
    }
}

impl<T> Drop for Block<T> {
    fn drop(&mut self) {
        if self.capacity > 0 {
            // SAFETY: the memory was allocated with this layout (see `Assembly::reserve`).
            // Elements are `Copy` (see `Assembly`'s methods), so nothing needs dropping.
            unsafe { dealloc(self.start.as_ptr().cast(), Block::<T>::layout(self.capacity)) };
        }
    }
}

impl<T: Copy + Send + Sync> Assembly<T> {
    /// An array over the memory of `v` (its elements dropped): a caller's array from its
    /// last extraction, whose pages are already in memory, so that placing the slabs costs
    /// no page fault (and no zeroing by the kernel) where fresh memory would cost one a
    /// page. Grows from there (or from nothing) in blocks of
    /// [`ROOM`](skelform_field::pages::ROOM) bytes or more.
    pub fn from_vec(v: Vec<T>) -> Self {
        let least = skelform_field::pages::ROOM / size_of::<T>();
        if v.capacity() == 0 {
            return Self::with_least(least);
        }
        let mut v = std::mem::ManuallyDrop::new(v);
        v.clear();
        // SAFETY (for `Block`'s use of it): a `Vec`'s memory comes from the global allocator
        // with the layout of `capacity` elements of `T`, the layout `Block` frees and
        // reallocates it with; the ManuallyDrop hands the ownership over.
        let start = NonNull::new(v.as_mut_ptr()).unwrap_or_else(|| unreachable!());
        let block = Block { start, capacity: v.capacity() };
        Assembly { memory: RwLock::new(block), least: least.max(1) }
    }

    fn with_least(least: usize) -> Self {
        assert!(size_of::<T>() > 0, "an assembly of zero-sized elements");
        let empty = Block { start: NonNull::dangling(), capacity: 0 };
        Assembly { memory: RwLock::new(empty), least: least.max(1) }
    }

    /// Makes the array hold at least `needed` elements, `wanted` if it has to grow (a guess
    /// at the final size saves growing again), keeping what has been written.
    ///
    /// The array is never smaller than [`ROOM`](skelform_field::pages::ROOM) bytes: blocks
    /// that large are mapped pages of their own, which `realloc` moves to a larger range by
    /// remapping them, with no copy (glibc; other allocators copy), and which cost nothing
    /// until written.
    pub fn reserve(&self, needed: usize, wanted: usize) {
        // Most calls find room: asking for the write lock would wait for the other threads'
        // pieces being written (and hold back their next ones), so look first.
        if self.memory.read().unwrap_or_else(|e| e.into_inner()).capacity >= needed {
            return;
        }
        let mut block = self.memory.write().unwrap_or_else(|e| e.into_inner());
        if block.capacity >= needed {
            return;
        }
        let generous = wanted.max(needed).max(block.capacity + block.capacity / 2).max(self.least);
        // SAFETY: the layout has a non-zero size (T is not zero-sized and capacity > 0). The
        // old block, when there is one, was allocated with `layout(block.capacity)`; realloc
        // keeps its bytes, written or not, as the start of the new block, and on failure
        // leaves the old block as it was.
        let grow = |capacity: usize| unsafe {
            let layout = Block::<T>::layout(capacity);
            let fresh = if block.capacity == 0 {
                alloc(layout)
            } else {
                let old = Block::<T>::layout(block.capacity);
                realloc(block.start.as_ptr().cast(), old, layout.size())
            };
            NonNull::new(fresh.cast::<T>()).map(|start| (start, capacity))
        };
        // A guess can be far too large (a dense first slab, the rest empty): when the
        // system refuses it, the size needed is enough.
        let Some((start, capacity)) = grow(generous).or_else(|| grow(needed)) else {
            handle_alloc_error(Block::<T>::layout(needed))
        };
        // Field by field: the old block's memory is the new one's now, not to be freed.
        (block.start, block.capacity) = (start, capacity);
        skelform_field::pages::advise_huge(start.as_ptr(), capacity);
    }

    /// Writes `f` of each of `from`, in order, at elements `at..at + from.len()`.
    ///
    /// Panics when those elements pass the [`reserve`](Self::reserve)d size.
    ///
    /// # Safety
    /// No other call may write any of those elements, at the same time or before: the
    /// caller assigns the ranges (each slab its own).
    pub unsafe fn place<S: Copy>(&self, at: usize, from: &[S], f: impl Fn(S) -> T) {
        // SAFETY: this method's contract is `write`'s, and every element is written.
        unsafe {
            self.write(at, from.len(), |to| {
                for (t, &x) in to.iter_mut().zip(from) {
                    t.write(f(x));
                }
            });
        }
    }

    /// Calls `f` with elements `at..at + len` (as uninitialised memory) for it to write
    /// them all, and returns what it returns: for writing several arrays in one pass.
    ///
    /// Panics when those elements pass the [`reserve`](Self::reserve)d size.
    ///
    /// # Safety
    /// As [`place`](Self::place): no other call may write any of those elements. The
    /// array may grow only after `f` returns (`reserve` waits for it).
    pub unsafe fn write<R>(
        &self,
        at: usize,
        len: usize,
        f: impl FnOnce(&mut [MaybeUninit<T>]) -> R,
    ) -> R {
        let block = self.memory.read().unwrap_or_else(|e| e.into_inner());
        assert!(at + len <= block.capacity, "a piece placed past the reserved size");
        // SAFETY: the range is inside the block (asserted), which cannot move or shrink while
        // the read lock is held; no other call writes it (this method's contract), and no
        // thread reads it before `into_vec`. As `MaybeUninit` the slice may be uninitialised.
        let to = unsafe {
            std::slice::from_raw_parts_mut(
                block.start.as_ptr().add(at).cast::<MaybeUninit<T>>(),
                len,
            )
        };
        f(to)
    }

    /// The first `len` elements as a `Vec`, the rest of the memory given back unless
    /// `keep` (memory a caller will write again).
    ///
    /// # Safety
    /// Every element of `0..len` must have been written by [`place`](Self::place).
    pub unsafe fn into_vec(self, len: usize, keep: bool) -> Vec<T> {
        let block = self.memory.into_inner().unwrap_or_else(|e| e.into_inner());
        if block.capacity == 0 {
            return Vec::new();
        }
        assert!(len <= block.capacity);
        let block = std::mem::ManuallyDrop::new(block);
        // SAFETY: the memory came from the global allocator with the layout of
        // `block.capacity` elements of T; the caller vouches for the first `len`; the
        // ManuallyDrop hands ownership to the Vec.
        let mut v = unsafe { Vec::from_raw_parts(block.start.as_ptr(), len, block.capacity) };
        if !keep {
            v.shrink_to_fit();
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pieces placed by many threads, out of order, with the array growing under them from
    /// nothing, come out in place and intact.
    #[test]
    fn pieces_placed_in_any_order_survive_growth() {
        use rayon::prelude::*;
        let sizes: Vec<usize> = (0..200).map(|i| (i * 37) % 101).collect();
        let starts: Vec<usize> = sizes
            .iter()
            .scan(0, |s, &n| {
                *s += n;
                Some(*s - n)
            })
            .collect();
        let total = starts[199] + sizes[199];
        // Room for two pieces at first: the array grows many times while pieces are placed.
        let a = Assembly::<u64>::with_least(100);
        (0..200).into_par_iter().rev().for_each(|p| {
            let piece: Vec<u32> = (0..sizes[p] as u32).collect();
            a.reserve(starts[p] + sizes[p], 0);
            // SAFETY: piece p alone writes its range.
            unsafe { a.place(starts[p], &piece, |x| ((p as u64) << 32) | x as u64) };
        });
        // SAFETY: the pieces cover 0..total.
        let v = unsafe { a.into_vec(total, false) };
        for (p, (&s, &n)) in starts.iter().zip(&sizes).enumerate() {
            for x in 0..n {
                assert_eq!(v[s + x], ((p as u64) << 32) | x as u64);
            }
        }
        assert_eq!(v.len(), total);
    }
}
