//! The binned-SAH builder's bin indices (Wald 2007, "On fast Construction of SAH-based
//! Bounding Volume Hierarchies"), three axes at once: a centroid's clamped bin
//! coordinates become byte offsets into the bins in one vector conversion, one mask
//! and one shift, where converting each lane to an integer apart took two operations
//! per lane and the masking and scaling of each index two more.

use glam::Vec3A;

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::{
    __m128i, _mm_and_si128, _mm_cvttps_epi32, _mm_set1_epi32, _mm_slli_epi32, _mm_storeu_si128,
};

/// `16 * (trunc(k) & mask)` for lanes 0-2 of `k`: each bin's offset in an array of
/// 16-byte rows. The caller clamps `k` to `[0, bins - 1]` first, so the truncation is
/// the bin index; the mask (`bins` a power of two at most, minus one) keeps every
/// offset inside the bins whatever the input (an out-of-range lane converts to
/// `i32::MIN`, which the mask clears).
#[inline(always)]
pub fn offsets16(k: Vec3A, mask: u32) -> [u32; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        let mut o = [0u32; 4];
        // SAFETY: SSE2 is part of the x86-64 baseline; the store writes the 16 bytes
        // of `o`.
        unsafe {
            let i = _mm_and_si128(_mm_cvttps_epi32(k.into()), _mm_set1_epi32(mask as i32));
            _mm_storeu_si128(o.as_mut_ptr().cast::<__m128i>(), _mm_slli_epi32::<4>(i));
        }
        [o[0], o[1], o[2]]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        // `as` saturates (NaN to 0) where the conversion above gives `i32::MIN`; both
        // are masked into range and neither occurs after the caller's clamp.
        let f = |x: f32| ((x as i32 as u32) & mask) << 4;
        [f(k.x), f(k.y), f(k.z)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every clamped coordinate of 32 bins gives 16 times its truncation; values
    /// outside the range (which the builder never passes) still land inside the bins.
    #[test]
    fn offsets_are_sixteen_times_the_truncated_lanes() {
        for step in 0..=31 * 64 {
            let x = step as f32 / 64.0;
            let k = Vec3A::new(x, 31.0 - x, (x * 7.0) % 31.0);
            let want = [k.x as u32 * 16, k.y as u32 * 16, k.z as u32 * 16];
            assert_eq!(offsets16(k, 31), want, "{k:?}");
        }
        for bad in [f32::NAN, f32::INFINITY, -1.0, 1e10, 32.0, 40.5] {
            let o = offsets16(Vec3A::splat(bad), 31);
            assert!(
                o.iter().all(|&o| o <= 31 * 16 && o % 16 == 0),
                "{bad}: {o:?}"
            );
        }
    }
}
