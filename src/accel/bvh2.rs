use super::filter::{FilterSink, HitFilter, QueryOptions};
use super::{Accel, AccelInfo, Primitives, TraversalCounts};
use crate::geometry::{Aabb, Hit, Ray, RayQuery};
use glam::{BVec3A, Vec3, Vec3A};
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

/// A box in SIMD-friendly form for the builder (`Vec3A`: one register per corner).
#[derive(Clone, Copy, Debug)]
pub(super) struct BBox {
    min: Vec3A,
    max: Vec3A,
}

impl BBox {
    const EMPTY: BBox = BBox {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    #[inline(always)]
    fn grow(&mut self, o: &BBox) {
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
    }

    #[inline(always)]
    fn grow_point(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    #[inline(always)]
    fn union(mut self, o: &BBox) -> BBox {
        self.grow(o);
        self
    }

    #[inline(always)]
    fn area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    fn extent(&self) -> Vec3A {
        (self.max - self.min).max(Vec3A::ZERO)
    }

    fn to_aabb(self) -> Aabb {
        Aabb::new(self.min.into(), self.max.into())
    }
}

/// Intermediate tree of the parallel build: flattened into a BVH2, or collapsed
/// straight into a BVH4.
pub(super) enum BuildNode {
    Leaf {
        bounds: BBox,
        start: usize,
        count: usize,
    },
    Interior {
        bounds: BBox,
        children: Box<[BuildNode; 2]>,
    },
}

impl BuildNode {
    /// Surface area of the node's box.
    pub(super) fn area(&self) -> f32 {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => bounds.area(),
        }
    }

    pub(super) fn bounds(&self) -> Aabb {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => bounds.to_aabb(),
        }
    }
}

struct Builder<'a> {
    bounds: &'a [BBox],
    centroids: &'a [Vec3A],
    opts: Bvh2BuildOptions,
}

/// Most bins per axis the builder supports.
const MAX_BINS: usize = 32;

/// Per-axis bins of one node: bounds and primitive counts.
#[derive(Clone)]
struct Bins {
    bounds: [[BBox; MAX_BINS]; 3],
    counts: [[u32; MAX_BINS]; 3],
}

impl Bins {
    fn new() -> Self {
        Bins {
            bounds: [[BBox::EMPTY; MAX_BINS]; 3],
            counts: [[0; MAX_BINS]; 3],
        }
    }

    fn merge(mut self, o: &Bins) -> Bins {
        for a in 0..3 {
            for k in 0..MAX_BINS {
                self.bounds[a][k].grow(&o.bounds[a][k]);
                self.counts[a][k] += o.counts[a][k];
            }
        }
        self
    }
}

impl Bins {
    /// Empties the first `n` bins of each axis (the only ones a node uses).
    fn clear(&mut self, n: usize) {
        for a in 0..3 {
            self.bounds[a][..n].fill(BBox::EMPTY);
            self.counts[a][..n].fill(0);
        }
    }

    fn add(&mut self, k: [usize; 3], b: &BBox) {
        for (axis, &bin) in k.iter().enumerate() {
            self.counts[axis][bin] += 1;
            self.bounds[axis][bin].grow(b);
        }
    }
}

thread_local! {
    /// Bins reused by every node a thread splits: clearing the bins in use is cheaper
    /// than building 3.5 KB of bins per node, most of which are tiny.
    static SCRATCH_BINS: std::cell::RefCell<Bins> = std::cell::RefCell::new(Bins::new());
    /// Per-thread scratch ids for the partition.
    static SCRATCH_IDS: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Where to split a node: axis, first bin of the right side, bin count, SAH cost.
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    bin: usize,
    bins: usize,
    cost: f32,
}

/// A node's bounds and its centroids' bounds, passed from parent to child so that
/// no pass over the primitives is spent recomputing them.
#[derive(Clone, Copy)]
struct NodeBounds {
    bounds: BBox,
    centroids: BBox,
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

/// The binned-SAH build itself: the tree (`None` for no primitives) and the primitive
/// order its leaf ranges index.
pub(super) fn build_tree<P: Primitives>(
    prims: &P,
    opts: Bvh2BuildOptions,
) -> (Option<BuildNode>, Vec<u32>) {
    {
        assert!(
            opts.bins >= 2 && opts.bins <= MAX_BINS,
            "bins must be in 2..={MAX_BINS}"
        );
        let n = prims.count();
        let bounds: Vec<BBox> = (0..n)
            .into_par_iter()
            .map(|i| {
                let b = prims.bounds(i);
                BBox {
                    min: b.min.into(),
                    max: b.max.into(),
                }
            })
            .collect();
        let centroids: Vec<Vec3A> = (0..n)
            .into_par_iter()
            .map(|i| prims.centroid(i).into())
            .collect();
        let mut ids: Vec<u32> = (0..n as u32).collect();
        let builder = Builder {
            bounds: &bounds,
            centroids: &centroids,
            opts,
        };
        if n == 0 {
            return (None, ids);
        }
        let nb = builder.node_bounds(&ids);
        let root = builder.build(&mut ids, 0, 0, nb);
        (Some(root), ids)
    }
}

impl Builder<'_> {
    /// Builds the subtree over `ids`, which start at global offset `offset`.
    fn build(&self, ids: &mut [u32], offset: usize, depth: usize, nb: NodeBounds) -> BuildNode {
        let n = ids.len();
        let leaf = || BuildNode::Leaf {
            bounds: nb.bounds,
            start: offset,
            count: n,
        };
        if n == 1 {
            return leaf();
        }
        // Any split costs at least `traversal_cost` (the area terms are not negative), so
        // a leaf that costs no more is the SAH's answer without binning: the same tree,
        // and a third fewer nodes binned for 4-wide leaves (every 1-4 triangle leaf).
        if n <= self.opts.max_leaf
            && self.opts.intersection_cost * self.blocks(n as u32) <= self.opts.traversal_cost
        {
            return leaf();
        }

        let mut split = None;
        let sah = depth < MEDIAN_DEPTH && nb.centroids.extent().max_element() > 0.0;
        if let Some(s) = sah.then(|| self.best_split(ids, &nb)).flatten() {
            let leaf_cost = self.opts.intersection_cost * self.blocks(n as u32);
            if n <= self.opts.max_leaf && leaf_cost <= s.cost {
                return leaf();
            }
            let (m, left, right) = self.partition(ids, &nb.centroids, s);
            if m > 0 && m < n {
                split = Some((m, left, right));
            }
        }
        let (mid, left, right) = match split {
            Some(s) => s,
            None => {
                if n <= self.opts.max_leaf {
                    return leaf();
                }
                // No useful SAH split (identical centroids, or too deep): object median
                // along the widest centroid axis, which always makes progress.
                let e = nb.centroids.extent();
                let axis = if e.x >= e.y && e.x >= e.z {
                    0
                } else if e.y >= e.z {
                    1
                } else {
                    2
                };
                let m = n / 2;
                ids.select_nth_unstable_by(m, |&a, &b| {
                    self.centroids[a as usize][axis].total_cmp(&self.centroids[b as usize][axis])
                });
                (m, self.node_bounds(&ids[..m]), self.node_bounds(&ids[m..]))
            }
        };

        let (left_ids, right_ids) = ids.split_at_mut(mid);
        let (l, r) = if n >= PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(left_ids, offset, depth + 1, left),
                || self.build(right_ids, offset + mid, depth + 1, right),
            )
        } else {
            (
                self.build(left_ids, offset, depth + 1, left),
                self.build(right_ids, offset + mid, depth + 1, right),
            )
        };
        BuildNode::Interior {
            bounds: nb.bounds,
            children: Box::new([l, r]),
        }
    }

    fn node_bounds(&self, ids: &[u32]) -> NodeBounds {
        let fold = |mut acc: NodeBounds, &i: &u32| {
            acc.bounds.grow(&self.bounds[i as usize]);
            acc.centroids.grow_point(self.centroids[i as usize]);
            acc
        };
        let empty = NodeBounds {
            bounds: BBox::EMPTY,
            centroids: BBox::EMPTY,
        };
        if ids.len() >= PARALLEL_THRESHOLD * 4 {
            ids.par_chunks(PARALLEL_THRESHOLD)
                .map(|c| c.iter().fold(empty, fold))
                .reduce(
                    || empty,
                    |a, b| NodeBounds {
                        bounds: a.bounds.union(&b.bounds),
                        centroids: a.centroids.union(&b.centroids),
                    },
                )
        } else {
            ids.iter().fold(empty, fold)
        }
    }

    /// Leaf test units for `n` primitives: started blocks of `block_size`.
    #[inline(always)]
    fn blocks(&self, n: u32) -> f32 {
        n.div_ceil(self.opts.block_size.max(1) as u32) as f32
    }

    /// Bin indices of a centroid on all three axes at once.
    #[inline(always)]
    fn bins_of(c: Vec3A, lo: Vec3A, scale: Vec3A, bins: usize) -> [usize; 3] {
        // Clamped on both sides, and min/max return the non-NaN operand, so every lane is
        // finite and in [0, bins - 1] even for a NaN centroid.
        let k = ((c - lo) * scale)
            .max(Vec3A::ZERO)
            .min(Vec3A::splat((bins - 1) as f32));
        // SAFETY: `to_int_unchecked` needs a finite value that fits the target type, which
        // the clamp above guarantees. The checked `as` cast saturates and tests for NaN on
        // every call, and cost 15 % of the build's instructions here.
        unsafe {
            [
                k.x.to_int_unchecked::<u32>() as usize,
                k.y.to_int_unchecked::<u32>() as usize,
                k.z.to_int_unchecked::<u32>() as usize,
            ]
        }
    }

    fn scale(cb: &BBox, bins: usize) -> Vec3A {
        let e = cb.extent();
        Vec3A::select(
            e.cmpgt(Vec3A::ZERO),
            Vec3A::splat(bins as f32) / e,
            Vec3A::ZERO,
        )
    }

    /// Bins centroids on all three axes and sweeps for the cheapest plane.
    fn best_split(&self, ids: &[u32], nb: &NodeBounds) -> Option<Split> {
        // Small nodes need few bins: at most two per primitive.
        let bins_n = self.opts.bins.min(ids.len().max(4));
        let cb = &nb.centroids;
        let scale = Self::scale(cb, bins_n);
        if ids.len() >= PARALLEL_THRESHOLD * 4 {
            let bins = ids
                .par_chunks(PARALLEL_THRESHOLD)
                .map(|chunk| {
                    let mut bins = Bins::new();
                    for &i in chunk {
                        let k = Self::bins_of(self.centroids[i as usize], cb.min, scale, bins_n);
                        bins.add(k, &self.bounds[i as usize]);
                    }
                    bins
                })
                .reduce(Bins::new, |a, b| a.merge(&b));
            self.sweep(&bins, bins_n, nb)
        } else {
            SCRATCH_BINS.with_borrow_mut(|bins| {
                bins.clear(bins_n);
                for &i in ids {
                    let k = Self::bins_of(self.centroids[i as usize], cb.min, scale, bins_n);
                    bins.add(k, &self.bounds[i as usize]);
                }
                self.sweep(bins, bins_n, nb)
            })
        }
    }

    /// The SAH sweep over filled bins: the cheapest plane on any axis.
    fn sweep(&self, bins: &Bins, bins_n: usize, nb: &NodeBounds) -> Option<Split> {
        let scale = Self::scale(&nb.centroids, bins_n);

        let inv_area = 1.0 / nb.bounds.area().max(f32::MIN_POSITIVE);
        let mut best: Option<Split> = None;
        let mut right_area = [0.0f32; MAX_BINS];
        let mut right_count = [0u32; MAX_BINS];
        for axis in 0..3 {
            if scale[axis] == 0.0 {
                continue;
            }
            let (mut acc, mut cnt) = (BBox::EMPTY, 0);
            for k in (1..bins_n).rev() {
                acc.grow(&bins.bounds[axis][k]);
                cnt += bins.counts[axis][k];
                right_area[k] = acc.area();
                right_count[k] = cnt;
            }
            let (mut acc, mut cnt) = (BBox::EMPTY, 0);
            for k in 1..bins_n {
                acc.grow(&bins.bounds[axis][k - 1]);
                cnt += bins.counts[axis][k - 1];
                if cnt == 0 || right_count[k] == 0 {
                    continue;
                }
                let cost = self.opts.traversal_cost
                    + self.opts.intersection_cost
                        * (acc.area() * self.blocks(cnt)
                            + right_area[k] * self.blocks(right_count[k]))
                        * inv_area;
                if best.is_none_or(|b| cost < b.cost) {
                    best = Some(Split {
                        axis,
                        bin: k,
                        bins: bins_n,
                        cost,
                    });
                }
            }
        }
        best
    }

    /// Moves primitives whose centroid bin is below the split bin to the front, and
    /// gathers both sides' bounds on the way. Returns the count moved and the bounds.
    ///
    /// Branch-free (which side a primitive goes to is a coin flip to the branch
    /// predictor): each id is written to both the next left and the next right slot of a
    /// scratch array and only one cursor advances, and each side's boxes grow by a
    /// box that is empty for the other side's primitives. Left keeps the input order,
    /// right reverses it.
    fn partition(&self, ids: &mut [u32], cb: &BBox, s: Split) -> (usize, NodeBounds, NodeBounds) {
        let scale = Self::scale(cb, s.bins);
        let mut left = NodeBounds {
            bounds: BBox::EMPTY,
            centroids: BBox::EMPTY,
        };
        let mut right = left;
        let n = ids.len();
        let moved = SCRATCH_IDS.with_borrow_mut(|tmp| {
            // Every slot is written before the copy back (left from the front, right from
            // the back, meeting where the last id lands), so it only has to be long enough.
            if tmp.len() < n {
                tmp.resize(n, 0);
            }
            let tmp = &mut tmp[..n];
            let (mut lo, mut hi) = (0usize, n);
            for &id in ids.iter() {
                let c = self.centroids[id as usize];
                let b = &self.bounds[id as usize];
                let goes_left = Self::bins_of(c, cb.min, scale, s.bins)[s.axis] < s.bin;
                // lo < hi here: fewer than n ids are placed
                tmp[lo] = id;
                tmp[hi - 1] = id;
                lo += usize::from(goes_left);
                hi -= usize::from(!goes_left);
                let (l, r) = (BVec3A::splat(goes_left), BVec3A::splat(!goes_left));
                let inf = Vec3A::splat(f32::INFINITY);
                left.bounds.min = left.bounds.min.min(Vec3A::select(l, b.min, inf));
                left.bounds.max = left.bounds.max.max(Vec3A::select(l, b.max, -inf));
                left.centroids.min = left.centroids.min.min(Vec3A::select(l, c, inf));
                left.centroids.max = left.centroids.max.max(Vec3A::select(l, c, -inf));
                right.bounds.min = right.bounds.min.min(Vec3A::select(r, b.min, inf));
                right.bounds.max = right.bounds.max.max(Vec3A::select(r, b.max, -inf));
                right.centroids.min = right.centroids.min.min(Vec3A::select(r, c, inf));
                right.centroids.max = right.centroids.max.max(Vec3A::select(r, c, -inf));
            }
            ids.copy_from_slice(tmp);
            lo
        });
        (moved, left, right)
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
