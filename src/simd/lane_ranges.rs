//! The least and greatest lane of several vectors at once: the reductions of the packet
//! kernels' whole-packet bounds (`accel::bvhn::packet_bounds`), as one transposed tree.
//!
//! Why: reduced one vector at a time, each minimum (or maximum) of sixteen lanes is four
//! halvings of shuffle and min (LLVM's tree: 17 instructions), and a packet group needs
//! eight of them (shared origin) or fourteen: `perf` put `PacketBounds::new` with its
//! reductions at 12 % of a bunny primary packet's time (`examples/stream_profile
//! bunny.obj bvh8-packet primary 40`, AVX-512, issue 12, pk19). Transposed, each halving
//! step combines two vectors into one (two lane shuffles and one min): sixteen
//! reductions take 45 instructions, eight take 23, and the results come out together in
//! one register. Maxima are minima of the negated lanes (negation is exact).

use super::Lanes;

/// The least lane of `mask` in each vector of `lo` and the greatest in each of `hi`
/// (`A + B <= 16`; the lanes of `mask` are not NaN; `mask` selects at least one lane,
/// or the answers are `+inf` and `-inf`). Exact: a min or max returns one of its inputs.
#[inline(always)]
pub fn lane_ranges<L: Lanes, const A: usize, const B: usize>(
    lo: [L; A],
    hi: [L; B],
    mask: u32,
) -> ([f32; A], [f32; B]) {
    const { assert!(A + B <= 16) };
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    if L::WIDTH == 16 {
        // SAFETY: the build has AVX-512F (cfg above); every vector has 16 lanes.
        return unsafe { avx512::lane_ranges(lo, hi, mask) };
    }
    lane_ranges_plain(lo, hi, mask)
}

/// One reduction per vector (the path without AVX-512 and for widths other than 16;
/// the reference of the transposed tree in the tests).
#[inline(always)]
pub fn lane_ranges_plain<L: Lanes, const A: usize, const B: usize>(
    lo: [L; A],
    hi: [L; B],
    mask: u32,
) -> ([f32; A], [f32; B]) {
    let lanes = L::mask_from_bits(mask);
    let reduce = |v: L, fill: f32, less: fn(f32, f32) -> bool| {
        let mut a = L::select(lanes, v, L::splat(fill)).to_array();
        let a = a.as_mut();
        let mut w = L::WIDTH / 2;
        while w > 0 {
            for i in 0..w {
                if less(a[i + w], a[i]) {
                    a[i] = a[i + w];
                }
            }
            w /= 2;
        }
        a[0]
    };
    (
        lo.map(|v| reduce(v, f32::INFINITY, |x, y| x < y)),
        hi.map(|v| reduce(v, f32::NEG_INFINITY, |x, y| x > y)),
    )
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
mod avx512 {
    use super::Lanes;
    use std::arch::x86_64::*;

    /// The lane-wise min of two selections of 128-bit blocks of `a` and `b` (`A`, `B`:
    /// `_mm512_shuffle_f32x4` immediates). With `0x44, 0xEE` ("halve"): the low 256
    /// bits hold `a`'s eight partial minima, the high `b`'s. With `0x88, 0xDD` on two
    /// halved results (inputs `a b` and `c d`), block `j` holds input `j`'s four partial
    /// minima (`a b c d`).
    #[inline(always)]
    unsafe fn blocks<const A: i32, const B: i32>(a: __m512, b: __m512) -> __m512 {
        unsafe {
            _mm512_min_ps(
                _mm512_shuffle_f32x4::<A>(a, b),
                _mm512_shuffle_f32x4::<B>(a, b),
            )
        }
    }

    #[inline(always)]
    unsafe fn halve(a: __m512, b: __m512) -> __m512 {
        unsafe { blocks::<0x44, 0xEE>(a, b) }
    }

    #[inline(always)]
    unsafe fn quarter(ab: __m512, cd: __m512) -> __m512 {
        unsafe { blocks::<0x88, 0xDD>(ab, cd) }
    }

    /// Within each 128-bit block: elements 0 and 1 of `x`'s block (two partial minima
    /// of one input, given two each), elements 2 and 3 of `y`'s.
    #[inline(always)]
    unsafe fn pairs(x: __m512, y: __m512) -> __m512 {
        unsafe {
            _mm512_min_ps(
                _mm512_shuffle_ps::<0x88>(x, y),
                _mm512_shuffle_ps::<0xDD>(x, y),
            )
        }
    }

    /// See [`super::lane_ranges`]. Input `k` (the vectors of `lo`, then those of `hi`)
    /// ends in lane `(k % 4) * 4 + k / 4` of sixteen inputs, `(k % 4) * 4 + (k / 4) * 2`
    /// of eight.
    ///
    /// # Safety
    /// `L::WIDTH` must be 16.
    #[inline(always)]
    pub(super) unsafe fn lane_ranges<L: Lanes, const A: usize, const B: usize>(
        lo: [L; A],
        hi: [L; B],
        mask: u32,
    ) -> ([f32; A], [f32; B]) {
        debug_assert_eq!(L::WIDTH, 16);
        unsafe {
            let k = mask as __mmask16;
            let inf = _mm512_set1_ps(f32::INFINITY);
            let sign = _mm512_set1_epi32(i32::MIN);
            let load = |v: L| _mm512_loadu_ps(v.to_array().as_ref().as_ptr());
            let neg =
                |x: __m512| _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), sign));
            let mut v = [inf; 16];
            for (i, x) in lo.into_iter().enumerate() {
                v[i] = _mm512_mask_blend_ps(k, inf, load(x));
            }
            for (i, x) in hi.into_iter().enumerate() {
                v[A + i] = _mm512_mask_blend_ps(k, inf, neg(load(x)));
            }
            let mut out = [0f32; 16];
            let index: fn(usize) -> usize = if A + B <= 8 {
                let n = [
                    halve(v[0], v[1]),
                    halve(v[2], v[3]),
                    halve(v[4], v[5]),
                    halve(v[6], v[7]),
                ];
                let r = pairs(quarter(n[0], n[1]), quarter(n[2], n[3]));
                _mm512_storeu_ps(
                    out.as_mut_ptr(),
                    _mm512_min_ps(r, _mm512_shuffle_ps::<0xB1>(r, r)),
                );
                |k| (k % 4) * 4 + (k / 4) * 2
            } else {
                let h = |i: usize| halve(v[2 * i], v[2 * i + 1]);
                let q0 = quarter(h(0), h(1));
                let q1 = quarter(h(2), h(3));
                let q2 = quarter(h(4), h(5));
                let q3 = quarter(h(6), h(7));
                _mm512_storeu_ps(out.as_mut_ptr(), pairs(pairs(q0, q1), pairs(q2, q3)));
                |k| (k % 4) * 4 + k / 4
            };
            (
                std::array::from_fn(|i| out[index(i)]),
                std::array::from_fn(|i| -out[index(A + i)]),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{F8, F16};

    /// A small deterministic generator (xorshift).
    fn rng(mut s: u32) -> impl FnMut() -> u32 {
        move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        }
    }

    /// Values with ties, signed zeros, infinities and magnitudes from tiny to huge.
    fn value(r: &mut impl FnMut() -> u32) -> f32 {
        match r() % 8 {
            0 => 0.0,
            1 => -0.0,
            2 => f32::INFINITY,
            3 => f32::NEG_INFINITY,
            4 => (r() % 5) as f32 - 2.0,
            _ => {
                let x = f32::from_bits(r() & 0x7f7f_ffff);
                if r() & 1 == 1 { -x } else { x }
            }
        }
    }

    /// The fold of the lanes of `mask` by `f32::min`/`f32::max` (value-equal: the tree
    /// may return either zero of a tie between `0.0` and `-0.0`).
    fn fold(v: &[f32], mask: u32, lo: bool) -> f32 {
        let lanes = (0..v.len()).filter(|i| mask >> i & 1 == 1).map(|i| v[i]);
        if lo {
            lanes.fold(f32::INFINITY, f32::min)
        } else {
            lanes.fold(f32::NEG_INFINITY, f32::max)
        }
    }

    fn check<L: Lanes, const A: usize, const B: usize>(r: &mut impl FnMut() -> u32) {
        let mut vec = || {
            let mut a = L::splat(0.0).to_array();
            a.as_mut().iter_mut().for_each(|x| *x = value(r));
            a
        };
        let lo: [L::Array; A] = std::array::from_fn(|_| vec());
        let hi: [L::Array; B] = std::array::from_fn(|_| vec());
        let full = if L::WIDTH == 32 {
            u32::MAX
        } else {
            (1 << L::WIDTH) - 1
        };
        // One lane, all lanes, and random subsets; bits past the width are ignored.
        for mask in [1, 1 << (L::WIDTH - 1), full, r(), r() | 1, r() & r()] {
            let m = mask & full;
            if m == 0 {
                continue;
            }
            let (a, b) = lane_ranges(lo.map(L::from_array), hi.map(L::from_array), mask);
            let (pa, pb) = lane_ranges_plain(lo.map(L::from_array), hi.map(L::from_array), mask);
            for i in 0..A {
                assert_eq!(a[i], fold(lo[i].as_ref(), m, true), "lo {i} mask {m:x}");
                assert_eq!(pa[i], a[i], "plain lo {i} mask {m:x}");
            }
            for i in 0..B {
                assert_eq!(b[i], fold(hi[i].as_ref(), m, false), "hi {i} mask {m:x}");
                assert_eq!(pb[i], b[i], "plain hi {i} mask {m:x}");
            }
        }
    }

    /// Every input count the packet bounds use (and the edges of both trees) at both
    /// packet widths: each answer equals the fold of the masked lanes.
    #[test]
    fn lane_ranges_equal_the_fold_of_the_masked_lanes() {
        let mut r = rng(0x9e37_79b9);
        for _ in 0..300 {
            check::<F16, 4, 4>(&mut r);
            check::<F16, 7, 7>(&mut r);
            check::<F16, 1, 0>(&mut r);
            check::<F16, 0, 9>(&mut r);
            check::<F16, 8, 8>(&mut r);
            check::<F8, 4, 4>(&mut r);
            check::<F8, 7, 7>(&mut r);
        }
    }
}
