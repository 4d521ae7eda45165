//! The complete scene, immutable after [`SceneBuilder::finish`](super::SceneBuilder::finish).

use super::{
    Camera, CameraEffects, CameraFrame, Environment, Features, InstanceSet, Light, Material,
    MotionSet, Plane, RenderSettings, SphereSet, TriangleMesh,
};
use crate::geometry::Aabb;
use glam::Vec3;
use std::sync::Arc;

/// A complete scene. Build one with [`SceneBuilder`](super::SceneBuilder), a loader in
/// [`load`](super::load) or a generator in [`procedural`](super::procedural).
#[derive(Clone, Debug)]
pub struct Scene {
    pub mesh: TriangleMesh,
    pub spheres: SphereSet,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    pub camera: Camera,
    /// Lens and shutter; the default is a pinhole with an instantaneous shutter.
    pub camera_effects: CameraEffects,
    /// Moving geometry (empty for a static scene).
    pub motion: MotionSet,
    /// Instanced objects and their placements (empty without `[[instance]]`).
    pub instances: InstanceSet,
    /// Infinite planes, outside [`bounds`](Self::bounds).
    pub planes: Vec<Plane>,
    /// Radiance of rays that miss everything when there is no `environment`: a
    /// backdrop that lights nothing.
    pub background: Vec3,
    /// Radiance from infinitely far away: seen by rays that miss (it replaces
    /// `background`) and lighting lit surfaces through shadow rays to infinity.
    pub environment: Option<Arc<Environment>>,
    pub ambient: Vec3,
    pub settings: RenderSettings,
    /// Bounds of all bounded geometry (infinite planes are left out).
    pub bounds: Aabb,
    pub features: Features,
}

impl Scene {
    /// The camera's image frame for `width x height` pixels with the projection its
    /// effects ask for (perspective, or orthographic): what every ray generator uses.
    pub fn camera_frame(&self, width: u32, height: u32) -> CameraFrame {
        self.camera
            .frame(width, height)
            .with_effects(&self.camera_effects)
    }

    /// Radiance seen by a ray with direction `dir` that hits nothing: the
    /// environment's if there is one, else the background colour.
    #[inline]
    pub fn miss_radiance(&self, dir: Vec3) -> Vec3 {
        match &self.environment {
            Some(env) => env.radiance(dir),
            None => self.background,
        }
    }

    pub fn primitive_count(&self) -> usize {
        self.mesh.len()
            + self.spheres.len()
            + self.motion.len()
            + self.instances.instanced_triangles()
            + self.planes.len()
    }
}
