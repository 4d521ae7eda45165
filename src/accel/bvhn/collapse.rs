//! The collapse of a binned-SAH BVH2 into N-wide nodes (greedy, largest area opened
//! first: Wald et al. 2008, "Getting Rid of Packets"), with triangle leaves packed
//! into groups of four.

use super::node::{BvhNode, COUNT_SHIFT, EMPTY_CHILD, FIRST_MASK, LEAF};
use crate::accel::Triangles;
use crate::accel::sah_build::{BuildNode, SpareRefs};
use crate::pages::LargeVec;
use crate::simd::kernels::TriGroup4;
use crate::simd::prefetch::prefetch;
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Levels of the collapse that hand their children's subtrees to separate threads (at
/// most N^2 tasks): the collapse was 13 % of a serial build (4 of 30 ms on the bunny).
pub(super) const PARALLEL_COLLAPSE_LEVELS: usize = 2;

pub(super) struct Collapse<'a, const N: usize> {
    pub(super) ids: &'a [u32],
    pub(super) triangles: Option<&'a Triangles>,
    pub(super) nodes: LargeVec<BvhNode<N>>,
    pub(super) groups: LargeVec<TriGroup4>,
}

/// Triangle leaves met by the node pass of a collapse, in the order their groups are
/// laid out, and the groups they take; [`Collapse::collapse`] fills the groups after
/// the nodes.
#[derive(Default)]
struct PendingLeaves {
    /// Per leaf, its range of the primitive order: first position and count.
    leaves: Vec<(u32, u32)>,
    groups: usize,
}

/// Leaves ahead of the one being gathered whose triangles are prefetched.
const GATHER_AHEAD: usize = 8;

impl<const N: usize> Collapse<'_, N> {
    /// [`Collapse::collapse_recycling`] without spare memory.
    #[cfg(test)]
    pub(super) fn collapse(&mut self, node: &BuildNode, parallel_levels: usize) -> u32 {
        self.collapse_recycling(node, parallel_levels, None)
    }

    /// The node reference for a build subtree: its two children, then the child with
    /// the largest area opened until there are N. The top `parallel_levels` levels
    /// collapse their children's subtrees in parallel.
    ///
    /// Two passes: the nodes first, recording each triangle leaf's range and giving it
    /// the next group indices; then the groups in one flat loop over those leaves
    /// (their triangles prefetched [`GATHER_AHEAD`] leaves ahead), with the same
    /// arrays as a gather inside the recursion. Measured (perf, 1 thread, 10^6
    /// triangles): the collapse was 9.5 % of a build, most of it waiting on the
    /// triangles' corners and on the build nodes, the gather one leaf at a time
    /// behind the tree walk.
    ///
    /// Where the groups array is still unallocated, the gather makes it in `spare`'s
    /// memory (sized once the node pass has counted the groups), not in fresh pages.
    pub(super) fn collapse_recycling(
        &mut self,
        node: &BuildNode,
        parallel_levels: usize,
        spare: Option<SpareRefs>,
    ) -> u32 {
        if parallel_levels > 0 {
            return self.collapse_parallel(node, parallel_levels, spare);
        }
        let mut pending = PendingLeaves {
            leaves: Vec::new(),
            groups: self.groups.len(),
        };
        let root = self.collapse_nodes(node, &mut pending);
        if let Some(tris) = self.triangles {
            self.gather(tris, &pending.leaves, spare);
        }
        root
    }

    /// [`Collapse::collapse_recycling`] with the top `levels` levels' subtrees
    /// collapsed by separate tasks, each writing its part of the final arrays.
    ///
    /// The top levels are laid out first ([`Top`], in the serial layout's order: a
    /// node, then each child's subtree); every subtree below them is one task. A
    /// first parallel pass counts each task's nodes and groups ([`count`]: the walk of
    /// the node pass without its writes), which gives each one's first node and first
    /// group in the final arrays; these are sized once, and the tasks, in parallel
    /// again, run their node pass straight into their range (references final from
    /// the start) and gather their groups into theirs.
    ///
    /// Before (issue 12, helper bd25, 2026-11-29): each child's subtree collapsed into
    /// arrays of its own (grown by doubling), and the parts were appended one after
    /// the other into their parent's arrays, at both parallel levels, so nodes and
    /// groups (42 MB at 10^6) were copied twice and the top copy ran on one thread;
    /// and the groups' array was sized by a walk of the whole build tree first (the
    /// parallel parts could not count it). Phase timers at 10^6 (`build_time 1000000 5
    /// N`, load ~4): the parallel collapse took 125-134 ms against 69-77 ms serial.
    ///
    /// Then (sessions 25-27, until bc28): the tasks' node passes ran into arrays of
    /// their own (a `LargeVec` with room for a node per four primitives, huge pages
    /// from 4 MiB), which gave their counts, and each task then copied its nodes into
    /// its range of the final array, moving every reference by the range's start. At
    /// 10^7 triangles and 2 threads (`perf record -e cpu-clock` of `build_time
    /// 10000000 3 2`, quiet host, session 28) the collapse took 0.6 s of a 2.1 s build,
    /// most of it `clear_page_erms` zeroing fresh pages: 64 task arrays of ~10 MB
    /// (two huge pages written in each; only four dropped mappings are kept,
    /// `pages::array::KEEP`) and a fresh 214 MB final node array (the kept slots were
    /// taken by the task arrays when the previous tree was dropped), then 214 MB
    /// copied. The counting walk costs ~60 ms of the two threads at 10^7 (perf); the
    /// collapse phase went from 0.6 to 0.35 s.
    ///
    /// Measured with the session's other page changes (the ids array advised, the
    /// arena's chunks kept, the smaller scratch array advised before it is zeroed;
    /// issue 12, bc28, session 28, AVX-512, interleaved against /tmp/base28, CPU ms
    /// per build, min / median / max of the rounds' medians): `build_time 10000000 3 2`
    /// quiet (load 1.6-2.0, 10 rounds) 3,258 / 3,524 / 3,767 -> 3,240 / 3,590 / 3,684,
    /// level (wall 1,816 -> 1,848 ms median), but under load (3.1-3.8, 4 rounds, one
    /// core for the build) 3,210 / 3,434 / 3,518 -> 3,115 / 3,205 / 3,378, and page
    /// faults per build 6.3-11k -> 1.1-2.1k (the slow host state makes each 5-40 us);
    /// `build_time 1000000 5 2` (3 rounds, load 1.6) 308 / 310 / 313 -> 285 / 286 / 287,
    /// wall 166 -> 149 ms; `build_time 1000000 5 1` 277 / 287 / 287 -> 250 / 256 / 262;
    /// `build_time 100000 20 2` 21.6 / 21.9 / 22.0 -> 20.7 / 21.4 / 21.6.
    fn collapse_parallel(
        &mut self,
        node: &BuildNode,
        levels: usize,
        spare: Option<SpareRefs>,
    ) -> u32 {
        let mut items = Vec::new();
        plan::<N>(node, levels, &mut items);
        let (ids, triangles) = (self.ids, self.triangles);
        let has_groups = triangles.is_some();
        // Each item's node and group count: one node for a top node, the collapse's
        // counts for a task's subtree.
        let counts: Vec<(usize, usize)> = items
            .par_iter()
            .with_max_len(1)
            .map(|item| match item {
                Top::Node { .. } => (1, 0),
                Top::Task(t) => count::<N>(t, has_groups),
            })
            .collect();
        // Each item's first node and first group, in layout order.
        let (node_start, group_start) = (self.nodes.len(), self.groups.len());
        let mut bases = Vec::with_capacity(items.len());
        let (mut nb, mut gb) = (node_start, group_start);
        for &(nodes, groups) in &counts {
            bases.push((nb, gb));
            nb += nodes;
            gb += groups;
        }
        if has_groups
            && self.groups.capacity() == 0
            && let Some(spare) = spare
        {
            self.groups = LargeVec::from_vec(spare.into_vec(gb - group_start));
        }
        self.nodes.reserve(nb - node_start);
        self.groups.reserve(gb - group_start);
        // Every item's ranges of the arrays' spare room, split off in layout order:
        // the tasks' ranges handed to them, the top nodes written once their
        // children's references are known.
        let mut node_room = &mut self.nodes.spare_capacity_mut()[..nb - node_start];
        let mut group_room = &mut self.groups.spare_capacity_mut()[..gb - group_start];
        let mut tasks = Vec::new();
        let mut tops = Vec::new();
        for (i, (item, &(nodes_here, groups_here))) in items.iter().zip(&counts).enumerate() {
            let (node_out, rest) = std::mem::take(&mut node_room).split_at_mut(nodes_here);
            node_room = rest;
            let (group_out, rest) = std::mem::take(&mut group_room).split_at_mut(groups_here);
            group_room = rest;
            match item {
                Top::Node { .. } => tops.push((i, node_out)),
                Top::Task(t) => tasks.push((i, *t, bases[i], node_out, group_out)),
            }
        }
        // Each task's root reference, by item.
        let roots: Vec<(usize, u32)> = tasks
            .into_par_iter()
            .with_max_len(1)
            .map(|(i, t, base, node_out, group_out)| {
                let mut sink = SliceNodes {
                    out: node_out,
                    used: 0,
                    base: base.0,
                };
                let mut pending = PendingLeaves {
                    leaves: Vec::new(),
                    groups: base.1,
                };
                let root = collapse_nodes(t, triangles.is_some(), &mut sink, &mut pending);
                assert_eq!(sink.used, sink.out.len(), "every counted node written");
                if let Some(tris) = triangles {
                    let mut out = group_out.iter_mut();
                    for_each_group(tris, ids, &pending.leaves, |g| {
                        out.next().expect("room for every group").write(g);
                    });
                    assert!(out.next().is_none(), "every counted group written");
                }
                (i, root)
            })
            .collect();
        let mut refs: Vec<u32> = bases.iter().map(|b| b.0 as u32).collect();
        for (i, r) in roots {
            refs[i] = r;
        }
        for (i, node_out) in tops {
            let Top::Node { kids, n, items } = &items[i] else {
                unreachable!("top nodes only")
            };
            node_out[0].write(wide_node(&kids[..*n], |slot| refs[items[slot]]));
        }
        // SAFETY: the first `nb - node_start` and `gb - group_start` slots of the
        // arrays' spare room were split into the items' ranges above, in order and with
        // nothing left over; each top node's one-slot range was written in the loop
        // just above, and each task wrote every slot of its node range and of its group
        // range (asserted: as many nodes and groups as its counts).
        unsafe {
            self.nodes.set_len(nb);
            self.groups.set_len(gb);
        }
        refs[0]
    }

    /// Fills the groups of `leaves` (in order) from `tris`; an unallocated groups
    /// array is made in `spare`'s memory.
    fn gather(&mut self, tris: &Triangles, leaves: &[(u32, u32)], spare: Option<SpareRefs>) {
        let ids = self.ids;
        let blocks: usize = leaves.iter().map(|l| (l.1 as usize).div_ceil(4)).sum();
        if self.groups.capacity() == 0
            && let Some(spare) = spare
        {
            self.groups = LargeVec::from_vec(spare.into_vec(blocks));
        }
        self.groups.reserve(blocks);
        // Tried, no measurable win, reverted (issue 12, big21, 2026-11-28, commit a8aec4c
        // on branch big21): the groups array made to start on a cache line. A group is
        // 160 bytes aligned to 16, and this array (a large `malloc` block, or the build's
        // reference array taken over by `realloc`) starts 16 bytes past a page, so every
        // second group starts 48 bytes into a line and spans four lines instead of three
        // (its ids, read by the packet leaf loop first, in the fourth, which the
        // traversals' three-line prefetch of a group does not reach). A `TriGroups`
        // type stored the groups in 16-byte chunks behind up to three skipped ones (the
        // spare reference memory still used) and read as `[TriGroup4]`; same checksums,
        // 30 images identical. Interleaved `bench --threads 1 --reps 5` against the
        // session's base, AVX-512, load 5-7 (`cpu` 0.2-0.7), Mrays per CPU-second,
        // medians, base / aligned: 10^6 bvh8-packet primary 17.35 / 18.56 (7 rounds),
        // 17.66 / 17.11 (6), 17.73 / 17.41 (8); shadow 7.06 / 6.75, 5.89 / 6.16, 5.95 /
        // 6.91; bvh8-stream diffuse 2.96 / 2.69, 2.59 / 2.57; bunny bvh8-packet primary
        // 37.67 / 33.82, bvh8-stream diffuse 3.73 / 4.09 (5). The L2's adjacent-line
        // prefetch (lines in aligned pairs) likely brings the fourth line with the third.
        // Dead end (build5, 2026-11-24): advising the groups' fresh pages to be huge pages
        // (madvise) halved the page faults of a 10^6 build (17,547 -> 8,349) but not its
        // CPU time: 1 thread, load 8-12, CPU ms per build, interleaved rounds' medians:
        // without 612 / 431 / 468, with 505 / 679 / 498; against the build before the
        // two-pass collapse, seven rounds 551..596 (median 542) before, 498..679 (median
        // 610) with the advice. Removed.
        // Again (big19, 2026-11-28), with the node array advised too (both arrays' fresh
        // pages): faults per 10^6 build 17,548 -> 2,744, but CPU ms per build (`build_time
        // 1000000 3 1`, 1 thread, load 4-5, 6 interleaved rounds, medians) 391/513/418/
        // 468/399/555 without against 474/482/432/731/499/455 with: huge pages are zeroed
        // (and compacted, `defrag` is `madvise` here) on the fault, so the per-4 KiB fault
        // cost saved is spent there. bvh8-packet 10^6 traversal with the tree in huge pages
        // (`stream_profile /tmp/m1e6.obj bvh8-packet W 5`, Mrays/s, 5 rounds): primary
        // 12.14/12.49/11.79/11.56/12.57 without, 12.31/12.97/12.29/11.88/12.64 with (+1-4 %),
        // shadow 4.37/3.92/4.05/4.22/3.94 without, 3.83/3.62/4.41/3.66/4.33 with: not taken.
        let groups = &mut self.groups;
        for_each_group(tris, ids, leaves, |g| groups.push(g));
    }

    fn collapse_nodes(&mut self, node: &BuildNode, pending: &mut PendingLeaves) -> u32 {
        collapse_nodes(node, self.triangles.is_some(), &mut self.nodes, pending)
    }
}

/// Where a node pass writes its nodes: a node's index is claimed before its children's
/// (the serial layout: a node, then each child's subtree) and its value put there once
/// they are done.
trait NodeSink<const N: usize> {
    /// The next node's index in the final array.
    fn claim(&mut self) -> usize;
    fn put(&mut self, index: usize, node: BvhNode<N>);
}

/// The serial pass pushes onto the whole array.
impl<const N: usize> NodeSink<N> for LargeVec<BvhNode<N>> {
    #[inline(always)]
    fn claim(&mut self) -> usize {
        let index = self.len();
        self.push(BvhNode::EMPTY);
        index
    }

    #[inline(always)]
    fn put(&mut self, index: usize, node: BvhNode<N>) {
        self[index] = node;
    }
}

/// A parallel task's range of the final array's room (`out`, starting at node `base`),
/// of which the first `used` slots are claimed.
struct SliceNodes<'o, const N: usize> {
    out: &'o mut [MaybeUninit<BvhNode<N>>],
    used: usize,
    base: usize,
}

impl<const N: usize> NodeSink<N> for SliceNodes<'_, N> {
    #[inline(always)]
    fn claim(&mut self) -> usize {
        assert!(self.used < self.out.len(), "more nodes than counted");
        self.used += 1;
        self.base + self.used - 1
    }

    #[inline(always)]
    fn put(&mut self, index: usize, node: BvhNode<N>) {
        self.out[index - self.base].write(node);
    }
}

/// The node pass over `node`'s subtree: its nodes into `sink`, its triangle leaves
/// (`groups`; else scalar leaves, which index the primitive order directly) recorded
/// in `pending` with the next group indices; returns its reference.
fn collapse_nodes<const N: usize>(
    node: &BuildNode,
    groups: bool,
    sink: &mut impl NodeSink<N>,
    pending: &mut PendingLeaves,
) -> u32 {
    let BuildNode::Interior { children, .. } = node else {
        let BuildNode::Leaf { start, count, .. } = node else {
            unreachable!()
        };
        return leaf(*start as usize, *count as usize, groups, pending);
    };
    let (kids, n) = open_children::<N>(children);
    let kids = &kids[..n];
    let index = sink.claim();
    let mut refs = [EMPTY_CHILD; N];
    for (slot, k) in kids.iter().enumerate() {
        refs[slot] = collapse_nodes(k, groups, sink, pending);
    }
    sink.put(index, wide_node(kids, |slot| refs[slot]));
    index as u32
}

/// What [`collapse_nodes`] makes of `node`'s subtree, counted without writing it:
/// (nodes, triangle groups; none for scalar leaves, `groups` false).
fn count<const N: usize>(node: &BuildNode, groups: bool) -> (usize, usize) {
    match node {
        BuildNode::Leaf { count, .. } => (
            0,
            if groups {
                count.div_ceil(4) as usize
            } else {
                0
            },
        ),
        BuildNode::Interior { children, .. } => {
            let (kids, n) = open_children::<N>(children);
            let mut total = (1, 0);
            for k in &kids[..n] {
                let (nodes, g) = count::<N>(k, groups);
                total.0 += nodes;
                total.1 += g;
            }
            total
        }
    }
}

/// A leaf's reference; a triangle leaf (`groups`) takes the next group indices and is
/// recorded in `pending` for [`Collapse::gather`].
fn leaf(first: usize, count: usize, groups: bool, pending: &mut PendingLeaves) -> u32 {
    if !groups {
        assert!(
            count < 16 && first <= FIRST_MASK as usize,
            "leaf exceeds the reference encoding"
        );
        return LEAF | (count as u32) << COUNT_SHIFT | first as u32;
    }
    let start = pending.groups;
    let ngroups = count.div_ceil(4);
    assert!(
        ngroups < 16 && start <= FIRST_MASK as usize,
        "leaf exceeds the reference encoding"
    );
    // `first + count` is at most the primitive count, below 2^32 (the builder's
    // limit).
    pending.leaves.push((first as u32, count as u32));
    pending.groups += ngroups;
    LEAF | (ngroups as u32) << COUNT_SHIFT | start as u32
}

/// The N-wide node over the build nodes `kids` (at most N): their boxes as the slots'
/// planes, slot `i`'s reference `child(i)`, the other slots empty.
#[inline(always)]
fn wide_node<const N: usize>(kids: &[&BuildNode], child: impl Fn(usize) -> u32) -> BvhNode<N> {
    let mut node = BvhNode::EMPTY;
    for (slot, k) in kids.iter().enumerate() {
        let b = k.bounds();
        for a in 0..3 {
            node.planes[a][slot] = b.min[a];
            node.planes[a + 3][slot] = b.max[a];
        }
        node.children[slot] = child(slot);
    }
    node
}

/// The groups of `leaves` (ranges of `ids`, in order) from `tris`, handed to `put` in
/// order; the triangles of the leaf [`GATHER_AHEAD`] ahead are prefetched.
#[inline(always)]
fn for_each_group(
    tris: &Triangles,
    ids: &[u32],
    leaves: &[(u32, u32)],
    mut put: impl FnMut(TriGroup4),
) {
    for (i, &(first, count)) in leaves.iter().enumerate() {
        if let Some(&(f, c)) = leaves.get(i + GATHER_AHEAD) {
            for &id in &ids[f as usize..(f + c) as usize] {
                let k = id as usize;
                prefetch(&tris.v0[k], 1);
                prefetch(&tris.v1[k], 1);
                prefetch(&tris.v2[k], 1);
            }
        }
        for chunk in ids[first as usize..(first + count) as usize].chunks(4) {
            let mut g = TriGroup4::EMPTY;
            for (lane, &id) in chunk.iter().enumerate() {
                let k = id as usize;
                g.set(lane, id, [tris.v0[k], tris.v1[k], tris.v2[k]]);
            }
            put(g);
        }
    }
}

/// One item of the top of a parallel collapse ([`Collapse::collapse_parallel`]), in
/// the serial layout's order.
enum Top<'t, const N: usize> {
    /// A node of the top levels: its children and their items' indices.
    Node {
        kids: [&'t BuildNode; N],
        n: usize,
        items: [usize; N],
    },
    /// A subtree below them (or a leaf among them), collapsed by one task.
    Task(&'t BuildNode),
}

/// Lays out the top `levels` levels of the collapse of `node` into `items` (a node,
/// then each child's items, as the serial collapse lays them); returns `node`'s item.
fn plan<'t, const N: usize>(
    node: &'t BuildNode,
    levels: usize,
    items: &mut Vec<Top<'t, N>>,
) -> usize {
    let i = items.len();
    match node {
        BuildNode::Interior { children, .. } if levels > 0 => {
            let (kids, n) = open_children::<N>(children);
            items.push(Top::Node {
                kids,
                n,
                items: [0; N],
            });
            let mut kid_items = [0; N];
            for (slot, k) in kids[..n].iter().enumerate() {
                kid_items[slot] = plan(k, levels - 1, items);
            }
            if let Top::Node { items: it, .. } = &mut items[i] {
                *it = kid_items;
            }
        }
        _ => items.push(Top::Task(node)),
    }
    i
}

/// The children of an interior node with children `children`: the two, then the
/// interior child of the largest area opened (replaced by its two children) until
/// there are `N` or none is interior; returns them in an array and their count. Ties
/// go to the last of equal areas (`Iterator::max_by`'s rule, which this replaced).
///
/// Each child's area is computed once, when it joins: the scan over the children
/// computed two areas per comparison, about 60 per BVH8 node.
fn open_children<const N: usize>(children: &[BuildNode; 2]) -> ([&BuildNode; N], usize) {
    // Up to N children in a fixed array (no allocation per node); opening a child
    // moves the last one into its slot, then appends the grandchildren. `area` holds
    // an interior child's area, `None` for a leaf (never opened).
    let area = |k: &BuildNode| match k {
        BuildNode::Interior { .. } => Some(k.area()),
        BuildNode::Leaf { .. } => None,
    };
    let mut kids: [&BuildNode; N] = [&children[1]; N];
    let mut areas: [Option<f32>; N] = [None; N];
    kids[0] = &children[0];
    areas[0] = area(kids[0]);
    areas[1] = area(kids[1]);
    let mut n = 2;
    while n < N {
        let mut open: Option<(usize, f32)> = None;
        for (i, a) in areas[..n].iter().enumerate() {
            if let Some(a) = *a
                && open.is_none_or(|(_, best)| a.total_cmp(&best).is_ge())
            {
                open = Some((i, a));
            }
        }
        let Some((pos, _)) = open else { break };
        let BuildNode::Interior { children, .. } = kids[pos] else {
            unreachable!("only interior children have an area")
        };
        kids[pos] = kids[n - 1];
        areas[pos] = areas[n - 1];
        kids[n - 1] = &children[0];
        areas[n - 1] = area(kids[n - 1]);
        kids[n] = &children[1];
        areas[n] = area(kids[n]);
        n += 1;
    }
    (kids, n)
}

#[cfg(test)]
mod tests {
    use super::super::tree::wide_build_options;
    use super::*;
    use crate::accel::Primitives;
    use crate::accel::sah_build::build_tree;
    use glam::Vec3;

    /// The collapse as it was before the two passes and the cached areas: children
    /// opened by `max_by` over recomputed areas, groups gathered at each leaf.
    fn reference<const N: usize>(
        node: &BuildNode,
        ids: &[u32],
        tris: &Triangles,
        nodes: &mut Vec<BvhNode<N>>,
        groups: &mut Vec<TriGroup4>,
    ) -> u32 {
        let children = match node {
            BuildNode::Leaf { start, count, .. } => {
                let first = groups.len();
                for chunk in ids[*start as usize..(start + count) as usize].chunks(4) {
                    let mut g = TriGroup4::EMPTY;
                    for (lane, &id) in chunk.iter().enumerate() {
                        let k = id as usize;
                        g.set(lane, id, [tris.v0[k], tris.v1[k], tris.v2[k]]);
                    }
                    groups.push(g);
                }
                let n = (groups.len() - first) as u32;
                return LEAF | n << COUNT_SHIFT | first as u32;
            }
            BuildNode::Interior { children, .. } => children,
        };
        let mut kids: Vec<&BuildNode> = vec![&children[0], &children[1]];
        while kids.len() < N {
            let open = (0..kids.len())
                .filter(|&i| matches!(kids[i], BuildNode::Interior { .. }))
                .max_by(|&a, &b| kids[a].area().total_cmp(&kids[b].area()));
            let Some(pos) = open else { break };
            let BuildNode::Interior { children, .. } = kids[pos] else {
                unreachable!()
            };
            let last = kids.len() - 1;
            kids[pos] = kids[last];
            kids[last] = &children[0];
            kids.push(&children[1]);
        }
        let index = nodes.len();
        nodes.push(BvhNode::EMPTY);
        for (slot, k) in kids.iter().enumerate() {
            let r = reference(k, ids, tris, nodes, groups);
            let b = k.bounds();
            let node = &mut nodes[index];
            for a in 0..3 {
                node.planes[a][slot] = b.min[a];
                node.planes[a + 3][slot] = b.max[a];
            }
            node.children[slot] = r;
        }
        index as u32
    }

    fn bits<const N: usize>(root: u32, nodes: &[BvhNode<N>], groups: &[TriGroup4]) -> Vec<u32> {
        let mut bits = vec![root];
        for n in nodes {
            bits.extend(n.planes.iter().flatten().map(|x| x.to_bits()));
            bits.extend(n.children);
        }
        for g in groups {
            bits.extend(g.v.iter().flatten().flatten().map(|x| x.to_bits()));
            bits.extend(g.ids);
        }
        bits
    }

    /// Triangles on a bumpy grid with repeated areas (ties between children), and a
    /// few degenerate ones.
    fn mesh(n: usize) -> Triangles {
        let mut corners = Vec::new();
        for i in 0..n {
            let (x, y) = ((i % 97) as f32, (i / 97) as f32);
            let z = ((i * 37) % 11) as f32 * 0.25;
            let s = if i % 53 == 0 { 0.0 } else { 1.0 };
            corners.push([
                Vec3::new(x, y, z),
                Vec3::new(x + s, y, z),
                Vec3::new(x, y + s, z + 0.5 * s),
            ]);
        }
        Triangles::from_corners(&corners)
    }

    fn check<const N: usize>(tris: &Triangles, levels: usize) -> usize {
        let (tree, ids) = build_tree(tris, wide_build_options(true));
        let tree = tree.expect("non-empty");
        let mut c = Collapse::<N> {
            ids: &ids,
            triangles: Some(tris),
            nodes: LargeVec::new(),
            groups: LargeVec::new(),
        };
        let root = c.collapse(&tree, levels);
        let (mut nodes, mut groups) = (Vec::new(), Vec::new());
        let want = reference::<N>(&tree, &ids, tris, &mut nodes, &mut groups);
        assert_eq!(
            bits(root, &c.nodes, &c.groups),
            bits(want, &nodes, &groups),
            "N = {N}, {levels} parallel levels"
        );
        assert!(c.groups.len() >= tris.count().div_ceil(4));
        c.nodes.len()
    }

    /// The counting walk the parallel collapse sizes its tasks' ranges by gives, for
    /// every subtree down to the third level, exactly the nodes and groups the serial
    /// node pass writes for it (triangle leaves in groups, and scalar leaves: none),
    /// 8 and 4 wide.
    #[test]
    fn counts_match_the_serial_node_pass_on_every_subtree() {
        fn subtrees<'t>(node: &'t BuildNode, depth: usize, out: &mut Vec<&'t BuildNode>) {
            out.push(node);
            if let (BuildNode::Interior { children, .. }, true) = (node, depth > 0) {
                subtrees(&children[0], depth - 1, out);
                subtrees(&children[1], depth - 1, out);
            }
        }
        fn check<const N: usize>(tree: &BuildNode, ids: &[u32], tris: &Triangles) {
            let mut nodes = Vec::new();
            subtrees(tree, 3, &mut nodes);
            assert!(nodes.len() >= 15);
            for (i, t) in nodes.into_iter().enumerate() {
                for groups in [true, false] {
                    let mut c = Collapse::<N> {
                        ids,
                        triangles: groups.then_some(tris),
                        nodes: LargeVec::new(),
                        groups: LargeVec::new(),
                    };
                    let mut pending = PendingLeaves::default();
                    c.collapse_nodes(t, &mut pending);
                    let want = (c.nodes.len(), if groups { pending.groups } else { 0 });
                    assert_eq!(count::<N>(t, groups), want, "N = {N}, subtree {i}");
                    assert!(!groups || pending.groups > 0);
                }
            }
        }
        let tris = mesh(20_000);
        let (tree, ids) = build_tree(&tris, wide_build_options(true));
        let tree = tree.expect("non-empty");
        check::<8>(&tree, &ids, &tris);
        check::<4>(&tree, &ids, &tris);
    }

    /// Both passes together lay out every bit of the nodes and groups as the one-pass
    /// collapse with `max_by` did, serial and with parallel levels, 4 and 8 wide.
    #[test]
    fn two_pass_collapse_matches_the_one_pass_reference() {
        for n in [1, 2, 5, 333, 20_000] {
            let tris = mesh(n);
            let nodes8 = check::<8>(&tris, 0);
            let nodes4 = check::<4>(&tris, 0);
            assert_eq!(check::<8>(&tris, 2), nodes8);
            assert_eq!(check::<4>(&tris, 3), nodes4);
            if n >= 333 {
                assert!(nodes8 > 1 && nodes4 > nodes8, "{n}: {nodes8} / {nodes4}");
            }
        }
    }

    /// A whole build at two threads (the top of the collapse laid out first, its
    /// subtrees counted, then written by tasks straight into their final ranges; the build tree freed
    /// in parallel tasks) gives every bit of the one-thread build's nodes and groups,
    /// 8 and 4 wide, and the same statistics.
    #[test]
    fn two_thread_build_lays_out_the_one_thread_build() {
        use super::super::node::{NodeWidth, Width};
        use super::super::tree::{Bvh, Leaves};
        fn layout<const N: usize>(tris: &Triangles, threads: usize) -> (Vec<u32>, String)
        where
            Width<N>: NodeWidth,
        {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let bvh = pool.install(|| Bvh::<Triangles, N>::build(tris.clone()));
            let Leaves::Triangles(groups) = &bvh.leaves else {
                panic!("triangle leaves")
            };
            let i = &bvh.info;
            let stats = format!(
                "{} {} {} {} {} {}",
                i.nodes,
                i.leaves,
                i.max_depth,
                i.memory_bytes,
                i.sah_cost.to_bits(),
                bvh.stack_need
            );
            (bits(bvh.root, &bvh.nodes, groups), stats)
        }
        for n in [1, 2, 333, 20_000, 150_000] {
            let tris = mesh(n);
            let (one8, two8) = (layout::<8>(&tris, 1), layout::<8>(&tris, 2));
            assert_eq!(one8, two8, "BVH8, {n} triangles");
            let (one4, two4) = (layout::<4>(&tris, 1), layout::<4>(&tris, 2));
            assert_eq!(one4, two4, "BVH4, {n} triangles");
            assert!(one8.0.len() > n && one4.0.len() > one8.0.len() / 2);
        }
    }
}
