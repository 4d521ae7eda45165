//! Rays from lanes into an array of [`Ray`]s: the camera stage's hand-over from its
//! lane-parallel ray construction ([`super::camera`]) to the ray queue, which holds
//! rays as structs.
//!
//! An 8x8 transpose of the first eight components (origin, direction, `tmin`, `tmax`)
//! gives each ray's first 32 bytes in one register: one unaligned store per ray and
//! the time after it, where the plain loop did nine loads and nine stores per ray.
//! Measured before (`perf record`, bunny 1024x1024, 1 thread, AVX2): the plain loop
//! (`RayLanes::append`) was about a third of the camera stage.

use crate::geometry::Ray;

// The layout the stores rely on: nine `f32`s in the order origin, direction, tmin,
// tmax, time, with no padding.
const _: () = {
    assert!(std::mem::size_of::<Ray>() == 36);
    assert!(std::mem::align_of::<Ray>() == 4);
    assert!(std::mem::offset_of!(Ray, origin) == 0);
    assert!(std::mem::offset_of!(Ray, dir) == 12);
    assert!(std::mem::offset_of!(Ray, tmin) == 24);
    assert!(std::mem::offset_of!(Ray, tmax) == 28);
    assert!(std::mem::offset_of!(Ray, time) == 32);
};

/// Appends rays `0..n` of the component arrays (each at least `n` long, a multiple of
/// eight long for the transposed path) to `out`, with `tmin = 0` and `tmax = inf`
/// (as [`Ray::new`]): ray `i` is `origin (o[0][i], o[1][i], o[2][i])`, direction
/// `d[..][i]`, time `t[i]`.
#[inline]
pub fn append_rays(o: [&[f32]; 3], d: [&[f32]; 3], t: &[f32], n: usize, out: &mut Vec<Ray>) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        let len = o.iter().chain(&d).map(|a| a.len()).min().unwrap_or(0);
        if len.is_multiple_of(8) && n <= len && t.len() >= n {
            out.reserve(n);
            // SAFETY: `reserve` made room for `n` more rays after `out.len()`; the
            // stores below write exactly rays `0..n` of it, every byte (the layout is
            // asserted above), before the length is raised over them. Every read
            // is of a slice of at least `len >= n` floats rounded up to whole groups of
            // eight that the check above guarantees.
            unsafe {
                let dst = out.as_mut_ptr().add(out.len()) as *mut f32;
                avx2::store(o, d, t, n, dst);
                out.set_len(out.len() + n);
            }
            return;
        }
    }
    append_plain(o, d, t, n, out);
}

/// The plain loop: the reference of the transposed path (and the path without AVX2).
pub fn append_plain(o: [&[f32]; 3], d: [&[f32]; 3], t: &[f32], n: usize, out: &mut Vec<Ray>) {
    let (ox, oy, oz) = (&o[0][..n], &o[1][..n], &o[2][..n]);
    let (dx, dy, dz) = (&d[0][..n], &d[1][..n], &d[2][..n]);
    let t = &t[..n];
    out.extend((0..n).map(|i| Ray {
        origin: glam::Vec3::new(ox[i], oy[i], oz[i]),
        dir: glam::Vec3::new(dx[i], dy[i], dz[i]),
        tmin: 0.0,
        tmax: f32::INFINITY,
        time: t[i],
    }));
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
pub(super) mod avx2 {
    use std::arch::x86_64::*;

    /// Writes rays `0..n` as nine floats each from `dst` on.
    ///
    /// # Safety
    /// `dst` must be valid for `9 n` floats; every slice of `o` and `d` must hold `n`
    /// rounded up to a multiple of 8 floats, `t` at least `n`.
    #[inline(always)]
    pub unsafe fn store(o: [&[f32]; 3], d: [&[f32]; 3], t: &[f32], n: usize, dst: *mut f32) {
        unsafe {
            let zero = _mm256_setzero_ps();
            let inf = _mm256_set1_ps(f32::INFINITY);
            let mut base = 0;
            while base < n {
                let ld = |a: &[f32]| _mm256_loadu_ps(a.as_ptr().add(base));
                let rows = transpose([
                    ld(o[0]),
                    ld(o[1]),
                    ld(o[2]),
                    ld(d[0]),
                    ld(d[1]),
                    ld(d[2]),
                    zero,
                    inf,
                ]);
                for (k, row) in rows.iter().enumerate().take(n - base) {
                    let p = dst.add(9 * (base + k));
                    _mm256_storeu_ps(p, *row);
                    *p.add(8) = t[base + k];
                }
                base += 8;
            }
        }
    }

    /// 8x8 transpose: row `i` of the result holds lane `i` of every input, in order
    /// (also `simd::ray_gather`'s, the other way: rays to component rows).
    #[inline(always)]
    pub(in crate::simd) unsafe fn transpose(r: [__m256; 8]) -> [__m256; 8] {
        unsafe {
            let t0 = _mm256_unpacklo_ps(r[0], r[1]);
            let t1 = _mm256_unpackhi_ps(r[0], r[1]);
            let t2 = _mm256_unpacklo_ps(r[2], r[3]);
            let t3 = _mm256_unpackhi_ps(r[2], r[3]);
            let t4 = _mm256_unpacklo_ps(r[4], r[5]);
            let t5 = _mm256_unpackhi_ps(r[4], r[5]);
            let t6 = _mm256_unpacklo_ps(r[6], r[7]);
            let t7 = _mm256_unpackhi_ps(r[6], r[7]);
            let s0 = _mm256_shuffle_ps::<0x44>(t0, t2);
            let s1 = _mm256_shuffle_ps::<0xee>(t0, t2);
            let s2 = _mm256_shuffle_ps::<0x44>(t1, t3);
            let s3 = _mm256_shuffle_ps::<0xee>(t1, t3);
            let s4 = _mm256_shuffle_ps::<0x44>(t4, t6);
            let s5 = _mm256_shuffle_ps::<0xee>(t4, t6);
            let s6 = _mm256_shuffle_ps::<0x44>(t5, t7);
            let s7 = _mm256_shuffle_ps::<0xee>(t5, t7);
            [
                _mm256_permute2f128_ps::<0x20>(s0, s4),
                _mm256_permute2f128_ps::<0x20>(s1, s5),
                _mm256_permute2f128_ps::<0x20>(s2, s6),
                _mm256_permute2f128_ps::<0x20>(s3, s7),
                _mm256_permute2f128_ps::<0x31>(s0, s4),
                _mm256_permute2f128_ps::<0x31>(s1, s5),
                _mm256_permute2f128_ps::<0x31>(s2, s6),
                _mm256_permute2f128_ps::<0x31>(s3, s7),
            ]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::PixelRng;

    /// The transposed stores give the plain loop's rays, bit for bit (NaN, signed
    /// zeros and infinities among the components), for every count 0..=16 of rays
    /// from 16-lane arrays, appended after rays already in the vector.
    #[test]
    fn transposed_stores_equal_the_plain_loop() {
        let mut rng = PixelRng::new(3, 9);
        let specials = [f32::NAN, -0.0, 0.0, f32::INFINITY, -1e-40];
        let mut draw = || {
            let r = rng.next_f32();
            if r < 0.1 {
                specials[(r * 50.0) as usize]
            } else {
                (rng.next_f32() - 0.5) * 1e3
            }
        };
        for n in 0..=16 {
            for _ in 0..20 {
                let mut a = [[0.0f32; 16]; 7];
                for c in a.iter_mut().flatten() {
                    *c = draw();
                }
                let o = [&a[0][..], &a[1][..], &a[2][..]];
                let d = [&a[3][..], &a[4][..], &a[5][..]];
                let head = Ray::new(glam::Vec3::ONE, glam::Vec3::X);
                let (mut got, mut want) = (vec![head; 3], vec![head; 3]);
                append_rays(o, d, &a[6], n, &mut got);
                append_plain(o, d, &a[6], n, &mut want);
                let bits = |r: &Ray| {
                    [
                        r.origin.to_array(),
                        r.dir.to_array(),
                        [r.tmin, r.tmax, r.time],
                    ]
                    .map(|c| c.map(f32::to_bits))
                };
                assert_eq!(got.len(), 3 + n);
                for (g, w) in got.iter().zip(&want) {
                    assert_eq!(bits(g), bits(w), "n {n}");
                }
            }
        }
    }
}
