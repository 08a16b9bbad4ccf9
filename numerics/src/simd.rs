//! Wider vectors where the CPU has them, with the same results.
//!
//! A release build targets the x86-64 baseline, whose vectors (SSE2) hold two `f64`. The
//! column loops of diagnose's fits (the anti-alias filter over the force and every
//! Jacobian column) run twice as wide with AVX2, present on every x86-64 server and rig
//! PC of the last decade. Such a loop is compiled a second time with AVX2 enabled and
//! chosen at run time when [`has_avx2`] says the CPU has it.
//!
//! The results are bit for bit the portable build's: Rust neither fuses a multiply and an
//! add nor reorders floating-point operations unless asked to, so each element goes
//! through the same IEEE operations in the same order, only more of them at a time
//! (`avx2` does not enable FMA). The tests of each dispatched function compare both paths
//! bit for bit.

/// Whether the CPU runs AVX2 instructions (detected once, then a cached load); `false` on
/// other architectures.
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
