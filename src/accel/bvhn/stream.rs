//! Stream traversal: a batch of hundreds to thousands of rays traced node by node, each
//! node fetched once for every ray of the batch that reaches it, in the spirit of
//! Barringer and Akenine-Möller, "Dynamic Ray Stream Traversal" (ACM TOG 33(4), SIGGRAPH
//! 2014: a depth-first walk of the tree carrying the list of ray ids that entered each
//! node, each child getting the sub-list of rays that enter it) and of Fuetterling,
//! Lojewski, Pfreundt and Ebert, "Efficient Ray Tracing Kernels for Modern CPU
//! Architectures" (JCGT 4(5), 2015: ordered ray stream traversal, children visited in
//! the order of the rays' mean entry distance).
//!
//! The rays are binned by direction octant first (every ray of a bin shares the near and
//! far slab planes, so a node's six plane vectors are loaded once per node and bin), and
//! within a bin keep the caller's order (the bench and the wavefront hand rays over in
//! pixel order, which already groups neighbouring origins). At an interior node each ray
//! of the list is tested against all N children at once (the single-ray N-wide slab
//! test, with the same arithmetic and the same conservative far-plane scale as
//! `single.rs`) and its child mask stored; then each entered child's list is compacted
//! from the masks, sixteen ids a step with AVX-512, eight with AVX2 (`simd::compact`). Children are pushed far to near
//! by their rays' mean entry distance, and prefetched as they are pushed. A list that
//! has shrunk to fewer than [`STREAM_MIN_RAYS`] rays finishes its subtree ray by ray
//! (`closest_from` / `any_from`), as DRST does. Leaves run the single-ray leaf kernels
//! (`leaf_closest` / `leaf_any`, the watertight test with its scalar edge fallback), so
//! every hit is the scalar oracle's, bit for bit: `t`, `u`, `v` and the primitive (an
//! exact tie in `t` between two primitives may go to either, as for the packets).
//!
//! What did not pay (bunny, 1 thread, `bench --modes bvh8-stream`; Mrays/s):
//! - Appending each ray's id to its children's lists as it is tested (one pass): the
//!   list counts were a loop-carried chain through memory. Diffuse 5.55-5.71, primary
//!   21-22; a branch-free append (every child's slot written, its count advanced by the
//!   mask bit) 6.16-6.33 diffuse but 17-20 primary. The two passes: 7.58-7.69 diffuse,
//!   26.4-26.6 primary (separate runs on a quiet machine).
//! - Sorting a bin's rays by origin (issue 12, big22, 2026-11-29; commit 45deb89 on
//!   branch big22, `ray_sort.rs`): each octant's rays in the Morton order of their
//!   origins in the batch's origin box (10 bits per axis; a three-pass 11-bit radix
//!   sort of octant-and-code keys, inside the timed region), as Garanzha and Loop
//!   (Eurographics 2010) and Moon et al. (TOG 2010) order rays. Same answers and
//!   checksums. Which rays enter a node does not depend on their order in the list, so
//!   node visits, tests and leaf tests are unchanged; only where a list's records lie
//!   moves (a band's bin of about a thousand rays fits in L2 anyway). Measured at
//!   10^6 (`bench --triangles 1000000 --threads 1 --reps 5 --modes bvh8-stream`,
//!   AVX-512, load 6-9, 6 interleaved rounds, diffuse Mrays per CPU-second): session
//!   base 2.88/2.34/2.49/2.85/2.69/2.24 (median 2.59), same binary unsorted 2.26/2.54/
//!   2.58/2.31/2.76/2.18 (2.42), sorted 2.77/2.05/2.12/2.89/2.52/2.00 (2.32); and
//!   `stream_profile 1000000 bvh8-stream diffuse 7`, 4 interleaved rounds, unsorted
//!   2.97/2.73/2.88/2.78 (2.83), sorted 2.70/2.71/2.15/2.44 (2.57): lower in every
//!   round (the sort's cost, nothing gained). Removed.
//! - Two rays per 512-bit register in the node test (8 children x 2 rays), not tried:
//!   the node-test loop is 23-24 % of `stream`'s samples (bunny and 10^6 triangles,
//!   AVX-512, `perf annotate`), 28 instructions a ray, its 11 ray values broadcast
//!   straight from the 64-byte record as memory operands. Pairing halves the 21
//!   arithmetic operations per ray but needs a two-source permute per ray value (11 a
//!   pair, all on one port), and 512-bit operations issue on two ports where 256-bit
//!   ones issue on three, so the loop's throughput bound stays about the same.
//! - Primary and shadow rays: their 16-ray packets (`packet.rs`, one node test for 16
//!   rays, one triangle test for 16 rays) stay 2x faster than this one-ray-per-test
//!   kernel (bunny primary 53.8 against 24.8), so `SceneAccel` streams only batches
//!   whose packets are incoherent ([`prefers_stream`]).
//!
//! Lists live in one arena: a node's children get `N` slots of the parent list's length
//! each, above everything still on the stack; an entry popped from the stack frees what
//! lies above its parent's block (the stack is LIFO, so everything there is finished).

use super::node::{NodeWidth, WideNode, Width, is_leaf};
use super::stack::insert_far_to_near;
use super::tree::Bvh;
use crate::accel::Primitives;
use crate::geometry::{Hit, ROBUST_FAR_SCALE, Ray, RayQuery, octant};
use crate::simd::Lanes;
use crate::simd::compact::{COMPACT_SLACK, select_ids};
use crate::simd::prefetch::prefetch;
use crate::simd::slab_fma::{
    FmaAxis, FmaRay, FusedLanes, fma_axes, t_slack, widened_tmax, widened_tmin,
};
use std::cell::RefCell;

/// Lists shorter than this finish their subtree ray by ray. 1 (only leaves ray by
/// ray), 2 and 3 measured within 3 % of each other on the bunny's diffuse rays
/// (6.80-7.17 Mrays/s, interleaved runs); 4 and 8 were 6 % slower (6.61, 6.65
/// against 7.06).
pub const STREAM_MIN_RAYS: u32 = 2;

/// How many rays ahead a leaf's (or a short list's) loop prefetches the queries.
///
/// Why: the leaf test reads each ray's query (origin, shear constants), which the node
/// passes never touch: up to 8,192 queries of 88 bytes in the caller's order, so the
/// first read often misses; `perf record` of `examples/stream_profile bunny.obj
/// bvh8-stream diffuse` put 5.0 % of `stream`'s samples on the query's first origin
/// load, none after the prefetch. Measured (2026-11-24, AVX2, 1 thread, load 7-8, `cpu`
/// 0.39-0.51, interleaved pairs old/new, median Mrays/s of 5 passes, and per CPU-second
/// = median / cpu): bunny 2.11/2.09, 2.12/1.83, 1.57/1.63, 1.63/1.66, 1.63/1.75 (per
/// CPU-second medians 4.07 old, 4.15 new: within the noise); 10^6 triangles
/// (`stream_profile 1000000`) 1.18/1.56, 1.19/1.28, 1.13/1.28 (per CPU-second
/// 2.95/3.06, 3.05/3.28, 2.90/3.05: +4-8 %, every pair).
const QUERY_AHEAD: usize = 2;

/// One ray as the node test reads it: 64 bytes, one cache line. With the FMA node test
/// (`simd/slab_fma.rs`) `a`, `b`, `c`, `e` are `rn`, `on`, `rf`, `of`; with Ize's test
/// `a` is the origin, `b` the reciprocal direction and `c` the reciprocal scaled by `1 +
/// 2 gamma(3)`, the conservative far-plane scale of `single.rs` (`e` unused). Was 48
/// bytes (Ize's test only) before the FMA test needed a fourth triple.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct StreamRay {
    a: [f32; 3],
    tmin: f32,
    b: [f32; 3],
    /// The end of the ray's interval: the closest hit so far (with Ize's test times its
    /// far-plane scale `1 + 2 gamma(3)`, applied here once rather than in every node
    /// test); NaN once an occlusion query is answered (a NaN far distance enters no
    /// child).
    tmax: f32,
    c: [f32; 3],
    /// With the FMA test, the ray's slack (`slab_fma::t_slack`): `tmin` and `tmax` are
    /// the node tests' widened interval, the query's own `tmax` is the best hit's `t`.
    slack: f32,
    e: [f32; 3],
    _pad2: f32,
}

const _: () = assert!(std::mem::size_of::<StreamRay>() == 64);

/// A list of rays waiting to traverse the subtree `node`: ids `start..start + len` of
/// the arena; `top` is where the arena is free once this entry is popped.
#[derive(Clone, Copy, Debug)]
struct Entry {
    node: u32,
    start: u32,
    len: u32,
    top: u32,
}

/// The reusable buffers of one thread's stream traversals.
#[derive(Default)]
struct Scratch {
    rays: Vec<StreamRay>,
    /// The query of each binned ray.
    queries: Vec<RayQuery>,
    /// Index in the caller's batch of each binned ray.
    index: Vec<u32>,
    /// The octant of each ray of the caller's batch (8: invalid).
    order: Vec<u32>,
    best: Vec<Option<Hit>>,
    done: Vec<bool>,
    arena: Vec<u32>,
    /// The child mask of each ray of the list at hand.
    masks: Vec<u32>,
    stack: Vec<Entry>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

impl Scratch {
    /// Bins the valid rays of `rays` by octant into `rays`/`queries`/`index` (all three
    /// in bin order); returns the first binned ray of each octant (and the end).
    fn bin(&mut self, rays: &[Ray], fma: bool, root: &[[f32; 3]; 2]) -> [u32; 9] {
        // A counting sort by octant (the direction's sign bits, which are the
        // reciprocal's: 1/(-0.0) is -inf; 8 for an invalid ray, which `RayQuery::new`
        // rejects), then each valid ray's query and node-test record built straight into
        // its bin slot by `RayQuery::of_valid`, inlined.
        //
        // Why: the former form built every query in the caller's order by calling
        // `RayQuery::new` (not inlined there), whose `Option<RayQuery>` came back through
        // the stack and was copied with 32-byte loads spanning the callee's 4-byte stores
        // (a failed store forward per load), and then read the queries back with a
        // `vgatherdps` to fill the records: `perf annotate` of `examples/stream_profile
        // bunny.obj bvh8-stream diffuse 15` (AVX-512) put `Scratch::bin` at 10.6 % of
        // all samples and `RayQuery::new` at 1.9 %, 59 % of `bin`'s samples on the
        // copy's loads and stores and the gather. Queries in bin order also spare the
        // leaf tests the `index` indirection. After: `bin` 9.1 % of the same profile's
        // samples (against 12.5 % for `bin` and `RayQuery::new` before; `stream` and
        // `closest_from` 56.4 % against 56.3 %); on the 10^6-triangle mesh
        // (`stream_profile 1000000`) 4.4 % against 4.5 %, the records' stores missing
        // the cache there. An earlier form that built the queries in their bin slots
        // (after a pre-fill, still through the `RayQuery::new` call) measured the same
        // as the caller-order one: 6.79-7.22 against 6.68-7.05 Mrays/s.
        let keys = &mut self.order;
        keys.clear();
        let mut count = [0u32; 10];
        for r in rays {
            let k = if r.is_valid() {
                octant(r.dir) as u32
            } else {
                8
            };
            count[k as usize + 1] += 1;
            keys.push(k);
        }
        for o in 0..9 {
            count[o + 1] += count[o];
        }
        let n = count[8] as usize;
        let mut next = count;
        // Grown when short, never refilled: every slot below `n` is written below.
        if self.rays.len() < n {
            self.rays.resize(n, StreamRay::default());
        }
        self.rays.truncate(n);
        if self.queries.len() < n {
            self.queries.resize(n, Self::placeholder());
        }
        self.queries.truncate(n);
        self.index.clear();
        self.index.resize(n, 0);
        for (i, (r, &k)) in rays.iter().zip(keys.iter()).enumerate() {
            if k == 8 {
                continue;
            }
            let s = next[k as usize] as usize;
            next[k as usize] += 1;
            self.index[s] = i as u32;
            let q = RayQuery::of_valid(r);
            self.rays[s] = if fma {
                let x = fma_axes(q.origin.to_array(), q.dir.to_array(), q.inv_dir.to_array());
                let kz = q.kz;
                let slack = t_slack(root[0][kz], root[1][kz], q.origin[kz], q.sz);
                StreamRay {
                    a: x.map(|x| x.rn),
                    tmin: widened_tmin(q.tmin, slack),
                    b: x.map(|x| x.on),
                    tmax: widened_tmax(q.tmax, slack),
                    c: x.map(|x| x.rf),
                    slack,
                    e: x.map(|x| x.of),
                    ..StreamRay::default()
                }
            } else {
                StreamRay {
                    a: q.origin.to_array(),
                    tmin: q.tmin,
                    b: q.inv_dir.to_array(),
                    tmax: q.tmax * ROBUST_FAR_SCALE,
                    c: (q.inv_dir * ROBUST_FAR_SCALE).to_array(),
                    ..StreamRay::default()
                }
            };
            self.queries[s] = q;
        }
        self.best.clear();
        self.best.resize(n, None);
        self.done.clear();
        self.done.resize(n, false);
        count[..9].try_into().expect("nine bin starts")
    }

    /// Prefetches the query of binned ray `id` (its two cache lines).
    #[inline(always)]
    fn prefetch_query(&self, id: u32) {
        if let Some(q) = self.queries.get(id as usize) {
            prefetch(q, 2);
        }
    }

    /// A query to fill `queries` with as it grows (every slot is overwritten).
    #[cold]
    fn placeholder() -> RayQuery {
        RayQuery::new(&Ray::new(glam::Vec3::ZERO, glam::Vec3::X)).expect("a valid ray")
    }
}

/// A node's six plane vectors in the order an octant's rays read them.
struct OctantPlanes<L: Lanes> {
    near: [L; 3],
    far: [L; 3],
}

impl<L: FusedLanes> OctantPlanes<L> {
    #[inline(always)]
    fn new<const N: usize>(p: &[[f32; N]; 6], octant: usize) -> Self {
        let near = [0, 1, 2].map(|a| if octant >> a & 1 == 1 { a + 3 } else { a });
        OctantPlanes {
            near: near.map(|i| L::load(&p[i])),
            far: near.map(|i| L::load(&p[if i >= 3 { i - 3 } else { i + 3 }])),
        }
    }

    /// The single-ray slab test of `single.rs`, the same operations: entry distances
    /// and the mask of the children entered. `FMA`: the FMA test (`FmaRay::test`),
    /// else Ize's (`NodeRay`).
    #[inline(always)]
    fn test<const FMA: bool>(&self, r: &StreamRay) -> (L, L) {
        let s = L::splat;
        if FMA {
            let n = |a: usize| self.near[a].mul_sub_fused(s(r.a[a]), s(r.b[a]));
            let f = |a: usize| self.far[a].mul_sub_fused(s(r.c[a]), s(r.e[a]));
            let enter = n(0).maxps(n(1).maxps(n(2).maxps(s(r.tmin))));
            let exit = f(0).minps(f(1).minps(f(2).minps(s(r.tmax))));
            (enter, enter.le(exit))
        } else {
            let d = |a: usize| (self.near[a] - s(r.a[a])) * s(r.b[a]);
            let f = |a: usize| (self.far[a] - s(r.a[a])) * s(r.c[a]);
            let enter = d(0).maxps(d(1).maxps(d(2).maxps(s(r.tmin))));
            let exit = f(0).minps(f(1).minps(f(2).minps(s(r.tmax))));
            (enter, enter.le(exit))
        }
    }
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    /// Closest hits of a batch of rays by stream traversal; the same answers as
    /// [`closest_single`](Self::closest_single) for each ray.
    pub fn closest_stream(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        assert!(out.len() >= rays.len(), "one answer per ray");
        SCRATCH.with_borrow_mut(|s| {
            self.stream::<false>(s, rays);
            out[..rays.len()].fill(None);
            for (&i, h) in s.index.iter().zip(&s.best) {
                out[i as usize] = *h;
            }
        });
    }

    /// [`closest_stream`](Self::closest_stream)'s answers as lanes: ray `k`'s distance
    /// and primitive in `t[k]` and `prim[k]`, NaN and `u32::MAX` where it has none
    /// (see `Accel::closest_hit_stream_lanes`).
    pub fn closest_stream_lanes(&self, rays: &[Ray], t: &mut [f32], prim: &mut [u32]) {
        let n = rays.len();
        assert!(t.len() >= n && prim.len() >= n, "one answer per ray");
        SCRATCH.with_borrow_mut(|s| {
            self.stream::<false>(s, rays);
            t[..n].fill(f32::NAN);
            prim[..n].fill(u32::MAX);
            for (&i, h) in s.index.iter().zip(&s.best) {
                if let Some(h) = h {
                    (t[i as usize], prim[i as usize]) = (h.t, h.prim);
                }
            }
        });
    }

    /// Occlusion of a batch of rays by stream traversal; the same answers as
    /// [`any_single`](Self::any_single) for each ray.
    pub fn any_stream(&self, rays: &[Ray], out: &mut [bool]) {
        assert!(out.len() >= rays.len(), "one answer per ray");
        SCRATCH.with_borrow_mut(|s| {
            self.stream::<true>(s, rays);
            out[..rays.len()].fill(false);
            for (&i, &d) in s.index.iter().zip(&s.done) {
                out[i as usize] = d;
            }
        });
    }

    fn stream<const ANY: bool>(&self, s: &mut Scratch, rays: &[Ray]) {
        // The FMA node test needs tmin >= 0 (`simd/slab_fma.rs`); a batch with a ray
        // that has not takes Ize's test throughout.
        let fma = self.fma_slab && rays.iter().all(|r| r.tmin >= 0.0 || r.tmin.is_nan());
        let bins = s.bin(rays, fma, &self.root_box);
        for octant in 0..8 {
            let (b0, b1) = (bins[octant], bins[octant + 1]);
            if b1 > b0 {
                s.arena.clear();
                s.arena.extend(b0..b1);
                if fma {
                    self.stream_octant::<ANY, true>(s, octant, b1 - b0);
                } else {
                    self.stream_octant::<ANY, false>(s, octant, b1 - b0);
                }
            }
        }
    }

    /// Traverses the rays `s.arena[..len]` (all of direction octant `octant`).
    fn stream_octant<const ANY: bool, const FMA: bool>(
        &self,
        s: &mut Scratch,
        octant: usize,
        len: u32,
    ) {
        s.stack.clear();
        s.stack.push(Entry {
            node: self.root,
            start: 0,
            len,
            top: len,
        });
        while let Some(e) = s.stack.pop() {
            let (start, end) = (e.start as usize, (e.start + e.len) as usize);
            if is_leaf(e.node) || e.len < STREAM_MIN_RAYS {
                // The queries the leaf tests read, prefetched QUERY_AHEAD rays ahead.
                for k in start..(start + QUERY_AHEAD).min(end) {
                    s.prefetch_query(s.arena[k]);
                }
                for k in start..end {
                    if k + QUERY_AHEAD < end {
                        s.prefetch_query(s.arena[k + QUERY_AHEAD]);
                    }
                    let id = s.arena[k] as usize;
                    self.finish::<ANY, FMA>(s, id, e.node);
                }
                continue;
            }
            let node = &self.nodes[e.node as usize];
            let top = e.top as usize;
            let len = e.len as usize;
            let block = N * len;
            if s.arena.len() < top + block + COMPACT_SLACK {
                s.arena.resize(top + block + COMPACT_SLACK, 0);
            }
            if s.masks.len() < len {
                s.masks.resize(len, 0);
            }
            let (below, above) = s.arena.split_at_mut(top);
            let list = &below[start..end];
            let planes = OctantPlanes::<<Width<N> as NodeWidth>::L>::new(&node.planes(), octant);
            // Pass 1: every ray against the N children (no loop-carried dependency but
            // the sum); pass 2: each entered child's list compacted from the masks.
            let mut sum = <<Width<N> as NodeWidth>::L as Lanes>::splat(0.0);
            let mut union = 0u32;
            for (&id, m) in list.iter().zip(&mut s.masks[..len]) {
                let (enter, hit) = planes.test::<FMA>(&s.rays[id as usize]);
                *m = hit.bitmask();
                union |= *m;
                if !ANY {
                    sum = sum + (hit & enter);
                }
            }
            let mut counts = [0u32; N];
            let mut u = union;
            while u != 0 {
                let c = u.trailing_zeros();
                u &= u - 1;
                counts[c as usize] =
                    select_ids(list, &s.masks[..len], c, &mut above[c as usize * len..]) as u32;
            }
            let stride = len;
            // Children far to near by the mean entry distance of their rays, so the
            // nearest is popped first (ordered ray stream traversal).
            let sum = sum.to_array();
            let mut order = [(0usize, 0f32); N];
            let mut n = 0;
            for (c, &k) in counts.iter().enumerate() {
                if k == 0 {
                    continue;
                }
                let key = if ANY { 0.0 } else { sum.as_ref()[c] / k as f32 };
                insert_far_to_near(&mut order, &mut n, c, key);
            }
            let new_top = (top + block) as u32;
            // The children's nodes (all four lines) and their leaves' first triangle
            // group are prefetched as they are pushed: 1M-triangle mesh, diffuse rays,
            // interleaved runs: 4.53/4.57 Mrays/s without, 4.25-4.68 with the nodes
            // only, 4.76/4.77 with both; the bunny's diffuse rays unchanged (6.80-6.86).
            let children = node.children();
            for &(c, _) in &order[..n] {
                if self.prefetch.stream {
                    self.prefetch_child(children[c]);
                }
                s.stack.push(Entry {
                    node: children[c],
                    start: (top + c * stride) as u32,
                    len: counts[c],
                    top: new_top,
                });
            }
        }
    }

    /// Ray `id` through the subtree `node` on its own (a leaf, or a short list). With
    /// `FMA` a short list's ray reuses its stream record's constants instead of
    /// deriving them again (`closest_from` would).
    #[inline(always)]
    fn finish<const ANY: bool, const FMA: bool>(&self, s: &mut Scratch, id: usize, node: u32) {
        let q = &s.queries[id];
        let r = &s.rays[id];
        let fma_ray = || {
            let axes = [0, 1, 2].map(|a| FmaAxis {
                rn: r.a[a],
                on: r.b[a],
                rf: r.c[a],
                of: r.e[a],
            });
            FmaRay::<<Width<N> as NodeWidth>::L>::from_axes(
                axes,
                q.dir.to_array().map(|d| d.is_sign_negative()),
                r.tmin,
                r.slack,
            )
        };
        if ANY {
            if s.done[id] {
                return;
            }
            let hit = if is_leaf(node) {
                self.leaf_any(q, node)
            } else if FMA && self.leaf_call {
                self.any_with::<_, true>(&fma_ray(), q, node)
            } else if FMA {
                self.any_with::<_, false>(&fma_ray(), q, node)
            } else {
                self.any_from(q, node)
            };
            if hit {
                s.done[id] = true;
                s.rays[id].tmax = f32::NAN;
            }
        } else {
            // The query's interval ends at the best hit so far (`r.tmax` is the node
            // tests' bound: widened with the FMA test, scaled with Ize's).
            let tmax = s.best[id].map_or(q.tmax, |h| h.t);
            let slack = r.slack;
            let h = if is_leaf(node) {
                self.leaf_closest(q, node, tmax)
            } else if FMA && self.leaf_call {
                self.closest_with::<_, true>(&fma_ray(), q, node, tmax)
            } else if FMA {
                self.closest_with::<_, false>(&fma_ray(), q, node, tmax)
            } else {
                self.closest_from(q, node, tmax)
            };
            if let Some(h) = h {
                s.rays[id].tmax = if FMA {
                    widened_tmax(h.t, slack)
                } else {
                    h.t * ROBUST_FAR_SCALE
                };
                s.best[id] = Some(h);
            }
        }
    }
}

/// Batches with fewer rays go through the packet kernels.
pub const STREAM_MIN_BATCH: usize = 128;

/// Whether the stream kernel beats the packet kernels' ray-by-ray fallback on
/// incoherent batches in the instruction set this binary was built for, as measured
/// (bunny, diffuse rays, 1 thread, interleaved runs, Mrays/s; see the README):
/// - AVX-512 (compaction by `vpcompressd`): stream level with Embree, 6.24 against
///   6.33, well ahead of packets.
/// - AVX2 with the left-pack compaction (`simd/left_pack.rs`): stream 2.77-2.93
///   against bvh8-packet 2.51-2.67 Mrays per CPU-second (a loaded machine; README,
///   "AVX2 compaction"); on the 10^6-triangle mesh level (1.83 against 1.92).
/// - Without AVX2 the compaction is the scalar loop, which measured no faster than
///   packets on this AVX2 machine when AVX2 builds still used it (stream 2.73 against
///   bvh8-packet 3.16 Mrays/s in a quiet run; 2.50-2.77 against 2.60-2.68 per
///   CPU-second under load): such builds keep incoherent batches in packets.
pub const STREAM_WINS: bool = cfg!(all(
    target_arch = "x86_64",
    any(target_feature = "avx2", target_feature = "avx512f")
));

/// Whether a batch is better traced as a stream than as packets: the stream kernel
/// wins in this build ([`STREAM_WINS`]) and the batch is [`incoherent_batch`].
pub fn prefers_stream(rays: &[Ray]) -> bool {
    STREAM_WINS && incoherent_batch(rays)
}

/// At least [`STREAM_MIN_BATCH`] rays, and most of its 16-ray packets incoherent (their
/// rays fall into more than two groups of direction octant and dominant axis, which
/// sends a packet ray by ray: see `packet_setup.rs`).
pub fn incoherent_batch(rays: &[Ray]) -> bool {
    if rays.len() < STREAM_MIN_BATCH {
        return false;
    }
    // The answer, `2 incoherent > packets`, is settled as soon as either count reaches
    // half the packets (`2 coherent >= packets` leaves `2 incoherent <= packets`): a
    // batch of coherent packets (camera rays, shadow rays towards a point light) is
    // decided after half of them.
    let packets = rays.len().div_ceil(crate::simd::PACKET_WIDTH);
    let (mut incoherent, mut coherent) = (0, 0);
    for packet in rays.chunks(crate::simd::PACKET_WIDTH) {
        let groups = packet.iter().fold(0u32, |g, r| {
            let kz = crate::geometry::dominant_axis(r.dir);
            g | 1 << (octant(r.dir) * 3 + kz)
        });
        if groups.count_ones() > 2 {
            incoherent += 1;
            if 2 * incoherent > packets {
                return true;
            }
        } else {
            coherent += 1;
            if 2 * coherent >= packets {
                return false;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Triangles;
    use crate::accel::bvhn::tree::Bvh8;
    use glam::Vec3;

    /// xorshift32 in [0, 1).
    fn uniform(s: &mut u32) -> f32 {
        *s ^= *s << 13;
        *s ^= *s >> 17;
        *s ^= *s << 5;
        (*s >> 8) as f32 / 16_777_216.0
    }

    /// Rays with every kind of direction the binning meets: random ones, signed zeros,
    /// ties between axes for the dominant one, and invalid rays (zero or non-finite
    /// direction, NaN origin, an empty interval) interleaved.
    fn mixed_rays(count: usize, seed: u32) -> Vec<Ray> {
        let mut s = seed;
        let mut rays = Vec::with_capacity(count);
        for i in 0..count {
            let mut u = || uniform(&mut s) * 2.0 - 1.0;
            let o = Vec3::new(u() * 12.0 + 5.0, u() * 12.0 + 5.0, u() * 12.0 + 5.0);
            let d = match i % 11 {
                0 => Vec3::new(-0.0, u(), 0.0),
                1 => Vec3::new(0.5, -0.5, u() * 0.5),
                2 => Vec3::new(-0.25, 0.25, -0.25),
                3 => Vec3::ZERO,
                4 => Vec3::new(f32::INFINITY, 1.0, 0.0),
                _ => Vec3::new(u(), u(), u()),
            };
            let mut r = Ray::new(o, d);
            match i % 13 {
                5 => r.origin.y = f32::NAN,
                6 => (r.tmin, r.tmax) = (2.0, 1.0),
                7 => (r.tmin, r.tmax, r.time) = (0.5, 9.0, 0.25),
                _ => {}
            }
            rays.push(r);
        }
        rays
    }

    /// `incoherent_batch`'s early answer against the whole count (`2 incoherent >
    /// packets`, every packet classified): batches of coherent and incoherent 16-ray
    /// packets in every proportion from none to all, in three orders (incoherent first,
    /// last, spread evenly), with a short last packet, around the exact half.
    #[test]
    fn incoherent_batch_answers_as_the_whole_count() {
        let coherent = |i: usize| Ray::new(Vec3::new(0.01 * i as f32, 0.0, 5.0), Vec3::NEG_Z);
        let incoherent_rays = mixed_rays(16, 9);
        let whole_count = |rays: &[Ray]| {
            let packets = rays.len().div_ceil(crate::simd::PACKET_WIDTH);
            let incoherent = rays
                .chunks(crate::simd::PACKET_WIDTH)
                .filter(|p| {
                    let groups = p.iter().fold(0u32, |g, r| {
                        g | 1 << (octant(r.dir) * 3 + crate::geometry::dominant_axis(r.dir))
                    });
                    groups.count_ones() > 2
                })
                .count();
            rays.len() >= STREAM_MIN_BATCH && 2 * incoherent > packets
        };
        let (mut yes, mut no) = (0, 0);
        for packets in [8usize, 9, 16, 17] {
            for tail in [0usize, 5] {
                let len = packets * 16 - if tail > 0 { 16 - tail } else { 0 };
                for bad in 0..=packets {
                    for order in 0..3 {
                        let is_bad = |p: usize| match order {
                            0 => p < bad,
                            1 => p >= packets - bad,
                            _ => p * bad / packets != (p + 1) * bad / packets,
                        };
                        let rays: Vec<Ray> = (0..len)
                            .map(|i| {
                                if is_bad(i / 16) {
                                    incoherent_rays[i % 16]
                                } else {
                                    coherent(i)
                                }
                            })
                            .collect();
                        let want = whole_count(&rays);
                        assert_eq!(
                            incoherent_batch(&rays),
                            want,
                            "{packets} packets ({len} rays), {bad} incoherent, order {order}"
                        );
                        if want { yes += 1 } else { no += 1 }
                    }
                }
            }
        }
        assert!(yes > 50 && no > 50, "both answers met ({yes}, {no})");
    }

    /// Batches of decreasing size through one thread's scratch (whose buffers are then
    /// longer than the batch and hold the previous batch's rays), with invalid rays
    /// among them: every answer is the single-ray kernel's.
    #[test]
    fn stream_batches_of_shrinking_size_answer_as_single_rays() {
        let mut corners = Vec::new();
        let mut s = 3u32;
        for _ in 0..4000 {
            let mut u = || uniform(&mut s);
            let c = Vec3::new(u(), u(), u()) * 10.0;
            corners.push([
                c,
                c + Vec3::new(u(), u(), 0.1),
                c + Vec3::new(0.2, u(), u()),
            ]);
        }
        let bvh = Bvh8::build(Triangles::from_corners(&corners));
        let rays = mixed_rays(3000, 5);
        let mut hits_seen = 0;
        for len in [3000, 1700, 400, 129, 5, 1, 0] {
            let batch = &rays[..len];
            let mut closest = vec![None; len];
            let mut occluded = vec![true; len];
            bvh.closest_stream(batch, &mut closest);
            bvh.any_stream(batch, &mut occluded);
            // The answers as lanes, into buffers longer than the batch holding junk.
            let (mut t, mut prim) = (vec![-7.0f32; len + 3], vec![7u32; len + 3]);
            bvh.closest_stream_lanes(batch, &mut t, &mut prim);
            for (i, r) in batch.iter().enumerate() {
                let single = bvh.closest_single(r);
                assert_eq!(closest[i], single, "batch {len}, ray {i}");
                let lanes =
                    single.map_or((f32::NAN.to_bits(), u32::MAX), |h| (h.t.to_bits(), h.prim));
                assert_eq!(
                    (t[i].to_bits(), prim[i]),
                    lanes,
                    "lanes: batch {len}, ray {i}"
                );
                assert_eq!(occluded[i], bvh.any_single(r), "batch {len}, ray {i}");
                hits_seen += single.is_some() as usize;
            }
        }
        assert!(hits_seen > 300, "{hits_seen} hits");
    }
}
