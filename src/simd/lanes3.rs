//! Three-component vectors over the lanes of a [`Packet`] ([`V3`]: one `Vec3` per lane,
//! structure of arrays), with the operations the shading stage needs in the same f32
//! operation order as glam's scalar `Vec3`, so that a lane computes bit for bit what
//! the scalar code computes for that lane; and [`offset_ray_origin`], the lane form of
//! [`crate::geometry::offset_ray_origin`] (bit-identical, including the final
//! `next_up`/`next_down` step, done on the bit patterns).

use super::Packet;
use crate::geometry::gamma;
use glam::Vec3;
use wide::bytemuck::cast;
use wide::i32x16;

// The bit-level step below reinterprets a packet as 16 `i32` lanes.
const _: () = assert!(std::mem::size_of::<Packet>() == std::mem::size_of::<i32x16>());
const _: () = assert!(std::mem::size_of::<Packet>() == 16 * 4);

/// One `Vec3` per lane.
#[derive(Clone, Copy, Debug)]
pub struct V3 {
    pub x: Packet,
    pub y: Packet,
    pub z: Packet,
}

impl V3 {
    #[inline(always)]
    pub fn splat(v: Vec3) -> V3 {
        V3 {
            x: Packet::splat(v.x),
            y: Packet::splat(v.y),
            z: Packet::splat(v.z),
        }
    }

    /// Lane `i` of the result is `(x[i], y[i], z[i])`; each slice holds at least 16.
    #[inline(always)]
    pub fn load(x: &[f32], y: &[f32], z: &[f32]) -> V3 {
        let l = |s: &[f32]| Packet::new(s[..16].try_into().expect("16 lanes"));
        V3 {
            x: l(x),
            y: l(y),
            z: l(z),
        }
    }

    /// Lane `i` as a `Vec3`.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(
            self.x.to_array()[i],
            self.y.to_array()[i],
            self.z.to_array()[i],
        )
    }

    /// `(x * o.x) + (y * o.y) + (z * o.z)`, glam's order.
    #[inline(always)]
    pub fn dot(self, o: V3) -> Packet {
        (self.x * o.x) + (self.y * o.y) + (self.z * o.z)
    }

    #[inline(always)]
    pub fn abs(self) -> V3 {
        V3 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// Every component times the lane's `s`.
    #[inline(always)]
    pub fn scale(self, s: Packet) -> V3 {
        V3 {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    /// Every component divided by the lane's `s` (glam's `Vec3 / f32`).
    #[inline(always)]
    pub fn over(self, s: Packet) -> V3 {
        V3 {
            x: self.x / s,
            y: self.y / s,
            z: self.z / s,
        }
    }

    /// Component-wise product.
    #[inline(always)]
    pub fn times(self, o: V3) -> V3 {
        V3 {
            x: self.x * o.x,
            y: self.y * o.y,
            z: self.z * o.z,
        }
    }

    #[inline(always)]
    pub fn plus(self, o: V3) -> V3 {
        V3 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    pub fn minus(self, o: V3) -> V3 {
        V3 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    #[inline(always)]
    pub fn negated(self) -> V3 {
        V3 {
            x: -self.x,
            y: -self.y,
            z: -self.z,
        }
    }

    /// `mask ? a : b` per lane.
    #[inline(always)]
    pub fn select(mask: Packet, a: V3, b: V3) -> V3 {
        V3 {
            x: mask.select(a.x, b.x),
            y: mask.select(a.y, b.y),
            z: mask.select(a.z, b.z),
        }
    }

    /// glam's `normalize_or_zero`: `self * (1 / length)` where that reciprocal is
    /// finite and positive, else zero.
    #[inline(always)]
    pub fn normalize_or_zero(self) -> V3 {
        let rcp = Packet::splat(1.0) / self.dot(self).sqrt();
        let ok = rcp.is_finite() & rcp.simd_gt(Packet::splat(0.0));
        let n = self.scale(rcp);
        V3::select(ok, n, V3::splat(Vec3::ZERO))
    }
}

/// Lane form of [`crate::geometry::offset_ray_origin`], bit for bit: the offset
/// `d = |n|·p_error · (1 + γ(8))` along `±n`, then each moved coordinate one float
/// further in the offset's direction (`f32::next_up` / `next_down` semantics: NaN and
/// an infinity moving outwards stay, ±0 steps to the smallest subnormal).
///
/// Tried and not kept: a fast path for groups whose every lane is ordinary (`po`
/// finite and non-zero, the offset not NaN), stepping by
/// `bits + ((bits ^ offset_bits) >> 31 | 1)` masked to zero where the offset is zero
/// (a test matched it bit for bit with `step`). Its check (three compares and a
/// movemask per coordinate) cost more than it saved: callgrind, whitted_base, 1
/// thread, `shade_group_lanes` inclusive 538.0 M instructions with it, 526.5 M
/// without (about 5 M of that from the cheaper finiteness check of
/// `direct_light::spawn_ray_to_point`, changed at the same time). A first form that
/// also required a non-zero offset never applied on the Whitted floor (an
/// axis-aligned normal leaves two offsets zero) and added about 9 M.
#[inline(always)]
pub fn offset_ray_origin(p: V3, p_error: V3, n: V3, w: V3) -> V3 {
    let d = n.abs().dot(p_error) * Packet::splat(1.0 + gamma(8));
    let offset = n.scale(d);
    let flip = w.dot(n).simd_lt(Packet::splat(0.0));
    let offset = V3::select(flip, offset.negated(), offset);
    let po = p.plus(offset);
    V3 {
        x: step(po.x, offset.x),
        y: step(po.y, offset.y),
        z: step(po.z, offset.z),
    }
}

/// `po.next_up()` where `offset > 0`, `po.next_down()` where `offset < 0`, `po` where
/// the offset is zero (or NaN).
#[inline(always)]
fn step(po: Packet, offset: Packet) -> Packet {
    let zero = Packet::splat(0.0);
    let up = offset.simd_gt(zero);
    let down = offset.simd_lt(zero);
    let bits: i32x16 = cast(po);
    let one = i32x16::splat(1);
    let away: Packet = cast(bits + one);
    let toward: Packet = cast(bits - one);
    let negative = po.is_sign_negative();
    // Up moves a positive number away from zero and a negative one towards it.
    let moves_away = (up & !negative) | (down & negative);
    let stepped = moves_away.select(away, toward);
    // ±0: the smallest subnormal on the side of the step.
    let tiny = f32::from_bits(1);
    let stepped = po.simd_eq(zero).select(
        up.select(Packet::splat(tiny), Packet::splat(-tiny)),
        stepped,
    );
    // NaN stays; an infinity moving outwards stays.
    let keep = po.is_nan() | (po.is_inf() & moves_away);
    let stepped = keep.select(po, stepped);
    (up | down).select(stepped, po)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry;

    /// The lane offset equals the scalar one bit for bit, on ordinary points and on
    /// the edge cases of the final step: zero coordinates (±0 stepping to a
    /// subnormal), infinities, NaN, zero error (no move), and both sides of `n`.
    #[test]
    fn lane_offset_is_bit_identical_to_the_scalar_offset() {
        let mut cases = Vec::new();
        let mut s = 0x2545_f491u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        for i in 0..2000 {
            let scale = [1e-30f32, 1e-3, 1.0, 1e3, 1e30][i % 5];
            let p = Vec3::new(rnd(), rnd(), rnd()) * scale;
            let n = Vec3::new(rnd(), rnd(), rnd()).normalize_or(Vec3::Y);
            let err = Vec3::new(rnd().abs(), rnd().abs(), rnd().abs()) * scale * 1e-6;
            let w = Vec3::new(rnd(), rnd(), rnd());
            cases.push((p, err, n, w));
        }
        let special = [0.0, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        for &a in &special {
            for &b in &special {
                let p = Vec3::new(a, b, 1.0);
                let n = Vec3::new(0.6, -0.8, 0.0);
                for w in [n, -n] {
                    cases.push((p, Vec3::splat(1e-3), n, w));
                    cases.push((p, Vec3::ZERO, n, w));
                    cases.push((Vec3::new(a, 0.0, -0.0), Vec3::splat(1e-30), n, w));
                }
            }
        }
        for chunk in cases.chunks(16) {
            let get = |f: fn(&(Vec3, Vec3, Vec3, Vec3)) -> Vec3| {
                let mut xs = [0.0f32; 16];
                let mut ys = [0.0f32; 16];
                let mut zs = [0.0f32; 16];
                for (i, c) in chunk.iter().enumerate() {
                    let v = f(c);
                    (xs[i], ys[i], zs[i]) = (v.x, v.y, v.z);
                }
                V3::load(&xs, &ys, &zs)
            };
            let lanes = offset_ray_origin(get(|c| c.0), get(|c| c.1), get(|c| c.2), get(|c| c.3));
            for (i, &(p, err, n, w)) in chunk.iter().enumerate() {
                let want = geometry::offset_ray_origin(p, err, n, w);
                let got = lanes.lane(i);
                for k in 0..3 {
                    assert_eq!(
                        got[k].to_bits(),
                        want[k].to_bits(),
                        "p {p} err {err} n {n} w {w}: lane {got} scalar {want}"
                    );
                }
            }
        }
    }
}
