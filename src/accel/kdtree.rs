//! kd-tree with binned SAH construction and ordered traversal over a t-interval stack
//! (the standard recursive algorithm in Wald's iterative form, Wald 2004 §7.3; Havran's
//! thesis 2000 for the cost model).
//!
//! Build: at each node, 32 equal-width bins per axis count where each primitive's bounds
//! (clipped to the node) start and end; the 31 planes between bins are evaluated with
//! the SAH `C_t + C_i (A_L N_L + A_R N_R) / A`, scaled by `1 - empty_bonus` when one side
//! is empty (cutting off empty space pays). A node becomes a leaf when the best plane
//! costs at least `C_i n` (the leaf's cost), or at depth `8 + 1.3 log2 n` (the usual
//! rule of thumb, Havran 2000), capped at [`MAX_DEPTH`]. Primitives whose bounds reach
//! within the assignment margin of the plane go to both children.

use super::spatial::{
    CountedTraversal, LeafSink, TraversalCounts, bounds_and_margins, boxes_overlap,
    clip_conservative, grown, moves_along, plane_error, region_margin,
};
use super::{AccelInfo, Primitives};
use crate::geometry::{Aabb, RayQuery};
use std::time::Instant;

/// Build parameters of a [`KdTree`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KdTreeOptions {
    /// Bins per axis of the SAH sweep (at most `MAX_BINS`).
    pub bins: usize,
    pub traversal_cost: f32,
    pub intersection_cost: f32,
    /// Cost reduction for a split with an empty side.
    pub empty_bonus: f32,
}

impl Default for KdTreeOptions {
    fn default() -> Self {
        KdTreeOptions {
            bins: 32,
            traversal_cost: 1.0,
            intersection_cost: 1.5,
            empty_bonus: 0.2,
        }
    }
}

pub const MAX_BINS: usize = 64;
/// Depth cap whatever `n`: the traversal stack has one entry per level.
pub const MAX_DEPTH: usize = 60;
const STACK_SIZE: usize = MAX_DEPTH + 4;

/// 8 bytes. `word` packs the kind in its low 2 bits (0, 1, 2: interior split on that
/// axis; 3: leaf) and in its upper 30 bits the index of the first of the two adjacent
/// children (below the plane, then above) or the leaf's primitive count. `data` is the
/// split position, or for a leaf the offset of its primitive ids (as bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KdNode {
    word: u32,
    data: f32,
}

const _: () = assert!(std::mem::size_of::<KdNode>() == 8);
const LEAF: u32 = 3;

impl KdNode {
    fn leaf(first: u32, count: u32) -> Self {
        KdNode {
            word: (count << 2) | LEAF,
            data: f32::from_bits(first),
        }
    }

    fn interior(axis: usize, split: f32, children: u32) -> Self {
        KdNode {
            word: (children << 2) | axis as u32,
            data: split,
        }
    }

    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.word & 3 == LEAF
    }

    #[inline(always)]
    fn axis(&self) -> usize {
        (self.word & 3) as usize
    }

    #[inline(always)]
    fn upper(&self) -> u32 {
        self.word >> 2
    }
}

pub struct KdTree<P: Primitives> {
    prims: P,
    nodes: Vec<KdNode>,
    refs: Vec<u32>,
    bounds: Aabb,
    info: AccelInfo,
}

struct Builder<'a, P: Primitives> {
    prims: &'a P,
    bounds: Vec<Aabb>,
    /// Assignment margin of each primitive ([`super::spatial::primitive_margin`]).
    pads: Vec<f32>,
    opts: KdTreeOptions,
    max_depth: usize,
    nodes: Vec<KdNode>,
    refs: Vec<u32>,
    depth_reached: usize,
    leaves: usize,
}

impl<P: Primitives> Builder<'_, P> {
    fn leaf(&mut self, node: usize, ids: &[u32]) {
        self.nodes[node] = KdNode::leaf(self.refs.len() as u32, ids.len() as u32);
        self.refs.extend_from_slice(ids);
        self.leaves += 1;
    }

    /// Cheapest (cost, axis, plane) among the bin boundaries.
    fn best_plane(&self, b: &Aabb, ids: &[u32]) -> Option<(f32, usize, f32)> {
        let nb = self.opts.bins.clamp(2, MAX_BINS);
        let n = ids.len();
        let inv_area = 1.0 / b.area().max(f32::MIN_POSITIVE);
        let mut best: Option<(f32, usize, f32)> = None;
        // No split of a node narrower than four margins of its primitives.
        let pad = ids
            .iter()
            .map(|&i| self.pads[i as usize])
            .fold(0.0, f32::max);
        for a in 0..3 {
            let ext = b.max[a] - b.min[a];
            if ext <= 4.0 * pad {
                continue;
            }
            let scale = nb as f32 / ext;
            let bin = |x: f32| (((x - b.min[a]) * scale) as usize).min(nb - 1);
            let mut starts = [0u32; MAX_BINS];
            let mut ends = [0u32; MAX_BINS];
            for &i in ids {
                let p = &self.bounds[i as usize];
                starts[bin(p.min[a].max(b.min[a]))] += 1;
                ends[bin(p.max[a].min(b.max[a]))] += 1;
            }
            let (mut left, mut ended) = (0u32, 0u32);
            for k in 1..nb {
                left += starts[k - 1];
                ended += ends[k - 1];
                let right = n as u32 - ended;
                let plane = b.min[a] + ext * k as f32 / nb as f32;
                let (mut lb, mut rb) = (*b, *b);
                lb.max[a] = plane;
                rb.min[a] = plane;
                let mut cost = self.opts.traversal_cost
                    + self.opts.intersection_cost
                        * (lb.area() * left as f32 + rb.area() * right as f32)
                        * inv_area;
                if left == 0 || right == 0 {
                    cost *= 1.0 - self.opts.empty_bonus;
                }
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, a, plane));
                }
            }
        }
        best
    }

    fn build(&mut self, node: usize, b: Aabb, ids: Vec<u32>, depth: usize) {
        self.depth_reached = self.depth_reached.max(depth);
        let n = ids.len();
        if n <= 1 || depth >= self.max_depth {
            return self.leaf(node, &ids);
        }
        let Some((cost, axis, split)) = self.best_plane(&b, &ids) else {
            return self.leaf(node, &ids);
        };
        if cost >= self.opts.intersection_cost * n as f32 {
            return self.leaf(node, &ids);
        }
        let (mut lb, mut rb) = (b, b);
        lb.max[axis] = split;
        rb.min[axis] = split;
        let side = |region: &Aabb| -> Vec<u32> {
            let rm = region_margin(region);
            ids.iter()
                .copied()
                .filter(|&i| {
                    let g = grown(region, self.pads[i as usize] + rm);
                    boxes_overlap(&self.bounds[i as usize], &g)
                        && self.prims.overlaps_box(i as usize, &g)
                })
                .collect()
        };
        let (left, right) = (side(&lb), side(&rb));
        if left.len() == n && right.len() == n {
            return self.leaf(node, &ids);
        }
        drop(ids);
        let first = self.nodes.len();
        self.nodes[node] = KdNode::interior(axis, split, first as u32);
        self.nodes.push(KdNode::leaf(0, 0));
        self.nodes.push(KdNode::leaf(0, 0));
        self.build(first, lb, left, depth + 1);
        self.build(first + 1, rb, right, depth + 1);
    }
}

impl<P: Primitives> KdTree<P> {
    pub fn build(prims: P) -> Self {
        Self::build_with(prims, KdTreeOptions::default())
    }

    pub fn build_with(prims: P, opts: KdTreeOptions) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let (bounds, pads, pad) = bounds_and_margins(&prims);
        let scene = bounds.iter().fold(Aabb::EMPTY, |b, p| b.union(p));
        let root = if n == 0 {
            Aabb::EMPTY
        } else {
            grown(&scene, pad)
        };
        let max_depth = ((8.0 + 1.3 * (n.max(1) as f64).log2()).round() as usize).min(MAX_DEPTH);
        let mut b = Builder {
            prims: &prims,
            bounds,
            pads,
            opts,
            max_depth,
            nodes: vec![KdNode::leaf(0, 0)],
            refs: Vec::new(),
            depth_reached: 0,
            leaves: 0,
        };
        if n > 0 {
            b.build(0, root, (0..n as u32).collect(), 0);
        } else {
            b.leaves = 1;
        }
        let info = AccelInfo {
            name: "kdtree",
            primitives: n,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            nodes: b.nodes.len(),
            leaves: b.leaves,
            max_depth: b.depth_reached,
            memory_bytes: b.nodes.len() * 8 + b.refs.len() * 4 + prims.memory_bytes(),
            sah_cost: 0.0,
        };
        let (nodes, refs) = (b.nodes, b.refs);
        KdTree {
            prims,
            nodes,
            refs,
            bounds: root,
            info,
        }
    }

    /// Total primitive references.
    pub fn references(&self) -> usize {
        self.refs.len()
    }

    fn query<const COUNT: bool, S: LeafSink>(
        &self,
        q: &RayQuery,
        mut sink: S,
    ) -> (S, TraversalCounts) {
        let mut counts = TraversalCounts::default();
        // Conservative intervals throughout (Ize 2013; pbrt-v4 §6.8): `[tn, tf]` always
        // contains the exact ray's interval in the current node, so no leaf the exact
        // ray enters is skipped, and the traversal stops only when the nearest hit is
        // at or before the *lower bound* of the next node's entry.
        let Some((mut tn, mut tf)) = clip_conservative(&self.bounds, q) else {
            return (sink, counts);
        };
        let mut stack = [(0u32, 0.0f32, 0.0f32); STACK_SIZE];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            counts.node::<COUNT>();
            let n = self.nodes[node];
            if !n.is_leaf() {
                let a = n.axis();
                let split = n.data;
                let below = n.upper() as usize;
                if !moves_along(q, a) {
                    // Parallel to the plane (either zero sign): only the origin's side.
                    // A ray lying in the plane may take either: primitives within the
                    // margin of the plane are in both children.
                    node = below + (q.origin[a] > split) as usize;
                    continue;
                }
                // The exact crossing lies in [ts - e, ts + e] (PLANE_DISTANCE_ERROR).
                let ts = (split - q.origin[a]) * q.inv_dir[a];
                let e = plane_error(ts);
                let (near, far) = if q.dir[a] > 0.0 {
                    (below, below + 1)
                } else {
                    (below + 1, below)
                };
                if ts - e > tf {
                    node = near;
                } else if ts + e < tn {
                    node = far;
                } else {
                    stack[sp] = (far as u32, tn.max(ts - e), tf);
                    sp += 1;
                    node = near;
                    tf = tf.min(ts + e);
                }
                continue;
            }
            let first = n.data.to_bits() as usize;
            for &id in &self.refs[first..first + n.upper() as usize] {
                counts.prim::<COUNT>();
                if sink.test(&self.prims, id, q) {
                    return (sink, counts);
                }
            }
            // No `sink.tmax() <= tf` shortcut: `tf` is an upper bound of this leaf's exit,
            // and the next leaf may be entered before it. A pending node is visited only
            // if the lower bound `a` of its entry is before the nearest hit.
            loop {
                if sp == 0 {
                    return (sink, counts);
                }
                sp -= 1;
                let (next, a, b) = stack[sp];
                if a < sink.tmax() {
                    node = next as usize;
                    (tn, tf) = (a, b);
                    break;
                }
            }
        }
    }
}

impl<P: Primitives> CountedTraversal for KdTree<P> {
    fn traverse_with<const COUNT: bool, S: LeafSink>(
        &self,
        q: &RayQuery,
        sink: S,
    ) -> (S, TraversalCounts) {
        self.query::<COUNT, S>(q, sink)
    }

    fn build_info(&self) -> &AccelInfo {
        &self.info
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::spatial::test_scenes::*;

    #[test]
    fn identical_triangles_terminate() {
        let k = KdTree::build(identical_triangles());
        assert!(k.info.max_depth <= MAX_DEPTH);
        assert!(k.references() <= 2 * 10_000, "{} refs", k.references());
        hits_identical_triangles(&k);
    }

    #[test]
    fn flat_scene_box_and_coplanar_primitives() {
        flat_scene_agrees_with_brute_force(KdTree::build);
    }
}
