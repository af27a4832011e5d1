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

    /// Writes `from` at elements `at..at + from.len()`.
    ///
    /// Panics when those elements pass the [`reserve`](Self::reserve)d size.
    ///
    /// # Safety
    /// No other call may write any of those elements, at the same time or before: the
    /// caller assigns the ranges (each slab its own).
    pub unsafe fn place(&self, at: usize, from: &[T]) {
        // SAFETY: this method's contract is `write`'s, and every element is written.
        unsafe {
            self.write(at, from.len(), |to| {
                for (t, &x) in to.iter_mut().zip(from) {
                    t.write(x);
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

impl Assembly<[u32; 3]> {
    /// Writes `from`'s numbers plus `shift` at elements `at..at + from.len()`: a slab's
    /// triangles, placed in the mesh after the vertices of the slabs below.
    ///
    /// The copy goes to memory no one reads until the mesh is whole, a slab after another,
    /// megabytes a mesh: stores that bypass the cache (x86-64) spare reading each line of
    /// the array in before it is overwritten and keep the cache for the extraction (a
    /// gyroid's 1.3 million triangles on two threads: 2.2 → 1.3 ms of copying).
    ///
    /// Panics when those elements pass the [`reserve`](Self::reserve)d size.
    ///
    /// # Safety
    /// As [`place`](Self::place).
    pub unsafe fn place_shifted(&self, at: usize, from: &[[u32; 3]], shift: u32) {
        let n = 3 * from.len();
        // SAFETY: this method's contract is `write`'s. Both sides are runs of `n` u32s
        // ([u32; 3] is three with no padding), apart (`to` is borrowed uniquely), and
        // `stream_shifted` writes every one of `to`'s.
        unsafe {
            self.write(at, from.len(), |to| {
                stream_shifted(to.as_mut_ptr().cast::<u32>(), from.as_ptr().cast::<u32>(), n, shift)
            });
        }
    }
}

/// `dst[i] = src[i] + shift` for `i < n`, through streaming stores on x86-64 (SSE2, part
/// of the baseline): a plain loop up to the first 16-byte boundary of `dst`, then four
/// 16-byte stores a step, the rest plain again; a fence at the end orders the streamed
/// stores before whatever the thread does next (handing the array over).
///
/// # Safety
/// `dst` and `src` are valid for `n` u32s each, and do not overlap.
unsafe fn stream_shifted(dst: *mut u32, src: *const u32, n: usize, shift: u32) {
    let mut i = 0;
    // SAFETY (all writes and reads): `i < n`, within both runs (the caller's contract).
    let plain = |i: usize| unsafe { dst.add(i).write(src.add(i).read().wrapping_add(shift)) };
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            __m128i, _mm_add_epi32, _mm_loadu_si128, _mm_set1_epi32, _mm_sfence, _mm_stream_si128,
        };
        while i < n && !(dst.wrapping_add(i) as usize).is_multiple_of(16) {
            plain(i);
            i += 1;
        }
        // SAFETY: SSE2 is in every x86-64 CPU; loads read `src[i..i + 16]` (unaligned
        // loads), streamed stores write `dst[i..i + 16]`, 16-byte aligned (the loop above),
        // both within `n`.
        unsafe {
            let add = _mm_set1_epi32(shift as i32);
            while i + 16 <= n {
                for lane in [0, 4, 8, 12] {
                    let x = _mm_loadu_si128(src.add(i + lane).cast::<__m128i>());
                    _mm_stream_si128(dst.add(i + lane).cast::<__m128i>(), _mm_add_epi32(x, add));
                }
                i += 16;
            }
            _mm_sfence();
        }
    }
    while i < n {
        plain(i);
        i += 1;
    }
}

/// Writes each of `rows` (a vertex's position, normal and value) to its element of the
/// three arrays, as many as each has: a slab's vertices, placed in a caller's arrays (see
/// [`VertexSink`](super::VertexSink)).
///
/// The arrays are the caller's (NumPy's), megabytes a mesh that no one reads during the
/// extraction: four vertices at a time, from the first vertex where all three arrays are
/// 16-byte aligned, the rows go through stores that bypass the cache (x86-64), which spare
/// reading each line of the arrays in before it is overwritten and keep the cache for the
/// extraction; a fence at the end orders them before the arrays are handed on.
pub fn stream_rows(
    positions: &mut [MaybeUninit<[f32; 3]>],
    normals: &mut [MaybeUninit<[f32; 3]>],
    values: &mut [MaybeUninit<f32>],
    mut rows: impl ExactSizeIterator<Item = ([f32; 3], [f32; 3], f32)>,
) {
    let n = rows.len().min(positions.len()).min(normals.len()).min(values.len());
    // Every write below goes through these, to elements `..n` of each array.
    let p = positions.as_mut_ptr().cast::<f32>();
    let q = normals.as_mut_ptr().cast::<f32>();
    let v = values.as_mut_ptr().cast::<f32>();
    let plain = |i: usize, (a, b, c): ([f32; 3], [f32; 3], f32)| {
        // SAFETY: i < n (every caller), so vertex i's floats lie within each array, at
        // element i of the arrays of triples (aligned as those are).
        unsafe {
            p.add(3 * i).cast::<[f32; 3]>().write(a);
            q.add(3 * i).cast::<[f32; 3]>().write(b);
            v.add(i).write(c);
        }
    };
    let mut i = 0;
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_loadu_ps, _mm_sfence, _mm_stream_ps};
        let aligned = |i: usize| {
            let at = |f: *mut f32| (f as usize).is_multiple_of(16);
            at(p.wrapping_add(3 * i)) && at(q.wrapping_add(3 * i)) && at(v.wrapping_add(i))
        };
        // A 16-byte boundary of all three within four vertices, if they have one in common.
        if let Some(start) = (0..4.min(n)).find(|&i| aligned(i)) {
            for r in rows.by_ref().take(start) {
                plain(i, r);
                i += 1;
            }
            while i + 4 <= n {
                let (mut ps, mut qs, mut vs) = ([0f32; 12], [0f32; 12], [0f32; 4]);
                for (j, (a, b, c)) in rows.by_ref().take(4).enumerate() {
                    ps[3 * j..3 * j + 3].copy_from_slice(&a);
                    qs[3 * j..3 * j + 3].copy_from_slice(&b);
                    vs[j] = c;
                }
                // SAFETY: SSE is in every x86-64 CPU. Vertices i..i + 4 lie within the
                // arrays (i + 4 <= n), and start 16-byte aligned in each (`start`, then
                // steps of four vertices: 48 and 16 bytes), so the streamed stores write
                // exactly their twelve, twelve and four floats, from the stack arrays.
                unsafe {
                    for k in [0, 4, 8] {
                        _mm_stream_ps(p.add(3 * i + k), _mm_loadu_ps(ps.as_ptr().add(k)));
                        _mm_stream_ps(q.add(3 * i + k), _mm_loadu_ps(qs.as_ptr().add(k)));
                    }
                    _mm_stream_ps(v.add(i), _mm_loadu_ps(vs.as_ptr()));
                }
                i += 4;
            }
            // SAFETY: SSE, as above.
            unsafe { _mm_sfence() };
        }
    }
    for r in rows.take(n - i) {
        plain(i, r);
        i += 1;
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
            let piece: Vec<u64> = (0..sizes[p] as u64).map(|x| ((p as u64) << 32) | x).collect();
            a.reserve(starts[p] + sizes[p], 0);
            // SAFETY: piece p alone writes its range.
            unsafe { a.place(starts[p], &piece) };
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

    /// Shifted triangles come out whole at every start (the streamed middle starts at any
    /// of the four alignments a triangle can have) and every length (short pieces never
    /// reach it).
    #[test]
    fn shifted_triangles_are_placed_whole() {
        let lengths = [0, 1, 2, 5, 6, 7, 21, 64, 333];
        let total: usize = lengths.iter().sum::<usize>() + 3;
        let a = Assembly::<[u32; 3]>::with_least(1);
        a.reserve(total, 0);
        let mut at = 3;
        let mut want = vec![[7, 7, 7]; 3];
        // SAFETY: the first three elements alone, written before the pieces.
        unsafe { a.place(0, &want) };
        for (p, &n) in lengths.iter().enumerate() {
            let piece: Vec<[u32; 3]> =
                (0..n as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
            let shift = 1000 * p as u32 + 1;
            want.extend(piece.iter().map(|t| t.map(|x| x + shift)));
            // SAFETY: piece p alone writes its range.
            unsafe { a.place_shifted(at, &piece, shift) };
            at += n;
        }
        // SAFETY: the pieces cover 0..total.
        assert_eq!(unsafe { a.into_vec(total, false) }, want);
    }

    /// Rows come out whole from any start in each array (so any alignment, in common or
    /// not) and for every count, short of four vertices or past it.
    #[test]
    fn rows_are_written_whole_at_any_alignment() {
        let row = |i: usize| {
            let f = i as f32;
            ([f, f + 0.25, f + 0.5], [-f, -f - 0.25, -f - 0.5], f * 10.0)
        };
        for n in [0, 1, 3, 4, 5, 9, 37] {
            for [a, b, c] in [[0, 0, 0], [1, 1, 1], [2, 3, 1], [3, 0, 2], [0, 1, 0], [3, 3, 3]] {
                let mut p = vec![MaybeUninit::new([9.0; 3]); n + 4];
                let mut q = vec![MaybeUninit::new([9.0; 3]); n + 4];
                let mut v = vec![MaybeUninit::new(9.0); n + 4];
                let (ps, qs, vs) = (&mut p[a..a + n], &mut q[b..b + n], &mut v[c..c + n]);
                stream_rows(ps, qs, vs, (0..n).map(row));
                // SAFETY: every element was initialised (with 9s, then the rows).
                let read = |x: &[MaybeUninit<[f32; 3]>]| {
                    x.iter().map(|e| unsafe { e.assume_init() }).collect::<Vec<_>>()
                };
                let (p, q) = (read(&p), read(&q));
                let v: Vec<f32> = v.iter().map(|e| unsafe { e.assume_init() }).collect();
                for i in 0..n {
                    assert_eq!((p[a + i], q[b + i], v[c + i]), row(i), "{n} rows at {a}, {b}, {c}");
                }
                // Nothing outside the rows' elements is written.
                assert!(p[..a].iter().chain(&p[a + n..]).all(|&e| e == [9.0; 3]));
                assert!(q[..b].iter().chain(&q[b + n..]).all(|&e| e == [9.0; 3]));
                assert!(v[..c].iter().chain(&v[c + n..]).all(|&e| e == 9.0));
            }
        }
    }
}
