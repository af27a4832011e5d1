//! Large arrays backed by transparent huge pages where the system allows it.
//!
//! A sampled volume or a new mesh array is memory the process has never touched, and the
//! first write to each 4 KiB page costs a page fault: on the virtual machines these
//! benchmarks run on, about 3 µs, which for the megabytes of a 256³ extraction is a fifth of
//! the time. Asking the kernel for
//! 2 MiB pages on such arrays (`madvise(MADV_HUGEPAGE)`, honoured where transparent huge pages
//! are set to `madvise` or `always`) makes the same memory cost a few faults. Elsewhere the
//! advice is skipped.

/// Huge pages are 2 MiB on x86-64 and on most aarch64 kernels.
const HUGE: usize = 2 << 20;

/// Room worth keeping ahead in a growing output array: sixteen huge pages. Only what is
/// written costs memory; the more room, the smaller the share of the array before its first
/// huge-page boundary, which is made of small pages, each its own fault.
pub const ROOM: usize = 16 * HUGE;

/// Asks for huge pages on the 2 MiB-aligned part of `v`'s memory; pages already touched stay
/// as they are. A hint: failure changes nothing but speed.
pub fn advise_huge<T>(v: &mut [T]) {
    let bytes = std::mem::size_of_val(v);
    #[cfg(target_os = "linux")]
    {
        let start = (v.as_mut_ptr() as usize).next_multiple_of(HUGE);
        let end = (v.as_mut_ptr() as usize + bytes) / HUGE * HUGE;
        if end > start {
            // SAFETY: [start, end) lies inside `v`'s allocation, which we hold mutably;
            // MADV_HUGEPAGE only changes how the kernel backs those pages, never their
            // contents or the mapping's validity.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
}
