//! Resource bounds checked before a render starts (issue 13): thread count, products
//! of sample counts, and the memory the integrator's per-tile buffers will take.
//! Every check runs before any work and says what it computed and what the limit is.

use super::camera_rays::SamplePlan;
use super::tiles::TILE;
use super::wavefront::MAX_WAVE_PATHS;
use super::{IntegratorKind, RenderOptions};
use crate::accel::SceneHit;
use crate::error::{Error, Result};
use crate::geometry::Ray;
use crate::scene::Scene;
use glam::Vec3;
use std::mem::size_of;

/// Most worker threads accepted (`--threads`). Far beyond any useful count: each
/// thread gets its own stack and tile buffers, and 100000 threads ran for 16 minutes
/// before failing to set up a stack guard page.
pub const MAX_THREADS: usize = 1024;

/// Most camera rays per pixel (`spp x lens x time`): both integrators hold one pixel's
/// camera rays at once (2^24 rays are about 0.6 GiB), and the per-pixel sample indices
/// (Sobol points, path identities of a round) are `u32`, with room to spare.
pub const MAX_CAMERA_RAYS_PER_PIXEL: u64 = 1 << 24;

/// Memory budget when the machine's available memory cannot be read (8 GiB).
pub const FALLBACK_MEMORY_BUDGET: u64 = 8 << 30;

/// Rejects more than [`MAX_THREADS`] threads (0 means all cores and is accepted).
pub fn validate_threads(threads: usize) -> Result<()> {
    if threads > MAX_THREADS {
        return Err(Error::parameter(
            "threads",
            format!("{threads}: at most {MAX_THREADS} worker threads (0 = all cores)"),
        ));
    }
    Ok(())
}

/// The sample products a render will use, in u64: camera rays per pixel
/// (`eye x lens x time`, absent effects count 1) and first-hit rays per pixel
/// including area-light shadow rays and glossy rays. Rejects camera rays per pixel
/// above [`MAX_CAMERA_RAYS_PER_PIXEL`] and any product that overflows u64 (for the
/// whole frame too).
pub fn validate_sample_products(scene: &Scene, opts: &RenderOptions) -> Result<SampleProducts> {
    let plan = SamplePlan::new(scene, opts);
    let f = &scene.features;
    let camera = plan.eye as u64 * plan.lens.max(1) as u64 * plan.time.max(1) as u64;
    if camera > MAX_CAMERA_RAYS_PER_PIXEL {
        return Err(Error::parameter(
            "sample counts",
            format!(
                "{} eye x {} lens x {} time = {camera} camera rays per pixel: at most {} \
                 (2^24) can be represented",
                plan.eye,
                plan.lens.max(1),
                plan.time.max(1),
                MAX_CAMERA_RAYS_PER_PIXEL
            ),
        ));
    }
    let area_lights = scene.lights.iter().filter(|l| l.is_area()).count() as u64;
    let other_lights = scene.lights.len() as u64 - area_lights;
    let shadow_per_hit = if f.area_lights {
        area_lights * plan.shadow as u64 + other_lights
    } else {
        other_lights
    } + plan.environment as u64;
    let glossy_per_hit = if f.glossy || f.translucency {
        plan.glossy as u64
    } else {
        0
    };
    let overflow = |what: &str| {
        Error::parameter(
            "sample counts",
            format!("{what} overflows 64 bits: lower the sample counts"),
        )
    };
    let shadow = camera
        .checked_mul(shadow_per_hit)
        .ok_or_else(|| overflow("shadow rays per pixel"))?;
    let glossy = camera
        .checked_mul(glossy_per_hit)
        .ok_or_else(|| overflow("glossy rays per pixel"))?;
    let per_pixel = camera
        .checked_add(shadow)
        .and_then(|n| n.checked_add(glossy))
        .ok_or_else(|| overflow("first-hit rays per pixel"))?;
    let pixels = opts.width as u64 * opts.height as u64;
    pixels
        .checked_mul(per_pixel)
        .ok_or_else(|| overflow("first-hit rays of the frame"))?;
    Ok(SampleProducts {
        camera,
        shadow,
        glossy,
    })
}

/// Rays per pixel at the first hit, as [`validate_sample_products`] computed them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleProducts {
    pub camera: u64,
    /// Shadow rays (area-light samples and one per other light) per pixel.
    pub shadow: u64,
    /// Glossy and translucency rays per pixel.
    pub glossy: u64,
}

/// Estimated peak bytes of the per-thread buffers: for the recursive integrator, one
/// pixel's camera rays per worker; for the wavefront one, a batch of at most
/// [`MAX_WAVE_PATHS`] paths in its queues (each entry counted at the largest queue
/// entry, with its hit and camera-sample accumulator) plus the camera rays and
/// radiance of the pixels in flight (two pixels' worth: the last pixel of a batch may
/// continue in the next). It leaves out the scene and the structure; used to refuse
/// renders that cannot fit.
pub fn peak_buffer_bytes(
    integrator: IntegratorKind,
    products: &SampleProducts,
    opts: &RenderOptions,
    workers: usize,
) -> u64 {
    let ray = size_of::<Ray>() as u64;
    let tiles = (opts.width.div_ceil(TILE) as u64) * (opts.height.div_ceil(TILE) as u64);
    let workers = (workers.max(1) as u64).min(tiles.max(1));
    let per_worker = match integrator {
        IntegratorKind::Whitted => products.camera.saturating_mul(ray + 8),
        IntegratorKind::Wavefront => {
            let vec3 = size_of::<Vec3>() as u64;
            // queue entry: ray, slot, weight, throughput, path id
            let queue = ray + 4 + 2 * vec3 + 8;
            let shadow = ray + 4 + vec3 + 1;
            // hit, occlusion flag, accumulator and pixel index of a camera sample
            let scratch = size_of::<Option<SceneHit>>() as u64 + 1 + vec3 + 8;
            let wave = MAX_WAVE_PATHS as u64 * (queue.max(shadow) + scratch);
            let pixels_in_flight = products.camera.saturating_mul(2 * (ray + 8 + vec3));
            pixels_in_flight.saturating_add(wave)
        }
    };
    per_worker.saturating_mul(workers)
}

/// Memory available to this process: `MemAvailable` of `/proc/meminfo`, or
/// [`FALLBACK_MEMORY_BUDGET`] where that cannot be read.
pub fn available_memory() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("MemAvailable:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(FALLBACK_MEMORY_BUDGET, |kb| kb.saturating_mul(1024))
}

/// Refuses an estimated peak above `limit` bytes, saying both.
pub fn check_memory(estimate: u64, limit: u64, integrator: IntegratorKind) -> Result<()> {
    if estimate > limit {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        return Err(Error::parameter(
            "sample counts",
            format!(
                "the {integrator} integrator's buffers would need about {:.1} GiB \
                 (estimated from the sample counts, tile size and threads), more than the \
                 {:.1} GiB available: lower the sample counts or --threads",
                gib(estimate),
                gib(limit)
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{CameraEffects, Light, Material, SceneBuilder};

    /// A scene with depth of field and one area light.
    fn dof_scene() -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::default());
        b.add_sphere(Vec3::ZERO, 1.0, m);
        b.add_light(Light::Sphere {
            center: Vec3::new(0.0, 3.0, 0.0),
            radius: 0.5,
            radiance: Vec3::ONE,
        });
        b.camera_effects = CameraEffects {
            aperture: 0.1,
            ..Default::default()
        };
        b.finish().unwrap()
    }

    #[test]
    fn products_are_checked_in_64_bits() {
        let scene = dof_scene();
        let mut o = RenderOptions::from_scene(&scene);
        o.width = 16;
        o.height = 16;
        o.spp = 65536;
        o.samples.lens = 1024;
        o.samples.shadow = 1024;
        // 2^26 camera rays per pixel: was an overflow of u32 products downstream
        let e = validate_sample_products(&scene, &o)
            .unwrap_err()
            .to_string();
        assert!(e.contains("67108864 camera rays per pixel"), "{e}");
        o.samples.lens = 256;
        let p = validate_sample_products(&scene, &o).unwrap();
        assert_eq!(p.camera, 1 << 24);
        assert_eq!(p.shadow, 1 << 34);
    }

    #[test]
    fn wavefront_estimate_scales_with_samples_and_workers() {
        let scene = dof_scene();
        let mut o = RenderOptions::from_scene(&scene);
        // Four tiles.
        o.width = 2 * TILE;
        o.height = 2 * TILE;
        o.spp = 1024;
        o.samples.lens = 16;
        o.samples.shadow = 1;
        let p = validate_sample_products(&scene, &o).unwrap();
        let w = IntegratorKind::Wavefront;
        let one = peak_buffer_bytes(w, &p, &o, 1);
        // Two pixels of 16384 camera rays plus one bounded wave: not 256 pixels' worth,
        // as before the queues were bounded (that estimate was 100x the recursive one).
        let whitted = peak_buffer_bytes(IntegratorKind::Whitted, &p, &o, 1);
        assert!(one >= 2 * 16384 * size_of::<Ray>() as u64, "{one}");
        assert!(
            one < 4 * whitted + MAX_WAVE_PATHS as u64 * 256,
            "{whitted} {one}"
        );
        // The wave part does not grow with the sample counts, the pixel part does.
        o.spp = 1;
        let p1 = validate_sample_products(&scene, &o).unwrap();
        let small = peak_buffer_bytes(w, &p1, &o, 1);
        assert!(
            small >= MAX_WAVE_PATHS as u64 * size_of::<Ray>() as u64,
            "{small}"
        );
        assert!(small < one, "{small} {one}");
        // four tiles: four workers at most
        assert_eq!(peak_buffer_bytes(w, &p1, &o, 4), 4 * small);
        assert_eq!(peak_buffer_bytes(w, &p1, &o, 100), 4 * small);
        assert!(check_memory(one, one, w).is_ok());
        let e = check_memory(one + 1, one, w).unwrap_err().to_string();
        assert!(e.contains("GiB") && e.contains("wavefront"), "{e}");
    }

    #[test]
    fn threads_are_capped() {
        assert!(validate_threads(0).is_ok());
        assert!(validate_threads(MAX_THREADS).is_ok());
        let e = validate_threads(100_000).unwrap_err().to_string();
        assert!(e.contains("at most 1024"), "{e}");
    }
}
