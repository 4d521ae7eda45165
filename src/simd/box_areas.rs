//! The surface areas of three boxes in the first three lanes of one vector, for the
//! binned-SAH sweep that runs its three axes in lanes (Wald 2007, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies"; Embree's binner sweeps its
//! axes the same way). The boxes come as their extents, one per vector (`x, y, z` in
//! lanes 0-2, lane 3 ignored); a 3x3 transpose puts the `x` extents of the three boxes
//! in one vector, the `y` and `z` in two more, and each lane then computes
//! `2 * (x * y + y * z + z * x)`: the operations of the builder's scalar box area, in
//! the same order, so each lane is that area bit for bit.
//!
//! With SSE (every x86-64) the transpose is six shuffles; elsewhere the lanes are
//! gathered one by one (the same values).

use glam::Vec4;

#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
use std::arch::x86_64::_mm_ceil_ps;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::{
    __m128, _mm_movehl_ps, _mm_movelh_ps, _mm_setzero_ps, _mm_unpackhi_ps, _mm_unpacklo_ps,
};

/// Each lane rounded up, for the sweep's leaf blocks (a side's count times
/// `1 / block_size`, then up to a whole block): one `roundps` with SSE4.1, where
/// glam's `Vec4::ceil` (built for plain SSE2) takes eight operations. Both give the
/// exact ceiling of every non-negative finite lane, so the sweep's costs are the
/// same bit for bit (they differ only in the sign of zero for lanes in (-1, 0)).
#[inline(always)]
pub fn ceil(v: Vec4) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        // SAFETY: SSE4.1 is enabled at compile time (the cfg above).
        unsafe { _mm_ceil_ps(v.into()).into() }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    {
        v.ceil()
    }
}

/// `[area(e0), area(e1), area(e2), 0]` for extents `e0, e1, e2` (lane 3 of each is
/// ignored), each area `2 * (x * y + y * z + z * x)`.
#[inline(always)]
pub fn areas3(e0: Vec4, e1: Vec4, e2: Vec4) -> Vec4 {
    let (x, y, z) = transpose3(e0, e1, e2);
    2.0 * (x * y + y * z + z * x)
}

/// The `x`, `y` and `z` lanes of three vectors, each gathered into lanes 0-2 of one
/// vector (lane 3 zero).
#[inline(always)]
fn transpose3(e0: Vec4, e1: Vec4, e2: Vec4) -> (Vec4, Vec4, Vec4) {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE is part of the x86-64 baseline; these are register shuffles.
        unsafe {
            let (a, b, c): (__m128, __m128, __m128) = (e0.into(), e1.into(), e2.into());
            let zero = _mm_setzero_ps();
            let t0 = _mm_unpacklo_ps(a, b); // a.x b.x a.y b.y
            let t1 = _mm_unpackhi_ps(a, b); // a.z b.z a.w b.w
            let t2 = _mm_unpacklo_ps(c, zero); // c.x 0 c.y 0
            let t3 = _mm_unpackhi_ps(c, zero); // c.z 0 c.w 0
            (
                _mm_movelh_ps(t0, t2).into(), // a.x b.x c.x 0
                _mm_movehl_ps(t2, t0).into(), // a.y b.y c.y 0
                _mm_movelh_ps(t1, t3).into(), // a.z b.z c.z 0
            )
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        (
            Vec4::new(e0.x, e1.x, e2.x, 0.0),
            Vec4::new(e0.y, e1.y, e2.y, 0.0),
            Vec4::new(e0.z, e1.z, e2.z, 0.0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each lane is the scalar area of its box, bit for bit, for extents with zeros,
    /// infinities (empty boxes clamp to zero extents, but an infinite extent is a
    /// possible input) and garbage in lane 3; lane 3 of the result is zero.
    #[test]
    fn lanes_are_the_scalar_areas() {
        let scalar = |e: Vec4| 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        let mut s = 0x2545_f491_u32;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            match s % 11 {
                0 => 0.0,
                1 => f32::INFINITY,
                2 => f32::NAN,
                _ => (s >> 8) as f32 * 1e-4,
            }
        };
        for i in 0..2000 {
            let mut e = [Vec4::ZERO; 3];
            for v in &mut e {
                *v = Vec4::new(next().abs(), next().abs(), next().abs(), next());
            }
            let got = areas3(e[0], e[1], e[2]).to_array();
            for k in 0..3 {
                assert_eq!(
                    got[k].to_bits(),
                    scalar(e[k]).to_bits(),
                    "case {i} box {k}: {:?}",
                    e[k]
                );
            }
            assert_eq!(got[3].to_bits(), 0, "case {i}");
        }
    }

    /// The ceiling is glam's, bit for bit, on the sweep's inputs: counts from 0 to
    /// 2^24 times a block size's inverse (1, 1/2, 1/4, 1/8), plus other non-negative
    /// values (fractions, halves, past 2^23, infinity).
    #[test]
    fn ceil_matches_glam_on_non_negative_lanes() {
        let mut vals: Vec<f32> = Vec::new();
        for inv in [1.0f32, 0.5, 0.25, 0.125] {
            for c in (0u32..5000).chain((1 << 24) - 5000..=(1 << 24)) {
                vals.push(c as f32 * inv);
            }
        }
        vals.extend([
            0.3,
            0.5,
            1.5,
            2.5,
            8_388_607.5,
            8_388_608.0,
            3e9,
            1e-40,
            f32::INFINITY,
        ]);
        for w in vals.chunks(4) {
            let mut a = [0.0f32; 4];
            a[..w.len()].copy_from_slice(w);
            let v = Vec4::from_array(a);
            assert_eq!(
                ceil(v).to_array().map(f32::to_bits),
                v.ceil().to_array().map(f32::to_bits),
                "{a:?}"
            );
        }
    }
}
