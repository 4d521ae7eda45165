//! What the scene-level queries answer: which primitive set and primitive a hit
//! belongs to, and which set blocks a ray first.

use super::Accel;

/// Which primitive set a scene-level hit belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimRef {
    Triangle(u32),
    Sphere(u32),
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
pub struct SceneHit {
    pub t: f32,
    pub prim: PrimRef,
    pub u: f32,
    pub v: f32,
}

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
