//! The node store: one array holding every node of an N-wide BVH and, right after each
//! node, the triangle groups of its leaf children (issue 12: "a leaf group stored next
//! to its parent node").
//!
//! Why: the collapse writes nodes and triangle groups into two arrays, each in
//! depth-first order, so a node and the groups of its leaves lie tens of megabytes apart
//! at 10^6 triangles. Embree's builder allocates a node and then its children's leaves
//! from one block allocator, so a leaf's primitives follow their parent's node in
//! memory; here the same: a traversal that has just read a node's four lines reads
//! its leaves' groups from the lines after it (the same page, and the lines the
//! hardware's streaming prefetcher fetches next).
//!
//! Layout, in units of 32 bytes: node after node in the collapse's order, each followed
//! by the groups of its leaf children in slot order (a group is 160 bytes, five
//! units), then one unit of padding where needed so that the next node starts on a
//! cache line (a node's alignment). An interior child reference is its node's unit
//! offset; a triangle leaf's `first` is the unit offset of its first group (its groups
//! are consecutive). Scalar leaves (not triangles) keep indexing their primitive
//! array: the store then holds nodes only.

use super::node::{BvhNode, COUNT_SHIFT, FIRST_MASK, LEAF, WideNode, is_leaf, leaf_range};
use crate::accel::sah_build::advise_huge_pages;
use crate::simd::kernels::TriGroup4;
use std::mem::{align_of, size_of};

/// The store's unit of addressing.
const UNIT: usize = 32;

/// A cache line of the store. Its bytes may include a node type's padding, which a
/// typed copy leaves uninitialised, hence `MaybeUninit`: the store only ever reads
/// whole nodes and groups, whose fields are all written.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Line([std::mem::MaybeUninit<u8>; 64]);

const _: () = assert!(size_of::<TriGroup4>() % UNIT == 0);
const _: () = assert!(align_of::<TriGroup4>() <= UNIT);
const _: () = assert!(size_of::<Line>() == 2 * UNIT);

/// Units a value of `T` takes.
const fn units<T>() -> usize {
    size_of::<T>() / UNIT
}

/// Every node of a tree and its leaves' triangle groups in one array (see the module
/// documentation).
pub struct NodeStore<T, const N: usize> {
    lines: Vec<Line>,
    /// Unit offset of each node, increasing (the collapse's node order).
    nodes: Vec<u32>,
    /// Triangle groups in the store.
    groups: usize,
    _node: std::marker::PhantomData<T>,
}

impl<T, const N: usize> NodeStore<T, N> {
    /// The store of no node.
    pub fn empty() -> Self {
        NodeStore {
            lines: Vec::new(),
            nodes: Vec::new(),
            groups: 0,
            _node: std::marker::PhantomData,
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether there is no node.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Number of triangle groups.
    pub fn group_count(&self) -> usize {
        self.groups
    }

    /// Bytes of the store (nodes, groups and padding).
    pub fn bytes(&self) -> usize {
        self.lines.len() * size_of::<Line>()
    }

    /// The address of unit `unit` if `bytes` bytes from it lie in the store and it is
    /// aligned to `align`.
    #[inline(always)]
    fn at(&self, unit: usize, bytes: usize, align: usize) -> Option<*const u8> {
        let start = unit.checked_mul(UNIT)?;
        let inside = start
            .checked_add(bytes)
            .is_some_and(|end| end <= self.bytes());
        (inside && start % align == 0).then(|| self.lines.as_ptr().cast::<u8>().wrapping_add(start))
    }

    /// The triangle groups of leaf reference `r` (empty for an empty slot). Panics
    /// where `r` does not lie in the store, which a built tree's references do
    /// (`validate()` checks).
    #[inline(always)]
    pub fn groups(&self, r: u32) -> &[TriGroup4] {
        let range = leaf_range(r);
        let count = range.len();
        let p = self
            .at(
                range.start,
                count * size_of::<TriGroup4>(),
                align_of::<TriGroup4>(),
            )
            .expect("leaf groups inside the node store");
        // SAFETY: `at` checked that the `count` groups lie inside the store and that
        // the first is aligned; `build` wrote every field of every node and group and
        // zeroed the rest, and a `TriGroup4` is plain `f32`s and `u32`s (no padding),
        // for which any bits are a value.
        unsafe { std::slice::from_raw_parts(p.cast::<TriGroup4>(), count) }
    }

    /// Groups of leaf reference `r`, or `None` where they do not lie in the store.
    pub fn get_groups(&self, r: u32) -> Option<&[TriGroup4]> {
        let range = leaf_range(r);
        self.at(
            range.start,
            range.len() * size_of::<TriGroup4>(),
            align_of::<TriGroup4>(),
        )?;
        Some(self.groups(r))
    }
}

impl<T: Copy, const N: usize> NodeStore<T, N> {
    /// The node at unit offset `unit`, if one starts there.
    pub fn get(&self, unit: usize) -> Option<&T> {
        self.nodes.binary_search(&u32::try_from(unit).ok()?).ok()?;
        Some(&self[unit])
    }

    /// The nodes in the store's order.
    pub fn iter(&self) -> impl Iterator<Item = &T> {
        self.nodes.iter().map(|&u| &self[u as usize])
    }

    /// Unit offsets of the nodes, in the store's order.
    pub fn offsets(&self) -> &[u32] {
        &self.nodes
    }
}

impl<'a, T: Copy, const N: usize> IntoIterator for &'a NodeStore<T, N> {
    type Item = &'a T;
    type IntoIter = Box<dyn Iterator<Item = &'a T> + 'a>;
    fn into_iter(self) -> Self::IntoIter {
        Box::new(self.iter())
    }
}

impl<T, const N: usize> std::ops::Index<usize> for NodeStore<T, N> {
    type Output = T;

    /// The node at unit offset `unit` (an interior child reference). Panics where no
    /// whole, aligned `T` lies there.
    #[inline(always)]
    fn index(&self, unit: usize) -> &T {
        let p = self
            .at(unit, size_of::<T>(), align_of::<T>())
            .expect("node inside the node store");
        // SAFETY: `at` checked bounds and alignment; the fields of whatever lies there
        // were written by `build` (a node, or a group or zeroes for a reference that
        // `validate()` would reject), and the node types (`BvhNode`, `QNode`) are plain
        // numbers, for which any bits are a value.
        unsafe { &*p.cast::<T>() }
    }
}

impl<T, const N: usize> std::ops::IndexMut<usize> for NodeStore<T, N> {
    fn index_mut(&mut self, unit: usize) -> &mut T {
        let p = self
            .at(unit, size_of::<T>(), align_of::<T>())
            .expect("node inside the node store")
            .cast_mut();
        // SAFETY: as for `index`; `&mut self` makes the reference unique.
        unsafe { &mut *p.cast::<T>() }
    }
}

/// Writes `value` at byte `at` of `lines`' spare capacity.
///
/// SAFETY: the caller keeps `at + size_of::<V>()` within the capacity and `at`
/// aligned for `V`.
unsafe fn put<V>(lines: &mut Vec<Line>, at: usize, value: &V) {
    // SAFETY: per the function's contract.
    unsafe {
        let dst = lines.as_mut_ptr().cast::<u8>().add(at);
        std::ptr::copy_nonoverlapping((value as *const V).cast::<u8>(), dst, size_of::<V>());
    }
}

impl<T: WideNode<N>, const N: usize> NodeStore<T, N> {
    /// Every triangle group, node by node (a tree with triangle leaves: other leaves
    /// index their primitive array, not the store).
    pub fn all_groups(&self) -> impl Iterator<Item = &TriGroup4> {
        self.iter().flat_map(|node| {
            node.children()
                .iter()
                .filter(|&&c| is_leaf(c))
                .flat_map(|&c| self.groups(c))
        })
    }

    /// Whether the units of leaf reference `r`'s groups overlap no node.
    pub fn groups_clear_of_nodes(&self, r: u32) -> bool {
        let range = leaf_range(r);
        let end = range.start + range.len() * units::<TriGroup4>();
        // The last node starting at or before the groups must end before them, the
        // next one start after them.
        let next = self.nodes.partition_point(|&o| (o as usize) <= range.start);
        let before = next
            .checked_sub(1)
            .is_none_or(|k| self.nodes[k] as usize + units::<T>() <= range.start);
        let after = self.nodes.get(next).is_none_or(|&o| o as usize >= end);
        before && after
    }

    /// The store of the collapse's `nodes` (interior references: node indices) with
    /// their leaves' `groups` (`Some`: triangle leaves, `first` a group index) after
    /// each node; returns it and the root's reference in it. The nodes are converted
    /// with [`WideNode::from_exact`] as they are written.
    ///
    /// Panics where the store would pass 4 GiB (`first` has 27 bits of units: some
    /// 2 x 10^8 triangles).
    pub fn build(nodes: &[BvhNode<N>], groups: Option<&[TriGroup4]>, root: u32) -> (Self, u32) {
        let group_units = units::<TriGroup4>();
        let node_units = units::<T>();
        let line_units = size_of::<Line>() / UNIT;
        const { assert!(align_of::<T>() <= size_of::<Line>()) };
        let align_units = align_of::<T>().max(UNIT) / UNIT;
        // A tree whose root is a leaf (a few triangles) has no node: its groups open
        // the store.
        let root_groups = match groups {
            Some(g) if is_leaf(root) => &g[leaf_range(root)],
            _ => &[],
        };
        // Pass 1: every node's offset.
        let mut offsets = Vec::with_capacity(nodes.len());
        let mut cursor = (root_groups.len() * group_units).next_multiple_of(align_units);
        for node in nodes {
            offsets.push(cursor);
            cursor += node_units;
            if groups.is_some() {
                for &c in node.children.iter().filter(|&&c| is_leaf(c)) {
                    cursor += leaf_range(c).len() * group_units;
                }
            }
            cursor = cursor.next_multiple_of(align_units);
        }
        let total = cursor.next_multiple_of(line_units);
        assert!(
            total <= FIRST_MASK as usize,
            "node store of {total} units: past the leaf references' 27 bits"
        );
        // Pass 2: the nodes and groups written in order, every byte (padding included).
        let mut lines: Vec<Line> = Vec::with_capacity(total / line_units);
        // Fresh pages (a 10^6 store is 63 MB, which glibc maps afresh for every
        // build): backed by huge pages where the machine allows, 15,500 fewer page
        // faults per 10^6 build.
        advise_huge_pages(lines.as_mut_ptr().cast(), total * UNIT);
        let first_node = offsets.first().copied().unwrap_or(total);
        // SAFETY: `0..first_node` lies within the capacity; the root leaf's groups
        // after the zeroing, on unit boundaries inside it.
        unsafe {
            std::ptr::write_bytes(lines.as_mut_ptr().cast::<u8>(), 0, first_node * UNIT);
            for (k, g) in root_groups.iter().enumerate() {
                put(&mut lines, k * group_units * UNIT, g);
            }
        }
        let mut group_count = root_groups.len();
        let remap = |r: u32| -> u32 {
            if !is_leaf(r) {
                offsets[r as usize] as u32
            } else if !root_groups.is_empty() {
                // The root leaf: its groups from unit 0.
                LEAF | (root_groups.len() as u32) << COUNT_SHIFT
            } else {
                r
            }
        };
        for (i, node) in nodes.iter().enumerate() {
            let start = offsets[i];
            let end = offsets.get(i + 1).copied().unwrap_or(total);
            // SAFETY: `start..end` lies within the capacity (`total` units); zeroing it
            // first initialises the padding of the node type and of the block.
            unsafe {
                let dst = lines.as_mut_ptr().cast::<u8>().add(start * UNIT);
                std::ptr::write_bytes(dst, 0, (end - start) * UNIT);
            }
            let mut exact = *node;
            let mut at = start + node_units;
            for c in exact.children.iter_mut() {
                if !is_leaf(*c) {
                    *c = remap(*c);
                } else if let Some(groups) = groups {
                    let range = leaf_range(*c);
                    if range.is_empty() {
                        continue;
                    }
                    *c = LEAF | (range.len() as u32) << COUNT_SHIFT | at as u32;
                    for g in &groups[range] {
                        // SAFETY: inside this node's block, on a unit boundary.
                        unsafe { put(&mut lines, at * UNIT, g) };
                        at += group_units;
                        group_count += 1;
                    }
                }
            }
            // SAFETY: `start` is a multiple of the node's alignment in units (pass 1),
            // the node's units lie inside its block.
            unsafe { put(&mut lines, start * UNIT, &T::from_exact(&exact)) };
        }
        // SAFETY: the lines are `MaybeUninit` bytes; besides, every field of the first
        // `total` units was written above (each block zeroed, then filled; blocks tile
        // `0..total`).
        unsafe { lines.set_len(total / line_units) };
        let store = NodeStore {
            lines,
            nodes: offsets.iter().map(|&o| o as u32).collect(),
            groups: group_count,
            _node: std::marker::PhantomData,
        };
        (store, remap(root))
    }
}
