//! The light samples of one shading point towards a quad light, sixteen lanes at a
//! time ([`QuadSamples`]): [`quad_light`](super::direct_light::quad_light) with the
//! shadow-ray origin computed once per shading point instead of once per lane group.
//!
//! `spawn_ray_to` offsets the origin along `±n_g` by the point's error bound, the sign
//! chosen per lane by `(target - base) · n_g < 0`, and then steps each coordinate one
//! float outwards: the same two points for every sample of the shading point. They are
//! computed here by the lane `offset_ray_origin` itself, on the splatted point, with a
//! direction that makes it take each sign, and selected per lane by the same test, so
//! every lane holds `quad_light`'s origin bit for bit (a test compares every field).
//! Everything else is `quad_light`'s arithmetic in its order.
//!
//! [`OriginBox`] holds the origins of a lane group of shading points (two per point),
//! so that the sphere cull of the quad light's segments (`integrator::tiny_shadow::
//! QuadCull`) is built once per group instead of once per point.

use super::direct_light::{Highlight, QuadLight, ShadowLanes, SurfaceLanes};
use super::lanes3::{V3, offset_ray_origin};
use super::pow::pow;
use super::{Lanes, Packet};
use crate::geometry::SPAWN_TO_ERROR;
use glam::{DVec3, Vec3};
use std::f32::consts::FRAC_1_PI;

/// An axis-aligned box of f32 corners holding shadow-ray origins: those of the
/// shading points of a lane group ([`of_group`](Self::of_group)), or of one point
/// ([`of`](Self::of)). Whether a point's origins lie in it ([`covers`](Self::covers))
/// is decided by f32 comparisons, exactly; a cull built for the box's ball
/// ([`ball`](Self::ball)) then holds for that point's segments whatever points built
/// the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OriginBox {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl OriginBox {
    /// The box of both origins (`QuadSamples::origins`) of each shading point of the
    /// lanes in `live` (one point per lane: `base`, `p_error` and `n_g` as
    /// `QuadSamples::new` takes them), leaving out lanes with `n_g · n_g` not positive
    /// (`QuadSamples::new` refuses them) or a non-finite origin. `None` where no lane
    /// is left.
    #[inline(always)]
    pub fn of_group(base: V3, p_error: V3, ng: V3, live: u32) -> Option<OriginBox> {
        let plain = offset_ray_origin(base, p_error, ng, ng);
        let flipped = offset_ray_origin(base, p_error, ng, ng.negated());
        let finite = |v: &V3| (v.x.is_finite() & v.y.is_finite() & v.z.is_finite()).bitmask();
        let nn = ng.dot(ng).simd_gt(Packet::splat(0.0)).bitmask();
        let live = live & 0xffff & nn & finite(&plain) & finite(&flipped);
        if live == 0 {
            return None;
        }
        let fill = <Packet as Lanes>::mask_from_bits(live);
        let v = plain.lane(live.trailing_zeros() as usize & 15);
        let fill = |o: &V3| V3::select(fill, *o, V3::splat(v));
        let (a, b) = (fill(&plain), fill(&flipped));
        let (lo, hi) = (a.x.minps(b.x), a.x.maxps(b.x));
        let (ly, hy) = (a.y.minps(b.y), a.y.maxps(b.y));
        let (lz, hz) = (a.z.minps(b.z), a.z.maxps(b.z));
        let low = |p: Packet| p.to_array().into_iter().fold(f32::INFINITY, f32::min);
        let high = |p: Packet| p.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max);
        Some(OriginBox {
            lo: Vec3::new(low(lo), low(ly), low(lz)),
            hi: Vec3::new(high(hi), high(hy), high(hz)),
        })
    }

    /// The box of two origins; `None` where one is not finite.
    pub fn of(origins: [Vec3; 2]) -> Option<OriginBox> {
        let [a, b] = origins;
        (a.is_finite() && b.is_finite()).then(|| OriginBox {
            lo: a.min(b),
            hi: a.max(b),
        })
    }

    /// Whether both `origins` lie in the box (f32 comparisons: exact; NaN is not in
    /// it).
    #[inline(always)]
    pub fn covers(&self, origins: [Vec3; 2]) -> bool {
        origins
            .iter()
            .all(|o| o.cmpge(self.lo).all() && o.cmple(self.hi).all())
    }

    /// `(g, rho)`: the box's centre and half diagonal in f64, so that every point of
    /// the box lies within `rho` of `g` up to a few f64 roundings of `g` and `rho`
    /// (relative `2^-52` of `|g| + rho`), which the cull's slack (`2^-40` of the
    /// magnitudes) covers.
    pub fn ball(&self) -> (DVec3, f64) {
        let (lo, hi) = (self.lo.as_dvec3(), self.hi.as_dvec3());
        ((lo + hi) * 0.5, (hi - lo).length() * 0.5)
    }
}

/// The per-shading-point part of `quad_light`: the two possible shadow-ray origins,
/// and the cosine below which the highlight is left out ([`faint_below`]).
#[derive(Clone, Copy, Debug)]
pub struct QuadSamples {
    /// The origin where `(target - base) · n_g` is not negative, and where it is.
    plain: V3,
    flipped: V3,
    /// `faint_below(hl.shininess)`.
    faint: f32,
}

/// A cosine below which the lane `pow(cos, shininess)` of the highlight
/// (`simd::pow`, `wide`'s `powf_simd`) is `+0.0` exactly: `2^(-150 / shininess)`
/// rounded to f32 (`0`, never skipping, for a shininess that is not positive and
/// finite).
///
/// Why it is zero there: `x^e <= 2^-150` (up to the f32 rounding of the bound:
/// `(1 + 2^-24)^e` more), and `powf_simd` builds its result from the rounded
/// `ee ≈ e log2 x` (three parts, each within one unit plus the polynomials' relative
/// error) and a mantissa in `[√½, √2]`: its biased exponent `ee + 126` or `ee + 127`
/// is negative well before `ee` reaches -150, where it returns zero (its underflow
/// branch), and `x = 0` returns zero for `e > 0`. A test checks it on every f32 just
/// below the cut and on a sweep of `[0, cut)` for shininesses from 0.5 to 10000.
///
/// The lanes now leave out the highlight below a higher cut, [`faint_below`]; this one
/// stays as the documented zero of the lane `pow` (its test), for the point lights'
/// recorded attempt (`direct_light::point_light`).
pub fn dark_below(shininess: f32) -> f32 {
    if !(shininess.is_finite() && shininess > 0.0) {
        return 0.0;
    }
    (-150.0 / shininess as f64).exp2() as f32
}

/// The exponent of [`faint_below`]: highlights below `2^-FAINT_EXP` are left out.
pub const FAINT_EXP: f64 = 64.0;

/// A cosine below which the highlight's power is left out (`+0.0`) of the light
/// samples of [`QuadSamples::lanes`]: `2^(-FAINT_EXP / shininess)` rounded to f32
/// (`0`, never leaving anything out, for a shininess that is not positive and finite or
/// where the cut is not a normal f32). Below it `x^e < 2^-64 (1 + 2^-24)^e`, and the lane
/// `pow` is within `POW_REL_ERROR` of that (or `POW_TINY` absolute): a term below
/// `1.1 · 2^-64` of the specular reflectance, left out.
///
/// Why: between `2^(-126/e)` and `2^(-64/e)` the power is normal but the products it
/// goes through (`specular · p`, the light's weight, `1 / samples`, the path weight
/// and the glass factor) reach the subnormals, each such multiply taking a microcode
/// assist on Intel; between [`dark_below`] and `2^(-126/e)` the power itself is
/// subnormal. 2^-64 leaves 62 binades for those factors before the products underflow.
/// Measured: whitted_area64 with the CPU flushing subnormals (FTZ/DAZ in MXCSR, an
/// `LD_PRELOAD` constructor), perf, 1 thread, AVX-512, 4 kHz, two runs each:
/// `shade_quads` 2999/2996 -> 2637/2640 samples, the difference on the multiplies
/// `specular · p`, `weight · f`, `· 1/samples` and `contribution · weight · factor`
/// (sample offsets within `shade_quads` compared run for run).
pub fn faint_below(shininess: f32) -> f32 {
    if !(shininess.is_finite() && shininess > 0.0) {
        return 0.0;
    }
    let cut = (-FAINT_EXP / shininess as f64).exp2() as f32;
    if cut.is_normal() { cut } else { 0.0 }
}

impl QuadSamples {
    /// The origins of the shading point `s` (all lanes the same point); `None` where
    /// `n_g · n_g` is not positive (no direction then makes `offset_ray_origin` flip),
    /// for the caller to use `quad_light`.
    #[inline(always)]
    pub fn new(s: &SurfaceLanes, hl: &Highlight) -> Option<QuadSamples> {
        let (q, accepted) = Self::per_lane(s, hl);
        (accepted & 1 == 1).then_some(q)
    }

    /// [`new`](Self::new) for lanes of different shading points (a pack of points,
    /// each over a block of lanes): every lane holds the origins `new` gives for its
    /// point (the same lane arithmetic on the same inputs), and the returned bits are
    /// the lanes whose point `new` accepts (`n_g · n_g > 0`); `hl` is every point's.
    #[inline(always)]
    pub fn per_lane(s: &SurfaceLanes, hl: &Highlight) -> (QuadSamples, u32) {
        let nn = s.ng.dot(s.ng).simd_gt(Packet::splat(0.0)).to_bitmask() & 0xffff;
        // `w · n < 0` is false for `w = n_g` (a sum of squares) and true for `-n_g` (its
        // negation, exactly, and positive).
        let q = QuadSamples {
            plain: offset_ray_origin(s.base, s.p_error, s.ng, s.ng),
            flipped: offset_ray_origin(s.base, s.p_error, s.ng, s.ng.negated()),
            faint: if hl.specular == Vec3::ZERO {
                0.0
            } else {
                faint_below(hl.shininess)
            },
        };
        (q, nn)
    }

    /// The two origins (lane 0 of each): every shadow ray of [`lanes`](Self::lanes)
    /// starts at one of them, bit for bit.
    pub fn origins(&self) -> [Vec3; 2] {
        self.origins_at(0)
    }

    /// The two origins of the point in lane `lane` (of a [`per_lane`](Self::per_lane)
    /// value).
    pub fn origins_at(&self, lane: usize) -> [Vec3; 2] {
        self.lane_origins().at(lane)
    }

    /// The two origins of every lane, unpacked once (a pack's points each ask for
    /// theirs: one store of each coordinate's lanes, not one per point).
    #[inline(always)]
    pub fn lane_origins(&self) -> LaneOrigins {
        LaneOrigins([Unpacked3::of(self.plain), Unpacked3::of(self.flipped)])
    }
}

/// The lanes of a [`V3`] as arrays, for reading several lanes (`V3::lane` stores the
/// three coordinates' lanes at every call).
pub struct Unpacked3([[f32; 16]; 3]);

impl Unpacked3 {
    #[inline(always)]
    pub fn of(v: V3) -> Unpacked3 {
        Unpacked3([v.x.to_array(), v.y.to_array(), v.z.to_array()])
    }

    /// `V3::lane(i & 15)`.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec3 {
        let i = i & 15;
        Vec3::new(self.0[0][i], self.0[1][i], self.0[2][i])
    }
}

/// The two shadow-ray origins of each lane of a [`QuadSamples`], unpacked
/// ([`QuadSamples::lane_origins`]).
pub struct LaneOrigins([Unpacked3; 2]);

impl LaneOrigins {
    /// [`QuadSamples::origins_at`] of lane `lane`.
    #[inline(always)]
    pub fn at(&self, lane: usize) -> [Vec3; 2] {
        [self.0[0].lane(lane), self.0[1].lane(lane)]
    }
}

impl QuadSamples {
    /// `quad_light(s, hl, q, u, v, samples, active)`, bit for bit (`hl` the highlight
    /// given to [`new`](Self::new)), except in the contribution of lanes outside the
    /// returned `mask` (which nobody reads) and of lanes whose highlight cosine is below
    /// [`faint_below`], whose highlight power is `+0.0` (below `1.1 · 2^-64` in
    /// `quad_light`): the highlight's `pow` is left out where every lane of the mask has
    /// its cosine below that cut, and a power-of-two sample count divides by
    /// multiplying with its reciprocal (exact: both round the same real number).
    ///
    /// Measured (whitted_area64 512x384, 1 thread, AVX-512, perf): the highlight's
    /// `pow` was 9.3 % of the frame's samples (the chrome and glass spheres'
    /// shininess 200 and 500 at every light sample).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn lanes(
        &self,
        s: &SurfaceLanes,
        hl: &Highlight,
        q: &QuadLight,
        u: Packet,
        v: Packet,
        samples: f32,
        active: u32,
    ) -> ShadowLanes {
        let zero = Packet::splat(0.0);
        let point = V3::splat(q.corner)
            .plus(V3::splat(q.edge1).scale(u))
            .plus(V3::splat(q.edge2).scale(v));
        let n = V3::splat(q.normal);
        let to = point.minus(s.p);
        let dist2 = to.dot(to);
        let dist = dist2.sqrt();
        let wi = to.over(dist);
        let cos_l = -wi.dot(n);
        let seen = cos_l.simd_gt(zero) & dist.simd_gt(zero);
        let weight = V3::splat(q.radiance).scale(cos_l * Packet::splat(q.area) / dist2);
        let (lit, f) = self.reflectance(s, hl, wi, seen.to_bitmask() & active);
        let per = weight.times(f);
        // A power of two: a normal with no mantissa bits; its reciprocal is exact.
        let contribution = if samples.is_normal() && samples.to_bits() & 0x007f_ffff == 0 {
            per.scale(Packet::splat(1.0 / samples))
        } else {
            per.over(Packet::splat(samples))
        };
        // `spawn_ray_to(base, p_error, n_g, point, q.p_error, n)` with the origin chosen.
        let flip = point.minus(s.base).dot(s.ng).simd_lt(zero);
        let o = V3::select(flip, self.flipped, self.plain);
        let target = offset_ray_origin(point, V3::splat(q.p_error), n, s.base.minus(point));
        let d = target.minus(o);
        let cos = n.dot(d).abs();
        let eps = Packet::splat(SPAWN_TO_ERROR) * (d.x.abs() + d.y.abs() + d.z.abs()) / cos;
        let one = Packet::splat(1.0);
        let tmax = eps.simd_lt(one).select(one - eps, zero);
        ShadowLanes {
            origin: o,
            dir: d,
            tmax,
            contribution,
            mask: (seen & lit).to_bitmask() & active,
        }
    }
}

impl QuadSamples {
    /// `direct_light::reflectance`, its operations in its order, with the highlight's
    /// power `+0.0` in the lanes whose cosine is below `self.faint`, and `pow` left out
    /// where that holds for every lane of `need` that the returned mask keeps (see
    /// [`lanes`](Self::lanes)).
    #[inline(always)]
    fn reflectance(&self, s: &SurfaceLanes, hl: &Highlight, wi: V3, need: u32) -> (Packet, V3) {
        let zero = Packet::splat(0.0);
        let cos_s = wi.dot(s.ns);
        let mask = cos_s.simd_gt(zero) & (s.smooth | wi.dot(s.ng).simd_gt(zero));
        let mut f = s.albedo.scale(Packet::splat(FRAC_1_PI) * cos_s);
        if hl.specular != Vec3::ZERO {
            let h = wi.plus(s.wo).normalize_or_zero();
            let cos_h = h.dot(s.ns).fast_max(zero);
            let faint = cos_h.simd_lt(Packet::splat(self.faint));
            let p = if !faint.to_bitmask() & need & mask.to_bitmask() & 0xffff == 0 {
                zero
            } else {
                // (A blend, no arithmetic on the subnormal powers `pow` may return.)
                faint.select(zero, pow(cos_h, Packet::splat(hl.shininess)))
            };
            f = f.plus(V3::splat(hl.specular).scale(p));
        }
        (mask, f)
    }
}

/// Lane `l` of the result is lane `from[l]` of `p` (`from[l] < 16`): a pack's values
/// per shading point (point `j` in lane `j`) spread over the points' blocks of lanes
/// (`integrator::area_light::shade_quads_packed`). One `vpermps` with AVX-512.
///
/// Measured: built lane by lane (`std::array::from_fn` over each lane's hit) the
/// pack's surface lanes were ~20 % of dof_area's samples (perf, 1 thread).
#[inline(always)]
pub fn spread(p: Packet, from: &[u32; 16]) -> Packet {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        use std::arch::x86_64::*;
        // SAFETY: AVX-512F is enabled at compile time; `from` is 64 readable bytes, and
        // `Packet` is sixteen f32 lanes in one 64-byte register (`__m512`).
        unsafe {
            let idx = _mm512_loadu_si512(from.as_ptr().cast());
            let v: __m512 = std::mem::transmute(p);
            std::mem::transmute::<__m512, Packet>(_mm512_permutexvar_ps(idx, v))
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    {
        let a = p.to_array();
        Packet::new(std::array::from_fn(|l| a[from[l] as usize & 15]))
    }
}

/// A pack's per-point vectors over the points' blocks of `2^shift` lanes: lane `l`
/// holds `value(min(l >> shift, n - 1))` (what [`spread`] gives of the values loaded
/// point `j` in lane `j`), built in registers: the last point's splat, then each other
/// point's splat blended over its block (`n >= 1`, `n << shift <= 16`).
///
/// Measured: stored point by point into arrays and loaded as lanes
/// (`integrator::area_light::shade_quads_packed`'s albedo and path weight), the loads
/// waited on the stores (a 64-byte load over 4-byte stores does not forward): ~2 % of
/// that function's perf samples on one such load (dof_area 960x720, 1 thread,
/// AVX-512).
#[inline(always)]
pub fn per_block(n: usize, shift: u32, value: impl Fn(usize) -> Vec3) -> V3 {
    debug_assert!(n >= 1 && shift <= 4 && n << shift <= 16);
    let stride = 1u32 << shift.min(4);
    let block = (1u32 << stride) - 1;
    let mut out = V3::splat(value(n.max(1) - 1));
    for j in 0..n.saturating_sub(1).min(15) {
        let m = <Packet as Lanes>::mask_from_bits(block << (j as u32 * stride));
        out = V3::select(m, V3::splat(value(j)), out);
    }
    out
}

/// The sums of the aligned blocks of `block` lanes of `p` (`block` 1, 2, 4, 8 or 16):
/// entry `j` is the sum of lanes `j block .. (j + 1) block` as `Packet::reduce_add`
/// sums a packet holding those lanes in lanes `0 .. block` and `+0.0` in the others,
/// bit for bit: a pack of shading points summing its points' light samples (one block
/// each) as each point's own lane group summed them.
///
/// With AVX-512, `reduce_add` (`_mm512_reduce_add_ps`) halves: lane `i` plus lane
/// `i + 8`, then `i + 4`, `i + 2`, `i + 1`. On such a packet the steps of a stride of
/// `block` or more add `+0.0` to each of the first `block` lanes (which leaves a value
/// as it is, but turns `-0.0` into `+0.0`: done once here), and the rest add within the
/// block, which is this tree on each block. Elsewhere (`wide`'s emulated sixteen lanes
/// sum their halves in another order) each block is moved to the front of a zeroed
/// packet and summed by `reduce_add` itself. A test compares both with `reduce_add`.
#[inline(always)]
pub fn block_sums(p: Packet, block: usize) -> [f32; 16] {
    debug_assert!(block.is_power_of_two() && block <= 16);
    let mut out = [0.0f32; 16];
    if cfg!(target_feature = "avx512f") {
        // Each step adds lane `i + t` to lane `i` in every lane (one permute); the lanes
        // at a block's start hold its tree.
        let mut a = if block < 16 {
            p + Packet::splat(0.0)
        } else {
            p
        };
        let mut t = block / 2;
        while t >= 1 {
            let next: [u32; 16] = std::array::from_fn(|i| ((i + t) & 15) as u32);
            a = a + spread(a, &next);
            t /= 2;
        }
        let a = a.to_array();
        for (o, b) in out.iter_mut().zip((0..16).step_by(block)) {
            *o = a[b];
        }
    } else {
        let a = p.to_array();
        for (o, b) in out.iter_mut().zip((0..16).step_by(block)) {
            let lanes = std::array::from_fn(|i| if i < block { a[(b + i) & 15] } else { 0.0 });
            *o = Packet::new(lanes).reduce_add();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::direct_light::quad_light;

    /// [`spread`] moves lane `from[l]` to lane `l`, bit for bit, for index patterns of
    /// every kind (packs of each width, repeats, reversals, random).
    #[test]
    fn spread_moves_each_lane() {
        let mut next = xorshift64(0x5851_f42d_4c95_7f2d);
        for case in 0..2000 {
            let a: [f32; 16] = std::array::from_fn(|_| f32::from_bits(next() as u32));
            let from: [u32; 16] = match case % 4 {
                0 => std::array::from_fn(|l| (l / (1 << (case / 4 % 5))) as u32),
                1 => std::array::from_fn(|l| 15 - l as u32),
                _ => std::array::from_fn(|_| (next() % 16) as u32),
            };
            let got = spread(Packet::new(a), &from).to_array();
            for l in 0..16 {
                assert_eq!(
                    got[l].to_bits(),
                    a[from[l] as usize].to_bits(),
                    "case {case} lane {l}"
                );
            }
        }
    }

    /// [`per_block`] against [`spread`] of the values loaded point `j` in lane `j`
    /// (what the pack built before), bit for bit: every stride and point count, values
    /// with zeros of both signs.
    #[test]
    fn per_block_is_the_spread_of_the_loaded_values() {
        let mut next = xorshift64(0x3c6e_f372_fe94_f82b);
        let mut lanes = 0;
        for case in 0..500 {
            let values: Vec<Vec3> = (0..16)
                .map(|_| {
                    let mut c = || match next() % 5 {
                        0 => 0.0,
                        1 => -0.0,
                        r => ((next() >> 40) as f32 - 8e6) * r as f32,
                    };
                    Vec3::new(c(), c(), c())
                })
                .collect();
            for shift in 0..=4u32 {
                for n in 1..=(16usize >> shift) {
                    let got = per_block(n, shift, |j| values[j]);
                    let from: [u32; 16] =
                        std::array::from_fn(|l| (l as u32 >> shift).min(n as u32 - 1));
                    let at = |k: usize| Packet::new(std::array::from_fn(|j| values[j][k]));
                    let want = [at(0), at(1), at(2)].map(|p| spread(p, &from).to_array());
                    let got = [got.x, got.y, got.z].map(|p| p.to_array());
                    for k in 0..3 {
                        for l in 0..16 {
                            assert_eq!(
                                got[k][l].to_bits(),
                                want[k][l].to_bits(),
                                "case {case} shift {shift} n {n} coordinate {k} lane {l}"
                            );
                            lanes += 1;
                        }
                    }
                }
            }
        }
        assert!(lanes > 700_000, "{lanes}");
    }

    /// [`block_sums`] is `reduce_add` of each block moved to the front of a zeroed
    /// packet, bit for bit: values of mixed magnitudes and signs (where the order of
    /// the additions shows), zeros of both signs, every block size.
    #[test]
    fn block_sums_are_the_reduce_add_of_each_block() {
        let mut next = xorshift64(0x8f1b_bcdc_bfa5_3e0b);
        let mut checked = 0;
        for case in 0..20_000 {
            let lanes: [f32; 16] = std::array::from_fn(|_| {
                let r = next();
                let m = ((r >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
                match r % 9 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => m * 1e-30,
                    3 => m * 1e7,
                    _ => m * ((r >> 8) % 64) as f32,
                }
            });
            for block in [1usize, 2, 4, 8, 16] {
                let sums = block_sums(Packet::new(lanes), block);
                for (j, b) in (0..16).step_by(block).enumerate() {
                    let front = std::array::from_fn(|i| if i < block { lanes[b + i] } else { 0.0 });
                    let want = Packet::new(front).reduce_add();
                    assert_eq!(
                        sums[j].to_bits(),
                        want.to_bits(),
                        "case {case} block {block} at {b}: {lanes:?}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 500_000);
    }
    use crate::test_rng::xorshift64;

    /// [`QuadSamples::lanes`] against `quad_light`, every field bit for bit (origin,
    /// direction, extent, contribution, mask) but the contribution of lanes whose faint
    /// highlight was left out (within the term left out): random shading points with random
    /// normals (a light behind, beside and in front of the surface, so that both
    /// origins are chosen, mixed within lane groups), errors, reflectances with and
    /// without a highlight, random quad lights and light points, partial groups.
    #[test]
    fn hoisted_origins_give_quad_light_bit_for_bit() {
        let mut next = xorshift64(0x3c6e_f372_fe94_f82b);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut lanes, mut flipped, mut plain) = (0usize, 0usize, 0usize);
        let (mut contributions, mut skipped, mut kept) = (0usize, 0usize, 0usize);
        let mut flushed = 0usize;
        for case in 0..8000 {
            let mut r3 = |s: f32| Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s;
            let p = r3(20.0);
            let ng = r3(2.0).normalize_or(Vec3::Y);
            let ns = (ng + r3(0.3)).normalize_or(ng);
            let q = QuadLight::new(r3(10.0) + Vec3::Y * 5.0, r3(4.0), r3(4.0), Vec3::splat(7.0));
            let s = SurfaceLanes {
                p: V3::splat(p),
                p_error: V3::splat(p.abs() * 1e-6 + r3(1e-5).abs()),
                ng: V3::splat(ng),
                ns: V3::splat(ns),
                base: V3::splat(p + ng * 1e-4 * (case % 2) as f32),
                smooth: Packet::splat(if case % 3 == 0 {
                    f32::from_bits(!0)
                } else {
                    0.0
                }),
                wo: V3::splat(r3(2.0).normalize_or(Vec3::Z)),
                // No diffuse part in a quarter of the cases (the glass of the Whitted
                // rows): the highlight alone, where leaving it out shows.
                albedo: V3::splat(if case % 4 == 3 {
                    Vec3::ZERO
                } else {
                    Vec3::new(0.7, 0.5, 0.3)
                }),
            };
            let hl = Highlight {
                specular: if case % 2 == 0 {
                    Vec3::ZERO
                } else {
                    Vec3::splat(0.4)
                },
                shininess: [30.0, 200.0, 500.0, 1.0, 7.3, 10000.0, 0.0][case / 2 % 7],
            };
            let samples = [64.0, 20.0, 1.0, 9.0, 16.0, 3.0][case / 14 % 6];
            let fast = QuadSamples::new(&s, &hl).expect("a unit normal");
            let u = Packet::new(std::array::from_fn(|_| unit()));
            let v = Packet::new(std::array::from_fn(|_| unit()));
            let active = if case % 5 == 0 { 0x7ff } else { 0xffff };
            let a = quad_light(&s, &hl, &q, u, v, samples, active);
            let b = fast.lanes(&s, &hl, &q, u, v, samples, active);
            let bits = |x: &V3| [x.x, x.y, x.z].map(|p| p.to_array().map(f32::to_bits));
            assert_eq!(bits(&a.origin), bits(&b.origin), "case {case}: origin");
            assert_eq!(bits(&a.dir), bits(&b.dir), "case {case}: direction");
            assert_eq!(
                a.tmax.to_array().map(f32::to_bits),
                b.tmax.to_array().map(f32::to_bits),
                "case {case}: tmax"
            );
            assert_eq!(a.mask, b.mask, "case {case}: mask");
            let point = V3::splat(q.corner)
                .plus(V3::splat(q.edge1).scale(u))
                .plus(V3::splat(q.edge2).scale(v));
            let wi = point.minus(s.p).normalize_or_zero();
            let cos_h = wi.plus(s.wo).normalize_or_zero().dot(s.ns).to_array();
            let cut = faint_below(hl.shininess);
            // The contribution of every lane of the mask (the others are never read):
            // `quad_light`'s bit for bit, or, where the highlight cosine is below the
            // cut (up to the rounding of this test's cosine), within what leaving the
            // highlight out moves it: the term `w · specular · p / samples`, `p < 1.1 ·
            // 2^-64` and `w` the light's weight, twice (the sum `diffuse + specular · p`
            // it left moves by at most twice the term as it rounds), and one ulp of the
            // contribution for each of the two roundings after the sum.
            let (ca, cb) = (bits(&a.contribution), bits(&b.contribution));
            for i in (0..16).filter(|i| a.mask >> i & 1 == 1) {
                let lane = |c: &[[u32; 16]; 3]| c.map(|c| c[i]);
                contributions += 1;
                if lane(&ca) == lane(&cb) {
                    continue;
                }
                assert!(
                    cos_h[i] < cut * (1.0 + 1e-5),
                    "case {case}: contribution {i}"
                );
                let to = point.lane(i) - p;
                let dist2 = to.length_squared() as f64;
                let cos_l = -(to.as_dvec3().normalize().dot(q.normal.as_dvec3()));
                let w = 7.0 * cos_l * q.area as f64 / dist2;
                let term = w * 0.4 * 1.1 * (-FAINT_EXP).exp2() / samples as f64;
                let (x, y) = (a.contribution.lane(i), b.contribution.lane(i));
                for c in 0..3 {
                    let ulp = (x[c].abs().max(y[c].abs()) as f64) * f32::EPSILON as f64;
                    let diff = (x[c] as f64 - y[c] as f64).abs();
                    // (A rounding among the subnormals is absolute: 2^-150.)
                    let tiny = f32::from_bits(1) as f64;
                    assert!(
                        diff <= 2.0 * term + 2.0 * ulp + 2.0 * tiny,
                        "case {case} lane {i}: {x} against {y}, term {term:e}"
                    );
                }
                flushed += 1;
            }
            // Groups whose highlight was left out (every lane of the mask below the cut).
            let dark = (0..16)
                .filter(|i| a.mask >> i & 1 == 1)
                .all(|i| cos_h[i] < cut);
            if hl.specular != Vec3::ZERO && a.mask != 0 {
                (skipped, kept) = (skipped + dark as usize, kept + !dark as usize);
            }
            // Lanes whose light point lies behind the surface (the flipped origin).
            let point = V3::splat(q.corner)
                .plus(V3::splat(q.edge1).scale(u))
                .plus(V3::splat(q.edge2).scale(v));
            let behind = point.minus(s.base).dot(s.ng).to_bitmask();
            flipped += behind.count_ones() as usize;
            plain += 16 - behind.count_ones() as usize;
            lanes += 16;
        }
        eprintln!(
            "{lanes} lanes, {flipped} with a corner behind the surface, {plain} before; \
             {contributions} contributions compared ({flushed} moved by leaving a faint \
             highlight out); highlight left out in {skipped} lit groups, kept in {kept}"
        );
        assert!(flipped > lanes / 5 && plain > lanes / 5);
        assert!(contributions > lanes / 6 && skipped > 300 && kept > 300);
        assert!(flushed > 100 && flushed < contributions / 4, "{flushed}");
    }

    /// [`dark_below`]: the lane `pow` gives `+0.0` (bit for bit) for every f32 of the
    /// 2^16 just below the cut, for a sweep of `[0, cut)` down to the subnormals, and
    /// for zero; shininesses from 0.5 to 10000 (a cut of zero for 0.5 and 1, where
    /// `x^e` is not that small in f32, and for 0, NaN and infinity).
    #[test]
    fn the_highlight_is_zero_below_its_cut() {
        let mut checked = 0usize;
        for e in [
            0.5f32, 1.0, 2.0, 7.3, 30.0, 64.0, 128.5, 200.0, 500.0, 1000.0, 1e4,
        ] {
            let cut = dark_below(e);
            if e <= 1.0 {
                assert_eq!(cut, 0.0, "shininess {e}");
                continue;
            }
            assert!(cut > 0.0 && cut < 1.0, "shininess {e}: cut {cut}");
            let below = (1..=1u32 << 16).map(|k| f32::from_bits(cut.to_bits() - k));
            let sweep = (0..4000).map(|k| cut * 0.99f32.powi(k));
            let xs: Vec<f32> = below
                .chain(sweep)
                .chain([0.0, f32::MIN_POSITIVE, 1e-40])
                .filter(|&x| x < cut)
                .collect();
            for chunk in xs.chunks(16) {
                let mut a = [0.0f32; 16];
                a[..chunk.len()].copy_from_slice(chunk);
                let got = pow(Packet::new(a), Packet::splat(e)).to_array();
                for (x, g) in a.iter().zip(got) {
                    assert_eq!(g.to_bits(), 0, "{x}^{e} = {g}, below the cut {cut}");
                    checked += 1;
                }
            }
        }
        for e in [0.0, f32::NAN, f32::INFINITY, -3.0] {
            assert_eq!(dark_below(e), 0.0, "shininess {e}");
        }
        assert!(dark_below(200.0) > 0.59 && dark_below(500.0) > 0.8);
        assert!(checked > 400_000, "{checked}");
    }

    /// [`faint_below`]: the lane `pow` stays below `1.1 · 2^-64` (what `lanes` may
    /// leave out) on the 2^16 floats just below the cut and on a sweep of `[0, cut)`,
    /// for shininesses from 0.9 to 10000; no cut where it would not be a normal f32 or
    /// the shininess is not positive and finite.
    #[test]
    fn the_faint_highlight_is_below_its_bound() {
        let bound = 1.1 * (-FAINT_EXP).exp2();
        let mut checked = 0usize;
        for e in [0.9f32, 1.0, 2.0, 7.3, 30.0, 64.0, 200.0, 500.0, 1000.0, 1e4] {
            let cut = faint_below(e);
            assert!(cut.is_normal() && cut < 1.0, "shininess {e}: cut {cut}");
            assert!(cut >= dark_below(e), "shininess {e}");
            let below = (1..=1u32 << 16).map(|k| f32::from_bits(cut.to_bits() - k));
            let sweep = (0..4000).map(|k| cut * 0.99f32.powi(k));
            let xs: Vec<f32> = below.chain(sweep).filter(|&x| x < cut).collect();
            for chunk in xs.chunks(16) {
                let mut a = [0.0f32; 16];
                a[..chunk.len()].copy_from_slice(chunk);
                let got = pow(Packet::new(a), Packet::splat(e)).to_array();
                for (x, g) in a.iter().zip(got) {
                    assert!((g as f64) < bound, "{x}^{e} = {g}, below the cut {cut}");
                    checked += 1;
                }
            }
            // Just above the cut the power is not that small: the cut is tight.
            let above = f32::from_bits(cut.to_bits() + 16);
            assert!((above as f64).powf(e as f64) > (-FAINT_EXP).exp2(), "{e}");
        }
        for e in [0.5, 0.0, f32::NAN, f32::INFINITY, -3.0] {
            assert_eq!(faint_below(e), 0.0, "shininess {e}");
        }
        assert!(faint_below(200.0) > 0.8 && faint_below(500.0) > 0.91);
        assert!(checked > 600_000, "{checked}");
    }
}
