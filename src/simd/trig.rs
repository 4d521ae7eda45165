//! `sin` and `cos` over lanes, with no libm call per lane: the lens points of depth of
//! field ([`super::aperture`]) need both for every camera ray.
//!
//! Only the primary range `|x| <= π/4` is needed (the concentric disk map's angle is
//! `π/4 · t`, `|t| <= 1`, the other octants follow by symmetry), so there is no range
//! reduction. The polynomials are the single-precision minimax ones of Cephes
//! (Moshier, "Methods and Programs for Mathematical Functions", 1989: `sinf.c`,
//! `cosf.c`), evaluated by Horner's rule with separate multiplies and adds: the
//! compiler never fuses them, so every lane width (and the one-lane scalar path of
//! [`sin_cos_one`]) gives the same bits on any x86-64 build, with or without FMA.
//!
//! Accuracy, measured by the test below against `f64` sine and cosine over
//! `[-π/4, π/4]`: see [`SIN_COS_MAX_ERROR`].
//!
//! Why: libm's `sincosf` per lens sample was 4.2-4.8 % of the whole 16-lens-sample
//! depth-of-field frame (`perf`, whitted_blur16, 1 thread), a sixth of its camera stage.

use super::{F4, Lanes};

/// The largest absolute error of [`sin_cos`] against the exact sine and cosine
/// (`f64`, unrounded) on `|x| <= π/4`: measured 4.5e-8 (sine) and 5.8e-8 (cosine);
/// half an ulp of values in `[0.5, 1)` is 3.0e-8, so the polynomials stay within one
/// ulp there, where libm's results are within half an ulp. The bound keeps a margin
/// over the measurement; the test holds the functions to it on 2^21 points of the
/// range and its ends. On the unit lens this moves a lens point by at most this much
/// (times the aperture radius in world units): 1.2e-8 scene units for blur16's 0.2.
pub const SIN_COS_MAX_ERROR: f32 = 8e-8;

/// `(sin x, cos x)` per lane for `|x| <= π/4` (larger arguments are out of contract:
/// the error grows with `|x|`).
#[inline(always)]
pub fn sin_cos<L: Lanes>(x: L) -> (L, L) {
    let z = x * x;
    let s = ((L::splat(-1.951_529_6e-4) * z + L::splat(8.332_161e-3)) * z
        + L::splat(-1.666_665_5e-1))
        * z
        * x
        + x;
    let c = ((L::splat(2.443_315_7e-5) * z + L::splat(-1.388_731_6e-3)) * z
        + L::splat(4.166_664_6e-2))
        * z
        * z
        - L::splat(0.5) * z
        + L::splat(1.0);
    (s, c)
}

/// [`sin_cos`] of one value, the same bits (it runs the lane code on one lane).
#[inline]
pub fn sin_cos_one(x: f32) -> (f32, f32) {
    let (s, c) = sin_cos(F4::splat(x));
    (s.to_array()[0], c.to_array()[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{F8, F16};
    use std::f32::consts::FRAC_PI_4;

    /// Every lane width gives the bits of the one-lane path, and the error against the
    /// exact sine and cosine stays within `SIN_COS_MAX_ERROR` on 2^21 evenly spaced
    /// points of `[-π/4, π/4]`, the ends, zero of both signs and tiny arguments (where
    /// `sin x` must be `x` and `cos x` must be 1).
    #[test]
    fn lane_sin_cos_is_within_its_stated_bound() {
        let n = 1 << 20;
        let mut xs: Vec<f32> = (-n..=n)
            .map(|i| (i as f64 / n as f64 * std::f64::consts::FRAC_PI_4) as f32)
            .collect();
        xs.extend([FRAC_PI_4, -FRAC_PI_4, 0.0, -0.0, 1e-30, -1e-20, 1e-4, 0.5]);
        let (mut worst_sin, mut worst_cos) = (0.0f64, 0.0f64);
        for chunk in xs.chunks(16) {
            let mut a = [0.0f32; 16];
            a[..chunk.len()].copy_from_slice(chunk);
            let (s16, c16) = sin_cos(F16::from_array(a));
            let (s16, c16) = (s16.to_array(), c16.to_array());
            let (s8, c8) = sin_cos(F8::load(&a[8..]));
            for (i, &x) in chunk.iter().enumerate() {
                let (s, c) = sin_cos_one(x);
                assert_eq!(
                    (s16[i].to_bits(), c16[i].to_bits()),
                    (s.to_bits(), c.to_bits())
                );
                if i >= 8 {
                    let (s8, c8) = (s8.to_array()[i - 8], c8.to_array()[i - 8]);
                    assert_eq!((s8.to_bits(), c8.to_bits()), (s.to_bits(), c.to_bits()));
                }
                let (es, ec) = ((x as f64).sin(), (x as f64).cos());
                worst_sin = worst_sin.max((s as f64 - es).abs());
                worst_cos = worst_cos.max((c as f64 - ec).abs());
                assert!(
                    (s as f64 - es).abs() <= SIN_COS_MAX_ERROR as f64
                        && (c as f64 - ec).abs() <= SIN_COS_MAX_ERROR as f64,
                    "x {x:e}: sin {s:e} vs {es:e}, cos {c:e} vs {ec:e}"
                );
            }
        }
        // Tiny arguments: exact.
        // (`-0` comes out as `+0`: `poly · z · x + x` adds `+0` to it.)
        for x in [0.0f32, -0.0, 1e-30, -1e-20, f32::from_bits(1)] {
            let (s, c) = sin_cos_one(x);
            assert_eq!((s, c), (x, 1.0), "{x:e}");
        }
        println!("worst |sin - exact| {worst_sin:e}, |cos - exact| {worst_cos:e}");
        // The bound is not loose by more than a factor of two (it says what it claims).
        assert!(worst_sin.max(worst_cos) > SIN_COS_MAX_ERROR as f64 / 2.0);
    }
}
