//! AVX2 left-pack: the selected lanes of an 8-lane integer vector moved to its front, in
//! order, for ray-id compaction (`compact.rs`) where there is no AVX-512 `vpcompressd`.
//! The eight selection bits (a `vmovmskps`) index a 256-entry table of packed 3-bit
//! lane indices (1 KiB, so it stays in L1 next to the node and ray data); the indices
//! are spread over the eight lanes with one variable shift (`vpsrlvd`) and applied with
//! one cross-lane permute (`vpermd`), then the whole register is stored and the output
//! position advanced by the number of selected lanes. This is the standard AVX2
//! emulation of compress-store (e.g. Lemire's "simdprune" and the AVX2 left-pack of
//! Embree's and simdjson's filtering kernels); the packed table avoids both an 8 KiB
//! table of whole index vectors and BMI2 `pdep`, which is microcoded on AMD Zen 1/2.

/// For each 8-bit selection `m`, the lane index of its `j`-th set bit (lowest first) in
/// bits `3j..3j + 3`; the positions past the count hold 0 (their lanes are stored but
/// not counted).
pub const LEFT_PACK: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut m = 0;
    while m < 256 {
        let (mut j, mut i, mut packed) = (0, 0, 0u32);
        while i < 8 {
            if m >> i & 1 == 1 {
                packed |= (i as u32) << (3 * j);
                j += 1;
            }
            i += 1;
        }
        t[m] = packed;
        m += 1;
    }
    t
};

/// The lane indices of `LEFT_PACK[m]`, unpacked (the table's scalar reading).
pub fn left_pack_indices(m: u8) -> [u32; 8] {
    let p = LEFT_PACK[m as usize];
    std::array::from_fn(|j| p >> (3 * j) & 7)
}

/// `out[j] = v[idx[j]]` for the packed indices of selection `m`, by the vector path
/// (`vpsrlvd` + `vpermd`); the twin of [`left_pack_indices`] applied lane by lane.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline]
pub fn left_pack8(v: [u32; 8], m: u8) -> [u32; 8] {
    use std::arch::x86_64::*;
    // SAFETY: AVX2 is enabled at compile time (the cfg above); the loads and stores are
    // of whole local arrays.
    unsafe {
        let x = _mm256_loadu_si256(v.as_ptr().cast());
        let packed = pack(x, m as u32);
        let mut out = [0u32; 8];
        _mm256_storeu_si256(out.as_mut_ptr().cast(), packed);
        out
    }
}

/// Lanes of `v` selected by `m` moved to the front.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
unsafe fn pack(v: std::arch::x86_64::__m256i, m: u32) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    unsafe {
        let shifts = _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21);
        let idx = _mm256_and_si256(
            _mm256_srlv_epi32(
                _mm256_set1_epi32(LEFT_PACK[m as usize & 0xff] as i32),
                shifts,
            ),
            _mm256_set1_epi32(7),
        );
        _mm256_permutevar8x32_epi32(v, idx)
    }
}

/// [`select_ids`](super::compact::select_ids) eight ids a step: bit `bit` of each of
/// eight masks shifted into the sign bit (`vpslld`) and gathered by `vmovmskps`, the
/// ids left-packed and stored whole; the last `len % 8` ids by the scalar loop.
///
/// # Safety
/// `masks.len() >= ids.len()`, `out.len() >= ids.len() + 8` and `bit < 32` (checked by
/// the caller).
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline]
pub unsafe fn select_ids_avx2(ids: &[u32], masks: &[u32], bit: u32, out: &mut [u32]) -> usize {
    use std::arch::x86_64::*;
    let len = ids.len();
    let (mut n, mut k) = (0usize, 0usize);
    // SAFETY: loads read ids[k..k + 8] and masks[k..k + 8] with k + 8 <= len; the store
    // writes out[n..n + 8] with n <= k, so within out (at least len + 8 long).
    unsafe {
        let shift = _mm_cvtsi32_si128(31 - bit as i32);
        while k + 8 <= len {
            let m = _mm256_loadu_si256(masks.as_ptr().add(k).cast());
            let sel = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_sll_epi32(m, shift))) as u32;
            let v = _mm256_loadu_si256(ids.as_ptr().add(k).cast());
            _mm256_storeu_si256(out.as_mut_ptr().add(n).cast(), pack(v, sel));
            n += sel.count_ones() as usize;
            k += 8;
        }
    }
    for (&id, &m) in ids[k..].iter().zip(&masks[k..]) {
        out[n] = id;
        n += (m >> bit & 1) as usize;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table against its definition, for all 256 selections: the set lanes in
    /// increasing order, then zeros.
    #[test]
    fn table_lists_the_set_lanes_in_order() {
        for m in 0..=255u8 {
            let want: Vec<u32> = (0..8).filter(|&i| m >> i & 1 == 1).collect();
            let got = left_pack_indices(m);
            assert_eq!(&got[..want.len()], &want[..], "mask {m:#010b}");
            assert!(got[want.len()..].iter().all(|&x| x == 0), "mask {m:#010b}");
        }
    }

    /// The vector left-pack against the scalar reading of the table, all 256 masks.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    #[test]
    fn vector_left_pack_matches_scalar_on_all_masks() {
        let v = [11u32, 22, 33, 44, 55, 66, 77, 88];
        for m in 0..=255u8 {
            let want: Vec<u32> = (0..8).filter(|&i| m >> i & 1 == 1).map(|i| v[i]).collect();
            let got = left_pack8(v, m);
            assert_eq!(&got[..want.len()], &want[..], "mask {m:#010b}");
            let idx = left_pack_indices(m);
            assert_eq!(got, idx.map(|i| v[i as usize]), "mask {m:#010b}");
        }
    }
}
