//! The shadow rays of point and directional lights in a tiny scene settled in the lanes
//! that build them ([`PointOccluders`]): the sixteen shadow rays of a lane group of
//! shading points towards one light are tested against the scene's few primitives
//! right away (`shade_stage`), glass transmittance included, and their contributions
//! summed in those lanes; no shadow queue for those lights.
//!
//! Why: queued, each ray became a 52-byte `Ray` + slot + contribution written and read
//! back, dealt into shear-key bins (`TinyScene::occluder_groups`), gathered into lanes
//! again, tested, and added to its camera sample one by one (perf, whitted_base, 1
//! thread, self time: `push_shadow` 2.6 %, `occluder_groups` and its closure 4.8 %,
//! `trace_shadows` 2.0 %, on top of `any_triangle` 4.0 % and `any_sphere` 2.4 %).
//! The same change for quad lights is `area_light` + `tiny_shadow::LaneOccluders`.
//!
//! Exactness: each lane gets the queue path's answer (`tiny_shadow::TinyShadow`, or
//! `SceneAccel::any_hit_batch` through the tiny scene where no shadow filter is on) bit
//! for bit: the same lane kernels (`TinyGroup::triangle_blocks` per shear key, the
//! sphere roots of `sphere_lanes` and `settle_gathered`, each sphere's computed once
//! per lane group: `tiny_shadow::settle_near_spheres`) on the same ray fields, a lane's answer
//! depending on its ray alone; invalid rays untested and unblocked, as
//! `TinyScene::for_each_group` leaves them; the glass factor multiplied in once per
//! crossing. Two culls skip tests that cannot find a hit (`simd::shadow_cull`, where
//! each argument is stated): a lane leaving an axis-aligned triangle's plane from its
//! origin's side (exact f32 comparisons), and a sphere clear of the group's segments
//! (towards a point light only, and only where [`SPHERE_CULL`] is set: not in AVX-512
//! builds, where it cost more than the lane tests it saved) by the sphere test's
//! derived root error bound (`simd::sphere_clearance`).
//!
//! The sums change order: the queue path added the unblocked contributions after the
//! wave was shaded, light by light, one at a time; here the local radiance and every
//! point and directional light's term of a hit are summed in its lane and added to its
//! camera sample once. Terms are the same f32 values (`contribution * weight *
//! factor`, the same products), all non-negative, so each order's sum is within
//! `γ_{N-1}` of the exact sum of the `N` terms of a camera sample (Higham, Accuracy
//! and Stability of Numerical Algorithms, 2nd ed., §4.2: any summation order), and the
//! two within `2 γ_N` relative of each other. (A camera sample whose wave holds one
//! hit adds `local + c0 + c1` in the same order either way: most sums stay bit-equal.)
//!
//! Measured (1 thread, AVX2, `--stats-json`, interleaved with the queue-path binary on
//! a machine loaded ~11 on 2 cores by other builds, so only the ratios mean anything;
//! render min/median/max ms): whitted_base 1018/1216/1512 -> 952/1079/1387 (7 runs),
//! aa3x3 10025/14732/18238 -> 8718/13081/15842, whitted_blur16 14520/17258/18471 ->
//! 14332/15046/15750 (5 runs each); ray counts equal; images byte-identical but for
//! one pixel by one in whitted_blur16 and whitted_area64. Not separated: the two culls'
//! share (no quiet machine in this session).

use super::shadow::ShadowFilter;
use super::tiny_shadow::{
    GlassSet, LaneSettled, glass_index, listed_near_bits, near_bits, settle_near_spheres,
    tiny_shadow_scene,
};
use crate::accel::{SceneAccel, TINY_MAX_PRIMITIVES};
use crate::simd::direct_light::ShadowLanes;
use crate::simd::kernels::RayLanes;
use crate::simd::lanes3::V3;
use crate::simd::shadow_cull::{AxisPlane, ClearOf, origin_ball};
use crate::simd::tiny::{TinyGroup, lane_shear_keys};
use crate::simd::{Lanes, Packet};
use glam::Vec3;

/// An owned copy of a tiny scene's primitives for settling the shadow rays of point and
/// directional lights in the shading lanes (see the module).
pub struct PointOccluders {
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle, its plane where axis-aligned.
    planes: Vec<Option<AxisPlane>>,
    /// Per triangle, an earlier triangle with the same axis plane (the two triangles
    /// of the floor quad), whose culled lanes it takes: the same comparisons.
    twins: Vec<Option<usize>>,
    spheres: Vec<(Vec3, f32)>,
    /// Per sphere of the glass set's opaque and glass lists, its index in `spheres`
    /// (the lists are parts of it), so that each sphere's cull is decided once per
    /// lane group and light (as `LaneOccluders::sphere_bits`).
    glass_index: (Vec<Option<usize>>, Vec<Option<usize>>),
    /// Where the sphere set is split: opaque spheres, glass spheres, transmission.
    glass: Option<GlassSet>,
    /// Whether a point light's spheres are culled (`ClearOf`) before their lane test
    /// ([`SPHERE_CULL`] unless a test sets it).
    sphere_cull: bool,
}

/// Whether [`PointOccluders::settle`] culls the spheres towards a point light by
/// `ClearOf` before the lane sphere test (off where a 16-lane value is one register).
///
/// The cull decides, per lane group, light and sphere, whether any segment of the
/// group can come near the sphere: a scalar f64 chain (the origins' box reduced from
/// the lanes and two square roots per group and light, then three square roots and a
/// division per sphere, each step waiting on the one before) that
/// saves the sphere's roots and root test in lanes where it says clear. With AVX-512
/// the lane test is one register wide and costs less than the chain: without the
/// cull, whitted_blur16 1024x768, 1 thread, `perf stat -e task-clock` (whole process,
/// 5 interleaved rounds, host load ~5 on 2 cores) went 1501/1536/1539 ms ->
/// 1428/1442/1485 ms (min/median/max), whitted_base 7 rounds median 162.0 -> 155.6 ms;
/// images byte-identical (a culled sphere is one the lane test finds no root on).
/// With AVX2 (two registers per lane value) not measured: the cull stays on there, as
/// it was.
pub const SPHERE_CULL: bool = !cfg!(target_feature = "avx512f");

impl PointOccluders {
    /// `Some` where the queue path (`wavefront::trace_shadows`) settles the shadow
    /// rays through the tiny scene alone: its batch queries go through the
    /// `TinyScene` (no moving geometry, instances or planes), and either no ray needs
    /// a second query (no `filter`) or the filter has a `tiny_pass`. The same
    /// conditions as `LaneOccluders::new`.
    pub fn new(accel: &SceneAccel, filter: Option<&ShadowFilter>) -> Option<PointOccluders> {
        let (tiny, glass) = tiny_shadow_scene(accel, filter)?;
        let spheres = tiny.spheres().to_vec();
        let glass_index = glass_index(&spheres, glass.as_ref());
        let planes: Vec<Option<AxisPlane>> = tiny.triangles().iter().map(AxisPlane::of).collect();
        let twins = (0..planes.len())
            .map(|i| planes[i].and_then(|p| (0..i).find(|&j| planes[j] == Some(p))))
            .collect();
        Some(PointOccluders {
            triangles: tiny.triangles().to_vec(),
            planes,
            twins,
            spheres,
            glass_index,
            glass,
            sphere_cull: SPHERE_CULL,
        })
    }

    /// The same occluders with the point lights' sphere cull on or off (the answers
    /// are the same either way; the tests settle both).
    #[cfg(test)]
    pub fn with_sphere_cull(mut self, on: bool) -> PointOccluders {
        self.sphere_cull = on;
        self
    }

    /// Settles the shadow rays of the set lanes of `s` (`origin + t dir`, `t` in
    /// `(0, tmax)`); `light` is the point they all end at (a point light's position),
    /// `None` for a directional light (unbounded rays: no sphere cull). The spheres
    /// towards a point light are culled first where `sphere_cull` is set.
    #[inline(always)]
    pub fn settle(&self, s: &ShadowLanes, light: Option<Vec3>) -> LaneSettled {
        let one = V3::splat(Vec3::ONE);
        let live = s.mask & 0xffff;
        let lanes = RayLanes {
            o: [s.origin.x, s.origin.y, s.origin.z],
            d: [s.dir.x, s.dir.y, s.dir.z],
            tmin: Packet::splat(0.0),
        };
        let tmax = s.tmax;
        // Tried and not kept (helper bl25, 2026-11-29): `valid` from `tiny::valid_lanes`
        // (the keys' union) and the six key masks computed only where a triangle is left
        // to test (the floor culls its triangles for nearly every lane by `leaving`);
        // `lane_shear_keys` was 2.1 % of `shade_group_lanes`' samples. Images
        // byte-identical, but whitted_blur16 1024x768, 1 thread, 7 interleaved rounds,
        // load ~4: process CPU (`perf stat -e task-clock`) min/median/max
        // 1039.2/1058.4/1119.9 -> 1043.1/1057.6/1091.5 ms: no change.
        let keys = lane_shear_keys(&lanes, tmax);
        let valid = keys.iter().fold(0, |a, &k| a | k) & live;
        if valid == 0 {
            // Nothing tested: every live lane passes unblocked (invalid rays).
            return LaneSettled {
                pass: live,
                factor: one,
                settled: 0,
            };
        }
        // Per triangle, the valid lanes that may meet it.
        let mut reach = [valid; TINY_MAX_PRIMITIVES];
        // The union of the triangles' `reach`, kept in a register as each is decided.
        //
        // Before: folded after the loop from the stored array, a masked vector load of
        // words just stored one at a time (no store forwarding): its first instruction
        // held 2.7 % of `shade_group_lanes`' samples (perf annotate, whitted_blur16, 1
        // thread, AVX-512).
        let mut any_reach = 0;
        for (i, (plane, twin)) in self.planes.iter().zip(&self.twins).enumerate() {
            match (plane, *twin) {
                (Some(_), Some(j)) => reach[i] = reach[j],
                (Some(p), None) => reach[i] &= !p.leaving(&s.origin, &s.dir, valid),
                (None, _) => {}
            }
            any_reach |= reach[i];
        }
        let mut tri = 0u32;
        if any_reach != 0 {
            for (key, &bits) in keys.iter().enumerate() {
                let mask = bits & any_reach;
                if mask == 0 {
                    continue;
                }
                let g = TinyGroup::from_lanes(key, lanes, tmax, mask);
                let mut t = 0;
                for (corners, reach) in self.triangles.iter().zip(reach) {
                    let test = mask & reach & !t;
                    if test != 0 {
                        t |= g.triangle_blocks(corners, test);
                    }
                }
                tri |= t;
            }
        }
        let rest = valid & !tri;
        if rest == 0 || self.spheres.is_empty() {
            return LaneSettled {
                pass: live & !tri,
                factor: one,
                settled: 0,
            };
        }
        // The spheres near the remaining lanes' segments (all for a directional light),
        // each decided once: the glass set's lists take their bits from `all`.
        //
        // Before: the opaque and the glass list were culled again where a lane met a
        // sphere, with the origins' ball recomputed each time (three balls and twice
        // the `sphere_clear` calls per lane group and light). With the ball in lanes
        // (`origin_ball`), perf samples of whitted_blur16 (1 thread, -F 2000, machine
        // loaded ~12 on 2 cores): `shade_group_lanes` + this function's closure +
        // `sphere_clear` 1632 -> 1151 (the two changes and `direct_light`'s together;
        // images byte-identical).
        //
        // The terms shared by the spheres are computed once per group and light
        // (`ClearOf`, the same answers as `sphere_clear` per sphere).
        let clear_of = light
            .filter(|_| self.sphere_cull)
            .map(|l| ClearOf::new(l, origin_ball(&s.origin, rest)));
        let near = |&(c, r): &(Vec3, f32)| !clear_of.as_ref().is_some_and(|k| k.clear(c, r));
        let all = near_bits(&self.spheres, near);
        let bits = |list: &[(Vec3, f32)], index: &[Option<usize>]| {
            listed_near_bits(list, index, all, near)
        };
        // Each near sphere's roots are computed once and kept for the glass
        // settlement (`settle_near_spheres`, as the quad lights do).
        //
        // Before: `sphere_lanes` per near sphere, then `settle_gathered` computing the
        // roots of the spheres the lanes met again (the chrome and the glass sphere's
        // roots twice wherever a lane group met them).
        settle_near_spheres(
            &lanes,
            tmax,
            (live, tri, rest),
            &self.spheres,
            all,
            self.glass.as_ref(),
            &self.glass_index,
            |(opaque, glass, _)| {
                let (oi, gi) = &self.glass_index;
                (bits(opaque, oi), bits(glass, gi))
            },
        )
    }
}

/// Settles the lanes of `s` with `occluders` and adds what reaches the light to `sum`
/// (`contribution * weight * factor`, the queue path's products): the ray counts as
/// the queue path counts them (`shadow` per live lane, `transmitted_shadow` per lane
/// settled through glass). Returns the lanes that added a term.
#[inline(always)]
pub(crate) fn settle_and_sum(
    occluders: &PointOccluders,
    s: &ShadowLanes,
    light: Option<Vec3>,
    weight: V3,
    sum: &mut V3,
    rays: &mut crate::stats::RayCounts,
) -> u32 {
    let live = s.mask & 0xffff;
    if live == 0 {
        return 0;
    }
    rays.shadow += live.count_ones() as u64;
    let settled = occluders.settle(s, light);
    rays.transmitted_shadow += settled.settled.count_ones() as u64;
    if settled.pass == 0 {
        return 0;
    }
    let c = s.contribution.times(weight).times(settled.factor);
    let pass = <Packet as Lanes>::mask_from_bits(settled.pass);
    *sum = sum.plus(V3::select(pass, c, V3::splat(Vec3::ZERO)));
    settled.pass
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{AccelKind, BatchScratch, TinyScratch};
    use crate::geometry::gamma;
    use crate::integrator::RenderOptions;
    use crate::integrator::camera_rays::SamplePlan;
    use crate::integrator::queues::{PerChildKind, RayQueue, ShadowQueue};
    use crate::integrator::shade_stage::{LaneShading, ShadeScratch, Sinks, shade_queue};
    use crate::integrator::shader::{ChildKind, Emitted, Shader};
    use crate::scene::{Camera, Light, Material, Scene, SceneBuilder};
    use crate::simd::shadow_cull::sphere_clear;
    use crate::stats::{EffectSamplesDrawn, RayCounts};

    /// A tiny scene of the Whitted rows' kind: an axis-aligned floor quad, a tilted
    /// triangle (no axis plane: always tested), a mirror, a glass and a small opaque
    /// sphere; two point lights, one low enough that its rays graze the spheres, and a
    /// directional light.
    fn scene() -> Scene {
        let mut b = SceneBuilder::new();
        let floor = b.add_material(Material {
            specular: Vec3::splat(0.3),
            shininess: 40.0,
            ..Material::diffuse("floor", Vec3::new(0.8, 0.6, 0.4))
        });
        let chrome = b.add_material(Material {
            diffuse: Vec3::splat(0.1),
            specular: Vec3::splat(0.6),
            shininess: 200.0,
            ..Material::mirror("chrome", Vec3::splat(0.8))
        });
        let glass = b.add_material(Material {
            transmission: Vec3::new(0.9, 0.7, 0.5),
            ..Material::glass("glass", 1.5)
        });
        b.add_quad(
            Vec3::new(-12.0, 0.0, -12.0),
            Vec3::new(0.0, 0.0, 24.0),
            Vec3::new(24.0, 0.0, 0.0),
            floor,
        );
        b.add_triangle(
            Vec3::new(2.5, 0.0, 1.5),
            Vec3::new(4.0, 2.5, 0.5),
            Vec3::new(3.0, 0.2, -0.5),
            floor,
        );
        b.add_sphere(Vec3::new(1.1, 1.3, -1.4), 1.3, chrome);
        b.add_sphere(Vec3::new(-0.9, 1.0, 1.0), 1.0, glass);
        b.add_sphere(Vec3::new(-2.5, 0.4, -0.5), 0.4, floor);
        b.add_light(Light::Point {
            position: Vec3::new(-5.0, 9.0, 7.0),
            intensity: Vec3::splat(60.0),
        });
        b.add_light(Light::Point {
            position: Vec3::new(4.0, 1.5, 3.0),
            intensity: Vec3::splat(20.0),
        });
        b.add_light(Light::Directional {
            direction: Vec3::new(0.4, -1.0, -0.3),
            irradiance: Vec3::splat(0.7),
        });
        b.camera = Some(Camera {
            eye: Vec3::new(0.0, 3.0, 9.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            vfov_deg: 75.0,
        });
        b.finish().expect("the test scene")
    }

    fn sinks(scene: &Scene, slots: usize) -> Sinks {
        Sinks {
            acc: vec![Vec3::ZERO; slots],
            slot_pixel: (0..slots as u64).collect::<Vec<_>>().into(),
            next: PerChildKind::default(),
            shadow: (0..scene.lights.len())
                .map(|_| ShadowQueue::default())
                .collect(),
            area: scene.lights.iter().map(Light::is_area).collect(),
            emitted: Emitted::default(),
            rays: RayCounts::default(),
            drawn: EffectSamplesDrawn::default(),
        }
    }

    /// The queue path's answer for every ray of `rays` (`wavefront::trace_shadows` for
    /// a tiny scene): the `TinyShadow` pass where a filter is on, else the tiny
    /// scene's occlusion batch.
    fn queue_transmittance(
        accel: &SceneAccel,
        filter: Option<&ShadowFilter>,
        rays: &[crate::geometry::Ray],
        counts: &mut RayCounts,
    ) -> Vec<Vec3> {
        let mut t = Vec::new();
        if let Some(pass) = filter.and_then(|f| f.tiny_pass(accel)) {
            pass.transmittance_batch(rays, &mut t, &mut TinyScratch::default(), counts);
        } else {
            assert!(filter.is_none(), "a filter without a tiny pass");
            let mut blocked = vec![false; rays.len()];
            accel.any_hit_batch(rays, &mut blocked, &mut BatchScratch::default());
            t = blocked
                .iter()
                .map(|&b| if b { Vec3::ZERO } else { Vec3::ONE })
                .collect();
        }
        t
    }

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Every field of a child queue, bit for bit.
    type QueueBits = (
        Vec<[u32; 9]>,
        Vec<u32>,
        Vec<[u32; 3]>,
        Vec<[u32; 3]>,
        Vec<u64>,
    );

    fn queue_bits(q: &Option<RayQueue>) -> Option<QueueBits> {
        q.as_ref().map(|q| {
            let ray = |r: &crate::geometry::Ray| {
                let [a, b, c] = bits(r.origin);
                let [d, e, f] = bits(r.dir);
                let rest = [r.tmin, r.tmax, r.time].map(f32::to_bits);
                [a, b, c, d, e, f, rest[0], rest[1], rest[2]]
            };
            let (slot, weight, throughput, path) = q.per_ray();
            (
                q.rays.iter().map(ray).collect(),
                slot,
                weight.into_iter().map(bits).collect(),
                throughput.into_iter().map(bits).collect(),
                path,
            )
        })
    }

    /// The shading lanes' settlement against the queue path, ray for ray and sum for
    /// sum, on real hits: camera rays and two waves of their children, transmitted
    /// shadows on (the `TinyShadow` glass pass) and off (the plain occlusion batch).
    ///
    /// Ray for ray: the queued shadow rays of each point and directional light, taken
    /// sixteen at a time into lanes and settled by [`PointOccluders::settle`] (with
    /// and without the sphere cull: the same answers bit for bit), pass exactly where the queue path's transmittance is not zero, with
    /// its factor bit for bit, and count the same rays settled through glass.
    ///
    /// Sum for sum: shading with the occluders (nothing queued for those lights)
    /// against shading into the queues then settling them: the same ray counts, samples
    /// drawn and child rays bit for bit, and each camera sample's radiance within
    /// `2 γ_N` relative, `N` the terms the queue path added to it (see the module).
    #[test]
    fn lane_settled_point_lights_match_the_queue_path_on_real_hits() {
        let scene = scene();
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        assert!(accel.tiny.is_some(), "the test scene is a tiny one");
        let ends: Vec<Option<Vec3>> = scene
            .lights
            .iter()
            .map(|l| match *l {
                Light::Point { position, .. } => Some(position),
                _ => None,
            })
            .collect();
        let (mut compared, mut blocked, mut through_glass, mut sums, mut differ) = (0, 0, 0, 0, 0);
        let (mut culled_spheres, mut settled_both) = (0, 0);
        for transmitted in [true, false] {
            let name = format!("transmitted shadows {transmitted}");
            let mut opts = RenderOptions::from_scene(&scene);
            opts.transmitted_shadows = transmitted;
            let plan = SamplePlan::new(&scene, &opts);
            let shader = Shader::new(&scene, &opts, plan);
            let filter = ShadowFilter::new(&scene, transmitted, accel.kind);
            assert_eq!(filter.is_some(), transmitted, "{name}");
            let occluders = PointOccluders::new(&accel, filter.as_ref()).expect("applies");
            // The other setting of the sphere cull than this build's: both must give
            // the queue path's answers.
            let other = PointOccluders::new(&accel, filter.as_ref())
                .expect("applies")
                .with_sphere_cull(!SPHERE_CULL);
            let queued = LaneShading::new(&scene, plan.environment).expect("lane path");
            let fused = LaneShading::new(&scene, plan.environment)
                .expect("lane path")
                .with_point_occluders(PointOccluders::new(&accel, filter.as_ref()));
            let (w, h) = (128, 96);
            let frame = scene.camera.frame(w, h);
            let queue = RayQueue::pixel_centres(&frame, w, h, plan.first_path());
            let slots = (w * h) as usize;
            let mut scratch = ShadeScratch::default();
            let mut queues = vec![(queue, 0)];
            while let Some((queue, depth)) = queues.pop() {
                let at = format!("{name} depth {depth}");
                let hits: Vec<_> = queue.rays.iter().map(|r| accel.closest_hit(r)).collect();
                let (mut a, mut b) = (sinks(&scene, slots), sinks(&scene, slots));
                shade_queue(
                    &shader,
                    Some(&fused),
                    &queue,
                    &hits,
                    depth,
                    &mut a,
                    &mut scratch,
                );
                shade_queue(
                    &shader,
                    Some(&queued),
                    &queue,
                    &hits,
                    depth,
                    &mut b,
                    &mut scratch,
                );
                assert!(a.shadow.iter().all(|q| q.rays.is_empty()), "{at}: queued");
                // Terms of each camera sample: its rays' local radiance, then its
                // unblocked shadow rays.
                let mut terms = vec![0u32; slots];
                for slot in (0..queue.rays.len()).map(|i| queue.slot(i)) {
                    terms[slot as usize] += 1;
                }
                let mut queue_counts = b.rays;
                for (light, q) in b.shadow.iter_mut().enumerate() {
                    let mut counts = RayCounts::default();
                    let t = queue_transmittance(&accel, filter.as_ref(), &q.rays, &mut counts);
                    queue_counts.transmitted_shadow += counts.transmitted_shadow;
                    let mut lane_glass = 0u64;
                    for (c, chunk) in q.rays.chunks(16).enumerate() {
                        let lane = |f: &dyn Fn(&crate::geometry::Ray) -> f32| {
                            let mut v = [0.0f32; 16];
                            for (x, r) in v.iter_mut().zip(chunk) {
                                *x = f(r);
                            }
                            Packet::new(v)
                        };
                        let s = ShadowLanes {
                            origin: V3 {
                                x: lane(&|r| r.origin.x),
                                y: lane(&|r| r.origin.y),
                                z: lane(&|r| r.origin.z),
                            },
                            dir: V3 {
                                x: lane(&|r| r.dir.x),
                                y: lane(&|r| r.dir.y),
                                z: lane(&|r| r.dir.z),
                            },
                            tmax: lane(&|r| r.tmax),
                            contribution: V3::splat(Vec3::ONE),
                            mask: ((1u64 << chunk.len()) - 1) as u32,
                        };
                        if let Some(l) = ends[light] {
                            let (g, rho) = origin_ball(&s.origin, s.mask);
                            culled_spheres += occluders
                                .spheres
                                .iter()
                                .filter(|&&(c, r)| sphere_clear(l, (g, rho), c, r))
                                .count();
                        }
                        let settled = occluders.settle(&s, ends[light]);
                        let o = other.settle(&s, ends[light]);
                        assert_eq!(
                            (o.pass, o.settled),
                            (settled.pass, settled.settled),
                            "{at} light {light}: sphere cull {}",
                            !SPHERE_CULL
                        );
                        for i in 0..16 {
                            if settled.pass >> i & 1 == 1 {
                                let (a, b) = (o.factor.lane(i), settled.factor.lane(i));
                                assert_eq!(bits(a), bits(b), "{at}: factor of lane {i}");
                            }
                        }
                        settled_both += 1;
                        lane_glass += settled.settled.count_ones() as u64;
                        for (i, &t) in t[c * 16..c * 16 + chunk.len()].iter().enumerate() {
                            let pass = settled.pass >> i & 1 == 1;
                            assert_eq!(pass, t != Vec3::ZERO, "{at} light {light} ray {i}");
                            if pass {
                                assert_eq!(bits(settled.factor.lane(i)), bits(t), "{at}");
                            }
                            blocked += !pass as usize;
                            compared += 1;
                        }
                    }
                    assert_eq!(lane_glass, counts.transmitted_shadow, "{at} light {light}");
                    through_glass += lane_glass;
                    for ((&t, &slot), &c) in t.iter().zip(&q.slot).zip(&q.contribution) {
                        if t != Vec3::ZERO {
                            b.acc[slot as usize] += c * t;
                            terms[slot as usize] += 1;
                        }
                    }
                    q.clear();
                }
                assert_eq!(a.rays, queue_counts, "{at}: ray counts");
                assert_eq!(a.drawn, b.drawn, "{at}: samples drawn");
                for (slot, (x, y)) in a.acc.iter().zip(&b.acc).enumerate() {
                    let n = terms[slot];
                    let tol = 2.0 * gamma(n) * x.abs().max(y.abs());
                    for c in 0..3 {
                        assert!(
                            (x[c] - y[c]).abs() <= tol[c],
                            "{at} sample {slot}: lanes {x} queue {y} ({n} terms)"
                        );
                    }
                    differ += (bits(*x) != bits(*y)) as usize;
                    sums += 1;
                }
                for kind in ChildKind::ALL {
                    let qa = &mut a.next[kind];
                    assert!(
                        queue_bits(qa) == queue_bits(&b.next[kind]),
                        "{at}: {kind:?}"
                    );
                    if depth < 2
                        && let Some(q) = qa.take()
                        && !q.rays.is_empty()
                    {
                        queues.push((q, depth + 1));
                    }
                }
            }
        }
        eprintln!(
            "point shadows in lanes: {compared} rays compared, {blocked} blocked, \
             {through_glass} through glass, {culled_spheres} group-sphere tests culled; \
             {differ} of {sums} camera-sample sums not bit-equal; {settled_both} lane groups \
             settled with and without the sphere cull"
        );
        assert!(settled_both > 1_000, "{settled_both} lane groups");
        assert!(compared > 30_000, "{compared} rays");
        assert!(blocked > 1_000 && through_glass > 500 && culled_spheres > 2_000);
    }
}
