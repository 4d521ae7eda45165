//! The binned-SAH builder's bin box as one 8-lane vector: the minimum corner in lanes
//! 0-3 and the *negated* maximum corner in lanes 4-7, so that growing a box by another
//! is a single lane minimum (`-max(a, b) = min(-a, -b)` exactly, negation being exact).
//! Embree's binner keeps its bins in this form for the same reason (one `min` per bin
//! update on AVX); see Wald 2007, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", for the binning itself.
//!
//! With AVX a grow is one 256-bit load-min-store; without it, two 128-bit minimums on
//! the same lanes (the same values: the lanes are independent).

use glam::{Vec3A, Vec4};

#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
use std::arch::x86_64::{
    __m256, _CMP_LT_OQ, _mm256_blendv_ps, _mm256_cmp_ps, _mm256_load_ps, _mm256_min_ps,
    _mm256_set_m128, _mm256_set1_ps, _mm256_setr_ps, _mm256_store_ps, _mm256_xor_ps,
};

/// A box as `[min.x, min.y, min.z, w, -max.x, -max.y, -max.z, w']` (the `w` lanes are
/// carried along and never read).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct BinBox {
    lo: Vec4,
    neg_hi: Vec4,
}

const _: () = assert!(std::mem::size_of::<BinBox>() == 32);
const _: () = assert!(std::mem::align_of::<BinBox>() == 32);
const _: () = assert!(std::mem::offset_of!(BinBox, neg_hi) == 16);

impl BinBox {
    /// The empty box: growing it by `b` gives `b`.
    pub const EMPTY: BinBox = BinBox {
        lo: Vec4::splat(f32::INFINITY),
        neg_hi: Vec4::splat(f32::INFINITY),
    };

    /// The box `[min, max]` (lanes `w` of both are kept as they are).
    #[inline(always)]
    pub fn new(min: Vec4, max: Vec4) -> BinBox {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        {
            // SAFETY: AVX is enabled at compile time (the cfg above).
            unsafe {
                let v = _mm256_set_m128(max.into(), min.into());
                BinBox::from_m256(_mm256_xor_ps(v, sign_hi()))
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        {
            BinBox {
                lo: min,
                neg_hi: -max,
            }
        }
    }

    /// Grows this box by `o`: each lane `min(self, o)` with x86 `minps` operand order
    /// (`o` where either is NaN), so the corners are `min(min, o.min)` and
    /// `max(max, o.max)` as `maxps(max, o.max)` gives them, bit for bit.
    #[inline(always)]
    pub fn grow(&mut self, o: &BinBox) {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        // SAFETY: AVX is enabled at compile time; both boxes are 32-byte aligned
        // (`repr(align(32))`), as the aligned load and store need.
        unsafe {
            let p = (self as *mut BinBox).cast::<f32>();
            let v = _mm256_min_ps(
                _mm256_load_ps(p),
                _mm256_load_ps((o as *const BinBox).cast::<f32>()),
            );
            _mm256_store_ps(p, v);
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        {
            self.lo = self.lo.min(o.lo);
            self.neg_hi = self.neg_hi.min(o.neg_hi);
        }
    }

    /// Grows `left` by `o` where `k < bin` (an ordered compare: false for a NaN), else
    /// `right`: each side grows as [`BinBox::grow`] by `o` or by the empty box, picked
    /// through a lane mask (no branch: the side is a coin flip to the branch
    /// predictor). Growing by the empty box is `min(self, +inf)` lane by lane, which is
    /// what the builder's plain boxes computed for the side a point did not go to.
    ///
    /// For the partition's centroid bounds (`BinBox::new(c, c)` per centroid): two
    /// blends and two 8-lane minimums where four 4-lane selects and four minimums or
    /// maximums took the same values.
    #[inline(always)]
    pub fn grow_either(left: &mut BinBox, right: &mut BinBox, o: BinBox, k: f32, bin: f32) {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        // SAFETY: AVX is enabled at compile time; register operations only.
        unsafe {
            let m = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_set1_ps(k), _mm256_set1_ps(bin));
            let (e, o) = (_mm256_set1_ps(f32::INFINITY), o.to_m256());
            *left = BinBox::from_m256(_mm256_min_ps(left.to_m256(), _mm256_blendv_ps(e, o, m)));
            *right = BinBox::from_m256(_mm256_min_ps(right.to_m256(), _mm256_blendv_ps(o, e, m)));
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        {
            let (l, r) = if k < bin {
                (o, BinBox::EMPTY)
            } else {
                (BinBox::EMPTY, o)
            };
            left.grow(&l);
            right.grow(&r);
        }
    }

    /// The minimum corner.
    #[inline(always)]
    pub fn min(&self) -> Vec3A {
        Vec3A::from_vec4(self.lo)
    }

    /// The maximum corner.
    #[inline(always)]
    pub fn max(&self) -> Vec3A {
        -Vec3A::from_vec4(self.neg_hi)
    }

    /// The extent `max - min`, clamped below at zero, as `(max - min).max(0)` computes
    /// it for [`Vec3A`]s (the same operations: `max` is the exact negation of the
    /// stored lanes); lane 3 holds no meaning.
    #[inline(always)]
    pub fn extent(&self) -> Vec4 {
        (-self.neg_hi - self.lo).max(Vec4::ZERO)
    }

    /// [`BinBox::extent`] negated, bit for bit in every lane (signed zeros
    /// included): `min(neg_hi + lo, -0.0)`. `-neg_hi - lo` is `-(neg_hi + lo)` unless
    /// the sum is zero (round to nearest is symmetric), `-max(-s, +0)` is `min(s, -0)`
    /// for every `s` (NaN gives `-0`, as the maximum gives `+0`), and a zero of either
    /// sign clamps to `-0` here as to `+0` there. Two operations where the extent
    /// takes three (a negation, a subtraction, a maximum); a product of two negated
    /// extents is the product of the extents, so the box areas come out the same.
    #[inline(always)]
    pub fn neg_extent(&self) -> Vec4 {
        (self.neg_hi + self.lo).min(Vec4::splat(-0.0))
    }

    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    #[inline(always)]
    fn to_m256(self) -> __m256 {
        // SAFETY: `BinBox` is 32 bytes of f32 lanes, as `__m256` is.
        unsafe { std::mem::transmute::<BinBox, __m256>(self) }
    }

    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    #[inline(always)]
    fn from_m256(v: __m256) -> BinBox {
        // SAFETY: `BinBox` is 32 bytes of f32 lanes, as `__m256` is.
        unsafe { std::mem::transmute::<__m256, BinBox>(v) }
    }
}

/// Sign bits of lanes 4-7.
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
#[inline(always)]
fn sign_hi() -> __m256 {
    // SAFETY: AVX is enabled at compile time.
    unsafe { _mm256_setr_ps(0.0, 0.0, 0.0, 0.0, -0.0, -0.0, -0.0, -0.0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(v: Vec3A) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Grown box by box, the corners are exactly what `Vec3A::min`/`max` fold to (the
    /// builder's plain boxes), signed zeros included.
    #[test]
    fn grow_matches_min_and_max_of_the_corners() {
        let mut x = 0x9e37_79b9_u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            ((x % 2001) as f32 - 1000.0) * 0.25
        };
        let mut b = BinBox::EMPTY;
        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        for i in 0..500 {
            let a = Vec3A::new(next(), next(), next());
            let c = if i % 7 == 0 {
                Vec3A::new(0.0, -0.0, 0.0)
            } else {
                a + Vec3A::new(next().abs(), next().abs(), next().abs())
            };
            let (mn, mx) = (a.min(c), a.max(c));
            b.grow(&BinBox::new(mn.extend(7.0), mx.extend(-3.0)));
            lo = lo.min(mn);
            hi = hi.max(mx);
            assert_eq!(bits(b.min()), bits(lo), "step {i}");
            assert_eq!(bits(b.max()), bits(hi), "step {i}");
            let e = Vec3A::from_vec4(b.extent());
            assert_eq!(bits(e), bits((hi - lo).max(Vec3A::ZERO)), "step {i}");
            assert_eq!(bits(-Vec3A::from_vec4(b.neg_extent())), bits(e), "step {i}");
        }
        let e = BinBox::EMPTY;
        assert_eq!(
            e.neg_extent().to_array().map(f32::to_bits),
            [(-0.0f32).to_bits(); 4]
        );
        assert_eq!(e.min(), Vec3A::splat(f32::INFINITY));
        assert_eq!(e.max(), Vec3A::splat(f32::NEG_INFINITY));
        assert_eq!(
            Vec3A::from_vec4(e.extent()),
            Vec3A::ZERO,
            "empty: zero extent"
        );
    }

    /// Every lane of the negated extent is the extent's with the sign bit flipped, for
    /// corners of either sign of zero, equal corners, NaNs, infinities and empty boxes.
    #[test]
    fn neg_extent_is_the_negated_extent() {
        let vals = [
            0.0f32,
            -0.0,
            1.5,
            -1.5,
            3.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1e-40,
        ];
        for &a in &vals {
            for &b in &vals {
                let bx = BinBox::new(Vec4::splat(a), Vec4::splat(b));
                let e = bx.extent().to_array();
                let n = bx.neg_extent().to_array();
                for k in 0..4 {
                    assert_eq!(
                        n[k].to_bits(),
                        (-e[k]).to_bits(),
                        "min {a} max {b} lane {k}"
                    );
                }
            }
        }
    }

    /// `grow_either` grows exactly one side by a point, bit for bit as the plain
    /// boxes' select-then-min/max did: `min(lo, k < bin ? c : inf)` and `max(hi, k < bin
    /// ? c : -inf)` on the left, the other way round on the right, with NaN lanes in
    /// the points and in the compared value (a NaN `k` goes right).
    #[test]
    fn grow_either_matches_selected_min_and_max() {
        let mut draw = crate::test_rng::xorshift64(0x2545_f491_4f6c_dd1d);
        let mut next = || {
            let x = (draw() >> 32) as u32;
            match x % 13 {
                0 => f32::NAN,
                1 => 0.0,
                2 => -0.0,
                _ => ((x >> 8) % 2001) as f32 * 0.25 - 250.0,
            }
        };
        let (mut l, mut r) = (BinBox::EMPTY, BinBox::EMPTY);
        let inf = Vec3A::splat(f32::INFINITY);
        let (mut lmin, mut lmax, mut rmin, mut rmax) = (inf, -inf, inf, -inf);
        let mut lefts = 0;
        for i in 0..2000 {
            let c = Vec3A::new(next(), next(), next());
            let k = next();
            let bin = 7.0;
            BinBox::grow_either(
                &mut l,
                &mut r,
                BinBox::new(c.extend(0.0), c.extend(0.0)),
                k,
                bin,
            );
            let left = Vec3A::splat(k).cmplt(Vec3A::splat(bin));
            lefts += usize::from(left.all());
            lmin = lmin.min(Vec3A::select(left, c, inf));
            lmax = lmax.max(Vec3A::select(left, c, -inf));
            rmin = rmin.min(Vec3A::select(left, inf, c));
            rmax = rmax.max(Vec3A::select(left, -inf, c));
            assert_eq!(bits(l.min()), bits(lmin), "step {i}");
            assert_eq!(bits(l.max()), bits(lmax), "step {i}");
            assert_eq!(bits(r.min()), bits(rmin), "step {i}");
            assert_eq!(bits(r.max()), bits(rmax), "step {i}");
        }
        assert!(
            lefts > 500 && lefts < 1500,
            "both sides grown: {lefts} of 2000 left"
        );
    }
}
