//! Camera rays for many pixels at once, built lane-parallel
//! ([`crate::simd::camera::camera_rays`], 16 rays per step) from the sampler's points.
//!
//! `CameraSampler::pixel_samples` stays the scalar oracle: for the same pixels,
//! `CameraSampler::block_rays` returns the same eye-sample offsets and the same rays
//! bit for bit, in the same order (pixel by pixel, eye sample major, then lens points,
//! then shutter times), and counts the same samples drawn. The sample sets themselves
//! are drawn per pixel by the scalar sampler (each pixel has its own random stream),
//! the lens set straight into coordinate arrays; a round lens's points are mapped onto
//! the disk in lanes ([`crate::simd::aperture`], the same bits as the oracle's
//! `sample_aperture`), a polygonal lens's from a table of its corners
//! ([`super::polygon_aperture`]). A plan whose pixel positions are the same in every
//! pixel (the grid, or one jittered sample at the centre, without lens or shutter)
//! draws them once per call.
//!
//! With a lens and a perspective frame, every ray of an eye sample passes through the
//! same focus point: the pinhole direction and the focus point (four divisions and a
//! square root per lane) are made once per eye sample ([`focus_points`]) and the rays
//! of its lens points from there ([`lens_rays`]), not per ray. perf (cpu-clock samples,
//! 1 thread, load ~10, whitted_blur16 1024x768): `block_rays` 333 -> 249 samples.
//!
//! Dead end (measured the same way): the lens set of a jittered plan with one eye
//! sample drawn in bulk, each SplitMix64 draw computed from its index (`start + j γ`)
//! so that LLVM ran the draws in 64-bit AVX-512 lanes (`vpmullq`), the shuffle's
//! draws too, then the points and the swaps: 280 samples against 275 for
//! `fill_2d_split` and `decorrelate_pairs` (that version still divided per point for
//! the stratum; it also had to restate `PixelRng`, private to sampling.rs). Left out.
//! What did pay later (branch cam15, whitted_blur16 1024x768, 1 thread, 5 interleaved
//! runs, load ~3 on 2 shared cores, camera stage 124/137/151 -> 115/125/145 ms
//! min/median/max, with the slot_pixel runs written in place): only the shuffle's
//! fifteen targets in lanes (`simd::splitmix::shuffle_targets16`) and each lens pair
//! swapped as one 64-bit value (`decorrelate_pairs`), the points' draws staying in
//! `fill_pairs16`.
//!
//! Measured (whitted_blur16, 16 lens samples per pixel, 1 thread, load ~7, 3
//! interleaved runs): camera stage 1067-1759 ms (median 1327) against 2623-2986 (2939)
//! with libm's `sincosf` per lens point and the lens set pushed ray by ray.
//!
//! A polygonal aperture's lens points are mapped sixteen at a time
//! (`simd::aperture::PolygonLanes`: the corner table in a register, each lane's two
//! corners by permutes), and a plan with one ray per eye sample (a lens point each or
//! none, no shutter: dof_area) stages an eye sample's offset, image point and lens
//! point in bulk per pixel. perf (dof_area 960x720, 1 thread, AVX-512): `block_rays`
//! 9.0 % -> 3.6 % of the frame's samples (the scalar table loop had been 29 % of
//! `block_rays`, the per-eye-sample staging loop 36 %). Camera stage (dof_area 320x240,
//! 1 thread, 7 rounds interleaved with the previous binary, flock'd, load 6-7, min /
//! median / max ms): 44/59/77 -> 23/37/46.

use super::SamplerKind;
use super::camera_rays::{CameraSampler, PixelSamples, SamplePlan};
use super::polygon_aperture::PolygonAperture;
use super::sampling::{
    Dimension, PixelRng, append_2d_split, decorrelate, decorrelate_pairs, fill_1d, fill_2d,
    fill_2d_split,
};
use crate::geometry::Ray;
use crate::scene::{CameraFrame, LensFrame};
use crate::simd::aperture::concentric_disk;
use crate::simd::camera::{
    RayLanes, camera_rays, column_term, focus_points, lens_rays, pinhole_rays, row_term,
    shutter_times,
};
use crate::simd::ray_store::UniformRays;
use crate::simd::{Lanes, PACKET_WIDTH, Packet};
use crate::stats::EffectSamplesDrawn;

/// The pixels of [`CameraSampler::block_rays`] (`(x, y, index in the image)`) and the
/// 4x4 blocks they consist of (or none).
pub(crate) type PixelBlocks<'a> = (&'a [(u32, u32, u64)], &'a [(u32, u32)]);

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
    /// Focus points, one per eye sample (thin lens, perspective frames), and per ray
    /// where the rays of an eye sample do not fill whole packets.
    focus: [Vec<f32>; 3],
    ray_focus: [Vec<f32>; 3],
    /// The pixel's lens set (all `eye * lens` points), split into coordinates.
    lu: Vec<f32>,
    lv: Vec<f32>,
    /// Eye-sample offsets shared by every pixel (constant plans only), and the seed
    /// and plan they were drawn for.
    constant: Vec<(f32, f32)>,
    constant_key: Option<(u64, SamplePlan)>,
    /// The pixels of whole 4x4 blocks, where `whole_block_rays` needs them listed.
    block_pixels: Vec<(u32, u32, u64)>,
    /// The offsets `whole_block_rays` makes for a caller that does not keep them.
    unread_offsets: Vec<(f32, f32)>,
    /// The corners of a polygonal aperture.
    polygon: PolygonAperture,
    /// Pinhole direction terms per image column and row (one-offset plans).
    terms: PinholeTerms,
    /// The store of rays from the eye at the shutter's open time (plain pinhole
    /// frames), with the bits of the eye and the time it was made for.
    uniform: Option<([u32; 4], UniformRays)>,
}

impl CameraStaging {
    /// The staged lens points of the packet starting at ray `start`, mapped to the unit
    /// disk lane by lane when `disk` (round apertures).
    fn lens_lanes(&self, start: usize, disk: bool) -> (Packet, Packet) {
        let end = start + PACKET_WIDTH;
        let (u, v) = (
            Packet::load(&self.lx[start..end]),
            Packet::load(&self.ly[start..end]),
        );
        if disk { concentric_disk(u, v) } else { (u, v) }
    }

    /// The shutter times of the packet starting at ray `start`: the staged draws
    /// mapped into the shutter interval `with_time`, else `closed` (the shutter's open
    /// time in every lane).
    fn time_lanes(
        &self,
        lens: &LensFrame,
        start: usize,
        with_time: bool,
        closed: Packet,
    ) -> Packet {
        if with_time {
            shutter_times(lens, Packet::load(&self.tu[start..start + PACKET_WIDTH]))
        } else {
            closed
        }
    }
}

/// The column and row terms of the pinhole direction
/// ([`crate::simd::camera::pinhole_rays`]) for every column and row of the image, at
/// the one eye-sample offset `(ox, oy)` of a constant plan: `cols[a][x]` is `forward[a]
/// + sx right[a]` at `px = x + ox`, `rows[a][y]` is `sy up[a]` at `py = y + oy`. Made
/// on first use and again whenever the frame or the offset differs (`key`).
#[derive(Default)]
struct PinholeTerms {
    key: Option<[u32; 17]>,
    cols: [Vec<f32>; 3],
    rows: [Vec<f32>; 3],
}

impl PinholeTerms {
    /// The terms for `frame` at offset `(ox, oy)`, made if they are not those.
    fn update(&mut self, frame: &CameraFrame, (ox, oy): (f32, f32)) -> &Self {
        let (e, f, r, u) = (frame.eye, frame.forward, frame.right, frame.up);
        let key = [
            e.x,
            e.y,
            e.z,
            f.x,
            f.y,
            f.z,
            r.x,
            r.y,
            r.z,
            u.x,
            u.y,
            u.z,
            frame.tan_half,
            frame.width,
            frame.height,
            ox,
            oy,
        ]
        .map(f32::to_bits);
        if self.key != Some(key) {
            // Pixel coordinates are integers below 2^24 here (the image size is
            // validated far below that), so `x as f32` is exact, as in the lane path.
            let (w, h) = (frame.width as usize, frame.height as usize);
            for c in &mut self.cols {
                c.clear();
            }
            for r in &mut self.rows {
                r.clear();
            }
            for x in 0..w {
                let t = column_term(frame, x as f32 + ox);
                for (c, t) in self.cols.iter_mut().zip(t) {
                    c.push(t);
                }
            }
            for y in 0..h {
                let t = row_term(frame, y as f32 + oy);
                for (r, t) in self.rows.iter_mut().zip(t) {
                    r.push(t);
                }
            }
            self.key = Some(key);
        }
        self
    }

    /// The rays of the 4x4 pixel block with top-left pixel `(bx, by)`, lane `i` at
    /// pixel `(bx + i % 4, by + i / 4)`; `None` if the block reaches past the tables.
    #[inline(always)]
    fn block(
        &self,
        eye: glam::Vec3,
        (bx, by): (u32, u32),
        time: Packet,
    ) -> Option<RayLanes<Packet>> {
        let (bx, by) = (bx as usize, by as usize);
        let col = |a: usize| -> Option<Packet> {
            let c: &[f32; 4] = self.cols[a].get(bx..bx + 4)?.try_into().ok()?;
            Some(Packet::new(std::array::from_fn(|i| c[i % 4])))
        };
        let row = |a: usize| -> Option<Packet> {
            let r: &[f32; 4] = self.rows[a].get(by..by + 4)?.try_into().ok()?;
            Some(Packet::new(std::array::from_fn(|i| r[i / 4])))
        };
        Some(pinhole_rays(
            eye,
            [col(0)?, col(1)?, col(2)?],
            [row(0)?, row(1)?, row(2)?],
            time,
        ))
    }
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

    /// Whether [`camera_rays`] reduces to [`pinhole_rays`] for this camera: a
    /// perspective frame, no lens, and no eye motion applied (no shutter interval or
    /// no motion).
    fn plain_pinhole(&self) -> bool {
        let [s0, s1] = self.lens.shutter;
        self.frame.ortho_half_height.is_none()
            && self.plan.lens == 0
            && !(self.lens.eye_motion != glam::Vec3::ZERO && s1 > s0)
    }

    /// Whether `block_rays` stages each pixel's whole lens set, in order, as its lens
    /// points (a lens, no shutter, every eye sample rendered, a sampler that draws the
    /// set: not Sobol), so that [`Self::draw_sets_split`] can append it to the staging
    /// arrays itself.
    fn direct_lens(&self) -> bool {
        let p = self.plan;
        p.lens > 0
            && p.time == 0
            && p.eye_begin == 0
            && p.eye_end == p.eye
            && p.sampler != SamplerKind::Sobol
    }

    /// The rays through `pixels` at the one offset `(ox, oy)`, 16 image points at a
    /// time into lanes, at the shutter time `closed`.
    fn point_rays(
        &self,
        pixels: &[(u32, u32, u64)],
        (ox, oy): (f32, f32),
        closed: Packet,
        rays: &mut Vec<Ray>,
    ) {
        for chunk in pixels.chunks(PACKET_WIDTH) {
            let (mut px, mut py) = ([0.5f32; PACKET_WIDTH], [0.5f32; PACKET_WIDTH]);
            if let Ok(full) = <&[_; PACKET_WIDTH]>::try_from(chunk) {
                // A whole packet: a fixed-length loop the compiler vectorises.
                px = full.map(|(x, _, _)| x as f32 + ox);
                py = full.map(|(_, y, _)| y as f32 + oy);
            } else {
                for (i, &(x, y, _)) in chunk.iter().enumerate() {
                    (px[i], py[i]) = (x as f32 + ox, y as f32 + oy);
                }
            }
            let (px, py) = (Packet::new(px), Packet::new(py));
            camera_rays(&self.frame, &self.lens, px, py, None, closed).append(chunk.len(), rays);
        }
    }

    /// [`draw_sets`](CameraSampler::draw_sets) for the lane path: the same draws from
    /// the pixel's stream in the same order, the same points, but the lens set goes
    /// into two coordinate arrays (`st.lu`, `st.lv`, written in place for a square
    /// jittered set, [`fill_2d_split`]) and is shuffled there, pairs kept together.
    /// With `direct` the lens set is appended to the staging arrays `st.lx`, `st.ly`
    /// instead ([`append_2d_split`]) and shuffled there: what `block_rays` would copy
    /// over when its rays take the whole set in order ([`Self::direct_lens`]).
    fn draw_sets_split(
        &self,
        seed: u64,
        index: u64,
        st: &mut CameraStaging,
        drawn: &mut EffectSamplesDrawn,
        direct: bool,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
        let rng = &mut PixelRng::new(seed, index);
        let out = &mut st.sets;
        fill_2d(
            plan.sampler,
            plan.eye,
            Dimension::Pixel,
            true,
            rng,
            &mut out.pixel_pos,
        );
        if plan.lens > 0 && direct {
            let n = plan.eye * lens_n;
            let start = st.lx.len();
            debug_assert_eq!(start, st.ly.len());
            append_2d_split(
                plan.sampler,
                n,
                Dimension::Lens,
                rng,
                (&mut st.lx, &mut st.ly),
                &mut out.lens_pos,
            );
            decorrelate_pairs(plan.sampler, &mut st.lx[start..], &mut st.ly[start..], rng);
            drawn.lens += n as u64;
        } else if plan.lens > 0 {
            let n = plan.eye * lens_n;
            fill_2d_split(
                plan.sampler,
                n,
                Dimension::Lens,
                rng,
                (&mut st.lu, &mut st.lv),
                &mut out.lens_pos,
            );
            decorrelate_pairs(
                plan.sampler,
                &mut st.lu[..n as usize],
                &mut st.lv[..n as usize],
                rng,
            );
            drawn.lens += n as u64;
        }
        if plan.time > 0 {
            let n = plan.eye * lens_n * time_n;
            fill_1d(plan.sampler, n, Dimension::Time, rng, &mut out.times);
            decorrelate(plan.sampler, &mut out.times, rng);
            drawn.time += n as u64;
        }
    }

    /// The thin-lens rays of a perspective frame from the staging arrays: image points
    /// per eye sample (`st.px`, `st.py`), lens points (`st.lx`, `st.ly`: unit square
    /// if `disk_lanes`, else already on the aperture) and shutter times (`st.tu`) per
    /// ray, `rays_per_eye` rays per eye sample. The focus points are made 16 eye
    /// samples at a time ([`focus_points`]); each packet of rays then takes its focus
    /// points from them (one splat when an eye sample's rays fill whole packets) and
    /// goes through the lens ([`lens_rays`]): the same bits as [`camera_rays`].
    fn focused_rays(&self, st: &mut CameraStaging, disk_lanes: bool, rays: &mut Vec<Ray>) {
        let rpe = self.rays_per_eye() as usize;
        let eyes = st.px.len();
        let n = st.lx.len();
        debug_assert_eq!(n, eyes * rpe);
        let padded = |k: usize| k.div_ceil(PACKET_WIDTH) * PACKET_WIDTH;
        st.px.resize(padded(eyes), 0.5);
        st.py.resize(padded(eyes), 0.5);
        for f in &mut st.focus {
            f.clear();
        }
        for start in (0..eyes).step_by(PACKET_WIDTH) {
            let end = start + PACKET_WIDTH;
            let (px, py) = (
                Packet::load(&st.px[start..end]),
                Packet::load(&st.py[start..end]),
            );
            let f = focus_points(&self.frame, &self.lens, px, py);
            for (v, f) in st.focus.iter_mut().zip(f) {
                v.extend_from_slice(f.to_array().as_ref());
            }
        }
        let whole = rpe.is_multiple_of(PACKET_WIDTH);
        if !whole {
            // Each eye sample's focus point repeated for its rays.
            for (r, f) in st.ray_focus.iter_mut().zip(&st.focus) {
                r.clear();
                for &v in &f[..eyes] {
                    r.resize(r.len() + rpe, v);
                }
                r.resize(padded(n), 0.0);
            }
        }
        st.lx.resize(padded(n), 0.0);
        st.ly.resize(padded(n), 0.0);
        let with_time = self.plan.time > 0;
        if with_time {
            st.tu.resize(padded(n), 0.0);
        }
        rays.reserve(n);
        let closed = Packet::splat(self.lens.shutter[0]);
        let st = &*st;
        let packet = |start: usize, focus: [Packet; 3], rays: &mut Vec<Ray>| {
            let lens = st.lens_lanes(start, disk_lanes);
            let time = st.time_lanes(&self.lens, start, with_time, closed);
            lens_rays(&self.frame, &self.lens, focus, lens, time)
                .append((n - start).min(PACKET_WIDTH), rays);
        };
        if whole {
            // Eye sample by eye sample, its focus point splatted once for its packets.
            // (Indexing the focus arrays by `start / rpe` per packet, through
            // `[0, 1, 2].map`, compiled to a division and an out-of-line `try_map`
            // whose result was reloaded from the stack: perf put 18 % of
            // `block_rays`'s samples on that reload, whitted_blur16 1024x768.)
            let per_eye = rpe / PACKET_WIDTH;
            let [fx, fy, fz] = &st.focus;
            for (e, ((&x, &y), &z)) in fx[..eyes]
                .iter()
                .zip(&fy[..eyes])
                .zip(&fz[..eyes])
                .enumerate()
            {
                let focus = [Packet::splat(x), Packet::splat(y), Packet::splat(z)];
                for j in 0..per_eye {
                    packet((e * per_eye + j) * PACKET_WIDTH, focus, rays);
                }
            }
        } else {
            for start in (0..n).step_by(PACKET_WIDTH) {
                let end = start + PACKET_WIDTH;
                let focus = [0, 1, 2].map(|a| Packet::load(&st.ray_focus[a][start..end]));
                packet(start, focus, rays);
            }
        }
    }

    /// The eye-sample offset of a pixel-pattern point `(sx, sy)` in the unit square:
    /// the point itself for the box filter, else scaled to the filter's footprint
    /// about the pixel centre.
    #[inline]
    fn eye_offset(&self, (sx, sy): (f32, f32)) -> (f32, f32) {
        let plan = self.plan;
        if plan.filter == super::FilterKind::Box {
            (sx, sy)
        } else {
            let footprint = 2.0 * plan.filter.radius();
            (0.5 + (sx - 0.5) * footprint, 0.5 + (sy - 0.5) * footprint)
        }
    }

    /// The eye-sample offsets of a constant plan ([`Self::constant_offsets`]) into
    /// `st.constant`: it draws nothing random, so the sets of pixel 0 are the sets of
    /// every pixel.
    ///
    /// Kept in `st` for the seed and plan (a constant plan draws no lens points nor
    /// shutter times, so `drawn` counts nothing): the wavefront asks once per tile,
    /// and drawing them again (a stream, the set, the offsets) showed among the
    /// camera stage's per-tile work (bunny 1024x1024, 16x16 tiles).
    fn draw_constant(&self, seed: u64, st: &mut CameraStaging, drawn: &mut EffectSamplesDrawn) {
        debug_assert!(self.constant_offsets());
        if st.constant_key == Some((seed, self.plan)) {
            return;
        }
        st.constant_key = Some((seed, self.plan));
        self.draw_sets(seed, 0, &mut st.sets, drawn);
        st.constant.clear();
        let eyes = self.plan.eye_begin as usize..self.plan.eye_end as usize;
        st.constant
            .extend(st.sets.pixel_pos[eyes].iter().map(|&p| self.eye_offset(p)));
    }

    /// Appends the rays of the 4x4 `blocks` at the one offset `(ox, oy)` of a plain
    /// pinhole ([`Self::plain_pinhole`]), each block's summed from per-column and
    /// per-row terms ([`PinholeTerms`]), until a block reaches past the image (past the
    /// tables); returns how many blocks were done.
    fn pinhole_blocks(
        &self,
        blocks: &[(u32, u32)],
        (ox, oy): (f32, f32),
        st: &mut CameraStaging,
        rays: &mut Vec<Ray>,
    ) -> usize {
        let closed = Packet::splat(self.lens.shutter[0]);
        let store = uniform_rays(&mut st.uniform, self.frame.eye, self.lens.shutter[0]);
        let terms = st.terms.update(&self.frame, (ox, oy));
        // Room for every block first, each block's rays written into it, and the
        // length raised once at the end ([`UniformRays::write16`]; appending block by
        // block kept the vector's length in memory, a store and a reload per block).
        rays.reserve(blocks.len() * PACKET_WIDTH);
        let mut done = 0;
        for (&b, dst) in blocks
            .iter()
            .zip(rays.spare_capacity_mut().chunks_exact_mut(PACKET_WIDTH))
        {
            let Some(lanes) = terms.block(self.frame.eye, b, closed) else {
                break;
            };
            // The eye and the open time in every lane: only the directions differ
            // ([`UniformRays`]).
            let d = lanes.dir.map(|l| l.to_array());
            let dst: &mut [_; PACKET_WIDTH] = dst.try_into().expect("chunks of 16");
            store.write16([&d[0], &d[1], &d[2]], dst);
            done += 1;
        }
        // SAFETY: `write16` initialised the first `done` chunks of 16 rays of the
        // spare capacity, the `done * 16` rays after the length, without a gap.
        unsafe { rays.set_len(rays.len() + done * PACKET_WIDTH) };
        done
    }

    /// [`block_rays`](CameraSampler::block_rays) of pixels given as whole 4x4 blocks
    /// only, without a list of pixels: block `(bx, by)` is pixels `(bx + i % 4, by + i
    /// / 4)` for `i` in `0..16`, index `y * width + x` ([`block_pixel_indices`]). With
    /// one offset per pixel and a plain pinhole (the usual 1-sample frame) the rays come
    /// from the blocks straight away; otherwise (and from a block past the image on)
    /// the pixels are listed in `st` first. The same rays, offsets and samples drawn
    /// as `block_rays` of those pixels; with `offsets` `None` the offsets are not kept
    /// (and, on the one-offset pinhole path, not written: see
    /// [`super::pixel_filter::reads_offsets`]).
    ///
    /// Measured (the wavefront's camera stage, bunny 1024x1024, 1 thread): the pixel
    /// list, 16 bytes a pixel built for every block only for `block_rays` to check its
    /// corners and the queue to copy out each index, was about a third of the stage's
    /// perf samples.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn whole_block_rays(
        &self,
        seed: u64,
        blocks: &[(u32, u32)],
        width: u32,
        st: &mut CameraStaging,
        offsets: Option<&mut Vec<(f32, f32)>>,
        rays: &mut Vec<Ray>,
        drawn: &mut EffectSamplesDrawn,
    ) {
        if self.constant_offsets() && self.plan.eye_rendered() == 1 && self.plain_pinhole() {
            self.draw_constant(seed, st, drawn);
            if let [(ox, oy)] = st.constant[..] {
                let n = blocks.len() * PACKET_WIDTH;
                if let Some(offsets) = offsets {
                    offsets.extend(std::iter::repeat_n((ox, oy), n));
                }
                rays.reserve(n);
                let from = self.pinhole_blocks(blocks, (ox, oy), st, rays);
                if from == blocks.len() {
                    return;
                }
                let mut rest = std::mem::take(&mut st.block_pixels);
                rest.clear();
                push_block_pixels(&blocks[from..], width, &mut rest);
                let closed = Packet::splat(self.lens.shutter[0]);
                self.point_rays(&rest, (ox, oy), closed, rays);
                st.block_pixels = rest;
                return;
            }
        }
        let mut pixels = std::mem::take(&mut st.block_pixels);
        pixels.clear();
        push_block_pixels(blocks, width, &mut pixels);
        let mut unread = std::mem::take(&mut st.unread_offsets);
        let offsets = offsets.unwrap_or(&mut unread);
        self.block_rays(seed, (&pixels, blocks), st, offsets, rays, drawn);
        unread.clear();
        st.unread_offsets = unread;
        st.block_pixels = pixels;
    }

    /// The camera rays of `pixels` (`(x, y, index in the image)`), appended to `rays`,
    /// and their eye-sample offsets, appended to `offsets`: exactly what
    /// [`pixel_samples`](CameraSampler::pixel_samples) gives pixel by pixel.
    ///
    /// `blocks` may name the 4x4 pixel blocks `pixels` consists of, in order (block
    /// `(bx, by)` is pixels `(bx + i % 4, by + i / 4, _)` for `i` in `0..16`), or be
    /// empty. With one eye-sample offset per pixel and a plain pinhole, the rays of a
    /// named block are summed from per-column and per-row terms
    /// ([`crate::simd::camera::pinhole_rays`], the same bits) instead of computing
    /// each image point; a `blocks` that does not match `pixels` is not used (its
    /// first and last pixels are checked per block).
    pub fn block_rays(
        &self,
        seed: u64,
        (pixels, blocks): PixelBlocks,
        st: &mut CameraStaging,
        offsets: &mut Vec<(f32, f32)>,
        rays: &mut Vec<Ray>,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1) as usize, plan.time.max(1) as usize);
        let offset = |s| self.eye_offset(s);
        for v in [&mut st.px, &mut st.py, &mut st.lx, &mut st.ly, &mut st.tu] {
            v.clear();
        }
        let constant = self.constant_offsets();
        // Thin lens, perspective: the image points are staged per eye sample and
        // their focus points made once each (`focused_rays`).
        // (One ray per eye sample shares nothing: the general path.)
        let focused =
            plan.lens > 0 && self.rays_per_eye() > 1 && self.frame.ortho_half_height.is_none();
        // The pixel's lens set drawn straight into `st.lx`, `st.ly`.
        let direct = self.direct_lens();
        if constant {
            self.draw_constant(seed, st, drawn);
            if let [(ox, oy)] = st.constant[..] {
                // One offset (the usual 1-sample frame): image points straight into
                // lanes, 16 pixels at a time, with no staging arrays.
                offsets.extend(std::iter::repeat_n((ox, oy), pixels.len()));
                rays.reserve(pixels.len());
                let closed = Packet::splat(self.lens.shutter[0]);
                let done = if self.plain_pinhole() && blocks_match(pixels, blocks) {
                    self.pinhole_blocks(blocks, (ox, oy), st, rays)
                } else {
                    0
                };
                // The general path for the rest (all, or from a block past the image).
                let rest = &pixels[done * PACKET_WIDTH..];
                self.point_rays(rest, (ox, oy), closed, rays);
                return;
            }
        }
        for &(x, y, index) in pixels {
            if constant {
                // One extend per array and pixel. Before: a push per offset and array
                // (a capacity check each), whose line held 44 % of this function's
                // samples at 9 grid offsets per pixel (perf annotate, whitted_base
                // `--spp 9 --sampler grid`, 1 thread).
                offsets.extend_from_slice(&st.constant);
                let (fx, fy) = (x as f32, y as f32);
                st.px.extend(st.constant.iter().map(|&(ox, _)| fx + ox));
                st.py.extend(st.constant.iter().map(|&(_, oy)| fy + oy));
                continue;
            }
            let sobol = if plan.sampler == SamplerKind::Sobol {
                self.pixel_sets(seed, index, &mut st.sets, drawn)
            } else {
                self.draw_sets_split(seed, index, st, drawn, direct);
                None
            };
            if sobol.is_none() && plan.time == 0 && lens_n == 1 && !focused {
                // One ray per eye sample (a lens point each, or none) from drawn
                // sets: the loop below in bulk, an eye sample's offset, image point
                // and lens point written together.
                let eyes = plan.eye_begin as usize..plan.eye_end as usize;
                let start = offsets.len();
                offsets.extend(st.sets.pixel_pos[eyes.clone()].iter().map(|&p| offset(p)));
                let (fx, fy) = (x as f32, y as f32);
                st.px
                    .extend(offsets[start..].iter().map(|&(ox, _)| fx + ox));
                st.py
                    .extend(offsets[start..].iter().map(|&(_, oy)| fy + oy));
                if plan.lens > 0 && !direct {
                    st.lx.extend_from_slice(&st.lu[eyes.clone()]);
                    st.ly.extend_from_slice(&st.lv[eyes]);
                }
                continue;
            }
            for e in plan.eye_begin as usize..plan.eye_end as usize {
                let (ox, oy) = offset(match &sobol {
                    Some(s) => s[0].point(e as u32),
                    None => st.sets.pixel_pos[e],
                });
                offsets.push((ox, oy));
                let (px, py) = (x as f32 + ox, y as f32 + oy);
                let first = e * lens_n;
                if focused {
                    // One image point per eye sample: its focus point is shared.
                    st.px.push(px);
                    st.py.push(py);
                }
                if plan.time == 0 {
                    // No shutter: one ray per lens point, written in bulk.
                    if !focused {
                        let len = st.px.len() + lens_n;
                        st.px.resize(len, px);
                        st.py.resize(len, py);
                    }
                    if plan.lens > 0 && !direct {
                        match &sobol {
                            Some(s) => {
                                for l in first..first + lens_n {
                                    let (u, v) = s[1].point(l as u32);
                                    st.lx.push(u);
                                    st.ly.push(v);
                                }
                            }
                            None => {
                                st.lx.extend_from_slice(&st.lu[first..first + lens_n]);
                                st.ly.extend_from_slice(&st.lv[first..first + lens_n]);
                            }
                        }
                    }
                    continue;
                }
                for lens_index in first..first + lens_n {
                    let (u, v) = if plan.lens > 0 {
                        match &sobol {
                            Some(s) => s[1].point(lens_index as u32),
                            None => (st.lu[lens_index], st.lv[lens_index]),
                        }
                    } else {
                        (0.5, 0.5)
                    };
                    for t in 0..time_n {
                        let k = lens_index * time_n + t;
                        if !focused {
                            st.px.push(px);
                            st.py.push(py);
                        }
                        st.lx.push(u);
                        st.ly.push(v);
                        st.tu.push(match &sobol {
                            Some(s) => s[2].value(k as u32),
                            None => st.sets.times[k],
                        });
                    }
                }
            }
        }
        // Polygonal apertures: the lens points from the (u, v) staged above, from a
        // table of the corners (`polygon_aperture`: in lanes up to 15 blades; libm's
        // cos and sin per point before); round ones are mapped in lanes below.
        let disk_lanes = plan.lens > 0 && self.lens.blades < 3;
        if plan.lens > 0 && !disk_lanes {
            let table = st.polygon.update(self.lens.blades, self.lens.rotation);
            table.map_points(&mut st.lx, &mut st.ly);
        }
        if focused {
            self.focused_rays(st, disk_lanes, rays);
            return;
        }
        // Lane-parallel ray construction, a packet at a time.
        let n = st.px.len();
        let padded = n.div_ceil(PACKET_WIDTH) * PACKET_WIDTH;
        st.px.resize(padded, 0.5);
        st.py.resize(padded, 0.5);
        let with_lens = plan.lens > 0;
        let with_time = plan.time > 0;
        if with_lens {
            st.lx.resize(padded, 0.0);
            st.ly.resize(padded, 0.0);
        }
        if with_time {
            st.tu.resize(padded, 0.0);
        }
        rays.reserve(n);
        let closed = Packet::splat(self.lens.shutter[0]);
        if !with_time && self.plain_pinhole() {
            // Every ray leaves the eye at the open time (several eye samples per
            // pixel, or a plan that draws them): only the directions are stored.
            let store = uniform_rays(&mut st.uniform, self.frame.eye, self.lens.shutter[0]);
            for start in (0..n).step_by(PACKET_WIDTH) {
                let end = start + PACKET_WIDTH;
                let px = Packet::load(&st.px[start..end]);
                let py = Packet::load(&st.py[start..end]);
                let lanes = camera_rays(&self.frame, &self.lens, px, py, None, closed);
                let d = lanes.dir.map(|l| l.to_array());
                store.append([&d[0], &d[1], &d[2]], (n - start).min(PACKET_WIDTH), rays);
            }
            return;
        }
        for start in (0..n).step_by(PACKET_WIDTH) {
            let end = start + PACKET_WIDTH;
            let px = Packet::load(&st.px[start..end]);
            let py = Packet::load(&st.py[start..end]);
            let lens = with_lens.then(|| st.lens_lanes(start, disk_lanes));
            let time = st.time_lanes(&self.lens, start, with_time, closed);
            camera_rays(&self.frame, &self.lens, px, py, lens, time)
                .append((n - start).min(PACKET_WIDTH), rays);
        }
    }
}

/// The store of rays leaving `eye` at `time` kept in `slot` ([`UniformRays`], made
/// once per worker and camera: its windows take longer to make than a tile's rays to
/// store), made if the one kept is not for those (compared by bits).
fn uniform_rays(
    slot: &mut Option<([u32; 4], UniformRays)>,
    eye: glam::Vec3,
    time: f32,
) -> &UniformRays {
    let key = [eye.x, eye.y, eye.z, time].map(f32::to_bits);
    if slot.as_ref().is_none_or(|(k, _)| *k != key) {
        *slot = None;
    }
    &slot
        .get_or_insert_with(|| (key, UniformRays::new(eye, time)))
        .1
}

/// The image indices (`y * width + x`) of the 4x4 block with top-left pixel `(bx,
/// by)`, lane `i` at pixel `(bx + i % 4, by + i / 4)`.
#[inline]
pub(crate) fn block_pixel_indices((bx, by): (u32, u32), width: u32) -> [u64; PACKET_WIDTH] {
    let (bx, by, w) = (bx as u64, by as u64, width as u64);
    std::array::from_fn(|i| (by + (i / 4) as u64) * w + bx + (i % 4) as u64)
}

/// Appends the 16 pixels of each of `blocks` (`(x, y, index in an image `width`
/// wide)`), block after block, lane order as [`block_pixel_indices`].
pub(crate) fn push_block_pixels(blocks: &[(u32, u32)], width: u32, out: &mut Vec<(u32, u32, u64)>) {
    for &(bx, by) in blocks {
        let index = block_pixel_indices((bx, by), width);
        out.extend((0..PACKET_WIDTH).map(|i| (bx + (i % 4) as u32, by + (i / 4) as u32, index[i])));
    }
}

/// Whether `pixels` are the 4x4 blocks `blocks` in order (see
/// [`CameraSampler::block_rays`]): the counts agree and each block's first and last
/// pixels are its corners (all sixteen are compared in debug builds).
fn blocks_match(pixels: &[(u32, u32, u64)], blocks: &[(u32, u32)]) -> bool {
    const B: usize = PACKET_WIDTH;
    const _: () = assert!(B == 16);
    !blocks.is_empty()
        && pixels.len() == B * blocks.len()
        && blocks
            .iter()
            .zip(pixels.chunks_exact(B))
            .all(|(&(bx, by), p)| {
                let corners = (p[0].0, p[0].1, p[B - 1].0, p[B - 1].1) == (bx, by, bx + 3, by + 3);
                debug_assert!(
                    !corners
                        || p.iter().enumerate().all(|(i, &(x, y, _))| {
                            (x, y) == (bx + i as u32 % 4, by + i as u32 / 4)
                        }),
                    "block ({bx}, {by}) does not match its pixels"
                );
                corners
            })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::camera_rays::SamplePlan;
    use crate::integrator::{FilterKind, SamplerKind};
    use crate::scene::{Camera, CameraEffects, LensFrame};
    use glam::Vec3;

    /// The scalar oracle's rays and offsets for `pixels` (seed 5), pixel after pixel.
    fn oracle_rays(
        camera: &CameraSampler,
        pixels: &[(u32, u32, u64)],
        drawn: &mut EffectSamplesDrawn,
    ) -> (Vec<Ray>, Vec<(f32, f32)>) {
        let (mut rays, mut off) = (Vec::new(), Vec::new());
        let mut s = PixelSamples::default();
        for &(x, y, index) in pixels {
            camera.pixel_samples(5, index, x, y, &mut s, drawn);
            rays.extend_from_slice(&s.rays);
            off.extend_from_slice(&s.offsets);
        }
        (rays, off)
    }

    /// [`CameraSampler::block_rays`]' rays and offsets for the same seed.
    fn block_rays_of(
        camera: &CameraSampler,
        pixels: PixelBlocks,
        st: &mut CameraStaging,
        drawn: &mut EffectSamplesDrawn,
    ) -> (Vec<Ray>, Vec<(f32, f32)>) {
        let (mut rays, mut off) = (Vec::new(), Vec::new());
        camera.block_rays(5, pixels, st, &mut off, &mut rays, drawn);
        (rays, off)
    }

    /// Every sampler, both filters, with and without lens (polygonal and round, 2 to
    /// 16 points per eye sample), shutter, eye motion and orthographic projection, a
    /// sample range: the lane-parallel rays are the scalar
    /// oracle's bit for bit, with the same offsets and the same samples counted. The
    /// lens sets of the samplers that draw them go straight into the staging arrays
    /// (`direct_lens`) without a shutter and where every eye sample is rendered (eye 1
    /// and 4; square sets of 9 and 16 points, lanes past a set's end among them), and
    /// through `st.lu`, `st.lv` otherwise (a shutter, or the range 2..7 of 9).
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
        // A round aperture (lens points mapped in lanes), moving, and the same
        // orthographic (the lens rays without focus points).
        let round = CameraEffects {
            aperture_blades: 0,
            ..dof
        };
        let ortho_round = CameraEffects {
            ortho_height: Some(2.0),
            ..round
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
                    // One polygonal lens point per eye sample: no focus points.
                    (dof, 1, 0),
                    (dof, 0, 3),
                    (dof, 4, 2),
                    (ortho, 0, 0),
                    // 16 rays per eye sample: one focus point per packet.
                    (round, 16, 0),
                    (round, 9, 0),
                    (round, 1, 0),
                    (round, 3, 2),
                    (round, 8, 2),
                    (ortho_round, 4, 1),
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
                        let mut want_drawn = EffectSamplesDrawn::default();
                        let (want_rays, want_off) = oracle_rays(&camera, &pixels, &mut want_drawn);
                        let mut drawn = EffectSamplesDrawn::default();
                        let mut st = CameraStaging::default();
                        let (rays, off) =
                            block_rays_of(&camera, (&pixels, &[]), &mut st, &mut drawn);
                        let bits = Ray::bits;
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
        assert_eq!(cases, 5 * 2 * 12 * 3);
    }

    /// Pixels given as 4x4 blocks (the wavefront's usual chunk): with one offset per
    /// pixel the rays come from per-column and per-row terms, and they are the scalar
    /// oracle's bit for bit, with the same offsets, for a perspective pinhole (terms),
    /// orthographic and moving cameras (the general path), blocks reaching past the
    /// image (the general path from there), both constant samplers and both filters;
    /// and a block list that does not match the pixels is not used.
    #[test]
    fn block_rays_of_4x4_blocks_equal_pixel_samples() {
        let cam = Camera {
            eye: Vec3::new(-0.4, 2.1, 4.7),
            target: Vec3::new(0.2, 0.3, -0.1),
            up: Vec3::Y,
            vfov_deg: 38.0,
        };
        let (moving, ortho) = moving_and_ortho();
        let (w, h) = (42, 30);
        // Every whole block of the image, then one reaching past its right edge.
        let mut blocks = whole_blocks(w, h);
        blocks.push((w - 2, 8));
        let pixels = block_pixels(&blocks, w);
        let shifted: Vec<(u32, u32)> = blocks.iter().map(|&(x, y)| (x, y + 1)).collect();
        let mut cases = 0;
        for (effects, terms) in [
            (CameraEffects::default(), true),
            (moving, false),
            (ortho, false),
        ] {
            for sampler in [SamplerKind::Jittered, SamplerKind::Grid] {
                for filter in [FilterKind::Box, FilterKind::Gaussian] {
                    let plan = pinhole_plan(sampler, 1, filter);
                    let camera = CameraSampler {
                        frame: cam.frame(w, h).with_effects(&effects),
                        lens: LensFrame::new(&cam, &effects),
                        plan,
                    };
                    assert!(camera.constant_offsets());
                    assert_eq!(camera.plain_pinhole(), terms);
                    let mut drawn = EffectSamplesDrawn::default();
                    let (want_rays, want_off) = oracle_rays(&camera, &pixels, &mut drawn);
                    let mut st = CameraStaging::default();
                    for list in [&blocks, &shifted] {
                        assert_eq!(blocks_match(&pixels, list), list == &blocks);
                        let (rays, off) =
                            block_rays_of(&camera, (&pixels, list), &mut st, &mut drawn);
                        assert_eq!(rays.len(), want_rays.len());
                        for (i, (g, r)) in rays.iter().zip(&want_rays).enumerate() {
                            let bits = Ray::bits;
                            assert_eq!(
                                bits(g),
                                bits(r),
                                "{sampler} {filter} ray {i}: {g:?} vs {r:?}"
                            );
                        }
                        assert_eq!(off, want_off);
                    }
                    // The terms were made for this camera (and only when used).
                    assert_eq!(st.terms.key.is_some(), terms);
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 12);
    }

    /// Whole 4x4 blocks given without a pixel list (`whole_block_rays`, the
    /// wavefront's chunks of whole blocks): the scalar oracle's rays bit for bit, the
    /// same offsets and samples drawn, for the pinhole-terms path (one offset: jittered
    /// 1 spp, grid 1 spp, a sample range of one), with a block past the image (the
    /// general path from there), and the listed-pixel paths (four grid offsets, a
    /// moving and an orthographic camera, a round lens with a shutter); and the listed
    /// pixels are the blocks' pixels in lane order.
    #[test]
    fn whole_block_rays_equal_pixel_samples() {
        let cam = Camera {
            eye: Vec3::new(0.6, 1.2, 4.4),
            target: Vec3::new(-0.3, 0.2, 0.0),
            up: Vec3::Y,
            vfov_deg: 44.0,
        };
        let (moving, ortho) = moving_and_ortho();
        let lens = CameraEffects {
            aperture: 0.2,
            aperture_blades: 0,
            shutter: [0.25, 1.5],
            ..Default::default()
        };
        let (w, h) = (36, 20);
        let mut blocks = whole_blocks(w, h);
        let inside = blocks.len();
        // Past the right edge, then one more inside: the general path from the first.
        blocks.push((w - 1, 4));
        blocks.push((8, 12));
        let pixels = block_pixels(&blocks, w);
        let mut listed = Vec::new();
        push_block_pixels(&blocks, w, &mut listed);
        assert_eq!(listed, pixels);
        for (k, &b) in blocks.iter().enumerate() {
            let want: Vec<u64> = pixels[16 * k..16 * (k + 1)].iter().map(|p| p.2).collect();
            assert_eq!(block_pixel_indices(b, w).to_vec(), want);
        }
        let mut cases = 0;
        for (effects, sampler, eye, range, (lens_n, time_n), terms) in [
            (
                CameraEffects::default(),
                SamplerKind::Jittered,
                1,
                0..1,
                (0, 0),
                true,
            ),
            (
                CameraEffects::default(),
                SamplerKind::Grid,
                1,
                0..1,
                (0, 0),
                true,
            ),
            (
                CameraEffects::default(),
                SamplerKind::Grid,
                4,
                2..3,
                (0, 0),
                true,
            ),
            (
                CameraEffects::default(),
                SamplerKind::Grid,
                4,
                0..4,
                (0, 0),
                false,
            ),
            (
                CameraEffects::default(),
                SamplerKind::Jittered,
                2,
                0..2,
                (0, 0),
                false,
            ),
            (moving, SamplerKind::Jittered, 1, 0..1, (0, 0), false),
            (ortho, SamplerKind::Grid, 1, 0..1, (0, 0), false),
            (lens, SamplerKind::Jittered, 1, 0..1, (4, 2), false),
        ] {
            for filter in [FilterKind::Box, FilterKind::Gaussian] {
                let camera = CameraSampler {
                    frame: cam.frame(w, h).with_effects(&effects),
                    lens: LensFrame::new(&cam, &effects),
                    plan: SamplePlan {
                        eye,
                        lens: lens_n,
                        time: time_n,
                        shadow: 1,
                        glossy: 1,
                        environment: 0,
                        sampler,
                        filter,
                        eye_begin: range.start,
                        eye_end: range.end,
                    },
                };
                let mut want_drawn = EffectSamplesDrawn::default();
                let (want_rays, want_off) = oracle_rays(&camera, &pixels, &mut want_drawn);
                // With the offsets kept, and without (the same rays and draws, no
                // offsets).
                for keep in [true, false] {
                    let mut st = CameraStaging::default();
                    let (mut rays, mut off) = (Vec::new(), Vec::new());
                    let mut drawn = EffectSamplesDrawn::default();
                    // Twice through one staging: the first call's state must not leak.
                    for (from, to) in [(0, inside), (inside, blocks.len())] {
                        camera.whole_block_rays(
                            5,
                            &blocks[from..to],
                            w,
                            &mut st,
                            keep.then_some(&mut off),
                            &mut rays,
                            &mut drawn,
                        );
                    }
                    assert_eq!(rays.len(), want_rays.len());
                    for (i, (g, r)) in rays.iter().zip(&want_rays).enumerate() {
                        assert_eq!(
                            g.bits(),
                            r.bits(),
                            "{sampler} {filter} eye {eye} lens {lens_n} ray {i}: {g:?} vs {r:?}"
                        );
                    }
                    assert_eq!(off, if keep { &want_off[..] } else { &[] });
                    assert!(st.unread_offsets.is_empty());
                    assert_eq!((drawn.lens, drawn.time), (want_drawn.lens, want_drawn.time));
                    // The pinhole terms were made exactly where the blocks skip the list.
                    assert_eq!(st.terms.key.is_some(), terms, "{sampler} eye {eye}");
                }
                cases += 1;
            }
        }
        assert_eq!(cases, 16);
    }

    /// A camera moving over the shutter and an orthographic one: the two effects that
    /// send 4x4 blocks down the general (listed-pixel) path.
    fn moving_and_ortho() -> (CameraEffects, CameraEffects) {
        let moving = CameraEffects {
            shutter: [0.0, 1.0],
            eye1: Some(Vec3::new(0.0, 2.0, 4.0)),
            ..Default::default()
        };
        let ortho = CameraEffects {
            ortho_height: Some(3.0),
            ..Default::default()
        };
        (moving, ortho)
    }

    /// A plan of `n` eye samples per pixel with `filter`, no lens and no shutter.
    fn pinhole_plan(sampler: SamplerKind, n: u32, filter: FilterKind) -> SamplePlan {
        SamplePlan {
            eye: n,
            lens: 0,
            time: 0,
            shadow: 1,
            glossy: 1,
            environment: 0,
            sampler,
            filter,
            eye_begin: 0,
            eye_end: n,
        }
    }

    /// The top-left corners of an image's whole 4x4 blocks, row by row.
    fn whole_blocks(w: u32, h: u32) -> Vec<(u32, u32)> {
        (0..h / 4)
            .flat_map(|by| (0..w / 4).map(move |bx| (4 * bx, 4 * by)))
            .collect()
    }

    /// The 16 pixels of each block (x, y, and the pixel index in an image `w` wide),
    /// block by block, row-major inside a block.
    fn block_pixels(blocks: &[(u32, u32)], w: u32) -> Vec<(u32, u32, u64)> {
        blocks
            .iter()
            .flat_map(|&(bx, by)| {
                (0..16u32).map(move |i| {
                    let (x, y) = (bx + i % 4, by + i / 4);
                    (x, y, (y * w + x) as u64)
                })
            })
            .collect()
    }

    /// One staging reused by constant plans that differ in filter, pattern or count
    /// (the offsets kept by `draw_constant` for a seed and plan): each call's offsets
    /// and rays are the scalar oracle's, on the 4x4-block path (one offset) and on the
    /// lane loop (several), whatever plan the staging served before, the same plan
    /// again included.
    #[test]
    fn kept_constant_offsets_follow_the_plan() {
        let (w, h) = (16u32, 8u32);
        let blocks = whole_blocks(w, h);
        let pixels = block_pixels(&blocks, w);
        let cam = Camera {
            eye: Vec3::new(0.3, 1.7, 5.2),
            target: Vec3::new(-0.2, 0.4, 0.1),
            up: Vec3::Y,
            vfov_deg: 41.0,
        };
        let effects = CameraEffects::default();
        let mut st = CameraStaging::default();
        let plans = [
            (SamplerKind::Grid, 4, FilterKind::Box),
            (SamplerKind::Grid, 4, FilterKind::Gaussian),
            (SamplerKind::Jittered, 1, FilterKind::Gaussian),
            (SamplerKind::Jittered, 1, FilterKind::Box),
            (SamplerKind::Jittered, 1, FilterKind::Box),
            (SamplerKind::Grid, 1, FilterKind::Gaussian),
            (SamplerKind::Grid, 9, FilterKind::Box),
            (SamplerKind::Grid, 4, FilterKind::Box),
        ];
        for (sampler, n, filter) in plans {
            let camera = CameraSampler {
                frame: cam.frame(w, h).with_effects(&effects),
                lens: LensFrame::new(&cam, &effects),
                plan: pinhole_plan(sampler, n, filter),
            };
            assert!(camera.constant_offsets());
            let mut want_drawn = EffectSamplesDrawn::default();
            let (want, want_off) = oracle_rays(&camera, &pixels, &mut want_drawn);
            let mut drawn = EffectSamplesDrawn::default();
            let (rays, off) = block_rays_of(&camera, (&pixels, &blocks), &mut st, &mut drawn);
            assert_eq!(off, want_off, "{sampler} {n} {filter}");
            assert_eq!(rays.len(), want.len());
            for (i, (g, r)) in rays.iter().zip(&want).enumerate() {
                assert_eq!(g.bits(), r.bits(), "{sampler} {n} {filter} ray {i}");
            }
            assert_eq!((drawn.lens, drawn.time), (want_drawn.lens, want_drawn.time));
        }
    }

    /// One staging reused by cameras of different eyes and shutter open times (as a
    /// worker's is from tile to tile): the kept store of rays from the eye
    /// ([`UniformRays`]) is remade for each, so the rays stay the scalar oracle's bit
    /// for bit, on the 4x4-block path (one offset) and on the lane loop (four grid
    /// offsets per pixel), and the store kept is the last camera's.
    #[test]
    fn a_reused_staging_follows_the_camera() {
        let (w, h) = (16u32, 8u32);
        let blocks = whole_blocks(w, h);
        let pixels = block_pixels(&blocks, w);
        let (a, b) = (Vec3::new(0.3, 1.7, 5.2), Vec3::new(-1.0, 0.5, 3.0));
        let mut st = CameraStaging::default();
        let mut cases = 0;
        for (eye, open) in [(a, 0.0), (b, 0.0), (b, 0.25), (a, 0.0)] {
            for (sampler, n) in [(SamplerKind::Jittered, 1), (SamplerKind::Grid, 4)] {
                let cam = Camera {
                    eye,
                    target: Vec3::new(-0.2, 0.4, 0.1),
                    up: Vec3::Y,
                    vfov_deg: 41.0,
                };
                let effects = CameraEffects {
                    shutter: [open, open + 0.5],
                    ..Default::default()
                };
                let camera = CameraSampler {
                    frame: cam.frame(w, h).with_effects(&effects),
                    lens: LensFrame::new(&cam, &effects),
                    plan: pinhole_plan(sampler, n, FilterKind::Box),
                };
                assert!(camera.plain_pinhole());
                let mut drawn = EffectSamplesDrawn::default();
                let (want, _) = oracle_rays(&camera, &pixels, &mut drawn);
                let (rays, _) = block_rays_of(&camera, (&pixels, &blocks), &mut st, &mut drawn);
                assert_eq!(rays.len(), want.len());
                for (i, (g, r)) in rays.iter().zip(&want).enumerate() {
                    assert_eq!(g.bits(), r.bits(), "{sampler} eye {eye} ray {i}");
                }
                let key = [eye.x, eye.y, eye.z, open].map(f32::to_bits);
                assert_eq!(st.uniform.as_ref().map(|u| u.0), Some(key));
                cases += 1;
            }
        }
        assert_eq!(cases, 8);
    }
}
