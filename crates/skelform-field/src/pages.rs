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

/// Asks for huge pages on the whole allocation `start..start + bytes` (a `Vec`'s buffer, all
/// of its capacity). A hint: failure changes nothing but speed, and pages already touched
/// stay as they are.
///
/// The advice covers every page the allocation touches, its first and last included. A
/// large block from the allocator is a mapping of its own, and advice on only a part of it
/// would split the mapping in two, which `mremap` cannot move as one: `realloc` would then
/// copy the block instead of remapping it (glibc falls back to copying when `mremap` fails).
/// Pages shared with neighbouring small allocations get the hint too, which changes nothing
/// for them but how the kernel may back them.
pub fn advise_huge<T>(start: *const T, capacity: usize) {
    let bytes = capacity.saturating_mul(std::mem::size_of::<T>());
    #[cfg(target_os = "linux")]
    if bytes >= HUGE {
        let page = page_size();
        let first = (start as usize) / page * page;
        let end = (start as usize).saturating_add(bytes).next_multiple_of(page);
        // SAFETY: MADV_HUGEPAGE changes only how the kernel backs pages, never their
        // contents or any mapping's validity; on unmapped addresses madvise fails (ENOMEM)
        // and does nothing else.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (start, bytes);
}

/// The system's page size (4 KiB where it cannot be asked).
#[cfg(target_os = "linux")]
fn page_size() -> usize {
    static PAGE: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    // SAFETY: sysconf only reads a system setting.
    *PAGE.get_or_init(|| match unsafe { libc::sysconf(libc::_SC_PAGESIZE) } {
        n if n > 0 => n as usize,
        _ => 4096,
    })
}
