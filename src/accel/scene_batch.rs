//! The scene-level batch queries of [`SceneAccel`]: packets, streams or the tiny
//! scene's lanes per primitive kind, merged as the single-ray queries merge them.

use super::scene_accel::closer;
use super::{
    Accel, AccelKind, Occluder, PacketHitLanes, PrimRef, SceneAccel, SceneHit, TinyScratch,
    prefers_stream,
};
use crate::geometry::{Hit, Ray};
use crate::simd::PACKET_WIDTH;
use crate::simd::ray_gather::packet_of_rays;
use crate::simd::ray_store::store_hit_records;

impl SceneAccel {
    /// Closest hits for a batch of rays, through each kind's batch entry point (BVH4:
    /// 16 consecutive rays as one packet; a batch that [`prefers_stream`], of at least
    /// [`STREAM_MIN_BATCH`](super::STREAM_MIN_BATCH) mostly incoherent rays in a build where the stream kernel
    /// measures faster ([`STREAM_WINS`](super::STREAM_WINS): AVX2 or AVX-512), as one stream), merged by distance exactly as
    /// [`closest_hit`](Self::closest_hit) merges them: each later kind searches only in
    /// front of the hit found so far, so the results are identical. `scratch` is reused
    /// between calls.
    pub fn closest_hit_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut BatchScratch,
    ) {
        debug_assert_eq!(rays.len(), out.len());
        if let Some(tiny) = &self.tiny {
            // Writes every entry of `out` itself (`None` first): no second pass here.
            tiny.closest_batch(rays, out, &mut scratch.tiny);
        } else {
            self.closest_sets_batch(rays, out, scratch);
        }
        if let Some(m) = &self.moving {
            for (r, o) in rays.iter().zip(out.iter_mut()) {
                let best = closer(*o, r, |r| m.closest_triangle(r), PrimRef::MovingTriangle);
                *o = closer(best, r, |r| m.closest_sphere(r), PrimRef::MovingSphere);
            }
        }
        if self.instances.is_some() || !self.planes.is_empty() {
            for (r, o) in rays.iter().zip(out.iter_mut()) {
                *o = self.closest_extra(r, *o);
            }
        }
    }

    /// The closest-hit batch over the triangle and sphere structures (every entry of
    /// `out` written).
    fn closest_sets_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut BatchScratch,
    ) {
        let hits = &mut scratch.hits;
        // Incoherent batches (diffuse-like queues) go through the stream kernel.
        let stream = prefers_stream(rays);
        let path = if stream {
            BatchPath::Stream
        } else if self.packets_are_batches() {
            BatchPath::Packets
        } else {
            BatchPath::Batch
        };
        match &self.triangles {
            Some(a) => closest_set(a.as_ref(), rays, out, hits, path, PrimRef::Triangle, true),
            None => out.fill(None),
        }
        if let Some(a) = &self.spheres {
            let clipped = &mut scratch.rays;
            clipped.clear();
            clipped.extend(rays.iter().zip(out.iter()).map(|(r, o)| {
                let mut r = *r;
                if let Some(b) = o {
                    r.tmax = b.t;
                }
                r
            }));
            closest_set(a.as_ref(), clipped, out, hits, path, PrimRef::Sphere, false);
        }
    }

    /// Whether each primitive set's batch entry point is its packet entry point over
    /// consecutive [`PACKET_WIDTH`]-ray chunks (the wide BVHs: both run the same packet
    /// kernel, `bvhn/tree.rs`), so that a batch can be handed over as packets
    /// ([`closest_packets`], [`any_packets`]) with the same answers.
    fn packets_are_batches(&self) -> bool {
        matches!(
            self.kind,
            AccelKind::Bvh4 | AccelKind::Bvh8 | AccelKind::Bvh4c | AccelKind::Bvh8c
        )
    }

    /// Occlusion for a batch of rays: each kind's batch entry point over the rays no
    /// earlier kind found blocked. Incoherent batches go through the stream kernel, as in
    /// [`closest_hit_batch`](Self::closest_hit_batch). Same answers as [`any_hit`](Self::any_hit).
    pub fn any_hit_batch(&self, rays: &[Ray], out: &mut [bool], scratch: &mut BatchScratch) {
        self.any_hit_batch_marking(rays, out, scratch, |_, _| {});
    }

    /// [`any_hit_batch`](Self::any_hit_batch) that says which primitive set blocks each
    /// ray (the same work and answers): `out[i]` is [`occluder`](Self::occluder) of ray
    /// `i`. `blocked` is scratch (the plain answers).
    pub fn occluders_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<Occluder>],
        blocked: &mut Vec<bool>,
        scratch: &mut BatchScratch,
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(None);
        blocked.clear();
        blocked.resize(rays.len(), false);
        self.any_hit_batch_marking(rays, blocked, scratch, |i, set| out[i] = Some(set));
    }

    /// The occlusion batch, calling `mark(i, set)` once for each ray `i` when the set
    /// `set` is the first found blocking it.
    #[inline(always)]
    fn any_hit_batch_marking(
        &self,
        rays: &[Ray],
        out: &mut [bool],
        scratch: &mut BatchScratch,
        mut mark: impl FnMut(usize, Occluder),
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(false);
        if let Some(tiny) = &self.tiny {
            tiny.occluders_batch(rays, &mut scratch.tiny, |i, set| {
                out[i] = true;
                mark(i, set);
            });
        } else {
            self.occluders_sets_batch(rays, out, scratch, &mut mark);
        }
        if let Some(m) = &self.moving {
            for (i, (r, o)) in rays.iter().zip(out.iter_mut()).enumerate() {
                if !*o && m.any_hit(r) {
                    *o = true;
                    mark(i, Occluder::Moving);
                }
            }
        }
        if self.instances.is_some() || !self.planes.is_empty() {
            for (i, (r, o)) in rays.iter().zip(out.iter_mut()).enumerate() {
                if !*o && self.any_extra(r) {
                    *o = true;
                    mark(i, Occluder::Other);
                }
            }
        }
    }

    /// The occlusion batch over the triangle and sphere structures (`out` starts all
    /// false).
    #[inline(always)]
    fn occluders_sets_batch(
        &self,
        rays: &[Ray],
        out: &mut [bool],
        scratch: &mut BatchScratch,
        mark: &mut impl FnMut(usize, Occluder),
    ) {
        let kinds = [
            (self.triangles.as_deref(), Occluder::Triangles),
            (self.spheres.as_deref(), Occluder::Spheres),
        ];
        let stream = prefers_stream(rays);
        let packets = !stream && self.packets_are_batches();
        let mut first = true;
        for (a, set) in kinds {
            let Some(a) = a else { continue };
            if first {
                if stream {
                    a.any_hit_stream(rays, out);
                } else if packets {
                    any_packets(a, rays, out);
                } else {
                    a.any_hit_batch(rays, out);
                }
                first = false;
                for (i, &b) in out.iter().enumerate() {
                    if b {
                        mark(i, set);
                    }
                }
                continue;
            }
            // Only the rays still unblocked, packed so packets stay full.
            scratch.index.clear();
            scratch.rays.clear();
            for (i, (r, o)) in rays.iter().zip(out.iter()).enumerate() {
                if !*o {
                    scratch.index.push(i as u32);
                    scratch.rays.push(*r);
                }
            }
            scratch.blocked.clear();
            scratch.blocked.resize(scratch.rays.len(), false);
            if stream {
                a.any_hit_stream(&scratch.rays, &mut scratch.blocked);
            } else if packets {
                any_packets(a, &scratch.rays, &mut scratch.blocked);
            } else {
                a.any_hit_batch(&scratch.rays, &mut scratch.blocked);
            }
            for (&i, &b) in scratch.index.iter().zip(scratch.blocked.iter()) {
                out[i as usize] = b;
                if b {
                    mark(i as usize, set);
                }
            }
        }
    }
}

/// `h` on the primitive set whose ids `prim` wraps.
#[inline(always)]
fn scene_hit(h: Hit, prim: impl Fn(u32) -> PrimRef) -> SceneHit {
    SceneHit {
        t: h.t,
        prim: prim(h.prim),
        u: h.u,
        v: h.v,
    }
}

/// How a batch goes to a primitive set's structure.
#[derive(Clone, Copy)]
enum BatchPath {
    /// The stream kernel (an incoherent batch, [`prefers_stream`]).
    Stream,
    /// Packets built in lanes ([`closest_packets`], [`any_packets`]).
    Packets,
    /// The structure's own batch entry point.
    Batch,
}

/// One primitive set's closest hits for `rays` merged into `out` by [`put_hit`]
/// (`first`: the first set searched; a later one searches in front of the hits so
/// far, its rays clipped by the caller). `hits` is scratch for the paths that answer
/// a whole batch at once.
fn closest_set(
    a: &dyn Accel,
    rays: &[Ray],
    out: &mut [Option<SceneHit>],
    hits: &mut Vec<Option<Hit>>,
    path: BatchPath,
    prim: impl Fn(u32) -> PrimRef + Copy,
    first: bool,
) {
    match path {
        BatchPath::Packets => return closest_packets(a, rays, out, prim, first),
        BatchPath::Stream | BatchPath::Batch => {
            hits.clear();
            hits.resize(rays.len(), None);
        }
    }
    if let BatchPath::Stream = path {
        a.closest_hit_stream(rays, hits);
    } else {
        a.closest_hit_batch(rays, hits);
    }
    for (o, h) in out.iter_mut().zip(hits.iter()) {
        put_hit(o, *h, prim, first);
    }
}

/// A set's answer `h` for one ray into `o`: every answer for the `first` set
/// searched, only hits for a later one (a hit there is in front of `o`'s).
#[inline(always)]
fn put_hit(o: &mut Option<SceneHit>, h: Option<Hit>, prim: impl Fn(u32) -> PrimRef, first: bool) {
    if first {
        *o = h.map(|h| scene_hit(h, prim));
    } else if let Some(h) = h {
        *o = Some(scene_hit(h, prim));
    }
}

/// The closest hits of `rays` in `a` as packets of [`PACKET_WIDTH`] consecutive rays,
/// each built in lanes ([`packet_of_rays`]) and answered into a packet's worth of
/// hits, then into `out` as hits on `prim`'s set: every entry (`first`, the first set
/// searched) or the hits only (a later set, searching in front of the hit so far).
///
/// What a [`packets_are_batches`](SceneAccel::packets_are_batches) structure's
/// `closest_hit_batch` does, without its gather lane by lane from the rays (with the
/// array it fills, two fifths of the packet wrapper's samples, `perf record -e
/// cpu-clock`, bunny 1024x1024, 1 thread) and without the batch-long array of hits
/// written, then read again into `out`. A packet's hits are read into `out` after the
/// next packet is traced, and `prim` is a generic (each set's constructor inlined):
/// with a function pointer, each hit was assembled on the stack around the call and
/// read back as a whole, and that read held a third of this function's samples.
///
/// The packet's hits come as lanes ([`Accel::closest_hit_packet_lanes`]: t, u, v,
/// primitive and a hit bit each, the wide BVHs' kernel lanes as they are), so that
/// neither the kernel writes the twenty-byte `Option<Hit>`s lane by lane nor `put`
/// reads them back with a branch per lane (issue 11, bf24, 2026-11-29). Measured
/// (perf record -e cpu-clock -F 10000, 5 bunny frames 1024x1024, 1 thread, AVX-512,
/// load ~6, two interleaved rounds): the samples of `SceneAccel::closest_hit_batch`
/// (this function inlined) and of the packet
/// wrappers (`closest_hit_packet[_lanes]`, `any_hit_packet`, `any_packets`) 402 / 409
/// before, 309 / 309 with the lanes, of 2,660-2,900 render-phase samples.
///
/// Tried, no win, reverted (commit 190e389, fr23b): the same pattern for occlusion,
/// `Accel::any_hit_packet_bits` (the wide BVHs' kernel bits) written into `out` by
/// [`any_packets`] instead of `any_hit_packet`'s `bool`s. Same answers; bunny
/// 1024x1024, 1 thread, `ab.sh` render ms medians of 21 interleaved rounds, load
/// 4.1-4.4, earlier binary / bits: 73.8 / 77.7, 71.3 / 75.4, (order swapped) 75.8 /
/// 77.3; against `/tmp/base23` 71.7 / 74.8; 9 rounds 77.8 / 77.8. Minimums 62.5-64.0
/// either way: the bits save one byte store per lane, within this host's noise at best.
fn closest_packets(
    a: &dyn Accel,
    rays: &[Ray],
    out: &mut [Option<SceneHit>],
    prim: impl Fn(u32) -> PrimRef + Copy,
    first: bool,
) {
    // The tag of `prim`'s hits where the packet's answers can be stored as whole
    // records ([`put_records`]): the first set searched, on triangles or spheres.
    let tag = match (first, prim(0), prim(1)) {
        (true, PrimRef::Triangle(0), PrimRef::Triangle(1)) => Some(PrimRef::TRIANGLE_TAG),
        (true, PrimRef::Sphere(0), PrimRef::Sphere(1)) => Some(PrimRef::SPHERE_TAG),
        _ => None,
    };
    // Lane `k` of `h` into `o[k]` (`get` and `put_hit` inlined: no `Option<Hit>` is
    // stored), a whole packet's at once where it can. A function, not a closure: with
    // the two paths the closure was kept out of line, a call per packet.
    #[inline(always)]
    fn put(
        o: &mut [Option<SceneHit>],
        h: &PacketHitLanes,
        tag: Option<u32>,
        prim: impl Fn(u32) -> PrimRef + Copy,
        first: bool,
    ) {
        if let (Some(tag), Ok(o)) = (tag, <&mut [_; PACKET_WIDTH]>::try_from(&mut *o)) {
            return put_records(o, h, tag);
        }
        for (k, o) in o.iter_mut().enumerate() {
            put_hit(o, h.get(k), prim, first);
        }
    }
    let mut hits = [PacketHitLanes::default(); 2];
    let mut pending: Option<(&mut [Option<SceneHit>], usize)> = None;
    for (k, (r, o)) in rays
        .chunks(PACKET_WIDTH)
        .zip(out.chunks_mut(PACKET_WIDTH))
        .enumerate()
    {
        a.closest_hit_packet_lanes(&packet_of_rays(r), &mut hits[k % 2]);
        if let Some((o, b)) = pending.take() {
            put(o, &hits[b], tag, prim, first);
        }
        pending = Some((o, k % 2));
    }
    if let Some((o, b)) = pending {
        put(o, &hits[b], tag, prim, first);
    }
}

/// A whole packet's answers `h` into `o` as [`put_hit`] writes them for the first set
/// searched, on the set whose [`PrimRef`] tag is `tag`: the sixteen hits stored as
/// records ([`store_hit_records`]: `t`, tag, index, a spare word, `u`, `v`, the layout
/// asserted in `scene_hit`), then `None` written over the lanes that missed; a packet
/// that hits nothing is sixteen `None`s.
///
/// Before: `put_hit` lane by lane, a branch on the lane's hit bit and five scalar
/// stores (tag, index, `t`, `u`, `v`) per lane: 28 % of the samples of
/// `SceneAccel::closest_hit_batch` (perf annotate, bunny 1024x1024, 1 thread,
/// AVX-512), which was 5 % of the render phase.
#[inline(always)]
fn put_records(o: &mut [Option<SceneHit>; PACKET_WIDTH], h: &PacketHitLanes, tag: u32) {
    let hit = h.hit & 0xffff;
    if hit == 0 {
        o.fill(None);
        return;
    }
    // SAFETY: `o` is sixteen 24-byte `Option<SceneHit>`s, 96 words, written whole.
    // Each record is a valid `SceneHit` (any bits in the floats and the index, a
    // primitive tag, the spare word being padding of that variant), which is, byte for
    // byte, the `Some` holding it (asserted in `scene_hit`: `Option<SceneHit>` is as
    // large as `SceneHit`, so `None` lies in a niche no valid `SceneHit` has).
    unsafe { store_hit_records((&h.t, &h.u, &h.v), &h.prim, tag, o.as_mut_ptr().cast()) };
    let mut miss = !hit & 0xffff;
    while miss != 0 {
        o[miss.trailing_zeros() as usize] = None;
        miss &= miss - 1;
    }
}

/// Occlusion of `rays` in `a` as packets of [`PACKET_WIDTH`] consecutive rays built in
/// lanes: [`closest_packets`]' counterpart, every entry of `out` written.
fn any_packets(a: &dyn Accel, rays: &[Ray], out: &mut [bool]) {
    for (r, o) in rays.chunks(PACKET_WIDTH).zip(out.chunks_mut(PACKET_WIDTH)) {
        a.any_hit_packet(&packet_of_rays(r), o);
    }
}

/// Reusable buffers of the batch queries.
#[derive(Default)]
pub struct BatchScratch {
    hits: Vec<Option<Hit>>,
    rays: Vec<Ray>,
    index: Vec<u32>,
    blocked: Vec<bool>,
    tiny: TinyScratch,
}

impl BatchScratch {
    /// The buffers of the tiny-scene lane groups, for a caller that runs them itself
    /// (`integrator::tiny_shadow`).
    pub fn tiny(&mut self) -> &mut TinyScratch {
        &mut self.tiny
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::RayPacket;
    use crate::scene::{Material, SceneBuilder, procedural};
    use glam::Vec3;

    /// The packet path of the batch queries (coherent batches in the wide BVHs, handed
    /// over as packets built in lanes) answers what the single-ray queries answer, hit
    /// for hit and bit for bit: closest hits (also where the spheres are searched in
    /// front of the triangles' hits), occlusion and the first occluding set, over a
    /// mesh with spheres in front of it, for a batch that ends in a partial packet and
    /// holds invalid rays and intervals that end early, in every wide BVH.
    #[test]
    fn packet_batches_agree_with_single_rays() {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::default());
        procedural::tessellated_mesh(&mut b, 20_000, Vec3::ZERO, 1.0, m);
        for k in 0..6 {
            let a = k as f32 * 1.05;
            b.add_sphere(Vec3::new(a.cos() * 0.6, 0.3 * k as f32 - 0.8, 1.0), 0.3, m);
        }
        let scene = b.finish().expect("a valid scene");
        // Camera-like rays from one eye through a 64 x 47 grid of pixels (not a
        // multiple of the packet width), with a few invalid rays and short intervals.
        let eye = Vec3::new(0.05, 0.1, 4.0);
        let mut rays: Vec<Ray> = (0..64 * 47)
            .map(|i| {
                let (x, y) = ((i % 64) as f32 / 63.0, (i / 64) as f32 / 46.0);
                let d = Vec3::new(x * 0.9 - 0.45, y * 0.9 - 0.45, -1.0).normalize();
                match i % 29 {
                    0 => Ray::new(eye, Vec3::ZERO),
                    1 | 2 => Ray::segment(eye, d, 0.0, 2.8 + (i % 7) as f32 * 0.1),
                    _ => Ray::new(eye, d),
                }
            })
            .collect();
        rays[5].origin = Vec3::splat(f32::NAN);
        assert!(!prefers_stream(&rays), "coherent rays stay in packets");
        for kind in [
            AccelKind::Bvh4,
            AccelKind::Bvh8,
            AccelKind::Bvh4c,
            AccelKind::Bvh8c,
        ] {
            let mut accel = SceneAccel::build(&scene, kind);
            accel.tiny = None;
            assert!(accel.packets_are_batches(), "{kind}");
            let mut scratch = BatchScratch::default();
            let mut hits = vec![None; rays.len()];
            accel.closest_hit_batch(&rays, &mut hits, &mut scratch);
            let mut blocked = vec![true; rays.len()];
            accel.any_hit_batch(&rays, &mut blocked, &mut scratch);
            let (mut first, mut plain) = (vec![None; rays.len()], Vec::new());
            accel.occluders_batch(&rays, &mut first, &mut plain, &mut scratch);
            let (mut tri, mut sph, mut miss) = (0, 0, 0);
            for (i, r) in rays.iter().enumerate() {
                let want = accel.closest_hit(r);
                let bits = |h: Option<SceneHit>| {
                    h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
                };
                assert_eq!(bits(hits[i]), bits(want), "{kind} ray {i}");
                assert_eq!(blocked[i], accel.any_hit(r), "{kind} ray {i}: occlusion");
                assert_eq!(first[i], accel.occluder(r), "{kind} ray {i}: occluder");
                match want.map(|h| h.prim) {
                    Some(PrimRef::Triangle(_)) => tri += 1,
                    Some(PrimRef::Sphere(_)) => sph += 1,
                    _ => miss += 1,
                }
            }
            assert!(
                tri > 300 && sph > 300 && miss > 300,
                "{kind}: too few of a kind to compare ({tri}, {sph}, {miss})"
            );
        }
    }

    /// `put_records` writes what `put_hit` writes lane by lane for the first set
    /// searched (the same `Option<SceneHit>` in every lane, compared whole), on
    /// triangles and on spheres, for packets that hit nothing, everything, and mixes,
    /// with stale values in the lanes that missed; the entries start as other hits.
    #[test]
    fn packet_records_are_the_lane_answers() {
        let mut next = crate::test_rng::xorshift64(41);
        let mut f = || f32::from_bits((next() >> 32) as u32 & 0x7fbf_ffff) - 1e-3;
        for case in 0..60u32 {
            let hit = match case % 5 {
                0 => 0,
                1 => 0xffff,
                2 => 0x8001,
                _ => case.wrapping_mul(0x9e37_79b9) >> 16,
            };
            let h = PacketHitLanes {
                t: std::array::from_fn(|_| f()),
                u: std::array::from_fn(|_| f()),
                v: std::array::from_fn(|_| f()),
                prim: std::array::from_fn(|k| case * 1000 + k as u32 * 7),
                hit: hit | if case % 7 == 0 { 0xffff_0000 } else { 0 },
            };
            type Ctor = fn(u32) -> PrimRef;
            for (tag, prim) in [
                (PrimRef::TRIANGLE_TAG, PrimRef::Triangle as Ctor),
                (PrimRef::SPHERE_TAG, PrimRef::Sphere as Ctor),
            ] {
                let stale = Some(SceneHit {
                    t: 9.0,
                    prim: PrimRef::Instance {
                        instance: 3,
                        prim: 4,
                    },
                    u: 0.5,
                    v: 0.25,
                });
                let mut got = [stale; PACKET_WIDTH];
                put_records(&mut got, &h, tag);
                for (k, g) in got.iter().enumerate() {
                    let mut want = stale;
                    put_hit(&mut want, h.get(k), prim, true);
                    let bits = |x: Option<SceneHit>| {
                        x.map(|x| (x.t.to_bits(), x.prim, x.u.to_bits(), x.v.to_bits()))
                    };
                    assert_eq!(bits(*g), bits(want), "case {case} tag {tag} lane {k}");
                    assert_eq!(g.is_some(), hit >> k & 1 == 1);
                }
            }
        }
    }

    /// `Accel::closest_hit_packet_lanes` answers what `closest_hit_packet` answers, lane
    /// for lane and bit for bit (t, u, v, primitive), with no hit bit at or past the
    /// packet's length: the wide BVHs' override (their kernel's lanes) and the trait's
    /// default (a BVH2, a grid), for packets of every length from 1 to 16 cut from
    /// camera-like rays with invalid lanes, ends early and misses among them.
    #[test]
    fn packet_hit_lanes_are_the_packet_answers() {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::default());
        procedural::tessellated_mesh(&mut b, 5_000, Vec3::ZERO, 1.0, m);
        let scene = b.finish().expect("a valid scene");
        let eye = Vec3::new(0.1, -0.05, 3.0);
        let mut rays: Vec<Ray> = (0..40 * 30)
            .map(|i| {
                let (x, y) = ((i % 40) as f32 / 39.0, (i / 40) as f32 / 29.0);
                let d = Vec3::new(x * 1.4 - 0.7, y * 1.4 - 0.7, -1.0).normalize();
                match i % 23 {
                    0 => Ray::new(eye, Vec3::ZERO),
                    1 => Ray::segment(eye, d, 0.0, 2.5),
                    _ => Ray::new(eye, d),
                }
            })
            .collect();
        rays[7].dir = Vec3::splat(f32::NAN);
        for kind in [
            AccelKind::Bvh4,
            AccelKind::Bvh8,
            AccelKind::Bvh4c,
            AccelKind::Bvh8c,
            AccelKind::Bvh2,
            AccelKind::Grid,
        ] {
            let accel = SceneAccel::build(&scene, kind);
            let a = accel.triangles.as_deref().expect("a triangle structure");
            let (mut hits, mut misses) = (0, 0);
            let mut start = 0;
            for len in (1..=PACKET_WIDTH).cycle() {
                if start + len > rays.len() {
                    break;
                }
                let packet = RayPacket::from_rays(&rays[start..start + len]);
                start += len;
                let mut want = [None; PACKET_WIDTH];
                a.closest_hit_packet(&packet, &mut want[..len]);
                // Stale values in every lane first: only the hit lanes are read.
                let mut got = PacketHitLanes {
                    t: [7.0; PACKET_WIDTH],
                    u: [7.0; PACKET_WIDTH],
                    v: [7.0; PACKET_WIDTH],
                    prim: [7; PACKET_WIDTH],
                    hit: u32::MAX,
                };
                a.closest_hit_packet_lanes(&packet, &mut got);
                assert_eq!(got.hit >> len, 0, "{kind}: hit bits past {len} lanes");
                let bits = |h: Option<Hit>| {
                    h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
                };
                for (k, w) in want[..len].iter().enumerate() {
                    assert_eq!(bits(got.get(k)), bits(*w), "{kind}: lane {k} of {len}");
                    hits += w.is_some() as usize;
                    misses += w.is_none() as usize;
                }
            }
            assert!(
                hits > 200 && misses > 100,
                "{kind}: {hits} hits, {misses} misses"
            );
        }
    }
}
