//! SplitMix64 draws (Steele, Lea, Flood, "Fast Splittable Pseudorandom Number
//! Generators", OOPSLA 2014) sixteen pairs at a time: what 32 successive
//! `PixelRng::next_f32` calls return (`integrator::sampling`, the scalar oracle), with
//! the 64-bit multiplies of its output function in AVX-512DQ lanes (`vpmullq`).
//!
//! SplitMix's state only advances by a constant (`γ`), so draw `m` after the state `s`
//! is `mix(s + (m + 1) γ)` (wrapping): every draw can be computed on its own, in lanes.
//! Each is the top 24 bits of the mix times `2^-24`, converted and scaled exactly, so
//! the lanes hold the scalar draws bit for bit (a test compares them).
//!
//! Only with AVX-512DQ: `PixelRng::fill_f32` records the dead end of the same idea on
//! AVX2 (64-bit multiplies emulated by three `vpmuludq` each: slower than the scalar
//! loop). Without AVX-512DQ this is the scalar loop.

/// SplitMix64's increment and the two multipliers of its output function (Stafford's
/// "Mix13"): the constants of `integrator::sampling::PixelRng`, the scalar oracle of
/// this file and of `jittered_pack`, which take them from here.
pub const GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;
pub const MIX1: u64 = 0xbf58_476d_1ce4_e5b9;
pub const MIX2: u64 = 0x94d0_49bb_1331_11eb;

/// The output function of draw `m` (0-based) after the state `state`, before its last
/// step (`z ^ (z >> 31)`, which changes bits 0..32 only).
#[inline(always)]
fn mix_unfinished(state: u64, m: u64) -> u64 {
    let mut z = state.wrapping_add((m + 1).wrapping_mul(GAMMA));
    z = (z ^ (z >> 30)).wrapping_mul(MIX1);
    (z ^ (z >> 27)).wrapping_mul(MIX2)
}

/// [`mix_unfinished`] in eight 64-bit lanes: `offsets` holds `(m + 1) γ` per lane.
///
/// # Safety
/// `offsets` must be valid for eight `u64`; AVX-512F/DQ enabled.
#[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
#[inline(always)]
unsafe fn mix_unfinished8(
    state: std::arch::x86_64::__m512i,
    offsets: *const u64,
) -> std::arch::x86_64::__m512i {
    use std::arch::x86_64::*;
    // SAFETY: the caller's contract.
    unsafe {
        let c1 = _mm512_set1_epi64(MIX1 as i64);
        let c2 = _mm512_set1_epi64(MIX2 as i64);
        let mut z = _mm512_add_epi64(state, _mm512_loadu_si512(offsets.cast()));
        z = _mm512_mullo_epi64(_mm512_xor_si512(z, _mm512_srli_epi64::<30>(z)), c1);
        _mm512_mullo_epi64(_mm512_xor_si512(z, _mm512_srli_epi64::<27>(z)), c2)
    }
}

/// Draw `m` (0-based) of 32 after the state `state`, as `next_f32` makes it.
#[inline(always)]
fn draw(state: u64, m: u64) -> f32 {
    (mix_unfinished(state, m) >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The 32 draws after `state`, deinterleaved: `u[p]` is draw `2p`, `v[p]` draw
/// `2p + 1` (the first and second coordinate of point `p` of a pair set). The caller
/// advances its state by `γ` per draw it uses.
#[inline]
pub fn unit_pairs16(state: u64, u: &mut [f32; 16], v: &mut [f32; 16]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
    {
        // SAFETY: AVX-512F/DQ are enabled at compile time; the stores write the two
        // 16-float arrays exactly (four 8-float stores).
        unsafe { unit_pairs16_avx512(state, u, v) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512dq")))]
    {
        unit_pairs16_scalar(state, u, v)
    }
}

/// The scalar twin of [`unit_pairs16`].
#[inline]
pub fn unit_pairs16_scalar(state: u64, u: &mut [f32; 16], v: &mut [f32; 16]) {
    for p in 0..16 {
        u[p] = draw(state, 2 * p as u64);
        v[p] = draw(state, 2 * p as u64 + 1);
    }
}

/// `(m + 1) γ` for the draws of the first (`ODD[p] = (2p + 1) γ`) and second
/// coordinates (`EVEN[p] = (2p + 2) γ`).
#[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
const ODD: [u64; 16] = offsets(1);
#[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
const EVEN: [u64; 16] = offsets(2);

#[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
const fn offsets(first: u64) -> [u64; 16] {
    let mut out = [0u64; 16];
    let mut p = 0;
    while p < 16 {
        out[p] = (first + 2 * p as u64).wrapping_mul(GAMMA);
        p += 1;
    }
    out
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
#[inline]
unsafe fn unit_pairs16_avx512(state: u64, u: &mut [f32; 16], v: &mut [f32; 16]) {
    use std::arch::x86_64::*;
    // SAFETY (whole body): the loads read the 16-element constant arrays in two halves,
    // the stores write `u` and `v` in two halves; the target features are enabled.
    unsafe {
        let s = _mm512_set1_epi64(state as i64);
        let scale = _mm256_set1_ps(1.0 / (1u32 << 24) as f32);
        let eight = |offsets: *const u64, out: *mut f32| {
            let z = mix_unfinished8(s, offsets);
            // 24 bits: exact in f32, as `(z >> 40) as f32`; the scale is a power of two.
            let f = _mm512_cvtepi64_ps(_mm512_srli_epi64::<40>(z));
            _mm256_storeu_ps(out, _mm256_mul_ps(f, scale));
        };
        eight(ODD.as_ptr(), u.as_mut_ptr());
        eight(ODD.as_ptr().add(8), u.as_mut_ptr().add(8));
        eight(EVEN.as_ptr(), v.as_mut_ptr());
        eight(EVEN.as_ptr().add(8), v.as_mut_ptr().add(8));
    }
}

/// Sixteen draws of sixteen streams at once: lane `l` is the `PixelRng::next_f32` draw
/// whose advanced state (the stream's state plus `(m + 1) γ` for its draw `m`) is
/// `z[l]`, bit for bit (the top 24 bits of the unfinished mix times `2^-24`). What
/// [`unit_pairs16`] computes for one stream, for lanes of different streams: the light
/// points of a pack of shading points, each with its own stream
/// (`integrator::area_light::shade_quads_packed`, `simd::jittered_pack`).
#[inline]
pub fn unit_draws16(z: &[u64; 16]) -> [f32; 16] {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
    {
        let mut out = [0.0f32; 16];
        // SAFETY: AVX-512F/DQ are enabled at compile time; the loads read `z` and the
        // stores write `out` exactly, each in two 8-element halves.
        unsafe {
            use std::arch::x86_64::*;
            let c1 = _mm512_set1_epi64(MIX1 as i64);
            let c2 = _mm512_set1_epi64(MIX2 as i64);
            let scale = _mm256_set1_ps(1.0 / (1u32 << 24) as f32);
            for h in 0..2 {
                let mut v = _mm512_loadu_si512(z.as_ptr().add(8 * h).cast());
                v = _mm512_mullo_epi64(_mm512_xor_si512(v, _mm512_srli_epi64::<30>(v)), c1);
                v = _mm512_mullo_epi64(_mm512_xor_si512(v, _mm512_srli_epi64::<27>(v)), c2);
                let f = _mm512_cvtepi64_ps(_mm512_srli_epi64::<40>(v));
                _mm256_storeu_ps(out.as_mut_ptr().add(8 * h), _mm256_mul_ps(f, scale));
            }
        }
        out
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512dq")))]
    {
        unit_draws16_scalar(z)
    }
}

/// The scalar twin of [`unit_draws16`].
#[inline]
pub fn unit_draws16_scalar(z: &[u64; 16]) -> [f32; 16] {
    // `mix_unfinished` of draw 0 after `z - γ` mixes `z` itself.
    z.map(|z| draw(z.wrapping_sub(GAMMA), 0))
}

/// The swap targets of a Fisher-Yates shuffle of `n <= 16` items (the scalar
/// oracle: `integrator::sampling::shuffle_by`, which draws `PixelRng::below(i + 1)` for
/// `i` from `n - 1` down to 1): `j[m]` is the target of step `m`, item `i = n - 1 - m`,
/// from draw `m` after `state` (the full mix, `next_u64`): `((draw >> 32) (n - m)) >>
/// 32`. Entries `m >= n - 1` are unspecified. The caller advances its state by `γ`
/// per step it takes.
#[inline]
pub fn shuffle_targets16(state: u64, n: u32) -> [u32; 16] {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
    {
        // SAFETY: AVX-512F/DQ are enabled at compile time; the stores write the
        // 16-element array exactly (two 8-element halves).
        unsafe { shuffle_targets16_avx512(state, n) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512dq")))]
    {
        shuffle_targets16_scalar(state, n)
    }
}

/// The scalar twin of [`shuffle_targets16`].
#[inline]
pub fn shuffle_targets16_scalar(state: u64, n: u32) -> [u32; 16] {
    std::array::from_fn(|m| {
        let mut z = mix_unfinished(state, m as u64);
        z ^= z >> 31;
        (((z >> 32) * (n.wrapping_sub(m as u32)) as u64) >> 32) as u32
    })
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512dq"))]
#[inline]
unsafe fn shuffle_targets16_avx512(state: u64, n: u32) -> [u32; 16] {
    use std::arch::x86_64::*;
    // `(m + 1) γ` and `m` for the sixteen steps.
    const STEPS: [u64; 16] = {
        let mut out = [0u64; 16];
        let mut m = 0;
        while m < 16 {
            out[m] = (m as u64 + 1).wrapping_mul(GAMMA);
            m += 1;
        }
        out
    };
    const IOTA: [u64; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15];
    let mut out = [0u32; 16];
    // SAFETY (whole body): the loads read the 16-element constant arrays in two halves,
    // the stores write `out` in two halves; the target features are enabled.
    unsafe {
        let s = _mm512_set1_epi64(state as i64);
        let nn = _mm512_set1_epi64(n as i64);
        for h in 0..2 {
            let mut z = mix_unfinished8(s, STEPS.as_ptr().add(8 * h));
            z = _mm512_xor_si512(z, _mm512_srli_epi64::<31>(z));
            // The bound `n - m` (its low 32 bits, as the scalar `u32` subtraction) times
            // the draw's top 32 bits: `vpmuludq` multiplies the low 32 bits of each lane.
            let bound = _mm512_sub_epi64(nn, _mm512_loadu_si512(IOTA.as_ptr().add(8 * h).cast()));
            let j = _mm512_srli_epi64::<32>(_mm512_mul_epu32(_mm512_srli_epi64::<32>(z), bound));
            _mm256_storeu_si256(out.as_mut_ptr().add(8 * h).cast(), _mm512_cvtepi64_epi32(j));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::PixelRng;
    use crate::test_rng::xorshift64;

    /// [`shuffle_targets16`] (lanes where built with AVX-512DQ) and its scalar twin
    /// against `PixelRng::below(i + 1)` drawn for `i` from `n - 1` down to 1, for every
    /// `n` from 2 to 16, streams from random states and states near the wrap.
    #[test]
    fn shuffle_targets_are_the_streams_draws() {
        let mut next = xorshift64(0x1f83_d9ab_fb41_bd6b);
        for case in 0..5_000 {
            let mut rng = PixelRng::new(next(), next());
            if case % 97 == 0 {
                rng =
                    PixelRng::from_state(u64::MAX.wrapping_sub((next() % 64).wrapping_mul(GAMMA)));
            }
            for n in 2..=16u32 {
                let state = rng.state();
                let lanes = shuffle_targets16(state, n);
                let scalar = shuffle_targets16_scalar(state, n);
                let mut r = PixelRng::from_state(state);
                for (m, i) in (1..n).rev().enumerate() {
                    let want = r.below(i + 1);
                    assert_eq!(lanes[m], want, "case {case} n {n} step {m}");
                    assert_eq!(scalar[m], want, "case {case} n {n} scalar step {m}");
                }
            }
        }
    }

    /// [`unit_draws16`] and its scalar twin against `PixelRng::next_f32` of sixteen
    /// streams, bit for bit: lane `l` holds draw `m_l` (0 to 31) of stream `l`, the
    /// advanced states given; random streams and states near the wrap.
    #[test]
    fn draws_of_sixteen_streams_are_each_streams_draw() {
        let mut next = xorshift64(0x2545_f491_4f6c_dd1d);
        for case in 0..20_000 {
            let mut z = [0u64; 16];
            let mut want = [0.0f32; 16];
            for l in 0..16 {
                let state = if case % 53 == 0 {
                    u64::MAX.wrapping_sub((next() % 64).wrapping_mul(GAMMA))
                } else {
                    next()
                };
                let m = next() % 32;
                let mut r = PixelRng::from_state(state);
                for _ in 0..m {
                    r.next_f32();
                }
                want[l] = r.next_f32();
                z[l] = state.wrapping_add((m + 1).wrapping_mul(GAMMA));
            }
            let lanes = unit_draws16(&z);
            let scalar = unit_draws16_scalar(&z);
            for l in 0..16 {
                assert_eq!(
                    lanes[l].to_bits(),
                    want[l].to_bits(),
                    "case {case} lane {l}"
                );
                assert_eq!(
                    scalar[l].to_bits(),
                    want[l].to_bits(),
                    "case {case} lane {l}"
                );
            }
        }
    }

    /// [`unit_pairs16`] (the lane kernel where built with AVX-512DQ) and its scalar twin
    /// against 32 successive `PixelRng::next_f32` draws, bit for bit: streams started
    /// from random seeds and pixels, advanced by a random number of draws first (so
    /// the state wraps around at random points), and states near the wrap.
    #[test]
    fn lane_draws_are_the_streams_draws_bit_for_bit() {
        let mut next = xorshift64(0x510e_527f_ade6_82d1);
        let mut checked = 0usize;
        for case in 0..20_000 {
            let mut rng = PixelRng::new(next(), next());
            for _ in 0..(next() % 40) {
                rng.next_f32();
            }
            if case % 97 == 0 {
                rng =
                    PixelRng::from_state(u64::MAX.wrapping_sub((next() % 64).wrapping_mul(GAMMA)));
            }
            let state = rng.state();
            let (mut u, mut v) = ([0.0f32; 16], [0.0f32; 16]);
            let (mut su, mut sv) = ([0.0f32; 16], [0.0f32; 16]);
            unit_pairs16(state, &mut u, &mut v);
            unit_pairs16_scalar(state, &mut su, &mut sv);
            for p in 0..16 {
                let (a, b) = (rng.next_f32(), rng.next_f32());
                assert_eq!(u[p].to_bits(), a.to_bits(), "case {case} u[{p}]");
                assert_eq!(v[p].to_bits(), b.to_bits(), "case {case} v[{p}]");
                assert_eq!(su[p].to_bits(), a.to_bits(), "case {case} scalar u[{p}]");
                assert_eq!(sv[p].to_bits(), b.to_bits(), "case {case} scalar v[{p}]");
                checked += 2;
            }
        }
        assert_eq!(checked, 20_000 * 32);
    }
}
