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

/// Defines `$name`, which runs `$body` (an always-inlined function, or method, of the same
/// parameters) in its copy for x86-64-v3, the function `$v3`, where the CPU has those
/// instruction sets ([`v3`]), and in the build's baseline elsewhere. What `$body` calls must
/// be inlined into it for the copy to reach it: a call left out of line runs baseline code.
macro_rules! compiled_twice {
    (
        $(#[$doc:meta])*
        $vis:vis fn $name:ident<$($g:ident: $bound:path),*>(&self $(, $arg:ident: $ty:ty)* $(,)?)
            $(-> $ret:ty)? => $v3:ident, $body:ident
    ) => {
        $(#[$doc])*
        $vis fn $name<$($g: $bound),*>(&self $(, $arg: $ty)*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::grid::extract::isa::v3() {
                // SAFETY: the CPU has the instruction sets the copy is compiled for.
                return unsafe { self.$v3($($arg),*) };
            }
            self.$body($($arg),*)
        }

        /// The copy for x86-64-v3 (see `isa`).
        ///
        /// # Safety
        /// The CPU must have the instruction sets enabled here (`isa::v3`).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx,avx2,bmi1,bmi2,fma,lzcnt,movbe")]
        unsafe fn $v3<$($g: $bound),*>(&self $(, $arg: $ty)*) $(-> $ret)? {
            self.$body($($arg),*)
        }
    };
    (
        $(#[$doc:meta])*
        $vis:vis fn $name:ident<$($g:ident: $bound:path),*>($($arg:ident: $ty:ty),* $(,)?)
            $(-> $ret:ty)? => $v3:ident, $body:ident
    ) => {
        $(#[$doc])*
        $vis fn $name<$($g: $bound),*>($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::grid::extract::isa::v3() {
                // SAFETY: the CPU has the instruction sets the copy is compiled for.
                return unsafe { $v3($($arg),*) };
            }
            $body($($arg),*)
        }

        /// The copy for x86-64-v3 (see `isa`).
        ///
        /// # Safety
        /// The CPU must have the instruction sets enabled here (`isa::v3`).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx,avx2,bmi1,bmi2,fma,lzcnt,movbe")]
        unsafe fn $v3<$($g: $bound),*>($($arg: $ty),*) $(-> $ret)? {
            $body($($arg),*)
        }
    };
}

#[cfg(test)]
pub(super) mod tests {
    use std::sync::atomic::AtomicBool;

    /// Set by a test to run the baseline copies whatever the CPU has. (Other tests running
    /// meanwhile may take them too: they make the same meshes, which is what that test
    /// checks.)
    pub(in super::super) static BASELINE: AtomicBool = AtomicBool::new(false);
}
