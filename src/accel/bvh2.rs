use super::{Accel, AccelInfo, Primitives};
use crate::geometry::{Aabb, Hit, Ray, RayQuery};
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

/// Binary BVH node, 32 bytes, two per cache line. Children of an interior node are
/// stored next to each other (`first`, `first + 1`), so one index serves both.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Bvh2Node {
    pub min: [f32; 3],
    /// Interior: index of the left child (the right one follows). Leaf: first primitive.
    pub first: u32,
    pub max: [f32; 3],
    /// Number of primitives in a leaf; 0 marks an interior node.
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<Bvh2Node>() == 32);

impl Bvh2Node {
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::new(Vec3::from_array(self.min), Vec3::from_array(self.max))
    }
}

/// Build parameters of the binned SAH builder (Wald 2007, "On fast Construction of
/// SAH-based Bounding Volume Hierarchies").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bvh2BuildOptions {
    /// Bins per axis (16-32 is the usual trade-off between build time and quality).
    pub bins: usize,
    /// A node with more primitives than this is always split.
    pub max_leaf: usize,
    /// SAH cost of visiting a node, relative to `intersection_cost`.
    pub traversal_cost: f32,
    pub intersection_cost: f32,
}

impl Default for Bvh2BuildOptions {
    fn default() -> Self {
        Bvh2BuildOptions {
            bins: 32,
            max_leaf: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
        }
    }
}

/// Past this depth the builder splits at the object median, so the depth of any tree
/// stays below `MEDIAN_DEPTH + 32` and a fixed traversal stack suffices.
const MEDIAN_DEPTH: usize = 40;
/// Traversal stack size: at most one entry per level is pending.
pub const STACK_SIZE: usize = 128;
/// Subtrees with fewer primitives are built on the current thread.
const PARALLEL_THRESHOLD: usize = 4096;

/// Binary BVH with binned-SAH construction; primitives are reordered so that each
/// leaf's primitives are contiguous.
pub struct Bvh2<P: Primitives> {
    pub nodes: Vec<Bvh2Node>,
    /// Primitives in leaf order.
    pub prims: P,
    /// Original index of each primitive in leaf order.
    pub prim_ids: Vec<u32>,
    info: AccelInfo,
}

/// Intermediate tree of the parallel build, flattened afterwards.
enum BuildNode {
    Leaf {
        bounds: Aabb,
        start: usize,
        count: usize,
    },
    Interior {
        bounds: Aabb,
        children: Box<[BuildNode; 2]>,
    },
}

impl BuildNode {
    fn bounds(&self) -> Aabb {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => *bounds,
        }
    }
}

struct Builder<'a> {
    bounds: &'a [Aabb],
    centroids: &'a [Vec3],
    opts: Bvh2BuildOptions,
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: usize,
}

impl Default for Bin {
    fn default() -> Self {
        Bin {
            bounds: Aabb::EMPTY,
            count: 0,
        }
    }
}

impl<P: Primitives> Bvh2<P> {
    pub fn build(prims: P) -> Self {
        Self::build_with(prims, Bvh2BuildOptions::default())
    }

    pub fn build_with(prims: P, opts: Bvh2BuildOptions) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let bounds: Vec<Aabb> = (0..n).into_par_iter().map(|i| prims.bounds(i)).collect();
        let centroids: Vec<Vec3> = (0..n).into_par_iter().map(|i| prims.centroid(i)).collect();
        let mut ids: Vec<u32> = (0..n as u32).collect();
        let builder = Builder {
            bounds: &bounds,
            centroids: &centroids,
            opts,
        };
        let mut nodes = Vec::with_capacity(2 * n.max(1));
        if n == 0 {
            nodes.push(Bvh2Node {
                min: [f32::INFINITY; 3],
                first: 0,
                max: [f32::NEG_INFINITY; 3],
                count: 0,
            });
        } else {
            let root = builder.build(&mut ids, 0, 0);
            flatten(&root, &mut nodes);
        }
        let prims = prims.permute(&ids);

        let mut info = AccelInfo {
            name: "bvh2",
            primitives: n,
            nodes: nodes.len(),
            memory_bytes: nodes.len() * std::mem::size_of::<Bvh2Node>()
                + ids.len() * 4
                + prims.memory_bytes(),
            ..Default::default()
        };
        if n > 0 {
            let (leaves, depth, cost) = tree_stats(&nodes, opts);
            info.leaves = leaves;
            info.max_depth = depth;
            info.sah_cost = cost;
        }
        info.build_ms = start.elapsed().as_secs_f64() * 1e3;
        Bvh2 {
            nodes,
            prims,
            prim_ids: ids,
            info,
        }
    }
}

impl Builder<'_> {
    /// Builds the subtree over `ids`, which start at global offset `offset`.
    fn build(&self, ids: &mut [u32], offset: usize, depth: usize) -> BuildNode {
        let n = ids.len();
        let (bounds, cbounds) = self.node_bounds(ids);
        let leaf = || BuildNode::Leaf {
            bounds,
            start: offset,
            count: n,
        };
        if n == 1 {
            return leaf();
        }

        let mut mid = None;
        if depth < MEDIAN_DEPTH && cbounds.extent().max_element() > 0.0 {
            if let Some((axis, split_bin, split_cost)) = self.best_split(ids, &cbounds, &bounds) {
                let leaf_cost = self.opts.intersection_cost * n as f32;
                if n <= self.opts.max_leaf && leaf_cost <= split_cost {
                    return leaf();
                }
                let m = self.partition(ids, &cbounds, axis, split_bin);
                if m > 0 && m < n {
                    mid = Some(m);
                }
            }
        }
        let mid = match mid {
            Some(m) => m,
            None => {
                if n <= self.opts.max_leaf {
                    return leaf();
                }
                // No useful SAH split (identical centroids, or too deep): object median
                // along the widest centroid axis, which always makes progress.
                let axis = cbounds.largest_axis();
                let m = n / 2;
                ids.select_nth_unstable_by(m, |&a, &b| {
                    self.centroids[a as usize][axis].total_cmp(&self.centroids[b as usize][axis])
                });
                m
            }
        };

        let (left_ids, right_ids) = ids.split_at_mut(mid);
        let (left, right) = if n >= PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(left_ids, offset, depth + 1),
                || self.build(right_ids, offset + mid, depth + 1),
            )
        } else {
            (
                self.build(left_ids, offset, depth + 1),
                self.build(right_ids, offset + mid, depth + 1),
            )
        };
        BuildNode::Interior {
            bounds,
            children: Box::new([left, right]),
        }
    }

    fn node_bounds(&self, ids: &[u32]) -> (Aabb, Aabb) {
        let fold = |(mut b, mut c): (Aabb, Aabb), &i: &u32| {
            b = b.union(&self.bounds[i as usize]);
            c.grow(self.centroids[i as usize]);
            (b, c)
        };
        let empty = (Aabb::EMPTY, Aabb::EMPTY);
        if ids.len() >= PARALLEL_THRESHOLD * 4 {
            ids.par_chunks(PARALLEL_THRESHOLD)
                .map(|c| c.iter().fold(empty, fold))
                .reduce(|| empty, |a, b| (a.0.union(&b.0), a.1.union(&b.1)))
        } else {
            ids.iter().fold(empty, fold)
        }
    }

    #[inline]
    fn bin_of(&self, c: f32, lo: f32, scale: f32) -> usize {
        (((c - lo) * scale) as usize).min(self.opts.bins - 1)
    }

    /// Bins centroids on all three axes and sweeps for the cheapest plane.
    /// Returns (axis, first bin of the right side, SAH cost).
    fn best_split(&self, ids: &[u32], cb: &Aabb, bounds: &Aabb) -> Option<(usize, usize, f32)> {
        let nb = self.opts.bins;
        let ext = cb.extent();
        let scale = Vec3::new(
            if ext.x > 0.0 { nb as f32 / ext.x } else { 0.0 },
            if ext.y > 0.0 { nb as f32 / ext.y } else { 0.0 },
            if ext.z > 0.0 { nb as f32 / ext.z } else { 0.0 },
        );
        let fill = |mut bins: Vec<[Bin; 3]>, &i: &u32| {
            let c = self.centroids[i as usize];
            let b = &self.bounds[i as usize];
            for axis in 0..3 {
                let k = self.bin_of(c[axis], cb.min[axis], scale[axis]);
                bins[k][axis].count += 1;
                bins[k][axis].bounds = bins[k][axis].bounds.union(b);
            }
            bins
        };
        let merge = |mut a: Vec<[Bin; 3]>, b: Vec<[Bin; 3]>| {
            for (x, y) in a.iter_mut().zip(b.iter()) {
                for axis in 0..3 {
                    x[axis].count += y[axis].count;
                    x[axis].bounds = x[axis].bounds.union(&y[axis].bounds);
                }
            }
            a
        };
        let empty = || vec![[Bin::default(); 3]; nb];
        let bins = if ids.len() >= PARALLEL_THRESHOLD * 4 {
            ids.par_chunks(PARALLEL_THRESHOLD)
                .map(|c| c.iter().fold(empty(), fill))
                .reduce(empty, merge)
        } else {
            ids.iter().fold(empty(), fill)
        };

        let inv_area = 1.0 / bounds.area().max(f32::MIN_POSITIVE);
        let mut best: Option<(usize, usize, f32)> = None;
        let mut right_area = vec![0.0f32; nb];
        let mut right_count = vec![0usize; nb];
        for axis in 0..3 {
            if scale[axis] == 0.0 {
                continue;
            }
            let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
            for k in (1..nb).rev() {
                acc = acc.union(&bins[k][axis].bounds);
                cnt += bins[k][axis].count;
                right_area[k] = acc.area();
                right_count[k] = cnt;
            }
            let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
            for k in 1..nb {
                acc = acc.union(&bins[k - 1][axis].bounds);
                cnt += bins[k - 1][axis].count;
                if cnt == 0 || right_count[k] == 0 {
                    continue;
                }
                let cost = self.opts.traversal_cost
                    + self.opts.intersection_cost
                        * (acc.area() * cnt as f32 + right_area[k] * right_count[k] as f32)
                        * inv_area;
                if best.is_none_or(|b| cost < b.2) {
                    best = Some((axis, k, cost));
                }
            }
        }
        best
    }

    /// Moves primitives whose centroid bin is below `split_bin` to the front; returns
    /// the count moved.
    fn partition(&self, ids: &mut [u32], cb: &Aabb, axis: usize, split_bin: usize) -> usize {
        let ext = cb.extent()[axis];
        let scale = self.opts.bins as f32 / ext;
        let lo = cb.min[axis];
        let left = |i: u32| self.bin_of(self.centroids[i as usize][axis], lo, scale) < split_bin;
        let (mut i, mut j) = (0, ids.len());
        while i < j {
            if left(ids[i]) {
                i += 1;
            } else {
                j -= 1;
                ids.swap(i, j);
            }
        }
        i
    }
}

/// Flattens the build tree so that siblings are adjacent; the root is node 0.
fn flatten(root: &BuildNode, nodes: &mut Vec<Bvh2Node>) {
    nodes.push(leaf_or_placeholder(root));
    let mut pending = vec![(0usize, root)];
    while let Some((index, node)) = pending.pop() {
        if let BuildNode::Interior { children, .. } = node {
            let first = nodes.len();
            nodes.push(leaf_or_placeholder(&children[0]));
            nodes.push(leaf_or_placeholder(&children[1]));
            nodes[index].first = first as u32;
            pending.push((first + 1, &children[1]));
            pending.push((first, &children[0]));
        }
    }
}

fn leaf_or_placeholder(node: &BuildNode) -> Bvh2Node {
    let b = node.bounds();
    let (first, count) = match node {
        BuildNode::Leaf { start, count, .. } => (*start as u32, *count as u32),
        BuildNode::Interior { .. } => (0, 0),
    };
    Bvh2Node {
        min: b.min.to_array(),
        first,
        max: b.max.to_array(),
        count,
    }
}

/// (leaf count, maximum depth, SAH cost normalised by the root's area).
fn tree_stats(nodes: &[Bvh2Node], opts: Bvh2BuildOptions) -> (usize, usize, f64) {
    let root_area = nodes[0].bounds().area().max(f32::MIN_POSITIVE) as f64;
    let (mut leaves, mut depth, mut cost) = (0, 0, 0.0);
    let mut stack = vec![(0usize, 0usize)];
    while let Some((i, d)) = stack.pop() {
        let node = &nodes[i];
        depth = depth.max(d);
        let rel = node.bounds().area() as f64 / root_area;
        if node.is_leaf() {
            leaves += 1;
            cost += rel * opts.intersection_cost as f64 * node.count as f64;
        } else {
            cost += rel * opts.traversal_cost as f64;
            stack.push((node.first as usize, d + 1));
            stack.push((node.first as usize + 1, d + 1));
        }
    }
    (leaves, depth, cost)
}

impl<P: Primitives> Bvh2<P> {
    #[inline]
    fn node_entry(&self, i: usize, q: &RayQuery, tmax: f32) -> Option<f32> {
        let n = &self.nodes[i];
        n.bounds().intersect(q.origin, q.inv_dir, q.tmin, tmax)
    }

    /// Closest hit on a prepared ray, nearer child first.
    pub fn closest_hit_query(&self, q: &RayQuery) -> Option<Hit> {
        let mut tmax = q.tmax;
        let mut best: Option<Hit> = None;
        self.node_entry(0, q, tmax)?;
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.is_leaf() {
                for k in n.first as usize..(n.first + n.count) as usize {
                    if let Some(h) = self.prims.intersect(k, q, tmax) {
                        tmax = h.t;
                        best = Some(Hit {
                            t: h.t,
                            prim: self.prim_ids[k],
                            u: h.u,
                            v: h.v,
                        });
                    }
                }
            } else {
                let l = n.first as usize;
                let hl = self.node_entry(l, q, tmax);
                let hr = self.node_entry(l + 1, q, tmax);
                match (hl, hr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, l + 1) } else { (l + 1, l) };
                        stack[sp] = far as u32;
                        sp += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = l + 1;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop, skipping nodes that start beyond the current closest hit.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let next = stack[sp] as usize;
                if self.node_entry(next, q, tmax).is_some() {
                    node = next;
                    break;
                }
            }
        }
    }

    /// Any hit in `(tmin, tmax)`: stops at the first one found.
    pub fn any_hit_query(&self, q: &RayQuery) -> bool {
        let tmax = q.tmax;
        if self.node_entry(0, q, tmax).is_none() {
            return false;
        }
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.is_leaf() {
                for k in n.first as usize..(n.first + n.count) as usize {
                    if self.prims.intersect(k, q, tmax).is_some() {
                        return true;
                    }
                }
            } else {
                let l = n.first as usize;
                let hl = self.node_entry(l, q, tmax).is_some();
                let hr = self.node_entry(l + 1, q, tmax).is_some();
                if hl && hr {
                    stack[sp] = (l + 1) as u32;
                    sp += 1;
                    node = l;
                    continue;
                } else if hl || hr {
                    node = if hl { l } else { l + 1 };
                    continue;
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }
}

impl<P: Primitives> Accel for Bvh2<P> {
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_query(&RayQuery::new(ray)?)
    }

    fn any_hit(&self, ray: &Ray) -> bool {
        RayQuery::new(ray).is_some_and(|q| self.any_hit_query(&q))
    }

    fn info(&self) -> AccelInfo {
        self.info.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Triangles;

    fn grid_soup(n: usize) -> Triangles {
        let mut corners = Vec::new();
        for i in 0..n {
            let x = (i % 37) as f32;
            let y = (i / 37) as f32;
            let z = ((i * 7919) % 13) as f32;
            corners.push([
                Vec3::new(x, y, z),
                Vec3::new(x + 0.9, y, z),
                Vec3::new(x, y + 0.9, z + 0.3),
            ]);
        }
        Triangles::from_corners(&corners)
    }

    fn check_invariants<P: Primitives>(bvh: &Bvh2<P>) {
        // Every primitive appears in exactly one leaf and every node bounds its children.
        let mut seen = vec![0u32; bvh.prim_ids.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = bvh.nodes[i];
            if n.is_leaf() {
                for k in n.first..n.first + n.count {
                    seen[bvh.prim_ids[k as usize] as usize] += 1;
                    let pb = bvh.prims.bounds(k as usize);
                    assert_eq!(
                        n.bounds().union(&pb),
                        n.bounds(),
                        "leaf does not bound its primitive"
                    );
                }
            } else {
                for c in [n.first as usize, n.first as usize + 1] {
                    assert_eq!(n.bounds().union(&bvh.nodes[c].bounds()), n.bounds());
                    stack.push(c);
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
    }

    #[test]
    fn structure_is_valid() {
        for n in [1, 2, 7, 100, 5000, 20000] {
            let bvh = Bvh2::build(grid_soup(n));
            check_invariants(&bvh);
            assert!(bvh.info.max_depth < STACK_SIZE);
        }
    }

    #[test]
    fn identical_triangles_terminate_with_bounded_depth() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let bvh = Bvh2::build(Triangles::from_corners(&vec![t; 100_000]));
        check_invariants(&bvh);
        assert!(bvh.info.max_depth <= 20, "depth {}", bvh.info.max_depth);
        assert!(bvh.nodes.len() < 2 * 100_000 / 4);
        let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
        assert_eq!(bvh.closest_hit(&ray).map(|h| h.t), Some(1.0));
    }

    #[test]
    fn empty_and_single() {
        let empty = Bvh2::build(Triangles::default());
        assert!(empty.closest_hit(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
        assert!(!empty.any_hit(&Ray::new(Vec3::ZERO, Vec3::X)));
        let one = Bvh2::build(Triangles::from_corners(&[[Vec3::ZERO, Vec3::X, Vec3::Y]]));
        let h = one
            .closest_hit(&Ray::new(Vec3::new(0.1, 0.1, -2.0), Vec3::Z))
            .unwrap();
        assert_eq!((h.prim, h.t), (0, 2.0));
    }
}
