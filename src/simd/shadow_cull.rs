//! Culls for the shadow rays of a lane group of shading points towards one point or
//! directional light in a tiny scene (`integrator::point_shadow`): which lanes cannot
//! meet a triangle whose plane is axis-aligned ([`AxisPlane`]), and which spheres no
//! segment of the group can come near ([`origin_ball`], [`sphere_clear`]). Each says
//! "no hit" only where the lane kernels (`TinyGroup::triangle_blocks`, `sphere_lanes`)
//! find none, so skipping them leaves every lane's answer unchanged.

use super::lanes3::V3;
use super::{Lanes, Packet};
use glam::Vec3;

/// A triangle whose three corners share one coordinate exactly (`x_axis = at`): the
/// Whitted floor. A ray with `o_axis >= at` and `d_axis > 0` (or `o_axis <= at` and
/// `d_axis < 0`) crosses that plane at `t* = (at - o_axis) / d_axis <= 0`, exactly, in
/// real arithmetic on the ray's f32 fields; the watertight test accepts only `t > δt`
/// (its conservative error bound; see `simd::tiny::TrianglePlane`, which makes the same
/// argument for an f64-decided side), so it reports no hit for such a ray. The side
/// and the direction's sign are f32 comparisons, exact: no margin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisPlane {
    pub axis: usize,
    pub at: f32,
}

impl AxisPlane {
    /// `Some` where the corners share a finite coordinate.
    pub fn of(c: &[Vec3; 3]) -> Option<AxisPlane> {
        (0..3)
            .find(|&k| c[0][k].is_finite() && c[0][k] == c[1][k] && c[1][k] == c[2][k])
            .map(|axis| AxisPlane {
                axis,
                at: c[0][axis],
            })
    }

    /// The lanes of `live` (origins `o`, directions `d`) that leave the plane from the
    /// side their origin lies on (or from the plane itself): they cannot hit the
    /// triangle. NaN fails every comparison and is kept.
    #[inline(always)]
    pub fn leaving(&self, o: &V3, d: &V3, live: u32) -> u32 {
        let pick = |v: &V3| match self.axis {
            0 => v.x,
            1 => v.y,
            _ => v.z,
        };
        let (o, d) = (pick(o), pick(d));
        let (at, zero) = (Packet::splat(self.at), Packet::splat(0.0));
        let up = d.simd_gt(zero) & o.simd_ge(at);
        let down = d.simd_lt(zero) & o.simd_le(at);
        (up | down).to_bitmask() & live
    }
}

/// `(g, rho)`: the centre of the bounding box of the origins of the lanes in `live`
/// (not empty, finite origins: the valid rays) and its half diagonal, so that every such origin lies within `rho` of
/// `g` (rounding aside: `sphere_clear`'s margin covers it).
#[inline(always)]
pub fn origin_ball(o: &V3, live: u32) -> (Vec3, f32) {
    let first = live.trailing_zeros() as usize & 15;
    let fill = <Packet as Lanes>::mask_from_bits(live);
    let v = o.lane(first);
    let (x, y, z) = (
        fill.select(o.x, Packet::splat(v.x)),
        fill.select(o.y, Packet::splat(v.y)),
        fill.select(o.z, Packet::splat(v.z)),
    );
    let range = |p: Packet| {
        let a = p.to_array();
        a.iter()
            .fold((a[0], a[0]), |(lo, hi), &v| (lo.min(v), hi.max(v)))
    };
    let ((lx, hx), (ly, hy), (lz, hz)) = (range(x), range(y), range(z));
    let (lo, hi) = (Vec3::new(lx, ly, lz), Vec3::new(hx, hy, hz));
    ((lo + hi) * 0.5, (hi - lo).length() * 0.5)
}

/// Whether the sphere `(center, radius)` is clear of every shadow segment of a group
/// whose origins lie within `rho` of `g` and which all end at `light` (`spawn_ray_to`
/// towards a point light: the target is the light's position, unoffset).
///
/// The segments lie in the convex hull of the origins and `light`, and a hull point
/// `light + s (o - light)` is within `s rho <= rho` of `light + s (g - light)`: so every
/// segment point is at least `dist(center, [light, g]) - rho` from the centre. Clear
/// when that exceeds `radius + m`, `m = 1e-2 sqrt(radius S) + 1e-4 S`, `S` a bound on
/// every length involved (`|center - light| + |g - light| + rho + radius` plus the
/// coordinates' magnitudes).
///
/// Why `m` suffices (first order, u = 2^-24): the distance, the ball and the ray's
/// rounded direction (`d = fl(light - o)`, the ray ends within `u |d|` per component of
/// the exact segment) are off by a few `u S`, far below `1e-4 S`. The lane sphere test
/// then finds a root on a segment only where its computed roots move a point of the
/// sphere by more than the margin: the roots are `b/a ± sqrt(r² - |l|²)/|d|` along the
/// ray, `b/a` carries a few `u S`, and the discriminant's `r² - |l|²` at most about
/// `16 u r S` (`l` is `f` minus its projection, `|f| <= S`), whose square root,
/// `4 sqrt(u r S)` ≈ `1e-3 sqrt(r S)` at a near tangent, is a tenth of the first term
/// of `m`.
pub fn sphere_clear(light: Vec3, g: Vec3, rho: f32, center: Vec3, radius: f32) -> bool {
    let w = g - light;
    let v = center - light;
    let ww = w.dot(w);
    let s = if ww > 0.0 {
        (v.dot(w) / ww).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let dist = (v - w * s).length();
    let big = light.abs().max_element() + center.abs().max_element() + g.abs().max_element();
    let scale = v.length() + ww.sqrt() + rho + radius + big;
    let m = 1e-2 * (radius * scale).sqrt() + 1e-4 * scale;
    // NaN anywhere: not clear.
    m.is_finite() && dist > radius + rho + m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{RayQuery, intersect_sphere, intersect_triangle, spawn_ray_to};
    use crate::test_rng::xorshift64;

    /// Where [`sphere_clear`] says a sphere is clear of a group's segments, the scalar
    /// sphere test ([`intersect_sphere`], which the lane test repeats bit for bit)
    /// finds no root on any of them: groups of 16 origins in a small patch (on a floor,
    /// offset as the renderer offsets them), a random point light, random spheres, a
    /// third of them placed to graze the segment from the patch's centre to the light
    /// (near-tangent rays, where the roots are least accurate).
    #[test]
    fn spheres_clear_of_a_group_meet_none_of_its_segments() {
        let mut next = xorshift64(0x51_7cc1_b727_220a);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut clear, mut cases, mut grazing) = (0, 0, 0);
        for case in 0..6000 {
            let light = Vec3::new(unit() - 0.5, 0.5 + unit(), unit() - 0.5) * 20.0;
            let g0 = Vec3::new(unit() - 0.5, 0.0, unit() - 0.5) * 16.0;
            let spread = 0.02 + unit() * 0.5;
            let origins: Vec<Vec3> = (0..16)
                .map(|_| g0 + Vec3::new(unit() - 0.5, 0.0, unit() - 0.5) * spread)
                .collect();
            let radius = 0.05 + unit() * 1.5;
            let center = if case % 3 == 0 {
                // Tangent to the central segment, pushed out by a little.
                let s = unit();
                let axis = (light - g0).normalize();
                let side = axis.cross(Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5));
                let side = side.normalize_or_zero();
                let out = radius + spread + unit() * 0.3;
                g0 + (light - g0) * s + side * out
            } else {
                Vec3::new(unit() - 0.5, unit(), unit() - 0.5) * 12.0
            };
            let lanes = V3 {
                x: Packet::new(
                    origins
                        .iter()
                        .map(|o| o.x)
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap(),
                ),
                y: Packet::new(
                    origins
                        .iter()
                        .map(|o| o.y)
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap(),
                ),
                z: Packet::new(
                    origins
                        .iter()
                        .map(|o| o.z)
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap(),
                ),
            };
            let live = if case % 2 == 0 { 0xffff } else { 0x0ff0 };
            let (g, rho) = origin_ball(&lanes, live);
            cases += 1;
            if !sphere_clear(light, g, rho, center, radius) {
                continue;
            }
            clear += 1;
            grazing += (case % 3 == 0) as usize;
            for (i, &p) in origins.iter().enumerate() {
                if live >> i & 1 == 0 {
                    continue;
                }
                let p_error = Vec3::new(1e-6, 0.0, 1e-6);
                let ray = spawn_ray_to(p, p_error, Vec3::Y, light, Vec3::ZERO, Vec3::Y);
                let query = RayQuery::new(&ray).expect("a valid segment");
                assert!(
                    intersect_sphere(&query, center, radius, ray.tmax).is_none(),
                    "{ray:?} meets the sphere {center} {radius} said clear"
                );
            }
        }
        eprintln!("{clear} of {cases} spheres clear of their group, {grazing} grazing");
        assert!(clear > 1000 && clear < cases && grazing > 300);
    }

    /// Every lane [`AxisPlane::leaving`] lets skip a triangle is a miss of the scalar
    /// test ([`intersect_triangle`], the lane test's oracle and fallback): segments
    /// from points on an axis-aligned floor (origins exactly on its plane), from points
    /// above and below it, towards targets on both sides, on the floor at y = 0 and on
    /// a wall at x = 2.5.
    #[test]
    fn axis_plane_culled_lanes_are_misses_of_the_scalar_test() {
        let mut next = xorshift64(0x2b99_2ddf_a232_49d6);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let triangles = [
            [
                Vec3::new(-4.0, 0.0, -4.0),
                Vec3::new(-4.0, 0.0, 4.0),
                Vec3::new(4.0, 0.0, -4.0),
            ],
            [
                Vec3::new(2.5, -1.0, -3.0),
                Vec3::new(2.5, 3.0, 0.5),
                Vec3::new(2.5, -2.0, 3.0),
            ],
        ];
        assert_eq!(
            AxisPlane::of(&[Vec3::ZERO, Vec3::X, Vec3::Y]),
            Some(AxisPlane { axis: 2, at: 0.0 })
        );
        assert_eq!(AxisPlane::of(&[Vec3::ZERO, Vec3::X, Vec3::ONE]), None);
        let (mut culled, mut on_plane, mut lanes) = (0, 0, 0);
        for c in &triangles {
            let plane = AxisPlane::of(c).expect("axis-aligned");
            let k = plane.axis;
            let mut n = Vec3::ZERO;
            n[k] = 1.0;
            for i in 0..6000 {
                let (u, v) = (unit(), unit());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let p = c[0] + (c[1] - c[0]) * u + (c[2] - c[0]) * v;
                let mut p = p;
                p[k] = plane.at;
                let target = p
                    + n * (unit() - 0.5) * 8.0
                    + Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * 6.0;
                let ray = if i % 2 == 0 {
                    spawn_ray_to(p, Vec3::ZERO, n, target, Vec3::ZERO, -n)
                } else {
                    let o = p + n * (unit() - 0.5) * 0.1;
                    crate::geometry::Ray::segment(o, target - o, 0.0, 1.0)
                };
                on_plane += (ray.origin[k] == plane.at) as usize;
                let o = V3::splat(ray.origin);
                let d = V3::splat(ray.dir);
                lanes += 1;
                if plane.leaving(&o, &d, 1) == 1 {
                    culled += 1;
                    let q = RayQuery::new(&ray).expect("a valid segment");
                    assert!(
                        intersect_triangle(&q, c[0], c[1], c[2], ray.tmax).is_none(),
                        "{ray:?} skipped {c:?} but hits it"
                    );
                }
            }
        }
        eprintln!("{culled} of {lanes} lanes skipped, {on_plane} origins on a plane");
        assert!(culled > 4_000 && culled < lanes && on_plane > 2_000);
    }
}
