//! sRGB encoding and luminance of linear RGB.

use glam::Vec3;

/// Relative luminance of linear Rec. 709 / sRGB primaries (ITU-R BT.709 weights).
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// sRGB OETF (IEC 61966-2-1): linear segment below 0.0031308, power 1/2.4 above.
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`linear_to_srgb`].
pub fn srgb_to_linear(s: f32) -> f32 {
    if s <= 0.040_45 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// One channel to an 8-bit sRGB code: clamp, encode, round. NaN becomes 0 rather
/// than whatever a float-to-int cast would make of it.
pub fn linear_to_srgb8(c: f32) -> u8 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    (linear_to_srgb(c) * 255.0).round() as u8
}

/// [`linear_to_srgb8`] by its code thresholds: `lower[k]` is the least `f32` in
/// `[0, 1]` that [`linear_to_srgb8`] turns into code `k` or more, found once by a
/// binary search over the bit patterns (8,000 `powf` calls), and a code is then the
/// number of thresholds at or below the value (eight comparisons, no `powf`).
///
/// The same codes as [`linear_to_srgb8`] for every `f32`, because that function is
/// non-decreasing on `[0, 1]` (the OETF is increasing, and libm's `powf` is within an
/// ulp and monotone there); the test compares the two on every 61st `f32` of `[0, 1]`,
/// on 300 ulps either side of every threshold and on the special values.
///
/// Why: writing the bunny's 1024x1024 PNG took 86-88 ms, as long as rendering it, and
/// the per-channel `powf` (and `exp2f` of the exposure) of `Film::to_display8` was 17 %
/// of the process (perf, whitted_base, 1 thread).
#[derive(Clone, Debug)]
pub struct Srgb8Table {
    lower: [f32; 256],
}

impl Default for Srgb8Table {
    fn default() -> Self {
        Self::new()
    }
}

impl Srgb8Table {
    pub fn new() -> Self {
        let one = 1.0f32.to_bits();
        let mut lower = [0.0f32; 256];
        for (k, t) in lower.iter_mut().enumerate().skip(1) {
            // The least bit pattern in [0, 1] with a code of k or more (1.0 gives 255).
            let (mut lo, mut hi) = (0u32, one);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if linear_to_srgb8(f32::from_bits(mid)) as usize >= k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *t = f32::from_bits(lo);
        }
        Srgb8Table { lower }
    }

    /// [`linear_to_srgb8`]`(c)`.
    #[inline]
    pub fn encode(&self, c: f32) -> u8 {
        let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
        let mut k = 0;
        for step in [128, 64, 32, 16, 8, 4, 2, 1] {
            if c >= self.lower[k + step] {
                k += step;
            }
        }
        k as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threshold_encoding_is_linear_to_srgb8() {
        let table = Srgb8Table::new();
        let check = |c: f32| {
            assert_eq!(
                table.encode(c),
                linear_to_srgb8(c),
                "{c:e} (bits {:#x})",
                c.to_bits()
            )
        };
        let one = 1.0f32.to_bits();
        let mut compared = 0u64;
        for bits in (0..=one).step_by(61) {
            check(f32::from_bits(bits));
            compared += 1;
        }
        for &t in &table.lower[1..] {
            let b = t.to_bits();
            for bits in b.saturating_sub(300)..=(b + 300).min(one) {
                check(f32::from_bits(bits));
                compared += 1;
            }
        }
        for c in [
            -0.0,
            -1e-30,
            -3.0,
            1.0 + f32::EPSILON,
            7.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
        ] {
            check(c);
        }
        // Every code is reached, in order.
        assert!(table.lower.windows(2).all(|w| w[0] < w[1]));
        assert!(compared > 17_000_000, "{compared}");
    }

    #[test]
    fn srgb_endpoints_and_round_trip() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(-3.0), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        // 18% grey is code 118 in sRGB, not the 0.18 * 255 = 46 of a linear encoding.
        assert_eq!(linear_to_srgb8(0.18), 118);
        for code in 0..=255u8 {
            let lin = srgb_to_linear(code as f32 / 255.0);
            assert_eq!(
                linear_to_srgb8(lin),
                code,
                "code {code} does not round-trip"
            );
        }
        // The two branches meet: the OETF is continuous at the threshold.
        let t = 0.003_130_8f32;
        assert!((12.92 * t - (1.055 * t.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
    }
}
