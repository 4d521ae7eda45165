//! Single-ray traversal: closest hit, any hit and the filtered query, one N-wide slab
//! test per node.
//!
//! Against Embree 3.13.5's one-ray BVH8 kernel on AVX2 (`bvh8-single` vs `rtcIntersect1`
//! diffuse 0.81x in README's run; `perf annotate` of `closest_from`, bunny, 2026-11-24):
//! - Node test: ours is 6 plane loads, 6 `vsubps`, 6 `vmulps`, 3 `vmaxps` and 3
//!   `vminps` (with `tmin`, `tmax`), `vcmpleps`, `vmovmskps`: 26 instructions, the
//!   reciprocals read from the stack (the kernel needs more than AVX2's 16 `ymm`
//!   registers). Embree's default (non-robust, what its harness runs) is one FMA per
//!   plane, `lower * rdir - org * rdir`, the loads folded: about 14. Embree's robust
//!   mode does what we do (subtract, multiply, far planes scaled by `1 + 2 gamma(3)`).
//!   Built since (`simd/slab_fma.rs`, issue 12): one FMA per plane against per-ray
//!   constants rounded in the safe direction (`rn`/`rf`: `1/d` toward/away from zero,
//!   `on`/`of`: `o * r` up/down), conservative for `tmin >= 0` with no scale at all (the
//!   proof is in that file); rays with `tmin < 0` and builds without FMA keep Ize's test
//!   (`NodeRay`). `perf annotate` (bvh8, bunny): the plane loads fold into the six
//!   `vfmadd132ps`, but the constants still live on the stack (each FMA reads one
//!   operand from there): the inlined leaf test needs the registers. The `+call` bench
//!   modes call the leaf out of line so the node loop may keep them; not measured yet.
//!   Measured (bunny, 1 thread, load 7-8, `cpu` 0.5, one binary, `+sub` = Ize's test (now the default; the FMA test is `+fma`),
//!   two interleaved rounds, medians Mrays/s): a first setup that branched on each
//!   rounding direction cost 33 % of `bvh8-single` (perf) and ran primary 2.46/2.37
//!   against 4.38/4.88; with the branch-free four-lane setup (`fma_axes`) `bvh8-single`
//!   primary 4.21/4.06 vs 3.06/4.29, shadow 1.91/1.91 vs 1.85/2.11, diffuse 1.42/1.46 vs
//!   1.29/1.39; `bvh8-stream` primary 4.72/5.72 vs 5.49/6.84, shadow 1.94/3.07 vs
//!   2.59/2.66, diffuse 1.43/1.93 vs 1.53/1.55: within the noise of this machine except
//!   single-ray diffuse (+5-10 %, both rounds).
//! - Child order: the same cases as Embree's `BVHNNodeTraverser1Hit` (one child: no
//!   stack; two: one compare; more: push and sort). The stack keeps its length in
//!   memory and bounds-checks each push (`cmp`/`ja`), Embree's a raw pointer; hot spots
//!   are elsewhere (the branch on the child mask and the first plane load, 7 % each).
//! - Leaf: `triangle4_closest` runs about 85 vector instructions before its all-miss
//!   exit (corners translated and sheared, three edge functions, their error bound,
//!   signs); Embree's Moeller-Trumbore on `Triangle4` (precomputed `v0, e1, e2, Ng`)
//!   about 30. Precomputed edges do not serve the watertight test (Woop et al.,
//!   JCGT 2013): it translates each corner to the ray origin before the shear.

use super::node::{NodeWidth, WideNode, Width, is_leaf, leaf_range};
use super::stack::{SINGLE_STACK, Stack};
use super::tree::{Bvh, Leaves};
use crate::accel::Primitives;
use crate::accel::filter::{FilterSink, triangle_candidates};
use crate::geometry::{Hit, ROBUST_FAR_SCALE, Ray, RayQuery};
use crate::simd::Lanes;
use crate::simd::kernels::{triangle4_any, triangle4_closest};
use crate::simd::slab_fma::{FmaRay, FusedLanes, t_slack};

/// A ray prepared for N-wide node tests: splatted origin and reciprocal direction, and
/// the plane indices its direction signs select. Ize's subtract-multiply test: rays with
/// `tmin < 0` and builds without FMA; everything else takes [`FmaRay`].
struct NodeRay<L: Lanes> {
    o: [L; 3],
    inv: [L; 3],
    /// `inv * (1 + 2 gamma(3))`: Ize's conservative far-plane scale folded into the
    /// reciprocal once per ray instead of once per node.
    inv_far: [L; 3],
    near: [usize; 3],
    far: [usize; 3],
    tmin: L,
}

impl<L: Lanes> NodeRay<L> {
    #[inline(always)]
    fn new(q: &RayQuery) -> Self {
        let near = [0, 1, 2].map(|a| {
            if q.inv_dir[a].is_sign_negative() {
                a + 3
            } else {
                a
            }
        });
        NodeRay {
            o: [0, 1, 2].map(|a| L::splat(q.origin[a])),
            inv: [0, 1, 2].map(|a| L::splat(q.inv_dir[a])),
            inv_far: [0, 1, 2].map(|a| L::splat(q.inv_dir[a] * ROBUST_FAR_SCALE)),
            near,
            far: near.map(|p| if p >= 3 { p - 3 } else { p + 3 }),
            tmin: L::splat(q.tmin),
        }
    }
}

/// The node test a single-ray traversal runs: entry distances and the bits of the
/// children entered within `[tmin, bound]`, and the bound a popped entry distance is
/// compared with.
pub(super) trait SlabTest<L: Lanes> {
    /// The `bound` the node tests take for a query interval ending at `tmax`.
    fn bound(&self, tmax: f32) -> f32;
    fn test<const N: usize>(&self, p: &[[f32; N]; 6], bound: f32) -> (L, u32);
    /// Whether a child pushed with entry distance `d` can still hold a hit before the
    /// interval's end (`bound` as [`bound`](Self::bound) gives it).
    fn may_enter(d: f32, bound: f32) -> bool;
}

impl<L: Lanes> SlabTest<L> for NodeRay<L> {
    /// Ize's far-plane scale applied to `tmax`: `tmax * (1 + 2 gamma(3))`, once per new
    /// interval end rather than in every node test and every pop.
    #[inline(always)]
    fn bound(&self, tmax: f32) -> f32 {
        tmax * ROBUST_FAR_SCALE
    }
    /// The same arithmetic as `Aabb::intersect` (`bound` is its scaled `tmax`).
    #[inline(always)]
    fn test<const N: usize>(&self, p: &[[f32; N]; 6], bound: f32) -> (L, u32) {
        let d = |plane: usize, a: usize| (L::load(&p[plane]) - self.o[a]) * self.inv[a];
        let f = |plane: usize, a: usize| (L::load(&p[plane]) - self.o[a]) * self.inv_far[a];
        let enter =
            d(self.near[0], 0).maxps(d(self.near[1], 1).maxps(d(self.near[2], 2).maxps(self.tmin)));
        let exit = f(self.far[0], 0)
            .minps(f(self.far[1], 1).minps(f(self.far[2], 2).minps(L::splat(bound))));
        (enter, enter.le(exit).bitmask())
    }
    #[inline(always)]
    fn may_enter(d: f32, bound: f32) -> bool {
        d <= bound
    }
}

impl<L: FusedLanes> SlabTest<L> for FmaRay<L> {
    /// `tmax` plus the ray's slack, rounded up (`slab_fma`: the triangle test's error
    /// in `t`).
    #[inline(always)]
    fn bound(&self, tmax: f32) -> f32 {
        FmaRay::bound(self, tmax)
    }
    #[inline(always)]
    fn test<const N: usize>(&self, p: &[[f32; N]; 6], bound: f32) -> (L, u32) {
        FmaRay::test(self, p, bound)
    }
    /// An entry distance is at most the exact one rounded to nearest (`slab_fma`), and
    /// `bound` is a float: no scale.
    #[inline(always)]
    fn may_enter(d: f32, bound: f32) -> bool {
        d <= bound
    }
}

/// The FMA test's constants for `q`, where it applies (see [`SlabTest`]), with the
/// slack of `simd::slab_fma::t_slack` against the root box `root` (`[min, max]`).
#[inline(always)]
pub(super) fn fma_ray<L: FusedLanes>(
    q: &RayQuery,
    on: bool,
    root: &[[f32; 3]; 2],
) -> Option<FmaRay<L>> {
    (on && q.tmin >= 0.0).then(|| {
        let kz = q.kz;
        FmaRay::with_reciprocal(
            q.origin.to_array(),
            q.dir.to_array(),
            q.inv_dir.to_array(),
            q.tmin,
            t_slack(root[0][kz], root[1][kz], q.origin[kz], q.sz),
        )
    })
}

/// Pushes the entered children (bits of `mask`) nearest-last and returns the nearest.
/// One child: no stack traffic; two: one comparison; more: all are pushed and the
/// pushed run is insertion-sorted in place, far to near, so no scratch array is filled.
#[inline(always)]
fn order_children<L: Lanes, const N: usize>(
    children: &[u32; N],
    enter: L,
    mask: u32,
    stack: &mut Stack<(u32, f32), SINGLE_STACK>,
) -> u32 {
    let i0 = mask.trailing_zeros() as usize;
    let rest = mask & (mask - 1);
    if rest == 0 {
        return children[i0];
    }
    let t = enter.to_array();
    let t = t.as_ref();
    let i1 = rest.trailing_zeros() as usize;
    let (a, b) = ((children[i0], t[i0]), (children[i1], t[i1]));
    let mut rest = rest & (rest - 1);
    if rest == 0 {
        let (near, far) = if b.1 < a.1 { (b, a) } else { (a, b) };
        stack.push(far);
        return near.0;
    }
    let base = stack.len;
    stack.push(a);
    stack.push(b);
    while rest != 0 {
        let i = rest.trailing_zeros() as usize;
        stack.push((children[i], t[i]));
        rest &= rest - 1;
    }
    stack.sort_top_far_to_near(base);
    stack.pop().expect("three or more entries were pushed").0
}

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    /// Closest hit of one ray in the subtree `start`, with interval `(q.tmin, tmax)`.
    #[inline]
    pub(super) fn closest_from(&self, q: &RayQuery, start: u32, tmax: f32) -> Option<Hit> {
        match fma_ray(q, self.fma_slab, &self.root_box) {
            Some(ray) if self.leaf_call => self.closest_with::<_, true>(&ray, q, start, tmax),
            Some(ray) => self.closest_with::<_, false>(&ray, q, start, tmax),
            None => self.closest_with::<_, false>(&NodeRay::new(q), q, start, tmax),
        }
    }

    /// Any hit of one ray in the subtree `start` within `(q.tmin, q.tmax)`.
    #[inline]
    pub(super) fn any_from(&self, q: &RayQuery, start: u32) -> bool {
        match fma_ray(q, self.fma_slab, &self.root_box) {
            Some(ray) if self.leaf_call => self.any_with::<_, true>(&ray, q, start),
            Some(ray) => self.any_with::<_, false>(&ray, q, start),
            None => self.any_with::<_, false>(&NodeRay::new(q), q, start),
        }
    }

    #[inline(always)]
    /// `CALL`: the leaf test is an out-of-line call (so the node loop may keep the
    /// ray's constants in registers), else inlined.
    pub(super) fn closest_with<R: SlabTest<<Width<N> as NodeWidth>::L>, const CALL: bool>(
        &self,
        ray: &R,
        q: &RayQuery,
        start: u32,
        mut tmax: f32,
    ) -> Option<Hit> {
        let mut best = None;
        let mut stack = Stack::new();
        let mut cur = start;
        let mut bound = ray.bound(tmax);
        loop {
            if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (enter, mask) = ray.test(&node.planes(), bound);
                if mask != 0 {
                    self.prefetch_entered(node.children(), mask, self.prefetch.single);
                    cur = order_children(node.children(), enter, mask, &mut stack);
                    continue;
                }
            } else if let Some(h) = if CALL {
                self.leaf_closest_call(q, cur, tmax)
            } else {
                self.leaf_closest(q, cur, tmax)
            } {
                tmax = h.t;
                bound = ray.bound(tmax);
                best = Some(h);
            }
            loop {
                let Some((r, d)) = stack.pop() else {
                    return best;
                };
                if R::may_enter(d, bound) {
                    cur = r;
                    break;
                }
            }
        }
    }

    #[inline(always)]
    pub(super) fn any_with<R: SlabTest<<Width<N> as NodeWidth>::L>, const CALL: bool>(
        &self,
        ray: &R,
        q: &RayQuery,
        start: u32,
    ) -> bool {
        let mut stack: Stack<u32, SINGLE_STACK> = Stack::new();
        let mut cur = start;
        let bound = ray.bound(q.tmax);
        loop {
            if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (_, mask) = ray.test(&node.planes(), bound);
                if mask != 0 {
                    let children = node.children();
                    self.prefetch_entered(children, mask, self.prefetch.single);
                    let mut m = mask;
                    cur = children[m.trailing_zeros() as usize];
                    m &= m - 1;
                    while m != 0 {
                        stack.push(children[m.trailing_zeros() as usize]);
                        m &= m - 1;
                    }
                    continue;
                }
            } else if if CALL {
                self.leaf_any_call(q, cur)
            } else {
                self.leaf_any(q, cur)
            } {
                return true;
            }
            match stack.pop() {
                Some(r) => cur = r,
                None => return false,
            }
        }
    }

    /// With `on`, prefetches the children of `mask` when there are two or more (a
    /// lone child is read at once, too soon for a prefetch to help).
    #[inline(always)]
    pub(super) fn prefetch_entered(&self, children: &[u32; N], mask: u32, on: bool) {
        if on && mask & (mask - 1) != 0 {
            let mut m = mask;
            while m != 0 {
                self.prefetch_child(children[m.trailing_zeros() as usize]);
                m &= m - 1;
            }
        }
    }

    #[inline(always)]
    pub(super) fn leaf_closest(&self, q: &RayQuery, r: u32, mut tmax: f32) -> Option<Hit> {
        let mut best = None;
        match &self.leaves {
            Leaves::Triangles(groups) => {
                for g in &groups[leaf_range(r)] {
                    if let Some((lane, h)) = triangle4_closest(q, g, tmax) {
                        tmax = h.t;
                        best = Some(Hit {
                            t: h.t,
                            prim: g.ids[lane],
                            u: h.u,
                            v: h.v,
                        });
                    }
                }
            }
            Leaves::Scalar { prims, ids } => {
                for k in leaf_range(r) {
                    if let Some(h) = prims.intersect(k, q, tmax) {
                        tmax = h.t;
                        best = Some(Hit {
                            t: h.t,
                            prim: ids[k],
                            u: h.u,
                            v: h.v,
                        });
                    }
                }
            }
        }
        best
    }

    /// [`leaf_closest`](Self::leaf_closest) as a call.
    #[inline(never)]
    fn leaf_closest_call(&self, q: &RayQuery, r: u32, tmax: f32) -> Option<Hit> {
        self.leaf_closest(q, r, tmax)
    }

    /// [`leaf_any`](Self::leaf_any) as a call.
    #[inline(never)]
    fn leaf_any_call(&self, q: &RayQuery, r: u32) -> bool {
        self.leaf_any(q, r)
    }

    #[inline(always)]
    pub(super) fn leaf_any(&self, q: &RayQuery, r: u32) -> bool {
        match &self.leaves {
            Leaves::Triangles(groups) => groups[leaf_range(r)]
                .iter()
                .any(|g| triangle4_any(q, g, q.tmax)),
            Leaves::Scalar { prims, .. } => {
                leaf_range(r).any(|k| prims.intersect(k, q, q.tmax).is_some())
            }
        }
    }

    /// The filtered query ([`super::filter`]): the single-ray traversal of
    /// `closest_from`, nearer children first, with the interval ended by the nearest
    /// accepted candidate only. Triangle groups are tested lane by lane with the scalar
    /// watertight test (the SIMD kernel is its bit-identical twin but reports only the
    /// nearest lane). Each primitive is in one leaf, so no deduplication is needed.
    pub(super) fn filtered_from(&self, q: &RayQuery, sink: &mut FilterSink) {
        // The node test `closest_from` takes, so that accepting everything visits the
        // same children in the same order and keeps the same hit on an exact tie (with
        // the FMA test in one and Ize's in the other, a tie between duplicated
        // triangles went to different ones: `queries::accepting_everything_is_the_
        // plain_query`).
        match fma_ray(q, self.fma_slab, &self.root_box) {
            Some(ray) => self.filtered_with(&ray, q, sink),
            None => self.filtered_with(&NodeRay::new(q), q, sink),
        }
    }

    fn filtered_with<R: SlabTest<<Width<N> as NodeWidth>::L>>(
        &self,
        ray: &R,
        q: &RayQuery,
        sink: &mut FilterSink,
    ) {
        let mut stack = Stack::new();
        let mut cur = self.root;
        loop {
            if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (enter, mask) = ray.test(&node.planes(), ray.bound(sink.tmax));
                if mask != 0 {
                    cur = order_children(node.children(), enter, mask, &mut stack);
                    continue;
                }
            } else if self.leaf_filtered(q, cur, sink) {
                return;
            }
            loop {
                let Some((r, d)) = stack.pop() else {
                    return;
                };
                if R::may_enter(d, ray.bound(sink.tmax)) {
                    cur = r;
                    break;
                }
            }
        }
    }

    /// Offers the candidates of leaf `r`; true when the traversal is finished.
    fn leaf_filtered(&self, q: &RayQuery, r: u32, sink: &mut FilterSink) -> bool {
        match &self.leaves {
            Leaves::Triangles(groups) => {
                for g in &groups[leaf_range(r)] {
                    for lane in (0..4).filter(|&l| g.ids[l] != u32::MAX) {
                        let corners = g.corners(lane);
                        if sink.test_with(g.ids[lane], |tmax, f| {
                            triangle_candidates(q, corners, tmax, f)
                        }) {
                            return true;
                        }
                    }
                }
            }
            Leaves::Scalar { prims, ids } => {
                for k in leaf_range(r) {
                    if sink.test(prims, k, ids[k], q) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Closest hit of one ray (the single-ray SIMD kernel).
    pub fn closest_single(&self, ray: &Ray) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        self.closest_from(&q, self.root, q.tmax)
    }

    /// Occlusion of one ray (the single-ray SIMD kernel).
    pub fn any_single(&self, ray: &Ray) -> bool {
        RayQuery::new(ray).is_some_and(|q| self.any_from(&q, self.root))
    }
}
