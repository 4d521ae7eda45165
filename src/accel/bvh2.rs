use super::filter::{FilterSink, HitFilter, QueryOptions};
use super::sah_build::{BuildNode, build_tree};
use super::{Accel, AccelInfo, Primitives, TraversalCounts};
use crate::geometry::{Aabb, Hit, Ray, RayQuery};
use glam::Vec3;
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
    /// Primitives tested together by one SIMD leaf test: the SAH charges a leaf per
    /// started block of this many (Embree's "SAH block size"), so leaves fill their
    /// lanes instead of splitting down to one triangle per 4-lane group.
    pub block_size: usize,
}

impl Default for Bvh2BuildOptions {
    fn default() -> Self {
        Bvh2BuildOptions {
            bins: 32,
            max_leaf: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            block_size: 1,
        }
    }
}

/// Traversal stack size: at most one entry per level is pending (the builder's median
/// fallback past `sah_build::MEDIAN_DEPTH` keeps every tree below it).
pub const STACK_SIZE: usize = 128;

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

impl<P: Primitives> Bvh2<P> {
    pub fn build(prims: P) -> Self {
        Self::build_with(prims, Bvh2BuildOptions::default())
    }

    pub fn build_with(prims: P, opts: Bvh2BuildOptions) -> Self {
        let start = Instant::now();
        let n = prims.count();
        let (root, ids) = build_tree(&prims, opts);
        let mut nodes = Vec::with_capacity(2 * n.max(1));
        match root {
            None => nodes.push(Bvh2Node {
                min: [f32::INFINITY; 3],
                first: 0,
                max: [f32::NEG_INFINITY; 3],
                count: 0,
            }),
            Some(root) => flatten(&root, &mut nodes),
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
        BuildNode::Leaf { start, count, .. } => (*start, *count),
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
        let mut sink = Nearest {
            tmax: q.tmax,
            best: None,
        };
        self.closest_hit_impl::<false, _>(q, &mut sink, &mut TraversalCounts::default());
        sink.best
    }

    /// The closest-hit traversal, nearer child first, shared by the plain query
    /// ([`Nearest`]) and the filtered one ([`FilterSink`], [`super::filter`]): the
    /// interval ends at `sink.tmax()`, which only the sink shortens. Each primitive is in
    /// one leaf, so no deduplication is needed. `COUNT` adds node visits and primitive
    /// tests to `counts`.
    #[inline(always)]
    fn closest_hit_impl<const COUNT: bool, S: LeafVisitor>(
        &self,
        q: &RayQuery,
        sink: &mut S,
        counts: &mut TraversalCounts,
    ) {
        if self.node_entry(0, q, sink.tmax()).is_none() {
            return;
        }
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            counts.node::<COUNT>();
            let n = &self.nodes[node];
            if n.is_leaf() {
                for k in n.first as usize..(n.first + n.count) as usize {
                    counts.prim::<COUNT>();
                    if sink.visit(&self.prims, k, self.prim_ids[k], q) {
                        return;
                    }
                }
            } else {
                let l = n.first as usize;
                let hl = self.node_entry(l, q, sink.tmax());
                let hr = self.node_entry(l + 1, q, sink.tmax());
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
                    return;
                }
                sp -= 1;
                let next = stack[sp] as usize;
                if self.node_entry(next, q, sink.tmax()).is_some() {
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

    fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut HitFilter<'_>,
    ) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        let mut sink = FilterSink::new(&q, opts, filter);
        self.closest_hit_impl::<false, _>(&q, &mut sink, &mut TraversalCounts::default());
        sink.best
    }

    fn traversal_counts(&self, ray: &Ray) -> Option<TraversalCounts> {
        let mut counts = TraversalCounts::default();
        if let Some(q) = RayQuery::new(ray) {
            let mut sink = Nearest {
                tmax: q.tmax,
                best: None,
            };
            self.closest_hit_impl::<true, _>(&q, &mut sink, &mut counts);
        }
        Some(counts)
    }

    fn info(&self) -> AccelInfo {
        self.info.clone()
    }
}

/// What [`Bvh2::closest_hit_impl`] does with a leaf's primitive.
trait LeafVisitor {
    /// The current end of the ray's interval.
    fn tmax(&self) -> f32;
    /// Tests leaf slot `k` (the scene's primitive `id`); true ends the traversal.
    fn visit<P: Primitives>(&mut self, prims: &P, k: usize, id: u32, q: &RayQuery) -> bool;
}

/// The plain closest-hit query: keeps the nearest hit and shortens the interval to it.
struct Nearest {
    tmax: f32,
    best: Option<Hit>,
}

impl LeafVisitor for Nearest {
    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.tmax
    }

    #[inline(always)]
    fn visit<P: Primitives>(&mut self, prims: &P, k: usize, id: u32, q: &RayQuery) -> bool {
        if let Some(h) = prims.intersect(k, q, self.tmax) {
            self.tmax = h.t;
            self.best = Some(Hit {
                t: h.t,
                prim: id,
                u: h.u,
                v: h.v,
            });
        }
        false
    }
}

impl LeafVisitor for FilterSink<'_, '_> {
    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.tmax
    }

    #[inline(always)]
    fn visit<P: Primitives>(&mut self, prims: &P, k: usize, id: u32, q: &RayQuery) -> bool {
        self.test(prims, k, id, q)
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
