//! Packet (hybrid) traversal: closest hit and occlusion of a packet group, with the
//! ray-by-ray finish of a subtree when few lanes stay active.

use super::node::{NodeWidth, WideNode, Width, is_leaf, leaf_range};
use super::packet_bounds::{PACKET_BOUNDS_MIN_NODES, PacketBounds};
use super::packet_setup::{PacketRays, PacketSetup, for_each_bit, lane_query};
use super::stack::{LaneStack, PACKET_STACK, insert_far_to_near};
use super::tree::{Bvh, Leaves};
use crate::accel::Primitives;
use crate::geometry::{
    Hit, LaneRays, PrimHit, ROBUST_FAR_SCALE, Ray, RayPacket, RayQuery, intersect_triangle,
};
use crate::simd::kernels::triangle_packet;
use crate::simd::{F8, Lanes, PACKET_WIDTH, Packet};
use glam::Vec3;

/// Rays a packet part keeps traversing together; with fewer active rays it finishes the
/// subtree ray by ray (measured: see README, "Packet threshold").
pub const PACKET_MIN_ACTIVE: u32 = 3;

/// Per-lane answers of a packet group: lanes under the bits of `hit` hold a hit.
pub(super) struct PacketHits<L: Lanes> {
    pub(super) t: L,
    pub(super) u: L,
    pub(super) v: L,
    /// Primitive ids as `f32` bit patterns (moved by blends only, never by arithmetic),
    /// so a hit updates every lane's id with one select instead of a loop over its bits.
    pub(super) prim: L,
    pub(super) hit: u32,
}

/// `id` as the lane value of [`PacketHits::prim`].
#[inline(always)]
fn prim_lanes<L: Lanes>(id: u32) -> L {
    L::splat(f32::from_bits(id))
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    /// Traces `rays` (exactly `L::WIDTH`) as packets: lanes are grouped by direction
    /// octant and dominant axis, each group traversed together; a packet whose rays fall
    /// into more than two groups is incoherent and goes ray by ray instead, as do all
    /// packets of a tree too deep for the packet stack.
    pub(super) fn packet_closest<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        rays: &R,
        out: &mut [Option<Hit>],
    ) {
        let out = &mut out[..rays.lane_count()];
        let all = self.packet_closest_lanes::<L, R>(rays);
        let (t, u, v, prim) = (
            all.t.to_array(),
            all.u.to_array(),
            all.v.to_array(),
            all.prim.to_array(),
        );
        for (i, o) in out.iter_mut().enumerate() {
            *o = (all.hit >> i & 1 == 1).then(|| Hit {
                t: t.as_ref()[i],
                prim: prim.as_ref()[i].to_bits(),
                u: u.as_ref()[i],
                v: v.as_ref()[i],
            });
        }
    }

    /// The closest hits of `rays` (exactly `L::WIDTH`) in lanes: lane `i` holds a hit
    /// where bit `i` of `hit` is set (what [`packet_closest`](Self::packet_closest)
    /// writes as `Option<Hit>`s).
    #[inline(always)]
    pub(super) fn packet_closest_lanes<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        rays: &R,
    ) -> PacketHits<L> {
        let setup = PacketSetup::<L>::new(rays);
        // No valid lane (no group) also takes this path: no hit.
        if setup.groups == 0 || !setup.coherent() || self.stack_need >= PACKET_STACK {
            return self.packet_closest_by_lane(rays, setup.valid);
        }
        // The groups' answers merged in lanes, then every lane written once: before,
        // `out` was filled with `None` first (compiled as AVX-512 scatters of the
        // 20-byte `Option<Hit>`'s tag: 1.5 % of `closest_hit_packet`'s samples, `perf
        // record` of `examples/stream_profile bunny.obj bvh8-packet primary 60`) and the
        // hits written over it.
        let mut all = self.packet_closest_group(
            &setup.group(0),
            rays,
            setup.group_mask[0],
            setup.shared_origin,
        );
        for g in 1..setup.groups {
            let h = self.packet_closest_group(
                &setup.group(g),
                rays,
                setup.group_mask[g],
                setup.shared_origin,
            );
            let sel = L::mask_from_bits(h.hit);
            all = PacketHits {
                t: L::select(sel, h.t, all.t),
                u: L::select(sel, h.u, all.u),
                v: L::select(sel, h.v, all.v),
                prim: L::select(sel, h.prim, all.prim),
                hit: all.hit | h.hit,
            };
        }
        all
    }

    /// The lanes of `valid` traced one by one (incoherent packets, trees too deep for
    /// the packet stack), their hits gathered into lanes.
    #[cold]
    #[inline(never)]
    fn packet_closest_by_lane<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        rays: &R,
        valid: u32,
    ) -> PacketHits<L> {
        let zero = L::splat(0.0).to_array();
        let (mut t, mut u, mut v) = (zero, zero, zero);
        let mut prim = prim_lanes::<L>(u32::MAX).to_array();
        let mut hit = 0;
        for_each_bit(valid, |i| {
            let q = lane_query(rays, i);
            if let Some(h) = self.closest_from(&q, self.root, q.tmax) {
                (t.as_mut()[i], u.as_mut()[i], v.as_mut()[i]) = (h.t, h.u, h.v);
                prim.as_mut()[i] = f32::from_bits(h.prim);
                hit |= 1 << i;
            }
        });
        PacketHits {
            t: L::from_array(t),
            u: L::from_array(u),
            v: L::from_array(v),
            prim: L::from_array(prim),
            hit,
        }
    }

    /// `shared`: every lane of `mask` starts at `p.first_origin()`.
    fn packet_closest_group<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        p: &PacketRays<'_, L>,
        rays: &R,
        mask: u32,
        shared: bool,
    ) -> PacketHits<L> {
        let mut tmax = p.tmax();
        let mut hit = 0u32;
        let mut tu = L::splat(0.0);
        let mut tv = L::splat(0.0);
        let mut tprim = prim_lanes::<L>(u32::MAX);
        let mut stack: LaneStack<L, PACKET_STACK> = LaneStack::new();
        let mut cur = self.root;
        let mut cur_enter = p.tmin();
        let bounds = PacketBounds::<<Width<N> as NodeWidth>::L>::new(
            p,
            mask,
            tmax,
            shared,
            self.nodes.len() >= PACKET_BOUNDS_MIN_NODES,
        );
        loop {
            // Scaled once per step: entries are compared with it (see `Aabb::intersect`).
            let tcull = tmax * L::splat(ROBUST_FAR_SCALE);
            let active = mask & cur_enter.le(tcull).bitmask();
            if active == 0 {
                // culled: every lane has a closer hit than this subtree's entry
            } else if active.count_ones() < self.packet_min_active[0] {
                // Too few rays left to share the work: finish the subtree ray by ray.
                let tm = tmax.to_array();
                let mut m = active;
                let mut new_t = tmax.to_array();
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    let q = &lane_query(rays, i);
                    if let Some(h) = self.closest_from(q, cur, tm.as_ref()[i]) {
                        new_t.as_mut()[i] = h.t;
                        hit |= 1 << i;
                        let sel = L::mask_from_bits(1 << i);
                        tu = L::select(sel, L::splat(h.u), tu);
                        tv = L::select(sel, L::splat(h.v), tv);
                        tprim = L::select(sel, prim_lanes(h.prim), tprim);
                    }
                    m &= m - 1;
                }
                tmax = L::from_array(new_t);
            } else if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (planes, children) = (node.planes(), node.children());
                // Written for the children entered, read for those only: not
                // zero-filled (512 bytes per 8-wide node visit with 16 lanes).
                let mut enters = [const { std::mem::MaybeUninit::<L>::uninit() }; N];
                // Tried, no win (issue 12, pk23): `order` declared once per group instead
                // (entries past `n` are never read), so it is not zero-filled at every
                // node visit (sixteen stores for an 8-wide node, ~1.5 % of this
                // function's samples in `perf annotate`). `stream_profile bunny.obj
                // bvh8-packet primary 9`, 8 interleaved rounds, load 3.3-3.4, Mrays per
                // CPU-second: 44.00/46.68/47.57 before, 33.44/45.98/46.55 after.
                let mut order = [(0usize, 0f32); N];
                let mut n = 0;
                let rep = active.trailing_zeros() as usize;
                // Tried, no win (issue 12, pk23): with a shared origin (camera packets),
                // children chosen by the whole-packet test alone, as Embree's coherent
                // path descends by its frustum: no per-lane test of the candidates, each
                // child pushed with its interval entry bound in every lane (no later than
                // any lane's entry, so the pop's per-lane cull stays exact) and ordered
                // by it; together with the far end shrink noted at `PacketBounds::new`.
                // Same checksums, bvhn / simd_equivalence / accel_equivalence tests
                // passed. `examples/stream_profile MESH bvh8-packet primary 9`, 1 thread,
                // AVX-512, interleaved, Mrays per CPU-second, min/median/max of the
                // rounds' medians: bunny, 10 rounds at load 3.8-8, 44.25/45.53/50.77
                // before, 26.19/43.96/55.31 after; 8 rounds at load 6.7-6.9, three ways,
                // 33.54/41.90/46.92 before, 32.56/42.06/48.04 with it, 31.55/41.20/43.24
                // with the shrink alone; 10^6 (`/tmp/m1e6.obj`), 4 rounds at load
                // 5.1-5.8, 16.95/20.26/23.54 before, 14.73/18.44/19.04 with it,
                // 18.96/19.59/20.71 with the shrink alone (likely reason at 10^6: the
                // interval test passes more small deep boxes no lane enters, and each
                // costs a node's lines). `bench --modes bvh4-packet,bvh8-packet`, 6
                // rounds, load 5-7: bvh8 primary 30.23/32.58/45.82 -> 31.59/32.67/33.65.
                // On a quiet host (load 2.4-2.8, same command, three ways): bunny, 6
                // rounds, 35.05/44.34/46.98 before, 32.96/43.84/53.94 with it,
                // 38.19/42.19/49.86 with the shrink alone; 10^6, 5 rounds,
                // 19.68/21.61/24.11 before, 17.32/19.73/20.74 with it (-9 %),
                // 19.03/20.29/20.99 with the shrink alone (-6 %). The change is kept as
                // a patch in the pk23 report, not in the tree.
                // Tried, no win (issue 12, pkt17): with a shared origin, the node's six
                // near/far planes moved to it once per node with N-lane subtractions
                // (shared by the whole-packet test, which computes those differences
                // anyway) and broadcast from a stack array into each child's test,
                // instead of one scalar subtraction per plane and child. CPU time of 20
                // primary passes (`perf stat -e task-clock examples/stream_profile
                // bunny.obj bvh8-packet primary 21`, minus the same with 1; AVX-512, load
                // 11-13, three interleaved rounds): 549/544/552 ms before, 557/564/555
                // after (+1.5 %), same checksums.
                let mut cand = bounds.candidates(&planes, children);
                while cand != 0 {
                    let c = cand.trailing_zeros() as usize;
                    cand &= cand - 1;
                    let (enter, bits) = p.child_test(&planes, c, tcull);
                    if bits & active != 0 {
                        enters[c].write(enter);
                        // insertion sort, far to near, by the representative lane's entry
                        let key = enter.to_array().as_ref()[rep];
                        insert_far_to_near(&mut order, &mut n, c, key);
                    }
                }
                if n > 0 {
                    // Tried, slower (issue 12, pk17): every candidate of the whole-packet
                    // test prefetched before the per-lane tests instead (nodes whole,
                    // leaves up to four groups, every line), so the nearest child's
                    // lines are on their way too. 10^6 primary (`stream_profile
                    // /tmp/m1e6.obj bvh8-packet+pf primary 7`, AVX-512, 1 thread, load
                    // 6-7, Mrays per CPU-second, three interleaved rounds): 13.29 / 13.36
                    // / 13.67 against this prefetch's 13.45 / 15.31 / 16.33.
                    if self.prefetch.packet && n > 1 {
                        for &(c, _) in &order[..n] {
                            self.prefetch_child(children[c]);
                        }
                    }
                    // SAFETY: `order[..n]` lists the children whose `enters` were written.
                    for &(c, _) in &order[..n - 1] {
                        stack.push(children[c], unsafe { enters[c].assume_init() });
                    }
                    let c = order[n - 1].0;
                    cur = children[c];
                    cur_enter = unsafe { enters[c].assume_init() };
                    continue;
                }
            } else if let Leaves::Scalar { prims, ids } = &self.leaves {
                for k in leaf_range(cur) {
                    let (t, u, v, bits) = prims.intersect_lanes(k, &p.lanes(), tmax, active, rays);
                    if bits != 0 {
                        let sel = L::mask_from_bits(bits);
                        tmax = L::select(sel, t, tmax);
                        tu = L::select(sel, u, tu);
                        tv = L::select(sel, v, tv);
                        hit |= bits;
                        tprim = L::select(sel, prim_lanes(ids[k]), tprim);
                    }
                }
            } else if let Leaves::Triangles(groups) = &self.leaves {
                for g in &groups[leaf_range(cur)] {
                    // Tried, slower (issue 12, pkt17): with a shared origin, the group's
                    // corners moved to it once per group with four-lane subtractions
                    // (nine, into a stack array, where some triangle is a candidate) and
                    // broadcast into each triangle's packet test, instead of nine scalar
                    // subtractions per triangle; with the node change above, the same
                    // measurement gave 629/631/622 ms against 549/544/552 (+14 %; the
                    // node change alone +1.5 %), same checksums.
                    let cand = bounds.triangle_candidates(g);
                    for lane in 0..4 {
                        if g.ids[lane] == u32::MAX || cand >> lane & 1 == 0 {
                            continue;
                        }
                        let (t, u, v, bits, edge) =
                            triangle_packet(p.o(), p.tmin(), &p.shear, g, lane, tmax, active);
                        let mut bits = bits;
                        let (mut t, mut u, mut v) = (t, u, v);
                        if edge != 0 {
                            // exactly-zero edge functions: the scalar test with its f64 fallback
                            let (mut ta, mut ua, mut va) =
                                (t.to_array(), u.to_array(), v.to_array());
                            let tm = tmax.to_array();
                            edge_lanes_scalar(
                                rays,
                                &g.corners(lane),
                                edge,
                                |i, _| tm.as_ref()[i],
                                |i, h| {
                                    ta.as_mut()[i] = h.t;
                                    ua.as_mut()[i] = h.u;
                                    va.as_mut()[i] = h.v;
                                    bits |= 1 << i;
                                },
                            );
                            (t, u, v) = (L::from_array(ta), L::from_array(ua), L::from_array(va));
                        }
                        if bits != 0 {
                            let sel = L::mask_from_bits(bits);
                            tmax = L::select(sel, t, tmax);
                            tu = L::select(sel, u, tu);
                            tv = L::select(sel, v, tv);
                            hit |= bits;
                            tprim = L::select(sel, prim_lanes(g.ids[lane]), tprim);
                        }
                    }
                }
            }
            match stack.pop() {
                Some((r, e)) => {
                    cur = r;
                    cur_enter = e;
                }
                None => break,
            }
        }
        PacketHits {
            t: tmax,
            u: tu,
            v: tv,
            prim: tprim,
            hit,
        }
    }

    pub(super) fn packet_any<L: Lanes, R: LaneRays + ?Sized>(&self, rays: &R, out: &mut [bool]) {
        let occluded = self.packet_any_bits::<L, R>(rays);
        for (i, o) in out[..rays.lane_count()].iter_mut().enumerate() {
            *o = occluded >> i & 1 == 1;
        }
    }

    /// Bits of the lanes of `rays` (exactly `L::WIDTH`) that hit something within
    /// their interval.
    #[inline(always)]
    fn packet_any_bits<L: Lanes, R: LaneRays + ?Sized>(&self, rays: &R) -> u32 {
        let setup = PacketSetup::<L>::new(rays);
        let mut occluded = 0;
        if !setup.coherent() || self.stack_need >= PACKET_STACK {
            for_each_bit(setup.valid, |i| {
                occluded |= u32::from(self.any_from(&lane_query(rays, i), self.root)) << i
            });
            return occluded;
        }
        for g in 0..setup.groups {
            let p = setup.group(g);
            let mask = setup.group_mask[g];
            occluded |= self.packet_any_group(&p, rays, mask, setup.shared_origin);
        }
        occluded
    }

    /// Bits of the lanes in `mask` that hit something within their interval (`shared`
    /// as in `packet_closest_group`).
    fn packet_any_group<L: Lanes, R: LaneRays + ?Sized>(
        &self,
        p: &PacketRays<'_, L>,
        rays: &R,
        mask: u32,
        shared: bool,
    ) -> u32 {
        let mut occluded = 0u32;
        let mut stack: LaneStack<L, PACKET_STACK> = LaneStack::new();
        let mut cur = self.root;
        let mut cur_enter = p.tmin();
        let tcull = p.tmax() * L::splat(ROBUST_FAR_SCALE);
        let bounds = PacketBounds::<<Width<N> as NodeWidth>::L>::new(
            p,
            mask,
            p.tmax(),
            shared,
            self.nodes.len() >= PACKET_BOUNDS_MIN_NODES,
        );
        loop {
            let active = mask & !occluded & cur_enter.le(tcull).bitmask();
            if active == 0 {
            } else if active.count_ones() < self.packet_min_active[1] {
                let mut m = active;
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    let q = &lane_query(rays, i);
                    if self.any_from(q, cur) {
                        occluded |= 1 << i;
                    }
                    m &= m - 1;
                }
            } else if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (planes, children) = (node.planes(), node.children());
                let mut first = None;
                let mut pushed = false;
                let mut cand = bounds.candidates(&planes, children);
                while cand != 0 {
                    let c = cand.trailing_zeros() as usize;
                    cand &= cand - 1;
                    let (enter, bits) = p.child_test(&planes, c, tcull);
                    if bits & active != 0 {
                        match first {
                            None => first = Some((children[c], enter)),
                            Some(_) => {
                                if self.prefetch.packet {
                                    self.prefetch_child(children[c]);
                                    pushed = true;
                                }
                                stack.push(children[c], enter);
                            }
                        }
                    }
                }
                if pushed && let Some((r, _)) = first {
                    self.prefetch_child(r);
                }
                if let Some((r, e)) = first {
                    cur = r;
                    cur_enter = e;
                    continue;
                }
            } else if let Leaves::Scalar { prims, .. } = &self.leaves {
                for k in leaf_range(cur) {
                    let live = active & !occluded;
                    occluded |= prims.intersect_lanes(k, &p.lanes(), p.tmax(), live, rays).3;
                    if active & !occluded == 0 {
                        break;
                    }
                }
            } else if let Leaves::Triangles(groups) = &self.leaves {
                'groups: for g in &groups[leaf_range(cur)] {
                    let cand = bounds.triangle_candidates(g);
                    for lane in 0..4 {
                        if g.ids[lane] == u32::MAX || cand >> lane & 1 == 0 {
                            continue;
                        }
                        let live = active & !occluded;
                        let (_, _, _, bits, edge) =
                            triangle_packet(p.o(), p.tmin(), &p.shear, g, lane, p.tmax(), live);
                        occluded |= bits;
                        if edge != 0 {
                            edge_lanes_scalar(
                                rays,
                                &g.corners(lane),
                                edge,
                                |_, q| q.tmax,
                                |i, _| occluded |= 1 << i,
                            );
                        }
                        if active & !occluded == 0 {
                            break 'groups;
                        }
                    }
                }
            }
            if mask & !occluded == 0 {
                return occluded;
            }
            match stack.pop() {
                Some((r, e)) => {
                    cur = r;
                    cur_enter = e;
                }
                None => return occluded,
            }
        }
    }
}

/// The packet triangle test's fallback, shared by the closest-hit and occlusion
/// kernels: each lane of `edge` (an edge function exactly zero, which the lane test
/// cannot decide) is retested with the scalar watertight test and its f64 fallback,
/// within `(tmin, tmax(i, query))`; `hit(i, h)` is called for each lane that hits.
#[inline(always)]
fn edge_lanes_scalar<R: LaneRays + ?Sized>(
    rays: &R,
    corners: &[Vec3; 3],
    edge: u32,
    tmax: impl Fn(usize, &RayQuery) -> f32,
    mut hit: impl FnMut(usize, PrimHit),
) {
    for_each_bit(edge, |i| {
        let q = &lane_query(rays, i);
        if let Some(h) = intersect_triangle(q, corners[0], corners[1], corners[2], tmax(i, q)) {
            hit(i, h);
        }
    });
}

/// Lanes `off..off + 8` of a [`RayPacket`] as an 8-ray packet (a 4x2 half of a 4x4
/// block): the packet kernels at the native width of AVX2.
struct HalfPacket<'a> {
    p: &'a RayPacket,
    off: usize,
}

impl LaneRays for HalfPacket<'_> {
    #[inline(always)]
    fn lane_count(&self) -> usize {
        self.p.len.saturating_sub(self.off).min(8)
    }
    #[inline(always)]
    fn load_lanes<L: Lanes>(&self) -> [L; 8] {
        let o = self.off;
        [
            L::load(&self.p.origin[0][o..]),
            L::load(&self.p.origin[1][o..]),
            L::load(&self.p.origin[2][o..]),
            L::load(&self.p.dir[0][o..]),
            L::load(&self.p.dir[1][o..]),
            L::load(&self.p.dir[2][o..]),
            L::load(&self.p.tmin[o..]),
            L::load(&self.p.tmax[o..]),
        ]
    }
    #[inline(always)]
    fn lane_origin(&self, i: usize) -> [f32; 3] {
        let i = self.off + i;
        [
            self.p.origin[0][i],
            self.p.origin[1][i],
            self.p.origin[2][i],
        ]
    }
    #[inline(always)]
    fn lane_query(&self, i: usize) -> Option<RayQuery> {
        RayQuery::new(&self.p.ray(self.off + i))
    }
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    /// Closest hits of a packet traced as two 8-ray halves (`F8` lanes).
    pub fn closest_hit_packet8(&self, packet: &RayPacket, out: &mut [Option<Hit>]) {
        for off in [0, 8] {
            if packet.len > off {
                self.packet_closest::<F8, _>(&HalfPacket { p: packet, off }, &mut out[off..]);
            }
        }
    }

    /// Occlusion of a packet traced as two 8-ray halves (`F8` lanes).
    pub fn any_hit_packet8(&self, packet: &RayPacket, out: &mut [bool]) {
        for off in [0, 8] {
            if packet.len > off {
                self.packet_any::<F8, _>(&HalfPacket { p: packet, off }, &mut out[off..]);
            }
        }
    }

    /// Closest hits of `rays` in packets of eight (`F8` lanes).
    pub fn closest_hit_batch8(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        for (r, o) in rays.chunks(8).zip(out.chunks_mut(8)) {
            self.packet_closest::<F8, _>(r, o);
        }
    }

    /// Occlusion of `rays` in packets of eight (`F8` lanes).
    pub fn any_hit_batch8(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.chunks(8).zip(out.chunks_mut(8)) {
            self.packet_any::<F8, _>(r, o);
        }
    }

    /// Closest hits of a packet as lanes, the form of Embree's `RTCRayHit16`: lane `k`'s
    /// distance and primitive in `t[k]` and `prim[k]`, NaN and `u32::MAX` where it has
    /// none (lanes past `packet.len` and invalid rays included). The same answers as
    /// [`closest_hit_packet`](crate::accel::Accel::closest_hit_packet), without its
    /// twenty-byte `Option<Hit>` per lane, which a caller that stores lanes reads back
    /// with a branch per lane (issue 12, pk21: building those answers was 2.9 % of a
    /// bunny primary pass and reading them back in the bench harness 4 %, `perf record`
    /// of `examples/stream_profile bunny.obj bvh8-packet primary 60`).
    pub fn closest_hit_packet_lanes(
        &self,
        packet: &RayPacket,
        t: &mut [f32; PACKET_WIDTH],
        prim: &mut [u32; PACKET_WIDTH],
    ) {
        let h = self.packet_closest_lanes::<Packet, _>(packet);
        let sel = Packet::mask_from_bits(h.hit);
        *t = Packet::select(sel, h.t, Packet::splat(f32::NAN)).to_array();
        *prim = Packet::select(sel, h.prim, prim_lanes(u32::MAX))
            .to_array()
            .map(f32::to_bits);
    }

    /// Occlusion of a packet as bits: bit `k` set where lane `k` hits something
    /// within its interval (the answers of
    /// [`any_hit_packet`](crate::accel::Accel::any_hit_packet)).
    pub fn any_hit_packet_bits(&self, packet: &RayPacket) -> u32 {
        self.packet_any_bits::<Packet, _>(packet)
    }
}

#[cfg(test)]
mod tests {
    use crate::accel::bvhn::node::{NodeWidth, Width};
    use crate::accel::bvhn::tree::{Bvh, Bvh4, Bvh8};
    use crate::accel::{Accel, Triangles};
    use crate::geometry::{Ray, RayPacket};
    use glam::Vec3;

    /// Deterministic floats in [0, 1] from the tests' shared xorshift64.
    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut next = crate::test_rng::xorshift64(seed);
        move || (next() >> 40) as f32 / (1u32 << 24) as f32
    }

    /// Checks one packet of `rays` in `bvh` (see the test); returns (hits, occluded).
    fn check<const N: usize>(bvh: &Bvh<Triangles, N>, rays: &[Ray]) -> (u32, u32)
    where
        Width<N>: NodeWidth,
    {
        let packet = RayPacket::from_rays(rays);
        let len = rays.len();
        let (mut want, mut want_occ) = ([None; 16], [false; 16]);
        bvh.closest_hit_packet(&packet, &mut want[..len]);
        bvh.any_hit_packet(&packet, &mut want_occ[..len]);
        let (mut t, mut prim) = ([0.0; 16], [0; 16]);
        bvh.closest_hit_packet_lanes(&packet, &mut t, &mut prim);
        let bits = bvh.any_hit_packet_bits(&packet);
        let (mut hits, mut occluded) = (0, 0);
        for k in 0..16 {
            let single = rays.get(k).and_then(|r| bvh.closest_hit(r));
            assert_eq!(want[k], single, "lane {k}");
            match single {
                Some(h) => {
                    hits += 1;
                    assert_eq!(
                        (t[k].to_bits(), prim[k]),
                        (h.t.to_bits(), h.prim),
                        "lane {k}"
                    );
                }
                None => assert!(t[k].is_nan() && prim[k] == u32::MAX, "lane {k}"),
            }
            let occ = rays.get(k).is_some_and(|r| bvh.any_hit(r));
            assert_eq!(want_occ[k], occ, "lane {k}");
            assert_eq!(bits >> k & 1 == 1, occ, "lane {k}");
            occluded += u32::from(occ);
        }
        (hits, occluded)
    }

    /// The answers in lanes (`closest_hit_packet_lanes`, `any_hit_packet_bits`) are
    /// the `Option<Hit>` and `bool` answers of the same packets, lane for lane and bit
    /// for bit, and those are the single-ray kernel's: coherent packets with a shared
    /// origin and with scattered ones, incoherent packets (traced ray by ray), short
    /// packets, invalid rays and intervals that end early, over a triangle soup, in
    /// both tree widths. Lanes past the packet's length answer a miss.
    #[test]
    fn packet_answers_in_lanes_are_the_packet_answers() {
        let mut r = rng(0x1234_5678_9abc_def1);
        // A closed tessellated mesh around the origin, about unit size.
        let tris = crate::bench::BenchMesh::procedural(2000).triangles;
        let (b4, b8) = (Bvh4::build(tris.clone()), Bvh8::build(tris));
        let (mut hits, mut occluded, mut lanes) = (0, 0, 0);
        for trial in 0..400 {
            let len = [16, 16, 16, 11, 1][trial % 5];
            let eye = Vec3::new(0.0, 0.0, -3.0) + Vec3::new(r(), r(), r()) * 0.5;
            let rays: Vec<Ray> = (0..len)
                .map(|k| {
                    let o = match trial % 3 {
                        0 => eye,
                        _ => eye + Vec3::new(r(), r(), r()) * 0.2,
                    };
                    let d = if trial % 7 == 3 {
                        Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5)
                    } else {
                        Vec3::new(r() * 0.8 - 0.4, r() * 0.8 - 0.4, 1.0)
                    };
                    match (trial + k) % 13 {
                        0 => Ray::new(o, Vec3::ZERO),
                        1 => Ray::new(Vec3::splat(f32::NAN), d),
                        2 | 3 => Ray::segment(o, d, 0.0, 1.5 + r() * 2.0),
                        _ => Ray::new(o, d),
                    }
                })
                .collect();
            for (h, o) in [check(&b4, &rays), check(&b8, &rays)] {
                hits += h;
                occluded += o;
                lanes += len as u32;
            }
        }
        assert!(
            hits > lanes / 10 && occluded > lanes / 10 && hits < lanes - lanes / 10,
            "too few hits or misses: {hits} hits, {occluded} occluded of {lanes} rays"
        );
    }
}
