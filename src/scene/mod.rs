//! The scene, stored structure-of-arrays and immutable after load.
//!
//! Vertex positions live in three `f32` arrays, triangles in three index arrays, and
//! every primitive carries a material id; spheres are arrays of centre, radius and
//! material. Bounds, counts and the [`Features`] a scene uses are computed once, in
//! [`SceneBuilder::finish`], which is also the last line of validation: every loader
//! and generator goes through it, so no scene with NaN vertices or dangling indices
//! can reach the renderer.

mod builder;
mod camera;
mod camera_override;
mod checks;
mod environment;
mod features;
pub mod instance;
mod light;
pub mod limits;
pub mod load;
mod material;
mod mesh;
mod motion;
mod plane;
pub mod procedural;
mod settings;
pub mod sky;
mod spheres;
mod store;

pub use builder::SceneBuilder;
pub use camera::{Camera, CameraEffects, CameraFrame, LensFrame};
pub use camera_override::{CameraOverrides, Side, UpAxis, parse_vec3};
pub use checks::nothing_visible_warning;
pub use environment::{
    Environment, EnvironmentSample, MAX_MAP_SIDE, direction_to_uv, uv_to_direction,
};
pub use features::Features;
pub use instance::{Affine, Instance, InstanceSet, SurfacePoint};
pub use light::{Light, LightSample, LightView, SphereView};
pub use material::{CHECKER_INSET, Checker, Material};
pub use mesh::TriangleMesh;
pub use motion::MotionSet;
pub use plane::Plane;
pub use settings::{RenderSettings, SampleCounts};
pub use spheres::SphereSet;
pub use store::Scene;
