//! The interface every structure implements ([`Accel`]) and its build statistics.

use super::{HitFilter, QueryOptions, TraversalCounts};
use crate::geometry::{Hit, Ray, RayPacket};
use crate::simd::PACKET_WIDTH;

/// A packet's closest hits as lanes ([`Accel::closest_hit_packet_lanes`]): lane `k` holds
/// a hit (distance, barycentrics, primitive index) where bit `k` of `hit` is set; the
/// other lanes' values are unspecified.
#[derive(Clone, Copy, Debug, Default)]
pub struct PacketHitLanes {
    pub t: [f32; PACKET_WIDTH],
    pub u: [f32; PACKET_WIDTH],
    pub v: [f32; PACKET_WIDTH],
    pub prim: [u32; PACKET_WIDTH],
    pub hit: u32,
}

impl PacketHitLanes {
    /// Lane `k`'s answer as [`closest_hit_packet`](Accel::closest_hit_packet) gives it.
    #[inline(always)]
    pub fn get(&self, k: usize) -> Option<Hit> {
        (self.hit >> k & 1 == 1).then(|| Hit {
            t: self.t[k],
            prim: self.prim[k],
            u: self.u[k],
            v: self.v[k],
        })
    }
}

/// Closest hits written as lanes: hit `k`'s distance and primitive in `t[k]` and
/// `prim[k]`, NaN and `u32::MAX` where there is none (the lane form of
/// [`Accel::closest_hit_stream_lanes`] for structures without one of their own).
pub fn hits_as_lanes(hits: &[Option<Hit>], t: &mut [f32], prim: &mut [u32]) {
    for ((h, t), p) in hits.iter().zip(t.iter_mut()).zip(prim.iter_mut()) {
        (*t, *p) = h.map_or((f32::NAN, u32::MAX), |h| (h.t, h.prim));
    }
}

/// Closest-hit and any-hit queries over one primitive set.
///
/// Interval semantics for every implementation: a hit counts only if `tmin < t < tmax`
/// (both strict), and an invalid ray (NaN/inf components, zero direction, empty interval)
/// hits nothing. `Hit::prim` is the primitive's index in the set the structure was built
/// from, whatever order the structure keeps internally.
pub trait Accel: Send + Sync {
    fn closest_hit(&self, ray: &Ray) -> Option<Hit>;
    fn any_hit(&self, ray: &Ray) -> bool;

    /// Filtered query (Embree's intersection filter): `filter` is offered each
    /// candidate hit nearer than the nearest it accepted, each exactly once, and
    /// returns whether to accept it; the result is the nearest accepted candidate, or
    /// with `opts.any` the first. Back faces are dropped first with
    /// `opts.cull_back_faces`. Single rays on every structure, separate from the
    /// plain queries so that they pay nothing. Full semantics: [`filter`](super::filter).
    fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut HitFilter<'_>,
    ) -> Option<Hit>;

    /// Closest hits for a batch of rays. Structures with packet kernels override this.
    fn closest_hit_batch(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.closest_hit(r);
        }
    }

    /// Occlusion for a batch of rays. Structures with packet kernels override this.
    fn any_hit_batch(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.any_hit(r);
        }
    }

    /// Closest hits for a large batch of rays (hundreds to thousands, incoherent ones
    /// above all) traced as one stream. Structures with a stream kernel (BVH4/BVH8:
    /// `bvhn/stream.rs`) override this; the others trace the batch as a batch.
    fn closest_hit_stream(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.closest_hit_batch(rays, out);
    }

    /// [`closest_hit_stream`](Self::closest_hit_stream)'s answers as lanes: ray `k`'s
    /// distance and primitive in `t[k]` and `prim[k]`, NaN and `u32::MAX` where it has
    /// none (`t` and `prim` at least as long as `rays`). The wide BVHs write them
    /// straight from their stream's answers.
    fn closest_hit_stream_lanes(&self, rays: &[Ray], t: &mut [f32], prim: &mut [u32]) {
        let mut hits = vec![None; rays.len()];
        self.closest_hit_stream(rays, &mut hits);
        hits_as_lanes(&hits, t, prim);
    }

    /// Occlusion for a large batch of rays traced as one stream.
    fn any_hit_stream(&self, rays: &[Ray], out: &mut [bool]) {
        self.any_hit_batch(rays, out);
    }

    /// Closest hits for one packet of rays in structure-of-arrays form (lanes
    /// `0..packet.len` into `out[..packet.len]`). Structures with packet kernels
    /// override this; the batch entry points of those go through it.
    fn closest_hit_packet(&self, packet: &RayPacket, out: &mut [Option<Hit>]) {
        for (i, o) in out[..packet.len].iter_mut().enumerate() {
            *o = self.closest_hit(&packet.ray(i));
        }
    }

    /// [`closest_hit_packet`](Self::closest_hit_packet)'s answers as lanes (bits of
    /// `out.hit` only below `packet.len`), for a caller that keeps lanes: the wide BVHs
    /// hand over their kernel's lanes, without the twenty-byte `Option<Hit>` written
    /// lane by lane and read back with a branch per lane.
    fn closest_hit_packet_lanes(&self, packet: &RayPacket, out: &mut PacketHitLanes) {
        let mut hits = [None; PACKET_WIDTH];
        self.closest_hit_packet(packet, &mut hits[..packet.len]);
        out.hit = 0;
        for (k, h) in hits[..packet.len].iter().enumerate() {
            if let Some(h) = h {
                (out.t[k], out.u[k], out.v[k], out.prim[k]) = (h.t, h.u, h.v, h.prim);
                out.hit |= 1 << k;
            }
        }
    }

    /// Occlusion for one packet of rays in structure-of-arrays form.
    fn any_hit_packet(&self, packet: &RayPacket, out: &mut [bool]) {
        for (i, o) in out[..packet.len].iter_mut().enumerate() {
            *o = self.any_hit(&packet.ray(i));
        }
    }

    /// What was built and what it cost.
    fn info(&self) -> AccelInfo;

    /// The closest-hit traversal's work for one ray (node visits, primitive tests), from
    /// a counting twin of the traversal so the normal path pays nothing; `None` where a
    /// structure has no counting twin.
    fn traversal_counts(&self, _ray: &Ray) -> Option<TraversalCounts> {
        None
    }
}

/// Build statistics of one structure.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct AccelInfo {
    pub name: &'static str,
    pub primitives: usize,
    pub build_ms: f64,
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    pub memory_bytes: usize,
    /// SAH cost of the tree (traversal cost 1, intersection cost 1 per primitive,
    /// normalised by the root area); 0 where it does not apply.
    pub sah_cost: f64,
}
