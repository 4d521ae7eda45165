//! Culls for the shadow rays of a lane group of shading points towards one point or
//! directional light in a tiny scene (`integrator::point_shadow`): which lanes cannot
//! meet a triangle whose plane is axis-aligned ([`AxisPlane`]), and which spheres no
//! segment of the group can come near ([`origin_ball`], [`sphere_clear`], with the
//! derived bound of `sphere_clearance`). Each says
//! "no hit" only where the lane kernels (`TinyGroup::triangle_blocks`, `sphere_lanes`)
//! find none, so skipping them leaves every lane's answer unchanged.

use super::lanes3::V3;
use super::sphere_clearance::{F64_SLACK, clearance};
use super::{Lanes, Packet};
use glam::{DVec3, Vec3};
use wide::f32x4;

/// `u = 2^-24`, the f32 unit roundoff.
const U: f64 = 1.0 / (1u64 << 24) as f64;

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
        self.leaving_on_axis(pick(o), pick(d), live)
    }

    /// [`leaving`](Self::leaving) on lanes held as component arrays (`RayLanes`' `o`
    /// and `d`), the plane's axis read in place: the same comparisons.
    ///
    /// Why: `TinyGroup::closest` built two `V3`s from its group's arrays to call
    /// `leaving`, a copy of six lane values to the stack in 32-byte halves that the
    /// axis' 64-byte load then read back without store forwarding: that load held
    /// about 5 % of the function's samples (perf annotate, whitted_blur16, 1 thread,
    /// AVX-512).
    #[inline(always)]
    pub fn leaving_lanes(&self, o: &[Packet; 3], d: &[Packet; 3], live: u32) -> u32 {
        let axis = self.axis.min(2);
        self.leaving_on_axis(o[axis], d[axis], live)
    }

    /// The lanes of `live` whose origin coordinate `o` and direction coordinate `d`
    /// (on the plane's axis) leave the plane from the origin's side.
    #[inline(always)]
    fn leaving_on_axis(&self, o: Packet, d: Packet, live: u32) -> u32 {
        let (at, zero) = (Packet::splat(self.at), Packet::splat(0.0));
        let up = d.simd_gt(zero) & o.simd_ge(at);
        let down = d.simd_lt(zero) & o.simd_le(at);
        (up | down).to_bitmask() & live
    }
}

/// `(g, rho)`: the centre of the bounding box of the origins of the lanes in `live`
/// (not empty, finite origins: the valid rays) and its half diagonal, in f64, so that
/// every such origin lies within `rho` of `g` (the midpoint of two f32 values is exact
/// in f64; `rho` carries a few f64 roundings, which `sphere_clear`'s slack covers).
///
/// The box comes from lane minima and maxima (the lanes outside `live` replaced by
/// `+inf` and `-inf`), folded four lanes wide then to one. On finite values `minps`/`maxps`
/// pick the least and greatest lane whatever the order; of `-0.0` and `+0.0` either may
/// come out, which moves no bound (the box, and every distance `sphere_clear` takes
/// from it, are the same).
///
/// Before: a scalar `f32::min`/`f32::max` fold over the sixteen lanes (NaN checks on
/// every step) with the lanes outside `live` filled from the first live one; with
/// `sphere_clear` it was a fifth of the whitted_blur16 profile (perf, 1 thread:
/// `PointOccluders::settle::{{closure}}` 13.3 %, `sphere_clear` 8.4 %).
#[inline(always)]
pub fn origin_ball(o: &V3, live: u32) -> (DVec3, f64) {
    let fill = <Packet as Lanes>::mask_from_bits(live);
    let (inf, neg) = (
        Packet::splat(f32::INFINITY),
        Packet::splat(f32::NEG_INFINITY),
    );
    let range = |p: Packet| {
        let (lo, hi) = (fill.select(p, inf), fill.select(p, neg));
        (
            reduce(lo, |a, b| a.fast_min(b)),
            reduce(hi, |a, b| a.fast_max(b)),
        )
    };
    let ((lx, hx), (ly, hy), (lz, hz)) = (range(o.x), range(o.y), range(o.z));
    let (lo, hi) = (
        DVec3::new(lx as f64, ly as f64, lz as f64),
        DVec3::new(hx as f64, hy as f64, hz as f64),
    );
    ((lo + hi) * 0.5, (hi - lo).length() * 0.5)
}

/// `f` folded over the lanes of `p` by quarters then halves: for an associative and
/// commutative `f` (the least or greatest of finite values), the fold.
#[inline(always)]
fn reduce(p: Packet, f: impl Fn(f32x4, f32x4) -> f32x4) -> f32 {
    let a = p.to_array();
    let q = |k: usize| f32x4::new([a[4 * k], a[4 * k + 1], a[4 * k + 2], a[4 * k + 3]]);
    let m = f(f(q(0), q(1)), f(q(2), q(3))).to_array();
    let m = f(
        f32x4::new([m[0], m[1], m[0], m[1]]),
        f32x4::new([m[2], m[3], m[2], m[3]]),
    )
    .to_array();
    f(f32x4::splat(m[0]), f32x4::splat(m[1])).to_array()[0]
}

/// Whether the sphere `(center, radius)` is clear of every shadow segment of a group
/// whose origins lie within `rho` of `g` (`origin_ball`) and which all end at `light`
/// (`spawn_ray_to` towards a point light: the target is the light's position,
/// unoffset, `tmax <= 1`), in the sense of [`clearance`]: the sphere test finds no root
/// on any of them.
///
/// The exact segments `[o, light]` lie in the convex hull of the ball and `light`: a
/// point `light + s (o - light)` is within `s rho <= rho` of `light + s (g - light)`.
/// The rays' own segments `[o, o + tmax d]` lie on `[o, o + d]`, whose end misses
/// `light` by the rounding of `d = fl(light - o)`, at most `u |light - o|`. So every
/// point of every segment is at least `dist(center, [g, light]) - rho - u L` from the
/// centre (`L = |light - g| + rho` bounds `|light - o|`), computed here in f64; clear
/// where that exceeds `clearance(radius, |center - g| + rho, ...)`: the radius plus the
/// sphere test's derived root error (no tuned margin).
///
/// Before (to 2026-11-24): a margin `1e-2 sqrt(radius S) + 1e-4 S` from a first-order
/// argument; the adversarial test found it wrong for negative radii (the sphere test
/// squares the radius), and the derivation shows the square-root term unneeded: a
/// root's error along a near-tangent ray moves its point along the sphere, not off it.
pub fn sphere_clear(light: Vec3, ball: (DVec3, f64), center: Vec3, radius: f32) -> bool {
    ClearOf::new(light, ball).clear(center, radius)
}

/// [`sphere_clear`] for several spheres of one group and light: the terms that do not
/// depend on the sphere (the segment from the ball's centre to the light, its length
/// and the bounds on `|d|`) computed once, each sphere's test then taking the same f64
/// values in the same order, so every answer is `sphere_clear`'s, bit for bit (a test
/// compares them).
///
/// Before: `sphere_clear` per sphere, every term recomputed (two spheres and two
/// lights per lane group of whitted_base: four calls, each with four square roots and
/// a division); it was 6.1 % of the whitted aa3x3 profile (perf, 1 thread, AVX-512).
/// With the shared terms: whitted aa3x3 CPU time 788 -> 773 ms (`perf stat -e
/// task-clock`, 1 thread, 5 interleaved pairs, medians, every pair faster; host load
/// ~11 on 2 cores).
pub struct ClearOf {
    l: DVec3,
    g: DVec3,
    rho: f64,
    w: DVec3,
    ww: f64,
    len: f64,
    longest: f64,
    shortest: f64,
    l_mag: f64,
    g_mag: f64,
}

impl ClearOf {
    /// The shared terms of the segments from a ball `(g, rho)` (`origin_ball`) to
    /// `light`.
    #[inline(always)]
    pub fn new(light: Vec3, (g, rho): (DVec3, f64)) -> ClearOf {
        let l = light.as_dvec3();
        let w = g - l;
        let ww = w.dot(w);
        let len = ww.sqrt();
        ClearOf {
            l,
            g,
            rho,
            w,
            ww,
            len,
            longest: (len + rho) * (1.0 + 2.0 * U),
            shortest: (len - rho) * (1.0 - 2.0 * U),
            l_mag: l.abs().max_element(),
            g_mag: g.abs().max_element(),
        }
    }

    /// Whether the sphere `(center, radius)` is clear of every segment (see
    /// [`sphere_clear`]).
    #[inline(always)]
    pub fn clear(&self, center: Vec3, radius: f32) -> bool {
        let (g, rho, w, ww, len) = (self.g, self.rho, self.w, self.ww, self.len);
        let c = center.as_dvec3();
        let v = c - self.l;
        let s = if ww > 0.0 {
            (v.dot(w) / ww).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let dist = (v - w * s).length();
        let mags = self.l_mag + c.abs().max_element() + self.g_mag + rho;
        let slack = rho + U * self.longest + F64_SLACK * (mags + len + v.length());
        let far = (c - g).length() + rho;
        // NaN anywhere: not clear (`clearance` refuses it, and NaN fails `>`).
        clearance(radius, far, slack, self.shortest, self.longest).is_some_and(|need| dist > need)
    }
}

/// The first lane of `s` (valid rays only, whatever `s.mask` says) on which the
/// scalar sphere test or its lane twin finds a root: the rays the renderer would
/// test if the cull did not skip the sphere.
#[cfg(test)]
pub(crate) fn lanes_meeting(
    s: &super::direct_light::ShadowLanes,
    center: Vec3,
    radius: f32,
) -> Option<crate::geometry::Ray> {
    let lanes = super::kernels::RayLanes {
        o: [s.origin.x, s.origin.y, s.origin.z],
        d: [s.dir.x, s.dir.y, s.dir.z],
        tmin: Packet::splat(0.0),
    };
    let keys = super::tiny::lane_shear_keys(&lanes, s.tmax);
    let valid = keys.iter().fold(0, |a, &k| a | k);
    let lane_hits = super::kernels::sphere_lanes(&lanes, center, radius, s.tmax, valid).1;
    (0..16).find_map(|i| {
        let ray = crate::geometry::Ray::segment(
            s.origin.lane(i),
            s.dir.lane(i),
            0.0,
            s.tmax.to_array()[i],
        );
        let query = crate::geometry::RayQuery::new(&ray)?;
        let hit = crate::geometry::intersect_sphere(&query, center, radius, ray.tmax).is_some();
        assert_eq!(
            hit,
            lane_hits >> i & 1 == 1,
            "the lane twin differs on {ray:?}"
        );
        hit.then_some(ray)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `leaving_lanes` on component arrays gives `leaving`'s bits on the same lanes,
    /// for every axis and both sides, on origins and directions that sit on the
    /// plane, cross it, run along it, or are NaN, infinite or signed zeros.
    #[test]
    fn leaving_lanes_matches_leaving() {
        let mut next = xorshift64(0x1eaf_0001);
        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e-30,
        ];
        let (mut compared, mut left) = (0, 0);
        for round in 0..400 {
            let axis = round % 3;
            let at = [0.0, 1.5, -2.25][round / 3 % 3];
            let plane = AxisPlane { axis, at };
            let mut value = |on_plane: bool| {
                let r = next();
                match r % 4 {
                    0 if on_plane => at,
                    1 => specials[(r >> 8) as usize % specials.len()],
                    _ => ((r >> 16) % 2001) as f32 / 250.0 - 4.0,
                }
            };
            let mut lanes = || -> [Packet; 3] {
                let mut a = [[0.0f32; 16]; 3];
                for (k, c) in a.iter_mut().enumerate() {
                    for x in c.iter_mut() {
                        *x = value(k == axis);
                    }
                }
                a.map(Packet::new)
            };
            let (o, d) = (lanes(), lanes());
            let live = (next() & 0xffff) as u32 | 1;
            let v3 = |a: &[Packet; 3]| V3 {
                x: a[0],
                y: a[1],
                z: a[2],
            };
            let want = plane.leaving(&v3(&o), &v3(&d), live);
            assert_eq!(plane.leaving_lanes(&o, &d, live), want, "round {round}");
            left += want.count_ones();
            compared += 1;
        }
        assert!(compared == 400 && left > 500, "{left} lanes leaving");
    }
    use crate::geometry::{RayQuery, intersect_sphere, intersect_triangle, spawn_ray_to};
    use crate::test_rng::xorshift64;

    /// `sphere_clear` as it was written before [`ClearOf`] (every term per sphere), the
    /// reference the shared terms must reproduce.
    fn sphere_clear_per_sphere(
        light: Vec3,
        (g, rho): (DVec3, f64),
        center: Vec3,
        radius: f32,
    ) -> bool {
        let (l, c) = (light.as_dvec3(), center.as_dvec3());
        let w = g - l;
        let v = c - l;
        let ww = w.dot(w);
        let s = if ww > 0.0 {
            (v.dot(w) / ww).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let dist = (v - w * s).length();
        let len = ww.sqrt();
        let longest = (len + rho) * (1.0 + 2.0 * U);
        let mags = l.abs().max_element() + c.abs().max_element() + g.abs().max_element() + rho;
        let slack = rho + U * longest + F64_SLACK * (mags + len + v.length());
        let far = (c - g).length() + rho;
        let shortest = (len - rho) * (1.0 - 2.0 * U);
        clearance(radius, far, slack, shortest, longest).is_some_and(|need| dist > need)
    }

    /// One [`ClearOf`] per group and light answers every sphere as the per-sphere
    /// formula does: random lights, balls (points and spread groups, at scales 1e-3 to
    /// 1e4, shifted far from the origin or not) and spheres, a third of them placed
    /// within a few ulps to 1e-1 of the clearance boundary (where a different rounding
    /// would flip the answer), some negative radii, and non-finite inputs; both answers
    /// occur many times.
    #[test]
    fn clear_of_answers_as_the_per_sphere_formula() {
        fn r3(unit: &mut impl FnMut() -> f32, s: f32) -> Vec3 {
            Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
        }
        let mut next = xorshift64(0x243f_6a88_85a3_08d3);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut clear, mut near) = (0usize, 0usize);
        for case in 0..50_000 {
            let scale = [1e-3f32, 1.0, 1e4][case % 3];
            let shift = if case / 3 % 2 == 0 {
                Vec3::ZERO
            } else {
                Vec3::new(1e5, -3e4, 7e4) * scale
            };
            let light = shift + (r3(&mut unit, 20.0) + Vec3::Y * 8.0) * scale;
            let g = (shift + r3(&mut unit, 16.0) * scale).as_dvec3();
            let rho = [0.0, 1e-6, 0.3, 8.0][case / 6 % 4] * scale as f64;
            let k = ClearOf::new(light, (g, rho));
            for sphere in 0..4 {
                let radius = [1e-3f32, 0.05, 0.8, 2.0][(case + sphere) % 4] * scale;
                let center = if sphere % 3 == 0 {
                    shift + r3(&mut unit, 12.0) * scale
                } else {
                    // Near the segment from the ball's centre to the light, at the
                    // radius plus the ball plus a push of 1e-1 down to a few ulps.
                    let (gf, lf) = (g.as_vec3(), light);
                    let side = (lf - gf).cross(r3(&mut unit, 1.0)).normalize_or(Vec3::X);
                    let push = 10f32.powf(-1.0 - 7.0 * unit()) * (lf - gf).length();
                    gf + (lf - gf) * unit() + side * (radius + rho as f32 + push)
                };
                let radius = if case % 11 == 0 { -radius } else { radius };
                let want = sphere_clear_per_sphere(light, (g, rho), center, radius);
                assert_eq!(k.clear(center, radius), want, "case {case} sphere {sphere}");
                assert_eq!(sphere_clear(light, (g, rho), center, radius), want);
                clear += want as usize;
                near += !want as usize;
            }
        }
        for bad in [f32::NAN, f32::INFINITY, -f32::INFINITY] {
            let (l, c) = (Vec3::Y * 9.0, Vec3::new(0.0, -50.0, 0.0));
            for (light, ball, center, radius) in [
                (l, (DVec3::ZERO, 0.1), c, bad),
                (l, (DVec3::ZERO, bad as f64), c, 1.0),
                (l, (DVec3::ZERO, 0.1), Vec3::new(bad, 0.0, 0.0), 1.0),
                (l, (DVec3::new(0.0, bad as f64, 0.0), 0.1), c, 1.0),
                (Vec3::new(bad, 9.0, 0.0), (DVec3::ZERO, 0.1), c, 1.0),
            ] {
                let want = sphere_clear_per_sphere(light, ball, center, radius);
                assert!(!want);
                assert_eq!(ClearOf::new(light, ball).clear(center, radius), want);
            }
        }
        eprintln!("{clear} clear, {near} not");
        assert!(clear > 20_000 && near > 20_000, "{clear} clear, {near} not");
    }

    /// [`origin_ball`]'s lane minima and maxima are the scalar fold's (the
    /// `f32::min`/`f32::max` fold over the live lanes, compared as numbers: `-0.0`
    /// and `+0.0` alike): random origins of every size, both signs of zero, random
    /// lane masks (single lanes, gaps, all sixteen); the stale lanes outside the mask
    /// hold huge values that must not leak in.
    #[test]
    fn origin_ball_is_the_box_of_the_live_origins() {
        let mut next = xorshift64(0x6a09_e667_f3bc_c908);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        for case in 0..20_000 {
            let scale = [1e-3f32, 1.0, 1e3, 1e6][case % 4];
            let live = match case % 5 {
                0 => 0xffff,
                1 => 1 << (case / 5 % 16),
                _ => ((unit() * 65536.0) as u32 & 0xffff) | 1 << (case % 16),
            };
            let mut c = [[0.0f32; 16]; 3];
            for (k, axis) in c.iter_mut().enumerate() {
                for (i, x) in axis.iter_mut().enumerate() {
                    *x = if live >> i & 1 == 0 {
                        1e30 * (unit() - 0.5)
                    } else if (case + i + k) % 7 == 0 {
                        [0.0, -0.0][i % 2]
                    } else {
                        (unit() - 0.5) * scale
                    };
                }
            }
            let o = V3::load(&c[0], &c[1], &c[2]);
            let (g, rho) = origin_ball(&o, live);
            let fold = |a: &[f32; 16]| {
                let mut it = (0..16).filter(|i| live >> i & 1 == 1).map(|i| a[i]);
                let first = it.next().expect("a live lane");
                it.fold((first, first), |(lo, hi), v| (lo.min(v), hi.max(v)))
            };
            let b = c.each_ref().map(fold);
            let lo = DVec3::new(b[0].0 as f64, b[1].0 as f64, b[2].0 as f64);
            let hi = DVec3::new(b[0].1 as f64, b[1].1 as f64, b[2].1 as f64);
            assert_eq!(g, (lo + hi) * 0.5, "case {case} live {live:#x}");
            assert_eq!(rho, (hi - lo).length() * 0.5, "case {case} live {live:#x}");
        }
    }

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
            if !sphere_clear(light, (g, rho), center, radius) {
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

    /// Adversarial cases for [`sphere_clear`]: wherever it says a sphere is clear of a
    /// group, neither the scalar sphere test nor its lane twin finds a root on any of
    /// the group's shadow rays, built as the renderer builds them (`point_light`):
    /// scenes of scale 1e-3, 1 and 1e4, shifted to 1e5 from the origin or not, groups
    /// of one point and of points spread up to 8 units of the scale, tiny spheres (1e-7
    /// and 1e-3 of the scale) and large ones placed tangent to the segment of a random
    /// or an extreme lane (pushed out by 1e-1 down to 1e-9 of its length, slid past
    /// both ends), a few ulps of tangency, negative radii. Non-finite inputs are never
    /// clear.
    #[test]
    fn sphere_clear_holds_against_adversarial_spheres() {
        use crate::simd::direct_light::{Highlight, SurfaceLanes, point_light};
        fn r3(unit: &mut impl FnMut() -> f32, s: f32) -> Vec3 {
            Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s
        }
        let mut next = xorshift64(0x3c6e_f372_fe94_f82b);
        let (mut cases, mut clear, mut close) = (0usize, 0usize, 0usize);
        let hl = Highlight {
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        for case in 0..40_000 {
            let mut unit = || (next() >> 40) as f32 / (1u64 << 24) as f32;
            let scale = [1e-3f32, 1.0, 1e4][case % 3];
            let shift = if case % 6 < 3 {
                Vec3::ZERO
            } else {
                Vec3::new(1e5, -3e4, 7e4) * scale
            };
            let light = shift + (r3(&mut unit, 20.0) + Vec3::Y * 8.0) * scale;
            let g0 = shift + r3(&mut unit, 16.0) * scale;
            let spread = [0.0f32, 1e-6, 0.3, 8.0][case / 3 % 4] * scale;
            let points: [Vec3; 16] = std::array::from_fn(|_| g0 + r3(&mut unit, spread));
            let normals: [Vec3; 16] =
                std::array::from_fn(|_| r3(&mut unit, 2.0).normalize_or(Vec3::Y));
            let lanes = |v: &[Vec3; 16]| V3 {
                x: Packet::new(v.map(|p| p.x)),
                y: Packet::new(v.map(|p| p.y)),
                z: Packet::new(v.map(|p| p.z)),
            };
            let errors = points.map(|p| crate::geometry::gamma(5) * p.abs());
            let s = SurfaceLanes {
                p: lanes(&points),
                p_error: lanes(&errors),
                ng: lanes(&normals),
                ns: lanes(&normals),
                base: lanes(&points),
                smooth: Packet::splat(0.0),
                wo: lanes(&normals),
                albedo: V3::splat(Vec3::ONE),
            };
            let sl = point_light(&s, &hl, light, Vec3::ONE, 0xffff);
            // The segment of a random lane, or of the one with the least or most x.
            let xs = sl.origin.x.to_array();
            let lane = match case % 5 {
                0 => (0..16)
                    .min_by(|&a, &b| xs[a].total_cmp(&xs[b]))
                    .unwrap_or(0),
                1 => (0..16)
                    .max_by(|&a, &b| xs[a].total_cmp(&xs[b]))
                    .unwrap_or(0),
                _ => (unit() * 16.0) as usize & 15,
            };
            let o = sl.origin.lane(lane);
            let radius = [1e-7f32, 1e-3, 0.05, 0.8][case / 12 % 4] * scale;
            let push = 10f32.powf(-1.0 - 8.0 * unit());
            let center = if case % 7 == 6 {
                shift + r3(&mut unit, 12.0) * scale
            } else {
                let along = [-0.05, 0.0, unit(), 1.0, 1.05][case / 48 % 5];
                let seg = light - o;
                let side = seg.cross(r3(&mut unit, 1.0)).normalize_or(Vec3::X);
                let out = if case % 13 == 0 {
                    radius * (1.0 + (case / 13 % 8) as f32 * f32::EPSILON)
                } else {
                    radius + push * seg.length()
                };
                o + seg * along + side * out
            };
            let radius = if case % 17 == 0 { -radius } else { radius };
            let (g, rho) = origin_ball(&sl.origin, 0xffff);
            cases += 1;
            if !sphere_clear(light, (g, rho), center, radius) {
                continue;
            }
            clear += 1;
            close += (case % 7 != 6 && push < 1e-4) as usize;
            if let Some(ray) = lanes_meeting(&sl, center, radius) {
                panic!("case {case}: {ray:?} meets the sphere {center} {radius} said clear");
            }
        }
        for bad in [f32::NAN, f32::INFINITY, -f32::INFINITY] {
            let (l, far) = (Vec3::Y * 9.0, Vec3::new(0.0, -50.0, 0.0));
            let (g, b) = (DVec3::ZERO, bad as f64);
            assert!(!sphere_clear(l, (g, 0.1), far, bad));
            assert!(!sphere_clear(l, (g, b), far, 1.0));
            assert!(!sphere_clear(l, (g, 0.1), Vec3::new(bad, 0.0, 0.0), 1.0));
            assert!(!sphere_clear(l, (DVec3::new(0.0, b, 0.0), 0.1), far, 1.0));
            assert!(!sphere_clear(Vec3::new(bad, 9.0, 0.0), (g, 0.1), far, 1.0));
        }
        eprintln!("{clear} of {cases} spheres clear ({close} pushed out by < 1e-4)");
        assert!(
            clear > cases / 4 && close > 500,
            "{clear} clear, {close} close"
        );
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
