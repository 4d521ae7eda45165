//! The N-wide BVH itself: what it owns, its build (binned-SAH BVH2, then the
//! collapse), its shape statistics, and the [`Accel`] entry points.

use super::collapse::{Collapse, PARALLEL_COLLAPSE_LEVELS};
use super::node::{BvhNode, EMPTY_CHILD, NodeWidth, WideNode, Width, is_leaf, leaf_range};
use super::packet::PACKET_MIN_ACTIVE;
use super::qnode::QNode;
use super::stack::SINGLE_STACK;
use crate::accel::filter::{FilterSink, HitFilter, QueryOptions};
use crate::accel::sah_build::{SpareRefs, build_tree_keeping_refs};
use crate::accel::{Accel, AccelInfo, Bvh2BuildOptions, PacketHitLanes, Primitives};
use crate::geometry::{Hit, Ray, RayPacket, RayQuery};
use crate::pages::LargeVec;
use crate::simd::kernels::TriGroup4;
use crate::simd::prefetch::prefetch;
use crate::simd::slab_fma::FMA_SLAB;
use crate::simd::{PACKET_WIDTH, Packet};
use std::time::Instant;

/// What the leaves hold.
pub(super) enum Leaves<P> {
    /// Triangle meshes: groups of four, SoA.
    Triangles(LargeVec<TriGroup4>),
    /// Anything else: the primitives in leaf order and their original indices.
    Scalar { prims: P, ids: Vec<u32> },
}

/// Which traversals prefetch the children they are about to visit (their nodes, or a
/// leaf's first triangle group) as they push them. Measured per kernel (README, issue
/// 12); [`Prefetch::default`] turns it on where it won.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prefetch {
    pub single: bool,
    pub packet: bool,
    pub stream: bool,
}

impl Default for Prefetch {
    fn default() -> Self {
        Prefetch {
            single: false,
            // On since issue 12 (pk17): 10^6 primary per CPU-second, interleaved,
            // `bvh8-packet+pf` / default 14.44 / 11.88 and 14.65 / 15.38, earlier
            // 13.45 / 11.44, 15.31 / 13.19, 16.33 / 12.99; bunny primary and shadow
            // and 10^6 shadow level.
            packet: true,
            stream: true,
        }
    }
}

/// An N-wide BVH over one primitive set (N = 4 or 8: see [`NodeWidth`]), with exact
/// ([`BvhNode`], the default) or compressed ([`QNode`]) nodes: see [`WideNode`].
pub struct Bvh<P: Primitives, const N: usize, T: WideNode<N> = BvhNode<N>> {
    pub nodes: LargeVec<T>,
    pub(super) leaves: Leaves<P>,
    pub(super) root: u32,
    pub(super) info: AccelInfo,
    /// The most entries any traversal can have on its stack: the largest sum of
    /// (children - 1) along a root-to-leaf path.
    pub(super) stack_need: usize,
    pub(super) prefetch: Prefetch,
    /// Packet traversal: a part with fewer active lanes than this finishes its subtree
    /// ray by ray (`[closest, occlusion]`).
    pub(super) packet_min_active: [u32; 2],
    /// The single-ray and stream kernels test nodes with the FMA slab test
    /// (`simd::slab_fma`; rays with `tmin >= 0` in builds with FMA), else with Ize's
    /// subtract-multiply test.
    pub(super) fma_slab: bool,
    /// The root box's planes (`[min, max]`), for the FMA test's slack
    /// (`simd::slab_fma::t_slack`).
    pub(super) root_box: [[f32; 3]; 2],
    /// The FMA single-ray kernel calls its leaf test out of line (`bench`'s `+call`
    /// modes; see `single.rs`).
    pub(super) leaf_call: bool,
}

/// The 4-wide BVH.
pub type Bvh4<P> = Bvh<P, 4>;
/// The 8-wide BVH.
pub type Bvh8<P> = Bvh<P, 8>;
/// The 4-wide BVH with compressed nodes (64 bytes each).
pub type Bvh4c<P> = Bvh<P, 4, QNode<4>>;
/// The 8-wide BVH with compressed nodes (128 bytes each).
pub type Bvh8c<P> = Bvh<P, 8, QNode<8>>;

/// Build parameters for 4-wide leaves. Triangle leaves are tested four at a time, so
/// the SAH counts them in blocks of four (a leaf of 1-4 triangles costs one test): on
/// the bunny this packs leaves (37k half-empty groups before) and builds 41 -> 30 ms,
/// with 4-7 % faster traversal. One group per leaf: on the bunny, leaves of up to two
/// groups were 3 % slower for single rays through the BVH8 (4.14 vs 4.28 Mrays/s
/// diffuse) and 7 % for its packets, and no faster for the BVH4. At 10^6 (big19,
/// 2026-11-28, `/tmp/m1e6.obj`, 1 thread, load 4-5, interleaved rounds, Mrays/s medians
/// of 5 passes) leaves of up to two groups (`max_leaf` 8) did not win either: 27,051
/// page faults per build against 17,547 (more, part-empty groups: a 5-triangle leaf
/// takes two), CPU ms per build 405/483/431/394 against 505/404/398/439; bvh8-packet
/// primary 9.14/12.38/12.27/12.36/12.54 against 12.14/12.49/11.79/11.56/12.57, shadow
/// 4.36/4.00/4.30/4.01 against 4.37/3.92/4.05/4.22; bvh8-stream diffuse 2.73/2.62/2.38/
/// 3.19 against 3.10/2.79/2.41/2.82. Scalar leaves (spheres) keep per-primitive costs.
pub fn wide_build_options(simd_triangle_leaves: bool) -> Bvh2BuildOptions {
    Bvh2BuildOptions {
        max_leaf: 4,
        block_size: if simd_triangle_leaves { 4 } else { 1 },
        ..Bvh2BuildOptions::default()
    }
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    pub fn build(prims: P) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let triangles = prims.as_triangles();
        let (tree, ids, spare) =
            build_tree_keeping_refs(&prims, wide_build_options(triangles.is_some()));
        let parallel = rayon::current_num_threads() > 1;
        // The triangle groups go into the build's dead reference array where it is
        // large (`SpareRefs`: at 10^7 its 320 MB of pages would otherwise be unmapped
        // and 420 MB of fresh ones faulted in), sized by the collapse once its node
        // pass has counted them (`Collapse::gather`, `Collapse::collapse_parallel`).
        let spare = triangles.map(|_| spare);
        let mut c = Collapse::<N> {
            ids: &ids,
            triangles,
            nodes: if parallel {
                LargeVec::new()
            } else {
                LargeVec::with_capacity(n / 2 + 1)
            },
            groups: LargeVec::new(),
        };
        // Tried, no clear win, removed (issue 12, pk17): `madvise(MADV_HUGEPAGE)` on the
        // node and group arrays before the collapse writes them, as Embree's allocator
        // does (`os_advise`); this host's transparent_hugepage is `madvise`, so a 10^6
        // tree (~60 MiB) sits in ~15,000 4 KiB pages. It took (56 MiB in huge pages)
        // but 10^6 primary (`stream_profile /tmp/m1e6.obj MODE primary 7`, AVX-512, 1
        // thread, load 6-7, Mrays per CPU-second, interleaved) gave 12.06 / 12.59
        // without packet prefetch against 11.88 / 15.38 / 11.44 / 13.19 / 12.99 without
        // the advice, and 15.18 / 15.12 with prefetch against 14.44 / 14.65. The
        // first-load stalls are latency, which the packet prefetch hides, not the TLB.
        // Tried, level, reverted (issue 12, session 26, commit 83897f4): the node array
        // and a fresh groups array advised for huge pages before the collapse writes
        // them (`pages::advise_huge_pages` over the capacity). pk26 had found Embree's
        // 10^6 process holding 62 MiB of huge pages and ours none, and Embree without
        // them (`PR_SET_THP_DISABLE`) 16-17 % slower at 10^6 primary. With the advice
        // our process held 20 MiB (the nodes; the groups came from recycled heap
        // memory). `stream_profile /tmp/m1e6.obj bvh8-packet primary 5` against the
        // session's base, 4 interleaved rounds, load 1.1-1.3, Mrays/s medians: base
        // 28.64/26.26/24.29/24.75, advised 25.82/26.40/26.22/25.61 (earlier 3 rounds
        // 25.97/22.29/22.39 against 23.09/26.20/24.42); `build_time 1000000 5 2` 174.8/
        // 179.9 against 192.9/193.6 ms, 1 thread 337.5 against 315.9. And
        // `madvise(MADV_COLLAPSE)` of both arrays after the build (the kernel copies the
        // written pages into huge pages; 5.4 ms for the nodes' 18 MiB, 9.8 ms for the
        // groups' 38 MiB, 1 thread): primary 24.15/26.56/26.63/27.68 without against
        // 27.03/27.60/27.73/28.44 with (4 rounds), but 2-thread builds 180-189 -> 203-239
        // ms, which the build target against Embree's (220-258 ms) cannot spare.
        // Since session 27 (hp27) both arrays are `LargeVec`s (`pages::LargeVec`): from
        // 4 MiB up a 2 MiB-aligned mapping of their own, advised for huge pages before
        // the collapse's first write, so the tree is in huge pages from the start (62
        // MiB of `AnonHugePages` at 10^6, against 0-8 before) with no copy. The nodes:
        // at 1 thread room for n / 2 + 1 reserved here (the collapse pushes them as it
        // goes; only the pages it writes are backed), at 2 threads the exact count,
        // reserved by the parallel collapse. The groups at their exact count, or in
        // the build's spare reference memory where that is recycled (`SpareRefs`, 10^7:
        // advised for huge pages before its first touch already); a spare array too
        // small to be recycled is dropped here, before the collapse.
        // The upper bound measured first (env switch, removed): `MADV_COLLAPSE` of both
        // arrays after the build, same binary on/off, `stream_profile /tmp/m1e6.obj MODE
        // W 5`, 1 thread, AVX-512, 6 interleaved rounds, load 2.0-2.6, medians of the
        // rounds' medians (Mrays/s): bvh8-stream diffuse 4.39 -> 4.64 (+5.6 %), bvh4-stream
        // diffuse 4.12 -> 4.44 (+7.8 %), bvh8-packet primary 28.45 -> 29.24 (+2.8 %),
        // shadow level. The `LargeVec` form's figures are in the commit messages and
        // `pages::array`'s header.
        let spare = spare.filter(SpareRefs::recycles);
        let root = match &tree {
            None => EMPTY_CHILD,
            // One thread gains nothing from the parallel levels and pays for them: each
            // task's subtree is walked twice, once to count its nodes and groups.
            Some(t) => {
                let levels = if parallel {
                    PARALLEL_COLLAPSE_LEVELS
                } else {
                    0
                };
                c.collapse_recycling(t, levels, spare)
            }
        };
        let Collapse { nodes, groups, .. } = c;
        // Tried, no clear win, removed (issue 12, big21, 2026-11-28): the nodes renumbered
        // after the collapse with siblings together (every node's interior children one
        // block of up to N consecutive nodes, the blocks depth first, the first child's
        // block next: the simplest of Yoon and Manocha's cache-conscious BVH layouts,
        // Eurographics 2006) instead of the collapse's depth-first order, where only a
        // node's first interior child is next to it. Same binary, the order switched by
        // an environment variable, interleaved `examples/stream_profile 1000000 MODE
        // WORKLOAD 7` rounds, AVX-512, 1 thread, load 5.5-7.4, Mrays per CPU-second
        // (medians; depth first / siblings together): bvh8-packet primary 17.98 / 17.75
        // (8 rounds) and 15.29 / 16.90 (10 rounds), shadow 6.15 / 6.74 (6) and 6.54 /
        // 6.18 (8), bvh8-stream diffuse 3.00 / 3.05 (8); bunny primary 35.73 / 36.68
        // (8). Same checksums. Within this host's noise either way, and the renumbering
        // copies the node array (22 MB at 10^6) inside the build.
        // Tried, no clear win, reverted (issue 12, big23, 2026-11-29; commit db5d216 on
        // branch big23, `store.rs`): every node followed by its leaf children's triangle
        // groups in one array of 32-byte units (a node's cache lines, then its leaves'
        // lines, as Embree's block allocator lays a leaf out after its parent; interior
        // references and leaf `first` as unit offsets; `validate()` checked that an
        // interior reference is a node's start and that a leaf's groups lie in the array
        // clear of every node), built by a pass after the collapse. Same checksums (10^6
        // and bunny, every mode). 10^6 (`bench --mesh /tmp/m1e6.obj --threads 1 --reps 5
        // --modes bvh8-packet,bvh8-stream`, AVX-512, load 5-7, 9 interleaved rounds
        // against the session's base binary, Mrays per CPU-second, min/median/max, base
        // then store): bvh8-packet primary 14.99/17.30/23.54 against 15.89/18.04/20.28,
        // shadow 5.23/6.09/7.15 against 5.58/6.31/6.57, diffuse 1.91/2.37/2.54 against
        // 1.95/2.35/2.54; bvh8-stream diffuse 2.23/2.72/2.89 against 2.25/2.73/3.16,
        // shadow 3.74/4.72/5.64 against 3.03/4.88/5.33: medians +2 to +4 % on primary
        // and shadow, level on diffuse, every range overlapping. The build paid for the
        // copy into a fresh 63 MB array (glibc maps a block that size afresh for every
        // build): `build_time 1000000 3 1`, 3 interleaved rounds, CPU ms medians
        // 348/328/359 against 393/389/382, page faults 17,546 against 33,077, peak RSS
        // 253 against 316 bytes per triangle, 62.9 against 63.6 bytes per triangle (a
        // unit of padding after an odd number of groups). With `madvise(MADV_HUGEPAGE)`
        // on the new array the faults fell to 17,747-18,258 but not the time (447/410/
        // 385 against 519/449/495, a slower state of the host). A form without the
        // copy would have the collapse write each node's leaf groups after it directly.
        // Compressed nodes are quantised from the exact ones (for exact nodes this is
        // the identity, collected in place).
        let nodes: LargeVec<T> = nodes.map(T::from_exact);
        let root_area = tree.as_ref().map_or(0.0, |t| t.bounds().area());
        let leaves = if triangles.is_some() {
            // Freed before the build tree, as it was when both were freed at the end of
            // this function (locals in reverse order): freed after it, the heap's top
            // was trimmed differently and the next build at 1 thread faulted ~14k more
            // pages (29.4k against 15.4k per 10^6 build, `build_time 1000000 3 1`).
            drop(ids);
            Leaves::Triangles(groups)
        } else {
            Leaves::Scalar {
                prims: prims.permute(&ids),
                ids,
            }
        };
        let leaf_bytes = match &leaves {
            Leaves::Triangles(g) => g.len() * std::mem::size_of::<TriGroup4>(),
            Leaves::Scalar { prims, ids } => prims.memory_bytes() + ids.len() * 4,
        };
        let mut bvh = Bvh {
            nodes,
            leaves,
            root,
            info: AccelInfo::default(),
            stack_need: 0,
            prefetch: Prefetch::default(),
            packet_min_active: [PACKET_MIN_ACTIVE; 2],
            fma_slab: false,
            root_box: tree.as_ref().map_or([[0.0; 3]; 2], |t| {
                let b = t.bounds();
                [b.min.to_array(), b.max.to_array()]
            }),
            leaf_call: false,
        };
        // The build tree (one arena of child pairs: `accel::build_arena`) is freed while
        // the shape walk runs, so `build_ms` counts its drop (it ended the build before,
        // after `build_ms` was taken; `bench`'s build ms, timed around the call, counted
        // it already).
        let ((leaf_count, depth, sah, stack_need), ()) =
            rayon::join(|| bvh.shape(root_area), || drop(tree));
        assert!(
            stack_need < SINGLE_STACK,
            "BVH{N} deeper than the BVH2 depth bound allows"
        );
        bvh.stack_need = stack_need;
        bvh.info = AccelInfo {
            name: match (N, T::COMPRESSED) {
                (4, false) => "bvh4",
                (4, true) => "bvh4c",
                (_, false) => "bvh8",
                (_, true) => "bvh8c",
            },
            primitives: n,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            nodes: bvh.nodes.len(),
            leaves: leaf_count,
            max_depth: depth,
            memory_bytes: bvh.nodes.len() * std::mem::size_of::<T>() + leaf_bytes,
            sah_cost: sah,
        };
        bvh
    }

    /// (leaf count, depth, SAH cost with one unit per node visit and per leaf group or
    /// primitive relative to the root's area, traversal stack need: the largest sum of
    /// children - 1 along a root-to-leaf path).
    fn shape(&self, root_area: f32) -> (usize, usize, f64, usize) {
        let (mut leaves, mut depth, mut cost, mut need) = (0, 0, 0.0, 0);
        let inv = 1.0 / root_area.max(f32::MIN_POSITIVE) as f64;
        let mut stack = vec![(self.root, 0usize, root_area, 0usize)];
        while let Some((r, d, area, pending)) = stack.pop() {
            depth = depth.max(d);
            need = need.max(pending);
            if is_leaf(r) {
                leaves += usize::from(r != EMPTY_CHILD);
                cost += area as f64 * inv * leaf_range(r).len() as f64;
            } else {
                cost += area as f64 * inv;
                let node = &self.nodes[r as usize];
                let kids = node
                    .children()
                    .iter()
                    .filter(|&&c| c != EMPTY_CHILD)
                    .count();
                for (slot, &c) in node.children().iter().enumerate() {
                    if c != EMPTY_CHILD {
                        let area = node.child_bounds(slot).area();
                        stack.push((c, d + 1, area, pending + kids - 1));
                    }
                }
            }
        }
        (leaves, depth, cost, need)
    }

    /// Which traversals prefetch (see [`Prefetch`]).
    pub fn set_prefetch(&mut self, prefetch: Prefetch) {
        self.prefetch = prefetch;
    }

    /// The packet kernels' ray-by-ray threshold (`[closest, occlusion]`; default
    /// [`PACKET_MIN_ACTIVE`] for both).
    pub fn set_packet_min_active(&mut self, min_active: [u32; 2]) {
        self.packet_min_active = min_active;
    }

    /// Whether the single-ray and stream kernels use the FMA slab test (only where the
    /// build has FMA: [`FMA_SLAB`], and only over triangle leaves: the slack that makes
    /// it agree with brute force bounds the triangle test's error in `t`, see
    /// `simd::slab_fma`). **Off by default**: the far-origin misses found at the merge
    /// are explained and fixed (the triangle test's `t` lies ulps below its own box at
    /// 10^8; each ray now widens its interval by `t_slack`), and with it on the suite's
    /// `rays_from_far_away_agree_with_brute_force`, `queries` (the filtered query takes
    /// the same node test) and `simd_equivalence` pass; but it did not measure faster
    /// (bunny, 1 thread, load 9, `cpu` 0.16-0.22, per CPU-second: `bvh8-single` diffuse
    /// 3.0 vs 2.5 with FMA, primary 9.0 vs 7.6; `bvh8-stream` diffuse 3.1 vs 3.0;
    /// `bvh4-single` diffuse 2.7 vs 2.7). On is the experiment `bench`'s `+fma` modes run.
    pub fn set_fma_slab(&mut self, on: bool) {
        self.fma_slab = on && FMA_SLAB && matches!(self.leaves, Leaves::Triangles(_));
    }

    /// Whether the FMA single-ray kernel calls its leaf test out of line.
    pub fn set_leaf_call(&mut self, on: bool) {
        self.leaf_call = on;
    }

    /// Prefetches what visiting child reference `r` reads first: its node (every
    /// line), or its leaf's first triangle group.
    #[inline(always)]
    pub(super) fn prefetch_child(&self, r: u32) {
        if !is_leaf(r) {
            prefetch(&self.nodes[r as usize], 4);
        } else if let Leaves::Triangles(groups) = &self.leaves
            && let Some(g) = groups.get(leaf_range(r).start)
        {
            prefetch(g, 3);
        }
    }

    /// Bytes per primitive of nodes and leaves.
    pub fn bytes_per_primitive(&self) -> f64 {
        self.info.memory_bytes as f64 / self.info.primitives.max(1) as f64
    }
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Accel for Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_single(ray)
    }

    fn any_hit(&self, ray: &Ray) -> bool {
        self.any_single(ray)
    }

    fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut HitFilter<'_>,
    ) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        let mut sink = FilterSink::new(&q, opts, filter);
        self.filtered_from(&q, &mut sink);
        sink.best
    }

    fn closest_hit_batch(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        // A partial last packet leaves its missing lanes invalid.
        for (r, o) in rays.chunks(PACKET_WIDTH).zip(out.chunks_mut(PACKET_WIDTH)) {
            self.packet_closest::<Packet, _>(r, o);
        }
    }

    fn any_hit_batch(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.chunks(PACKET_WIDTH).zip(out.chunks_mut(PACKET_WIDTH)) {
            self.packet_any::<Packet, _>(r, o);
        }
    }

    fn closest_hit_stream(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.closest_stream(rays, out);
    }

    fn closest_hit_stream_lanes(&self, rays: &[Ray], t: &mut [f32], prim: &mut [u32]) {
        self.closest_stream_lanes(rays, t, prim);
    }

    fn any_hit_stream(&self, rays: &[Ray], out: &mut [bool]) {
        self.any_stream(rays, out);
    }

    fn closest_hit_packet(&self, packet: &RayPacket, out: &mut [Option<Hit>]) {
        self.packet_closest::<Packet, _>(packet, out);
    }

    fn any_hit_packet(&self, packet: &RayPacket, out: &mut [bool]) {
        self.packet_any::<Packet, _>(packet, out);
    }

    /// The kernel's lanes as they are (no `Option<Hit>` per lane); the hit bits cut at
    /// `packet.len` (lanes past it are invalid rays, which hit nothing anyway).
    fn closest_hit_packet_lanes(&self, packet: &RayPacket, out: &mut PacketHitLanes) {
        let h = self.packet_closest_lanes::<Packet, _>(packet);
        out.t = h.t.to_array();
        out.u = h.u.to_array();
        out.v = h.v.to_array();
        // A plain loop (one bit cast of the vector), not `array::map` (an out-of-line
        // call in places: see `PacketBounds::triangle_candidates`).
        let prim = h.prim.to_array();
        for (o, p) in out.prim.iter_mut().zip(prim) {
            *o = p.to_bits();
        }
        out.hit = h.hit & ((1u32 << packet.len) - 1);
    }

    fn info(&self) -> AccelInfo {
        self.info.clone()
    }
}
