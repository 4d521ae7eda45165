//! The pixel filter step: the radiance of a pixel's camera rays, weighted by the
//! reconstruction filter ([`FilterKind`](super::FilterKind)) at each eye sample's
//! offset, into the pixel's exact filter sums.

use super::camera_rays::SamplePlan;
use crate::film::PixelSums;
use glam::Vec3;

/// Filters the radiance of a pixel's camera rays (`radiance[i]` for `rays[i]` of
/// [`PixelSamples`](super::camera_rays::PixelSamples)) into the pixel's filter sums ([`PixelSums::value`] is the pixel
/// value). A ray whose radiance is NaN or infinite is dropped and counted in
/// `nonfinite`; so is an eye sample whose mean overflows.
///
/// The sums are exact ([`ExactSum`](crate::film::exact_sum::ExactSum)), so they do not
/// depend on the order or grouping of the samples: rounds of samples rendered apart
/// and merged give the bits of one render of all of them.
pub(crate) fn resolve_pixel(
    plan: &SamplePlan,
    offsets: &[(f32, f32)],
    radiance: &[Vec3],
    nonfinite: &mut u64,
) -> PixelSums {
    let mut sums = PixelSums::default();
    resolve_pixel_into(plan, offsets, radiance, nonfinite, &mut sums);
    sums
}

/// Camera rays per eye sample.
fn per_eye(plan: &SamplePlan) -> usize {
    (plan.lens.max(1) * plan.time.max(1)) as usize
}

/// [`resolve_pixel`] adding into `sums` where they lie (the wavefront's tile buffer),
/// rather than returning them by value.
pub(crate) fn resolve_pixel_into(
    plan: &SamplePlan,
    offsets: &[(f32, f32)],
    radiance: &[Vec3],
    nonfinite: &mut u64,
    sums: &mut PixelSums,
) {
    if per_eye(plan) == 1 {
        for (&offset, &r) in offsets.iter().zip(radiance) {
            add_single(plan, offset, r, nonfinite, sums);
        }
    } else {
        add_means(plan, offsets, radiance, nonfinite, sums);
    }
}

/// Where [`resolve_pixels`] puts a tile's pixels: their values, and (for a partial
/// image, `--keep-sums`) their filter sums, each indexed by the pixel's row-major
/// position in the tile.
pub(crate) struct TileOut<'a> {
    pub values: &'a mut [Vec3],
    pub sums: Option<&'a mut [PixelSums]>,
}

/// Whether [`resolve_pixels`] reads the eye-sample offsets for `plan` (`sums`: the
/// tile keeps its pixels' sums): not for one box-filtered ray per pixel without kept
/// sums, whose value is the ray's radiance alone, so that a caller may leave them
/// out there (the wavefront's 1-sample frame: 8 bytes a camera ray written for
/// nothing).
pub(crate) fn reads_offsets(plan: &SamplePlan, sums: bool) -> bool {
    let rays = plan.eye_rendered() as usize * per_eye(plan);
    sums || rays != 1 || plan.filter != super::FilterKind::Box
}

/// The pixels of a tile at once, each with all its samples: pixel `g` has the
/// eye-sample offsets `offsets[g * eye..]`, the radiance `radiance[g * rays..]`
/// (`rays` per pixel) and its place `at[g]` in `out`. Each pixel's sums are built
/// on the stack and resolved into its value there and then (kept in `out.sums` only
/// when a partial image asks for them): no per-tile buffer of sums. One ray per pixel
/// without kept sums (the common frame) skips the sums altogether
/// ([`PixelSums::one_sample_value`], the same bits). `offsets` may be empty where
/// [`reads_offsets`] says they are not read.
pub(crate) fn resolve_pixels(
    plan: &SamplePlan,
    offsets: &[(f32, f32)],
    radiance: &[Vec3],
    at: &[u32],
    nonfinite: &mut u64,
    out: &mut TileOut,
) {
    let eye = plan.eye_rendered() as usize;
    let rays = eye * per_eye(plan);
    debug_assert!(
        offsets.len() == at.len() * eye || !reads_offsets(plan, out.sums.is_some()),
        "the offsets of every pixel, where they are read"
    );
    if let Some(sums) = &mut out.sums {
        for (g, &a) in at.iter().enumerate() {
            let s = &mut sums[a as usize];
            *s = PixelSums::default();
            resolve_pixel_into(
                plan,
                &offsets[g * eye..(g + 1) * eye],
                &radiance[g * rays..(g + 1) * rays],
                nonfinite,
                s,
            );
            out.values[a as usize] = s.value();
        }
        return;
    }
    if !reads_offsets(plan, false) {
        box_one_ray(radiance, at, nonfinite, out.values);
        return;
    }
    if rays == 1 {
        for ((&offset, &r), &a) in offsets.iter().zip(radiance).zip(at) {
            out.values[a as usize] = single_value(plan, offset, r, nonfinite);
        }
        return;
    }
    if eye == 1 {
        // One eye sample of several rays (lens or shutter samples): its mean is the
        // one sample of the pixel, so no sums.
        for ((&offset, r), &a) in offsets.iter().zip(radiance.chunks_exact(rays)).zip(at) {
            let mean = eye_mean(r, nonfinite);
            out.values[a as usize] = single_value(plan, offset, mean, nonfinite);
        }
        return;
    }
    let box_filter = plan.filter == super::FilterKind::Box;
    for (g, &a) in at.iter().enumerate() {
        let pixel = &radiance[g * rays..(g + 1) * rays];
        if box_filter && rays == eye {
            // Box filter, one ray per eye sample: three exact f64 sums when they
            // are exact (the same bits), else the general sums below.
            if let Some((value, dropped)) = PixelSums::box_mean_value(pixel) {
                *nonfinite += dropped;
                out.values[a as usize] = value;
                continue;
            }
        }
        let mut s = PixelSums::default();
        resolve_pixel_into(
            plan,
            &offsets[g * eye..(g + 1) * eye],
            &radiance[g * rays..(g + 1) * rays],
            nonfinite,
            &mut s,
        );
        out.values[a as usize] = s.value();
    }
}

/// One ray per pixel, box filter: weight 1, so [`single_value`] reduces to `r + 0`
/// (as `one_sample_value`), and black for a non-finite `r` (counted).
///
/// Four pixels at a time where they lie side by side in `values` (a 4x4 block's row,
/// as the wavefront generates them) and all twelve components are finite: one check of
/// the run, one bounds check, twelve additions the compiler vectorises; any other
/// pixel the plain way. Measured before (callgrind, bunny 1024x1024, 1 thread): the
/// plain loop, 29 instructions per pixel. Returns how many pixels went four at a time.
#[inline]
fn box_one_ray(radiance: &[Vec3], at: &[u32], nonfinite: &mut u64, values: &mut [Vec3]) -> usize {
    let one = |r: Vec3, nonfinite: &mut u64| {
        if r.is_finite() {
            r + Vec3::ZERO
        } else {
            *nonfinite += 1;
            Vec3::ZERO
        }
    };
    let n = radiance.len().min(at.len());
    let (mut g, mut runs) = (0, 0);
    while g < n {
        if let (Some(r), Some(a)) = (radiance.get(g..g + 4), at.get(g..g + 4)) {
            let a0 = a[0] as usize;
            let side_by_side =
                a[1] as usize == a0 + 1 && a[2] as usize == a0 + 2 && a[3] as usize == a0 + 3;
            let c: [f32; 12] = std::array::from_fn(|i| r[i / 3][i % 3]);
            // Finite: below infinity in magnitude (false for NaN), no early exit.
            let finite = c.iter().fold(true, |ok, x| ok & (x.abs() < f32::INFINITY));
            if side_by_side
                && finite
                && let Some(dst) = values.get_mut(a0..a0 + 4)
            {
                let v = c.map(|x| x + 0.0);
                for (k, d) in dst.iter_mut().enumerate() {
                    *d = Vec3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
                }
                (g, runs) = (g + 4, runs + 4);
                continue;
            }
        }
        values[at[g] as usize] = one(radiance[g], nonfinite);
        g += 1;
    }
    runs
}

/// The value of a pixel with one eye sample of one ray: what [`add_single`] into
/// empty sums and [`PixelSums::value`] give, bit for bit, and the same count of
/// dropped samples.
#[inline(always)]
fn single_value(plan: &SamplePlan, (ox, oy): (f32, f32), r: Vec3, nonfinite: &mut u64) -> Vec3 {
    let r = if r.is_finite() {
        r
    } else {
        *nonfinite += 1;
        Vec3::ZERO
    };
    let w = plan.filter.weight(ox - 0.5, oy - 0.5);
    if !(w * r).is_finite() {
        // Dropped: no sample, so the value of empty sums.
        *nonfinite += 1;
        return Vec3::ZERO;
    }
    PixelSums::one_sample_value(w, r)
}

/// One eye sample with one ray: no mean to take. The same sums as [`add_means`] with
/// one ray per eye sample (there `0 + r` may turn a `-0` component into `+0`, and
/// zero addends add nothing to the sums; the test below checks it).
#[inline(always)]
fn add_single(
    plan: &SamplePlan,
    (ox, oy): (f32, f32),
    r: Vec3,
    nonfinite: &mut u64,
    sums: &mut PixelSums,
) {
    let r = if r.is_finite() {
        r
    } else {
        *nonfinite += 1;
        Vec3::ZERO
    };
    let w = plan.filter.weight(ox - 0.5, oy - 0.5);
    if !(w * r).is_finite() {
        *nonfinite += 1;
        return;
    }
    sums.add_sample(w, r);
}

/// The mean radiance of one eye sample's rays, in ray order, non-finite ones counted
/// in `nonfinite` and taken as black (no division for one ray).
///
/// Tried and not kept (helper fr24, 2026-11-29): four pixels' means at a time in
/// `resolve_pixels`' one-eye-sample branch (a ray of each of the four pixels per step,
/// four independent addition chains instead of one pixel's chain of 16 dependent
/// additions on whitted_blur16; tested bit for bit against this function). perf,
/// whitted_blur16 1024x768, 1 thread, AVX-512, -F 10000: `resolve_pixels` with the
/// flush closure it is inlined into 3.2 % of the samples before and after; task-clock,
/// 5 interleaved rounds (host load ~3.7), min/median 868.1/873.9 -> 858.5/875.5 ms.
#[inline(always)]
fn eye_mean(radiance: &[Vec3], nonfinite: &mut u64) -> Vec3 {
    let mut radiance_sum = Vec3::ZERO;
    for &r in radiance {
        if r.is_finite() {
            radiance_sum += r;
        } else {
            *nonfinite += 1;
        }
    }
    if radiance.len() == 1 {
        radiance_sum
    } else {
        radiance_sum / radiance.len() as f32
    }
}

/// Each eye sample's mean over its rays, weighted by the filter, into `sums`.
fn add_means(
    plan: &SamplePlan,
    offsets: &[(f32, f32)],
    radiance: &[Vec3],
    nonfinite: &mut u64,
    sums: &mut PixelSums,
) {
    let per_eye = per_eye(plan);
    for (e, &(ox, oy)) in offsets.iter().enumerate() {
        let radiance = eye_mean(&radiance[e * per_eye..(e + 1) * per_eye], nonfinite);
        let w = plan.filter.weight(ox - 0.5, oy - 0.5);
        if !(w * radiance).is_finite() {
            *nonfinite += 1;
            continue;
        }
        sums.add_sample(w, radiance);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::PixelRng;
    use crate::integrator::{FilterKind, SamplerKind};

    fn plan(filter: FilterKind, eye: u32, lens: u32) -> SamplePlan {
        SamplePlan {
            eye,
            lens,
            time: 0,
            shadow: 1,
            glossy: 1,
            environment: 0,
            sampler: SamplerKind::Jittered,
            filter,
            eye_begin: 0,
            eye_end: eye,
        }
    }

    /// The box filter's one-ray path (four side-by-side pixels at a time) gives the
    /// values and the non-finite count of the general one-ray step (`single_value`
    /// at weight 1), bit for bit, on
    /// pixels laid out as a tile's 4x4 blocks (runs of four side by side), in reverse
    /// and in order, with non-finite and signed-zero components among them; and it
    /// does take the four-pixel path on most of the in-order pixels.
    #[test]
    fn box_one_ray_runs_equal_the_plain_loop() {
        let mut rng = PixelRng::new(23, 8);
        let specials = [f32::NAN, f32::INFINITY, -f32::INFINITY, -0.0, 0.0];
        let n = 16 * 16;
        let radiance: Vec<Vec3> = (0..n)
            .map(|_| {
                Vec3::from_array(std::array::from_fn(|_| {
                    let u = rng.next_f32();
                    if u < 0.02 {
                        specials[(u * 250.0) as usize]
                    } else {
                        (rng.next_f32() - 0.3) * 10f32.powi((u * 20.0) as i32 - 10)
                    }
                }))
            })
            .collect();
        // A 16x16 tile's pixels in 4x4 blocks, row-major positions in the tile.
        let blocks: Vec<u32> = (0..n as u32)
            .map(|i| {
                let (b, k) = (i / 16, i % 16);
                (4 * (b / 4) + k / 4) * 16 + 4 * (b % 4) + k % 4
            })
            .collect();
        let reversed: Vec<u32> = blocks.iter().rev().copied().collect();
        let mut ran = 0;
        for at in [&blocks, &reversed] {
            let (mut want, mut want_nf) = (vec![Vec3::NAN; n], 0);
            for (&r, &a) in radiance.iter().zip(at) {
                want[a as usize] =
                    single_value(&plan(FilterKind::Box, 1, 0), (0.5, 0.5), r, &mut want_nf);
            }
            let (mut got, mut got_nf) = (vec![Vec3::NAN; n], 0);
            ran += box_one_ray(&radiance, at, &mut got_nf, &mut got);
            assert_eq!(got_nf, want_nf);
            let bits = |v: &Vec3| v.to_array().map(f32::to_bits);
            for (a, (g, w)) in got.iter().zip(&want).enumerate() {
                assert_eq!(bits(g), bits(w), "pixel {a}");
            }
            assert!(want_nf > 0);
        }
        // In order: every run of four without a non-finite component (about 86 %
        // of them: 1.2 % of the components are NaN or infinite); reversed: none.
        assert!(ran > n / 2, "{ran}");
    }

    /// The shortcuts (`resolve_pixel_into`'s one ray per eye sample, and
    /// `resolve_pixels`' with kept sums and without: its 1-ray, 1-eye-sample and
    /// box-filter paths build no sums) give exactly the sums (compared exactly), the
    /// values (bit for bit) and the non-finite count of the general mean loop, on
    /// radiance with NaN, infinities, signed zeros, tiny and huge components, for both
    /// filters, 1 to 9 eye samples and 1 to 4 rays per eye sample.
    #[test]
    fn single_ray_paths_equal_the_mean_loop() {
        let mut rng = PixelRng::new(11, 4);
        let specials = [
            f32::NAN,
            f32::INFINITY,
            -f32::INFINITY,
            -0.0,
            0.0,
            1e-40,
            3e38,
        ];
        let value = |rng: &mut PixelRng| match (rng.next_f32() * 10.0) as usize {
            k @ 0..=6 => specials[k],
            _ => (rng.next_f32() - 0.2) * 10f32.powi((rng.next_f32() * 60.0) as i32 - 30),
        };
        let (mut nonfinite_seen, mut pixels_seen) = (0, 0);
        for filter in [FilterKind::Box, FilterKind::Gaussian] {
            for (eye, lens) in [(1, 0), (3, 0), (9, 0), (1, 4), (2, 3)] {
                let plan = plan(filter, eye, lens);
                let per = lens.max(1) as usize;
                let n = 300;
                let offsets: Vec<(f32, f32)> = (0..n * eye)
                    .map(|_| (2.0 * rng.next_f32() - 0.5, 2.0 * rng.next_f32() - 0.5))
                    .collect();
                let radiance: Vec<Vec3> = (0..n as usize * eye as usize * per)
                    .map(|_| Vec3::new(value(&mut rng), value(&mut rng), value(&mut rng)))
                    .collect();
                let e = eye as usize;
                let mut want = vec![PixelSums::default(); n as usize];
                let mut got = want.clone();
                let (mut want_nf, mut got_nf) = (0, 0);
                for (g, sums) in want.iter_mut().enumerate() {
                    let o = &offsets[g * e..(g + 1) * e];
                    let r = &radiance[g * e * per..(g + 1) * e * per];
                    add_means(&plan, o, r, &mut want_nf, sums);
                }
                // Pixels stored in reverse order, as a tile's blocks scatter them;
                // once keeping the sums (a partial image), once values only (the
                // 1-ray shortcut for eye 1).
                let at: Vec<u32> = (0..n).rev().collect();
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                let mut values = vec![Vec3::NAN; n as usize];
                let mut out = TileOut {
                    values: &mut values,
                    sums: Some(&mut got),
                };
                resolve_pixels(&plan, &offsets, &radiance, &at, &mut got_nf, &mut out);
                got.reverse();
                values.reverse();
                assert_eq!(got_nf, want_nf, "{filter} eye {eye}");
                for (g, (a, b)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(a, b, "{filter} eye {eye} pixel {g}");
                    assert_eq!(bits(a.value()), bits(b.value()));
                    assert_eq!(bits(values[g]), bits(b.value()));
                }
                let mut values = vec![Vec3::NAN; n as usize];
                let mut out = TileOut {
                    values: &mut values,
                    sums: None,
                };
                let mut values_nf = 0;
                resolve_pixels(&plan, &offsets, &radiance, &at, &mut values_nf, &mut out);
                values.reverse();
                assert_eq!(values_nf, want_nf, "{filter} eye {eye}");
                for (g, (v, b)) in values.iter().zip(&want).enumerate() {
                    assert_eq!(bits(*v), bits(b.value()), "{filter} eye {eye} pixel {g}");
                }
                nonfinite_seen += want_nf;
                pixels_seen += n;
            }
        }
        assert!(
            nonfinite_seen > 100 && pixels_seen == 3000,
            "{nonfinite_seen}"
        );
    }
}
