//! Octree: recursive 8-way subdivision of the scene box at its centre, traversed front
//! to back (children in the order the ray enters them, a 2x2x2 DDA per node, in the
//! spirit of Revelles, Ureña & Lastra's parametric traversal, 2000).
//!
//! Primitives straddling child boundaries go into *every* child they overlap (so the
//! leaves partition space and the traversal can stop at the first leaf that holds a
//! hit); a node stays a leaf when it has at most `max_leaf` primitives, is at
//! `max_depth`, or when splitting would multiply its references by more than
//! `max_duplication` (primitives that all straddle the centre, e.g. 10^4 identical
//! triangles, would otherwise be copied into all eight children at every level).

use super::spatial::{
    CountedTraversal, LeafSink, TraversalCounts, bounds_and_margins, boxes_overlap,
    clip_conservative, grown, moves_along, plane_error, region_margin,
};
use super::{AccelInfo, Primitives};
use crate::geometry::{Aabb, RayQuery};
use glam::Vec3;
use std::time::Instant;

/// Build limits of an [`Octree`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctreeOptions {
    pub max_depth: u32,
    pub max_leaf: usize,
    /// A node is split only if its children hold at most this many times its references.
    pub max_duplication: f32,
}

impl Default for OctreeOptions {
    fn default() -> Self {
        OctreeOptions {
            max_depth: 20,
            max_leaf: 8,
            max_duplication: 3.0,
        }
    }
}

/// 8 bytes: an interior node's eight children are contiguous from `first`; a leaf's
/// primitive ids are `refs[first..first + count]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OctreeNode {
    pub first: u32,
    /// Primitive count of a leaf; `INTERIOR` for an interior node.
    pub count: u32,
}

const INTERIOR: u32 = u32::MAX;
const _: () = assert!(std::mem::size_of::<OctreeNode>() == 8);

pub struct Octree<P: Primitives> {
    prims: P,
    nodes: Vec<OctreeNode>,
    refs: Vec<u32>,
    /// Root box: a cube around the scene bounds grown by the assignment margin.
    bounds: Aabb,
    info: AccelInfo,
}

struct Builder<'a, P: Primitives> {
    prims: &'a P,
    bounds: Vec<Aabb>,
    /// Assignment margin of each primitive ([`super::spatial::primitive_margin`]).
    pads: Vec<f32>,
    opts: OctreeOptions,
    nodes: Vec<OctreeNode>,
    refs: Vec<u32>,
    max_depth: u32,
    leaves: usize,
}

/// Child `c`'s box: bit `a` of `c` selects the upper half along axis `a`.
#[inline(always)]
fn child_box(lo: Vec3, hi: Vec3, mid: Vec3, c: usize) -> (Vec3, Vec3) {
    let mut clo = lo;
    let mut chi = mid;
    for a in 0..3 {
        if c >> a & 1 == 1 {
            clo[a] = mid[a];
            chi[a] = hi[a];
        }
    }
    (clo, chi)
}

impl<P: Primitives> Builder<'_, P> {
    fn leaf(&mut self, node: usize, ids: &[u32]) {
        self.nodes[node] = OctreeNode {
            first: self.refs.len() as u32,
            count: ids.len() as u32,
        };
        self.refs.extend_from_slice(ids);
        self.leaves += 1;
    }

    fn build(&mut self, node: usize, lo: Vec3, hi: Vec3, ids: Vec<u32>, depth: u32) {
        self.max_depth = self.max_depth.max(depth);
        if ids.len() <= self.opts.max_leaf || depth >= self.opts.max_depth {
            return self.leaf(node, &ids);
        }
        let mid = 0.5 * (lo + hi);
        let mut children: Vec<Vec<u32>> = Vec::with_capacity(8);
        let mut total = 0usize;
        for c in 0..8 {
            let (clo, chi) = child_box(lo, hi, mid, c);
            let region = Aabb::new(clo, chi);
            let rm = region_margin(&region);
            let list: Vec<u32> = ids
                .iter()
                .copied()
                .filter(|&i| {
                    let g = grown(&region, self.pads[i as usize] + rm);
                    boxes_overlap(&self.bounds[i as usize], &g)
                        && self.prims.overlaps_box(i as usize, &g)
                })
                .collect();
            total += list.len();
            children.push(list);
        }
        if total as f32 > self.opts.max_duplication * ids.len() as f32 {
            return self.leaf(node, &ids);
        }
        drop(ids);
        let first = self.nodes.len();
        self.nodes[node] = OctreeNode {
            first: first as u32,
            count: INTERIOR,
        };
        self.nodes
            .resize(first + 8, OctreeNode { first: 0, count: 0 });
        for (c, list) in children.into_iter().enumerate() {
            let (clo, chi) = child_box(lo, hi, mid, c);
            self.build(first + c, clo, chi, list, depth + 1);
        }
    }
}

/// Mutable state of one ray's traversal.
struct RayState<S: LeafSink> {
    sink: S,
    counts: TraversalCounts,
}

impl<P: Primitives> Octree<P> {
    pub fn build(prims: P) -> Self {
        Self::build_with(prims, OctreeOptions::default())
    }

    pub fn build_with(prims: P, opts: OctreeOptions) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let (bounds, pads, pad) = bounds_and_margins(&prims);
        let scene = bounds.iter().fold(Aabb::EMPTY, |b, p| b.union(p));
        // A cube around the scene: a flat scene's plane is then split by the root's
        // middle plane only, not at every level (which would double its references each
        // level).
        let root = if n == 0 {
            Aabb::EMPTY
        } else {
            let half = Vec3::splat(0.5 * scene.extent().max_element() + pad);
            Aabb::new(scene.center() - half, scene.center() + half)
        };
        let mut b = Builder {
            prims: &prims,
            bounds,
            pads,
            opts,
            nodes: vec![OctreeNode { first: 0, count: 0 }],
            refs: Vec::new(),
            max_depth: 0,
            leaves: 0,
        };
        if n > 0 {
            b.build(0, root.min, root.max, (0..n as u32).collect(), 0);
        } else {
            b.leaves = 1;
        }
        let (nodes, refs, max_depth, leaves) = (b.nodes, b.refs, b.max_depth, b.leaves);
        let info = AccelInfo {
            name: "octree",
            primitives: n,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            nodes: nodes.len(),
            leaves,
            max_depth: max_depth as usize,
            memory_bytes: nodes.len() * 8 + refs.len() * 4 + prims.memory_bytes(),
            sah_cost: 0.0,
        };
        Octree {
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

    fn query<const COUNT: bool, S: LeafSink>(&self, q: &RayQuery, sink: S) -> (S, TraversalCounts) {
        let mut s = RayState {
            sink,
            counts: TraversalCounts::default(),
        };
        if let Some((t0, t1)) = clip_conservative(&self.bounds, q) {
            self.visit::<COUNT, S>(0, self.bounds.min, self.bounds.max, t0, t1, q, &mut s);
        }
        (s.sink, s.counts)
    }

    /// Visits the subtree of `node` (box `lo..hi`) over the ray interval `[t0, t1]`, a
    /// conservative interval: it contains the exact ray's interval inside the box.
    /// Returns true when the sink ends the traversal (any hit found).
    ///
    /// The children's intervals come from the nine plane distances (lo, mid, hi per
    /// axis), each widened by its error bound ([`plane_error`], Ize 2013): the order in
    /// which the ray crosses the three middle planes is uncertain when two crossings
    /// are within their bounds, so instead of a 2x2x2 DDA every child whose widened
    /// interval overlaps `[t0, t1]` is visited, in order of its entry's lower bound, and
    /// the level stops once the nearest hit is at or before the next child's entry
    /// lower bound. Axes the ray does not move along keep the exact origin-side rule.
    #[allow(clippy::too_many_arguments)]
    fn visit<const COUNT: bool, S: LeafSink>(
        &self,
        node: usize,
        lo: Vec3,
        hi: Vec3,
        t0: f32,
        t1: f32,
        q: &RayQuery,
        s: &mut RayState<S>,
    ) -> bool {
        s.counts.node::<COUNT>();
        let n = self.nodes[node];
        if n.count != INTERIOR {
            for &id in &self.refs[n.first as usize..(n.first + n.count) as usize] {
                s.counts.prim::<COUNT>();
                if s.sink.test(&self.prims, id, q) {
                    return true;
                }
            }
            return false;
        }
        let mid = 0.5 * (lo + hi);
        // Per axis and half (0: lower, 1: upper): the conservative [enter, exit] of the
        // ray in that half-slab, or for a parallel axis the whole line on the origin's
        // side and nothing on the other.
        let mut slab = [[(f32::NEG_INFINITY, f32::INFINITY); 2]; 3];
        for a in 0..3 {
            if moves_along(q, a) {
                let t = [lo[a], mid[a], hi[a]].map(|x| (x - q.origin[a]) * q.inv_dir[a]);
                let lower = t.map(|t| t - plane_error(t));
                let upper = t.map(|t| t + plane_error(t));
                for h in 0..2 {
                    // half h lies between planes h and h + 1
                    slab[a][h] = if q.dir[a] > 0.0 {
                        (lower[h], upper[h + 1])
                    } else {
                        (lower[h + 1], upper[h])
                    };
                }
            } else {
                let h = (q.origin[a] < mid[a]) as usize;
                slab[a][h] = (f32::INFINITY, f32::NEG_INFINITY);
            }
        }
        // (entry lower bound, exit upper bound, child), at most 8, sorted by entry.
        let mut order = [(0.0f32, 0.0f32, 0u8); 8];
        let mut k = 0usize;
        for c in 0..8usize {
            let mut enter = t0;
            let mut exit = t1;
            for (a, halves) in slab.iter().enumerate() {
                let (e, x) = halves[c >> a & 1];
                enter = enter.max(e);
                exit = exit.min(x);
            }
            if enter <= exit {
                let mut j = k;
                while j > 0 && order[j - 1].0 > enter {
                    order[j] = order[j - 1];
                    j -= 1;
                }
                order[j] = (enter, exit, c as u8);
                k += 1;
            }
        }
        for &(enter, exit, c) in &order[..k] {
            // Closest hit at or before this child's earliest possible entry: nothing in
            // it or in the later children can be nearer.
            if s.sink.tmax() <= enter {
                return false;
            }
            let c = c as usize;
            let (clo, chi) = child_box(lo, hi, mid, c);
            if self.visit::<COUNT, S>(n.first as usize + c, clo, chi, enter, exit, q, s) {
                return true;
            }
        }
        false
    }
}

impl<P: Primitives> CountedTraversal for Octree<P> {
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
        let o = Octree::build(identical_triangles());
        assert!(o.references() <= 3 * 10_000, "{} refs", o.references());
        assert!(o.info.max_depth <= 20);
        hits_identical_triangles(&o);
    }

    #[test]
    fn flat_scene_box_and_coplanar_primitives() {
        flat_scene_agrees_with_brute_force(Octree::build);
    }
}
