//! Surface interactions of triangle and sphere hits over the lanes of a [`Packet`]: the
//! lane form of `integrator::interaction::SurfaceInteraction::new` for hits on static
//! spheres ([`sphere_surfaces`]) and on the static triangle mesh
//! ([`triangle_surfaces`]): for triangles the hit point from the barycentrics with its error
//! bound (pbrt-v4 §6.8.7, `triangle_point`), geometric and interpolated shading
//! normals facing the ray, the side, and on smooth meshes the shadow-ray base point
//! lifted onto the surface the vertex normals describe (Hanika, "Hacking the Shadow
//! Terminator", Ray Tracing Gems II, ch. 4, 2021; `geometry::terminator`).
//!
//! Every lane repeats the scalar code's f32 operations in the same order (glam's `Vec3`
//! is plain `f32` arithmetic; Rust never fuses a multiply and an add; division and
//! square root are correctly rounded in both), and every branch of the scalar code is a
//! lane select on the same condition, so each lane is bit for bit the scalar
//! interaction. The test in `integrator::hit_batch` compares both on the hits of every
//! shipped scene, and the unit test below on degenerate triangles and normals.

use super::lanes3::V3;
use super::{Lanes, Packet};
use crate::geometry::gamma;
use glam::Vec3;

/// Up to 16 hits on triangles of one mesh, gathered by the caller (unused lanes hold
/// anything finite or not: lanes never mix).
#[derive(Clone, Copy, Debug)]
pub struct TriangleHits {
    /// The triangle's corners, as `TriangleMesh::corners`.
    pub corners: [V3; 3],
    /// The mesh's vertex normals at the corners as stored (not normalised); `None` for
    /// a mesh without normals.
    pub normals: Option<[V3; 3]>,
    /// Barycentrics of the hit (weights of corners 1 and 2).
    pub u: Packet,
    pub v: Packet,
    /// Ray direction as traced (not normalised).
    pub dir: V3,
}

/// What [`triangle_surfaces`] and [`sphere_surfaces`] return per lane: the fields of a `SurfaceInteraction`
/// (with `p_shadow` as `base`, `p` where there is none, and the flag `smooth`) and the
/// unit ray direction.
#[derive(Clone, Copy, Debug)]
pub struct Surfaces {
    pub p: V3,
    pub p_error: V3,
    pub ng: V3,
    pub ns: V3,
    pub base: V3,
    /// Mask: the hit has a shadow-terminator base point (all three vertex normals
    /// non-zero).
    pub smooth: Packet,
    /// Mask: the ray hit the side the winding faces (`front_face`).
    pub front: Packet,
    /// `dir.normalize()`.
    pub dir: V3,
}

impl Surfaces {
    /// `mask ? a : b` per lane, every field.
    #[inline(always)]
    pub fn select(mask: Packet, a: &Surfaces, b: &Surfaces) -> Surfaces {
        Surfaces {
            p: V3::select(mask, a.p, b.p),
            p_error: V3::select(mask, a.p_error, b.p_error),
            ng: V3::select(mask, a.ng, b.ng),
            ns: V3::select(mask, a.ns, b.ns),
            base: V3::select(mask, a.base, b.base),
            smooth: mask.select(a.smooth, b.smooth),
            front: mask.select(a.front, b.front),
            dir: V3::select(mask, a.dir, b.dir),
        }
    }
}

/// glam's `Vec3::cross`, lane by lane.
#[inline(always)]
fn cross(a: V3, b: V3) -> V3 {
    V3 {
        x: a.y * b.z - b.y * a.z,
        y: a.z * b.x - b.z * a.x,
        z: a.x * b.y - b.x * a.y,
    }
}

/// Mask: `v == Vec3::ZERO` (every component compares equal to zero, so `-0.0` counts).
#[inline(always)]
fn is_zero(v: V3) -> Packet {
    let zero = Packet::splat(0.0);
    v.x.simd_eq(zero) & v.y.simd_eq(zero) & v.z.simd_eq(zero)
}

/// glam's `Vec3::normalize`: `v * (1 / |v|)`.
#[inline(always)]
fn normalize(v: V3) -> V3 {
    v.scale(Packet::splat(1.0) / v.dot(v).sqrt())
}

/// The surface interactions of the hits `h`, lane `i` bit for bit what
/// `SurfaceInteraction::new` builds for a hit on a static triangle with those corners,
/// normals, barycentrics and ray direction (texture coordinates aside).
#[inline(always)]
pub fn triangle_surfaces(h: &TriangleHits) -> Surfaces {
    let zero = Packet::splat(0.0);
    let one = Packet::splat(1.0);
    let [p0, p1, p2] = h.corners;
    let (u, v) = (h.u, h.v);
    // triangle_point: p = b0 p0 + u p1 + v p2 and its error bound.
    let b0 = one - u - v;
    let (a0, a1, a2) = (p0.scale(b0), p1.scale(u), p2.scale(v));
    let p = a0.plus(a1).plus(a2);
    let sum = a0.abs().plus(a1.abs()).plus(a2.abs());
    let k = Packet::splat(gamma(3)) * (one + u.abs() + v.abs());
    let p_error = sum.scale(Packet::splat(gamma(7))).plus(p0.abs().scale(k));
    // TriangleMesh::geometric_normal.
    let ng0 = cross(p1.minus(p0), p2.minus(p0)).normalize_or_zero();
    let dir = normalize(h.dir);
    // TriangleMesh::shading_normal (the geometric normal where the interpolated one is
    // zero or there are none) and TriangleMesh::vertex_normals.
    let (ns0, vertex) = match h.normals {
        None => (ng0, None),
        Some([n0, n1, n2]) => {
            let s = n0
                .scale(b0)
                .plus(n1.scale(u))
                .plus(n2.scale(v))
                .normalize_or_zero();
            let unit = [n0, n1, n2].map(V3::normalize_or_zero);
            let smooth = !(is_zero(unit[0]) | is_zero(unit[1]) | is_zero(unit[2]));
            (V3::select(is_zero(s), ng0, s), Some((unit, smooth)))
        }
    };
    // A degenerate triangle faces the ray; then both normals face the incident side.
    let ng1 = V3::select(is_zero(ng0), dir.negated(), ng0);
    let front = h.dir.dot(ng1).simd_lt(zero);
    let ng = V3::select(front, ng1, ng1.negated());
    let flip = ns0.dot(ng).simd_lt(zero);
    let ns = V3::select(flip, ns0.negated(), ns0);
    let (base, smooth) = match vertex {
        None => (p, zero),
        Some((unit, smooth)) => {
            // shadow_terminator_point with the (flipped) unit vertex normals.
            let bary = [b0, u, v];
            let mut lift = V3::splat(Vec3::ZERO);
            for i in 0..3 {
                let n = V3::select(flip, unit[i].negated(), unit[i]);
                // f32::min(x, 0) is 0 for a NaN x; minps(x, 0) returns its second
                // operand then. (The sign of a zero depth cannot reach `lift`, which
                // starts at +0 and so never becomes -0.)
                let depth = p.minus(h.corners[i]).dot(n).minps(zero);
                lift = lift.minus(n.scale(bary[i] * depth));
            }
            let q = p.plus(lift);
            let finite = q.x.is_finite() & q.y.is_finite() & q.z.is_finite();
            let above = q.minus(p).dot(ng).simd_gt(zero);
            (V3::select(smooth & finite & above, q, p), smooth)
        }
    };
    Surfaces {
        p,
        p_error,
        ng,
        ns,
        base,
        smooth,
        front,
        dir,
    }
}

/// Up to 16 hits on static spheres, gathered by the caller (unused lanes hold anything:
/// lanes never mix).
#[derive(Clone, Copy, Debug)]
pub struct SphereHits {
    pub center: V3,
    pub radius: Packet,
    /// The ray as traced: origin, direction (not normalised) and hit distance.
    pub origin: V3,
    pub dir: V3,
    pub t: Packet,
}

/// The surface interactions of the sphere hits `h`, lane `i` bit for bit what
/// `SurfaceInteraction::new` builds for a hit on a static sphere (texture coordinates
/// aside): `ray.at(t)` reprojected onto the sphere with its error bound
/// (`geometry::sphere_point`, pbrt-v4 §6.8.5), both normals the outward normal turned
/// to face the ray (a hit at the centre faces the ray), no shadow-ray base point.
#[inline(always)]
pub fn sphere_surfaces(h: &SphereHits) -> Surfaces {
    let zero = Packet::splat(0.0);
    // Ray::at: origin + t * dir.
    let near = h.origin.plus(h.dir.scale(h.t));
    // sphere_point.
    let n = near.minus(h.center).normalize_or_zero();
    let local = n.scale(h.radius);
    let p = h.center.plus(local);
    let p_error = local
        .abs()
        .scale(Packet::splat(gamma(5)))
        .plus(p.abs().scale(Packet::splat(gamma(2))));
    let dir = normalize(h.dir);
    let ng1 = V3::select(is_zero(n), dir.negated(), n);
    let front = h.dir.dot(ng1).simd_lt(zero);
    let ng = V3::select(front, ng1, ng1.negated());
    // The shading normal is the outward one, flipped to the facing side as `ng` was
    // (where `n` is zero, `ns = n = 0` stays zero: `0·ng < 0` is false).
    let flip = n.dot(ng).simd_lt(zero);
    let ns = V3::select(flip, n.negated(), n);
    Surfaces {
        p,
        p_error,
        ng,
        ns,
        base: p,
        smooth: zero,
        front,
        dir,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::terminator::shadow_terminator_point;
    use crate::geometry::triangle_point;
    use crate::integrator::sampling::PixelRng;

    /// The scalar rule of `SurfaceInteraction::new` for a static triangle, written out
    /// with the mesh's own formulas (corners, raw vertex normals), as the oracle.
    #[allow(clippy::type_complexity)]
    fn scalar(
        c: [Vec3; 3],
        normals: Option<[Vec3; 3]>,
        u: f32,
        v: f32,
        dir: Vec3,
    ) -> (Vec3, Vec3, Vec3, Vec3, Option<Vec3>, bool, Vec3) {
        let (p, p_error) = triangle_point(c, u, v);
        let geometric = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
        let (ns, smooth) = match normals {
            None => (geometric, None),
            Some(n) => {
                let s = ((1.0 - u - v) * n[0] + u * n[1] + v * n[2]).normalize_or_zero();
                let unit = n.map(Vec3::normalize_or_zero);
                (
                    if s == Vec3::ZERO { geometric } else { s },
                    unit.iter().all(|n| *n != Vec3::ZERO).then_some(unit),
                )
            }
        };
        let ng = if geometric == Vec3::ZERO {
            -dir.normalize()
        } else {
            geometric
        };
        let front = dir.dot(ng) < 0.0;
        let ng = if front { ng } else { -ng };
        let flip = ns.dot(ng) < 0.0;
        let ns = if flip { -ns } else { ns };
        let p_shadow = smooth.map(|n| {
            let n = if flip { n.map(|n| -n) } else { n };
            shadow_terminator_point(p, c, n, [1.0 - u - v, u, v], ng)
        });
        (p, p_error, ng, ns, p_shadow, front, dir.normalize())
    }

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Random triangles (some degenerate: a repeated corner, collinear corners) with
    /// random vertex normals (some zero, some opposing, some pointing inwards) hit at
    /// random barycentrics from random directions: every lane equals the scalar rule
    /// bit for bit, and the special cases were met (a degenerate triangle facing the
    /// ray, a zero vertex normal, a lifted base point, a back face).
    #[test]
    fn lane_interactions_equal_the_scalar_rule_bit_for_bit() {
        let mut rng = PixelRng::new(3, 9);
        let mut r = |s: f32| (2.0 * rng.next_f32() - 1.0) * s;
        let (mut degenerate, mut rough, mut lifted, mut back) = (0, 0, 0, 0);
        for round in 0..400 {
            let with_normals = round % 4 != 0;
            let mut lanes = [[[0.0f32; 16]; 3]; 3];
            let mut nl = [[[0.0f32; 16]; 3]; 3];
            let (mut ul, mut vl, mut dl) = ([0.0f32; 16], [0.0f32; 16], [[0.0f32; 16]; 3]);
            let mut want = Vec::new();
            for l in 0..16 {
                let mut c: [Vec3; 3] =
                    std::array::from_fn(|_| Vec3::new(r(4.0), r(4.0), r(4.0) + 1.0));
                match l % 8 {
                    0 => c[2] = c[1],
                    1 => c[2] = c[0] + 2.0 * (c[1] - c[0]),
                    _ => {}
                }
                let face = (c[1] - c[0]).cross(c[2] - c[0]);
                let mut n: [Vec3; 3] = std::array::from_fn(|_| {
                    face.normalize_or_zero() * r(3.0) + Vec3::new(r(0.6), r(0.6), r(0.6))
                });
                match l % 5 {
                    0 => n[1] = Vec3::ZERO,
                    1 => n = [-face, -face, -face],
                    2 => n = [n[0], -n[0], Vec3::ZERO],
                    _ => {}
                }
                let (u, v) = {
                    let (a, b) = (r(0.5) + 0.5, r(0.5) + 0.5);
                    if a + b > 1.0 {
                        (1.0 - a, 1.0 - b)
                    } else {
                        (a, b)
                    }
                };
                let dir = Vec3::new(r(2.0), r(2.0), r(2.0)) * (1.0 + 10.0 * r(1.0).abs());
                for k in 0..3 {
                    for a in 0..3 {
                        lanes[k][a][l] = c[k][a];
                        nl[k][a][l] = n[k][a];
                    }
                    dl[k][l] = dir[k];
                }
                (ul[l], vl[l]) = (u, v);
                want.push(scalar(c, with_normals.then_some(n), u, v, dir));
            }
            let v3 = |a: &[[f32; 16]; 3]| V3::load(&a[0], &a[1], &a[2]);
            let h = TriangleHits {
                corners: lanes.each_ref().map(v3),
                normals: with_normals.then(|| nl.each_ref().map(v3)),
                u: Packet::new(ul),
                v: Packet::new(vl),
                dir: v3(&dl),
            };
            let got = triangle_surfaces(&h);
            let (smooth, front) = (got.smooth.bitmask(), got.front.bitmask());
            for (l, w) in want.iter().enumerate() {
                let (p, p_error, ng, ns, p_shadow, is_front, dir) = *w;
                let at = |x: &V3| bits(x.lane(l));
                assert_eq!(at(&got.p), bits(p), "round {round} lane {l}: p");
                assert_eq!(at(&got.p_error), bits(p_error), "round {round} lane {l}");
                assert_eq!(at(&got.ng), bits(ng), "round {round} lane {l}: ng");
                assert_eq!(at(&got.ns), bits(ns), "round {round} lane {l}: ns");
                assert_eq!(at(&got.dir), bits(dir), "round {round} lane {l}: dir");
                assert_eq!(front >> l & 1 == 1, is_front, "round {round} lane {l}");
                assert_eq!(
                    smooth >> l & 1 == 1,
                    p_shadow.is_some(),
                    "round {round} {l}"
                );
                assert_eq!(
                    at(&got.base),
                    bits(p_shadow.unwrap_or(p)),
                    "round {round} {l}"
                );
                degenerate += (ng == -dir) as u32;
                rough += (with_normals && p_shadow.is_none()) as u32;
                lifted += p_shadow.is_some_and(|q| q != p) as u32;
                back += !is_front as u32;
            }
        }
        assert!(
            degenerate > 0 && rough > 0 && lifted > 0 && back > 0,
            "{degenerate} degenerate, {rough} without a base point, {lifted} lifted, {back} back"
        );
    }
}
