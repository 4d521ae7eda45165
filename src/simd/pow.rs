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

/// [`pow`] with the same exponent `e` in every lane, bit for bit `pow(x, splat(e))`
/// for every `x` and `e`, with less work where the shading stage calls it.
///
/// Where `e` is finite and `≥ 0` and no lane of `x` is negative or NaN (the sign bit
/// clear: `+0 ..= +inf`), `wide`'s `powf_simd` returns the value its kernel builds after
/// the overflow, underflow and zero-base selects: its sign fix-up (`x` negative) selects
/// nothing, its final test for non-finite inputs falls through to `select(is_nan(x) |
/// is_nan(e), x + e, z)`, which is `z` without a NaN, and the zero base's value
/// (`inf` for `e < 0`, else `1` for `e = 0`, else `0`) is decided once from `e`. Those
/// selects and tests are skipped here and the rest is `powf_simd`'s code, operation for
/// operation (VCL `pow_template_f`, see the module notes); elsewhere it calls [`pow`].
///
/// Measured before (perf, whitted_aa3x3 and whitted_blur16, 1 thread): [`pow`] was
/// 5-7 % of `shade_group_lanes`' samples (the point lights' highlights).
// The constants as `wide` (and VCL) write them, digit for digit, so they can be
// compared with the source; each rounds to the same f32.
#[allow(clippy::excessive_precision)]
#[inline(always)]
pub fn pow_uniform(x: Packet, e: f32) -> Packet {
    use wide::bytemuck::cast;
    use wide::{i32x16, u32x16};
    let bits: i32x16 = cast(x);
    // Sign bit clear and not NaN: 0 ..= 0x7f80_0000 as a signed integer.
    let outside = bits.simd_lt(i32x16::splat(0)) | bits.simd_gt(i32x16::splat(0x7f80_0000));
    if !(0.0..=f32::MAX).contains(&e) || outside.to_bitmask() != 0 {
        return pow(x, Packet::splat(e));
    }
    let n = Packet::splat(e);
    let c = Packet::splat;
    let (half, one) = (Packet::HALF, Packet::ONE);
    let (ln2f_hi, ln2f_lo) = (c(0.693359375), c(-2.12194440e-4));
    let p = [
        3.3333331174E-1,
        -2.4999993993E-1,
        2.0000714765E-1,
        -1.6668057665E-1,
        1.4249322787E-1,
        -1.2420140846E-1,
        1.1676998740E-1,
        -1.1514610310E-1,
        7.0376836292E-2,
    ]
    .map(c);
    let q = [
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
    ]
    .map(c);

    // `x1 = abs(x)` is `x`: the sign bit is clear.
    let x1 = x;
    // `fraction_2`: the mantissa with exponent -1.
    let u: u32x16 = cast(x1);
    let x: Packet = cast((u & u32x16::splat(0x007F_FFFF)) | u32x16::splat(0x3F00_0000));
    let mask = x.simd_gt(Packet::SQRT_2 * half);
    let x = (!mask).select(x + x, x);
    let x = x - one;
    let x2 = x * x;
    // `polynomial_8!`
    let (x4, x8) = (x2 * x2, (x2 * x2) * (x2 * x2));
    let lg1 = x4.mul_add(
        x2.mul_add(p[7].mul_add(x, p[6]), x.mul_add(p[5], p[4])),
        x8.mul_add(
            p[8],
            x2.mul_add(x.mul_add(p[3], p[2]), x.mul_add(p[1], p[0])),
        ),
    );
    let lg1 = lg1 * x2 * x;
    // `exponent`: the unbiased exponent as a float.
    let pow2_23 = c(8388608.0);
    let ef: Packet = cast::<u32x16, Packet>((u >> 23_u32) | cast::<Packet, u32x16>(pow2_23));
    let ef = ef - (pow2_23 + c(127.0));
    let ef = mask.select(ef + one, ef);
    let e1 = (ef * n).round_ties_even();
    let yr = ef.mul_sub(n, e1);

    let lg = half.mul_neg_add(x2, x) + lg1;
    let x2_err = (half * x).mul_sub(x, half * x2);
    let lg_err = half.mul_add(x2, lg - x) - lg1;

    let e2 = (lg * n * Packet::LOG2_E).round_ties_even();
    let v = lg.mul_sub(n, e2 * ln2f_hi);
    let v = e2.mul_neg_add(ln2f_lo, v);
    let v = v - (lg_err + x2_err).mul_sub(n, yr * Packet::LN_2);

    let x = v;
    let e3 = (x * Packet::LOG2_E).round_ties_even();
    let x = e3.mul_neg_add(Packet::LN_2, x);
    let x2 = x * x;
    // `polynomial_5!`
    let x4 = x2 * x2;
    let poly = q[3]
        .mul_add(x, q[2])
        .mul_add(x2, q[5].mul_add(x, q[4]).mul_add(x4, q[1].mul_add(x, q[0])));
    let z = x2.mul_add(poly, x + one);

    let ee = e1 + e2 + e3;
    let ei: i32x16 = ee.round_int();
    let ej: i32x16 = ei + (cast::<Packet, i32x16>(z) >> 23_i32);
    let overflow: Packet =
        cast::<i32x16, Packet>(ej.simd_gt(i32x16::splat(0x0FF))) | ee.simd_gt(c(300.0));
    let underflow: Packet =
        cast::<i32x16, Packet>(ej.simd_lt(i32x16::splat(0))) | ee.simd_lt(c(-300.0));
    let z: Packet = cast::<i32x16, Packet>(cast::<Packet, i32x16>(z) + (ei << 23_i32));
    let z = underflow.select(c(0.0), z);
    let z = overflow.select(c(f32::INFINITY), z);
    // `is_zero_or_subnormal` of the base: `0^e` is 1 for `e = 0`, else 0 (`e > 0`).
    let zero_base = (bits & i32x16::splat(0x7F80_0000)).simd_eq(i32x16::splat(0));
    let zero_value = c(if e == 0.0 { 1.0 } else { 0.0 });
    cast::<i32x16, Packet>(zero_base).select(zero_value, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`pow_uniform`] is [`pow`] of the splat bit for bit: bases of every exponent
    /// (subnormals, zeros of both signs, near 1, above 1 up to overflow, infinities,
    /// NaNs, negative numbers: the last three in some lanes of a group send the group
    /// to [`pow`]) against exponents of the shading domain and outside it (negative,
    /// infinite, NaN), and the fast path was taken. A NaN result must be a NaN on both
    /// sides; its sign and payload are not compared.
    #[test]
    fn uniform_pow_is_the_lane_pow_bit_for_bit() {
        let mut state = 0x853c_49e6_748f_ea9bu64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut xs: Vec<f32> = (0..4000).map(|i| i as f32 / 4000.0).collect();
        xs.extend((1..2000).map(|i| 1.0 - i as f32 * 1e-6));
        xs.extend((0..3000).map(|_| f32::from_bits(next() as u32 & 0x7fff_ffff)));
        xs.extend((0..1000).map(|_| f32::from_bits(next() as u32 & 0x3fff_ffff)));
        xs.extend([
            0.0,
            f32::MIN_POSITIVE,
            1e-45,
            1.0,
            1.0000001,
            2.0,
            1e30,
            f32::MAX,
        ]);
        // Either side of the mantissa split at √½.
        let split = std::f32::consts::FRAC_1_SQRT_2.to_bits();
        xs.extend([split - 1, split, split + 1].map(f32::from_bits));
        xs.extend([f32::INFINITY, 0.999_999_9, 0.5]);
        let outside = [-0.0, -1e-3, -2.0, f32::NAN, -f32::NAN, f32::NEG_INFINITY];
        let es = [
            0.0,
            -0.0,
            0.5,
            1.0,
            2.0,
            3.0,
            7.3,
            32.0,
            100.0,
            200.0,
            500.0,
            1e4,
            1e6,
            1e30,
            f32::MAX,
            -1.0,
            -2.5,
            f32::INFINITY,
            f32::NAN,
        ];
        let (mut groups, mut fast) = (0, 0);
        for (k, &e) in es.iter().enumerate() {
            for (g, chunk) in xs.chunks(16).enumerate() {
                let mut a = [0.25f32; 16];
                a[..chunk.len()].copy_from_slice(chunk);
                if g % 7 == 3 {
                    a[(g + k) % 16] = outside[(g / 7 + k) % outside.len()];
                }
                let x = Packet::new(a);
                // Bits compared exactly, except that any NaN counts as one NaN: Rust
                // leaves the sign and payload of a NaN result nondeterministic (the
                // reference's floating-point NaN semantics), and the unoptimised test
                // profile gives `-NaN + NaN` either sign; nothing downstream reads them.
                let canon = |v: f32| {
                    if v.is_nan() {
                        f32::NAN.to_bits()
                    } else {
                        v.to_bits()
                    }
                };
                let got = pow_uniform(x, e).to_array().map(canon);
                let want = pow(x, Packet::splat(e)).to_array().map(canon);
                assert_eq!(got, want, "{a:?}^{e}");
                groups += 1;
                fast += (g % 7 != 3 && (0.0..=f32::MAX).contains(&e)) as usize;
            }
        }
        assert!(
            fast > groups / 2 && fast < groups,
            "{fast} of {groups} on the fast path"
        );
    }

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
