//! Integrators: how radiance is estimated per pixel. [`recursive`] is the depth-first
//! scalar reference renderer; [`wavefront`] renders the same images breadth first,
//! tracing rays in batches from queues.
//!
//! Both are built from the same stages, one file each, in the order a sample meets
//! them: [`camera_rays`] (ray generation), [`interaction`] (surface interactions),
//! [`shader`] (materials, BRDFs, Fresnel via [`optics`], emitted shadow and child
//! rays), [`path_keys`] (random streams keyed by path identity), [`pixel_filter`]
//! (camera-ray radiance into filter sums) and [`tiles`] (tile scheduler and film
//! assembly); the wavefront adds its [`queues`].

pub mod adaptive;
pub mod aov;
pub(crate) mod area_light;
pub mod budget;
pub mod camera_packets;
pub mod camera_rays;
pub(crate) mod environment;
pub(crate) mod hit_batch;
pub mod interaction;
mod kind;
pub mod optics;
mod options;
mod output;
pub mod path_keys;
pub mod pixel_filter;
pub(crate) mod point_shadow;
mod polygon_aperture;
pub mod queues;
pub mod recursive;
pub mod region;
pub(crate) mod round_lights;
pub mod sampling;
pub(crate) mod shade_stage;
pub mod shader;
pub mod shadow;
mod slot_pixels;
pub mod sobol;
pub mod texturing;
pub mod tiles;
pub mod tiny_shadow;
pub mod wavefront;

pub use kind::IntegratorKind;
pub use options::{ProgressFn, RenderOptions};
pub use output::RenderOutput;
pub use region::PixelBounds;
pub use sampling::{FilterKind, SamplerKind};
