//! N-wide BVHs: the fast path. [`Bvh4`] (4-wide nodes, SSE-width slab tests) and
//! [`Bvh8`] (8-wide nodes, AVX-width slab tests) share one implementation, generic over
//! the node width.
//!
//! Built by collapsing the binned-SAH BVH2: each node takes a BVH2 node's two children
//! and repeatedly opens the child with the largest surface area until it has N (the
//! greedy SAH-aware collapse of Wald et al. 2008, "Getting Rid of Packets"). A node
//! stores its children's bounds as lane arrays, so one N-wide slab test covers all
//! children; leaves of a triangle mesh hold [`TriGroup4`]s, so one SIMD test covers four
//! triangles. Other primitive kinds keep scalar leaves.
//!
//! Traversals: single ray (`closest_single`, `any_single`), and coherent packets of
//! [`PACKET_WIDTH`] rays, given as a slice (the [`Accel`] batch entry points) or as a SoA
//! [`RayPacket`] (`closest_hit_packet`/`any_hit_packet`), both through the same kernels
//! (generic over [`LaneRays`]). A packet is split by direction octant and dominant axis
//! so that each part shares its slab planes and its watertight shear; each part first
//! tests a node's children against the interval bounds of all its rays
//! ([`PacketBounds`]), then runs the per-lane slab test only for children some lane may
//! enter; a part with few active rays left finishes a subtree ray by ray, as Embree's
//! hybrid traversal does.

use super::bvh2::{BuildNode, build_tree};
use super::filter::{FilterSink, HitFilter, QueryOptions, triangle_candidates};
use super::{Accel, AccelInfo, Bvh2BuildOptions, Primitives, Triangles};
use crate::geometry::{Aabb, Hit, LaneRays, ROBUST_FAR_SCALE, Ray, RayPacket, RayQuery};
use crate::simd::kernels::{
    PacketShear, RayLanes, TriGroup4, triangle_packet, triangle4_any, triangle4_closest,
};
use crate::simd::{F4, F8, Lanes, PACKET_WIDTH, Packet};
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

/// A node of an N-wide BVH: the children's bounds as lane arrays and packed child
/// references.
///
/// `planes[0..3]` are `min_x, min_y, min_z` and `planes[3..6]` are `max_x, max_y, max_z`,
/// each `[f32; N]` with one lane per child, so the near plane of axis `a` for a ray with
/// a negative direction component is `planes[a + 3]` and no per-ray shuffling is needed.
/// Unused child slots have empty bounds (+inf..-inf), which no ray can enter.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct BvhNode<const N: usize> {
    pub planes: [[f32; N]; 6],
    /// Child references: an interior node's index, or [`LEAF`] | count << 27 | first.
    pub children: [u32; N],
}

/// A 4-wide node: two cache lines.
pub type Bvh4Node = BvhNode<4>;
/// An 8-wide node: 224 bytes of bounds and references, padded to four cache lines.
pub type Bvh8Node = BvhNode<8>;

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 64);
const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);
const _: () = assert!(std::mem::align_of::<Bvh8Node>() == 64);

/// The node widths there are kernels for, and the lane type of their slab test.
pub trait NodeWidth {
    /// N lanes: one per child.
    type L: Lanes;
}

/// Marker for node width `N`.
pub struct Width<const N: usize>;

impl NodeWidth for Width<4> {
    type L = F4;
}

impl NodeWidth for Width<8> {
    type L = F8;
}

/// Leaf flag of a child reference. A leaf's `first` (27 bits) indexes triangle groups
/// (triangle meshes) or primitives (other kinds); `count` (4 bits) is how many.
pub const LEAF: u32 = 1 << 31;
const COUNT_SHIFT: u32 = 27;
const FIRST_MASK: u32 = (1 << COUNT_SHIFT) - 1;
/// An unused child slot: a leaf with nothing in it (and empty bounds).
pub const EMPTY_CHILD: u32 = LEAF;

#[inline(always)]
fn is_leaf(r: u32) -> bool {
    r & LEAF != 0
}

#[inline(always)]
fn leaf_range(r: u32) -> std::ops::Range<usize> {
    let first = (r & FIRST_MASK) as usize;
    let count = ((r & !LEAF) >> COUNT_SHIFT) as usize;
    first..first + count
}

/// Single-ray traversal stack capacity. A node pushes at most N - 1 entries per level it
/// descends and the BVH2 depth bound (`bvh2::STACK_SIZE`) bounds the levels, so
/// 7 x 128 entries cover an 8-wide tree of any shape (checked at build time).
const SINGLE_STACK: usize = 7 * super::bvh2::STACK_SIZE + 1;

/// Packet traversal stack capacity (an entry holds a lane vector of entry distances, so
/// this is kept smaller). A tree whose worst path needs more (a path through more than
/// 36 full 8-wide nodes) traces its packets ray by ray.
const PACKET_STACK: usize = 256;

/// A fixed-size traversal stack that is not zero-filled per ray (a 3 KB memset per ray
/// cost 17 % of single-ray time). Entries below `len` are always initialised.
struct Stack<T: Copy, const CAP: usize> {
    items: [std::mem::MaybeUninit<T>; CAP],
    len: usize,
}

impl<T: Copy, const CAP: usize> Stack<T, CAP> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            items: [const { std::mem::MaybeUninit::uninit() }; CAP],
            len: 0,
        }
    }

    #[inline(always)]
    fn push(&mut self, x: T) {
        self.items[self.len].write(x);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below the old `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

impl<const CAP: usize> Stack<(u32, f32), CAP> {
    /// Insertion-sorts the entries from `base` up by decreasing distance, so the nearest
    /// is popped first. Equal distances keep their push order.
    #[inline(always)]
    fn sort_top_far_to_near(&mut self, base: usize) {
        // SAFETY: every slot below `len` was written by `push`.
        let items = unsafe {
            std::slice::from_raw_parts_mut(self.items.as_mut_ptr().cast::<(u32, f32)>(), self.len)
        };
        let run = &mut items[base..];
        for i in 1..run.len() {
            let x = run[i];
            let mut j = i;
            while j > 0 && run[j - 1].1 < x.1 {
                run[j] = run[j - 1];
                j -= 1;
            }
            run[j] = x;
        }
    }
}

/// Rays a packet part keeps traversing together; with fewer active rays it finishes the
/// subtree ray by ray (measured: see README, "Packet threshold").
pub const PACKET_MIN_ACTIVE: u32 = 3;

/// What the leaves hold.
enum Leaves<P> {
    /// Triangle meshes: groups of four, SoA.
    Triangles(Vec<TriGroup4>),
    /// Anything else: the primitives in leaf order and their original indices.
    Scalar { prims: P, ids: Vec<u32> },
}

/// Trees with fewer nodes skip the whole-packet bounds: computing them costs about as
/// much as a few child tests, which a packet crossing a handful of nodes never wins
/// back (the 2-sphere, 2-triangle Whitted room traced its shadow queue 17 % slower
/// with them; the bunny's BVH4 has 8.9k nodes).
const PACKET_BOUNDS_MIN_NODES: usize = 32;

/// Levels of the collapse that hand their children's subtrees to separate threads (at
/// most N^2 tasks): the collapse was 13 % of a serial build (4 of 30 ms on the bunny).
const PARALLEL_COLLAPSE_LEVELS: usize = 2;

/// An N-wide BVH over one primitive set (N = 4 or 8: see [`NodeWidth`]).
pub struct Bvh<P: Primitives, const N: usize> {
    pub nodes: Vec<BvhNode<N>>,
    leaves: Leaves<P>,
    root: u32,
    info: AccelInfo,
    /// The most entries any traversal can have on its stack: the largest sum of
    /// (children - 1) along a root-to-leaf path.
    stack_need: usize,
}

/// The 4-wide BVH.
pub type Bvh4<P> = Bvh<P, 4>;
/// The 8-wide BVH.
pub type Bvh8<P> = Bvh<P, 8>;

/// Build parameters for 4-wide leaves. Triangle leaves are tested four at a time, so
/// the SAH counts them in blocks of four (a leaf of 1-4 triangles costs one test): on
/// the bunny this packs leaves (37k half-empty groups before) and builds 41 -> 30 ms,
/// with 4-7 % faster traversal. One group per leaf: on the bunny, leaves of up to two
/// groups were 3 % slower for single rays through the BVH8 (4.14 vs 4.28 Mrays/s
/// diffuse) and 7 % for its packets, and no faster for the BVH4. Scalar leaves
/// (spheres) keep per-primitive costs.
pub fn wide_build_options(simd_triangle_leaves: bool) -> Bvh2BuildOptions {
    Bvh2BuildOptions {
        max_leaf: 4,
        block_size: if simd_triangle_leaves { 4 } else { 1 },
        ..Bvh2BuildOptions::default()
    }
}

impl<P: Primitives, const N: usize> Bvh<P, N>
where
    Width<N>: NodeWidth,
{
    pub fn build(prims: P) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let triangles = prims.as_triangles();
        let (tree, ids) = build_tree(&prims, wide_build_options(triangles.is_some()));
        let mut c = Collapse::<N> {
            ids: &ids,
            triangles,
            nodes: Vec::with_capacity(n / 2 + 1),
            groups: Vec::new(),
        };
        let root = match &tree {
            None => EMPTY_CHILD,
            Some(t) => c.collapse(t, PARALLEL_COLLAPSE_LEVELS),
        };
        let Collapse { nodes, groups, .. } = c;
        let root_area = tree.as_ref().map_or(0.0, |t| t.bounds().area());
        let leaves = if triangles.is_some() {
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
        };
        let (leaf_count, depth, sah, stack_need) = bvh.shape(root_area);
        assert!(
            stack_need < SINGLE_STACK,
            "BVH{N} deeper than the BVH2 depth bound allows"
        );
        bvh.stack_need = stack_need;
        bvh.info = AccelInfo {
            name: if N == 4 { "bvh4" } else { "bvh8" },
            primitives: n,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            nodes: bvh.nodes.len(),
            leaves: leaf_count,
            max_depth: depth,
            memory_bytes: bvh.nodes.len() * std::mem::size_of::<BvhNode<N>>() + leaf_bytes,
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
                let kids = node.children.iter().filter(|&&c| c != EMPTY_CHILD).count();
                for (slot, &c) in node.children.iter().enumerate() {
                    if c != EMPTY_CHILD {
                        let area = node.child_bounds(slot).area();
                        stack.push((c, d + 1, area, pending + kids - 1));
                    }
                }
            }
        }
        (leaves, depth, cost, need)
    }

    /// Bytes per primitive of nodes and leaves.
    pub fn bytes_per_primitive(&self) -> f64 {
        self.info.memory_bytes as f64 / self.info.primitives.max(1) as f64
    }
}

struct Collapse<'a, const N: usize> {
    ids: &'a [u32],
    triangles: Option<&'a Triangles>,
    nodes: Vec<BvhNode<N>>,
    groups: Vec<TriGroup4>,
}

impl<const N: usize> Collapse<'_, N> {
    /// The node reference for a build subtree: its two children, then the child with
    /// the largest area opened until there are N. The top `parallel_levels` levels
    /// collapse their children's subtrees in parallel.
    fn collapse(&mut self, node: &BuildNode, parallel_levels: usize) -> u32 {
        let BuildNode::Interior { children, .. } = node else {
            let BuildNode::Leaf { start, count, .. } = node else {
                unreachable!()
            };
            return self.leaf(*start, *count);
        };
        // Up to N children in a fixed array (no allocation per node); opening a child
        // moves the last one into its slot, then appends the grandchildren.
        let mut kids: [&BuildNode; N] = [&children[1]; N];
        kids[0] = &children[0];
        let mut n = 2;
        while n < N {
            let open = (0..n)
                .filter(|&i| matches!(kids[i], BuildNode::Interior { .. }))
                .max_by(|&a, &b| kids[a].area().total_cmp(&kids[b].area()));
            let Some(pos) = open else { break };
            let BuildNode::Interior { children, .. } = kids[pos] else {
                unreachable!()
            };
            kids[pos] = kids[n - 1];
            kids[n - 1] = &children[0];
            kids[n] = &children[1];
            n += 1;
        }
        let kids = &kids[..n];
        let index = self.nodes.len();
        self.nodes.push(BvhNode {
            planes: [
                [f32::INFINITY; N],
                [f32::INFINITY; N],
                [f32::INFINITY; N],
                [f32::NEG_INFINITY; N],
                [f32::NEG_INFINITY; N],
                [f32::NEG_INFINITY; N],
            ],
            children: [EMPTY_CHILD; N],
        });
        let mut refs = [EMPTY_CHILD; N];
        if parallel_levels > 0 {
            // Each child's subtree into arrays of its own, appended in slot order: the
            // same layout the serial recursion gives.
            let (ids, triangles) = (self.ids, self.triangles);
            let parts: Vec<(Collapse<'_, N>, u32)> = kids
                .par_iter()
                .map(|k| {
                    let mut part = Collapse {
                        ids,
                        triangles,
                        nodes: Vec::new(),
                        groups: Vec::new(),
                    };
                    let r = part.collapse(k, parallel_levels - 1);
                    (part, r)
                })
                .collect();
            for (slot, (part, r)) in parts.into_iter().enumerate() {
                refs[slot] = self.append(part, r);
            }
        } else {
            for (slot, k) in kids.iter().enumerate() {
                refs[slot] = self.collapse(k, 0);
            }
        }
        let node = &mut self.nodes[index];
        for (slot, k) in kids.iter().enumerate() {
            let b = k.bounds();
            for a in 0..3 {
                node.planes[a][slot] = b.min[a];
                node.planes[a + 3][slot] = b.max[a];
            }
            node.children[slot] = refs[slot];
        }
        index as u32
    }

    /// Appends a subtree collapsed on its own, moving its node and group references
    /// past what is already here; returns its root's reference, moved likewise.
    fn append(&mut self, part: Collapse<'_, N>, root: u32) -> u32 {
        let node_base = self.nodes.len() as u32;
        let group_base = self.groups.len() as u32;
        // Scalar leaves index the permuted primitives directly and never move.
        let moves_leaves = self.triangles.is_some();
        let relocate = |r: u32| {
            if r == EMPTY_CHILD || (is_leaf(r) && !moves_leaves) {
                r
            } else if is_leaf(r) {
                let first = (r & FIRST_MASK) + group_base;
                assert!(first <= FIRST_MASK, "leaf exceeds the reference encoding");
                r & !FIRST_MASK | first
            } else {
                r + node_base
            }
        };
        self.nodes.extend(part.nodes.into_iter().map(|mut node| {
            node.children = node.children.map(relocate);
            node
        }));
        self.groups.extend(part.groups);
        relocate(root)
    }

    fn leaf(&mut self, first: usize, count: usize) -> u32 {
        let Some(tris) = self.triangles else {
            assert!(
                count < 16 && first <= FIRST_MASK as usize,
                "leaf exceeds the reference encoding"
            );
            return LEAF | (count as u32) << COUNT_SHIFT | first as u32;
        };
        let start = self.groups.len();
        for chunk in self.ids[first..first + count].chunks(4) {
            let mut g = TriGroup4::EMPTY;
            for (lane, &id) in chunk.iter().enumerate() {
                let k = id as usize;
                g.set(lane, id, [tris.v0[k], tris.v1[k], tris.v2[k]]);
            }
            self.groups.push(g);
        }
        let ngroups = self.groups.len() - start;
        assert!(
            ngroups < 16 && start <= FIRST_MASK as usize,
            "leaf exceeds the reference encoding"
        );
        LEAF | (ngroups as u32) << COUNT_SHIFT | start as u32
    }
}

/// A ray prepared for N-wide node tests: splatted origin and reciprocal direction, and
/// the plane indices its direction signs select.
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

    /// Slab test against a node's children: entry distances and the bits of the
    /// children entered within `[tmin, tmax]`. The same arithmetic as `Aabb::intersect`.
    #[inline(always)]
    fn test<const N: usize>(&self, node: &BvhNode<N>, tmax: f32) -> (L, u32) {
        let p = &node.planes;
        let d = |plane: usize, a: usize| (L::load(&p[plane]) - self.o[a]) * self.inv[a];
        let f = |plane: usize, a: usize| (L::load(&p[plane]) - self.o[a]) * self.inv_far[a];
        let enter =
            d(self.near[0], 0).maxps(d(self.near[1], 1).maxps(d(self.near[2], 2).maxps(self.tmin)));
        let exit = f(self.far[0], 0).minps(
            f(self.far[1], 1).minps(f(self.far[2], 2).minps(L::splat(tmax * ROBUST_FAR_SCALE))),
        );
        (enter, enter.le(exit).bitmask())
    }
}

/// Pushes the entered children (bits of `mask`) nearest-last and returns the nearest.
/// One child: no stack traffic; two: one comparison; more: all are pushed and the
/// pushed run is insertion-sorted in place, far to near, so no scratch array is filled.
#[inline(always)]
fn order_children<L: Lanes, const N: usize>(
    node: &BvhNode<N>,
    enter: L,
    mask: u32,
    stack: &mut Stack<(u32, f32), SINGLE_STACK>,
) -> u32 {
    let i0 = mask.trailing_zeros() as usize;
    let rest = mask & (mask - 1);
    if rest == 0 {
        return node.children[i0];
    }
    let t = enter.to_array();
    let t = t.as_ref();
    let i1 = rest.trailing_zeros() as usize;
    let (a, b) = ((node.children[i0], t[i0]), (node.children[i1], t[i1]));
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
        stack.push((node.children[i], t[i]));
        rest &= rest - 1;
    }
    stack.sort_top_far_to_near(base);
    stack.pop().expect("three or more entries were pushed").0
}

impl<P: Primitives, const N: usize> Bvh<P, N>
where
    Width<N>: NodeWidth,
{
    /// Closest hit of one ray in the subtree `start`, with interval `(q.tmin, tmax)`.
    #[inline]
    fn closest_from(&self, q: &RayQuery, start: u32, mut tmax: f32) -> Option<Hit> {
        let ray = NodeRay::<<Width<N> as NodeWidth>::L>::new(q);
        let mut best = None;
        let mut stack = Stack::new();
        let mut cur = start;
        loop {
            if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (enter, mask) = ray.test(node, tmax);
                if mask != 0 {
                    cur = order_children(node, enter, mask, &mut stack);
                    continue;
                }
            } else if let Some(h) = self.leaf_closest(q, cur, tmax) {
                tmax = h.t;
                best = Some(h);
            }
            loop {
                let Some((r, d)) = stack.pop() else {
                    return best;
                };
                if d <= tmax * ROBUST_FAR_SCALE {
                    cur = r;
                    break;
                }
            }
        }
    }

    /// Any hit of one ray in the subtree `start` within `(q.tmin, q.tmax)`.
    #[inline]
    fn any_from(&self, q: &RayQuery, start: u32) -> bool {
        let ray = NodeRay::<<Width<N> as NodeWidth>::L>::new(q);
        let mut stack: Stack<u32, SINGLE_STACK> = Stack::new();
        let mut cur = start;
        loop {
            if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (_, mask) = ray.test(node, q.tmax);
                if mask != 0 {
                    let mut m = mask;
                    cur = node.children[m.trailing_zeros() as usize];
                    m &= m - 1;
                    while m != 0 {
                        stack.push(node.children[m.trailing_zeros() as usize]);
                        m &= m - 1;
                    }
                    continue;
                }
            } else if self.leaf_any(q, cur) {
                return true;
            }
            match stack.pop() {
                Some(r) => cur = r,
                None => return false,
            }
        }
    }

    #[inline(always)]
    fn leaf_closest(&self, q: &RayQuery, r: u32, mut tmax: f32) -> Option<Hit> {
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

    #[inline(always)]
    fn leaf_any(&self, q: &RayQuery, r: u32) -> bool {
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
    fn filtered_from(&self, q: &RayQuery, sink: &mut FilterSink) {
        let ray = NodeRay::<<Width<N> as NodeWidth>::L>::new(q);
        let mut stack = Stack::new();
        let mut cur = self.root;
        loop {
            if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let (enter, mask) = ray.test(node, sink.tmax);
                if mask != 0 {
                    cur = order_children(node, enter, mask, &mut stack);
                    continue;
                }
            } else if self.leaf_filtered(q, cur, sink) {
                return;
            }
            loop {
                let Some((r, d)) = stack.pop() else {
                    return;
                };
                if d <= sink.tmax * ROBUST_FAR_SCALE {
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

/// Packet traversal over lanes of type `L`.
struct PacketRays<L: Lanes> {
    /// Origins, directions and `tmin` as lanes, for scalar-leaf primitives' lane tests.
    lanes: RayLanes<L>,
    o: [L; 3],
    inv: [L; 3],
    inv_far: [L; 3],
    tmin: L,
    tmax: L,
    near: [usize; 3],
    far: [usize; 3],
    shear: PacketShear<L>,
}

/// Per-lane answers of a packet.
struct PacketHits<L: Lanes> {
    t: L::Array,
    u: L::Array,
    v: L::Array,
    prim: [u32; 16],
    hit: u32,
}

impl<P: Primitives, const N: usize> Bvh<P, N>
where
    Width<N>: NodeWidth,
{
    /// Traces `rays` (exactly `L::WIDTH`) as packets: lanes are grouped by direction
    /// octant and dominant axis, each group traversed together; a packet whose rays fall
    /// into more than two groups is incoherent and goes ray by ray instead, as do all
    /// packets of a tree too deep for the packet stack.
    fn packet_closest<L: Lanes, R: LaneRays + ?Sized>(&self, rays: &R, out: &mut [Option<Hit>]) {
        let setup = PacketSetup::<L>::new(rays);
        out[..rays.lane_count()].fill(None);
        if !setup.coherent() || self.stack_need >= PACKET_STACK {
            for_each_bit(setup.valid, |i| {
                let q = lane_query(rays, i);
                out[i] = self.closest_from(&q, self.root, q.tmax);
            });
            return;
        }
        for g in 0..setup.groups {
            let p = setup.group(g);
            let mask = setup.group_mask[g];
            let hits = if setup.shared_origin {
                self.packet_closest_group::<L, R, true>(&p, rays, mask)
            } else {
                self.packet_closest_group::<L, R, false>(&p, rays, mask)
            };
            for_each_bit(hits.hit, |i| {
                out[i] = Some(Hit {
                    t: hits.t.as_ref()[i],
                    prim: hits.prim[i],
                    u: hits.u.as_ref()[i],
                    v: hits.v.as_ref()[i],
                })
            });
        }
    }

    fn packet_closest_group<L: Lanes, R: LaneRays + ?Sized, const SHARED: bool>(
        &self,
        p: &PacketRays<L>,
        rays: &R,
        mask: u32,
    ) -> PacketHits<L> {
        let mut tmax = p.tmax;
        let mut res = PacketHits::<L> {
            t: L::splat(0.0).to_array(),
            u: L::splat(0.0).to_array(),
            v: L::splat(0.0).to_array(),
            prim: [u32::MAX; 16],
            hit: 0,
        };
        let mut tu = L::splat(0.0);
        let mut tv = L::splat(0.0);
        let mut stack: Stack<(u32, L), PACKET_STACK> = Stack::new();
        let mut cur = self.root;
        let mut cur_enter = p.tmin;
        let bounds = PacketBounds::<<Width<N> as NodeWidth>::L>::new(
            p,
            mask,
            tmax,
            SHARED,
            self.nodes.len() >= PACKET_BOUNDS_MIN_NODES,
        );
        loop {
            // Scaled once per step: entries are compared with it (see `Aabb::intersect`).
            let tcull = tmax * L::splat(ROBUST_FAR_SCALE);
            let active = mask & cur_enter.le(tcull).bitmask();
            if active == 0 {
                // culled: every lane has a closer hit than this subtree's entry
            } else if active.count_ones() < PACKET_MIN_ACTIVE {
                // Too few rays left to share the work: finish the subtree ray by ray.
                let tm = tmax.to_array();
                let mut m = active;
                let mut new_t = tmax.to_array();
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    let q = &lane_query(rays, i);
                    if let Some(h) = self.closest_from(q, cur, tm.as_ref()[i]) {
                        new_t.as_mut()[i] = h.t;
                        res.prim[i] = h.prim;
                        res.u.as_mut()[i] = h.u;
                        res.v.as_mut()[i] = h.v;
                        res.hit |= 1 << i;
                        let sel = L::mask_from_bits(1 << i);
                        tu = L::select(sel, L::splat(h.u), tu);
                        tv = L::select(sel, L::splat(h.v), tv);
                    }
                    m &= m - 1;
                }
                tmax = L::from_array(new_t);
            } else if !is_leaf(cur) {
                let node = &self.nodes[cur as usize];
                let mut enters = [L::splat(0.0); N];
                let mut order = [(0usize, 0f32); N];
                let mut n = 0;
                let rep = active.trailing_zeros() as usize;
                let mut cand = bounds.candidates(node);
                while cand != 0 {
                    let c = cand.trailing_zeros() as usize;
                    cand &= cand - 1;
                    let (enter, bits) = p.child_test::<SHARED, N>(node, c, tcull);
                    if bits & active != 0 {
                        enters[c] = enter;
                        // insertion sort, far to near, by the representative lane's entry
                        let key = enter.to_array().as_ref()[rep];
                        let mut j = n;
                        while j > 0 && order[j - 1].1 < key {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = (c, key);
                        n += 1;
                    }
                }
                if n > 0 {
                    for &(c, _) in &order[..n - 1] {
                        stack.push((node.children[c], enters[c]));
                    }
                    let c = order[n - 1].0;
                    cur = node.children[c];
                    cur_enter = enters[c];
                    continue;
                }
            } else if let Leaves::Scalar { prims, ids } = &self.leaves {
                for k in leaf_range(cur) {
                    let (t, u, v, bits) = prims.intersect_lanes(k, &p.lanes, tmax, active, rays);
                    if bits != 0 {
                        let sel = L::mask_from_bits(bits);
                        tmax = L::select(sel, t, tmax);
                        tu = L::select(sel, u, tu);
                        tv = L::select(sel, v, tv);
                        res.hit |= bits;
                        for_each_bit(bits, |i| res.prim[i] = ids[k]);
                    }
                }
            } else if let Leaves::Triangles(groups) = &self.leaves {
                for g in &groups[leaf_range(cur)] {
                    for lane in 0..4 {
                        if g.ids[lane] == u32::MAX {
                            continue;
                        }
                        let corners = g.corners(lane);
                        let (t, u, v, bits, edge) =
                            triangle_packet::<L, SHARED>(&p.shear, &corners, tmax, active);
                        let mut bits = bits;
                        let (mut t, mut u, mut v) = (t, u, v);
                        if edge != 0 {
                            // exactly-zero edge functions: the scalar test with its f64 fallback
                            let (mut ta, mut ua, mut va) =
                                (t.to_array(), u.to_array(), v.to_array());
                            let tm = tmax.to_array();
                            let mut m = edge;
                            while m != 0 {
                                let i = m.trailing_zeros() as usize;
                                let q = &lane_query(rays, i);
                                if let Some(h) = crate::geometry::intersect_triangle(
                                    q,
                                    corners[0],
                                    corners[1],
                                    corners[2],
                                    tm.as_ref()[i],
                                ) {
                                    ta.as_mut()[i] = h.t;
                                    ua.as_mut()[i] = h.u;
                                    va.as_mut()[i] = h.v;
                                    bits |= 1 << i;
                                }
                                m &= m - 1;
                            }
                            (t, u, v) = (L::from_array(ta), L::from_array(ua), L::from_array(va));
                        }
                        if bits != 0 {
                            let sel = L::mask_from_bits(bits);
                            tmax = L::select(sel, t, tmax);
                            tu = L::select(sel, u, tu);
                            tv = L::select(sel, v, tv);
                            res.hit |= bits;
                            let mut m = bits;
                            while m != 0 {
                                res.prim[m.trailing_zeros() as usize] = g.ids[lane];
                                m &= m - 1;
                            }
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
        res.t = tmax.to_array();
        res.u = tu.to_array();
        res.v = tv.to_array();
        res
    }

    fn packet_any<L: Lanes, R: LaneRays + ?Sized>(&self, rays: &R, out: &mut [bool]) {
        let setup = PacketSetup::<L>::new(rays);
        out[..rays.lane_count()].fill(false);
        if !setup.coherent() || self.stack_need >= PACKET_STACK {
            for_each_bit(setup.valid, |i| {
                out[i] = self.any_from(&lane_query(rays, i), self.root)
            });
            return;
        }
        for g in 0..setup.groups {
            let p = setup.group(g);
            let mask = setup.group_mask[g];
            let occluded = if setup.shared_origin {
                self.packet_any_group::<L, R, true>(&p, rays, mask)
            } else {
                self.packet_any_group::<L, R, false>(&p, rays, mask)
            };
            for_each_bit(occluded, |i| out[i] = true);
        }
    }

    /// Bits of the lanes in `mask` that hit something within their interval.
    fn packet_any_group<L: Lanes, R: LaneRays + ?Sized, const SHARED: bool>(
        &self,
        p: &PacketRays<L>,
        rays: &R,
        mask: u32,
    ) -> u32 {
        let mut occluded = 0u32;
        let mut stack: Stack<(u32, L), PACKET_STACK> = Stack::new();
        let mut cur = self.root;
        let mut cur_enter = p.tmin;
        let tcull = p.tmax * L::splat(ROBUST_FAR_SCALE);
        let bounds = PacketBounds::<<Width<N> as NodeWidth>::L>::new(
            p,
            mask,
            p.tmax,
            SHARED,
            self.nodes.len() >= PACKET_BOUNDS_MIN_NODES,
        );
        loop {
            let active = mask & !occluded & cur_enter.le(tcull).bitmask();
            if active == 0 {
            } else if active.count_ones() < PACKET_MIN_ACTIVE {
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
                let mut first = None;
                let mut cand = bounds.candidates(node);
                while cand != 0 {
                    let c = cand.trailing_zeros() as usize;
                    cand &= cand - 1;
                    let (enter, bits) = p.child_test::<SHARED, N>(node, c, tcull);
                    if bits & active != 0 {
                        match first {
                            None => first = Some((node.children[c], enter)),
                            Some(_) => stack.push((node.children[c], enter)),
                        }
                    }
                }
                if let Some((r, e)) = first {
                    cur = r;
                    cur_enter = e;
                    continue;
                }
            } else if let Leaves::Scalar { prims, .. } = &self.leaves {
                for k in leaf_range(cur) {
                    let live = active & !occluded;
                    occluded |= prims.intersect_lanes(k, &p.lanes, p.tmax, live, rays).3;
                    if active & !occluded == 0 {
                        break;
                    }
                }
            } else if let Leaves::Triangles(groups) = &self.leaves {
                'groups: for g in &groups[leaf_range(cur)] {
                    for lane in 0..4 {
                        if g.ids[lane] == u32::MAX {
                            continue;
                        }
                        let live = active & !occluded;
                        let corners = g.corners(lane);
                        let (_, _, _, bits, edge) =
                            triangle_packet::<L, SHARED>(&p.shear, &corners, p.tmax, live);
                        occluded |= bits;
                        let mut m = edge;
                        while m != 0 {
                            let i = m.trailing_zeros() as usize;
                            let q = &lane_query(rays, i);
                            if crate::geometry::intersect_triangle(
                                q, corners[0], corners[1], corners[2], q.tmax,
                            )
                            .is_some()
                            {
                                occluded |= 1 << i;
                            }
                            m &= m - 1;
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

impl<L: Lanes> PacketRays<L> {
    /// Slab test of child `c` for every lane: entry distances and hit bits. `tcull` is
    /// the closest hit so far, already scaled by `ROBUST_FAR_SCALE`.
    #[inline(always)]
    fn child_test<const SHARED: bool, const N: usize>(
        &self,
        node: &BvhNode<N>,
        c: usize,
        tcull: L,
    ) -> (L, u32) {
        let p = &node.planes;
        let o = &self.shear.shared_origin;
        // With a shared origin, `plane - o` is one scalar per plane, broadcast: the same
        // value every lane would compute.
        let rel = |plane: usize, a: usize| {
            if SHARED {
                L::splat(p[plane][c] - o[a])
            } else {
                L::splat(p[plane][c]) - self.o[a]
            }
        };
        let d = |plane: usize, a: usize| rel(plane, a) * self.inv[a];
        let f = |plane: usize, a: usize| rel(plane, a) * self.inv_far[a];
        let enter =
            d(self.near[0], 0).maxps(d(self.near[1], 1).maxps(d(self.near[2], 2).maxps(self.tmin)));
        let exit = f(self.far[0], 0).minps(f(self.far[1], 1).minps(f(self.far[2], 2).minps(tcull)));
        (enter, enter.le(exit).bitmask())
    }
}

/// Interval bounds of a packet group's rays, for a conservative test of all of a node's
/// children at once (interval arithmetic over the lanes, as in the packet traversals of
/// Wald et al. and Boulos et al.): a child that fails it is missed by every lane, so its
/// per-lane slab test is skipped. On the bunny 70 % (BVH4) and 83 % (BVH8) of the per-lane
/// child tests of primary packets hit no lane; with the bounds first, 3 % do, and primary
/// packets run 1.1x (BVH4) and 1.2x (BVH8) faster. Computing the bounds must be cheap:
/// with a scalar loop over the lanes it cost more than it saved.
///
/// Exact, not approximate: each lane computes `round(round(p - o) * inv)`; with
/// `o` in `[o_lo, o_hi]` and `inv` in `[inv_lo, inv_hi]` of one sign, rounding is
/// monotone, so that value lies between the rounded products at the interval's corners,
/// and the node test built from those corners fails only where every lane's test fails.
/// Groups with an infinite reciprocal (a zero direction component) skip the bounds.
struct PacketBounds<NL: Lanes> {
    /// Per axis: the origin bound that minimises the near-plane distance and the one that
    /// maximises the far-plane distance.
    o_near: [NL; 3],
    o_far: [NL; 3],
    /// Per axis: the lanes' smallest and largest reciprocal, and far-scaled reciprocal.
    inv: [[NL; 2]; 3],
    inv_far: [[NL; 2]; 3],
    tmin: NL,
    tcull: NL,
    near: [usize; 3],
    far: [usize; 3],
    enabled: bool,
}

impl<NL: Lanes> PacketBounds<NL> {
    /// Bounds over the lanes of `mask`, whose intervals end at most at `tmax`.
    #[inline(always)]
    fn new<L: Lanes>(p: &PacketRays<L>, mask: u32, tmax: L, shared: bool, wanted: bool) -> Self {
        let zero = NL::splat(0.0);
        let mut b = PacketBounds {
            o_near: [zero; 3],
            o_far: [zero; 3],
            inv: [[zero; 2]; 3],
            inv_far: [[zero; 2]; 3],
            tmin: zero,
            tcull: zero,
            near: p.near,
            far: p.far,
            enabled: false,
        };
        if !wanted {
            return b;
        }
        let range = |v: L| lane_range(v, mask);
        let mut enabled = mask != 0;
        b.tmin = NL::splat(range(p.tmin).0);
        // `round(x * scale)` is monotone in x, so the bound of the lanes' products is the
        // product of the bound (here and for the far reciprocals below).
        b.tcull = NL::splat(range(tmax).1 * ROBUST_FAR_SCALE);
        for a in 0..3 {
            let (o_lo, o_hi) = if shared {
                (p.shear.shared_origin[a], p.shear.shared_origin[a])
            } else {
                range(p.o[a])
            };
            let (i_lo, i_hi) = range(p.inv[a]);
            let (f_lo, f_hi) = (i_lo * ROBUST_FAR_SCALE, i_hi * ROBUST_FAR_SCALE);
            enabled &= f_lo.is_finite() && f_hi.is_finite();
            // A positive reciprocal: distances grow with `p - o`, so the near distance
            // is smallest at the largest origin and the far one largest at the smallest.
            let negative = p.near[a] >= 3;
            b.o_near[a] = NL::splat(if negative { o_lo } else { o_hi });
            b.o_far[a] = NL::splat(if negative { o_hi } else { o_lo });
            b.inv[a] = [NL::splat(i_lo), NL::splat(i_hi)];
            b.inv_far[a] = [NL::splat(f_lo), NL::splat(f_hi)];
        }
        b.enabled = enabled;
        b
    }

    /// Bits of the children of `node` that some lane may enter (all non-empty children
    /// when the bounds are off).
    #[inline(always)]
    fn candidates<const N: usize>(&self, node: &BvhNode<N>) -> u32 {
        if !self.enabled {
            return node
                .children
                .iter()
                .enumerate()
                .fold(0, |m, (c, &r)| m | u32::from(r != EMPTY_CHILD) << c);
        }
        let lo = |a: usize| {
            let x = NL::load(&node.planes[self.near[a]]) - self.o_near[a];
            (x * self.inv[a][0]).minps(x * self.inv[a][1])
        };
        let hi = |a: usize| {
            let x = NL::load(&node.planes[self.far[a]]) - self.o_far[a];
            (x * self.inv_far[a][0]).maxps(x * self.inv_far[a][1])
        };
        let enter = lo(0).maxps(lo(1).maxps(lo(2).maxps(self.tmin)));
        let exit = hi(0).minps(hi(1).minps(hi(2).minps(self.tcull)));
        enter.le(exit).bitmask()
    }
}

/// The smallest and largest value of the lanes of `mask` (none NaN): masked lanes out of
/// the way, then a tree of min/max over halves (plain comparisons, which vectorise).
#[inline(always)]
fn lane_range<L: Lanes>(v: L, mask: u32) -> (f32, f32) {
    let lanes = L::mask_from_bits(mask);
    let mut lo = L::select(lanes, v, L::splat(f32::INFINITY)).to_array();
    let mut hi = L::select(lanes, v, L::splat(f32::NEG_INFINITY)).to_array();
    let (lo, hi) = (lo.as_mut(), hi.as_mut());
    let mut w = L::WIDTH / 2;
    while w > 0 {
        for i in 0..w {
            lo[i] = if lo[i + w] < lo[i] { lo[i + w] } else { lo[i] };
            hi[i] = if hi[i + w] > hi[i] { hi[i + w] } else { hi[i] };
        }
        w /= 2;
    }
    (lo[0], hi[0])
}

/// The query of valid lane `i` of a packet (built in registers for a `RayPacket`: a
/// `Ray` written to memory field by field and read back with vector loads right away
/// stalls on store forwarding).
#[inline(always)]
fn lane_query<R: LaneRays + ?Sized>(rays: &R, i: usize) -> RayQuery {
    rays.lane_query(i)
        .expect("packet setup passes valid lanes only")
}

/// Calls `f` with the index of every set bit.
#[inline(always)]
fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// A packet loaded into lanes, its valid lanes, and its lane groups of equal direction
/// octant and dominant axis (at most three; more means incoherent). Validity, reciprocal
/// and dominant axis are computed lane-parallel with the same operations as
/// `Ray::is_valid` and `RayQuery::new`, so every lane agrees with the scalar path.
struct PacketSetup<L: Lanes> {
    o: [L; 3],
    d: [L; 3],
    inv: [L; 3],
    tmin: L,
    tmax: L,
    valid: u32,
    /// Every valid lane starts at the first valid lane's origin (camera rays).
    shared_origin: bool,
    origin0: [f32; 3],
    groups: usize,
    group_mask: [u32; 3],
    /// (octant sign bits, kz) per group.
    group_key: [(u32, usize); 3],
}

impl<L: Lanes> PacketSetup<L> {
    #[inline(always)]
    fn new<R: LaneRays + ?Sized>(rays: &R) -> Self {
        // Lanes past the count may hold anything: they are masked off from `valid` below.
        let [ox, oy, oz, dx, dy, dz, tmin, tmax] = rays.load_lanes::<L>();
        let (o, d) = ([ox, oy, oz], [dx, dy, dz]);
        let zero = L::splat(0.0);
        let finite = o[0].is_finite()
            & o[1].is_finite()
            & o[2].is_finite()
            & d[0].is_finite()
            & d[1].is_finite()
            & d[2].is_finite();
        let nonzero = !(d[0].eq(zero) & d[1].eq(zero) & d[2].eq(zero)).bitmask();
        // tmin <= tmax is false for NaN in either, matching `Ray::is_valid`.
        let lanes = if L::WIDTH == 32 {
            u32::MAX
        } else {
            (1u32 << L::WIDTH) - 1
        };
        let valid = finite.bitmask()
            & nonzero
            & tmin.le(tmax).bitmask()
            & lanes
            & ((1u64 << rays.lane_count().min(L::WIDTH)) - 1) as u32;
        let inv = [
            L::splat(1.0) / d[0],
            L::splat(1.0) / d[1],
            L::splat(1.0) / d[2],
        ];

        // Dominant axis as in `RayQuery::new`: x if |x| >= |y| and |x| >= |z|, else y if |y| >= |z|, else z.
        let abs = |v: L| L::select(v.lt(zero), zero - v, v);
        let (ax, ay, az) = (abs(d[0]), abs(d[1]), abs(d[2]));
        let is_x = (ay.le(ax) & az.le(ax)).bitmask();
        let is_y = !is_x & az.le(ay).bitmask();
        let signs = [d[0].sign_bits(), d[1].sign_bits(), d[2].sign_bits()];

        let (shared_origin, origin0) = match valid {
            0 => (false, [0.0; 3]),
            v => {
                let i0 = v.trailing_zeros() as usize;
                let r0 = rays.lane_origin(i0);
                let same = |k: usize| o[k].eq(L::splat(r0[k])).bitmask();
                let same_bits = same(0) & same(1) & same(2);
                (valid & !same_bits == 0, r0)
            }
        };
        let mut s = PacketSetup {
            o,
            d,
            inv,
            tmin,
            tmax,
            valid,
            shared_origin,
            origin0,
            groups: 0,
            group_mask: [0; 3],
            group_key: [(0, 0); 3],
        };
        let mut rest = valid;
        while rest != 0 {
            let i = rest.trailing_zeros();
            let octant = (signs[0] >> i & 1) | (signs[1] >> i & 1) << 1 | (signs[2] >> i & 1) << 2;
            let kz = if is_x >> i & 1 == 1 {
                0
            } else if is_y >> i & 1 == 1 {
                1
            } else {
                2
            };
            let same_octant = !(signs[0] ^ 0u32.wrapping_sub(octant & 1))
                & !(signs[1] ^ 0u32.wrapping_sub(octant >> 1 & 1))
                & !(signs[2] ^ 0u32.wrapping_sub(octant >> 2 & 1));
            let same_axis = match kz {
                0 => is_x,
                1 => is_y,
                _ => !is_x & !is_y,
            };
            let members = rest & same_octant & same_axis;
            if s.groups == 3 {
                s.groups = 4;
                break;
            }
            s.group_mask[s.groups] = members;
            s.group_key[s.groups] = (octant, kz);
            s.groups += 1;
            rest &= !members;
        }
        s
    }

    fn coherent(&self) -> bool {
        self.groups <= 2
    }

    /// The traversal state of group `g`: its planes and watertight shear.
    #[inline(always)]
    fn group(&self, g: usize) -> PacketRays<L> {
        let (octant, kz) = self.group_key[g];
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if octant >> kz & 1 == 1 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = L::splat(1.0) / self.d[kz];
        let near = [0, 1, 2].map(|a| if octant >> a & 1 == 1 { a + 3 } else { a });
        PacketRays {
            lanes: RayLanes {
                o: self.o,
                d: self.d,
                tmin: self.tmin,
            },
            o: self.o,
            inv: self.inv,
            inv_far: self.inv.map(|x| x * L::splat(ROBUST_FAR_SCALE)),
            tmin: self.tmin,
            tmax: self.tmax,
            near,
            far: near.map(|p| if p >= 3 { p - 3 } else { p + 3 }),
            shear: PacketShear {
                o: self.o,
                shared_origin: self.origin0,
                kx,
                ky,
                kz,
                sx: self.d[kx] * sz,
                sy: self.d[ky] * sz,
                sz,
                tmin: self.tmin,
            },
        }
    }
}

impl<P: Primitives, const N: usize> Accel for Bvh<P, N>
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

    fn closest_hit_packet(&self, packet: &RayPacket, out: &mut [Option<Hit>]) {
        self.packet_closest::<Packet, _>(packet, out);
    }

    fn any_hit_packet(&self, packet: &RayPacket, out: &mut [bool]) {
        self.packet_any::<Packet, _>(packet, out);
    }

    fn info(&self) -> AccelInfo {
        self.info.clone()
    }
}

impl<const N: usize> BvhNode<N> {
    /// Bounds of child slot `c`.
    pub fn child_bounds(&self, c: usize) -> Aabb {
        Aabb::new(
            Vec3::new(self.planes[0][c], self.planes[1][c], self.planes[2][c]),
            Vec3::new(self.planes[3][c], self.planes[4][c], self.planes[5][c]),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn soup() -> Triangles {
        let mut corners = Vec::new();
        let mut s = 7u32;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        for _ in 0..3000 {
            let c = Vec3::new(r(), r(), r()) * 10.0;
            corners.push([
                c,
                c + Vec3::new(r(), r(), 0.1),
                c + Vec3::new(0.2, r(), r()),
            ]);
        }
        Triangles::from_corners(&corners)
    }

    /// A tree too deep for the packet stack traces its packets ray by ray, with the same
    /// answers as the packet kernels.
    #[test]
    fn packets_of_a_tree_too_deep_for_the_packet_stack_go_ray_by_ray() {
        let mut bvh = Bvh8::build(soup());
        assert!(bvh.stack_need > 0 && bvh.stack_need < PACKET_STACK);
        let rays: Vec<Ray> = (0..512)
            .map(|i| {
                let a = i as f32 * 0.37;
                Ray::new(
                    Vec3::new(5.0, 5.0, -20.0),
                    Vec3::new(a.cos() * 0.2, a.sin() * 0.2, 1.0),
                )
            })
            .collect();
        let mut packet = vec![None; rays.len()];
        let mut packet_occ = vec![false; rays.len()];
        bvh.closest_hit_batch(&rays, &mut packet);
        bvh.any_hit_batch(&rays, &mut packet_occ);
        assert!(packet.iter().filter(|h| h.is_some()).count() > 50);
        bvh.stack_need = PACKET_STACK;
        let mut deep = vec![None; rays.len()];
        let mut deep_occ = vec![false; rays.len()];
        bvh.closest_hit_batch(&rays, &mut deep);
        bvh.any_hit_batch(&rays, &mut deep_occ);
        assert_eq!(packet, deep);
        assert_eq!(packet_occ, deep_occ);
    }

    /// Collapsing the top levels in parallel gives exactly the serial layout.
    #[test]
    fn parallel_collapse_lays_out_the_serial_tree() {
        fn layout<const N: usize, P: Primitives>(prims: &P, levels: usize) -> Vec<u32> {
            let (tree, ids) = build_tree(prims, wide_build_options(prims.as_triangles().is_some()));
            let mut c = Collapse::<N> {
                ids: &ids,
                triangles: prims.as_triangles(),
                nodes: Vec::new(),
                groups: Vec::new(),
            };
            let root = c.collapse(&tree.expect("non-empty"), levels);
            // every bit of the arrays, NaN corners of unused lanes included
            let mut bits = vec![root];
            for n in &c.nodes {
                bits.extend(n.planes.iter().flatten().map(|x| x.to_bits()));
                bits.extend(n.children);
            }
            for g in &c.groups {
                bits.extend(g.v.iter().flatten().flatten().map(|x| x.to_bits()));
                bits.extend(g.ids);
            }
            bits
        }
        let tris = soup();
        assert_eq!(layout::<8, _>(&tris, 0), layout::<8, _>(&tris, 3));
        assert_eq!(layout::<4, _>(&tris, 0), layout::<4, _>(&tris, 2));
        let centers: Vec<Vec3> = (0..500)
            .map(|i| Vec3::new(i as f32, (i * 7 % 13) as f32, 0.0))
            .collect();
        let spheres = crate::accel::Spheres {
            center: centers,
            radius: vec![0.4; 500],
        };
        assert_eq!(layout::<8, _>(&spheres, 0), layout::<8, _>(&spheres, 2));
    }

    /// The whole-packet node test never drops a child that some lane's own slab test
    /// enters: every node of both widths against packets of many shapes (shared and
    /// scattered origins, narrow and wide cones, nearly axis-parallel directions with
    /// huge reciprocals, intervals starting late and ending early).
    #[test]
    fn packet_bounds_never_cull_a_child_a_lane_enters() {
        fn check<const N: usize>(bvh: &Bvh<Triangles, N>, rays: &[Ray]) -> (u64, u64)
        where
            Width<N>: NodeWidth,
        {
            let packet = RayPacket::from_rays(rays);
            let setup = PacketSetup::<Packet>::new(&packet);
            let (mut entered, mut kept) = (0, 0);
            for g in 0..setup.groups.min(3) {
                let p = setup.group(g);
                let mask = setup.group_mask[g];
                let shared = setup.shared_origin;
                let bounds =
                    PacketBounds::<<Width<N> as NodeWidth>::L>::new(&p, mask, p.tmax, shared, true);
                let tcull = p.tmax * Packet::splat(ROBUST_FAR_SCALE);
                for node in &bvh.nodes {
                    let cand = bounds.candidates(node);
                    for c in 0..N {
                        if node.children[c] == EMPTY_CHILD {
                            continue;
                        }
                        let bits = if shared {
                            p.child_test::<true, N>(node, c, tcull).1
                        } else {
                            p.child_test::<false, N>(node, c, tcull).1
                        };
                        if bits & mask != 0 {
                            entered += 1;
                            assert!(cand >> c & 1 == 1, "child {c} culled, lanes {bits:b}");
                        }
                        kept += u64::from(cand >> c & 1);
                    }
                }
            }
            (entered, kept)
        }
        let tris = soup();
        let (b4, b8) = (Bvh4::build(tris.clone()), Bvh8::build(tris));
        let mut s = 99u32;
        let mut r = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        let (mut entered, mut kept) = (0, 0);
        for trial in 0..120 {
            let spread = [0.0, 1e-3, 0.5, 4.0][trial % 4];
            let cone = [1e-3, 0.05, 0.4][trial % 3];
            let base = Vec3::new(5.0, 5.0, -10.0) + Vec3::new(r(), r(), r()) * 4.0;
            let axis = if trial % 5 == 0 {
                Vec3::new(1e-7, 2e-7, 1.0) // reciprocals near 1e7
            } else {
                (Vec3::new(r(), r(), 8.0) - Vec3::splat(0.5)).normalize()
            };
            let rays: Vec<Ray> = (0..16)
                .map(|_| {
                    let o = base + Vec3::new(r(), r(), r()) * spread;
                    let d = (axis + Vec3::new(r() - 0.5, r() - 0.5, 0.0) * cone).normalize();
                    let (tmin, tmax) = if trial % 7 == 0 {
                        (5.0, 14.0)
                    } else {
                        (0.0, f32::INFINITY)
                    };
                    Ray::segment(o, d, tmin, tmax)
                })
                .collect();
            for (e, k) in [check(&b4, &rays), check(&b8, &rays)] {
                entered += e;
                kept += k;
            }
        }
        assert!(
            entered > 1000,
            "too few entered children to check: {entered}"
        );
        assert!(
            kept < 3 * entered,
            "the bounds cull little: {kept} kept, {entered} entered"
        );
    }

    /// The stack need is the largest sum of (children - 1) along a path, and within the
    /// single-ray capacity.
    #[test]
    fn stack_need_bounds_the_pending_entries() {
        let b4 = Bvh4::build(soup());
        let b8 = Bvh8::build(soup());
        assert!(b4.stack_need <= 3 * b4.info.max_depth);
        assert!(b8.stack_need <= 7 * b8.info.max_depth);
        assert!(b8.info.max_depth < b4.info.max_depth);
        assert!(b8.stack_need < SINGLE_STACK);
    }
}
