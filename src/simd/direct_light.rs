//! Direct light over the lanes of a [`Packet`]: the Lambert plus Blinn-Phong
//! reflectance of `integrator::shader` ([`reflectance`]), the solid checkerboard
//! ([`checker_albedo`]), and the shadow rays towards a point light (lanes over shading
//! points, [`point_light`]; a directional light, [`directional_light`]) and towards points on a quad light (lanes over the light
//! samples of one shading point, [`quad_light`]), each with its unoccluded contribution.
//!
//! Every formula repeats the scalar one's f32 operations in the same order, so each
//! lane computes bit for bit what the scalar shader computes, except the Blinn-Phong
//! power: [`super::pow::pow`] is within [`super::pow::POW_REL_ERROR`]
//! of libm's `powf`. Shadow-ray geometry (origin, direction, extent) does not depend on
//! the power and is bit-identical, so both paths trace the same shadow rays.

use super::Packet;
use super::lanes3::{V3, offset_ray_origin};
use super::pow::pow_uniform;
use crate::geometry::{SPAWN_TO_ERROR, gamma};
use crate::scene::{CHECKER_INSET, Checker};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;
use wide::bytemuck::cast;
use wide::i32x16;

/// The shading points of up to 16 hits (or one hit splatted over 16 light samples).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceLanes {
    pub p: V3,
    pub p_error: V3,
    /// Geometric and shading normals, facing the incident ray.
    pub ng: V3,
    pub ns: V3,
    /// Base point of shadow rays (the lifted point on smooth meshes, else `p`).
    pub base: V3,
    /// Mask: the hit is on a smooth-shaded mesh (a light below the facet still counts).
    pub smooth: Packet,
    /// Towards the viewer (`-d`, `d` the unit ray direction).
    pub wo: V3,
    pub albedo: V3,
}

impl SurfaceLanes {
    /// One shading point in every lane (tests): the shading normal, the shadow rays'
    /// base and the view along the geometric normal and the point, not on a smooth mesh.
    #[cfg(test)]
    pub fn splat_point(p: Vec3, p_error: Vec3, ng: Vec3, albedo: Vec3) -> SurfaceLanes {
        SurfaceLanes {
            p: V3::splat(p),
            p_error: V3::splat(p_error),
            ng: V3::splat(ng),
            ns: V3::splat(ng),
            base: V3::splat(p),
            smooth: Packet::splat(0.0),
            wo: V3::splat(ng),
            albedo: V3::splat(albedo),
        }
    }
}

/// The per-material part of the reflectance.
#[derive(Clone, Copy, Debug)]
pub struct Highlight {
    pub specular: Vec3,
    pub shininess: f32,
}

/// `(mask, f)`: where `mask` is set, the light from `wi` is reflected with `f` (Lambert
/// `albedo / π · cosθ` plus Blinn-Phong `ks (n·h)^shininess`), as the scalar
/// shader's `reflectance` closure; where it is clear, that closure returns `None`.
#[inline(always)]
pub fn reflectance(s: &SurfaceLanes, hl: &Highlight, wi: V3) -> (Packet, V3) {
    let zero = Packet::splat(0.0);
    let cos_s = wi.dot(s.ns);
    let mask = lit_lanes(s, wi);
    let mut f = s.albedo.scale(Packet::splat(FRAC_1_PI) * cos_s);
    if hl.specular != Vec3::ZERO {
        let h = wi.plus(s.wo).normalize_or_zero();
        // f32::max(x, 0) returns 0 for a NaN x; maxps(x, 0) returns its second operand then.
        let cos_h = h.dot(s.ns).fast_max(zero);
        let p = pow_uniform(cos_h, hl.shininess);
        f = f.plus(V3::splat(hl.specular).scale(p));
    }
    (mask, f)
}

/// The mask of [`reflectance`] alone: the lanes that the light from `wi` reaches
/// (`n_s · wi > 0`, and `n_g · wi > 0` unless on a smooth mesh).
#[inline(always)]
pub fn lit_lanes(s: &SurfaceLanes, wi: V3) -> Packet {
    let zero = Packet::splat(0.0);
    wi.dot(s.ns).simd_gt(zero) & (s.smooth | wi.dot(s.ng).simd_gt(zero))
}

/// Shadow rays of up to 16 lanes: `Ray::segment(origin, dir, 0, tmax)` and what the
/// light adds where unblocked, for the lanes whose bit is set in `mask`.
#[derive(Clone, Copy, Debug)]
pub struct ShadowLanes {
    pub origin: V3,
    pub dir: V3,
    pub tmax: Packet,
    pub contribution: V3,
    pub mask: u32,
}

impl ShadowLanes {
    /// No lane set: what [`point_light`] and [`directional_light`] return for a lane
    /// group that faces away from the light in every active lane, without building
    /// the rays or the reflectance (its callers read nothing of a group with no lane
    /// set: `push_shadow` and `settle_and_sum` return first).
    #[inline(always)]
    pub fn none() -> ShadowLanes {
        let zero = V3::splat(Vec3::ZERO);
        ShadowLanes {
            origin: zero,
            dir: zero,
            tmax: Packet::splat(0.0),
            contribution: zero,
            mask: 0,
        }
    }
}

/// Lane form of [`crate::geometry::spawn_ray_to`]: `(origin, dir, tmax)`, bit for bit.
#[inline(always)]
pub fn spawn_ray_to(p: V3, p_error: V3, n: V3, q: V3, q_error: V3, n_q: V3) -> (V3, V3, Packet) {
    let o = offset_ray_origin(p, p_error, n, q.minus(p));
    let target = offset_ray_origin(q, q_error, n_q, p.minus(q));
    let d = target.minus(o);
    let cos = n_q.dot(d).abs();
    let eps = Packet::splat(SPAWN_TO_ERROR) * (d.x.abs() + d.y.abs() + d.z.abs()) / cos;
    let one = Packet::splat(1.0);
    let tmax = eps.simd_lt(one).select(one - eps, Packet::splat(0.0));
    (o, d, tmax)
}

/// [`spawn_ray_to`] towards the exact point `q` (no error bound: a point light's
/// position), bit for bit. The target's offset there is `n_q · (|n_q| · 0) (1 + γ(8))`:
/// `±0` in every coordinate wherever `n_q` is finite, which leaves every non-zero
/// coordinate of `q` as it is (`q + ±0 = q`) and takes no step (`step` moves only along
/// a non-zero offset). So where `q` has no zero coordinate (a `-0.0` could turn into
/// `+0.0`) and every lane of `n_q` is finite, the target is `q` itself and its
/// `offset_ray_origin` (half of `spawn_ray_to`'s instructions) is skipped; elsewhere
/// it is computed as `spawn_ray_to` computes it.
///
/// Measured (callgrind, whitted_base 1024x768, 1 thread, images byte-identical): the
/// target's offset was 31.9 M instructions of `shade_group_lanes`; with it skipped the
/// shading stage (`shade_queue` inclusive) went from 738.0 M to 708.5 M and the render
/// phase from 1026.3 M to 996.8 M.
#[inline(always)]
pub fn spawn_ray_to_point(p: V3, p_error: V3, n: V3, q: Vec3, n_q: V3) -> (V3, V3, Packet) {
    let qv = V3::splat(q);
    let o = offset_ray_origin(p, p_error, n, qv.minus(p));
    // Every lane of `n_q` finite where the sum of its coordinates is (a non-finite
    // coordinate makes it infinite or NaN; an overflow only takes the general path).
    // `s - s` is zero exactly where `s` is finite (two compares fewer than
    // `is_finite` on AVX2).
    let sum = n_q.x + n_q.y + n_q.z;
    #[allow(clippy::eq_op)]
    let finite = (sum - sum).simd_eq(Packet::splat(0.0));
    let target = if !q.cmpeq(Vec3::ZERO).any() && finite.to_bitmask() == 0xffff {
        qv
    } else {
        offset_ray_origin(qv, V3::splat(Vec3::ZERO), n_q, p.minus(qv))
    };
    let d = target.minus(o);
    let cos = n_q.dot(d).abs();
    let eps = Packet::splat(SPAWN_TO_ERROR) * (d.x.abs() + d.y.abs() + d.z.abs()) / cos;
    let one = Packet::splat(1.0);
    let tmax = eps.simd_lt(one).select(one - eps, Packet::splat(0.0));
    (o, d, tmax)
}

/// `V3::splat(v).over(d)` (glam's `Vec3 / f32`, per lane): where the three components
/// of `v` have the same bits (a grey light: every point light of the shipped scenes)
/// the three quotients are the same division, done once.
#[inline(always)]
pub fn over_lanes(v: Vec3, d: Packet) -> V3 {
    let [x, y, z] = v.to_array().map(f32::to_bits);
    if x == y && y == z {
        let q = Packet::splat(v.x) / d;
        V3 { x: q, y: q, z: q }
    } else {
        V3::splat(v).over(d)
    }
}

/// `1 / s` where multiplying by it is dividing by `s`, bit for bit, for every `f32`:
/// `s` a power of two whose reciprocal is a normal number (`2^-126 <= s <= 2^126`).
/// Then `x · (1/s)` and `x / s` are the same real number, and IEEE multiplication and
/// division each round that number once, the same way (overflow, underflow and
/// subnormal results included; a NaN stays a NaN).
pub fn exact_reciprocal(s: f32) -> Option<f32> {
    let bits = s.to_bits();
    let exponent = (bits >> 23) & 0xff;
    let power_of_two = bits & 0x807f_ffff == 0;
    // Biased exponents 1..=253: 2^-126 ..= 2^126.
    (power_of_two && (1..=253).contains(&exponent)).then(|| 1.0 / s)
}

/// Shadow rays from the shading points `s` (lanes in `active`) to a point light.
///
/// Tried and not kept (helper shade13, 2026-11-25): the area lights' highlight cut
/// (`dark_below`: skip `pow` where every lit lane's cosine is below 2^(-150/shininess))
/// for point and directional lights. Bit-identical and tested, but on the whitted room
/// the cut (0.59 at shininess 200, 54 degrees off the half vector) rarely holds for a
/// whole lane group: callgrind on an AVX2 build, `shade_group_lanes` inclusive 456.5 M
/// -> 457.1 M instructions at 1024x768 and 401.5 M -> 402.1 M at 320x240 with 3x3
/// samples; CPU time within noise (aa3x3 761 -> 751 ms, load 8-11).
#[inline(always)]
pub fn point_light(
    s: &SurfaceLanes,
    hl: &Highlight,
    position: Vec3,
    intensity: Vec3,
    active: u32,
) -> ShadowLanes {
    let pos = V3::splat(position);
    let to_light = pos.minus(s.p);
    let dist2 = to_light.dot(to_light);
    let wi = to_light.over(dist2.sqrt());
    if lit_lanes(s, wi).to_bitmask() & active == 0 {
        return ShadowLanes::none();
    }
    let (lit, f) = reflectance(s, hl, wi);
    let contribution = over_lanes(intensity, dist2).times(f);
    let (origin, dir, tmax) = spawn_ray_to_point(s.base, s.p_error, s.ng, position, wi.negated());
    ShadowLanes {
        origin,
        dir,
        tmax,
        contribution,
        mask: lit.to_bitmask() & active,
    }
}

/// Shadow rays from the shading points `s` (lanes in `active`) along the unit
/// direction `wi` towards a directional light (`Ray::new`: unbounded).
#[inline(always)]
pub fn directional_light(
    s: &SurfaceLanes,
    hl: &Highlight,
    wi: Vec3,
    irradiance: Vec3,
    active: u32,
) -> ShadowLanes {
    let wi = V3::splat(wi);
    if lit_lanes(s, wi).to_bitmask() & active == 0 {
        return ShadowLanes::none();
    }
    let (lit, f) = reflectance(s, hl, wi);
    ShadowLanes {
        origin: offset_ray_origin(s.base, s.p_error, s.ng, wi),
        dir: wi,
        tmax: Packet::splat(f32::INFINITY),
        contribution: V3::splat(irradiance).times(f),
        mask: lit.to_bitmask() & active,
    }
}

/// A quad light's constants, computed as `Light::sample` computes them.
#[derive(Clone, Copy, Debug)]
pub struct QuadLight {
    pub corner: Vec3,
    pub edge1: Vec3,
    pub edge2: Vec3,
    pub radiance: Vec3,
    pub normal: Vec3,
    pub area: f32,
    pub p_error: Vec3,
}

impl QuadLight {
    pub fn new(corner: Vec3, edge1: Vec3, edge2: Vec3, radiance: Vec3) -> QuadLight {
        let c = edge1.cross(edge2);
        let area = c.length();
        QuadLight {
            corner,
            edge1,
            edge2,
            radiance,
            normal: c / area,
            area,
            p_error: gamma(32) * (corner.abs() + edge1.abs() + edge2.abs()),
        }
    }
}

/// Shadow rays from one shading point (splatted over the lanes of `s`) to the points
/// `(u, v)` of a quad light, lanes in `active`, each contribution divided by
/// `samples` (the light's sample count), as the scalar area-light loop.
#[inline(always)]
pub fn quad_light(
    s: &SurfaceLanes,
    hl: &Highlight,
    q: &QuadLight,
    u: Packet,
    v: Packet,
    samples: f32,
    active: u32,
) -> ShadowLanes {
    let point = V3::splat(q.corner)
        .plus(V3::splat(q.edge1).scale(u))
        .plus(V3::splat(q.edge2).scale(v));
    let light = FlatLight {
        normal: q.normal,
        area: q.area,
        radiance: q.radiance,
        p_error: q.p_error,
    };
    towards_points(s, hl, &light, point, samples, active)
}

/// What a flat area light (a quad or a disk) shares between its samples: its unit
/// normal, area, radiance and the error bound of its sampled points.
#[derive(Clone, Copy, Debug)]
pub struct FlatLight {
    pub normal: Vec3,
    pub area: f32,
    pub radiance: Vec3,
    pub p_error: Vec3,
}

/// Shadow rays from one shading point (splatted over the lanes of `s`) to the sampled
/// points `point` of the flat light `light`, lanes in `active`, each contribution
/// divided by `samples`: the rest of `Light::sample` (`towards`: direction, distance,
/// the light's cosine and `cosθ' A / r²`) and of the scalar area-light loop, bit for
/// bit but for the Blinn-Phong power ([`reflectance`]).
#[inline(always)]
pub fn towards_points(
    s: &SurfaceLanes,
    hl: &Highlight,
    light: &FlatLight,
    point: V3,
    samples: f32,
    active: u32,
) -> ShadowLanes {
    let zero = Packet::splat(0.0);
    let q = light;
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
    let (origin, dir, tmax) = spawn_ray_to(s.base, s.p_error, s.ng, point, V3::splat(q.p_error), n);
    ShadowLanes {
        origin,
        dir,
        tmax,
        contribution,
        mask: (seen & lit).to_bitmask() & active,
    }
}

/// The checkerboard albedo of `Material::albedo_on_surface` per lane, for a surface
/// with outward normal `outward`. Lanes whose cell index is not an exactly represented
/// integer below 2^24 (the parity in f32 would differ from the scalar `as i64`
/// parity) are returned in the second value, a bitmask, for the scalar code to redo.
#[inline(always)]
pub fn checker_albedo(c: &Checker, p: V3, p_error: V3, outward: V3) -> (V3, u32) {
    let inset = Packet::splat(2.0) * outward.abs().dot(p_error)
        + Packet::splat(CHECKER_INSET) * p.abs().x.fast_max(p.abs().y.fast_max(p.abs().z));
    let look = p.minus(outward.scale(inset));
    // A power-of-two cell size (1.0 in the Whitted scenes) by a multiplication:
    // three divisions fewer, the same bits (`exact_reciprocal`).
    let q = match exact_reciprocal(c.scale) {
        Some(r) => look.scale(Packet::splat(r)),
        None => look.over(Packet::splat(c.scale)),
    };
    let q = V3 {
        x: q.x.floor(),
        y: q.y.floor(),
        z: q.z.floor(),
    };
    // The parity of the cell-index sum in integer lanes: the three floors below 2^24
    // convert exactly, their wrapping sum stays below 2^26, and its low bit is the
    // scalar `(x + y + z) as i64` parity (two's complement); the lanes not below 2^24
    // are redone by the caller. Before: each index's parity as `x - 2 floor(x / 2)`,
    // then the sum's parity the same way (four more floors, about eight more operations).
    let (ix, iy, iz) = (
        q.x.fast_round_int(),
        q.y.fast_round_int(),
        q.z.fast_round_int(),
    );
    let odd = ((ix + iy + iz) & i32x16::splat(1)).simd_eq(i32x16::splat(1));
    let odd: Packet = cast(odd);
    let limit = Packet::splat(16_777_216.0);
    let exact = q.x.abs().simd_lt(limit) & q.y.abs().simd_lt(limit) & q.z.abs().simd_lt(limit);
    let albedo = V3::select(odd, V3::splat(c.color_b), V3::splat(c.color_a));
    (albedo, !exact.to_bitmask() & 0xffff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::xorshift64;

    /// Sixteen rows of `K` vectors as `K` lane vectors: `v3(k)` holds row `i`'s `k`-th
    /// vector in lane `i`.
    fn column_lanes<const K: usize>(rows: &[[Vec3; K]]) -> impl Fn(usize) -> V3 {
        let mut lanes = [[[0.0f32; 16]; 3]; K];
        for (i, row) in rows.iter().enumerate() {
            for (k, v) in row.iter().enumerate() {
                (lanes[k][0][i], lanes[k][1][i], lanes[k][2][i]) = (v.x, v.y, v.z);
            }
        }
        move |k| V3::load(&lanes[k][0], &lanes[k][1], &lanes[k][2])
    }

    /// [`exact_reciprocal`] is offered for powers of two only, and where it is, the
    /// product is the quotient bit for bit: random finite values of every exponent,
    /// subnormals, the ends of the range (overflow and underflow), zeros, infinities;
    /// [`over_lanes`] is `V3::over` of the splat, grey or not.
    #[test]
    fn exact_reciprocals_divide_bit_for_bit() {
        let mut next = xorshift64(0x9e37_79b9_7f4a_7c15);
        let mut checked = 0;
        for e in -130i32..=130 {
            let s = 2f32.powi(e);
            let r = exact_reciprocal(s);
            assert_eq!(r.is_some(), (-126..=126).contains(&e), "2^{e}");
            assert_eq!(exact_reciprocal(-s), None, "negative 2^{e}");
            let Some(r) = r else { continue };
            let mut xs: Vec<f32> = (0..400).map(|_| f32::from_bits(next() as u32)).collect();
            xs.extend([0.0, -0.0, f32::MAX, -f32::MAX, f32::MIN_POSITIVE, 1e-45]);
            xs.extend([f32::INFINITY, f32::NEG_INFINITY, 1.0, 3.0]);
            for x in xs.into_iter().filter(|x| !x.is_nan()) {
                assert_eq!((x * r).to_bits(), (x / s).to_bits(), "{x} / 2^{e}");
                checked += 1;
            }
        }
        for s in [0.0f32, 3.0, 0.3, 1.5, f32::INFINITY, f32::NAN, 1e-40] {
            assert_eq!(exact_reciprocal(s), None, "{s}");
        }
        assert!(checked > 90_000);
        let d = Packet::new(std::array::from_fn(|i| 0.1 + i as f32 * 7.3));
        for v in [
            Vec3::splat(124.0),
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(5.0, 5.0, 6.0),
        ] {
            let (a, b) = (over_lanes(v, d), V3::splat(v).over(d));
            for i in 0..16 {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(a.lane(i)), bits(b.lane(i)), "{v} lane {i}");
            }
        }
    }

    /// [`checker_albedo`] is `Material::albedo_on_surface` bit for bit in every lane it
    /// does not hand back: random points of both signs (cells of both parities), cell
    /// sizes a power of two and not, points on cell faces, and cell indices at and past
    /// 2^24 (handed back, and only those).
    #[test]
    fn lane_checker_is_the_scalar_checker() {
        let mut next = xorshift64(0x6a09_e667_f3bc_c908);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
        let (mut colours, mut handed_back) = ([0usize; 2], 0);
        for case in 0..3000 {
            let scale = [1.0f32, 0.3, 2.5, 0.125][case % 4];
            let c = Checker {
                color_a: Vec3::new(0.9, 0.1, 0.2),
                color_b: Vec3::new(0.05, 0.8, 0.3),
                scale,
            };
            let m = crate::scene::Material {
                checker: Some(c),
                ..Default::default()
            };
            let size = [1.0f32, 50.0, 1e4, 2.5e7][case % 4 * 7 % 4];
            let rows: Vec<[Vec3; 3]> = (0..16)
                .map(|i| {
                    let mut p = Vec3::new(unit(), unit(), unit()) * size;
                    if i % 5 == 0 {
                        p.y = (p.y * 4.0).round() * 0.25;
                    }
                    let err = Vec3::new(unit().abs(), unit().abs(), unit().abs()) * 1e-6;
                    let n = Vec3::new(unit(), unit(), unit()).normalize_or(Vec3::Y);
                    [p, err, n]
                })
                .collect();
            let v3 = column_lanes(&rows);
            let (albedo, redo) = checker_albedo(&c, v3(0), v3(1), v3(2));
            for (i, [p, err, n]) in rows.iter().enumerate() {
                let want = m.albedo_on_surface(*p, *err, *n);
                let inset = 2.0 * n.abs().dot(*err) + CHECKER_INSET * p.abs().max_element();
                let q = ((*p - *n * inset) / scale).floor();
                let huge = q.abs().max_element() >= 16_777_216.0;
                assert_eq!(redo >> i & 1 == 1, huge, "case {case} lane {i}: {p} {q}");
                if huge {
                    handed_back += 1;
                    continue;
                }
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(
                    bits(albedo.lane(i)),
                    bits(want),
                    "case {case} lane {i}: {p}"
                );
                colours[(want == c.color_b) as usize] += 1;
            }
        }
        assert!(colours[0] > 5000 && colours[1] > 5000 && handed_back > 500);
    }

    /// [`spawn_ray_to_point`] gives [`spawn_ray_to`]'s origin, direction and extent bit
    /// for bit with a zero target error: random shading points, normals and point
    /// lights (coordinates of every size, lights with `±0.0` coordinates, which take the
    /// general path), and lane groups where `n_q` has an infinite or NaN lane (a
    /// shading point on the light).
    #[test]
    fn spawn_to_a_point_equals_the_general_spawn() {
        let mut next = xorshift64(0x2545_f491_4f6c_dd1d);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
        let (mut groups, mut shortcut) = (0, 0);
        for case in 0..3000 {
            let scale = [1e-3f32, 1.0, 1e3, 1e6][case % 4];
            let mut q = Vec3::new(unit(), unit(), unit()) * scale * 4.0;
            if case % 5 == 0 {
                q.x = 0.0;
            }
            if case % 7 == 0 {
                q.z = -0.0;
            }
            let rows: Vec<[Vec3; 4]> = (0..16)
                .map(|i| {
                    let p = Vec3::new(unit(), unit(), unit()) * scale;
                    let err = Vec3::new(unit().abs(), unit().abs(), unit().abs()) * scale * 1e-6;
                    let n = Vec3::new(unit(), unit(), unit()).normalize_or(Vec3::Y);
                    let mut nq = -(q - p).normalize_or(Vec3::X);
                    if case % 11 == 0 && i == 3 {
                        nq = Vec3::new(f32::INFINITY, f32::NAN, 1.0);
                    }
                    [p, err, n, nq]
                })
                .collect();
            let v3 = column_lanes(&rows);
            let (p, err, n, nq) = (v3(0), v3(1), v3(2), v3(3));
            let (o, d, t) = spawn_ray_to_point(p, err, n, q, nq);
            let (o2, d2, t2) = spawn_ray_to(p, err, n, V3::splat(q), V3::splat(Vec3::ZERO), nq);
            groups += 1;
            shortcut += (q.cmpne(Vec3::ZERO).all() && case % 11 != 0) as usize;
            for i in 0..16 {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(o.lane(i)), bits(o2.lane(i)), "case {case} lane {i}");
                assert_eq!(bits(d.lane(i)), bits(d2.lane(i)), "case {case} lane {i}");
                let (a, b) = (t.to_array()[i], t2.to_array()[i]);
                assert_eq!(a.to_bits(), b.to_bits(), "case {case} lane {i}");
            }
        }
        assert!(groups > shortcut && shortcut > 1000, "{groups} {shortcut}");
    }
}
