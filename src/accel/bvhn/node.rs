//! The N-wide node: children's bounds as lane arrays and packed child references,
//! the leaf encoding of a child reference, and [`WideNode`], what every traversal asks
//! of a node (so that single-ray, packet and stream kernels run unchanged on the exact
//! [`BvhNode`] and on the compressed [`QNode`](super::QNode)).

use crate::geometry::Aabb;
use crate::simd::slab_fma::FusedLanes;
use crate::simd::{F4, F8};
use glam::Vec3;

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
    /// Child references: an interior node's index, or `LEAF` | count << 27 | first.
    pub children: [u32; N],
}

/// A 4-wide node: two cache lines.
pub type Bvh4Node = BvhNode<4>;
/// An 8-wide node: 224 bytes of bounds and references, padded to four cache lines.
pub type Bvh8Node = BvhNode<8>;

impl<const N: usize> BvhNode<N> {
    /// A node with every slot unused: empty boxes (min +inf, max -inf) that no ray
    /// enters, and `EMPTY_CHILD` references. Builders fill its slots in place.
    pub const EMPTY: Self = Self {
        planes: [
            [f32::INFINITY; N],
            [f32::INFINITY; N],
            [f32::INFINITY; N],
            [f32::NEG_INFINITY; N],
            [f32::NEG_INFINITY; N],
            [f32::NEG_INFINITY; N],
        ],
        children: [EMPTY_CHILD; N],
    };
}

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 64);
const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);
const _: () = assert!(std::mem::align_of::<Bvh8Node>() == 64);

/// What the traversals read from an N-wide node: its children's box planes as lane
/// arrays (in [`BvhNode::planes`]' order) and its child references. Implemented by the
/// exact [`BvhNode`] (planes read in place) and the compressed
/// [`QNode`](super::QNode) (planes decoded per visit).
pub trait WideNode<const N: usize>: Copy + Send + Sync + std::fmt::Debug + 'static {
    /// Whether the child boxes are quantised (`bvh4c`, `bvh8c`).
    const COMPRESSED: bool;
    /// The planes as the traversal reads them: a reference into the node, or the
    /// decoded copy.
    type Planes<'a>: std::ops::Deref<Target = [[f32; N]; 6]>
    where
        Self: 'a;

    /// The node for the exact child boxes and references of `node`; every box it
    /// reports contains the exact one.
    fn from_exact(node: &BvhNode<N>) -> Self;
    /// The six plane arrays `min_x, min_y, min_z, max_x, max_y, max_z`.
    fn planes(&self) -> Self::Planes<'_>;
    /// Child references (`EMPTY_CHILD` for an unused slot).
    fn children(&self) -> &[u32; N];

    /// Bounds of child slot `c`, as the traversal sees them.
    fn child_bounds(&self, c: usize) -> Aabb {
        let p = self.planes();
        Aabb::new(
            Vec3::new(p[0][c], p[1][c], p[2][c]),
            Vec3::new(p[3][c], p[4][c], p[5][c]),
        )
    }
}

impl<const N: usize> WideNode<N> for BvhNode<N> {
    const COMPRESSED: bool = false;
    type Planes<'a> = &'a [[f32; N]; 6];

    #[inline(always)]
    fn from_exact(node: &BvhNode<N>) -> Self {
        *node
    }
    #[inline(always)]
    fn planes(&self) -> &[[f32; N]; 6] {
        &self.planes
    }
    #[inline(always)]
    fn children(&self) -> &[u32; N] {
        &self.children
    }
}

/// The node widths there are kernels for, and the lane type of their slab test.
pub trait NodeWidth {
    /// N lanes: one per child.
    type L: FusedLanes;
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
pub(super) const COUNT_SHIFT: u32 = 27;
pub(super) const FIRST_MASK: u32 = (1 << COUNT_SHIFT) - 1;
/// An unused child slot: a leaf with nothing in it (and empty bounds).
pub const EMPTY_CHILD: u32 = LEAF;

#[inline(always)]
pub(super) fn is_leaf(r: u32) -> bool {
    r & LEAF != 0
}

#[inline(always)]
pub(super) fn leaf_range(r: u32) -> std::ops::Range<usize> {
    let first = (r & FIRST_MASK) as usize;
    let count = ((r & !LEAF) >> COUNT_SHIFT) as usize;
    first..first + count
}
