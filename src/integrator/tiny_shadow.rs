//! Shadow rays of a tiny scene settled in one pass of lanes ([`TinyShadow`]): the
//! occlusion query and the transmittance through glass spheres in the same lane group,
//! instead of the occlusion batch (`SceneAccel::occluders_batch`, which names the
//! first blocking set of every ray) followed by `ShadowFilter::transmittance_batch`
//! (which copies the rays blocked by the sphere set out and gathers them into lanes a
//! second time).
//!
//! Applies where the scene's batch queries go through [`TinyScene`] and nothing else
//! (no moving geometry, instances or planes), its triangles are all opaque, and its
//! spheres are either all opaque or a split set whose passing part is glass of one
//! transmission (`ShadowFilter::tiny_pass`): the Whitted rows. The answers are the
//! two-step path's bit for bit (a test compares factors and counts on real shadow
//! rays): the same lane kernels run on the same lanes (`TinyGroup::any_triangle`,
//! `any_sphere`, then [`settle_gathered`], the body of `settle_lanes`), each lane's
//! answer depends on its ray alone, and a ray through glass only gets `transmission`
//! multiplied in once per crossing, as `ShadowFilter::glass_factor` does.
//!
//! Measured with the binned lane groups of `accel/tiny.rs` (same change), 1 thread,
//! AVX2, `--stats-json`, interleaved with the previous binary on a machine loaded 5-10
//! on 2 cores (only the ratios mean anything), ms, images byte-identical:
//! whitted_area64 area-shadow stage 15245-17411 -> 10822-11976 (5 runs, load ~9) and
//! 7570-8565 -> 5088-5437 (3 runs, load ~6); whitted_blur16 shadow stage 1023-1123 ->
//! 519-658, whitted_base 71-85 -> 36-46 (3 runs each, load ~3). perf (area64 512x384):
//! the sort by key plus the second gather (`occluders_batch` with `TinyGroup::new`,
//! `transmittance_batch`, `settle_lanes`) were ~21 % of the frame before, the binning
//! and the fused pass ~14 % after.

use super::shadow::ShadowFilter;
use crate::accel::{Occluder, SceneAccel, TINY_MAX_PRIMITIVES, TinyScene, TinyScratch};
use crate::geometry::Ray;
use crate::simd::Packet;
use crate::simd::direct_light::QuadLight;
use crate::simd::glass_shadow::settle_gathered;
use crate::simd::kernels::RayLanes;
use crate::simd::kernels::sphere_lanes;
use crate::simd::lanes3::V3;
use crate::simd::tiny::{TinyGroup, TrianglePlane, lane_shear_keys};
use crate::stats::RayCounts;
use glam::Vec3;

/// What a shadow ray blocked by the sphere set (and by no triangle) transmits.
#[derive(Clone, Copy)]
pub(super) enum SphereShadow<'a> {
    /// Every sphere blocks light.
    Opaque,
    /// `opaque` spheres block light; `glass` spheres each multiply `transmission` in
    /// once per crossing of their surface.
    Glass {
        opaque: &'a [(Vec3, f32)],
        glass: &'a [(Vec3, f32)],
        transmission: Vec3,
    },
}

/// The one-pass shadow settlement of a tiny scene (see the module).
pub struct TinyShadow<'a> {
    pub(super) tiny: &'a TinyScene,
    pub(super) spheres: SphereShadow<'a>,
}

impl TinyShadow<'_> {
    /// The transmittance of every ray of `rays` into `out`: one where unblocked, zero
    /// where an opaque primitive blocks it, `transmission^n` through `n` glass
    /// crossings; the rays blocked first by a split sphere set are counted in
    /// `counts.transmitted_shadow`. What `occluders_batch` then
    /// `ShadowFilter::transmittance_batch` give, bit for bit.
    pub fn transmittance_batch(
        &self,
        rays: &[Ray],
        out: &mut Vec<Vec3>,
        scratch: &mut TinyScratch,
        counts: &mut RayCounts,
    ) {
        out.clear();
        out.resize(rays.len(), Vec3::ONE);
        let mut settled = 0u64;
        let spheres = self.spheres;
        self.tiny
            .occluder_groups(rays, scratch, |ids, g, tri, sph| {
                for_each_bit(tri, |i| out[ids[i] as usize] = Vec3::ZERO);
                if sph == 0 {
                    return;
                }
                match spheres {
                    SphereShadow::Opaque => {
                        for_each_bit(sph, |i| out[ids[i] as usize] = Vec3::ZERO)
                    }
                    SphereShadow::Glass {
                        opaque,
                        glass,
                        transmission,
                    } => {
                        settled += sph.count_ones() as u64;
                        let (blocked, n) = settle_gathered(&g.lanes, g.tmax, sph, opaque, glass);
                        for_each_bit(sph, |i| {
                            out[ids[i] as usize] = if blocked >> i & 1 == 1 {
                                Vec3::ZERO
                            } else {
                                // `ShadowFilter::glass_factor` with no later sets.
                                let mut t = Vec3::ONE;
                                for _ in 0..n[i] {
                                    t *= transmission;
                                }
                                t
                            };
                        });
                    }
                }
            });
        counts.transmitted_shadow += settled;
    }
}

/// Calls `f` with the index of every set bit.
#[inline(always)]
fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// The shadow settlement of a tiny scene for rays already in lanes: the light samples
/// of one shading point towards one quad light, tested where they are generated
/// (`integrator::area_light`) instead of through the area-shadow queue. An owned copy
/// of the scene's few primitives, so that the shading stage can hold it.
///
/// Applies where the queue path of the area-shadow stage (`wavefront::trace_shadows`)
/// goes through [`TinyShadow`] or through the tiny scene's plain occlusion batch: the
/// scene's batch queries go through its `TinyScene` alone (no moving geometry,
/// instances or planes), and either no shadow ray needs a second query (no
/// [`ShadowFilter`](super::shadow::ShadowFilter)) or the filter has a
/// [`tiny_pass`](super::shadow::ShadowFilter::tiny_pass). Each lane gets the queue
/// path's answer bit for bit: the same lane kernels (`TinyGroup::any_triangle`,
/// `any_sphere`, [`settle_gathered`]) on the same ray fields, grouped by shear key
/// within the sixteen lanes (a lane's answer depends on its ray alone), invalid rays
/// untested and unblocked as `TinyScene::for_each_group` leaves them, and the glass
/// factor multiplied in once per crossing as `transmittance_batch` does.
pub struct LaneOccluders {
    triangles: Vec<[Vec3; 3]>,
    /// Their planes: lanes leaving a triangle's plane from its origin's side skip it.
    planes: Vec<TrianglePlane>,
    /// Per plane, an earlier one that is the same plane (`TrianglePlane::same_plane`:
    /// the two triangles of a quad), whose side and culled lanes it takes.
    twins: Vec<Option<usize>>,
    spheres: Vec<(Vec3, f32)>,
    /// Per sphere of the opaque and of the glass list, its index in `spheres` (the
    /// lists are parts of it), so that each sphere is tested once per shading point.
    glass_index: (Vec<Option<usize>>, Vec<Option<usize>>),
    /// Where the sphere set is split: the opaque spheres, the glass spheres and their
    /// transmission (`SphereShadow::Glass`).
    glass: Option<GlassSet>,
}

/// Which spheres the light samples of one shading point may meet
/// ([`LaneOccluders::spheres_near`]): bit `k` for sphere `k` of each list.
#[derive(Clone, Copy)]
pub struct NearSpheres {
    all: u32,
    opaque: u32,
    glass: u32,
    /// Bit `k`: triangle `k`'s plane cull may skip some of these segments
    /// (`TrianglePlane::may_cull`); it is not tried for the others.
    planes: u32,
    /// The last shared origin seen and the side of each triangle's plane it lies on
    /// (`TrianglePlane::side`, computed once per shading point and light, not per
    /// lane group).
    sides: (Option<Vec3>, [Option<f32>; TINY_MAX_PRIMITIVES]),
}

/// Whether a plane separates the sphere `(center, radius)` from every segment between
/// `origin` and a point of the quad light `q`, with a margin of `1e-4` of the scene's
/// scale here (distances and coordinates): one of the pyramid's faces (the planes
/// through `origin` and each light edge, the light's own plane), or the plane through
/// `origin` across the direction to the centre with the whole light behind it.
///
/// Why the sphere lane test then finds no root on these rays: a shadow ray's origin
/// lies within `p_error` of the shading point's base point (its offset) and its end
/// within the light's point error of the light quad, both far below the margin, so the
/// ray stays inside the margin-widened pyramid and clear of the sphere by at least the
/// margin; the test's roots carry errors of a few f32 roundings of the same scale
/// (`|o - center|`, `|d|`), a hundred times smaller, so its discriminant stays negative
/// or its roots outside the segment.
pub fn sphere_clear_of(origin: Vec3, q: &QuadLight, center: Vec3, radius: f32) -> bool {
    let f = center - origin;
    let dist = f.length();
    let corners = [
        q.corner,
        q.corner + q.edge1,
        q.corner + q.edge1 + q.edge2,
        q.corner + q.edge2,
    ];
    let rel = corners.map(|c| c - origin);
    let reach = rel.iter().fold(0.0f32, |m, r| m.max(r.length()));
    let scale = dist + radius + reach + origin.abs().max_element() + center.abs().max_element();
    let m = 1e-4 * scale;
    // NaN anywhere: not clear.
    if !m.is_finite() || dist <= radius + m {
        return false;
    }
    // The light entirely behind the plane through `origin` across `f`.
    let axis = f / dist;
    if rel.iter().all(|r| axis.dot(*r) < -m) {
        return true;
    }
    let inside = (rel[0] + rel[1] + rel[2] + rel[3]) * 0.25;
    for i in 0..4 {
        let n = rel[i].cross(rel[(i + 1) % 4]);
        let len = n.length();
        let min = 1e-3 * rel[i].length() * rel[(i + 1) % 4].length();
        if len.is_nan() || min.is_nan() || len <= min {
            continue;
        }
        let n = if n.dot(inside) > 0.0 {
            -n / len
        } else {
            n / len
        };
        if n.dot(f) > radius + m {
            return true;
        }
    }
    // Beyond the light's plane, on the far side from `origin`.
    let side = q.normal.dot(rel[0]);
    if side.abs() > m {
        let n = if side > 0.0 { q.normal } else { -q.normal };
        if n.dot(center - q.corner) > radius + m {
            return true;
        }
    }
    false
}

/// The opaque spheres, the glass spheres and the glass's transmission.
pub(crate) type GlassSet = (Vec<(Vec3, f32)>, Vec<(Vec3, f32)>, Vec3);

/// What [`LaneOccluders::settle`] found for sixteen lanes.
pub struct LaneSettled {
    /// Bits of the lanes whose contribution reaches the shading point: unblocked with a
    /// transmittance that is not zero in every channel (the queue path's
    /// `t != Vec3::ZERO`), invalid rays included (untested).
    pub pass: u32,
    /// The transmittance of each lane (one where no glass is crossed).
    pub factor: V3,
    /// Lanes settled through the glass spheres (`RayCounts::transmitted_shadow`).
    pub settled: u32,
}

/// The tiny scene and its glass split (opaque spheres, glass spheres, transmission;
/// `None`: every sphere opaque) where the queue path (`wavefront::trace_shadows`)
/// settles shadow rays through the tiny scene alone: its batch queries go through the
/// `TinyScene` (no moving geometry, instances or planes), and either no ray needs a
/// second query (no `filter`) or the filter has a `tiny_pass`. What the lane-settled
/// shadows of quad lights ([`LaneOccluders`]) and of point lights
/// (`point_shadow::PointOccluders`) both start from.
pub(crate) fn tiny_shadow_scene<'a>(
    accel: &'a SceneAccel,
    filter: Option<&ShadowFilter>,
) -> Option<(&'a TinyScene, Option<GlassSet>)> {
    let tiny = accel.tiny.as_ref()?;
    if accel.has_sets_from(Occluder::Moving) {
        return None;
    }
    let glass = match filter {
        None => None,
        Some(f) => match f.tiny_pass(accel)?.spheres {
            SphereShadow::Opaque => None,
            SphereShadow::Glass {
                opaque,
                glass,
                transmission,
            } => Some((opaque.to_vec(), glass.to_vec(), transmission)),
        },
    };
    Some((tiny, glass))
}

impl LaneOccluders {
    /// `Some` where the queue path would settle area-shadow rays by the tiny scene
    /// alone (see the type); `filter` is the render's shadow filter.
    pub fn new(accel: &SceneAccel, filter: Option<&ShadowFilter>) -> Option<LaneOccluders> {
        let (tiny, glass) = tiny_shadow_scene(accel, filter)?;
        let planes: Vec<TrianglePlane> = tiny.triangles().iter().map(TrianglePlane::new).collect();
        let twins = (0..planes.len())
            .map(|i| (0..i).find(|&j| planes[j].same_plane(&planes[i])))
            .collect();
        let spheres = tiny.spheres().to_vec();
        let index = |list: &[(Vec3, f32)]| {
            list.iter()
                .map(|s| spheres.iter().position(|a| a.0 == s.0 && a.1 == s.1))
                .collect()
        };
        let glass_index = glass
            .as_ref()
            .map_or((Vec::new(), Vec::new()), |g: &GlassSet| {
                (index(&g.0), index(&g.1))
            });
        Some(LaneOccluders {
            triangles: tiny.triangles().to_vec(),
            planes,
            twins,
            spheres,
            glass_index,
            glass,
        })
    }

    /// The spheres that a segment from (about) `base` to a point of the quad light `q`
    /// may come near: all but those a plane separates from every such segment (see
    /// [`sphere_clear_of`]); one bit per sphere of the scene's list, of the opaque and
    /// of the glass list.
    pub fn spheres_near(&self, base: Vec3, q: &QuadLight) -> NearSpheres {
        let near = |&(c, r): &(Vec3, f32)| !sphere_clear_of(base, q, c, r);
        let all = self
            .spheres
            .iter()
            .enumerate()
            .fold(0u32, |b, (k, s)| b | (near(s) as u32) << (k & 31));
        // A listed sphere that is one of `spheres` takes its bit (the same call).
        let bits = |list: &[(Vec3, f32)], index: &[Option<usize>]| {
            list.iter()
                .zip(index)
                .enumerate()
                .fold(0u32, |b, (k, (s, i))| {
                    let n = i.map_or_else(|| near(s), |i| all >> (i & 31) & 1 == 1);
                    b | (n as u32) << (k & 31)
                })
        };
        let (oi, gi) = &self.glass_index;
        let corners = [
            q.corner,
            q.corner + q.edge1,
            q.corner + q.edge1 + q.edge2,
            q.corner + q.edge2,
        ];
        let planes = self.planes.iter().enumerate().fold(0u32, |b, (k, p)| {
            b | (p.may_cull(base, &corners) as u32) << (k & 31)
        });
        NearSpheres {
            planes,
            sides: (None, [None; TINY_MAX_PRIMITIVES]),
            all,
            opaque: self.glass.as_ref().map_or(0, |g| bits(&g.0, oi)),
            glass: self.glass.as_ref().map_or(0, |g| bits(&g.1, gi)),
        }
    }

    /// Settles the rays `origin + t dir`, `t` in `(0, tmax)`, of the lanes in `live`,
    /// testing only the spheres in `near_spheres` (the others meet none of these
    /// rays); it keeps the triangle sides of the last shared origin.
    #[inline(always)]
    pub fn settle(
        &self,
        origin: V3,
        dir: V3,
        tmax: Packet,
        live: u32,
        near_spheres: &mut NearSpheres,
    ) -> LaneSettled {
        let lanes = RayLanes {
            o: [origin.x, origin.y, origin.z],
            d: [dir.x, dir.y, dir.z],
            tmin: Packet::splat(0.0),
        };
        let keys = lane_shear_keys(&lanes, tmax);
        let valid = keys.iter().fold(0, |a, &k| a | k) & live;
        // One origin for every valid lane (the common case: every sample of a shading
        // point leaves from the same offset point), bit for bit: equal as floats and
        // with equal sign bits (`to_bitmask` reads the sign bits), so a zero and a
        // negative zero differ.
        let shared = (valid != 0).then(|| origin.lane(valid.trailing_zeros() as usize & 15));
        let shared = shared.filter(|o| {
            let same = |p: Packet, v: f32| {
                let signs = p.to_bitmask();
                let signs = if v.is_sign_negative() { signs } else { !signs };
                p.simd_eq(Packet::splat(v)).to_bitmask() & signs
            };
            same(origin.x, o.x) & same(origin.y, o.y) & same(origin.z, o.z) & valid == valid
        });
        // Per triangle, the valid lanes that may meet it: all but those leaving its
        // plane from the shared origin's side (`TrianglePlane`), tried where it may
        // skip some (`NearSpheres::planes`); below, per key group, also all but those
        // ending before its corners (`TinyGroup::beyond`: the light's own triangles).
        //
        // Measured before `beyond` (counters, whitted_area64 512x384): every lane group
        // ran the full triangle test on both of the light's triangles (each sample's
        // segment ends just short of them), the largest part of `shade_quads`.
        let mut reach = [valid; TINY_MAX_PRIMITIVES];
        if let Some(o) = shared {
            if near_spheres.sides.0 != Some(o) {
                let mut sides = [None; TINY_MAX_PRIMITIVES];
                for (i, (plane, twin)) in self.planes.iter().zip(&self.twins).enumerate() {
                    let tried = near_spheres.planes >> (i & 31) & 1 == 1;
                    sides[i] = match *twin {
                        Some(j) => sides[j],
                        None if tried => plane.side(o),
                        None => None,
                    };
                }
                near_spheres.sides = (Some(o), sides);
            }
            let sides = &near_spheres.sides.1;
            for (i, (plane, twin)) in self.planes.iter().zip(&self.twins).enumerate() {
                match (*twin, sides[i]) {
                    (Some(j), _) => reach[i] = reach[j],
                    (None, Some(side)) => reach[i] &= !plane.leaving(side, &lanes.d, valid),
                    (None, None) => {}
                }
            }
        }
        let (mut tri, mut sph) = (0u32, 0u32);
        for (key, &bits) in keys.iter().enumerate() {
            let mask = bits & live;
            if mask == 0 {
                continue;
            }
            let g = match shared {
                Some(o) => TinyGroup::from_lanes_at(key, lanes, tmax, mask, o),
                None => TinyGroup::from_lanes(key, lanes, tmax, mask),
            };
            let mut t = 0;
            for (corners, reach) in self.triangles.iter().zip(reach) {
                let test = mask & reach & !t;
                if test != 0 {
                    // The light's own triangles, beyond the segments' ends.
                    let test = test & !g.beyond(corners, test);
                    if test != 0 {
                        t |= g.triangle_blocks(corners, test);
                    }
                }
            }
            tri |= t;
            for (k, &(center, radius)) in self.spheres.iter().enumerate() {
                let rest = mask & !t & !sph;
                if near_spheres.all >> (k & 31) & 1 == 1 && rest != 0 {
                    sph |= sphere_lanes(&g.lanes, center, radius, g.tmax, rest).1;
                }
            }
        }
        settle_spheres(&lanes, tmax, (live, tri, sph), self.glass.as_ref(), |_| {
            (near_spheres.opaque, near_spheres.glass)
        })
    }
}

/// The end of both lane-settled shadow paths (quad lights here, point lights in
/// `point_shadow`): of the `live` lanes, `tri` are blocked by a triangle and `sph` meet
/// a sphere. Without a glass split every sphere blocks; with one (`glass`), the sphere
/// lanes are settled as the queue path settles them (`settle_gathered` on the spheres
/// `near` picks from each list: its bits of the opaque and the glass list), each lane's
/// transmittance multiplied in once per crossing, and a lane passes unless blocked or
/// fully dark.
#[inline(always)]
pub(crate) fn settle_spheres(
    lanes: &RayLanes<Packet>,
    tmax: Packet,
    (live, tri, sph): (u32, u32, u32),
    glass: Option<&GlassSet>,
    near: impl FnOnce(&GlassSet) -> (u32, u32),
) -> LaneSettled {
    let one = V3::splat(Vec3::ONE);
    let Some(set) = glass else {
        return LaneSettled {
            pass: live & !(tri | sph),
            factor: one,
            settled: 0,
        };
    };
    if sph == 0 {
        return LaneSettled {
            pass: live & !tri,
            factor: one,
            settled: 0,
        };
    }
    let (opaque, glass, transmission) = set;
    let (opaque_bits, glass_bits) = near(set);
    let pick = |list: &[(Vec3, f32)], bits: u32| {
        let mut out = [(Vec3::ZERO, 0.0f32); TINY_MAX_PRIMITIVES];
        let mut n = 0;
        for (k, s) in list.iter().enumerate() {
            if bits >> (k & 31) & 1 == 1 {
                out[n & 7] = *s;
                n += 1;
            }
        }
        (out, n.min(TINY_MAX_PRIMITIVES))
    };
    let (o, no) = pick(opaque, opaque_bits);
    let (g, ng) = pick(glass, glass_bits);
    let (blocked, n) = settle_gathered(lanes, tmax, sph, &o[..no], &g[..ng]);
    // `t *= transmission` once per crossing, lane by lane: the same products in the
    // same order as the scalar loop (`ShadowFilter::glass_factor`).
    let counts = Packet::new(n.map(|c| c as f32));
    let most = n.iter().max().copied().unwrap_or(0);
    let tr = V3::splat(*transmission);
    let mut factor = one;
    for k in 0..most {
        let more = counts.simd_gt(Packet::splat(k as f32));
        factor = V3::select(more, factor.times(tr), factor);
    }
    let zero = Packet::splat(0.0);
    let dark = factor.x.simd_eq(zero) & factor.y.simd_eq(zero) & factor.z.simd_eq(zero);
    LaneSettled {
        pass: live & !tri & !blocked & !dark.to_bitmask(),
        factor,
        settled: sph,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{RayQuery, intersect_sphere};
    use crate::test_rng::xorshift64;

    /// Where [`sphere_clear_of`] says a sphere is clear of a shading point's light
    /// samples, the scalar sphere test ([`intersect_sphere`], which the lane test
    /// repeats bit for bit) finds no root on any shadow segment from the point to the
    /// light: random spheres, quad lights and points, 64 segments each to random light
    /// points built as the renderer builds them (`quad_light`'s `spawn_ray_to`).
    #[test]
    fn spheres_clear_of_a_light_meet_none_of_its_segments() {
        let mut next = xorshift64(0x2545_f491_4f6c_dd1d);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut clear, mut cases) = (0, 0);
        for _ in 0..3000 {
            let mut r3 = |s: f32| Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * s;
            let q = QuadLight::new(
                Vec3::new(-2.0, 5.0, -1.0) + r3(4.0),
                Vec3::new(2.0, 0.0, 0.0) + r3(1.0),
                Vec3::new(0.0, 0.0, 2.0) + r3(1.0),
                Vec3::ONE,
            );
            let center = r3(6.0) + Vec3::new(0.0, 1.5, 0.0);
            let radius = 0.2 + unit() * 1.2;
            let p = Vec3::new(unit() - 0.5, 0.0, unit() - 0.5) * 16.0;
            cases += 1;
            if !sphere_clear_of(p, &q, center, radius) {
                continue;
            }
            clear += 1;
            let p_error = Vec3::splat(1e-6);
            for _ in 0..64 {
                let point = q.corner + q.edge1 * unit() + q.edge2 * unit();
                let ray =
                    crate::geometry::spawn_ray_to(p, p_error, Vec3::Y, point, q.p_error, q.normal);
                let query = RayQuery::new(&ray).expect("a valid segment");
                assert!(
                    intersect_sphere(&query, center, radius, ray.tmax).is_none(),
                    "{ray:?} meets the sphere {center} {radius} said clear"
                );
            }
        }
        eprintln!("{clear} of {cases} spheres clear of the light");
        assert!(clear > 500 && clear < cases);
    }
}
