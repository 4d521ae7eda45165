//! packet-render: a data-oriented CPU ray tracer.
//!
//! Data flows one way (see `ARCHITECTURE.md`):
//! scene files → [`scene::Scene`] (structure-of-arrays, immutable) → an acceleration
//! structure behind [`accel::Accel`] → an integrator → a [`film::Film`] → image files.
//!
//! ```ignore
//! use packet_render::{scene, accel, integrator, film};
//! let scene = scene::load::load_scene(std::path::Path::new("scenes/whitted.toml")).unwrap();
//! let accel = accel::SceneAccel::build(&scene, accel::AccelKind::Bvh2);
//! let opts = integrator::RenderOptions::from_scene(&scene);
//! let out = integrator::recursive::render(&scene, &accel, &opts);
//! out.film.save(std::path::Path::new("out.png")).unwrap();
//! ```

pub mod accel;
pub mod bench;
pub mod error;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod job;
mod pages;
pub mod plot;
pub mod progressive;
pub mod scene;
pub mod simd;
pub mod stats;
#[cfg(test)]
mod test_rng;
pub mod texture;

pub use error::{Error, Result};
