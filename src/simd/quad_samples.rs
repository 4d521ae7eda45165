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

use super::Packet;
use super::direct_light::{Highlight, QuadLight, ShadowLanes, SurfaceLanes, reflectance};
use super::lanes3::{V3, offset_ray_origin};
use crate::geometry::SPAWN_TO_ERROR;
use glam::Vec3;

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
