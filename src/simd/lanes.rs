//! The lane types and the [`Lanes`] trait every kernel is written against, the packet
//! width, and the instruction set this build compiles to.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};
use wide::{f32x4, f32x8, f32x16, i32x4, i32x8, i32x16};

/// A vector of `f32` lanes with the operations the kernels need.
///
/// [`minps`](Lanes::minps)/[`maxps`](Lanes::maxps) have the x86 semantics (`wide`'s
/// `fast_min`/`fast_max`): if either operand is NaN the result is `other`. The slab
/// tests rely on it: they fold a possibly-NaN plane distance into a never-NaN
/// accumulator as `x.maxps(acc)`, so a NaN (ray lying in the slab's plane) is ignored.
/// The names differ from `min`/`max` on purpose: `wide`'s inherent `min`/`max` (which
/// check for NaN, at twice the cost) would otherwise win method resolution on concrete
/// lane types.
pub trait Lanes:
    Copy
    + Send
    + Sync
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
{
    const WIDTH: usize;
    type Array: AsRef<[f32]> + AsMut<[f32]> + Copy;

    fn splat(x: f32) -> Self;
    fn from_array(a: Self::Array) -> Self;
    fn to_array(self) -> Self::Array;
    /// Lanes `0..WIDTH` of `s` (which must be at least that long).
    fn load(s: &[f32]) -> Self;
    /// Lane minimum with x86 `minps` semantics: `other` if either operand is NaN.
    fn minps(self, other: Self) -> Self;
    /// Lane maximum with x86 `maxps` semantics: `other` if either operand is NaN.
    fn maxps(self, other: Self) -> Self;
    fn lt(self, other: Self) -> Self;
    fn le(self, other: Self) -> Self;
    fn gt(self, other: Self) -> Self;
    fn eq(self, other: Self) -> Self;
    /// `mask ? a : b` per lane.
    fn select(mask: Self, a: Self, b: Self) -> Self;
    /// Bit `i` set where lane `i` is a mask lane (all ones).
    fn bitmask(self) -> u32;
    /// Bit `i` set where lane `i` has its sign bit set (so `-0.0` counts as negative).
    fn sign_bits(self) -> u32;
    fn is_finite(self) -> Self;
    /// Absolute value (clears the sign bit, as `f32::abs`).
    fn abs(self) -> Self;
    /// IEEE square root (correctly rounded, as `f32::sqrt`).
    fn sqrt(self) -> Self;
    /// A mask with lanes `i` set where bit `i` of `bits` is set.
    fn mask_from_bits(bits: u32) -> Self;
}

macro_rules! impl_lanes {
    ($t:ty, $i:ty, $n:expr) => {
        impl Lanes for $t {
            const WIDTH: usize = $n;
            type Array = [f32; $n];

            #[inline(always)]
            fn splat(x: f32) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn from_array(a: [f32; $n]) -> Self {
                <$t>::new(a)
            }
            #[inline(always)]
            fn to_array(self) -> [f32; $n] {
                <$t>::to_array(self)
            }
            #[inline(always)]
            fn load(s: &[f32]) -> Self {
                let a: [f32; $n] = s[..$n].try_into().expect("slice of at least WIDTH lanes");
                <$t>::new(a)
            }
            #[inline(always)]
            fn minps(self, other: Self) -> Self {
                self.fast_min(other)
            }
            #[inline(always)]
            fn maxps(self, other: Self) -> Self {
                self.fast_max(other)
            }
            #[inline(always)]
            fn lt(self, other: Self) -> Self {
                self.simd_lt(other)
            }
            #[inline(always)]
            fn le(self, other: Self) -> Self {
                self.simd_le(other)
            }
            #[inline(always)]
            fn gt(self, other: Self) -> Self {
                self.simd_gt(other)
            }
            #[inline(always)]
            fn eq(self, other: Self) -> Self {
                self.simd_eq(other)
            }
            #[inline(always)]
            fn select(mask: Self, a: Self, b: Self) -> Self {
                mask.select(a, b)
            }
            #[inline(always)]
            fn bitmask(self) -> u32 {
                self.to_bitmask()
            }
            #[inline(always)]
            fn sign_bits(self) -> u32 {
                // movmskps reads exactly the sign bits
                self.to_bitmask()
            }
            #[inline(always)]
            fn is_finite(self) -> Self {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            /// In lanes: `bits & (1 << i)` compared with `1 << i` (three instructions
            /// per register where a loop over the lanes stored each one). Callgrind,
            /// whitted_base 1024x768, 1 thread, images byte-identical:
            /// `TinyGroup::closest` 139.1 M -> 138.0 M instructions, the render
            /// phase 1020.3 M -> 1017.8 M.
            #[inline(always)]
            fn mask_from_bits(bits: u32) -> Self {
                const LANE_BIT: [i32; $n] = {
                    let mut a = [0i32; $n];
                    let mut i = 0;
                    while i < $n {
                        a[i] = 1 << i;
                        i += 1;
                    }
                    a
                };
                let lane_bit = <$i>::new(LANE_BIT);
                let set = (<$i>::splat(bits as i32) & lane_bit).simd_eq(lane_bit);
                wide::bytemuck::cast(set)
            }
        }
    };
}

// Tried and not kept (helper blur26, 2026-11-29): `load` and `splat` of `f32x16` as one
// `_mm512_loadu_ps` / `_mm512_set1_ps` (transmuted to `f32x16`), and `V3::load` /
// `V3::splat` through them. `wide`'s `new` and `splat` go through a `[f32; 16]`, and
// where the lanes went on into a struct kept on the stack (`SurfaceLanes` in
// `shade_group_lanes`) LLVM stored the array in 32-byte halves (its `memcpy` lowering
// under `prefer-256-bit`), so the field's later 64-byte loads could not be forwarded
// (perf annotate, whitted_blur16, 1 thread, AVX-512: 6.4 % of `shade_group_lanes` on the
// `SurfaceLanes` copy, then 3.3 % on a multiply reading `albedo.y`, a `V3::splat`). With
// both, every store there was whole, images byte-identical and the lib tests passed, but
// no time moved beyond the host's noise: whitted_blur16 512x384, 1 thread, 25
// interleaved rounds, load ~3, render min/median 236.0/250.2 -> 235.8/249.0 ms; aa3x3
// (whitted_base --spp 9 --sampler grid) 512x384, 25 rounds, 128.5/139.7 -> 126.8/139.8 ms;
// full frame blur16, 9 rounds, 993.0/1012.7 -> 991.6/1030.6 ms. (Out-of-order execution
// hides the failed forwards; the README's `-prefer-256-bit` build, which made such copies
// whole everywhere, was level too.)
impl_lanes!(f32x4, i32x4, 4);
impl_lanes!(f32x8, i32x8, 8);
impl_lanes!(f32x16, i32x16, 16);

/// Four lanes: one BVH4 node's children, one leaf group's triangles.
pub type F4 = f32x4;
/// Eight lanes.
pub type F8 = f32x8;
/// Sixteen lanes.
pub type F16 = f32x16;

/// Rays per coherent packet (chosen by measurement with `packet-render bench`; see README).
pub const PACKET_WIDTH: usize = 16;
/// The lane type of a packet.
pub type Packet = F16;

/// Instruction set the lane types compile to in this build.
pub fn instruction_set() -> &'static str {
    if cfg!(target_feature = "avx512f") {
        "AVX-512"
    } else if cfg!(target_feature = "avx2") {
        "AVX2"
    } else if cfg!(target_feature = "sse4.1") {
        "SSE4.1"
    } else {
        "SSE2"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<L: Lanes>() {
        let a = L::from_array({
            let mut a = L::splat(0.0).to_array();
            for (i, x) in a.as_mut().iter_mut().enumerate() {
                *x = i as f32;
            }
            a
        });
        let m = a.lt(L::splat(2.0));
        assert_eq!(m.bitmask(), 0b11);
        assert_eq!(L::mask_from_bits(0b101).bitmask(), 0b101);
        // Every lane's bit on its own, all of them, and bits past the width ignored.
        let all = (1u64 << L::WIDTH) as u32 - 1;
        for i in 0..L::WIDTH {
            assert_eq!(L::mask_from_bits(1 << i).bitmask(), 1 << i);
            let m = L::mask_from_bits(1 << i).to_array();
            assert!(
                m.as_ref()
                    .iter()
                    .all(|x| x.to_bits() == 0 || x.to_bits() == u32::MAX)
            );
        }
        assert_eq!(L::mask_from_bits(u32::MAX).bitmask(), all);
        assert_eq!(L::mask_from_bits(!all).bitmask(), 0);
        let s = L::select(m, L::splat(7.0), a).to_array();
        assert_eq!(&s.as_ref()[..3], &[7.0, 7.0, 2.0]);
        // NaN in self is ignored by max/min: the slab-test contract.
        let nan = L::splat(f32::NAN);
        assert_eq!(nan.maxps(L::splat(1.0)).to_array().as_ref()[0], 1.0);
        assert_eq!(nan.minps(L::splat(1.0)).to_array().as_ref()[0], 1.0);
        assert_eq!(nan.lt(L::splat(1.0)).bitmask(), 0);
        assert_eq!(L::splat(f32::INFINITY).is_finite().bitmask(), 0);
    }

    #[test]
    fn lane_contracts_hold_for_every_width() {
        check::<F4>();
        check::<F8>();
        check::<F16>();
    }
}
