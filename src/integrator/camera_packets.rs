//! Camera rays for many pixels at once, built lane-parallel
//! ([`crate::simd::camera::camera_rays`], 16 rays per step) from the sampler's points.
//!
//! `CameraSampler::pixel_samples` stays the scalar oracle: for the same pixels,
//! `CameraSampler::block_rays` returns the same eye-sample offsets and the same rays
//! bit for bit, in the same order (pixel by pixel, eye sample major, then lens points,
//! then shutter times), and counts the same samples drawn. The sample sets themselves
//! are drawn per pixel by the scalar sampler (each pixel has its own random stream);
//! a plan whose pixel positions are the same in every pixel (the grid, or one jittered
//! sample at the centre, without lens or shutter) draws them once per call.

use super::SamplerKind;
use super::camera_rays::{CameraSampler, PixelSamples};
use crate::geometry::Ray;
use crate::geometry::warp::sample_aperture;
use crate::simd::camera::{camera_rays, shutter_times};
use crate::simd::{Lanes, PACKET_WIDTH, Packet};
use crate::stats::EffectSamplesDrawn;

/// Reusable staging buffers of [`CameraSampler::block_rays`]: one entry per ray,
/// structure of arrays, padded to whole packets.
#[derive(Default)]
pub(crate) struct CameraStaging {
    sets: PixelSamples,
    px: Vec<f32>,
    py: Vec<f32>,
    lx: Vec<f32>,
    ly: Vec<f32>,
    tu: Vec<f32>,
    /// Eye-sample offsets shared by every pixel (constant plans only).
    constant: Vec<(f32, f32)>,
}

impl CameraSampler {
    /// Whether every pixel has the same eye-sample offsets and draws nothing: no
    /// lens, no shutter, and a pixel pattern without randomness.
    fn constant_offsets(&self) -> bool {
        let p = self.plan;
        p.lens == 0
            && p.time == 0
            && (p.sampler == SamplerKind::Grid
                || (p.sampler == SamplerKind::Jittered && p.eye == 1))
    }

    /// The camera rays of `pixels` (`(x, y, index in the image)`), appended to `rays`,
    /// and their eye-sample offsets, appended to `offsets`: exactly what
    /// [`pixel_samples`](CameraSampler::pixel_samples) gives pixel by pixel.
    pub fn block_rays(
        &self,
        seed: u64,
        pixels: &[(u32, u32, u64)],
        st: &mut CameraStaging,
        offsets: &mut Vec<(f32, f32)>,
        rays: &mut Vec<Ray>,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1) as usize, plan.time.max(1) as usize);
        let footprint = 2.0 * plan.filter.radius();
        let box_filter = plan.filter == super::FilterKind::Box;
        let offset = |(sx, sy): (f32, f32)| {
            if box_filter {
                (sx, sy)
            } else {
                (0.5 + (sx - 0.5) * footprint, 0.5 + (sy - 0.5) * footprint)
            }
        };
        for v in [&mut st.px, &mut st.py, &mut st.lx, &mut st.ly, &mut st.tu] {
            v.clear();
        }
        let constant = self.constant_offsets();
        if constant {
            // No random draws: the sets of pixel 0 are the sets of every pixel.
            self.draw_sets(seed, 0, &mut st.sets, drawn);
            st.constant.clear();
            let eyes = plan.eye_begin as usize..plan.eye_end as usize;
            st.constant
                .extend(st.sets.pixel_pos[eyes].iter().map(|&p| offset(p)));
            if let [(ox, oy)] = st.constant[..] {
                // One offset (the usual 1-sample frame): image points straight into
                // lanes, 16 pixels at a time, with no staging arrays.
                offsets.extend(std::iter::repeat_n((ox, oy), pixels.len()));
                rays.reserve(pixels.len());
                let closed = Packet::splat(self.lens.shutter[0]);
                for chunk in pixels.chunks(PACKET_WIDTH) {
                    let (mut px, mut py) = ([0.5f32; PACKET_WIDTH], [0.5f32; PACKET_WIDTH]);
                    for (i, &(x, y, _)) in chunk.iter().enumerate() {
                        (px[i], py[i]) = (x as f32 + ox, y as f32 + oy);
                    }
                    let (px, py) = (Packet::new(px), Packet::new(py));
                    camera_rays(&self.frame, &self.lens, px, py, None, closed)
                        .append(chunk.len(), rays);
                }
                return;
            }
        }
        for &(x, y, index) in pixels {
            if constant {
                offsets.extend_from_slice(&st.constant);
                for &(ox, oy) in &st.constant {
                    st.px.push(x as f32 + ox);
                    st.py.push(y as f32 + oy);
                }
                continue;
            }
            let sobol = self.pixel_sets(seed, index, &mut st.sets, drawn);
            let sets = &st.sets;
            for e in plan.eye_begin as usize..plan.eye_end as usize {
                let (ox, oy) = offset(match &sobol {
                    Some(s) => s[0].point(e as u32),
                    None => sets.pixel_pos[e],
                });
                offsets.push((ox, oy));
                let (px, py) = (x as f32 + ox, y as f32 + oy);
                for l in 0..lens_n {
                    let lens_index = e * lens_n + l;
                    let lens_point = if plan.lens > 0 {
                        let (u, v) = match &sobol {
                            Some(s) => s[1].point(lens_index as u32),
                            None => sets.lens_pos[lens_index],
                        };
                        sample_aperture(u, v, self.lens.blades, self.lens.rotation)
                    } else {
                        glam::Vec2::ZERO
                    };
                    for t in 0..time_n {
                        let k = lens_index * time_n + t;
                        let u = if plan.time > 0 {
                            match &sobol {
                                Some(s) => s[2].value(k as u32),
                                None => sets.times[k],
                            }
                        } else {
                            0.0
                        };
                        st.px.push(px);
                        st.py.push(py);
                        st.lx.push(lens_point.x);
                        st.ly.push(lens_point.y);
                        st.tu.push(u);
                    }
                }
            }
        }
        // Lane-parallel ray construction, a packet at a time.
        let n = st.px.len();
        let padded = n.div_ceil(PACKET_WIDTH) * PACKET_WIDTH;
        st.px.resize(padded, 0.5);
        st.py.resize(padded, 0.5);
        let with_lens = plan.lens > 0;
        let with_time = plan.time > 0;
        if with_lens || with_time {
            st.lx.resize(padded, 0.0);
            st.ly.resize(padded, 0.0);
            st.tu.resize(padded, 0.0);
        }
        rays.reserve(n);
        let closed = Packet::splat(self.lens.shutter[0]);
        for start in (0..n).step_by(PACKET_WIDTH) {
            let end = start + PACKET_WIDTH;
            let px = Packet::load(&st.px[start..end]);
            let py = Packet::load(&st.py[start..end]);
            let lens = with_lens.then(|| {
                (
                    Packet::load(&st.lx[start..end]),
                    Packet::load(&st.ly[start..end]),
                )
            });
            let time = if with_time {
                shutter_times(&self.lens, Packet::load(&st.tu[start..end]))
            } else {
                closed
            };
            camera_rays(&self.frame, &self.lens, px, py, lens, time)
                .append((n - start).min(PACKET_WIDTH), rays);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::camera_rays::SamplePlan;
    use crate::integrator::{FilterKind, SamplerKind};
    use crate::scene::{Camera, CameraEffects, LensFrame};
    use glam::Vec3;

    /// Every sampler, both filters, with and without lens, shutter, eye motion and
    /// orthographic projection, a sample range: the lane-parallel rays are the scalar
    /// oracle's bit for bit, with the same offsets and the same samples counted.
    #[test]
    fn block_rays_equal_pixel_samples_ray_for_ray() {
        let cam = Camera {
            eye: Vec3::new(0.3, 1.7, 5.2),
            target: Vec3::new(-0.2, 0.4, 0.1),
            up: Vec3::Y,
            vfov_deg: 41.0,
        };
        let dof = CameraEffects {
            aperture: 0.2,
            aperture_blades: 6,
            aperture_rotation_deg: 10.0,
            shutter: [0.25, 1.5],
            eye1: Some(Vec3::new(0.5, 1.5, 4.0)),
            ..Default::default()
        };
        let ortho = CameraEffects {
            ortho_height: Some(2.0),
            ..Default::default()
        };
        let pixels: Vec<(u32, u32, u64)> = (0..23u32)
            .map(|i| (i % 7 + 3, i / 7 + 2, ((i / 7 + 2) * 40 + i % 7 + 3) as u64))
            .collect();
        let mut cases = 0;
        for &sampler in SamplerKind::ALL {
            for filter in [FilterKind::Box, FilterKind::Gaussian] {
                for (effects, lens, time) in [
                    (CameraEffects::default(), 0, 0),
                    (dof, 2, 0),
                    (dof, 0, 3),
                    (dof, 4, 2),
                    (ortho, 0, 0),
                ] {
                    for (eye, range) in [(1, 0..1), (4, 0..4), (9, 2..7)] {
                        let plan = SamplePlan {
                            eye,
                            lens,
                            time,
                            shadow: 1,
                            glossy: 1,
                            environment: 0,
                            sampler,
                            filter,
                            eye_begin: range.start,
                            eye_end: range.end,
                        };
                        let camera = CameraSampler {
                            frame: cam.frame(40, 30).with_effects(&effects),
                            lens: LensFrame::new(&cam, &effects),
                            plan,
                        };
                        let (mut want_rays, mut want_off) = (Vec::new(), Vec::new());
                        let mut want_drawn = EffectSamplesDrawn::default();
                        let mut s = PixelSamples::default();
                        for &(x, y, index) in &pixels {
                            camera.pixel_samples(5, index, x, y, &mut s, &mut want_drawn);
                            want_rays.extend_from_slice(&s.rays);
                            want_off.extend_from_slice(&s.offsets);
                        }
                        let (mut rays, mut off) = (Vec::new(), Vec::new());
                        let mut drawn = EffectSamplesDrawn::default();
                        let mut st = CameraStaging::default();
                        camera.block_rays(5, &pixels, &mut st, &mut off, &mut rays, &mut drawn);
                        let bits = |r: &Ray| {
                            [
                                r.origin.to_array(),
                                r.dir.to_array(),
                                [r.tmin, r.tmax, r.time],
                            ]
                            .map(|a| a.map(f32::to_bits))
                        };
                        assert_eq!(rays.len(), want_rays.len());
                        for (i, (g, w)) in rays.iter().zip(&want_rays).enumerate() {
                            assert_eq!(
                                bits(g),
                                bits(w),
                                "{sampler} {filter} lens {lens} time {time} eye {eye}: ray {i}: {g:?} vs {w:?}"
                            );
                        }
                        assert_eq!(off, want_off);
                        assert_eq!((drawn.lens, drawn.time), (want_drawn.lens, want_drawn.time));
                        cases += 1;
                    }
                }
            }
        }
        assert_eq!(cases, 5 * 2 * 5 * 3);
    }
}
