//! Software prefetch of data a traversal will read soon (x86 `prefetcht0`; nothing
//! elsewhere).

/// Asks for the cache lines of `x` (at most `lines` of them, from its start) to be
/// brought into L1. Never faults, whatever the address.
#[inline(always)]
pub fn prefetch<T>(x: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = (x as *const T).cast::<i8>();
        for k in 0..lines.min(std::mem::size_of::<T>().div_ceil(64)) {
            // SAFETY: a prefetch is a hint: it reads nothing architecturally and never
            // faults; the address stays within `x`.
            unsafe {
                std::arch::x86_64::_mm_prefetch(p.add(64 * k), std::arch::x86_64::_MM_HINT_T0);
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (x, lines);
    }
}
