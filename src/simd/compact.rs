//! Ray-id compaction for stream traversal: the ids whose child mask has a given bit,
//! in order. With AVX-512 sixteen ids are selected per step (`vpcompressd` into a
//! register, then one full store: the memory form of `vpcompressd` is microcoded and
//! slow on AMD Zen 4). With AVX2 (no compress instruction) eight ids per step by the
//! standard left-pack: the eight selection bits index a table of packed lane indices
//! (`left_pack`), which `vpermd` applies to the ids before one full store. Otherwise a
//! branch-free scalar loop.

/// Writes the ids `ids[k]` with bit `bit` set in `masks[k]` to the front of `out`, in
/// order, and returns how many. `masks` must be as long as `ids`, `out` at least
/// [`COMPACT_SLACK`] longer than `ids` (the vector paths store whole registers), and
/// `bit` below 32.
#[inline]
pub fn select_ids(ids: &[u32], masks: &[u32], bit: u32, out: &mut [u32]) -> usize {
    assert!(masks.len() >= ids.len() && out.len() >= ids.len() + COMPACT_SLACK && bit < 32);
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        // SAFETY: the lengths were checked above: every load reads within `ids` and
        // `masks` (the tail's loads are masked), every store writes 16 lanes at
        // `out[n..]` with n <= ids.len().
        unsafe { select_ids_avx512(ids, masks, bit, out) }
    }
    #[cfg(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        not(target_feature = "avx512f")
    ))]
    {
        // SAFETY: the lengths were checked above: the vector loads read 8 lanes at
        // `k < ids.len() - 7`, every store writes 8 lanes at `out[n..]` with
        // n <= k <= ids.len(), and the tail is scalar.
        unsafe { super::left_pack::select_ids_avx2(ids, masks, bit, out) }
    }
    #[cfg(not(all(
        target_arch = "x86_64",
        any(target_feature = "avx512f", target_feature = "avx2")
    )))]
    {
        select_ids_scalar(ids, masks, bit, out)
    }
}

/// Lanes `out` needs beyond the ids' count.
pub const COMPACT_SLACK: usize = 16;

/// The scalar twin: every id is stored, the count advances only for the selected ones.
#[inline]
pub fn select_ids_scalar(ids: &[u32], masks: &[u32], bit: u32, out: &mut [u32]) -> usize {
    let mut n = 0;
    for (&id, &m) in ids.iter().zip(masks) {
        out[n] = id;
        n += (m >> bit & 1) as usize;
    }
    n
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
#[inline]
unsafe fn select_ids_avx512(ids: &[u32], masks: &[u32], bit: u32, out: &mut [u32]) -> usize {
    use std::arch::x86_64::*;
    let (mut n, mut k) = (0usize, 0usize);
    let len = ids.len();
    unsafe {
        let b = _mm512_set1_epi32(1 << bit);
        while k < len {
            let lanes: __mmask16 = if len - k >= 16 {
                0xffff
            } else {
                (1u16 << (len - k)) - 1
            };
            let m = _mm512_maskz_loadu_epi32(lanes, masks.as_ptr().add(k).cast());
            let sel = _mm512_mask_test_epi32_mask(lanes, m, b);
            let v = _mm512_maskz_loadu_epi32(lanes, ids.as_ptr().add(k).cast());
            let packed = _mm512_maskz_compress_epi32(sel, v);
            _mm512_storeu_si512(out.as_mut_ptr().add(n).cast(), packed);
            n += sel.count_ones() as usize;
            k += 16;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vector_and_scalar_selection_agree() {
        let mut s = 12345u32;
        for len in [0usize, 1, 5, 15, 16, 17, 31, 32, 33, 100] {
            let ids: Vec<u32> = (0..len as u32).map(|i| i * 7 + 3).collect();
            let masks: Vec<u32> = (0..len)
                .map(|_| {
                    s ^= s << 13;
                    s ^= s >> 17;
                    s ^= s << 5;
                    s & 0xff
                })
                .collect();
            for bit in 0..8 {
                let mut a = vec![0; len + COMPACT_SLACK];
                let mut b = vec![0; len + COMPACT_SLACK];
                let na = select_ids(&ids, &masks, bit, &mut a);
                let nb = select_ids_scalar(&ids, &masks, bit, &mut b);
                let want: Vec<u32> = ids
                    .iter()
                    .zip(&masks)
                    .filter(|(_, m)| *m >> bit & 1 == 1)
                    .map(|(i, _)| *i)
                    .collect();
                assert_eq!(&a[..na], &want[..], "len {len} bit {bit}");
                assert_eq!(&b[..nb], &want[..], "len {len} bit {bit}");
            }
        }
    }
}
