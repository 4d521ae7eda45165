//! Acceleration structures, all interchangeable behind [`Accel`].
//!
//! Each structure is built over one primitive set ([`Triangles`] or [`Spheres`], both
//! implementing [`Primitives`]) and owns the copy of the primitive data it traverses, in
//! the order its leaves want. [`SceneAccel`] holds one structure per primitive kind the
//! scene actually has, so a scene without spheres never runs a sphere kernel.

mod bruteforce;
mod build_arena;
mod bvh2;
mod bvhn;
mod extras;
pub mod filter;
mod grid;
mod instance;
mod interface;
mod kdtree;
mod kind;
mod moving;
mod octree;
mod primitives;
mod sah_build;
mod scene_accel;
mod scene_batch;
mod scene_hit;
pub mod spatial;
mod tiny;

/// The buffer type of [`Bvh::nodes`] (a slice through `Deref`).
pub use crate::pages::LargeVec;
pub use bruteforce::BruteForce;
pub use bvh2::{Bvh2, Bvh2BuildOptions, Bvh2Node};
pub use bvhn::{
    Bvh, Bvh4, Bvh4Node, Bvh4QNode, Bvh4c, Bvh8, Bvh8Node, Bvh8QNode, Bvh8c, BvhNode, NodeWidth,
    PACKET_MIN_ACTIVE, Prefetch, QNode, STREAM_MIN_BATCH, STREAM_MIN_RAYS, STREAM_WINS, WideNode,
    Width, incoherent_batch, prefers_stream,
};
pub use filter::{Candidate, HitFilter, QueryOptions, all_hits};
pub use grid::{Grid, GridOptions};
pub use instance::InstanceAccel;
pub use interface::{Accel, AccelInfo, PacketHitLanes, hits_as_lanes};
pub use kdtree::{KdNode, KdTree, KdTreeOptions};
pub use kind::AccelKind;
pub use moving::{MovingAccel, MovingSpheres, MovingTriangles};
pub use octree::{Octree, OctreeNode, OctreeOptions};
pub use primitives::{Primitives, Spheres, Triangles};
pub use scene_accel::SceneAccel;
pub use scene_batch::BatchScratch;
pub use scene_hit::{Occluder, PrimRef, SceneCandidate, SceneHit};
pub use spatial::TraversalCounts;
pub use tiny::{TINY_MAX_PRIMITIVES, TinyScene, TinyScratch};
