//! Lens points of a round aperture over lanes: the concentric map of the unit square
//! onto the unit disk (Shirley, Chiu, "A Low Distortion Map Between Disk and Square",
//! JGT 1997), with the lane sine and cosine of [`super::trig`].
//!
//! The scalar camera (`geometry::warp::sample_aperture`, the oracle of the
//! lane-parallel camera rays) calls [`concentric_disk_one`], this code on one lane, so
//! both give the same lens points bit for bit. The map is the libm-based
//! [`crate::geometry::warp::concentric_disk`]'s (still used by disk area lights), with
//! the angle of the octants above the diagonals taken as `π/2 - x` by symmetry
//! (`cos(π/2 - x) = sin x`) rather than rounded to f32 first; the two differ by at
//! most [`LIBM_DISK_DIFFERENCE`] per coordinate.

use super::trig::sin_cos;
use super::{F4, Lanes, PACKET_WIDTH, Packet};
use std::f32::consts::FRAC_PI_4;

/// Largest error of a coordinate of [`concentric_disk`] against the exact map of the
/// same point (in f64): [`super::trig::SIN_COS_MAX_ERROR`] of the sine or cosine,
/// the rounding of the angle `π/4 · t` (3e-8 rad) and of the product with `r`
/// (3e-8). Measured by the test below: 1.12e-7 (the libm map: 2.17e-7, its angle
/// rounded to f32 above the diagonals).
pub const DISK_MAX_ERROR: f32 = 1.5e-7;

/// Largest difference of a coordinate from the libm map
/// ([`crate::geometry::warp::concentric_disk`], the lens before): that map rounds the
/// angle `π/2 - π/4 · t` to f32 before its cosine and sine, up to 1.2e-7 rad above
/// the diagonals, so the two differ by up to about 2e-7 there. Measured by the test
/// below: 1.79e-7. On a lens of radius 0.2 (blur16) that is 5e-8 scene units.
pub const LIBM_DISK_DIFFERENCE: f32 = 2.5e-7;

/// The point of the unit disk for `(u, v)` in `[0, 1)²`, per lane.
#[inline(always)]
pub fn concentric_disk<L: Lanes>(u: L, v: L) -> (L, L) {
    let (one, two, zero) = (L::splat(1.0), L::splat(2.0), L::splat(0.0));
    let a = two * u - one;
    let b = two * v - one;
    // Below the diagonals: r = a, angle π/4 · b/a; above: r = b, angle π/2 - π/4 · a/b.
    let below = a.abs().gt(b.abs());
    let r = L::select(below, a, b);
    let x = L::splat(FRAC_PI_4) * (L::select(below, b, a) / r);
    let (s, c) = sin_cos(x);
    let (cos_phi, sin_phi) = (L::select(below, c, s), L::select(below, s, c));
    // The centre (a = b = 0, where x is 0/0) maps to the origin.
    let centre = a.eq(zero) & b.eq(zero);
    (
        L::select(centre, zero, r * cos_phi),
        L::select(centre, zero, r * sin_phi),
    )
}

/// [`concentric_disk`] of one point, the same bits.
#[inline]
pub fn concentric_disk_one(u: f32, v: f32) -> glam::Vec2 {
    let (x, y) = concentric_disk(F4::splat(u), F4::splat(v));
    glam::Vec2::new(x.to_array()[0], y.to_array()[0])
}

/// The largest value below one (`geometry::warp::ONE_MINUS_EPSILON`).
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The corner table of a polygonal aperture (`integrator::polygon_aperture`) in lanes:
/// corners `0..=blades` (corner `blades` is corner 0 again, from its own angle), at
/// most [`PACKET_WIDTH`] of them, so that a lane's two corners are two permutes of
/// the table rather than two loads by index.
///
/// [`points`](Self::points) gives per lane what the scalar table's `sample` gives
/// (`sample_aperture`'s triangle pick, square root and glam's `lerp`), the same
/// operations in the same order, bit for bit, for any `u`, `v` (NaN and out-of-range
/// included: `x as u32` saturates, NaN to 0, and `f32::min` returns the number where
/// the other operand is NaN, as `maxps`/`minps` with the constant second do).
///
/// Measured: the scalar table loop, one point at a time after the staging, was 29 %
/// of `block_rays`' perf samples on dof_area 960x720 (hexagonal aperture, 1 thread).
#[derive(Clone, Copy, Debug)]
pub struct PolygonLanes {
    x: Packet,
    y: Packet,
    blades: Packet,
    last: Packet,
}

impl PolygonLanes {
    /// The table of `corners` (`blades + 1` of them, `blades >= 1`); `None` where they
    /// do not fit one packet.
    pub fn new(corners: &[glam::Vec2]) -> Option<PolygonLanes> {
        if !(2..=PACKET_WIDTH).contains(&corners.len()) {
            return None;
        }
        let blades = (corners.len() - 1) as u32;
        let lane = |f: fn(&glam::Vec2) -> f32| {
            Packet::from_array(std::array::from_fn(|i| corners.get(i).map_or(0.0, f)))
        };
        Some(PolygonLanes {
            x: lane(|c| c.x),
            y: lane(|c| c.y),
            blades: Packet::splat(blades as f32),
            last: Packet::splat((blades - 1) as f32),
        })
    }

    /// The lens points of the unit-square points `(u, v)`, one per lane: the scalar
    /// `PolygonAperture::sample` of each lane.
    #[inline(always)]
    pub fn points(&self, u: Packet, v: Packet) -> (Packet, Packet) {
        let x = u * self.blades;
        // `(x as u32).min(blades - 1)`: NaN and negatives to 0, large to the last
        // triangle, then the whole part (exact: at most 14).
        let clamped = x.maxps(Packet::splat(0.0)).minps(self.last);
        let (k, [ax, ay, bx, by]) = corners_at(clamped, [self.x, self.y]);
        let t = (x - k).minps(Packet::splat(ONE_MINUS_EPSILON));
        let s = t.sqrt();
        let w = Packet::splat(1.0) - v;
        (s * (ax * w + bx * v), s * (ay * w + by * v))
    }
}

/// The whole part `k` of each lane of `at` (in `[0, 15)`), and the table entries `k`
/// and `k + 1` of each of `tables` (x then y): `[x[k], y[k], x[k + 1], y[k + 1]]`.
#[inline(always)]
fn corners_at(at: Packet, [tx, ty]: [Packet; 2]) -> (Packet, [Packet; 4]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        use std::arch::x86_64::*;
        // SAFETY: AVX-512F is enabled at compile time, and `Packet` is sixteen f32
        // lanes in one 64-byte register (`__m512`); the indices are in 0..16.
        unsafe {
            let t = |p: Packet| std::mem::transmute::<Packet, __m512>(p);
            let p = |m: __m512| std::mem::transmute::<__m512, Packet>(m);
            let i = _mm512_cvttps_epi32(t(at));
            let j = _mm512_add_epi32(i, _mm512_set1_epi32(1));
            let (x, y) = (t(tx), t(ty));
            (
                p(_mm512_cvtepi32_ps(i)),
                [
                    p(_mm512_permutexvar_ps(i, x)),
                    p(_mm512_permutexvar_ps(i, y)),
                    p(_mm512_permutexvar_ps(j, x)),
                    p(_mm512_permutexvar_ps(j, y)),
                ],
            )
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    {
        let i = at.to_array().map(|a| (a as u32).min(14) as usize);
        let (x, y) = (tx.to_array(), ty.to_array());
        let pick = |t: &[f32; 16], d: usize| Packet::from_array(i.map(|k| t[k + d]));
        (
            Packet::from_array(i.map(|k| k as f32)),
            [pick(&x, 0), pick(&y, 0), pick(&x, 1), pick(&y, 1)],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::warp::concentric_disk as libm_disk;
    use crate::integrator::sampling::PixelRng;
    use crate::simd::Packet;

    /// The lane map gives the one-lane bits in every lane; each coordinate is within
    /// `DISK_MAX_ERROR` of the exact map (f64 from the same `a`, `b`) and within
    /// `LIBM_DISK_DIFFERENCE` of the libm map, on random points, the centre, the
    /// diagonals and the edges of the square.
    #[test]
    fn lane_disk_equals_one_lane_and_stays_near_the_exact_map() {
        let mut rng = PixelRng::new(3, 5);
        let mut pts: Vec<(f32, f32)> = (0..200_000)
            .map(|_| (rng.next_f32(), rng.next_f32()))
            .collect();
        pts.extend([
            (0.5, 0.5),
            (0.0, 0.0),
            (0.25, 0.25),
            (0.75, 0.25),
            (0.0, 0.5),
        ]);
        pts.extend([(0.5, 0.0), (0.9999999, 0.5), (0.5, 0.9999999), (0.5, 0.75)]);
        let (mut worst, mut worst_libm, mut worst_libm_exact) = (0.0f64, 0.0f32, 0.0f64);
        for chunk in pts.chunks(16) {
            let (mut u, mut v) = ([0.5f32; 16], [0.5f32; 16]);
            for (i, &(a, b)) in chunk.iter().enumerate() {
                (u[i], v[i]) = (a, b);
            }
            let (x, y) = concentric_disk(Packet::from_array(u), Packet::from_array(v));
            let (x, y) = (x.to_array(), y.to_array());
            for (i, &(u, v)) in chunk.iter().enumerate() {
                let one = concentric_disk_one(u, v);
                assert_eq!(
                    (x[i].to_bits(), y[i].to_bits()),
                    (one.x.to_bits(), one.y.to_bits())
                );
                // The exact map of the same (a, b), both exact in f32.
                let (a, b) = ((2.0 * u - 1.0) as f64, (2.0 * v - 1.0) as f64);
                let (r, phi) = if a == 0.0 && b == 0.0 {
                    (0.0, 0.0)
                } else if a.abs() > b.abs() {
                    (a, std::f64::consts::FRAC_PI_4 * (b / a))
                } else {
                    (
                        b,
                        std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (a / b),
                    )
                };
                let exact = (r * phi.cos(), r * phi.sin());
                let err = (one.x as f64 - exact.0)
                    .abs()
                    .max((one.y as f64 - exact.1).abs());
                assert!(
                    err <= DISK_MAX_ERROR as f64,
                    "({u}, {v}): {one} vs {exact:?}"
                );
                let libm = libm_disk(u, v);
                let diff = (one - libm).abs().max_element();
                assert!(
                    diff <= LIBM_DISK_DIFFERENCE,
                    "({u}, {v}): {one} vs libm {libm}"
                );
                assert!(one.length() <= 1.0 + f32::EPSILON, "({u}, {v}): {one}");
                worst = worst.max(err);
                worst_libm = worst_libm.max(diff);
                worst_libm_exact = worst_libm_exact.max(
                    (libm.x as f64 - exact.0)
                        .abs()
                        .max((libm.y as f64 - exact.1).abs()),
                );
            }
        }
        assert_eq!(concentric_disk_one(0.5, 0.5), glam::Vec2::ZERO);
        println!(
            "worst coordinate error: lanes {worst:e}, libm map {worst_libm_exact:e}; \
             lanes against libm map {worst_libm:e}"
        );
        assert!(
            worst > DISK_MAX_ERROR as f64 / 2.0,
            "bound loose: {worst:e}"
        );
    }
}
