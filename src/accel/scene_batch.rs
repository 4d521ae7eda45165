//! The scene-level batch queries of [`SceneAccel`]: packets, streams or the tiny
//! scene's lanes per primitive kind, merged as the single-ray queries merge them.

use super::scene_accel::closer;
use super::{Occluder, PrimRef, SceneAccel, SceneHit, TinyScratch, prefers_stream};
use crate::geometry::{Hit, Ray};

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
            out.fill(None);
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

    /// The closest-hit batch over the triangle and sphere structures (`out` starts
    /// all `None`).
    fn closest_sets_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut BatchScratch,
    ) {
        let hits = &mut scratch.hits;
        hits.clear();
        hits.resize(rays.len(), None);
        let scene_hit = |h: Hit, prim: fn(u32) -> PrimRef| SceneHit {
            t: h.t,
            prim: prim(h.prim),
            u: h.u,
            v: h.v,
        };
        // Incoherent batches (diffuse-like queues) go through the stream kernel.
        let stream = prefers_stream(rays);
        if let Some(a) = &self.triangles {
            if stream {
                a.closest_hit_stream(rays, hits);
            } else {
                a.closest_hit_batch(rays, hits);
            }
            for (o, h) in out.iter_mut().zip(hits.iter()) {
                *o = h.map(|h| scene_hit(h, PrimRef::Triangle));
            }
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
            if stream {
                a.closest_hit_stream(clipped, hits);
            } else {
                a.closest_hit_batch(clipped, hits);
            }
            for (o, h) in out.iter_mut().zip(hits.iter()) {
                if let Some(h) = h {
                    *o = Some(scene_hit(*h, PrimRef::Sphere));
                }
            }
        }
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
        let mut first = true;
        for (a, set) in kinds {
            let Some(a) = a else { continue };
            if first {
                if stream {
                    a.any_hit_stream(rays, out);
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
