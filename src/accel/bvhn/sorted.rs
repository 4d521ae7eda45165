//! Sorted packets: a batch of incoherent rays (diffuse bounces, say) regrouped by
//! direction octant and dominant axis before it is cut into packets, so that each
//! packet shares its slab planes and watertight shear and is traced by the packet
//! kernel (`packet.rs`) instead of ray by ray. This is what Embree's `rtcIntersect1M`
//! does with an incoherent stream on AVX2 (its rays sorted by octant into packets for
//! the hybrid kernels); the "binning rays by direction before tracing".
//!
//! The sort is a stable counting sort over the 24 keys (octant x dominant axis): within
//! a key the rays keep the caller's order, which for the bench's tiles and the
//! wavefront's queues groups neighbouring origins. Each key's rays are cut into
//! packets of [`PACKET_WIDTH`]; every packet then passes the packet kernel's coherence
//! test (one group), and its answers are the packet kernel's, so the same as the scalar
//! oracle's (the equivalence tests compare them).
//!
//! Measured: a dead end on AVX2, kept as bench modes (`bvh4-sorted`, `bvh8-sorted`,
//! `bvh8-sorted@K`) for the AVX-512 machine, where a 16-ray packet is one register.
//! Bunny, diffuse rays, 1 thread, `examples/stream_profile` (5 passes, medians, Mrays/s,
//! 2026-11-24 07:13 and 07:25 UTC, loaded: cpu 0.40-0.55, interleaved): `bvh8-packet`
//! 1.41/1.55/1.36 and 1.21/1.00/1.23, `bvh8-single` 1.18/1.02/1.05, `bvh8-stream`
//! 1.53/1.48/1.80; `bvh8-sorted` 0.92/0.77/0.83, `bvh4-sorted` 0.87/0.90/0.82, and with
//! the ray-by-ray threshold raised (`@K`: a part with fewer than K active rays finishes
//! ray by ray) `@8` 0.88/0.71/0.72, `@12` 0.73/0.88/0.67, `@15` 0.77/0.68/0.68. Rays of
//! one octant from one 8x8 tile still part after a node or two, and the packet kernel
//! then pays per subtree what a single ray pays once (a `closest_from` per subtree
//! left, each with its setup), so even `@15` loses a third to the ray-by-ray path.

use super::node::{NodeWidth, WideNode, Width};
use super::tree::Bvh;
use crate::accel::Primitives;
use crate::geometry::{Hit, Ray, dominant_axis, octant};
use crate::simd::{PACKET_WIDTH, Packet};
use std::cell::RefCell;

/// Keys: direction octant (3 sign bits) times dominant axis.
const KEYS: usize = 24;

/// The grouping key of a ray: the packet kernel's group (`packet_setup.rs`).
#[inline(always)]
fn key(r: &Ray) -> usize {
    octant(r.dir) * 3 + dominant_axis(r.dir)
}

/// Per-thread buffers: the rays in key order and each one's index in the batch.
#[derive(Default)]
struct Scratch {
    rays: Vec<Ray>,
    index: Vec<u32>,
    /// Start of each key's run in `rays`, and the end.
    starts: [usize; KEYS + 1],
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

impl Scratch {
    /// Stable counting sort of `rays` by [`key`].
    fn sort(&mut self, rays: &[Ray]) {
        let mut count = [0usize; KEYS + 1];
        for r in rays {
            count[key(r) + 1] += 1;
        }
        for k in 0..KEYS {
            count[k + 1] += count[k];
        }
        self.starts = count;
        let mut next = count;
        self.rays.clear();
        self.rays
            .resize(rays.len(), Ray::new(glam::Vec3::ZERO, glam::Vec3::X));
        self.index.clear();
        self.index.resize(rays.len(), 0);
        for (i, r) in rays.iter().enumerate() {
            let k = key(r);
            self.rays[next[k]] = *r;
            self.index[next[k]] = i as u32;
            next[k] += 1;
        }
    }

    /// Calls `f(packet, indices)` for each packet: up to [`PACKET_WIDTH`] rays of one
    /// key, with their indices in the batch.
    fn for_each_packet(&self, mut f: impl FnMut(&[Ray], &[u32])) {
        for k in 0..KEYS {
            let (a, b) = (self.starts[k], self.starts[k + 1]);
            let mut s = a;
            while s < b {
                let e = (s + PACKET_WIDTH).min(b);
                f(&self.rays[s..e], &self.index[s..e]);
                s = e;
            }
        }
    }
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    /// Closest hits of `rays`, regrouped by octant and dominant axis into packets; the
    /// same answers as [`closest_single`](Self::closest_single) for each ray.
    pub fn closest_hit_sorted(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        assert!(out.len() >= rays.len(), "one answer per ray");
        SCRATCH.with_borrow_mut(|s| {
            s.sort(rays);
            let mut hits = [None; PACKET_WIDTH];
            s.for_each_packet(|packet, index| {
                self.packet_closest::<Packet, _>(packet, &mut hits);
                for (&i, h) in index.iter().zip(&hits) {
                    out[i as usize] = *h;
                }
            });
        });
    }

    /// Occlusion of `rays`, regrouped as [`closest_hit_sorted`](Self::closest_hit_sorted)
    /// does; the same answers as [`any_single`](Self::any_single) for each ray.
    pub fn any_hit_sorted(&self, rays: &[Ray], out: &mut [bool]) {
        assert!(out.len() >= rays.len(), "one answer per ray");
        SCRATCH.with_borrow_mut(|s| {
            s.sort(rays);
            let mut occ = [false; PACKET_WIDTH];
            s.for_each_packet(|packet, index| {
                self.packet_any::<Packet, _>(packet, &mut occ);
                for (&i, &o) in index.iter().zip(&occ) {
                    out[i as usize] = o;
                }
            });
        });
    }
}
