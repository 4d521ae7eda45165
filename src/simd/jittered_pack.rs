//! The light points of a pack of shading points in one lane group ([`PackLayout`]):
//! each point's square jittered set (`integrator::sampling::append_2d_split`, the
//! scalar oracle, with `jittered_block` in lanes) drawn from its own stream, point `j`
//! in lanes `j stride ..` (`integrator::area_light::shade_quads_packed`), zeros in the
//! lanes between and after, as the pack's arrays were filled point by point.
//!
//! Why: with 4 light samples per point (dof_area) each point's set went through
//! `append_2d_split` on its own: 32 SplitMix draws in lanes of which 8 were used, a
//! `jittered_block` whose row wrap loops eight times for `k = 2`, and the pushes onto
//! the pack's arrays with a zero fill per point (perf, dof_area 640x480, 1 thread:
//! `append_2d_split` 10.7 %, `hit_points_append` 1.4 % of the frame). Here one pack's
//! 32 draws are 32 lanes of the four streams (`simd::splitmix::unit_draws16`), the
//! strata's columns and rows come from a table made once per sample count.
//!
//! Exactness: lane `l` of point `j`, sample `p = l mod stride`, holds
//! `(column_p + u) * inv`, `(row_p + v) * inv` with `u`, `v` the stream's draws `2p`,
//! `2p + 1` (`fill_pairs16`'s), `column_p = p mod k`, `row_p = p div k` exact in f32 and
//! `inv = 1 / k` rounded as the scalar code rounds it: the same two roundings per
//! coordinate as `jittered_block` (a test compares every lane and the streams' states
//! with the scalar path).

use super::Packet;
use super::splitmix::{GAMMA, unit_draws16};

/// The lanes of a pack of `n`-point square jittered sets, one per block of `stride`
/// lanes: per lane its draws' offsets from its stream's state, its stratum's column
/// and row, and whether it holds a point.
#[derive(Clone, Copy, Debug)]
pub struct PackLayout {
    shift: u32,
    /// `(2p + 1) γ`, `(2p + 2) γ`: the advances of the lane's two draws.
    off_u: [u64; 16],
    off_v: [u64; 16],
    col: [f32; 16],
    row: [f32; 16],
    inv: f32,
    /// The lanes `p < n` of the first block.
    block: u32,
    stride: usize,
}

impl PackLayout {
    /// The layout for sets of `n = k * k` points in blocks of `stride` lanes (a power
    /// of two, `n <= stride <= 16`); `None` where `n` is not such a square.
    pub fn new(n: u32, stride: usize) -> Option<PackLayout> {
        let k = n.isqrt();
        if n == 0 || k * k != n || !stride.is_power_of_two() || stride > 16 || n as usize > stride {
            return None;
        }
        let p = |l: usize| (l & (stride - 1)) as u32;
        Some(PackLayout {
            shift: stride.trailing_zeros(),
            off_u: std::array::from_fn(|l| (2 * p(l) as u64 + 1).wrapping_mul(GAMMA)),
            off_v: std::array::from_fn(|l| (2 * p(l) as u64 + 2).wrapping_mul(GAMMA)),
            col: std::array::from_fn(|l| (p(l) % k) as f32),
            row: std::array::from_fn(|l| (p(l) / k) as f32),
            inv: 1.0 / k as f32,
            block: (1u32 << n) - 1,
            stride,
        })
    }

    /// The points `(u, v)` of the blocks in `blocks` (bit `j`: block `j`), block `j`'s
    /// drawn from the stream whose state is `states[j]` (the stream advanced by the
    /// caller past its `n` pairs, `PixelRng::skip_pairs`); `0.0` in every other lane.
    #[inline(always)]
    pub fn points(&self, states: &[u64; 16], blocks: u32) -> (Packet, Packet) {
        let (zu, zv) = self.draw_states(states, blocks);
        let (du, dv) = (unit_draws16(&zu), unit_draws16(&zv));
        let inv = Packet::splat(self.inv);
        let u = (Packet::new(self.col) + Packet::new(du)) * inv;
        let v = (Packet::new(self.row) + Packet::new(dv)) * inv;
        let mut live = 0u32;
        let mut b = blocks & (u32::MAX >> (32 - (16 >> self.shift)));
        while b != 0 {
            let j = b.trailing_zeros();
            b &= b - 1;
            live |= self.block << (j as usize * self.stride);
        }
        let keep = <Packet as super::Lanes>::mask_from_bits(live & 0xffff);
        let zero = Packet::splat(0.0);
        (keep.select(u, zero), keep.select(v, zero))
    }
}

impl PackLayout {
    /// Per lane, the states its two draws mix (`unit_draws16`): its block's stream
    /// state plus `off_u` and `off_v`, for the blocks in `blocks` (the others' lanes
    /// are left to the caller's zeros). With AVX-512 each block's state is broadcast
    /// over its lanes in registers (`vpbroadcastq` under a lane mask); elsewhere lane
    /// by lane.
    ///
    /// Measured: lane by lane (`std::array::from_fn` over `states[l >> shift]`), these
    /// two arrays were ~6 % of `shade_quads_packed`'s samples (perf, dof_area 960x720,
    /// 1 thread, AVX-512); with the states spread by permutes of the array (loaded as
    /// two registers) the load still waited on the scalar stores of the states (no
    /// forwarding from 8-byte stores to a 64-byte load), ~1 %.
    #[inline(always)]
    fn draw_states(&self, states: &[u64; 16], blocks: u32) -> ([u64; 16], [u64; 16]) {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
        {
            use std::arch::x86_64::*;
            let (mut zu, mut zv) = ([0u64; 16], [0u64; 16]);
            let stride = 1u32 << self.shift.min(4);
            let block = (1u32 << stride) - 1;
            // SAFETY: AVX-512F is enabled at compile time; every load reads eight
            // elements of a 16-element array (`off_u`, `off_v`) and every store writes
            // eight of `zu` or `zv`, in bounds.
            unsafe {
                let (mut lo, mut hi) = (_mm512_setzero_si512(), _mm512_setzero_si512());
                let mut b = blocks & (u32::MAX >> (32 - (16 >> self.shift.min(4))));
                while b != 0 {
                    let j = b.trailing_zeros();
                    b &= b - 1;
                    let lanes = block << (j * stride);
                    let state = states[j as usize & 15] as i64;
                    lo = _mm512_mask_set1_epi64(lo, lanes as u8, state);
                    hi = _mm512_mask_set1_epi64(hi, (lanes >> 8) as u8, state);
                }
                for (h, s) in [lo, hi].into_iter().enumerate() {
                    let ou = _mm512_loadu_si512(self.off_u.as_ptr().add(8 * h).cast());
                    let ov = _mm512_loadu_si512(self.off_v.as_ptr().add(8 * h).cast());
                    _mm512_storeu_si512(zu.as_mut_ptr().add(8 * h).cast(), _mm512_add_epi64(s, ou));
                    _mm512_storeu_si512(zv.as_mut_ptr().add(8 * h).cast(), _mm512_add_epi64(s, ov));
                }
            }
            (zu, zv)
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
        {
            let _ = blocks;
            let state = |l: usize| states[(l >> self.shift) & 15];
            (
                std::array::from_fn(|l| state(l).wrapping_add(self.off_u[l])),
                std::array::from_fn(|l| state(l).wrapping_add(self.off_v[l])),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::{Dimension, PixelRng, SamplerKind, append_2d_split};
    use crate::test_rng::xorshift64;

    /// [`PackLayout::points`] against the pack's arrays filled point by point as
    /// `shade_quads_packed` filled them (`append_2d_split` at each drawn block, zeros
    /// between and after), bit for bit, and the streams' states after `skip_pairs`
    /// against those after `append_2d_split`: every square set that fits a block
    /// (1, 4, 9, 16 points), every stride it fits, random streams and block sets.
    #[test]
    fn pack_points_are_the_point_by_point_sets() {
        let mut next = xorshift64(0x6a09_e667_f3bc_c908);
        let mut lanes = 0usize;
        for case in 0..4000 {
            for n in [1u32, 4, 9, 16] {
                for stride in [1usize, 2, 4, 8, 16] {
                    let Some(layout) = PackLayout::new(n, stride) else {
                        assert!(n as usize > stride, "n {n} stride {stride}");
                        continue;
                    };
                    let blocks = 16 / stride;
                    let drawn = (next() as u32) & ((1u32 << blocks) - 1) | (case & 1);
                    let starts: Vec<u64> = (0..blocks).map(|_| next()).collect();
                    let (mut u, mut v, mut pairs) = (Vec::new(), Vec::new(), Vec::new());
                    let mut states = [0u64; 16];
                    for j in 0..blocks {
                        if drawn >> j & 1 == 0 {
                            continue;
                        }
                        u.resize(j * stride, 0.0);
                        v.resize(j * stride, 0.0);
                        let mut scalar = PixelRng::from_state(starts[j]);
                        append_2d_split(
                            SamplerKind::Jittered,
                            n,
                            Dimension::Hit,
                            &mut scalar,
                            (&mut u, &mut v),
                            &mut pairs,
                        );
                        let mut packed = PixelRng::from_state(starts[j]);
                        states[j] = packed.skip_pairs(n);
                        assert_eq!(packed.state(), scalar.state(), "case {case} n {n}");
                    }
                    u.resize(16, 0.0);
                    v.resize(16, 0.0);
                    let (pu, pv) = layout.points(&states, drawn);
                    let (pu, pv) = (pu.to_array(), pv.to_array());
                    for l in 0..16 {
                        assert_eq!(
                            pu[l].to_bits(),
                            u[l].to_bits(),
                            "case {case} n {n} lane {l}"
                        );
                        assert_eq!(
                            pv[l].to_bits(),
                            v[l].to_bits(),
                            "case {case} n {n} lane {l}"
                        );
                        lanes += 1;
                    }
                }
            }
        }
        assert!(lanes > 500_000, "{lanes}");
    }

    /// No layout where the set is not a square or does not fit its block.
    #[test]
    fn layouts_only_for_square_sets_that_fit() {
        assert!(PackLayout::new(4, 4).is_some() && PackLayout::new(1, 1).is_some());
        for (n, stride) in [(2, 2), (3, 4), (4, 2), (0, 4), (8, 8), (16, 8), (4, 3)] {
            assert!(
                PackLayout::new(n, stride).is_none(),
                "n {n} stride {stride}"
            );
        }
    }
}
