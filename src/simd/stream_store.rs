//! Non-temporal stores (x86 `movntps`, `sfence`) for arrays written once and read
//! back only after far more data than the caches hold has gone by: the builder's
//! partition of its largest nodes. A plain store first reads its line from memory
//! (read for ownership); a streaming store fills the line in a write-combining buffer
//! and writes it out whole, so a pass that copies an array from memory to memory
//! moves two arrays' bytes instead of three. Elsewhere plain stores.

use glam::Vec4;

/// Writes `a` to `dst[0]` and `b` to `dst[1]` with non-temporal stores (plain
/// stores off x86-64). The stores are not ordered with later stores of this thread as
/// seen by other threads until [`fence`].
///
/// # Safety
/// `dst` must be valid for writes of two `Vec4`s and 16-byte aligned.
#[inline(always)]
pub unsafe fn stream_pair(dst: *mut Vec4, a: Vec4, b: Vec4) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::_mm_stream_ps;
        // SAFETY: the caller's contract: two aligned, writable `Vec4`s (16 bytes each,
        // `movntps` needs 16-byte alignment); SSE is part of x86-64.
        unsafe {
            _mm_stream_ps(dst.cast::<f32>(), a.into());
            _mm_stream_ps(dst.add(1).cast::<f32>(), b.into());
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    // SAFETY: the caller's contract.
    unsafe {
        dst.write(a);
        dst.add(1).write(b);
    }
}

/// Orders this thread's earlier [`stream_pair`] stores before its later stores
/// (`sfence`): needed before another thread may read what they wrote, since
/// non-temporal stores are not ordered by the release stores that hand work over.
#[inline(always)]
pub fn fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `sfence` has no operands and no preconditions (SSE, part of x86-64).
    unsafe {
        std::arch::x86_64::_mm_sfence();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streamed_pairs_read_back_as_written() {
        let mut dst = [Vec4::ZERO; 6];
        let vals: Vec<Vec4> = (0..6)
            .map(|i| Vec4::new(i as f32, -(i as f32), f32::from_bits(i + 1), 0.5))
            .collect();
        for k in [2usize, 0, 4] {
            // SAFETY: `dst[k..k + 2]` lies inside the array; `Vec4` is 16-byte aligned.
            unsafe { stream_pair(dst.as_mut_ptr().add(k), vals[k], vals[k + 1]) };
        }
        fence();
        for (d, v) in dst.iter().zip(&vals) {
            assert_eq!(
                d.to_array().map(f32::to_bits),
                v.to_array().map(f32::to_bits)
            );
        }
    }
}
