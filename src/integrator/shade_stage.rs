//! The wavefront's shading stage ([`shade_queue`]): the hits of a wave are gathered
//! into a [`HitBatch`] (structure of arrays, grouped by material by a counting sort),
//! then each material group is shaded 16 hits at a time in lanes where the lane path
//! covers it ([`LaneShading`]), or hit by hit by the scalar [`Shader::shade_emit`].
//!
//! The lane path (`simd::direct_light`): checkerboard albedo, emission and ambient,
//! and the shadow rays of every point and directional light with lanes over the hits; the shadow rays
//! of quad lights with lanes over the light samples of one hit; all written straight
//! into the per-light shadow queues. The child rays of mirrors and clear glass (no
//! random numbers) are built 16 hits at a time in lanes (`simd::specular`: reflection,
//! Schlick-Fresnel refraction, total internal reflection, both offset origins) in the
//! same pass over the group, then weighted and cut off hit by hit with the scalar
//! rules and queued with one extend per queue array and lane group; glossy and
//! translucent lobes come from the scalar [`Shader::emit_children`], hit by hit, after
//! the direct light, so that a shading point draws its random numbers in the scalar
//! order. Lanes repeat
//! the scalar f32 operations in order: the emitted rays are bit-identical, the
//! contributions differ only by the lane power function's error (a test checks both).
//!
//! The shadow rays of disk and sphere lights come from lanes over the light samples of
//! one hit too (`round_lights`), in scenes without quad lights.
//!
//! Not in lanes (the scalar shader handles them, per material or per scene): image
//! textures, spot lights, quad lights together with round ones, and the environment.

use super::area_light::{
    LightPoints, QuadLights, ShadingPoint, pack_stride, shade_quads, shade_quads_packed,
};
use super::hit_batch::HitBatch;
use super::path_keys::child_path;
use super::point_shadow::{PointOccluders, settle_and_sum};
use super::queues::{PerChildKind, RayQueue, ShadowQueue};
use super::round_lights::{RoundLight, shade_round};
use super::sampling::PixelRng;
use super::shader::{ChildKind, Emitted, Shader};
use super::slot_pixels::SlotPixels;
use super::tiny_shadow::LaneOccluders;
use crate::accel::SceneHit;
use crate::scene::{Light, Scene};
use crate::simd::Packet;
use crate::simd::direct_light::{
    Highlight, QuadLight, ShadowLanes, SurfaceLanes, checker_albedo, directional_light, point_light,
};
use crate::simd::lane_rays::lane_rays;
use crate::simd::lanes3::{V3, is_run, offset_ray_origin as lane_offset};
use crate::simd::ray_store::append_rays;
use crate::simd::specular;
use crate::stats::{EffectSamplesDrawn, RayCounts};
use glam::Vec3;

/// Where shading puts its results.
pub(crate) struct Sinks {
    /// Radiance of each camera sample of the batch in flight.
    pub acc: Vec<Vec3>,
    /// Image index of the pixel of each camera sample of the batch in flight.
    pub slot_pixel: SlotPixels,
    pub next: PerChildKind<Option<RayQueue>>,
    /// One shadow queue per light, so that the rays of a packet converge on one light
    /// (interleaving two lights' rays splits every packet by octant).
    pub shadow: Vec<ShadowQueue>,
    /// Whether each light is an area light (its queue is the area-shadow stage).
    pub area: Vec<bool>,
    pub emitted: Emitted,
    pub rays: RayCounts,
    pub drawn: EffectSamplesDrawn,
}

/// Scratch of the shading stage, reused across waves.
#[derive(Default)]
pub(crate) struct ShadeScratch {
    pub batch: HitBatch,
    albedo: Vec<Vec3>,
    /// The light points of one hit (`area_light`).
    light: LightPoints,
    /// The reflected and refracted children of one lane group (`specular_children`),
    /// reused: only the entries below each one's count are read.
    children: Box<[Children; 2]>,
}

/// What the lane path of a scene needs: which materials it covers and the lights in
/// lane form. `None` from [`LaneShading::new`] when a light or the environment is
/// outside it (then every hit is shaded by the scalar shader).
pub(crate) struct LaneShading {
    /// Per material: shaded in lanes (no image texture on the diffuse or specular colour).
    covered: Vec<bool>,
    points: Vec<(u32, Vec3, Vec3)>,
    /// `(light, wi, irradiance)`: `wi` towards the light, as the scalar shader's.
    directional: Vec<(u32, Vec3, Vec3)>,
    quads: QuadLights,
    /// The disk and sphere lights (`round_lights`), in light order. A scene has these
    /// or quads in lanes, not both (one point's streams are drawn light by light).
    round: Vec<(u32, RoundLight)>,
    /// Where set, the point and directional lights' shadow rays are settled in the
    /// shading lanes instead of queued (`point_shadow`).
    point_occluders: Option<PointOccluders>,
}

impl LaneShading {
    pub fn new(scene: &Scene, environment_samples: u32) -> Option<LaneShading> {
        if scene.environment.is_some() && environment_samples > 0 {
            return None;
        }
        let mut points = Vec::new();
        let mut directional = Vec::new();
        let mut quads = QuadLights::default();
        let mut round = Vec::new();
        for (i, light) in scene.lights.iter().enumerate() {
            match *light {
                Light::Point {
                    position,
                    intensity,
                } => points.push((i as u32, position, intensity)),
                Light::Directional {
                    direction,
                    irradiance,
                } => directional.push((i as u32, -direction.normalize(), irradiance)),
                Light::Quad {
                    corner,
                    edge1,
                    edge2,
                    radiance,
                } => quads
                    .lights
                    .push((i as u32, QuadLight::new(corner, edge1, edge2, radiance))),
                Light::Disk { .. } | Light::Sphere { .. } => {
                    round.push((i as u32, RoundLight::of(light)?))
                }
                _ => return None,
            }
        }
        if !quads.is_empty() && !round.is_empty() {
            return None;
        }
        Some(LaneShading {
            covered: scene
                .materials
                .iter()
                .map(|m| m.textures.diffuse.is_none() && m.textures.specular.is_none())
                .collect(),
            points,
            directional,
            quads,
            round,
            point_occluders: None,
        })
    }

    /// The quad lights in lane form (tests).
    #[cfg(test)]
    pub fn quads(&self) -> &QuadLights {
        &self.quads
    }

    /// Settles the quad lights' samples in lanes with `occluders` where given, instead
    /// of queueing them (`area_light`).
    pub fn with_area_occluders(mut self, occluders: Option<LaneOccluders>) -> LaneShading {
        self.quads.occluders = occluders;
        self
    }

    /// Settles the point and directional lights' shadow rays in the shading lanes with
    /// `occluders` where given, and sums their contributions there with the local
    /// radiance, instead of queueing them (`point_shadow`).
    pub fn with_point_occluders(mut self, occluders: Option<PointOccluders>) -> LaneShading {
        self.point_occluders = occluders;
        self
    }
}

/// Shades every ray of `queue` (at wave `depth`) with its hit, emitting into `sinks`:
/// misses add the background, hits are batched by material and shaded in lanes where
/// `lanes` covers their material, else by the scalar shader.
pub(crate) fn shade_queue(
    shader: &Shader,
    lanes: Option<&LaneShading>,
    queue: &RayQueue,
    hits: &[Option<SceneHit>],
    depth: u32,
    sinks: &mut Sinks,
    scratch: &mut ShadeScratch,
) {
    let scene = shader.scene;
    scratch.batch.build(scene, &queue.rays, hits);
    // The misses, from the batch's material pass (one pass over the hits, not two).
    // Camera rays against a plain background (no environment) add the same value,
    // `weight * background` with weight one, to consecutive slots: the queue's camera
    // run and the background settled once, not per miss (before, each miss matched
    // the queue's kind twice and the environment once, and loaded its 52-byte ray).
    let camera_plain = queue
        .camera_first_slot()
        .filter(|_| scene.environment.is_none());
    if let Some(first) = camera_plain {
        let add = Vec3::ONE * scene.background;
        let acc = &mut sinks.acc[first as usize..];
        for i in scratch.batch.misses() {
            acc[i] += add;
        }
    } else {
        for i in scratch.batch.misses() {
            let slot = queue.slot(i) as usize;
            sinks.acc[slot] += queue.weight(i) * scene.miss_radiance(queue.rays[i].dir);
        }
    }
    let groups = std::mem::take(&mut scratch.batch.groups);
    for (material, range) in &groups {
        match lanes {
            Some(l) if l.covered[*material as usize] => {
                shade_group_lanes(
                    shader,
                    l,
                    *material,
                    range.clone(),
                    queue,
                    depth,
                    sinks,
                    scratch,
                );
            }
            _ => {
                for k in range.clone() {
                    shade_scalar(shader, &scratch.batch, *material, k, queue, depth, sinks);
                }
            }
        }
    }
    scratch.batch.groups = groups;
}

/// Hit `k` of the batch through the scalar shader.
fn shade_scalar(
    shader: &Shader,
    batch: &HitBatch,
    material: u32,
    k: usize,
    queue: &RayQueue,
    depth: u32,
    sinks: &mut Sinks,
) {
    let i = batch.ray[k] as usize;
    let si = batch.interaction(k, material);
    let slot = queue.slot(i);
    let weight = queue.weight(i);
    let pixel = sinks.slot_pixel.get(slot);
    let out = &mut sinks.emitted;
    shader.shade_emit(
        batch.dir.get(k),
        queue.rays[i].time,
        &si,
        depth,
        queue.throughput(i),
        pixel,
        queue.path(i),
        out,
        &mut sinks.rays,
        &mut sinks.drawn,
    );
    sinks.acc[slot as usize] += weight * out.local;
    for s in &out.shadow {
        let q = &mut sinks.shadow[s.light as usize];
        q.rays.push(s.ray);
        q.slot.push(slot);
        q.contribution.push(weight * s.contribution);
    }
    push_children(&mut sinks.next, &sinks.emitted, slot, weight);
}

/// The child rays of one shading point into the next wave's queues.
fn push_children(
    next: &mut PerChildKind<Option<RayQueue>>,
    out: &Emitted,
    slot: u32,
    weight: Vec3,
) {
    for c in &out.children {
        let q = next[c.kind].get_or_insert_with(RayQueue::default);
        q.push(c.ray, slot, weight * c.weight, c.throughput, c.path);
    }
}

/// Per lane: the camera sample, the weight and the time of the ray that made the hit
/// (or of the one hit whose light samples the lanes are).
#[derive(Default)]
pub(super) struct LanePaths {
    slot: [u32; 16],
    weight: [[f32; 16]; 3],
    time: [f32; 16],
}

impl LanePaths {
    /// Every lane from one hit.
    pub(super) fn splat(slot: u32, weight: Vec3, time: f32) -> Self {
        LanePaths {
            slot: [slot; 16],
            weight: [[weight.x; 16], [weight.y; 16], [weight.z; 16]],
            time: [time; 16],
        }
    }

    fn weight(&self) -> V3 {
        V3::load(&self.weight[0], &self.weight[1], &self.weight[2])
    }
}

/// Adds lane `i` of `sums` to the camera sample `slot[i]`, for the `n` lanes of a
/// group. Where the sixteen slots are consecutive (a run of one material's hits in a
/// camera wave: each pixel's samples are consecutive queue entries, and their children
/// keep their order) the sums go in as three 16-float windows ([`V3::add_to`]), else
/// lane by lane; the same sums either way (each slot of a group is a different camera
/// sample: one hit per ray).
///
/// Before: the lane-by-lane loop for every group, a bounds check and three scalar
/// loads, adds and stores per lane: 3.8 % of `shade_group_lanes`' samples (perf,
/// whitted_blur16, 1 thread).
#[inline(always)]
fn add_sums(acc: &mut [Vec3], slot: &[u32; 16], n: usize, sums: &V3) {
    let first = slot[0] as usize;
    if n == 16
        && is_run(slot)
        && let Some(dst) = acc.get_mut(first..first + 16)
    {
        let dst: &mut [Vec3; 16] = dst.try_into().expect("16 samples");
        sums.add_to(dst);
        return;
    }
    let [sx, sy, sz] = [sums.x, sums.y, sums.z].map(|p| p.to_array());
    for (i, &s) in slot[..n].iter().enumerate() {
        acc[s as usize] += Vec3::new(sx[i], sy[i], sz[i]);
    }
}

/// The shadow rays of the set lanes of `s` into `q`; lane `i` belongs to the camera
/// sample `paths.slot[i]`, keeps the time `paths.time[i]`, and its contribution is
/// scaled by `weight` (`paths`' weights as lanes; the same f32 product as the scalar
/// `weight * contribution`). The queue's arrays are each extended once per call, from
/// the set lanes in order: all sixteen (the common case: every hit of a floor or wall
/// group faces the light) by a loop over constant lane indices, else lane by lane over
/// the set bits.
///
/// Measured (perf, whitted_aa3x3, 1 thread): building each ray from the lane arrays at
/// an index taken from the mask (a bounds check per field) and extending three arrays
/// hit by hit was about a fifth of `shade_group_lanes`. The rays come out of their
/// lanes by a transpose ([`lane_rays`]; see there for its measurement).
pub(super) fn push_shadow(
    q: &mut ShadowQueue,
    s: &ShadowLanes,
    paths: &LanePaths,
    weight: V3,
    rays: &mut RayCounts,
) {
    let mask = s.mask & 0xffff;
    if mask == 0 {
        return;
    }
    let arr = |v: &V3| [v.x.to_array(), v.y.to_array(), v.z.to_array()];
    let lane_rays = lane_rays(&s.origin, &s.dir, s.tmax, &paths.time);
    let c = arr(&s.contribution.times(weight));
    let ray = |i: usize| lane_rays[i & 15];
    let contribution = |i: usize| Vec3::new(c[0][i], c[1][i], c[2][i]);
    if mask == 0xffff {
        rays.shadow += 16;
        q.rays.extend_from_slice(&lane_rays);
        q.slot.extend_from_slice(&paths.slot);
        q.contribution.extend((0..16).map(contribution));
        return;
    }
    let n = mask.count_ones() as usize;
    let mut set = [0usize; 16];
    let mut bits = mask;
    for k in set.iter_mut().take(n) {
        // Below 16: `mask` has no higher bit.
        *k = bits.trailing_zeros() as usize & 15;
        bits &= bits - 1;
    }
    let set = &set[..n];
    rays.shadow += n as u64;
    q.rays.extend(set.iter().map(|&i| ray(i)));
    q.slot.extend(set.iter().map(|&i| paths.slot[i]));
    q.contribution.extend(set.iter().map(|&i| contribution(i)));
}

/// One material group in lanes: local light and point lights 16 hits at a time, then
/// per hit the quad lights (lanes over samples) and the child rays.
#[allow(clippy::too_many_arguments)]
fn shade_group_lanes(
    shader: &Shader,
    lanes: &LaneShading,
    material: u32,
    range: std::ops::Range<usize>,
    queue: &RayQueue,
    depth: u32,
    sinks: &mut Sinks,
    scratch: &mut ShadeScratch,
) {
    let scene = shader.scene;
    let m = &scene.materials[material as usize];
    let lit = Shader::is_lit(m);
    let hl = Highlight {
        specular: m.specular,
        shininess: m.shininess,
    };
    let batch = &scratch.batch;
    let albedo = &mut scratch.albedo;
    let kids = &mut scratch.children;
    albedo.clear();
    let spawns = m.mirror != Vec3::ZERO || m.is_glossy() || m.is_transmissive();
    // Mirrors and clear glass draw no random numbers: their child rays are built in
    // lanes in the loop below, from the lane group's loads (each queue receives only
    // its kind, in hit order, whatever else is queued in between). Glossy and
    // translucent lobes go through the scalar shader, hit by hit, after the hit's
    // light samples (the order of its random stream).
    let spawns = spawns && depth < shader.max_depth;
    let lane_children = spawns && !m.is_glossy() && !m.is_translucent();
    // The area-light loop below reads each hit's albedo; nothing else does.
    let keep_albedo = lit && !(lanes.quads.is_empty() && lanes.round.is_empty());
    let mut children = ChildPaths {
        throughput: [Vec3::ZERO; 16],
        path: [0; 16],
    };
    let mut j = range.start;
    while j < range.end {
        let n = (range.end - j).min(16);
        let active = if n == 16 { 0xffff } else { (1u32 << n) - 1 };
        // The camera sample, weight and time of each hit's ray, gathered once for the
        // shadow rays of every light and the local radiance. Gathered first: its
        // values are stored lane by lane and read back as lanes, and a load spanning
        // stores still in flight waits for them (before, the gather came after the
        // checker, right before the weight's loads). Measured with the camera paths'
        // remainders (`CameraRun::paths`), 1 thread, host load ~4.7, interleaved:
        // shade stage medians aa3x3 740 -> 727 ms (11 rounds), blur16 1524 -> 1473 ms
        // (7 rounds), within the host's noise.
        //
        // Tried and not kept (helper blur26, 2026-11-29): the gather one lane group
        // ahead (two `LanePaths` and `ChildPaths` alternating, the next group's gathered
        // before this group's work), so that its scalar stores have reached the cache
        // when the group loads them as lanes. Images byte-identical; whitted_blur16
        // 512x384, 1 thread, 21 interleaved rounds, load ~2 (both on top of the
        // whole-register loads and splats recorded at `simd::lanes`' `impl_lanes!`):
        // `perf stat -e task-clock` median 301.8 ms with it against 291.3 ms without,
        // render min 244.5 against 239.7 ms (the gather became an out-of-line call).
        // The multiply that seemed to wait on the weights was waiting on `albedo`.
        let mut paths = LanePaths::default();
        queue.gather(
            &batch.ray[j..j + n],
            &mut paths.slot,
            &mut paths.weight,
            &mut paths.time,
            lane_children.then_some((&mut children.throughput, &mut children.path)),
        );
        let ng = batch.ng.lanes(j);
        let d = batch.dir.lanes(j);
        let mut s = SurfaceLanes {
            p: batch.p.lanes(j),
            p_error: batch.p_error.lanes(j),
            ng,
            ns: batch.ns.lanes(j),
            base: batch.base.lanes(j),
            smooth: Packet::new(batch.smooth[j..j + 16].try_into().expect("16 lanes")),
            wo: d.negated(),
            albedo: V3::splat(m.diffuse),
        };
        if lit && let Some(c) = &m.checker {
            // The winding normal, as the scalar shader's checker lookup.
            let front = Packet::new(batch.front[j..j + 16].try_into().expect("16 lanes"));
            let outward = V3::select(front, ng, ng.negated());
            let (a, mut redo) = checker_albedo(c, s.p, s.p_error, outward);
            s.albedo = a;
            redo &= active;
            if redo != 0 {
                // Cell indices past 2^24: the scalar lookup, lane by lane.
                let mut xyz = (a.x.to_array(), a.y.to_array(), a.z.to_array());
                while redo != 0 {
                    let i = redo.trailing_zeros() as usize;
                    redo &= redo - 1;
                    let o = outward.lane(i);
                    let v = m.albedo_on_surface(s.p.lane(i), s.p_error.lane(i), o);
                    (xyz.0[i], xyz.1[i], xyz.2[i]) = (v.x, v.y, v.z);
                }
                s.albedo = V3 {
                    x: Packet::new(xyz.0),
                    y: Packet::new(xyz.1),
                    z: Packet::new(xyz.2),
                };
            }
        }
        if keep_albedo {
            // The albedo lanes stored once (`V3::lane` stored all three vectors per hit).
            let [ax, ay, az] = [s.albedo.x, s.albedo.y, s.albedo.z].map(|p| p.to_array());
            albedo.extend((0..n).map(|i| Vec3::new(ax[i], ay[i], az[i])));
        }
        // Tried and not kept (helper bl25, 2026-11-29): for a camera run, the weights
        // as a splat of one (what `RayQueue::gather` fills them with) and the run of
        // `add_sums` read from the batch's indices, so that neither waits on the
        // gather's one-by-one stores (the multiply loading the weights held 2.9 % of
        // this function's samples, perf annotate, whitted_blur16, 1 thread). Images
        // byte-identical, but whitted_blur16 1024x768, 1 thread, two sets of 7
        // interleaved rounds, load ~5: process CPU medians 1050.0 -> 1062.6 and
        // 1013.7 -> 1017.6 ms (no gain).
        let weight = paths.weight();
        // `weight * (emission + ambient * albedo)` in lanes, the scalar shader's f32
        // operations, then added to each hit's camera sample in hit order.
        let local = if lit {
            V3::splat(m.emission).plus(V3::splat(scene.ambient).times(s.albedo))
        } else {
            V3::splat(m.emission)
        };
        let local = weight.times(local);
        let fused = lanes.point_occluders.as_ref().filter(|_| lit);
        if let Some(occluders) = fused {
            // The local radiance and every point and directional light's unblocked
            // term summed in the hit's lane, then added to its camera sample once
            // (`point_shadow`: the same terms, another order).
            let mut sum = local;
            for &(_, position, intensity) in &lanes.points {
                let sl = point_light(&s, &hl, position, intensity, active);
                settle_and_sum(
                    occluders,
                    &sl,
                    Some(position),
                    weight,
                    &mut sum,
                    &mut sinks.rays,
                );
            }
            for &(_, wi, irradiance) in &lanes.directional {
                let sl = directional_light(&s, &hl, wi, irradiance, active);
                settle_and_sum(occluders, &sl, None, weight, &mut sum, &mut sinks.rays);
            }
            add_sums(&mut sinks.acc, &paths.slot, n, &sum);
        } else {
            add_sums(&mut sinks.acc, &paths.slot, n, &local);
        }
        if lit && fused.is_none() {
            for &(index, position, intensity) in &lanes.points {
                let sl = point_light(&s, &hl, position, intensity, active);
                let q = &mut sinks.shadow[index as usize];
                push_shadow(q, &sl, &paths, weight, &mut sinks.rays);
            }
            for &(index, wi, irradiance) in &lanes.directional {
                let sl = directional_light(&s, &hl, wi, irradiance, active);
                let q = &mut sinks.shadow[index as usize];
                push_shadow(q, &sl, &paths, weight, &mut sinks.rays);
            }
        }
        if lane_children {
            let front = Packet::new(batch.front[j..j + 16].try_into().expect("16 lanes"));
            specular_children(shader, m, n, &s, d, front, &paths, &children, kids, sinks);
        }
        j += 16;
    }

    // Per hit below: the quad lights and the scalar child lobes. A group with neither
    // (every hit of whitted_base) skips the loop and its per-hit gathers.
    let quads = lit && !lanes.quads.is_empty();
    let round = lit && !lanes.round.is_empty();
    let scalar_children = spawns && !lane_children;
    if !(quads || round || scalar_children) {
        return;
    }
    let point = |k: usize, slot_pixel: &SlotPixels| {
        let q = batch.ray[k] as usize;
        let slot = queue.slot(q);
        ShadingPoint {
            batch,
            k,
            albedo: if quads || round {
                albedo[k - range.start]
            } else {
                Vec3::ZERO
            },
            hl,
            slot,
            weight: queue.weight(q),
            time: queue.rays[q].time,
            pixel: slot_pixel.get(slot),
            path: queue.path(q),
            depth,
        }
    };
    let children = |h: &ShadingPoint, stream: &mut Option<PixelRng>, sinks: &mut Sinks| {
        let q = batch.ray[h.k] as usize;
        let si = batch.interaction(h.k, material);
        let out = &mut sinks.emitted;
        out.children.clear();
        shader.emit_children(
            batch.dir.get(h.k),
            h.time,
            &si,
            depth,
            queue.throughput(q),
            h.pixel,
            h.path,
            stream,
            out,
            &mut sinks.rays,
            &mut sinks.drawn,
        );
        debug_assert!(
            out.children.iter().all(|c| c.kind != ChildKind::Refraction) || scene.features.glass,
            "a refracted ray from a scene without glass"
        );
        push_children(&mut sinks.next, &sinks.emitted, h.slot, h.weight);
    };
    // The quad lights of several points per lane group where a point's samples leave
    // lanes idle (`area_light::shade_quads_packed`): each point's sums added to its
    // camera sample in point order and light order, and its stream then handed to its
    // child lobes, as below.
    let packed = lanes
        .quads
        .occluders
        .as_ref()
        .filter(|_| quads)
        .zip(pack_stride(shader.plan.shadow));
    if let Some((occluders, stride)) = packed {
        let lights = lanes.quads.lights.len();
        let mut k = range.start;
        while k < range.end {
            let n = (range.end - k).min(16 / stride);
            let mut pts = [point(k, &sinks.slot_pixel); 16];
            for (j, h) in pts.iter_mut().enumerate().take(n).skip(1) {
                *h = point(k + j, &sinks.slot_pixel);
            }
            let pts = &pts[..n];
            let mut streams: [Option<PixelRng>; 16] = Default::default();
            let light = &mut scratch.light;
            let left = shade_quads_packed(
                shader,
                &lanes.quads,
                occluders,
                pts,
                stride,
                &mut streams,
                sinks,
                light,
            );
            for (j, (h, stream)) in pts.iter().zip(&mut streams).enumerate() {
                if left >> j & 1 == 1 {
                    shade_quads(shader, &lanes.quads, h, stream, sinks, light);
                } else {
                    for t in light.totals[j * lights..(j + 1) * lights].iter().flatten() {
                        sinks.acc[h.slot as usize] += *t;
                    }
                }
                if scalar_children {
                    children(h, stream, sinks);
                }
            }
            k += n;
        }
        return;
    }
    for k in range.clone() {
        let h = point(k, &sinks.slot_pixel);
        let mut stream = None;
        if quads {
            shade_quads(
                shader,
                &lanes.quads,
                &h,
                &mut stream,
                sinks,
                &mut scratch.light,
            );
        }
        if round {
            shade_round(
                shader,
                &lanes.round,
                &h,
                &mut stream,
                sinks,
                &mut scratch.light,
            );
        }
        if scalar_children {
            children(&h, &mut stream, sinks);
        }
    }
}

/// The child rays of one kind from one lane group, in the order the scalar shader
/// queues them: per entry the lane, the child's weight and throughput and its branch
/// number (what keys its path).
///
/// Kept in the stage's scratch and reset per lane group (`n = 0`): made afresh per
/// group, the two of them were two `memset` calls (1160 and 768 bytes) per lane group
/// of a mirror or glass.
struct Children {
    n: usize,
    lane: [usize; 32],
    w: [Vec3; 32],
    tp: [Vec3; 32],
    branch: [u32; 32],
}

impl Default for Children {
    fn default() -> Self {
        Children {
            n: 0,
            lane: [0; 32],
            w: [Vec3::ZERO; 32],
            tp: [Vec3::ZERO; 32],
            branch: [0; 32],
        }
    }
}

impl Children {
    fn add(&mut self, lane: usize, w: Vec3, tp: Vec3, branch: &mut u32) {
        // At most two per hit (the mirror's and the glass's reflection), 16 hits.
        let k = self.n & 31;
        (self.lane[k], self.w[k], self.tp[k], self.branch[k]) = (lane & 15, w, tp, *branch);
        self.n += 1;
        *branch += 1;
    }

    /// The entries into the queue `q` (created on the first entry, as the scalar
    /// `push_children` does), leaving from `origin` along `dir` (lanes).
    fn flush(
        &self,
        q: &mut Option<RayQueue>,
        paths: &LanePaths,
        children: &ChildPaths,
        origin: &V3,
        dir: &V3,
    ) {
        let n = self.n.min(32);
        if n == 0 {
            return;
        }
        let q = q.get_or_insert_with(RayQueue::default);
        let lanes = &self.lane[..n];
        let weight = |i: usize| {
            let w = &paths.weight;
            Vec3::new(w[0][i], w[1][i], w[2][i])
        };
        // The entries are lanes `0..n` in order (every hit of the group spawned one
        // child of this kind, or the first `n` did: a mirror's or a clear glass's
        // group, nearly always): the rays go from the lanes straight into the queue
        // (`ray_store::append_rays`, the camera stage's store: tmin 0, tmax infinite,
        // as `lane_rays` below builds them), with the other arrays extended by the
        // same `n` (`RayQueue::extend_with`).
        //
        // Before: every group through `lane_rays` (sixteen rays built on the stack)
        // and a copy of each kept one into the queue: `RayQueue::extend`'s ray copy
        // was a fifth of this function's samples and `lane_rays` an eighth (perf,
        // whitted_blur16, 1 thread).
        if n <= 16 && lanes.iter().enumerate().all(|(k, &i)| i == k) {
            let [ox, oy, oz] = [origin.x, origin.y, origin.z].map(|p| p.to_array());
            let [dx, dy, dz] = [dir.x, dir.y, dir.z].map(|p| p.to_array());
            q.extend_with(
                |rays| append_rays([&ox, &oy, &oz], [&dx, &dy, &dz], &paths.time, n, rays),
                paths.slot[..n].iter().copied(),
                self.w[..n].iter().enumerate().map(|(i, &w)| weight(i) * w),
                &self.tp[..n],
                self.branch[..n]
                    .iter()
                    .enumerate()
                    .map(|(i, &b)| child_path(children.path[i], b)),
            );
            return;
        }
        let rays = lane_rays(origin, dir, Packet::splat(f32::INFINITY), &paths.time);
        q.extend(
            lanes.iter().map(|&i| rays[i & 15]),
            lanes.iter().map(|&i| paths.slot[i]),
            lanes.iter().zip(&self.w).map(|(&i, &w)| weight(i) * w),
            &self.tp[..n],
            lanes
                .iter()
                .zip(&self.branch)
                .map(|(&i, &b)| child_path(children.path[i], b)),
        );
    }
}

/// Per lane of a group, besides its [`LanePaths`]: what the ray that made the hit
/// passes on to its children.
struct ChildPaths {
    throughput: [Vec3; 16],
    path: [u64; 16],
}

/// The child rays of the `n` hits `s` (one lane group, ray directions `d`, side
/// `front`) on the mirror or clear glass `m` (no glossy or translucent lobe), as
/// `Shader::emit_children` emits them: the origins and directions in lanes
/// (`simd::specular`, bit for bit the scalar optics), then per hit, in hit order, the
/// weights and the contribution cutoff with the scalar rules, and one extend of each
/// queue array per kind.
///
/// Measured (perf, whitted_aa3x3, 1 thread): pushing each child ray through
/// `RayQueue::push` (five arrays, each a capacity check) right where it was decided was
/// about a tenth of `shade_group_lanes`; run as a second pass over the group's hits it
/// loaded the surface lanes and gathered the paths' data a second time.
///
/// Tried and not kept: for a mirror alone or a clear glass alone, the weights and the
/// cutoff in lanes (throughputs gathered as x, y, z lanes, glam's `max_element` as two
/// selects, then one entry per kept lane); the shading test matched it bit for bit
/// (7052 reflected, 1094 refracted children) and the images were byte-identical, but
/// `perf stat -e task-clock`, whitted_base `--spp 9 --sampler grid`, 1 thread, 5
/// interleaved rounds, went from 751 ms (median, this loop) to 764 ms (base 761 ms).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn specular_children(
    shader: &Shader,
    m: &crate::scene::Material,
    n: usize,
    s: &SurfaceLanes,
    d: V3,
    front: Packet,
    paths: &LanePaths,
    cp: &ChildPaths,
    kids: &mut [Children; 2],
    sinks: &mut Sinks,
) {
    let mirror = m.mirror != Vec3::ZERO;
    let transmissive = m.is_transmissive();
    let min = shader.min_contribution;
    let (p, p_error, ng, ns) = (s.p, s.p_error, s.ng, s.ns);
    // Every reflected direction leaves on the facing side: one origin for them all.
    let out = lane_offset(p, p_error, ng, ng);
    let reflected = specular::reflection_dir(d, ns, ng);
    let glass = transmissive.then(|| {
        let g = specular::glass(d, ns, ng, front, m.ior);
        // Refraction leaves into the far side: offset against the facing normal.
        let inside = lane_offset(p, p_error, ng, ng.negated());
        (
            g.reflectance.to_array(),
            g.refracted,
            g.tir.to_bitmask(),
            inside,
        )
    });
    let [reflection, refraction] = kids;
    (reflection.n, refraction.n) = (0, 0);
    for i in 0..n.min(16) {
        let throughput = cp.throughput[i];
        let mut branch = 0;
        if mirror {
            let tp = throughput * m.mirror;
            if tp.max_element() >= min {
                reflection.add(i, m.mirror, tp, &mut branch);
            }
        }
        if let Some((reflectance, _, tir, _)) = &glass {
            let f = reflectance[i];
            if f > 0.0 {
                let tp = throughput * f;
                if tp.max_element() >= min {
                    reflection.add(i, Vec3::splat(f), tp, &mut branch);
                }
            }
            if tir >> i & 1 == 0 {
                let w = (1.0 - f) * m.transmission;
                let tp = throughput * w;
                if tp.max_element() >= min && w != Vec3::ZERO {
                    refraction.add(i, w, tp, &mut branch);
                }
            }
        }
    }
    sinks.rays.reflection += reflection.n as u64;
    sinks.rays.refraction += refraction.n as u64;
    let next = &mut sinks.next;
    reflection.flush(&mut next.reflection, paths, cp, &out, &reflected);
    if let Some((_, refracted, _, inside)) = &glass {
        refraction.flush(&mut next.refraction, paths, cp, inside, refracted);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{AccelKind, SceneAccel};
    use crate::geometry::Ray;
    use crate::integrator::RenderOptions;
    use crate::integrator::camera_rays::SamplePlan;
    use crate::scene::load::load_scene;
    use crate::simd::pow::{POW_REL_ERROR, POW_TINY};

    /// How far a lane contribution may be from the scalar one, relative. The lanes
    /// repeat every scalar f32 operation in order, except the Blinn-Phong power: the
    /// lane `pow` is within `POW_REL_ERROR` of the exact power and libm's `powf` within
    /// 1 ulp (2u, u = 2^-24), so the two powers differ by at most `POW_REL_ERROR + 2u`
    /// relative. The power then passes through `ks · P` (non-negative, added to the
    /// non-negative Lambert term, so its relative change bounds the sum's) and three
    /// products and one sum whose roundings may go either way on the two sides: 2u
    /// each, 8u. Total `POW_REL_ERROR + 10u`.
    const REL: f32 = POW_REL_ERROR + 10.0 * f32::EPSILON / 2.0;
    /// Below `POW_TINY` the power's error is absolute; scaled by the largest factor a
    /// shipped scene puts on it (intensity / distance² · ks · weight < 1e6).
    const ABS: f32 = POW_TINY * 1e6;

    fn sinks(scene: &Scene, slots: usize) -> Sinks {
        Sinks {
            acc: vec![Vec3::ZERO; slots],
            slot_pixel: (0..slots as u64).collect::<Vec<_>>().into(),
            next: PerChildKind::default(),
            shadow: (0..scene.lights.len() + scene.environment.is_some() as usize)
                .map(|_| ShadowQueue::default())
                .collect(),
            area: Vec::new(),
            emitted: Emitted::default(),
            rays: RayCounts::default(),
            drawn: EffectSamplesDrawn::default(),
        }
    }

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    fn ray_bits(r: &Ray) -> [u32; 9] {
        let [a, b, c] = bits(r.origin);
        let [d, e, f] = bits(r.dir);
        [
            a,
            b,
            c,
            d,
            e,
            f,
            r.tmin.to_bits(),
            r.tmax.to_bits(),
            r.time.to_bits(),
        ]
    }

    /// Compares what the lane path and the scalar path emitted; returns the number of
    /// shadow rays compared, how many of their contributions were not bit-equal, and
    /// the number of reflected and refracted child rays compared.
    fn compare(name: &str, lane: &Sinks, scalar: &Sinks) -> (usize, usize, [usize; 2]) {
        assert_eq!(lane.rays, scalar.rays, "{name}: ray counts");
        assert_eq!(lane.drawn, scalar.drawn, "{name}: samples drawn");
        // Emission and ambient: the same operations, bit for bit.
        for (slot, (a, b)) in lane.acc.iter().zip(&scalar.acc).enumerate() {
            assert_eq!(
                bits(*a),
                bits(*b),
                "{name}: local radiance of sample {slot}"
            );
        }
        let (mut compared, mut inexact, mut children) = (0, 0, [0, 0]);
        for (light, (a, b)) in lane.shadow.iter().zip(&scalar.shadow).enumerate() {
            assert_eq!(a.rays.len(), b.rays.len(), "{name}: light {light}");
            assert_eq!(a.slot, b.slot, "{name}: light {light}");
            for i in 0..a.rays.len() {
                assert_eq!(
                    ray_bits(&a.rays[i]),
                    ray_bits(&b.rays[i]),
                    "{name}: light {light} shadow ray {i}: {:?} against {:?}",
                    a.rays[i],
                    b.rays[i]
                );
                let (ca, cb) = (a.contribution[i], b.contribution[i]);
                for c in 0..3 {
                    let tol = REL * ca[c].abs().max(cb[c].abs()) + ABS;
                    assert!(
                        (ca[c] - cb[c]).abs() <= tol,
                        "{name}: light {light} ray {i}: lanes {ca} scalar {cb}"
                    );
                }
                inexact += (bits(ca) != bits(cb)) as usize;
            }
            compared += a.rays.len();
        }
        for (kind, a) in lane.next.iter() {
            let b = &scalar.next[kind];
            let (a, b) = (a.as_ref(), b.as_ref());
            assert_eq!(a.is_some(), b.is_some(), "{name}: {kind:?} queue");
            if let (Some(a), Some(b)) = (a, b) {
                let ab: Vec<_> = a.rays.iter().map(ray_bits).collect();
                let bb: Vec<_> = b.rays.iter().map(ray_bits).collect();
                assert_eq!(ab, bb, "{name}: {kind:?} rays");
                assert!(a.per_ray() == b.per_ray(), "{name}: {kind:?} values");
                match kind {
                    ChildKind::Reflection => children[0] += a.rays.len(),
                    ChildKind::Refraction => children[1] += a.rays.len(),
                    _ => {}
                }
            }
        }
        (compared, inexact, children)
    }

    /// The lane path and the scalar shader shade the same hits (camera rays of every
    /// shipped scene the lane path covers, then two waves of their child rays) into the
    /// same queues: the same shadow and child rays bit for bit, the same local radiance
    /// bit for bit, the same counts, and shadow contributions within `REL` (the lane
    /// power function; see there).
    #[test]
    fn lane_shading_matches_the_scalar_shader_on_the_same_hits() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let mut paths: Vec<_> = std::fs::read_dir(&dir)
            .expect("scenes/")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        paths.sort();
        let (mut scenes, mut shadow_rays, mut inexact, mut quad, mut smooth) = (0, 0, 0, 0, 0);
        let mut round = 0;
        let (mut reflected, mut refracted) = (0, 0);
        for path in paths {
            let name = path.display().to_string();
            let scene = load_scene(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
            let mut opts = RenderOptions::from_scene(&scene);
            opts.samples.shadow = opts.samples.shadow.min(20);
            opts.samples.glossy = opts.samples.glossy.min(3);
            let plan = SamplePlan::new(&scene, &opts);
            let Some(lanes) = LaneShading::new(&scene, plan.environment) else {
                eprintln!("{name}: a light or the environment is outside the lane path, skipped");
                continue;
            };
            scenes += 1;
            quad += lanes.quads.lights.len();
            round += lanes.round.len();
            let shader = Shader::new(&scene, &opts, plan);
            let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
            let (w, h) = (48, 36);
            let frame = scene.camera.frame(w, h);
            let queue = RayQueue::pixel_centres(&frame, w, h, plan.first_path());
            let slots = (w * h) as usize;
            let mut scratch = ShadeScratch::default();
            let mut queues = vec![(queue, 0)];
            while let Some((queue, depth)) = queues.pop() {
                let hits: Vec<_> = queue.rays.iter().map(|r| accel.closest_hit(r)).collect();
                let mut a = sinks(&scene, slots);
                let mut b = sinks(&scene, slots);
                shade_queue(
                    &shader,
                    Some(&lanes),
                    &queue,
                    &hits,
                    depth,
                    &mut a,
                    &mut scratch,
                );
                smooth += scratch.batch.smooth[..scratch.batch.len()]
                    .iter()
                    .filter(|m| m.to_bits() != 0)
                    .count();
                shade_queue(&shader, None, &queue, &hits, depth, &mut b, &mut scratch);
                let (n, x, c) = compare(&format!("{name} depth {depth}"), &a, &b);
                shadow_rays += n;
                inexact += x;
                reflected += c[0];
                refracted += c[1];
                if depth < 2 {
                    for kind in ChildKind::ALL {
                        if let Some(q) = a.next[kind].take() {
                            queues.push((q, depth + 1));
                        }
                    }
                }
            }
        }
        eprintln!(
            "lane shading: {scenes} scenes, {shadow_rays} shadow rays, {inexact} contributions \
             not bit-equal (the power), {smooth} smooth-mesh hits, {reflected} reflected and \
             {refracted} refracted child rays"
        );
        // Mirrors and clear glass: their children come from the lanes of
        // `specular_children` on one side and from `emit_children` on the other.
        assert!(reflected > 1_000 && refracted > 500);
        assert!(scenes >= 6, "{scenes} shipped scenes in the lane path");
        assert!(quad > 0, "a quad light was compared");
        assert!(round >= 2, "{round} disk and sphere lights compared");
        assert!(smooth > 0, "a smooth-mesh hit was compared");
        assert!(shadow_rays > 10_000, "{shadow_rays} shadow rays compared");
    }
}
