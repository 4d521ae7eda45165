//! `x^e` over the lanes of a [`Packet`], with no libm call per lane: the Blinn-Phong
//! highlight `(n·h)^shininess` of the lane-parallel shading stage.
//!
//! The kernel is `wide`'s `powf_simd`, a port of Agner Fog's VCL `pow` (Vector Class
//! Library, `vectormath_exp.h`): `ln x` by a degree-8 minimax polynomial on the
//! mantissa with the exponent split off, carried in extended precision (the rounding
//! errors of `ln x` and of `e ln x` are kept and fed back), then `exp` by range
//! reduction with a two-part `ln 2` and a degree-7 Taylor polynomial. Its accuracy on
//! the shading domain is measured by the test below against an f64 reference.

use super::Packet;

/// Largest relative error of [`pow`] against the exact `x^e` (f64 `powf`, rounded to
/// f32) over the shading domain `x ∈ [0, 1]`, `e ∈ [0, 10000]`, for results above
/// `POW_TINY`. The error grows with `|e ln x|` (the reduced exponent's rounding is
/// scaled by it, about 1.2e-8 per unit): measured on the grid of the test, 1.2e-7 for
/// results above 1e-6 and 8.5e-7 at worst (`0.707^200 = 7.7e-31`, `|e ln x| = 69`,
/// next to the mantissa split at `√½`); the bound keeps a factor of two over the
/// worst. libm's `powf` is within 1 ulp (2^-23 relative), so the two differ by at most
/// `POW_REL_ERROR + 2^-23` relative.
#[cfg(target_feature = "fma")]
pub const POW_REL_ERROR: f32 = 2e-6;
/// Without FMA (a portable x86-64-v2 build) `wide` evaluates the same polynomials
/// with separate multiplies and adds, which round once more per step: measured worst
/// on the same grid 4.3e-6 (2.7e-6 at `0.00025^7.3`); the bound keeps a factor of two.
#[cfg(not(target_feature = "fma"))]
pub const POW_REL_ERROR: f32 = 1e-5;

/// Below this result size the relative bound does not hold (the result is subnormal in
/// f32, or flushed to zero by one and not the other): the error is absolute there, at
/// most this much. A highlight this small is invisible in any image.
pub const POW_TINY: f32 = 1e-36;

/// `x^e` per lane for `x ≥ 0` (a clamped cosine) and finite `e ≥ 0` (a validated
/// shininess): `0^0 = 1`, `0^e = 0` for `e > 0`, as `f32::powf`.
#[inline(always)]
pub fn pow(x: Packet, e: Packet) -> Packet {
    x.powf_simd(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative error against f64 `powf` over a grid of the shading domain, including
    /// the ends (`x = 0, 1`, `e = 0`) and the huge exponents of a sharp highlight.
    #[test]
    fn lane_pow_is_within_its_stated_bound() {
        let mut xs: Vec<f32> = (0..=4000).map(|i| i as f32 / 4000.0).collect();
        // Close to 1, where (n·h)^e with a large e changes fastest.
        xs.extend((1..2000).map(|i| 1.0 - i as f32 * 1e-6));
        xs.extend([f32::MIN_POSITIVE, 1e-20, 1e-3, 0.5, 0.999_999_9]);
        let es = [
            0.0, 0.5, 1.0, 2.0, 7.3, 32.0, 100.0, 200.0, 500.0, 1000.0, 2500.0, 10000.0,
        ];
        let mut worst = 0.0f64;
        for &e in &es {
            for chunk in xs.chunks(16) {
                let mut a = [0.5f32; 16];
                a[..chunk.len()].copy_from_slice(chunk);
                let got = pow(Packet::new(a), Packet::splat(e)).to_array();
                for (i, &x) in chunk.iter().enumerate() {
                    let want = (x as f64).powf(e as f64);
                    let g = got[i] as f64;
                    if want < POW_TINY as f64 {
                        assert!(
                            (g - want).abs() <= POW_TINY as f64,
                            "{x}^{e}: {g} against {want}"
                        );
                        continue;
                    }
                    let rel = (g - want).abs() / want;
                    worst = worst.max(rel);
                    assert!(
                        rel <= POW_REL_ERROR as f64,
                        "{x}^{e}: {g} against {want}, relative error {rel:e}"
                    );
                }
            }
        }
        // The special values f32::powf defines.
        let z = pow(
            Packet::splat(0.0),
            Packet::new([
                0.0, 1.0, 500.0, 0.5, 0.0, 1.0, 500.0, 0.5, 0.0, 1.0, 500.0, 0.5, 0.0, 1.0, 500.0,
                0.5,
            ]),
        )
        .to_array();
        assert_eq!(&z[..4], &[1.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            pow(Packet::splat(1.0), Packet::splat(1e4)).to_array()[0],
            1.0
        );
        eprintln!("lane pow: worst relative error {worst:e}");
    }
}
