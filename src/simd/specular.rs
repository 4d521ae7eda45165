//! Child-ray directions of specular surfaces over the lanes of a [`Packet`]: mirror
//! reflection kept on the incident side of the true surface ([`reflection_dir`]), and
//! Snell refraction with Schlick's Fresnel approximation and total internal reflection
//! at a dielectric ([`dielectric`], [`glass`]): the lane form of
//! `integrator::optics` as `integrator::shader::Shader::emit_children` uses it.
//!
//! Every lane repeats the scalar f32 operations in the same order (glam's `Vec3` is
//! plain `f32` arithmetic, `powi(2)` and `powi(5)` are the products `x·x` and
//! `x·((x·x)·(x·x))` that LLVM's expansion and compiler-rt's `__powisf2` both compute,
//! `f32::clamp` passes a NaN through as the selects below do), and every branch is a
//! lane select on the same condition, so each lane is bit for bit the scalar result.
//! The test below compares both on random directions and normals, including grazing
//! angles, total internal reflection and index-matched media; the shading stage's
//! test compares the child rays both paths queue on every shipped scene.

use super::Packet;
use super::lanes3::V3;

/// `optics::reflect`: `d - 2 (d·n) n`.
#[inline(always)]
pub fn reflect(d: V3, n: V3) -> V3 {
    d.minus(n.scale(Packet::splat(2.0) * d.dot(n)))
}

/// The mirror direction of the unit direction `d` about the shading normal `ns`, or
/// about the geometric normal `ng` where the first would not leave on the incident side
/// of the true surface (`optics::scatter_dir`).
#[inline(always)]
pub fn reflection_dir(d: V3, ns: V3, ng: V3) -> V3 {
    let mirror = reflect(d, ns);
    let leaves = mirror.dot(ng).simd_gt(Packet::splat(0.0));
    V3::select(leaves, mirror, reflect(d, ng))
}

/// What [`dielectric`] returns per lane (`optics::DielectricScatter`).
#[derive(Clone, Copy, Debug)]
pub struct DielectricLanes {
    /// Fresnel reflectance; 1 under total internal reflection.
    pub reflectance: Packet,
    /// Unit refracted direction where `tir` is clear.
    pub refracted: V3,
    /// Mask: total internal reflection (no refracted ray).
    pub tir: Packet,
}

/// glam's `Vec3::normalize`: `v * (1 / |v|)`.
#[inline(always)]
fn normalize(v: V3) -> V3 {
    v.scale(Packet::splat(1.0) / v.dot(v).sqrt())
}

/// `f32::clamp(x, lo, hi)`: a NaN stays NaN.
#[inline(always)]
fn clamp(x: Packet, lo: f32, hi: f32) -> Packet {
    let (lo, hi) = (Packet::splat(lo), Packet::splat(hi));
    let x = x.simd_lt(lo).select(lo, x);
    x.simd_gt(hi).select(hi, x)
}

/// `optics::dielectric` per lane: unit incident direction `d`, unit normal `n` on the
/// incident side, refractive indices `eta_i` (incident) and `eta_t` (transmitted).
#[inline(always)]
pub fn dielectric(d: V3, n: V3, eta_i: Packet, eta_t: Packet) -> DielectricLanes {
    let eta = eta_i / eta_t;
    let a = (eta_i - eta_t) / (eta_i + eta_t);
    dielectric_with(d, n, eta_i, eta_t, eta, a)
}

/// [`dielectric`] given its two quotients, `eta = eta_i / eta_t` and
/// `a = (eta_i - eta_t) / (eta_i + eta_t)`, each computed as written there.
#[inline(always)]
fn dielectric_with(
    d: V3,
    n: V3,
    eta_i: Packet,
    eta_t: Packet,
    eta: Packet,
    a: Packet,
) -> DielectricLanes {
    let (zero, one) = (Packet::splat(0.0), Packet::splat(1.0));
    let cos_i = clamp(-d.dot(n), 0.0, 1.0);
    let sin2_t = eta * eta * (one - cos_i * cos_i);
    let tir = sin2_t.simd_gt(one);
    let cos_t = (one - sin2_t).sqrt();
    let refracted = normalize(d.scale(eta).plus(n.scale(eta * cos_i - cos_t)));
    let r0 = a * a;
    let cos = eta_i.simd_gt(eta_t).select(cos_t, cos_i);
    let x = one - cos;
    let x2 = x * x;
    let x5 = x * (x2 * x2);
    let reflectance = clamp(r0 + (one - r0) * x5, 0.0, 1.0);
    // Index-matched media: no interface, the ray goes straight on.
    let matched = eta_i.simd_eq(eta_t);
    DielectricLanes {
        reflectance: matched.select(zero, tir.select(one, reflectance)),
        refracted: V3::select(matched, d, refracted),
        tir: tir & !matched,
    }
}

/// The glass interface of `Shader::emit_children`: indices `(1, ior)` entering (the
/// ray hit the outside, `front`), `(ior, 1)` leaving; the shading normal `ns` first,
/// and the geometric normal `ng` where the refracted ray would leave on the incident
/// side of the true surface.
///
/// The indices take two values, so `dielectric`'s two quotients do too: each is
/// divided once in f32 (the same operation on the same operands, so the same bits as
/// every lane's division) and selected per lane. Measured before (perf, whitted_aa3x3
/// and whitted_blur16, 1 thread): `dielectric` was 3 % of `shade_group_lanes`' samples,
/// with four lane divisions (two here, one square root and division in `normalize`).
#[inline(always)]
pub fn glass(d: V3, ns: V3, ng: V3, front: Packet, ior: f32) -> DielectricLanes {
    let quotients = |eta_i: f32, eta_t: f32| (eta_i / eta_t, (eta_i - eta_t) / (eta_i + eta_t));
    let (entering, leaving) = (quotients(1.0, ior), quotients(ior, 1.0));
    let (one, ior) = (Packet::splat(1.0), Packet::splat(ior));
    let (eta_i, eta_t) = (front.select(one, ior), front.select(ior, one));
    let pick = |e: f32, l: f32| front.select(Packet::splat(e), Packet::splat(l));
    let eta = pick(entering.0, leaving.0);
    let a = pick(entering.1, leaving.1);
    let s = dielectric_with(d, ns, eta_i, eta_t, eta, a);
    let redo = !s.tir & s.refracted.dot(ng).simd_ge(Packet::splat(0.0));
    if redo.to_bitmask() == 0 {
        return s;
    }
    let g = dielectric_with(d, ng, eta_i, eta_t, eta, a);
    DielectricLanes {
        reflectance: redo.select(g.reflectance, s.reflectance),
        refracted: V3::select(redo, g.refracted, s.refracted),
        tir: redo.select(g.tir, s.tir),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::optics;
    use crate::integrator::sampling::PixelRng;
    use glam::Vec3;

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    fn v3(vs: &[Vec3]) -> V3 {
        let c = |k: usize| std::array::from_fn::<f32, 16, _>(|i| vs[i][k]);
        V3 {
            x: Packet::new(c(0)),
            y: Packet::new(c(1)),
            z: Packet::new(c(2)),
        }
    }

    /// Random unit directions against random normals (a shading normal tilted off the
    /// geometric one, on either side of the surface), entering and leaving glass of
    /// several indices, index-matched media (`ior = 1`) and grazing angles: every lane's
    /// reflection direction, reflectance, refracted direction and TIR flag equal the
    /// scalar optics bit for bit, and the cases were met (TIR, the geometric-normal
    /// redo, the geometric reflection fallback, index matching).
    #[test]
    fn lane_optics_equal_the_scalar_optics_bit_for_bit() {
        let mut rng = PixelRng::new(7, 11);
        let mut r = || 2.0 * rng.next_f32() - 1.0;
        let (mut tir, mut redo, mut fallback, mut matched) = (0, 0, 0, 0);
        for round in 0..2000 {
            let ior = [1.5, 1.33, 2.4, 1.0, 1.05][round % 5];
            let mut d = [Vec3::ZERO; 16];
            let mut ng = [Vec3::ZERO; 16];
            let mut ns = [Vec3::ZERO; 16];
            let mut front = [0.0f32; 16];
            for l in 0..16 {
                let g = Vec3::new(r(), r(), r()).normalize_or(Vec3::Y);
                let mut dir = Vec3::new(r(), r(), r()).normalize_or(-Vec3::Y);
                if dir.dot(g) > 0.0 {
                    dir = -dir;
                }
                if l % 4 == 0 {
                    // Grazing: almost in the surface's plane.
                    dir = (dir - dir.dot(g) * g * 0.999_9).normalize_or(-g);
                }
                let tilt = [0.0, 0.05, 0.4, 1.2][l % 4];
                let s = (g + tilt * Vec3::new(r(), r(), r())).normalize_or(g);
                let s = if s.dot(g) < 0.0 { -s } else { s };
                (d[l], ng[l], ns[l]) = (dir, g, s);
                front[l] = if r() < 0.0 {
                    f32::from_bits(u32::MAX)
                } else {
                    0.0
                };
            }
            let (dl, nsl, ngl) = (v3(&d), v3(&ns), v3(&ng));
            let fl = Packet::new(front);
            let refl = reflection_dir(dl, nsl, ngl);
            let glass_lanes = glass(dl, nsl, ngl, fl, ior);
            let (tir_bits, reflectance) = (
                glass_lanes.tir.to_bitmask(),
                glass_lanes.reflectance.to_array(),
            );
            for l in 0..16 {
                let (d, ns, ng) = (d[l], ns[l], ng[l]);
                let want =
                    optics::scatter_dir(optics::reflect(d, ns), ng, || optics::reflect(d, ng));
                assert_eq!(bits(refl.lane(l)), bits(want), "round {round} lane {l}");
                fallback += (optics::reflect(d, ns).dot(ng) <= 0.0) as u32;
                let (eta_i, eta_t) = if front[l].to_bits() != 0 {
                    (1.0, ior)
                } else {
                    (ior, 1.0)
                };
                let mut s = optics::dielectric(d, ns, eta_i, eta_t);
                if s.refracted.is_some_and(|t| t.dot(ng) >= 0.0) {
                    s = optics::dielectric(d, ng, eta_i, eta_t);
                    redo += 1;
                }
                let at = format!("round {round} lane {l}: ior {ior} d {d} ns {ns} ng {ng}");
                assert_eq!(
                    reflectance[l].to_bits(),
                    s.reflectance.to_bits(),
                    "{at}: reflectance {} against {}",
                    reflectance[l],
                    s.reflectance
                );
                assert_eq!(tir_bits >> l & 1 == 1, s.refracted.is_none(), "{at}: TIR");
                if let Some(t) = s.refracted {
                    assert_eq!(bits(glass_lanes.refracted.lane(l)), bits(t), "{at}");
                }
                tir += s.refracted.is_none() as u32;
                matched += (eta_i == eta_t) as u32;
            }
        }
        assert!(
            tir > 100 && redo > 50 && fallback > 100 && matched > 100,
            "{tir} TIR, {redo} redone with the geometric normal, {fallback} geometric \
             reflections, {matched} index-matched"
        );
    }
}
