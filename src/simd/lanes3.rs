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

// `V3::add_to` reads sixteen `Vec3`s as 48 contiguous floats.
const _: () = assert!(std::mem::size_of::<[Vec3; 16]>() == 48 * 4);
const _: () = assert!(std::mem::align_of::<Vec3>() == 4);

/// The permute tables of [`V3::add_to`], per 16-float window `k` of sixteen `Vec3`s
/// (float `16 k + m` is component `(16 k + m) % 3` of lane `(16 k + m) / 3`): the
/// two-source index taking each x or y component from `x` (`lane`) or `y` (`16 +
/// lane`), the index of each z component's lane in `z`, and the mask of the z lanes.
#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
const AOS_TABLES: ([[u32; 16]; 3], [[u32; 16]; 3], [u16; 3]) = {
    let (mut xy, mut zi, mut zm) = ([[0u32; 16]; 3], [[0u32; 16]; 3], [0u16; 3]);
    let mut k = 0;
    while k < 3 {
        let mut m = 0;
        while m < 16 {
            let e = 16 * k + m;
            let (lane, c) = ((e / 3) as u32, e % 3);
            if c == 2 {
                zi[k][m] = lane;
                zm[k] |= 1 << m;
            } else {
                xy[k][m] = lane + 16 * c as u32;
            }
            m += 1;
        }
        k += 1;
    }
    (xy, zi, zm)
};

/// Whether `v` is `v[0], v[0] + 1, ..., v[0] + 15` (wrapping): one lane compare.
#[inline(always)]
pub fn is_run(v: &[u32; 16]) -> bool {
    use wide::u32x16;
    const INDEX: [u32; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15];
    (u32x16::new(*v) - u32x16::splat(v[0]))
        .simd_eq(u32x16::new(INDEX))
        .all()
}

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

    /// `dst[i] += self.lane(i)` for the sixteen lanes: per component the same f32 sum
    /// `dst[i].x + x[i]` as glam's `Vec3 += Vec3`.
    ///
    /// With AVX-512 the sixteen `Vec3`s are three 64-byte windows of 48 floats: each
    /// window's lanes are gathered from `x`, `y`, `z` by two permutes (`x` and `y` by
    /// one two-source permute, `z` merged by a masked one, the tables of
    /// [`AOS_TABLES`]), added to the window in one `vaddps` and stored back, where the
    /// loop did three scalar loads, adds and stores per lane. For the shading stage's
    /// sums over a run of consecutive camera samples (`shade_stage`).
    #[inline(always)]
    pub fn add_to(&self, dst: &mut [Vec3; 16]) {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
        {
            use std::arch::x86_64::*;
            let (x, y, z) = (self.x.to_array(), self.y.to_array(), self.z.to_array());
            let (xy, zi, zm) = AOS_TABLES;
            // SAFETY: `dst` is 16 `Vec3`s, 48 contiguous f32 (`Vec3` is three f32,
            // `repr(C)`, asserted below): three unaligned 16-float windows. The other
            // loads are of 16-element arrays of 4-byte values.
            unsafe {
                let (x, y, z) = (
                    _mm512_loadu_ps(x.as_ptr()),
                    _mm512_loadu_ps(y.as_ptr()),
                    _mm512_loadu_ps(z.as_ptr()),
                );
                let p = dst.as_mut_ptr() as *mut f32;
                for k in 0..3 {
                    let ixy = _mm512_loadu_si512(xy[k].as_ptr().cast());
                    let iz = _mm512_loadu_si512(zi[k].as_ptr().cast());
                    let w = _mm512_permutex2var_ps(x, ixy, y);
                    let w = _mm512_mask_permutexvar_ps(w, zm[k], iz, z);
                    let q = p.add(16 * k);
                    _mm512_storeu_ps(q, _mm512_add_ps(_mm512_loadu_ps(q), w));
                }
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
        {
            let (x, y, z) = (self.x.to_array(), self.y.to_array(), self.z.to_array());
            for (i, d) in dst.iter_mut().enumerate() {
                *d += Vec3::new(x[i], y[i], z[i]);
            }
        }
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

    /// `is_run` says yes exactly for sixteen consecutive values.
    #[test]
    fn is_run_finds_consecutive_values() {
        for first in [0u32, 7, u32::MAX - 20, u32::MAX - 3] {
            let mut v: [u32; 16] = std::array::from_fn(|i| first.wrapping_add(i as u32));
            assert!(is_run(&v), "{first}");
            for i in 0..16 {
                for bad in [1u32, 2, 16, 1 << 31] {
                    let keep = v[i];
                    v[i] = keep.wrapping_add(bad);
                    assert!(!is_run(&v), "{first}: lane {i} moved by {bad}");
                    v[i] = keep;
                }
            }
        }
    }

    /// `add_to` adds each lane to its `Vec3` as the scalar `+=` does, bit for bit: random
    /// values of every magnitude and sign, signed zeros, infinities and subnormals (NaN
    /// only as NaN: the payload of a sum of two NaNs is not fixed by `+`).
    #[test]
    fn add_to_is_the_scalar_sum_per_lane() {
        let mut s = 0x9e37_79b9u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        let special = [
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1e-40,
            -3.5,
        ];
        for round in 0..2000 {
            let mut value = || {
                let r = rnd();
                if round % 3 == 0 && r % 5 == 0 {
                    special[(r / 5) as usize % special.len()]
                } else {
                    // Any finite f32 bit pattern, or a moderate value.
                    let f = f32::from_bits(r);
                    if f.is_finite() {
                        f
                    } else {
                        (r % 1000) as f32 * 0.37
                    }
                }
            };
            let dst: [Vec3; 16] = std::array::from_fn(|_| Vec3::new(value(), value(), value()));
            let add: [Vec3; 16] = std::array::from_fn(|_| Vec3::new(value(), value(), value()));
            let lanes = V3 {
                x: Packet::new(add.map(|v| v.x)),
                y: Packet::new(add.map(|v| v.y)),
                z: Packet::new(add.map(|v| v.z)),
            };
            let mut got = dst;
            lanes.add_to(&mut got);
            for i in 0..16 {
                let want = dst[i] + add[i];
                for c in 0..3 {
                    let (g, w) = (got[i][c], want[c]);
                    assert!(
                        g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
                        "round {round} lane {i} component {c}: {g:?} against {w:?}"
                    );
                }
            }
        }
    }

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
