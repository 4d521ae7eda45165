//! The only module that names `wide` types. Everything else asks for lanes through
//! [`Lanes`]: [`F4`] for the four children of a BVH4 node or the four triangles of a
//! leaf group, and [`Packet`] for a coherent ray packet of [`PACKET_WIDTH`] rays.
//!
//! Lane width: with AVX-512 (`target-cpu=native` on the development machines) a
//! 16-wide packet is one register; without it `wide` emulates 16 lanes with two 8-lane
//! (AVX2) or four 4-lane (SSE2) registers, which stays correct, only slower.
//!
//! Masks are lane vectors whose lanes are all-ones or all-zeros, as `wide` returns
//! from comparisons; [`Lanes::bitmask`] turns one into an integer with bit `i` for lane `i`.

pub mod camera;
pub mod compact;
pub mod direct_light;
pub mod exact_sums;
pub mod glass_shadow;
pub mod kernels;
pub mod lanes3;
pub mod left_pack;
pub mod pow;
pub mod prefetch;
pub mod quant;
pub mod ray_store;
pub mod specular;
pub mod surface;
pub mod tiny;

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};
use wide::{f32x4, f32x8, f32x16};

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
    ($t:ty, $n:expr) => {
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
            #[inline(always)]
            fn mask_from_bits(bits: u32) -> Self {
                let mut a = [0.0f32; $n];
                for (i, l) in a.iter_mut().enumerate() {
                    *l = f32::from_bits(if bits >> i & 1 == 1 { u32::MAX } else { 0 });
                }
                <$t>::new(a)
            }
        }
    };
}

impl_lanes!(f32x4, 4);
impl_lanes!(f32x8, 8);
impl_lanes!(f32x16, 16);

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
