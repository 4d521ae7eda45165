//! What the pixel filter accumulates for one pixel, kept exact so that the sums of
//! several renders of disjoint sample slices (`--sample-range`) merge into exactly the
//! sums of one render of all the samples.
//!
//! Exact and cheap: the seven sums are kept in `f64` for as long as that is exact,
//! and only a pixel whose addends span too many binary orders of magnitude falls back
//! to the long accumulator ([`ExactSum`], 88 bytes per sum). Every addend is an `f32`,
//! so it is a multiple of its own ulp `2^e` (`e = max(biased exponent, 1) - 150`); with
//! `e_min` the smallest such exponent of a pixel's addends, every partial sum is a
//! multiple of `2^e_min` and at most `Σ|x|` in magnitude, so while
//! `Σ|x| < 2^(e_min + 53)` every partial sum has at most 53 significant bits and every
//! `f64` addition is exact. `Σ|x|` is itself such a sum, so the test on it is exact too
//! (rounding is monotone and `2^(e_min + 53)` is a float). An exact `f64` total is what
//! [`ExactSum::to_f64`] returns for the same total (Horner's rule over the limbs of a
//! value with 53 significant bits never rounds), so the pixel value has the same bits
//! on either path, and merges may mix the two.
//!
//! Why: the render of a frame at 1 sample per pixel spent 25 % of its render phase in
//! the long accumulator (`ExactSum::add`, `to_f64`, and moves of the 616-byte sums;
//! bunny 1024x1024, 1 thread, `perf record`). 1 to thousands of radiance samples of
//! similar magnitude take the `f64` path.

use super::exact_sum::ExactSum;
use crate::simd::exact_sums::{add7_if_exact, box_sums_if_exact, exact_bound};
use glam::Vec3;

/// Index of `Σ w` among the seven sums (`Σ w·L` r, g, b; `Σ w`; `Σ L` r, g, b).
const WEIGHT: usize = 3;

/// The filter sums of one pixel over some of its eye samples: `Σ w·L` per channel,
/// `Σ w`, the unweighted `Σ L` (the fallback should every weight be zero) and the
/// number of eye samples. Exact (see the module documentation).
#[derive(Clone, Debug)]
pub struct PixelSums {
    /// The seven sums, exact in `f64` while `exact` is `None`.
    fast: [f64; 7],
    /// `Σ |x|` of each sum: bounds every partial sum.
    abs: [f64; 7],
    /// The smallest ulp exponent of any non-zero addend (`i32::MAX` before the first).
    ulp_min: i32,
    /// The long accumulators, once `f64` could no longer hold a sum exactly.
    exact: Option<Box<[ExactSum; 7]>>,
    pub samples: u32,
}

impl Default for PixelSums {
    fn default() -> Self {
        PixelSums {
            fast: [0.0; 7],
            abs: [0.0; 7],
            ulp_min: i32::MAX,
            exact: None,
            samples: 0,
        }
    }
}

/// Whether sums whose addends are multiples of `2^ulp_min` and whose absolute sums are
/// `abs` are held exactly by `f64`: every `abs` below `2^(ulp_min + 53)`.
#[inline]
fn f64_exact(abs: &[f64; 7], ulp_min: i32) -> bool {
    if ulp_min == i32::MAX {
        return true; // no non-zero addend yet: every sum is zero
    }
    let bound = exact_bound(ulp_min);
    // `&` rather than `all`: seven compares without a branch each.
    abs.iter().fold(true, |ok, &a| ok & (a < bound))
}

impl PixelSums {
    /// Adds one eye sample of filter weight `w` and (finite) radiance `l`. The product
    /// `w * l` is rounded to f32 here, per sample, so it does not depend on how the
    /// samples are split.
    #[inline]
    pub fn add_sample(&mut self, w: f32, l: Vec3) {
        let wl = w * l;
        let xs = [wl.x, wl.y, wl.z, w, l.x, l.y, l.z];
        self.samples += 1;
        if let Some(exact) = &mut self.exact {
            for (s, x) in exact.iter_mut().zip(xs) {
                s.add(x);
            }
            return;
        }
        // The rule of the module documentation, in eight lanes without branches
        // (`simd::exact_sums`; its test has the scalar loop as the oracle).
        if !add7_if_exact(&mut self.fast, &mut self.abs, &mut self.ulp_min, xs) {
            let exact = self.promote();
            for (s, x) in exact.iter_mut().zip(xs) {
                s.add(x);
            }
        }
    }

    /// Moves the sums into long accumulators (the `f64` sums are exact, so they carry
    /// over without loss) and returns them.
    fn promote(&mut self) -> &mut [ExactSum; 7] {
        let sums = self.exact_sums();
        self.exact.get_or_insert_with(|| Box::new(sums))
    }

    /// The seven sums as long accumulators: `Σ w·L` r, g, b, `Σ w`, `Σ L` r, g, b.
    pub fn exact_sums(&self) -> [ExactSum; 7] {
        match &self.exact {
            Some(e) => **e,
            None => self.fast.map(|v| {
                let mut s = ExactSum::default();
                s.add_f64_exact(v);
                s
            }),
        }
    }

    /// Sums read back from long accumulators (a decoded partial image).
    pub fn from_exact_sums(sums: [ExactSum; 7], samples: u32) -> PixelSums {
        PixelSums {
            exact: Some(Box::new(sums)),
            samples,
            ..PixelSums::default()
        }
    }

    /// The seven sums rounded to f64 ([`ExactSum::to_f64`] of each).
    pub fn sums_f64(&self) -> [f64; 7] {
        match &self.exact {
            Some(e) => e.map(|s| s.to_f64()),
            None => self.fast,
        }
    }

    /// Adds the sums of other samples of the same pixel.
    pub fn merge(&mut self, o: &PixelSums) {
        self.samples += o.samples;
        if self.exact.is_none() && o.exact.is_none() {
            let ulp_min = self.ulp_min.min(o.ulp_min);
            let mut abs = self.abs;
            for (a, b) in abs.iter_mut().zip(o.abs) {
                *a += b;
            }
            if f64_exact(&abs, ulp_min) {
                for (a, b) in self.fast.iter_mut().zip(o.fast) {
                    *a += b;
                }
                self.abs = abs;
                self.ulp_min = ulp_min;
                return;
            }
        }
        let other = o.exact_sums();
        for (s, x) in self.promote().iter_mut().zip(&other) {
            s.add_sum(x);
        }
    }

    /// The pixel value: `Σ w·L / Σ w` (a ratio estimator; the plain mean for the box
    /// filter, whose weights are all 1), or the plain mean `Σ L / n` should every sample
    /// have landed where the filter is zero; black for a pixel without samples. Divided
    /// in f64 and rounded once to f32.
    pub fn value(&self) -> Vec3 {
        let s = self.sums_f64();
        let w = s[WEIGHT];
        let (num, den) = if w > 0.0 {
            (&s[0..3], w)
        } else if self.samples > 0 {
            (&s[4..7], self.samples as f64)
        } else {
            return Vec3::ZERO;
        };
        Vec3::new(
            (num[0] / den) as f32,
            (num[1] / den) as f32,
            (num[2] / den) as f32,
        )
    }

    /// The value of a pixel whose only eye sample has filter weight `w` and radiance
    /// `l` (`w * l` finite): the bits [`value`](Self::value) returns after one
    /// [`add_sample`](Self::add_sample), without building the sums. One addend is exact
    /// in `f64` (24 significant bits), so the sums would be the addends themselves,
    /// with a zero (of either sign) stored as `+0`, and `value` divides them by `Σ w`
    /// (or, for `w == 0`, by the one sample). The 1-sample frame's film path
    /// (`pixel_filter::resolve_pixels`); the test below holds it to the general one.
    #[inline(always)]
    pub fn one_sample_value(w: f32, l: Vec3) -> Vec3 {
        // `+ 0.0` is what the f64 sum starting at +0 does to a -0 addend.
        if w == 1.0 {
            // The box filter: `l / 1` in f64 is `l`, exact in f32.
            return l + Vec3::ZERO;
        }
        let (num, den) = if w > 0.0 {
            ((w * l).as_dvec3() + 0.0, w as f64)
        } else {
            (l.as_dvec3() + 0.0, 1.0)
        };
        (num / den).as_vec3()
    }

    /// The value of a pixel whose eye samples all have filter weight 1 (the box
    /// filter), one radiance each (a non-finite one counts as black, as the pixel
    /// filter drops it), with the number of non-finite ones: the bits
    /// [`value`](Self::value) gives after an [`add_sample`](Self::add_sample) of each,
    /// from three `f64` sums and one exactness test for the whole pixel rather than
    /// the seven-sum bookkeeping per sample. `None` (the caller takes the general
    /// path) for no samples, or when a sum might round: the test is the module's rule
    /// with the smallest ulp of all the pixel's non-zero addends, so where it passes
    /// the sums are exact, hence what the long accumulators return, and `Σ w` is the
    /// sample count.
    ///
    /// Why: at 9 samples per pixel `add_sample` and the filter step were 11 % of the
    /// frame (`perf`, whitted_base `--spp 9 --sampler grid`, 1 thread).
    #[inline]
    pub fn box_mean_value(radiance: &[Vec3]) -> Option<(Vec3, u64)> {
        if radiance.is_empty() {
            return None;
        }
        let (sum, nonfinite) = box_sums_if_exact(radiance)?;
        let n = radiance.len() as f64;
        let value = Vec3::new(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
        );
        Some((value, nonfinite))
    }

    /// Whether the sums went over to the long accumulators (for tests and stats).
    pub fn uses_long_accumulators(&self) -> bool {
        self.exact.is_some()
    }
}

/// Equal sums: the same exact totals and sample count, on either path.
impl PartialEq for PixelSums {
    fn eq(&self, o: &PixelSums) -> bool {
        self.samples == o.samples
            && self
                .exact_sums()
                .iter()
                .zip(o.exact_sums())
                .all(|(a, b)| a.sign_magnitude() == b.sign_magnitude())
    }
}

impl Eq for PixelSums {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_is_the_weighted_mean_and_merging_is_exact() {
        let samples = [
            (1.0, Vec3::new(1e8, 0.5, 0.0)),
            (0.25, Vec3::new(1.0, 0.25, 2.0)),
            (0.5, Vec3::new(-1e8, 0.75, 4.0)),
        ];
        let mut all = PixelSums::default();
        for &(w, l) in &samples {
            all.add_sample(w, l);
        }
        // Σ w L = (1e8 + 0.25 - 5e7, 0.5 + 0.0625 + 0.375, 0 + 0.5 + 2) over Σ w = 1.75.
        let expect = Vec3::new(
            ((1e8 + 0.25 - 5e7) / 1.75) as f32,
            (0.9375 / 1.75) as f32,
            (2.5 / 1.75) as f32,
        );
        assert_eq!(all.value(), expect);
        let (mut a, mut b) = (PixelSums::default(), PixelSums::default());
        a.add_sample(samples[2].0, samples[2].1);
        b.add_sample(samples[0].0, samples[0].1);
        b.add_sample(samples[1].0, samples[1].1);
        a.merge(&b);
        assert_eq!(
            a.value().to_array().map(f32::to_bits),
            all.value().to_array().map(f32::to_bits)
        );
        assert_eq!(a.samples, 3);
    }

    /// The sums of the old representation: seven long accumulators, nothing else.
    fn reference(samples: &[(f32, Vec3)]) -> ([ExactSum; 7], Vec3) {
        let mut s = [ExactSum::default(); 7];
        for &(w, l) in samples {
            let wl = w * l;
            for (a, x) in s.iter_mut().zip([wl.x, wl.y, wl.z, w, l.x, l.y, l.z]) {
                a.add(x);
            }
        }
        let w = s[WEIGHT].to_f64();
        let value = if w > 0.0 {
            Vec3::new(
                (s[0].to_f64() / w) as f32,
                (s[1].to_f64() / w) as f32,
                (s[2].to_f64() / w) as f32,
            )
        } else if samples.is_empty() {
            Vec3::ZERO
        } else {
            let n = samples.len() as f64;
            Vec3::new(
                (s[4].to_f64() / n) as f32,
                (s[5].to_f64() / n) as f32,
                (s[6].to_f64() / n) as f32,
            )
        };
        (s, value)
    }

    #[test]
    fn the_f64_path_gives_the_bits_of_the_long_accumulators() {
        // Sample sets of 1 to 300 samples whose magnitudes span 0 to 120 binary orders
        // (so some stay on the f64 path and some fall back part-way through), weights
        // from a Gaussian-like range including 0, radiance with zeros, subnormals and
        // values near f32::MAX; every split of each set merged back.
        let mut next = crate::test_rng::xorshift64(0x2545_f491_4f6c_dd1du64);
        let (mut fast, mut fell_back) = (0, 0);
        for case in 0..400 {
            let n = 1 + (next() % 300) as usize;
            let spread = (case % 13) * 10; // binary orders of magnitude
            let value = |r: u64| -> f32 {
                match r % 23 {
                    0 => 0.0,
                    1 if spread > 100 => f32::from_bits(1 + (r >> 40) as u32 % 1000),
                    2 if spread > 100 => f32::MAX / (1.0 + (r >> 50) as f32),
                    _ => {
                        let m = ((r >> 8) & 0xffff) as f32 / 65536.0 + 0.5;
                        let e = if spread == 0 {
                            0
                        } else {
                            ((r >> 24) % spread as u64) as i32
                        };
                        m * 2f32.powi(e - spread / 2)
                    }
                }
            };
            let samples: Vec<(f32, Vec3)> = (0..n)
                .map(|_| {
                    let w = if next().is_multiple_of(7) {
                        0.0
                    } else {
                        (next() % 1000) as f32 / 999.0
                    };
                    let l = Vec3::new(value(next()), value(next()), value(next()));
                    if (w * l).is_finite() {
                        (w, l)
                    } else {
                        (1.0, l)
                    }
                })
                .collect();
            let (expect, expect_value) = reference(&samples);
            let mut all = PixelSums::default();
            for &(w, l) in &samples {
                all.add_sample(w, l);
            }
            if all.uses_long_accumulators() {
                fell_back += 1;
            } else {
                fast += 1;
            }
            let got = all.exact_sums();
            for c in 0..7 {
                assert_eq!(
                    got[c].sign_magnitude(),
                    expect[c].sign_magnitude(),
                    "case {case} sum {c}"
                );
            }
            assert_eq!(
                all.value().to_array().map(f32::to_bits),
                expect_value.to_array().map(f32::to_bits),
                "case {case}"
            );
            let split = (next() as usize) % (n + 1);
            let (mut a, mut b) = (PixelSums::default(), PixelSums::default());
            for &(w, l) in &samples[..split] {
                a.add_sample(w, l);
            }
            for &(w, l) in &samples[split..] {
                b.add_sample(w, l);
            }
            b.merge(&a);
            assert!(b == all, "case {case} split {split}");
            assert_eq!(
                b.value().to_array().map(f32::to_bits),
                expect_value.to_array().map(f32::to_bits)
            );
            let decoded = PixelSums::from_exact_sums(all.exact_sums(), all.samples);
            assert_eq!(
                decoded.value().to_array().map(f32::to_bits),
                expect_value.to_array().map(f32::to_bits)
            );
        }
        // Both paths were exercised, each many times.
        assert!(
            fast > 50 && fell_back > 50,
            "fast {fast}, fell back {fell_back}"
        );
    }

    /// The 1-sample shortcut gives the bits of the sums' own value, on weights and
    /// radiance with zeros of both signs, subnormals, values near `f32::MAX` (whose
    /// product overflows and is left out, as the filter drops it) and random ones.
    #[test]
    fn one_sample_value_equals_the_value_of_one_added_sample() {
        let mut next = crate::test_rng::xorshift64(0x9e37_79b9_7f4a_7c15u64);
        let specials = [0.0, -0.0, 1.0, f32::from_bits(1), 1e-39, 3e38, -2.5, 0.5];
        let (mut checked, mut zero_weight, mut unit_weight) = (0, 0, 0);
        for case in 0..20_000 {
            let pick = |r: u64| -> f32 {
                if r.is_multiple_of(4) {
                    specials[(r >> 8) as usize % specials.len()]
                } else {
                    let m = ((r >> 8) & 0xffff) as f32 / 65536.0 + 0.5;
                    let e = ((r >> 24) % 80) as i32 - 40;
                    let sign = if (r >> 60) & 1 == 0 { 1.0 } else { -1.0 };
                    sign * m * 2f32.powi(e)
                }
            };
            let w = if case % 5 == 0 {
                0.0
            } else if case % 5 == 1 {
                1.0
            } else {
                pick(next()).abs()
            };
            let l = Vec3::new(pick(next()), pick(next()), pick(next()));
            if !(w * l).is_finite() {
                continue;
            }
            let mut sums = PixelSums::default();
            sums.add_sample(w, l);
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            assert_eq!(
                bits(PixelSums::one_sample_value(w, l)),
                bits(sums.value()),
                "w {w:e}, l {l:?}"
            );
            checked += 1;
            zero_weight += (w == 0.0) as u32;
            unit_weight += (w == 1.0) as u32;
        }
        assert!(
            checked > 15_000 && zero_weight > 3_000 && unit_weight > 3_000,
            "{checked} {zero_weight} {unit_weight}"
        );
    }

    /// The box shortcut gives the bits of the general sums' value (black for a
    /// non-finite sample, which still counts) and the same non-finite count, on 1 to
    /// 40 samples with zeros of both signs, subnormals, NaN, infinities and spreads
    /// from 1 to 50 binary orders; it declines (`None`) only where a sum could round,
    /// and both outcomes occur.
    #[test]
    fn box_mean_value_equals_the_value_of_the_added_samples() {
        let mut next = crate::test_rng::xorshift64(0x5851_f42d_4c95_7f2du64);
        let specials = [0.0, -0.0, f32::NAN, f32::INFINITY, f32::from_bits(3), 1e-39];
        let (mut taken, mut declined) = (0, 0);
        for case in 0..5000 {
            let n = 1 + (next() % 40) as usize;
            let span = 1 + (case % 50) as u64;
            let pick = |r: u64| -> f32 {
                if r.is_multiple_of(31) {
                    specials[(r >> 8) as usize % specials.len()]
                } else {
                    let e = 127 - 40 + ((r >> 40) % span) as u32;
                    f32::from_bits(((r >> 63) as u32) << 31 | e << 23 | (r as u32 & 0x7f_ffff))
                }
            };
            let radiance: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(pick(next()), pick(next()), pick(next())))
                .collect();
            let mut sums = PixelSums::default();
            let mut want_nonfinite = 0;
            for &r in &radiance {
                let r = if r.is_finite() {
                    r
                } else {
                    want_nonfinite += 1;
                    Vec3::ZERO
                };
                sums.add_sample(1.0, r);
            }
            match PixelSums::box_mean_value(&radiance) {
                Some((v, nonfinite)) => {
                    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                    assert_eq!(bits(v), bits(sums.value()), "case {case}: {radiance:?}");
                    assert_eq!(nonfinite, want_nonfinite, "case {case}");
                    taken += 1;
                }
                None => {
                    // Declined only where the long accumulators were needed.
                    assert!(sums.uses_long_accumulators(), "case {case}: {radiance:?}");
                    declined += 1;
                }
            }
        }
        assert!(PixelSums::box_mean_value(&[]).is_none());
        assert!(taken > 1000 && declined > 1000, "{taken} {declined}");
    }

    #[test]
    fn zero_weights_fall_back_to_the_plain_mean() {
        let mut p = PixelSums::default();
        assert_eq!(p.value(), Vec3::ZERO);
        p.add_sample(0.0, Vec3::new(1.0, 2.0, 3.0));
        p.add_sample(0.0, Vec3::new(3.0, 2.0, 1.0));
        assert_eq!(p.value(), Vec3::splat(2.0));
    }
}
