//! N-wide BVHs: the fast path. [`Bvh4`] (4-wide nodes, SSE-width slab tests) and
//! [`Bvh8`] (8-wide nodes, AVX-width slab tests) share one implementation, generic over
//! the node width.
//!
//! Built by collapsing the binned-SAH BVH2: each node takes a BVH2 node's two children
//! and repeatedly opens the child with the largest surface area until it has N (the
//! greedy SAH-aware collapse of Wald et al. 2008, "Getting Rid of Packets"). A node
//! stores its children's bounds as lane arrays, so one N-wide slab test covers all
//! children; leaves of a triangle mesh hold [`TriGroup4`](crate::simd::kernels::TriGroup4)s, so one SIMD test covers four
//! triangles. Other primitive kinds keep scalar leaves.
//!
//! Traversals: single ray (`closest_single`, `any_single`), and coherent packets of
//! [`PACKET_WIDTH`](crate::simd::PACKET_WIDTH) rays, given as a slice (the [`Accel`](super::Accel) batch entry points) or as a SoA
//! [`RayPacket`](crate::geometry::RayPacket) (`closest_hit_packet`/`any_hit_packet`), both through the same kernels
//! (generic over [`LaneRays`](crate::geometry::LaneRays)). A packet is split by direction octant and dominant axis
//! so that each part shares its slab planes and its watertight shear; each part first
//! tests a node's children against the interval bounds of all its rays
//! (`PacketBounds`), then runs the per-lane slab test only for children some lane may
//! enter; a part with few active rays left finishes a subtree ray by ray, as Embree's
//! hybrid traversal does. Large incoherent batches go through the stream kernel
//! (`closest_stream`/`any_stream`): the rays binned by octant, each node tested once for
//! the list of rays that reached it (`stream.rs`). `closest_hit_sorted`/`any_hit_sorted`
//! regroup a batch by octant and dominant axis into packets first (`sorted.rs`).
//!
//! Nodes come exact ([`BvhNode`], the default) or compressed ([`QNode`]: child boxes
//! quantised to 8 bits per plane against the node's box, rounded outward, half or a
//! quarter of the bytes); every traversal is generic over [`WideNode`], so the same
//! kernels run on both. `validate()` checks a built tree's boxes against its leaves.
//!
//! One concern per file, as Embree keeps node types, node intersectors, single-ray and
//! hybrid (packet) traversal apart: `node.rs` (layout and leaf encoding), `stack.rs`,
//! `qnode.rs` (the compressed node), `tree.rs` (the structure, its build and the
//! `Accel` entry points), `validate.rs`, `collapse.rs`,
//! `single.rs`, `packet_setup.rs`, `packet_bounds.rs`, `packet.rs`, `sorted.rs` and
//! `stream.rs`.

mod collapse;
mod node;
mod packet;
mod packet_bounds;
mod packet_setup;
mod qnode;
mod single;
mod sorted;
mod stack;
mod stream;
#[cfg(test)]
mod tests;
mod tree;
mod validate;

pub use node::{Bvh4Node, Bvh8Node, BvhNode, NodeWidth, WideNode, Width};
pub use packet::PACKET_MIN_ACTIVE;
pub use qnode::{Bvh4QNode, Bvh8QNode, QNode};
pub use stream::{
    STREAM_MIN_BATCH, STREAM_MIN_RAYS, STREAM_WINS, incoherent_batch, prefers_stream,
};
pub use tree::{Bvh, Bvh4, Bvh4c, Bvh8, Bvh8c, Prefetch};
