//! `validate()`: a built tree checked against its own leaves, independently of how
//! it was built: references in range, every primitive in exactly one leaf, and every
//! child box, as the traversal reads it (decoded, for compressed nodes), containing
//! the exact bounds of the primitives below it.

use super::node::{EMPTY_CHILD, NodeWidth, WideNode, Width, is_leaf, leaf_range};
use super::tree::{Bvh, Leaves};
use crate::accel::Primitives;
use crate::geometry::Aabb;

impl<P: Primitives, const N: usize, T: WideNode<N>> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    /// Checks the tree; the first violation found, described, as the error. A child
    /// box must contain its subtree's exact bounds: a box that is too small would let
    /// a ray miss a primitive it hits. An axis a compressed node could not quantise
    /// (NaN planes) counts as unbounded, which is how the slab tests read it.
    pub fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.info.primitives];
        if self.root != EMPTY_CHILD {
            self.check_subtree(self.root, &mut seen, 0)?;
        }
        match seen.iter().position(|s| !s) {
            Some(i) => Err(format!("primitive {i} is in no leaf")),
            None => Ok(()),
        }
    }

    /// Exact bounds of the subtree `r`, after checking it.
    fn check_subtree(&self, r: u32, seen: &mut [bool], depth: usize) -> Result<Aabb, String> {
        if depth > 4 * crate::accel::bvh2::STACK_SIZE {
            return Err(format!("deeper than {depth} levels: a cycle?"));
        }
        if is_leaf(r) {
            return self.check_leaf(r, seen);
        }
        let node = self
            .nodes
            .get(r as usize)
            .ok_or_else(|| format!("node reference {r} past {} nodes", self.nodes.len()))?;
        let mut bounds = Aabb::EMPTY;
        for (c, &child) in node.children().iter().enumerate() {
            if child == EMPTY_CHILD {
                continue;
            }
            let exact = self.check_subtree(child, seen, depth + 1)?;
            let b = node.child_bounds(c);
            for a in 0..3 {
                // `!(x > y)`: a NaN plane (an unquantised axis) bounds nothing.
                if b.min[a] > exact.min[a] || b.max[a] < exact.max[a] {
                    return Err(format!(
                        "node {r} child {c}: box {:?}..{:?} does not contain its subtree's \
                         bounds {:?}..{:?} on axis {a}",
                        b.min, b.max, exact.min, exact.max
                    ));
                }
            }
            bounds = bounds.union(&exact);
        }
        Ok(bounds)
    }

    fn check_leaf(&self, r: u32, seen: &mut [bool]) -> Result<Aabb, String> {
        let range = leaf_range(r);
        let mut bounds = Aabb::EMPTY;
        let mut mark = |id: u32| {
            let s = seen
                .get_mut(id as usize)
                .ok_or_else(|| format!("leaf {r:#x}: primitive id {id} out of range"))?;
            if std::mem::replace(s, true) {
                return Err(format!("primitive {id} is in two leaves"));
            }
            Ok(())
        };
        match &self.leaves {
            Leaves::Triangles(groups) => {
                let groups = groups
                    .get(range.clone())
                    .ok_or_else(|| format!("leaf {r:#x}: groups {range:?} out of range"))?;
                for g in groups {
                    for lane in (0..4).filter(|&l| g.ids[l] != u32::MAX) {
                        mark(g.ids[lane])?;
                        for p in g.corners(lane) {
                            bounds.grow(p);
                        }
                    }
                }
            }
            Leaves::Scalar { prims, ids } => {
                if range.end > ids.len() {
                    return Err(format!("leaf {r:#x}: primitives {range:?} out of range"));
                }
                for k in range {
                    mark(ids[k])?;
                    bounds = bounds.union(&prims.bounds(k));
                }
            }
        }
        Ok(bounds)
    }
}
