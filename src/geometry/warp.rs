//! Warps from the unit square onto the shapes distribution ray tracing samples: the
//! disk (concentric map), a polygonal aperture, and the Phong lobe around an axis.
//! Pure maths on `[0, 1)²` points, used by the camera (lens points), the lights (disk
//! area lights) and the shader (glossy and translucent directions), so it sits below
//! both `scene` and `integrator`.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_4, PI, TAU};

/// The largest f32 below 1: sample coordinates are clamped to it so that a point never
/// steps into the next stratum (or triangle of an aperture).
pub(crate) const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Concentric map of `[0, 1)²` onto the unit disk (Shirley, Chiu 1997): keeps
/// strata compact, unlike the polar map.
pub fn concentric_disk(u: f32, v: f32) -> Vec2 {
    let a = 2.0 * u - 1.0;
    let b = 2.0 * v - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, 0.5 * PI - FRAC_PI_4 * (a / b))
    };
    Vec2::new(r * phi.cos(), r * phi.sin())
}

/// Uniform point on an aperture of unit circumradius: the disk for `blades == 0`, else
/// a regular polygon with `blades` corners, the first at angle `rotation` (radians).
/// The polygon is cut into `blades` triangles around the centre; `u` picks the
/// triangle (all have equal area) and is reused, rescaled, inside it.
///
/// The disk is [`crate::simd::aperture::concentric_disk_one`]: the concentric map with a
/// polynomial sine and cosine, the bits the lane-parallel camera computes for a whole
/// packet of lens points (within `SIN_COS_MAX_ERROR` of [`concentric_disk`]'s libm).
pub fn sample_aperture(u: f32, v: f32, blades: u32, rotation: f32) -> Vec2 {
    if blades < 3 {
        return crate::simd::aperture::concentric_disk_one(u, v);
    }
    let x = u * blades as f32;
    let k = (x as u32).min(blades - 1);
    let u = (x - k as f32).min(ONE_MINUS_EPSILON);
    let corner = |i: u32| {
        let a = rotation + TAU * i as f32 / blades as f32;
        Vec2::new(a.cos(), a.sin())
    };
    // Uniform in the triangle (0, c_k, c_k+1): sqrt(u) along the spoke, v across.
    u.sqrt() * corner(k).lerp(corner(k + 1), v)
}

/// A direction in the Phong lobe `cos^n α` around the unit `axis`, with the cosine
/// distribution sampled exactly (`cos α = u^(1/(n+1))`), so an estimator that averages
/// radiance over such directions needs no weights.
pub fn sample_phong_lobe(axis: Vec3, exponent: f32, u: f32, v: f32) -> Vec3 {
    let cos = u.powf(1.0 / (exponent + 1.0));
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = TAU * v;
    let (t, b) = super::orthonormal_basis(axis);
    (sin * phi.cos() * t + sin * phi.sin() * b + cos * axis).normalize()
}
#[cfg(test)]
mod tests {
    use super::*;
    // Only a source of uniform numbers for the estimates below.
    use crate::integrator::sampling::PixelRng;

    #[test]
    fn apertures_are_uniform_and_bounded() {
        for blades in [0u32, 5, 6] {
            let mut rng = PixelRng::new(3, blades as u64);
            let n = 20_000;
            let mut mean = Vec2::ZERO;
            let mut r2 = 0.0;
            for _ in 0..n {
                let p = sample_aperture(rng.next_f32(), rng.next_f32(), blades, 0.3);
                assert!(p.length() <= 1.0 + 1e-5);
                mean += p;
                r2 += p.length_squared();
            }
            mean /= n as f32;
            r2 /= n as f32;
            assert!(mean.length() < 0.02, "{blades}: {mean}");
            // Uniform disk: E[r²] = 1/2; a regular polygon of circumradius 1 has
            // E[r²] = (1 + 2 cos²(π/n)) / 6, slightly less.
            let expect = if blades == 0 {
                0.5
            } else {
                let c = (PI / blades as f32).cos();
                (1.0 + 2.0 * c * c) / 6.0
            };
            assert!((r2 - expect).abs() < 0.01, "{blades}: {r2} vs {expect}");
        }
    }

    #[test]
    fn phong_lobe_mean_cosine() {
        // E[cos α] = (n + 1) / (n + 2) for the cos^n lobe.
        let axis = Vec3::new(0.3, -0.5, 0.8).normalize();
        let mut rng = PixelRng::new(5, 5);
        for n in [0.0f32, 10.0, 200.0] {
            let m = 20_000;
            let mean: f32 = (0..m)
                .map(|_| sample_phong_lobe(axis, n, rng.next_f32(), rng.next_f32()).dot(axis))
                .sum::<f32>()
                / m as f32;
            let expect = (n + 1.0) / (n + 2.0);
            assert!((mean - expect).abs() < 0.01, "n {n}: {mean} vs {expect}");
        }
    }
}
