//! Ray generation: the sample counts a render uses ([`SamplePlan`]) and the camera
//! rays of a pixel (`CameraSampler::pixel_samples`): pixel positions (any
//! [`SamplerKind`]), lens points (depth of field) and shutter times (motion blur),
//! drawn from the pixel's own random stream, so that every integrator generates the
//! same rays for a pixel whatever the thread count or the order of tiles.

use super::sampling::{Dimension, PixelRng, decorrelate, fill_1d, fill_2d};
use super::sobol::{SobolDim, SobolSet};
use super::{FilterKind, RenderOptions, SamplerKind};
use crate::geometry::Ray;
use crate::geometry::warp::sample_aperture;
use crate::scene::{CameraFrame, LensFrame, Scene};
use crate::stats::EffectSamplesDrawn;

/// The sample counts a render actually uses: a count for an effect the scene lacks is
/// 1 and draws nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SamplePlan {
    pub eye: u32,
    /// Lens samples per eye sample; 0 when the scene has no depth of field.
    pub lens: u32,
    /// Shutter times per lens sample; 0 when nothing moves.
    pub time: u32,
    pub shadow: u32,
    pub glossy: u32,
    /// Directions towards the environment per lit shading point; 0 when the scene has
    /// no (non-black) environment.
    pub environment: u32,
    pub sampler: SamplerKind,
    pub filter: FilterKind,
    /// The eye samples rendered, `eye_begin..eye_end` of `0..eye` (all of them unless
    /// `--sample-range` picks a round). The pattern is always drawn for all `eye`.
    pub eye_begin: u32,
    pub eye_end: u32,
}

impl SamplePlan {
    pub fn new(scene: &Scene, opts: &RenderOptions) -> Self {
        let f = &scene.features;
        SamplePlan {
            eye: opts.spp.max(1),
            lens: if f.depth_of_field {
                opts.samples.lens
            } else {
                0
            },
            time: if f.motion { opts.samples.time } else { 0 },
            shadow: opts.samples.shadow,
            glossy: opts.samples.glossy,
            environment: if f.environment {
                opts.samples.environment
            } else {
                0
            },
            sampler: opts.sampler,
            filter: opts.filter,
            eye_begin: opts.sample_range.as_ref().map_or(0, |r| r.start),
            eye_end: opts
                .sample_range
                .as_ref()
                .map_or(opts.spp.max(1), |r| r.end),
        }
    }

    /// Eye samples rendered per pixel (`eye_end - eye_begin`).
    pub fn eye_rendered(&self) -> u32 {
        self.eye_end - self.eye_begin
    }

    /// Path identity of the first camera ray rendered: camera rays are numbered over
    /// all `eye` samples of the pixel, so a round's rays keep the numbers (and the
    /// random streams) they have in a render of all samples.
    pub fn first_path(&self) -> u64 {
        self.eye_begin as u64 * (self.lens.max(1) * self.time.max(1)) as u64
    }

    /// Camera rays per pixel: `eye * lens * time` (absent effects count 1).
    pub fn camera_rays_per_pixel(&self) -> u32 {
        self.eye * self.lens.max(1) * self.time.max(1)
    }
}

/// Everything that turns sample positions into camera rays.
#[derive(Clone, Copy)]
pub(crate) struct CameraSampler {
    pub frame: CameraFrame,
    pub lens: LensFrame,
    pub plan: SamplePlan,
}

/// The camera samples of one pixel: the pixel offsets of the eye samples rendered
/// (`eye_begin..eye_end`), and for each of them `rays_per_eye` rays (lens points times
/// shutter times), eye sample major.
#[derive(Default)]
pub(crate) struct PixelSamples {
    /// Offset of each eye sample inside the pixel (or the filter footprint).
    pub offsets: Vec<(f32, f32)>,
    pub rays: Vec<Ray>,
    pub(crate) pixel_pos: Vec<(f32, f32)>,
    pub(crate) lens_pos: Vec<(f32, f32)>,
    pub(crate) times: Vec<f32>,
}

impl CameraSampler {
    /// The camera of `scene` at the image size of `opts`, with the render's plan.
    pub fn new(scene: &Scene, opts: &RenderOptions) -> Self {
        CameraSampler {
            frame: scene.camera_frame(opts.width, opts.height),
            lens: LensFrame::new(&scene.camera, &scene.camera_effects),
            plan: SamplePlan::new(scene, opts),
        }
    }

    /// Camera rays per eye sample: `lens * time` (absent effects count 1).
    pub fn rays_per_eye(&self) -> u32 {
        self.plan.lens.max(1) * self.plan.time.max(1)
    }

    /// The camera rays of pixel `(x, y)` (`index` in the image), drawn from the pixel's
    /// own stream. Draw order is fixed: pixel positions, lens points, shutter times. A
    /// scene with no lens and no motion draws the pixel positions only, exactly as the
    /// plain Whitted renderer did.
    pub fn pixel_samples(
        &self,
        seed: u64,
        index: u64,
        x: u32,
        y: u32,
        out: &mut PixelSamples,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
        let sobol = self.pixel_sets(seed, index, out, drawn);
        // Box: samples inside the pixel; otherwise over the filter's footprint.
        let footprint = 2.0 * plan.filter.radius();
        out.offsets.clear();
        out.rays.clear();
        for e in plan.eye_begin as usize..plan.eye_end as usize {
            let (sx, sy) = match &sobol {
                Some(sets) => sets[0].point(e as u32),
                None => out.pixel_pos[e],
            };
            let (ox, oy) = if plan.filter == FilterKind::Box {
                (sx, sy)
            } else {
                (0.5 + (sx - 0.5) * footprint, 0.5 + (sy - 0.5) * footprint)
            };
            out.offsets.push((ox, oy));
            let pinhole = self.frame.ray(x as f32 + ox, y as f32 + oy);
            for l in 0..lens_n {
                let lens_index = e * lens_n as usize + l as usize;
                let lens_point = (plan.lens > 0).then(|| {
                    let (u, v) = match &sobol {
                        Some(sets) => sets[1].point(lens_index as u32),
                        None => out.lens_pos[lens_index],
                    };
                    sample_aperture(u, v, self.lens.blades, self.lens.rotation)
                });
                for t in 0..time_n {
                    let time = if plan.time > 0 {
                        let k = lens_index * time_n as usize + t as usize;
                        self.lens.time(match &sobol {
                            Some(sets) => sets[2].value(k as u32),
                            None => out.times[k],
                        })
                    } else {
                        self.lens.shutter[0]
                    };
                    out.rays
                        .push(self.lens.ray(&self.frame, pinhole, lens_point, time));
                }
            }
        }
    }

    /// The sample sets of pixel `index`: the Sobol sampler computes each point from
    /// its index (only the rendered ones, counted in `drawn`) and returns its sets
    /// (pixel, lens, time); the other samplers draw every set of the pixel into `sets`,
    /// in a fixed order ([`draw_sets`](Self::draw_sets)), and return `None`. Shared by
    /// the scalar [`pixel_samples`](Self::pixel_samples) and the lane-parallel
    /// `block_rays`.
    pub(crate) fn pixel_sets(
        &self,
        seed: u64,
        index: u64,
        sets: &mut PixelSamples,
        drawn: &mut EffectSamplesDrawn,
    ) -> Option<[SobolSet; 3]> {
        let plan = self.plan;
        if plan.sampler != SamplerKind::Sobol {
            self.draw_sets(seed, index, sets, drawn);
            return None;
        }
        let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
        let rendered = (plan.eye_end - plan.eye_begin) as u64;
        if plan.lens > 0 {
            drawn.lens += rendered * lens_n as u64;
        }
        if plan.time > 0 {
            drawn.time += rendered * (lens_n * time_n) as u64;
        }
        Some(
            [SobolDim::Pixel, SobolDim::Lens, SobolDim::Time]
                .map(|d| SobolSet::new(seed, index, d)),
        )
    }

    /// Draws every camera set of the pixel (all `eye` samples) from the pixel's own
    /// stream, for the patterns that are drawn as whole sets. Draw order is fixed:
    /// pixel positions, lens points, shutter times.
    pub(crate) fn draw_sets(
        &self,
        seed: u64,
        index: u64,
        out: &mut PixelSamples,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
        let rng = &mut PixelRng::new(seed, index);
        fill_2d(
            plan.sampler,
            plan.eye,
            Dimension::Pixel,
            true,
            rng,
            &mut out.pixel_pos,
        );
        if plan.lens > 0 {
            let n = plan.eye * lens_n;
            fill_2d(
                plan.sampler,
                n,
                Dimension::Lens,
                false,
                rng,
                &mut out.lens_pos,
            );
            decorrelate(plan.sampler, &mut out.lens_pos, rng);
            drawn.lens += n as u64;
        }
        if plan.time > 0 {
            let n = plan.eye * lens_n * time_n;
            fill_1d(plan.sampler, n, Dimension::Time, rng, &mut out.times);
            decorrelate(plan.sampler, &mut out.times, rng);
            drawn.time += n as u64;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A round of the first 4 of 16 eye samples (`--sample-range 0..4`, or the first
    /// progressive pass): with the Sobol sampler their pixel positions are a
    /// (0,2,2)-net, one in each quarter of the pixel in every elementary shape; the
    /// jittered pattern (the behaviour before) orders strata row by row, so its first
    /// 4 all lie in the top row of strata, in every pixel.
    #[test]
    fn a_prefix_of_sobol_pixel_positions_is_stratified_and_of_jittered_is_not() {
        use crate::integrator::sobol::is_0m2_net;
        let mut pos = Vec::new();
        for pixel in 0..64 {
            let set = SobolSet::new(1, pixel, SobolDim::Pixel);
            let sobol: Vec<_> = (0..4).map(|i| set.point(i)).collect();
            assert!(is_0m2_net(&sobol), "pixel {pixel}: {sobol:?}");
            let mut rng = PixelRng::new(1, pixel);
            fill_2d(
                SamplerKind::Jittered,
                16,
                Dimension::Pixel,
                true,
                &mut rng,
                &mut pos,
            );
            assert!(!is_0m2_net(&pos[..4]), "pixel {pixel}: {:?}", &pos[..4]);
            assert!(pos[..4].iter().all(|p| p.1 < 0.25));
        }
    }
}
