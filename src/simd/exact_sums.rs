//! The `f64` fast path of the pixel filter's exact sums
//! ([`PixelSums`](crate::film::PixelSums)), seven addends in one 8-lane step: every
//! lane does the same operations and no lane branches.
//!
//! Measured (callgrind, render phase of the bunny at 512x512, 1 sample per pixel): the
//! scalar per-addend loop (a short-circuit `x != 0 && is_finite` and a compare per
//! addend) cost about 340 instructions per pixel, a fifth of the frame's
//! instructions; written branch-free in scalars the compiler still did not vectorise
//! it (330).

use glam::Vec3;
use wide::{f32x8, f64x4, f64x8, i32x8, u32x4};

/// `2^(ulp_min + 53)`: sums of `f32` addends that are multiples of `2^ulp_min` are
/// exact in `f64` while every sum of their magnitudes stays below it (the argument of
/// [`PixelSums`](crate::film::PixelSums)). `ulp_min` is in -149..=104, so the bound is
/// a normal `f64`.
#[inline(always)]
pub fn exact_bound(ulp_min: i32) -> f64 {
    f64::from_bits(((ulp_min + 53 + 1023) as u64) << 52)
}

/// Adds the seven `f32` addends `xs` to the `f64` sums `fast` (and their magnitudes to
/// `abs`, the smallest ulp exponent of the finite non-zero ones to `ulp_min`) if every
/// sum stays exact: every `abs` below `2^(ulp_min + 53)` (the argument of
/// [`PixelSums`](crate::film::PixelSums)). Zero and non-finite addends add nothing.
/// Returns `false`, changing nothing, when some sum could round.
///
/// The same results, bit for bit, as the scalar rule: each `f64` addition is exact
/// whenever this returns `true`, so the order of lanes does not matter, and the ulp
/// exponent is `max(biased exponent, 1) - 150` as for the scalar code.
#[inline(always)]
pub fn add7_if_exact(
    fast: &mut [f64; 7],
    abs: &mut [f64; 7],
    ulp_min: &mut i32,
    xs: [f32; 7],
) -> bool {
    let x = f32x8::new([xs[0], xs[1], xs[2], xs[3], xs[4], xs[5], xs[6], 0.0]);
    let bits: i32x8 = wide::bytemuck::cast(x);
    let magnitude = bits & i32x8::splat(0x7fff_ffff);
    // magnitude >= 0, so the signed compares are the unsigned ones.
    let keep = magnitude.simd_gt(i32x8::splat(0)) & magnitude.simd_lt(i32x8::splat(0x7f80_0000));
    let biased: i32x8 = magnitude >> 23;
    let e = biased.max(i32x8::splat(1)) - i32x8::splat(150);
    let e_min = keep
        .select(e, i32x8::splat(i32::MAX))
        .reduce_min()
        .min(*ulp_min);
    let kept: [f32; 8] = wide::bytemuck::cast(bits & keep);
    let v = f64x8::new(kept.map(f64::from));
    let mut a8 = [0.0f64; 8];
    a8[..7].copy_from_slice(abs);
    let a = f64x8::new(a8) + v.abs();
    if e_min != i32::MAX {
        let bound = exact_bound(e_min);
        if !a.simd_lt(f64x8::splat(bound)).all() {
            return false;
        }
    }
    let mut f8 = [0.0f64; 8];
    f8[..7].copy_from_slice(fast);
    let f = (f64x8::new(f8) + v).to_array();
    let a = a.to_array();
    fast.copy_from_slice(&f[..7]);
    abs.copy_from_slice(&a[..7]);
    *ulp_min = e_min;
    true
}

/// One of [`box_sums_if_exact`]'s two accumulators: the `f64` sums of its samples'
/// components and of their magnitudes in lanes 0-2, the smallest magnitude (as bits)
/// minus one, wrapping (a zero addend becomes `u32::MAX` and so never the minimum),
/// and the count of non-finite samples.
#[derive(Clone, Copy)]
struct BoxLanes {
    sum: f64x4,
    abs: f64x4,
    min: u32x4,
    nonfinite: u64,
}

impl BoxLanes {
    fn new() -> Self {
        BoxLanes {
            sum: f64x4::splat(0.0),
            abs: f64x4::splat(0.0),
            min: u32x4::splat(u32::MAX),
            nonfinite: 0,
        }
    }

    #[inline(always)]
    fn add(&mut self, r: Vec3) {
        let finite = r.is_finite();
        self.nonfinite += !finite as u64;
        let r = if finite { r } else { Vec3::ZERO };
        let v = f64x4::new([r.x as f64, r.y as f64, r.z as f64, 0.0]);
        self.sum += v;
        self.abs += v.abs();
        let m = r.abs().to_array().map(f32::to_bits);
        self.min = self
            .min
            .min(u32x4::new([m[0], m[1], m[2], 0]) - u32x4::splat(1));
    }
}

/// The box filter's three `f64` sums of a pixel's radiance samples (a non-finite
/// sample counts as zero), with the number of non-finite samples, where the sums are
/// exact by [`PixelSums`](crate::film::PixelSums)' rule (every `Σ|x|` below
/// `2^(e_min + 53)`, `e_min` the smallest ulp exponent of the pixel's non-zero
/// addends); `None` where a sum might round.
///
/// The samples go alternately into two accumulators of `f64x4` lanes (x, y, z) and the
/// two are added at the end. Where the rule holds every partial sum is exact in any
/// order, so these are the bits of the samples summed one after another; where it
/// fails the test fails here too: a partial sum of non-negative magnitudes whose exact
/// value reaches the power of two `2^(e_min + 53)` rounds to at least it (rounding is
/// monotone), and sums below it are exact.
///
/// Why: the scalar loop (`PixelSums::box_mean_value` before) carried one chain of
/// minimums through all the pixel's 27 components and chains of nine dependent `f64`
/// additions per component: its `min` line held a fifth of the pixel filter's samples
/// (perf annotate, whitted_base `--spp 9 --sampler grid`, 1 thread).
#[inline(always)]
pub fn box_sums_if_exact(radiance: &[Vec3]) -> Option<([f64; 3], u64)> {
    let (mut a, mut b) = (BoxLanes::new(), BoxLanes::new());
    let mut pairs = radiance.chunks_exact(2);
    for p in &mut pairs {
        a.add(p[0]);
        b.add(p[1]);
    }
    if let [r] = pairs.remainder() {
        a.add(*r);
    }
    let min = a.min.min(b.min).to_array();
    // Back to the magnitude; 0 where every addend is zero (no bound to test).
    let min_magnitude = min[0].min(min[1]).min(min[2]).wrapping_add(1);
    let abs = (a.abs + b.abs).to_array();
    if min_magnitude != 0 {
        let ulp_min = ((min_magnitude >> 23) as i32).max(1) - 150;
        let bound = exact_bound(ulp_min);
        if !(abs[0] < bound && abs[1] < bound && abs[2] < bound) {
            return None;
        }
    }
    let sum = (a.sum + b.sum).to_array();
    Some(([sum[0], sum[1], sum[2]], a.nonfinite + b.nonfinite))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scalar rule of `PixelSums` (before this step), as the oracle.
    fn scalar(fast: &mut [f64; 7], abs: &mut [f64; 7], ulp_min: &mut i32, xs: [f32; 7]) -> bool {
        let mut u = *ulp_min;
        let mut a = *abs;
        for (s, x) in a.iter_mut().zip(xs) {
            if x != 0.0 && x.is_finite() {
                u = u.min((((x.to_bits() >> 23) & 0xff) as i32).max(1) - 150);
                *s += x.abs() as f64;
            }
        }
        let exact = u == i32::MAX || {
            let bound = f64::from_bits(((u + 53 + 1023) as u64) << 52);
            a.iter().all(|&s| s < bound)
        };
        if exact {
            for (s, x) in fast.iter_mut().zip(xs) {
                if x.is_finite() {
                    *s += x as f64;
                }
            }
            *abs = a;
            *ulp_min = u;
        }
        exact
    }

    #[test]
    fn the_lanes_give_the_scalar_rules_bits() {
        let specials = [
            0.0f32,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            1e-45,
            -3e-40,
            f32::MAX,
            -f32::MAX,
            1.0,
            -0.75,
        ];
        let mut next = crate::test_rng::xorshift64(0x9e37_79b9_7f4a_7c15u64);
        let (mut exact, mut not) = (0, 0);
        for _ in 0..2000 {
            let (mut f1, mut a1, mut u1) = ([0.0f64; 7], [0.0f64; 7], i32::MAX);
            let (mut f2, mut a2, mut u2) = (f1, a1, u1);
            let samples = 1 + next() % 40;
            // Binary orders the set's addends span: 1 stays exact, 60 soon does not.
            let span = 1 + (next() % 60) as u32;
            for _ in 0..samples {
                let xs: [f32; 7] = std::array::from_fn(|_| {
                    let r = next();
                    if r.is_multiple_of(50) {
                        specials[(r >> 8) as usize % specials.len()]
                    } else {
                        // random sign, exponent in the set's window, mantissa
                        let e = 127 - 30 + (r >> 40) as u32 % span;
                        f32::from_bits(((r >> 63) as u32) << 31 | e << 23 | (r as u32 & 0x7f_ffff))
                    }
                });
                let r1 = add7_if_exact(&mut f1, &mut a1, &mut u1, xs);
                let r2 = scalar(&mut f2, &mut a2, &mut u2, xs);
                assert_eq!(r1, r2, "{xs:?}");
                assert_eq!(f1.map(f64::to_bits), f2.map(f64::to_bits), "{xs:?}");
                assert_eq!(a1.map(f64::to_bits), a2.map(f64::to_bits), "{xs:?}");
                assert_eq!(u1, u2, "{xs:?}");
                if r1 {
                    exact += 1;
                } else {
                    not += 1;
                    break;
                }
            }
        }
        // Both outcomes exercised many times.
        assert!(exact > 1000 && not > 100, "exact {exact}, not {not}");
    }
}
