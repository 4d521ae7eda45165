//! An exact, order-independent sum of `f32` values: a fixed-point accumulator wide
//! enough for every finite `f32` (Kulisch's long accumulator, "Computer Arithmetic and
//! Validity", 2nd ed. 2013, ch. 6; the same idea as Neal's superaccumulators,
//! arXiv:1505.05571).
//!
//! Why: a pixel's value is a weighted mean of its samples. Summed in `f32` (or `f64`)
//! the result depends on the grouping of the additions, so a frame rendered in sample
//! rounds (`--sample-range`) and merged would differ in the last bits from a frame
//! rendered in one go. Summed exactly, the total is a property of the multiset of
//! addends alone: any split into rounds, in any order, gives the same bits, and the one
//! rounding happens in [`ExactSum::to_f64`], a fixed function of the exact total.
//!
//! Every finite `f32` is `sig * 2^(pos - 149)` with `sig < 2^24` and `0 <= pos <= 253`,
//! so its bits lie in positions `0..277` of a fixed-point number with 149 fraction bits.
//! Sums of up to `2^31` addends need 31 more bits, and a sign one more: 309 bits, held
//! in [`LIMBS`] limbs of 32 bits. Limbs are `i64` so that up to `2^31` additions can be
//! made before carries are propagated ([`ExactSum::normalize`]); the normalized form
//! is unique, so equal sums have equal limbs.

/// Limbs of 32 bits: 320 bits, enough for 2^31 addends of any finite f32 (see above).
pub const LIMBS: usize = 10;
/// The weight of bit 0: 2^-149, the smallest positive (subnormal) f32.
const BIT0_EXP: i32 = -149;
/// Additions allowed between normalizations: each adds less than 2^32 to a limb and
/// a limb holds magnitudes below 2^63.
const MAX_PENDING: u32 = 1 << 30;

/// An exact sum of finite `f32` values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExactSum {
    limbs: [i64; LIMBS],
    /// Additions since the last normalization.
    pending: u32,
}

impl ExactSum {
    /// Adds `x` exactly. `x` must be finite (the caller drops NaN and infinities, as
    /// the pixel filter counts them); a non-finite `x` panics in debug builds and is
    /// ignored in release builds. Every finite `f32` is an `f64` that is a multiple of
    /// 2^-149 below 2^128, so this is [`add_f64_exact`](Self::add_f64_exact).
    #[inline]
    pub fn add(&mut self, x: f32) {
        debug_assert!(x.is_finite(), "ExactSum::add({x})");
        self.add_f64_exact(x as f64);
    }

    /// Adds `v` exactly, where `v` is a multiple of 2^-149 with `|v| < 2^160`: every
    /// `f64` that holds a sum of `f32` values computed without rounding is one
    /// (`film::pixel_sums` hands its exact `f64` partial sums over this way when it
    /// falls back to the long accumulator). Its 53 significant bits land in at most
    /// three consecutive limbs.
    pub fn add_f64_exact(&mut self, v: f64) {
        debug_assert!(
            v.is_finite() && v.abs() < 2f64.powi(160),
            "add_f64_exact({v})"
        );
        if !v.is_finite() || v == 0.0 {
            return;
        }
        if self.pending >= MAX_PENDING {
            self.normalize();
        }
        self.pending += 1;
        let bits = v.to_bits();
        let biased = ((bits >> 52) & 0x7ff) as i32;
        let mantissa = bits & ((1u64 << 52) - 1);
        // |v| >= 2^-149 is far above f64's subnormal range: `biased` is never 0 here.
        let mut sig = mantissa | 1 << 52;
        // v = sig * 2^(biased - 1075); bit 0 of the accumulator is worth 2^-149.
        let mut pos = biased - 1075 - BIT0_EXP;
        let tz = sig.trailing_zeros() as i32;
        sig >>= tz;
        pos += tz;
        debug_assert!(pos >= 0, "add_f64_exact({v}): not a multiple of 2^-149");
        if pos < 0 {
            return;
        }
        let (limb, shift) = ((pos / 32) as usize, pos % 32);
        let wide = (sig as u128) << shift; // < 2^85: three limbs
        let sign = if bits >> 63 == 0 { 1 } else { -1 };
        for k in 0..3 {
            let part = ((wide >> (32 * k)) & 0xffff_ffff) as i64;
            if part != 0 {
                debug_assert!(limb + k < LIMBS, "add_f64_exact({v}): out of range");
                if let Some(l) = self.limbs.get_mut(limb + k) {
                    *l += sign * part;
                }
            }
        }
    }

    /// Adds another exact sum (exactly).
    pub fn add_sum(&mut self, other: &ExactSum) {
        self.normalize();
        let mut o = *other;
        o.normalize();
        for (a, b) in self.limbs.iter_mut().zip(o.limbs) {
            *a += b;
        }
        self.pending = 2;
        self.normalize();
    }

    /// Propagates carries: limbs `0..LIMBS-1` end in `[0, 2^32)`, the top limb carries
    /// the sign. This form is unique for each value.
    pub fn normalize(&mut self) {
        if self.pending == 0 {
            return;
        }
        for i in 0..LIMBS - 1 {
            let carry = self.limbs[i] >> 32; // arithmetic: floor division by 2^32
            self.limbs[i] -= carry << 32;
            self.limbs[i + 1] += carry;
        }
        self.pending = 0;
    }

    /// Whether the sum is exactly zero.
    pub fn is_zero(&self) -> bool {
        self.limbs.iter().all(|&l| l == 0) || {
            let mut n = *self;
            n.normalize();
            n.limbs.iter().all(|&l| l == 0)
        }
    }

    /// The sum rounded to `f64`: Horner's rule over the normalized limbs from the top,
    /// then an exact scaling by 2^-149. Not necessarily the correctly rounded value (it
    /// is within a few ulps of f64, far below f32 resolution), but a fixed function of
    /// the exact value, which is what makes sums split in any way agree bit for bit.
    pub fn to_f64(&self) -> f64 {
        let mut n = *self;
        n.normalize();
        let mut acc = 0.0f64;
        for &l in n.limbs.iter().rev() {
            acc = acc * 4_294_967_296.0 + l as f64;
        }
        acc * 2f64.powi(BIT0_EXP)
    }

    /// Sign and magnitude, the magnitude in 32-bit limbs, least significant first,
    /// bit 0 worth 2^-149 (for serialisation). Zero is `(false, [0; LIMBS])`.
    pub fn sign_magnitude(&self) -> (bool, [u32; LIMBS]) {
        let mut n = *self;
        n.normalize();
        let negative = n.limbs[LIMBS - 1] < 0;
        if negative {
            for l in &mut n.limbs {
                *l = -*l;
            }
            n.pending = 1;
            n.normalize();
        }
        // Normalized and non-negative: every limb in [0, 2^32), the top one included
        // (the value is below 2^309).
        (negative, n.limbs.map(|l| l as u32))
    }

    /// The inverse of [`sign_magnitude`](Self::sign_magnitude). `None` for a magnitude
    /// no sum of 2^31 finite f32 can reach (top limb at or above 2^31), or a negative
    /// zero: neither is ever written, so either means a corrupt input.
    pub fn from_sign_magnitude(negative: bool, magnitude: [u32; LIMBS]) -> Option<ExactSum> {
        if magnitude[LIMBS - 1] >= 1 << 31 || (negative && magnitude.iter().all(|&l| l == 0)) {
            return None;
        }
        let sign = if negative { -1 } else { 1 };
        let mut s = ExactSum {
            limbs: magnitude.map(|l| sign * l as i64),
            pending: 1,
        };
        s.normalize();
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sum(xs: &[f32]) -> ExactSum {
        let mut s = ExactSum::default();
        for &x in xs {
            s.add(x);
        }
        s
    }

    #[test]
    fn exact_where_floats_are_not() {
        // 1e8 + 1 - 1e8 is 0 in f32 (1 is below half an ulp of 1e8) but 1 exactly.
        let xs = [1e8f32, 1.0, -1e8];
        assert_eq!(xs.iter().sum::<f32>(), 0.0);
        assert_eq!(sum(&xs).to_f64(), 1.0);
        // The extremes: the largest finite and the smallest subnormal f32, together.
        let s = sum(&[f32::MAX, f32::from_bits(1), f32::MAX, -f32::MAX, -f32::MAX]);
        assert_eq!(s.to_f64(), 2f64.powi(-149));
        assert_eq!(sum(&[f32::from_bits(1); 3]).to_f64(), 3.0 * 2f64.powi(-149));
        assert_eq!(sum(&[-2.5, 0.5]).to_f64(), -2.0);
        assert!(sum(&[3.0, -3.0]).is_zero());
        assert!(!sum(&[3.0]).is_zero());
    }

    #[test]
    fn any_split_and_order_gives_the_same_bits() {
        // Values spread over 60 binary orders of magnitude, both signs: f32 sums of the
        // same values in different groupings differ, the exact sums must not.
        let mut next = crate::test_rng::xorshift64(0x9e37_79b9_7f4a_7c15u64);
        let xs: Vec<f32> = (0..1000)
            .map(|_| {
                let r = next();
                let m = (r & 0xffff) as f32 / 65536.0 + 0.5;
                let e = ((r >> 16) % 60) as i32 - 30;
                let sign = if r >> 63 == 0 { 1.0 } else { -1.0 };
                sign * m * 2f32.powi(e)
            })
            .collect();
        let whole = sum(&xs);
        let forward: f32 = xs.iter().sum();
        let backward: f32 = xs.iter().rev().sum();
        assert_ne!(
            forward, backward,
            "the test data must defeat float summation"
        );
        let mut reversed: Vec<f32> = xs.clone();
        reversed.reverse();
        assert_eq!(sum(&reversed).sign_magnitude(), whole.sign_magnitude());
        for split in [1, 7, 500, 999] {
            let mut a = sum(&xs[split..]);
            a.add_sum(&sum(&xs[..split]));
            assert_eq!(a.sign_magnitude(), whole.sign_magnitude(), "split {split}");
            assert_eq!(a.to_f64().to_bits(), whole.to_f64().to_bits());
        }
        // And the value is right: within f64 rounding of an f64 sum whose own error is
        // bounded by n * eps64 * sum |x| (Higham, Accuracy and Stability, eq. 4.4).
        let f64_sum: f64 = xs.iter().map(|&x| x as f64).sum();
        let bound = 1000.0 * f64::EPSILON * xs.iter().map(|&x| x.abs() as f64).sum::<f64>();
        assert!((whole.to_f64() - f64_sum).abs() <= bound);
    }

    #[test]
    fn f64_partials_land_where_their_f32_addends_do() {
        // An f64 sum of f32 values that was computed exactly, handed over in one piece,
        // gives the same limbs as the values added one by one: near the bottom of the
        // range (subnormals), in the middle, and at the top (sums beyond f32::MAX).
        for xs in [
            &[
                f32::from_bits(1),
                f32::from_bits(3),
                f32::from_bits(0x80_0000),
            ][..],
            &[1.5, 0.25, -3.0, 1024.0, 1e-3],
            &[f32::MAX, f32::MAX, f32::MAX],
            &[-f32::MAX, -1e30],
            &[0.0, -0.0],
        ] {
            let exact = sum(xs);
            let f64_sum: f64 = xs.iter().map(|&x| x as f64).sum();
            assert_eq!(f64_sum, exact.to_f64(), "{xs:?}: the f64 sum must be exact");
            let mut s = ExactSum::default();
            s.add_f64_exact(f64_sum);
            assert_eq!(s.sign_magnitude(), exact.sign_magnitude(), "{xs:?}");
            // And mixed with single adds.
            let mut m = sum(&[7.0, -2e-40]);
            m.add_f64_exact(f64_sum);
            let mut all = xs.to_vec();
            all.extend([7.0, -2e-40]);
            assert_eq!(m.sign_magnitude(), sum(&all).sign_magnitude(), "{xs:?}");
        }
    }

    #[test]
    fn sign_magnitude_round_trips_and_rejects_the_impossible() {
        for xs in [
            &[1.5f32, -1e-30, 3e20][..],
            &[-1.5, 1e-30, -3e20],
            &[],
            &[2.0, -2.0],
        ] {
            let s = sum(xs);
            let (neg, mag) = s.sign_magnitude();
            let back = ExactSum::from_sign_magnitude(neg, mag).unwrap();
            assert_eq!(back.sign_magnitude(), (neg, mag));
            assert_eq!(back.to_f64().to_bits(), s.to_f64().to_bits(), "{xs:?}");
        }
        assert!(sum(&[-1.0]).sign_magnitude().0);
        let mut top = [0u32; LIMBS];
        top[LIMBS - 1] = 1 << 31;
        assert!(ExactSum::from_sign_magnitude(false, top).is_none());
        assert!(ExactSum::from_sign_magnitude(true, [0; LIMBS]).is_none());
    }
}
