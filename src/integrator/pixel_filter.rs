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

/// [`resolve_pixel`] adding into `sums` where they lie (the wavefront's tile buffer),
/// rather than returning them by value.
pub(crate) fn resolve_pixel_into(
    plan: &SamplePlan,
    offsets: &[(f32, f32)],
    radiance: &[Vec3],
    nonfinite: &mut u64,
    sums: &mut PixelSums,
) {
    let per_eye = (plan.lens.max(1) * plan.time.max(1)) as usize;
    for (e, &(ox, oy)) in offsets.iter().enumerate() {
        let mut radiance_sum = Vec3::ZERO;
        for &r in &radiance[e * per_eye..(e + 1) * per_eye] {
            if r.is_finite() {
                radiance_sum += r;
            } else {
                *nonfinite += 1;
            }
        }
        let radiance = if per_eye == 1 {
            radiance_sum
        } else {
            radiance_sum / per_eye as f32
        };
        let w = plan.filter.weight(ox - 0.5, oy - 0.5);
        if !(w * radiance).is_finite() {
            *nonfinite += 1;
            continue;
        }
        sums.add_sample(w, radiance);
    }
}
