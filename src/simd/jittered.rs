//! The points of a square jittered set (`k × k` strata, one uniform point in each,
//! row by row: `integrator::sampling::fill_2d_split`, the scalar oracle) sixteen at a
//! time ([`jittered_block`]): the strata's column and row of sixteen successive points
//! in lanes, then `(column + u) / k`, `(row + v) / k` as the scalar loop computes them.
//!
//! Why: the draws of a block are already computed in lanes (`simd::splitmix`; LLVM
//! vectorised the scalar stream's loop the same way), and what was left of
//! `fill_2d_split` was its per-point loop (an integer-to-float conversion, two
//! multiply-adds and two scalar stores per point, and the stratum counters).
//!
//! Exactness: columns and rows are integers below `2^24` (the caller's `k`, `n` are),
//! so they are exact in f32, and the lane holds `(i as f32 + d) * inv` with the same
//! two roundings as the scalar loop (a test compares every point bit for bit).

use super::Packet;

/// The sixteen points `q0 + p`, `p < 16`, of a `k × k` jittered set (`inv = 1 / k` as
/// the caller rounds it) whose first point `q0` lies in column `i0 < k`, row `j0`:
/// `u[p] = (i_p + du[p]) * inv`, `v[p] = (j_p + dv[p]) * inv` for the column `i_p` and
/// row `j_p` of point `q0 + p`. Requires `k >= 1` and `k * (j0 + 16 / k + 2) < 2^24`
/// (exact integers in f32).
#[inline(always)]
pub fn jittered_block(
    (i0, j0, k): (u32, u32, u32),
    inv: f32,
    du: &[f32; 16],
    dv: &[f32; 16],
) -> ([f32; 16], [f32; 16]) {
    const IOTA: [f32; 16] = [
        0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
    ];
    let kk = Packet::splat(k as f32);
    let one = Packet::splat(1.0);
    let mut i = Packet::splat(i0 as f32) + Packet::new(IOTA);
    let mut j = Packet::splat(j0 as f32);
    // Each pass moves the lanes past the end of a row to the next (at most
    // `15 / k + 1` passes; every value stays an exact integer).
    loop {
        let wrap = i.simd_ge(kk);
        if !wrap.any() {
            break;
        }
        i = wrap.select(i - kk, i);
        j = wrap.select(j + one, j);
    }
    let inv = Packet::splat(inv);
    let u = (i + Packet::new(*du)) * inv;
    let v = (j + Packet::new(*dv)) * inv;
    (u.to_array(), v.to_array())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::xorshift64;

    /// [`jittered_block`] against the scalar loop of `fill_2d_split` (column and row
    /// counters, `(i as f32 + d) * inv`), bit for bit: every block of square sets of
    /// side 1 to 40 and of side 1000 (blocks that start mid-row, rows shorter and
    /// longer than a block), random draws in `[0, 1)` including 0 and the largest.
    #[test]
    fn lane_points_are_the_scalar_loops_bit_for_bit() {
        let mut next = xorshift64(0x9b05_688c_2b3e_6c1f);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let mut blocks = 0;
        for k in (1u32..=40).chain([1000]) {
            let n = k * k;
            let inv = 1.0 / k as f32;
            let (mut i, mut j) = (0u32, 0u32);
            for b in 0..n.div_ceil(16).min(200) {
                let mut draw = |p: usize| match (b + p as u32) % 29 {
                    0 => 0.0,
                    1 => 1.0 - f32::EPSILON / 2.0,
                    _ => unit(),
                };
                let du: [f32; 16] = std::array::from_fn(&mut draw);
                let dv: [f32; 16] = std::array::from_fn(&mut draw);
                let (u, v) = jittered_block((i, j, k), inv, &du, &dv);
                let m = (n - 16 * b).min(16) as usize;
                for p in 0..m {
                    let (su, sv) = ((i as f32 + du[p]) * inv, (j as f32 + dv[p]) * inv);
                    assert_eq!(u[p].to_bits(), su.to_bits(), "k {k} block {b} u[{p}]");
                    assert_eq!(v[p].to_bits(), sv.to_bits(), "k {k} block {b} v[{p}]");
                    i += 1;
                    if i == k {
                        (i, j) = (0, j + 1);
                    }
                }
                blocks += 1;
            }
        }
        assert!(blocks > 1000, "{blocks} blocks");
    }
}
