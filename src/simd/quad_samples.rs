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

use super::direct_light::{Highlight, QuadLight, ShadowLanes, SurfaceLanes, reflectance};
use super::lanes3::{V3, offset_ray_origin};
use super::{Lanes, Packet};
use crate::geometry::SPAWN_TO_ERROR;
use glam::{DVec3, Vec3};

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

/// The per-shading-point part of `quad_light`: the two possible shadow-ray origins.
#[derive(Clone, Copy, Debug)]
pub struct QuadSamples {
    /// The origin where `(target - base) · n_g` is not negative, and where it is.
    plain: V3,
    flipped: V3,
}

impl QuadSamples {
    /// The origins of the shading point `s` (all lanes the same point); `None` where
    /// `n_g · n_g` is not positive (no direction then makes `offset_ray_origin` flip),
    /// for the caller to use `quad_light`.
    #[inline(always)]
    pub fn new(s: &SurfaceLanes) -> Option<QuadSamples> {
        let nn = s.ng.dot(s.ng);
        if nn.to_array()[0] > 0.0 {
            // `w · n < 0` is false for `w = n_g` (a sum of squares) and true for `-n_g`
            // (its negation, exactly, and positive).
            Some(QuadSamples {
                plain: offset_ray_origin(s.base, s.p_error, s.ng, s.ng),
                flipped: offset_ray_origin(s.base, s.p_error, s.ng, s.ng.negated()),
            })
        } else {
            None
        }
    }

    /// The two origins (lane 0 of each): every shadow ray of [`lanes`](Self::lanes)
    /// starts at one of them, bit for bit.
    pub fn origins(&self) -> [Vec3; 2] {
        [self.plain.lane(0), self.flipped.lane(0)]
    }

    /// `quad_light(s, hl, q, u, v, samples, active)`, bit for bit.
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
        let (lit, f) = reflectance(s, hl, wi);
        let contribution = weight.times(f).over(Packet::splat(samples));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::direct_light::quad_light;
    use crate::test_rng::xorshift64;

    /// [`QuadSamples::lanes`] against `quad_light`, every field bit for bit (origin,
    /// direction, extent, contribution, mask): random shading points with random
    /// normals (a light behind, beside and in front of the surface, so that both
    /// origins are chosen, mixed within lane groups), errors, reflectances with and
    /// without a highlight, random quad lights and light points, partial groups.
    #[test]
    fn hoisted_origins_give_quad_light_bit_for_bit() {
        let mut next = xorshift64(0x3c6e_f372_fe94_f82b);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut lanes, mut flipped, mut plain) = (0usize, 0usize, 0usize);
        for case in 0..4000 {
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
                albedo: V3::splat(Vec3::new(0.7, 0.5, 0.3)),
            };
            let hl = Highlight {
                specular: if case % 2 == 0 {
                    Vec3::ZERO
                } else {
                    Vec3::splat(0.4)
                },
                shininess: 30.0,
            };
            let fast = QuadSamples::new(&s).expect("a unit normal");
            let u = Packet::new(std::array::from_fn(|_| unit()));
            let v = Packet::new(std::array::from_fn(|_| unit()));
            let active = if case % 5 == 0 { 0x7ff } else { 0xffff };
            let a = quad_light(&s, &hl, &q, u, v, 64.0, active);
            let b = fast.lanes(&s, &hl, &q, u, v, 64.0, active);
            let bits = |x: &V3| [x.x, x.y, x.z].map(|p| p.to_array().map(f32::to_bits));
            assert_eq!(bits(&a.origin), bits(&b.origin), "case {case}: origin");
            assert_eq!(bits(&a.dir), bits(&b.dir), "case {case}: direction");
            assert_eq!(
                a.tmax.to_array().map(f32::to_bits),
                b.tmax.to_array().map(f32::to_bits),
                "case {case}: tmax"
            );
            assert_eq!(bits(&a.contribution), bits(&b.contribution), "case {case}");
            assert_eq!(a.mask, b.mask, "case {case}: mask");
            // Lanes whose light point lies behind the surface (the flipped origin).
            let point = V3::splat(q.corner)
                .plus(V3::splat(q.edge1).scale(u))
                .plus(V3::splat(q.edge2).scale(v));
            let behind = point.minus(s.base).dot(s.ng).to_bitmask();
            flipped += behind.count_ones() as usize;
            plain += 16 - behind.count_ones() as usize;
            lanes += 16;
        }
        eprintln!("{lanes} lanes, {flipped} with a corner behind the surface, {plain} before");
        assert!(flipped > lanes / 5 && plain > lanes / 5);
    }
}
