//! What the scene-level queries answer: which primitive set and primitive a hit
//! belongs to, and which set blocks a ray first.

use super::Accel;

/// Which primitive set a scene-level hit belongs to.
///
/// `repr(u32)` (a `u32` tag, then the fields, RFC 2195) and [`SceneHit`] `repr(C)`: a
/// packet's hits are stored sixteen at a time as six-word records
/// (`scene_batch::closest_packets`, [`crate::simd::ray_store::store_hit_records`]), the
/// layout asserted below.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum PrimRef {
    Triangle(u32) = 0,
    Sphere(u32) = 1,
    /// Index into `Scene::motion.mesh`.
    MovingTriangle(u32),
    /// Index into `Scene::motion.spheres`.
    MovingSphere(u32),
    /// Triangle `prim` of the object placed by `Scene::instances.instances[instance]`.
    Instance {
        instance: u32,
        prim: u32,
    },
    /// Index into `Scene::planes` (infinite planes).
    Plane(u32),
}

/// A closest hit in the whole scene.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct SceneHit {
    pub t: f32,
    pub prim: PrimRef,
    pub u: f32,
    pub v: f32,
}

impl PrimRef {
    /// The tag word of [`PrimRef::Triangle`] and [`PrimRef::Sphere`] (their explicit
    /// discriminants), word 1 of a [`SceneHit`].
    pub(super) const TRIANGLE_TAG: u32 = 0;
    pub(super) const SPHERE_TAG: u32 = 1;
}

// The six-word record of a `Some(SceneHit)` on a triangle or a sphere: `t`, the tag,
// the index, a spare word (the second index of `Instance`), `u`, `v`; and `None` in
// the tag's niche (an `Option<SceneHit>` no larger than a `SceneHit`), so that every
// valid `SceneHit` is, byte for byte, the `Some` holding it.
const _: () = {
    use std::mem::{offset_of, size_of};
    assert!(size_of::<PrimRef>() == 12);
    assert!(size_of::<SceneHit>() == 24);
    assert!(size_of::<Option<SceneHit>>() == size_of::<SceneHit>());
    assert!(std::mem::align_of::<Option<SceneHit>>() == 4);
    assert!(offset_of!(SceneHit, t) == 0);
    assert!(offset_of!(SceneHit, prim) == 4);
    assert!(offset_of!(SceneHit, u) == 16);
    assert!(offset_of!(SceneHit, v) == 20);
};

/// Which primitive sets of a scene block a ray first, in the order the scene-level
/// queries test them ([`SceneAccel::occluder`](super::SceneAccel::occluder), [`SceneAccel::occluders_batch`](super::SceneAccel::occluders_batch)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Occluder {
    Triangles,
    Spheres,
    /// Moving triangles or moving spheres (one occlusion query covers both).
    Moving,
    /// Instances or infinite planes.
    Other,
}

impl Occluder {
    pub const ALL: [Occluder; 4] = [
        Occluder::Triangles,
        Occluder::Spheres,
        Occluder::Moving,
        Occluder::Other,
    ];

    /// The first of the filtered query's four flat sets (triangles, spheres, moving
    /// triangles, moving spheres) that this group covers; 4 is past them all.
    pub(super) fn first_set(self) -> usize {
        match self {
            Occluder::Triangles => 0,
            Occluder::Spheres => 1,
            Occluder::Moving => 2,
            Occluder::Other => 4,
        }
    }
}

/// One primitive set of a scene and how its hits are named.
pub(super) type PrimSet<'a> = (Option<&'a dyn Accel>, fn(u32) -> PrimRef);

/// A candidate hit of a scene-level filtered query ([`SceneAccel::filtered_hit`](super::SceneAccel::filtered_hit)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneCandidate {
    pub hit: SceneHit,
    /// Whether the ray meets the front face ([`QueryOptions::cull_back_faces`](super::QueryOptions::cull_back_faces)).
    pub front_face: bool,
}
