//! The collapse of a binned-SAH BVH2 into N-wide nodes (greedy, largest area opened
//! first: Wald et al. 2008, "Getting Rid of Packets"), with triangle leaves packed
//! into groups of four.

use super::node::{BvhNode, COUNT_SHIFT, EMPTY_CHILD, FIRST_MASK, LEAF, is_leaf};
use crate::accel::Triangles;
use crate::accel::sah_build::BuildNode;
use crate::simd::kernels::TriGroup4;
use rayon::prelude::*;

/// Levels of the collapse that hand their children's subtrees to separate threads (at
/// most N^2 tasks): the collapse was 13 % of a serial build (4 of 30 ms on the bunny).
pub(super) const PARALLEL_COLLAPSE_LEVELS: usize = 2;

pub(super) struct Collapse<'a, const N: usize> {
    pub(super) ids: &'a [u32],
    pub(super) triangles: Option<&'a Triangles>,
    pub(super) nodes: Vec<BvhNode<N>>,
    pub(super) groups: Vec<TriGroup4>,
}

impl<const N: usize> Collapse<'_, N> {
    /// The node reference for a build subtree: its two children, then the child with
    /// the largest area opened until there are N. The top `parallel_levels` levels
    /// collapse their children's subtrees in parallel.
    pub(super) fn collapse(&mut self, node: &BuildNode, parallel_levels: usize) -> u32 {
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
