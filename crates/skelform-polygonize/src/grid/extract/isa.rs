//! Which instruction sets the CPU running the extractor has, for the compiled copies of its
//! kernel (`extract_slab` and the edge numberings' `emit`).
//!
//! The build targets x86-64-v2 so that its binaries run on any x86-64 CPU from 2009 on; the
//! kernel's copy for x86-64-v3 runs about 8% fewer instructions (BMI's bit scans and
//! clears over the numbered edges, AVX's three-operand forms in the vertex records) and
//! takes 3–4% less time. Both copies make the same mesh bit for bit: they do the same
//! floating-point operations in the same order (Rust never fuses a product and a sum into
//! an FMA on its own), only in other instructions.

/// Whether the CPU has every instruction set the x86-64-v3 copies are compiled for. (The
/// standard library caches what it detects: a few loads.)
#[cfg(target_arch = "x86_64")]
#[inline]
pub(super) fn v3() -> bool {
    use std::arch::is_x86_feature_detected as has;
    #[cfg(test)]
    if tests::BASELINE.load(std::sync::atomic::Ordering::Relaxed) {
        return false;
    }
    has!("avx")
        && has!("avx2")
        && has!("bmi1")
        && has!("bmi2")
        && has!("fma")
        && has!("lzcnt")
        && has!("movbe")
}

#[cfg(test)]
pub(super) mod tests {
    use std::sync::atomic::AtomicBool;

    /// Set by a test to run the baseline copies whatever the CPU has. (Other tests running
    /// meanwhile may take them too: they make the same meshes, which is what that test
    /// checks.)
    pub(in super::super) static BASELINE: AtomicBool = AtomicBool::new(false);
}
