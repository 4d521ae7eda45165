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
///
/// With AVX-512 and sixteen-float arrays (the camera's packets), the sixteen rays are
/// nine 64-byte windows, each merged from the seven arrays by four masked two-source
/// permutes ([`avx512::store_lanes`]) where the two 8x8 transposes took 48 shuffles,
/// 16 stores and 16 scalar time stores.
#[inline(always)]
pub fn append_rays(o: [&[f32]; 3], d: [&[f32]; 3], t: &[f32], n: usize, out: &mut Vec<Ray>) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    if let (Ok(o0), Ok(o1), Ok(o2), Ok(d0), Ok(d1), Ok(d2), Ok(tt)) = (
        <&[f32; 16]>::try_from(o[0]),
        <&[f32; 16]>::try_from(o[1]),
        <&[f32; 16]>::try_from(o[2]),
        <&[f32; 16]>::try_from(d[0]),
        <&[f32; 16]>::try_from(d[1]),
        <&[f32; 16]>::try_from(d[2]),
        <&[f32; 16]>::try_from(t),
    ) {
        let n = n.min(16);
        out.reserve(n);
        // SAFETY: `reserve` made room for `n` more rays after `out.len()`;
        // `store_lanes` writes exactly their `9 n` floats (masked stores past them),
        // every byte of each ray (the layout is asserted above), before the length is
        // raised over them; it reads the seven 16-float arrays.
        unsafe {
            let dst = out.as_mut_ptr().add(out.len()) as *mut f32;
            avx512::store_lanes([o0, o1, o2, d0, d1, d2, tt], n, dst);
            out.set_len(out.len() + n);
        }
        return;
    }
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

/// Appends rays that share one origin and one time (pinhole camera rays without eye
/// motion: only the direction differs from ray to ray), as [`append_rays`] with every
/// origin lane `origin` and every time lane `time`.
///
/// With AVX-512 sixteen such rays are 144 floats, nine 64-byte stores: each store is
/// the constant part of its window of the ray array (origin, `tmin`, `tmax`, time,
/// made once in [`UniformRays::new`]) with the directions merged in by two masked
/// permutes, against 24 shuffles, 16 stores and 16 scalar time stores for the
/// transposes of [`append_rays`]. Without AVX-512 the transposed path.
pub struct UniformRays {
    origin: [[f32; 16]; 3],
    time: [f32; 16],
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    windows: avx512::Windows,
}

impl UniformRays {
    /// The store of rays from `origin` at `time`.
    pub fn new(origin: glam::Vec3, time: f32) -> Self {
        UniformRays {
            origin: origin.to_array().map(|c| [c; 16]),
            time: [time; 16],
            #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
            windows: avx512::Windows::new(origin, time),
        }
    }

    /// Appends rays `0..n` (at most 16) with directions `d` (each of the three at least
    /// `n` long) to `out`: ray `i` leaves the origin along `(d[0][i], d[1][i], d[2][i])`.
    /// Inlined into the camera's block loop, so that the windows' constants can stay
    /// in registers from block to block.
    #[inline(always)]
    pub fn append(&self, d: [&[f32]; 3], n: usize, out: &mut Vec<Ray>) {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
        if let (Ok(x), Ok(y), Ok(z)) = (
            <&[f32; 16]>::try_from(d[0]),
            <&[f32; 16]>::try_from(d[1]),
            <&[f32; 16]>::try_from(d[2]),
        ) {
            let n = n.min(16);
            out.reserve(n);
            // SAFETY: `reserve` made room for `n` more rays after `out.len()`; `store`
            // writes exactly their `9 n` floats (masked stores past them), every byte
            // of each ray (the layout is asserted above), before the length is raised
            // over them; it reads the three 16-float arrays `x`, `y`, `z`.
            unsafe {
                let dst = out.as_mut_ptr().add(out.len()) as *mut f32;
                self.windows.store([x, y, z], n, dst);
                out.set_len(out.len() + n);
            }
            return;
        }
        let n = n.min(16);
        let o = [
            &self.origin[0][..],
            &self.origin[1][..],
            &self.origin[2][..],
        ];
        append_rays(o, d, &self.time, n, out);
    }

    /// Writes the sixteen rays with directions `d` into `dst`, ray `i` leaving the
    /// origin along `(d[0][i], d[1][i], d[2][i])`: the rays [`Self::append`] appends
    /// for `n = 16`, into memory the caller owns, so that a loop over many blocks
    /// (`CameraSampler::pinhole_blocks`) raises its vector's length once, not per
    /// block. Appending per block stored the length after each block and loaded it
    /// again (with the capacity) for the next: the vector's header may alias the
    /// rays' stores, so it stayed in memory (perf annotate, bunny 4096x4096, 1 thread:
    /// `addq` to the length in every block of the camera's hottest loop).
    #[inline(always)]
    pub fn write16(&self, d: [&[f32; 16]; 3], dst: &mut [std::mem::MaybeUninit<Ray>; 16]) {
        let out = dst.as_mut_ptr() as *mut f32;
        #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
        // SAFETY: `dst` is sixteen rays, the `9 * 16` floats `store` writes (every
        // byte of each ray, layout asserted above); it reads the three arrays of `d`.
        unsafe {
            self.windows.store(d, 16, out);
        }
        #[cfg(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            not(target_feature = "avx512f")
        ))]
        // SAFETY: `dst` is sixteen rays, the `9 * 16` floats `store` writes; every
        // array it reads (origin, direction, time) is sixteen floats, two groups of
        // eight.
        unsafe {
            let o = [
                &self.origin[0][..],
                &self.origin[1][..],
                &self.origin[2][..],
            ];
            avx2::store(o, [&d[0][..], &d[1][..], &d[2][..]], &self.time, 16, out);
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
        {
            let _ = out;
            for (i, r) in dst.iter_mut().enumerate() {
                r.write(Ray {
                    origin: glam::Vec3::new(
                        self.origin[0][i],
                        self.origin[1][i],
                        self.origin[2][i],
                    ),
                    dir: glam::Vec3::new(d[0][i], d[1][i], d[2][i]),
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                    time: self.time[i],
                });
            }
        }
    }
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

/// Sixteen records of six 32-bit words from lanes: record `i` is `[t[i], tag, prim[i],
/// 0, u[i], v[i]]` (floats as their bits), written from `dst` on, 96 words in a row.
/// The scene-level hit (`accel::SceneHit`, `repr(C)`: `t`, the `repr(u32)` primitive
/// tag and index and a spare word, `u`, `v`) of a packet's sixteen lanes, in place of
/// the twenty scalar stores per lane of building each `Option<SceneHit>` on its own.
///
/// With AVX-512: six 64-byte windows, each merged from the pairs `(t, prim)` and `(u,
/// v)` by two masked two-source permutes and the tag by a masked move (the tables of
/// [`avx512::hit_records`], as [`append_rays`] builds its windows).
///
/// # Safety
/// `dst` must be valid for writes of 96 `u32`s.
#[inline(always)]
pub unsafe fn store_hit_records(
    (t, u, v): (&[f32; 16], &[f32; 16], &[f32; 16]),
    prim: &[u32; 16],
    tag: u32,
    dst: *mut u32,
) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    // SAFETY: the caller's contract.
    unsafe {
        avx512::hit_records([t, u, v], prim, tag, dst)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    // SAFETY: the caller's contract: words `0..96` from `dst`.
    unsafe {
        hit_records_plain((t, u, v), prim, tag, dst)
    }
}

/// The plain loop of [`store_hit_records`], word by word: its reference (and the path
/// without AVX-512).
///
/// # Safety
/// `dst` must be valid for writes of 96 `u32`s.
pub unsafe fn hit_records_plain(
    (t, u, v): (&[f32; 16], &[f32; 16], &[f32; 16]),
    prim: &[u32; 16],
    tag: u32,
    dst: *mut u32,
) {
    for i in 0..16 {
        let record = [
            t[i].to_bits(),
            tag,
            prim[i],
            0,
            u[i].to_bits(),
            v[i].to_bits(),
        ];
        // SAFETY: words `6 i..6 i + 6 <= 96` from `dst` (the caller's contract).
        unsafe { dst.add(6 * i).cast::<[u32; 6]>().write_unaligned(record) };
    }
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

/// The sixteen-ray stores of [`UniformRays`].
#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
mod avx512 {
    use std::arch::x86_64::*;

    /// Float `p` of sixteen rays laid out one after the other (nine floats each) is
    /// component `p % 9` of ray `p / 9`; window `k` is floats `16 k..16 k + 16`.
    const fn component(k: usize, lane: usize) -> (usize, usize) {
        let p = 16 * k + lane;
        (p / 9, p % 9)
    }

    /// Per window: `base`, the constant floats (origin, `tmin`, `tmax`, time) with, in
    /// the lanes of the directions' x and y, the two-source permute index of that
    /// component of that ray (only its low five bits are read: lane `r` of x is index
    /// `r`, of y `16 + r`); `xy`, the mask of those lanes; `zi` and `z`, the index and
    /// mask of the direction's z.
    pub(super) struct Windows {
        base: [__m512; 9],
        xy: [__mmask16; 9],
        zi: [__m512i; 9],
        z: [__mmask16; 9],
    }

    impl Windows {
        pub(super) fn new(origin: glam::Vec3, time: f32) -> Self {
            let mut base = [[0u32; 16]; 9];
            let mut zi = [[0i32; 16]; 9];
            let (mut xy, mut z) = ([0u16; 9], [0u16; 9]);
            for k in 0..9 {
                for lane in 0..16 {
                    let (r, c) = component(k, lane);
                    base[k][lane] = match c {
                        0..=2 => origin[c].to_bits(),
                        3 => r as u32,
                        4 => 16 + r as u32,
                        5 => {
                            zi[k][lane] = r as i32;
                            z[k] |= 1 << lane;
                            0
                        }
                        6 => 0f32.to_bits(),
                        7 => f32::INFINITY.to_bits(),
                        _ => time.to_bits(),
                    };
                    if c == 3 || c == 4 {
                        xy[k] |= 1 << lane;
                    }
                }
            }
            // SAFETY: unaligned loads of 16-element arrays of 4-byte values.
            unsafe {
                Windows {
                    base: base.map(|b| _mm512_castsi512_ps(_mm512_loadu_si512(b.as_ptr().cast()))),
                    xy,
                    zi: zi.map(|i| _mm512_loadu_si512(i.as_ptr().cast())),
                    z,
                }
            }
        }

        /// Writes rays `0..n` (`n <= 16`) from `dst` on, nine floats each, directions
        /// from `d`.
        ///
        /// # Safety
        /// `dst` must be valid for `9 n` floats.
        #[inline(always)]
        pub(super) unsafe fn store(&self, d: [&[f32; 16]; 3], n: usize, dst: *mut f32) {
            unsafe {
                let x = _mm512_loadu_ps(d[0].as_ptr());
                let y = _mm512_loadu_ps(d[1].as_ptr());
                let z = _mm512_loadu_ps(d[2].as_ptr());
                let floats = 9 * n;
                for k in 0..9 {
                    // Lanes not in `xy` keep `base`'s bits (vpermi2ps writes the index
                    // operand's lane where the mask is clear).
                    let idx = _mm512_castps_si512(self.base[k]);
                    let w = _mm512_mask2_permutex2var_ps(x, idx, self.xy[k], y);
                    let w = _mm512_mask_permutexvar_ps(w, self.z[k], self.zi[k], z);
                    let p = dst.add(16 * k);
                    if floats >= 16 * (k + 1) {
                        _mm512_storeu_ps(p, w);
                    } else {
                        let left = floats.saturating_sub(16 * k);
                        let mask = ((1u32 << left) - 1) as __mmask16;
                        _mm512_mask_storeu_ps(p, mask, w);
                    }
                }
            }
        }
    }

    /// The tables of [`hit_records`], per window `k` of the sixteen six-word records
    /// (word `p` is field `p % 6` of record `p / 6`): `INDEX[k]` holds, in the lanes of
    /// `t` and `prim`, the two-source permute index of that lane (`r`, `16 + r`), in the
    /// lanes of `u` and `v` likewise, zero elsewhere; `MASKS[k]` the masks of the lanes of
    /// `(t, prim)`, of `(u, v)` and of the tag.
    const HIT_TABLES: ([[u32; 16]; 6], [[u16; 3]; 6]) = {
        let mut index = [[0u32; 16]; 6];
        let mut masks = [[0u16; 3]; 6];
        let mut k = 0;
        while k < 6 {
            let mut lane = 0;
            while lane < 16 {
                let p = 16 * k + lane;
                let (r, c) = ((p / 6) as u32, p % 6);
                match c {
                    0 | 2 => {
                        index[k][lane] = r + 16 * (c == 2) as u32;
                        masks[k][0] |= 1 << lane;
                    }
                    4 | 5 => {
                        index[k][lane] = r + 16 * (c == 5) as u32;
                        masks[k][1] |= 1 << lane;
                    }
                    1 => masks[k][2] |= 1 << lane,
                    _ => {}
                }
                lane += 1;
            }
            k += 1;
        }
        (index, masks)
    };

    /// [`store_hit_records`](super::store_hit_records): each window starts from its
    /// index lanes (zero in the spare word's), takes `(t, prim)` and `(u, v)` by masked
    /// two-source permutes (`vpermi2d`: lanes outside the mask keep the index
    /// operand's bits) and the tag by a masked move.
    ///
    /// # Safety
    /// `dst` must be valid for writes of 96 `u32`s.
    #[inline(always)]
    pub(super) unsafe fn hit_records(
        [t, u, v]: [&[f32; 16]; 3],
        prim: &[u32; 16],
        tag: u32,
        dst: *mut u32,
    ) {
        unsafe {
            let ld = |a: &[f32; 16]| _mm512_castps_si512(_mm512_loadu_ps(a.as_ptr()));
            let (t, u, v) = (ld(t), ld(u), ld(v));
            let prim = _mm512_loadu_si512(prim.as_ptr().cast());
            let tag = _mm512_set1_epi32(tag as i32);
            let (index, masks) = &HIT_TABLES;
            for k in 0..6 {
                let w = _mm512_loadu_si512(index[k].as_ptr().cast());
                let w = _mm512_mask2_permutex2var_epi32(t, w, masks[k][0], prim);
                let w = _mm512_mask2_permutex2var_epi32(u, w, masks[k][1], v);
                let w = _mm512_mask_mov_epi32(w, masks[k][2], tag);
                _mm512_storeu_si512(dst.add(16 * k).cast(), w);
            }
        }
    }

    /// The permute tables of [`store_lanes`], per window `k`: `BASE[k]` holds `tmin`
    /// (zero) and `tmax` (infinity) in their lanes and, in every other lane, the
    /// two-source permute index of its component within its pair of sources (pair 0:
    /// origin x, y; 1: origin z, direction x; 2: direction y, z; 3: time, time), and
    /// `PAIR[k][q]` is the mask of the lanes pair `q` fills.
    const LANE_TABLES: ([[u32; 16]; 9], [[u16; 4]; 9]) = {
        let mut base = [[0u32; 16]; 9];
        let mut pair = [[0u16; 4]; 9];
        let mut k = 0;
        while k < 9 {
            let mut lane = 0;
            while lane < 16 {
                let (r, c) = component(k, lane);
                if c == 6 {
                    base[k][lane] = 0f32.to_bits();
                } else if c == 7 {
                    base[k][lane] = f32::INFINITY.to_bits();
                } else {
                    // Component `c` of the seven sources (6 is the time, the 7th).
                    let s = if c == 8 { 6 } else { c };
                    base[k][lane] = (r + 16 * (s % 2)) as u32;
                    pair[k][s / 2] |= 1 << lane;
                }
                lane += 1;
            }
            k += 1;
        }
        (base, pair)
    };

    /// Writes rays `0..n` (`n <= 16`) from `dst` on, nine floats each: ray `i` is
    /// lane `i` of the sources origin x, y, z, direction x, y, z and time, with `tmin`
    /// zero and `tmax` infinity. Each window starts from its constant lanes and index
    /// lanes and takes each pair of sources in turn by a masked two-source permute
    /// (`vpermi2ps`: lanes outside the mask keep the index operand's bits, the
    /// constants and the indices of the pairs still to come).
    ///
    /// # Safety
    /// `dst` must be valid for `9 n` floats.
    #[inline(always)]
    pub(super) unsafe fn store_lanes(s: [&[f32; 16]; 7], n: usize, dst: *mut f32) {
        unsafe {
            let ld = |a: &[f32; 16]| _mm512_loadu_ps(a.as_ptr());
            let src = [
                (ld(s[0]), ld(s[1])),
                (ld(s[2]), ld(s[3])),
                (ld(s[4]), ld(s[5])),
                (ld(s[6]), ld(s[6])),
            ];
            let (base, pair) = &LANE_TABLES;
            let floats = 9 * n;
            for k in 0..9 {
                let mut w = _mm512_loadu_si512(base[k].as_ptr().cast());
                for (q, &(a, b)) in src.iter().enumerate() {
                    if pair[k][q] != 0 {
                        let v = _mm512_mask2_permutex2var_ps(a, w, pair[k][q], b);
                        w = _mm512_castps_si512(v);
                    }
                }
                let w = _mm512_castsi512_ps(w);
                let p = dst.add(16 * k);
                if floats >= 16 * (k + 1) {
                    _mm512_storeu_ps(p, w);
                } else {
                    let left = floats.saturating_sub(16 * k);
                    let mask = ((1u32 << left) - 1) as __mmask16;
                    _mm512_mask_storeu_ps(p, mask, w);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampling::PixelRng;

    /// A ray component: one in ten a special value (NaN, signed zeros, infinity, a
    /// subnormal), otherwise uniform in (-500, 500).
    fn component(rng: &mut PixelRng) -> f32 {
        const SPECIALS: [f32; 5] = [f32::NAN, -0.0, 0.0, f32::INFINITY, -1e-40];
        let r = rng.next_f32();
        if r < 0.1 {
            SPECIALS[(r * 50.0) as usize]
        } else {
            (rng.next_f32() - 0.5) * 1e3
        }
    }

    /// Seven 16-lane arrays of `draw`n components: origin, direction and time lanes.
    fn seven_lanes(draw: &mut impl FnMut() -> f32) -> [[f32; 16]; 7] {
        let mut a = [[0.0f32; 16]; 7];
        for c in a.iter_mut().flatten() {
            *c = draw();
        }
        a
    }

    /// The transposed stores give the plain loop's rays, bit for bit (NaN, signed
    /// zeros and infinities among the components), for every count 0..=16 of rays
    /// from 16-lane arrays, appended after rays already in the vector.
    #[test]
    fn transposed_stores_equal_the_plain_loop() {
        let mut rng = PixelRng::new(3, 9);
        let mut draw = || component(&mut rng);
        for n in 0..=16 {
            for _ in 0..20 {
                let a = seven_lanes(&mut draw);
                let o = [&a[0][..], &a[1][..], &a[2][..]];
                let d = [&a[3][..], &a[4][..], &a[5][..]];
                let head = Ray::new(glam::Vec3::ONE, glam::Vec3::X);
                let mut want = vec![head; 3];
                append_plain(o, d, &a[6], n, &mut want);
                assert_stores(&want, n, |got| append_rays(o, d, &a[6], n, got));
            }
        }
    }

    /// [`append_rays`] of sixteen-lane arrays (the AVX-512 window stores where the
    /// build has them) gives the plain loop's rays bit for bit for every count 0..=16,
    /// appended after rays already in the vector, with special values in every
    /// component, the time included; and lanes past `n` are not written (the vector's
    /// spare room keeps its sentinel).
    #[test]
    fn lane_stores_equal_the_plain_loop_and_stop_at_n() {
        let mut rng = PixelRng::new(11, 17);
        let mut draw = || component(&mut rng);
        for n in 0..=16 {
            for _ in 0..20 {
                let a = seven_lanes(&mut draw);
                let o = [&a[0][..], &a[1][..], &a[2][..]];
                let d = [&a[3][..], &a[4][..], &a[5][..]];
                let head = Ray::new(glam::Vec3::ONE, glam::Vec3::X);
                let mut want = vec![head; 2];
                append_plain(o, d, &a[6], n, &mut want);
                assert_stores(&want, n, |got| append_rays(o, d, &a[6], n, got));
            }
        }
    }

    /// Runs `store` on a vector holding `want`'s first rays (all but its last `n`)
    /// whose spare room for sixteen more holds a sentinel, then asserts that it
    /// appended `want`'s last `n` rays bit for bit and left the room past them holding
    /// the sentinel (no lane past `n` written).
    fn assert_stores(want: &[Ray], n: usize, store: impl FnOnce(&mut Vec<Ray>)) {
        let head = want.len() - n;
        let sentinel = Ray::new(glam::Vec3::splat(7.0), glam::Vec3::Y);
        // Room for all sixteen, filled with the sentinel, then cut back.
        let mut got = want[..head].to_vec();
        got.resize(head + 16, sentinel);
        got.truncate(head);
        store(&mut got);
        assert_eq!(got.len(), head + n);
        for (g, w) in got.iter().zip(want) {
            assert_eq!(g.bits(), w.bits(), "n {n}");
        }
        // SAFETY: the vector was `head + 16` rays long before `truncate` and the store
        // did not need to grow it (`reserve` of at most 16 more), so its capacity
        // covers rays `head + n..head + 16`, still the sentinel's bytes unless the
        // store wrote past ray `n`.
        assert!(got.capacity() >= head + 16);
        let spare = unsafe { std::slice::from_raw_parts(got.as_ptr().add(head + n), 16 - n) };
        for r in spare {
            assert_eq!(r.bits(), sentinel.bits(), "n {n}: wrote past the rays");
        }
    }

    /// A one-origin, one-time set of sixteen rays drawn from `draw`: the store, its
    /// origin as lanes, the directions and the time.
    #[allow(clippy::type_complexity)]
    fn uniform_case(
        draw: &mut impl FnMut() -> f32,
    ) -> (UniformRays, [[f32; 16]; 3], [[f32; 16]; 3], f32) {
        let origin = glam::Vec3::new(draw(), draw(), draw());
        let time = draw();
        let mut d = [[0.0f32; 16]; 3];
        for c in d.iter_mut().flatten() {
            *c = draw();
        }
        let o = origin.to_array().map(|c| [c; 16]);
        (UniformRays::new(origin, time), o, d, time)
    }

    /// [`UniformRays`] gives the plain loop's rays with every origin lane the one
    /// origin and every time lane the one time, bit for bit, for every count 0..=16
    /// of rays appended after rays already in the vector, with NaN, signed zeros,
    /// infinities and subnormals among the directions, the origin and the time; and
    /// lanes past `n` are not written (the vector's spare room keeps its sentinel).
    #[test]
    fn uniform_rays_equal_the_plain_loop() {
        let mut rng = PixelRng::new(5, 13);
        let mut draw = || component(&mut rng);
        for n in 0..=16 {
            for _ in 0..20 {
                let (store, o, d, time) = uniform_case(&mut draw);
                let head = Ray::new(glam::Vec3::ONE, glam::Vec3::X);
                let mut want = vec![head; 3];
                append_plain(
                    [&o[0][..], &o[1][..], &o[2][..]],
                    [&d[0][..], &d[1][..], &d[2][..]],
                    &[time; 16],
                    n,
                    &mut want,
                );
                assert_stores(&want, n, |got| store.append([&d[0], &d[1], &d[2]], n, got));
            }
        }
    }

    /// [`store_hit_records`] writes the plain loop's 96 words bit for bit (special
    /// values among the floats, any index and tag), every word of the sixteen records
    /// (a sentinel-filled array, compared whole).
    #[test]
    fn hit_records_equal_the_plain_loop() {
        let mut rng = PixelRng::new(3, 17);
        let mut draw = || component(&mut rng);
        for case in 0..50u32 {
            let a = seven_lanes(&mut draw);
            let prim: [u32; 16] = std::array::from_fn(|i| a[3][i].to_bits() ^ case);
            let tag = [0, 1, 5, u32::MAX][case as usize % 4];
            let (mut got, mut want) = ([0xdead_beef_u32; 96], [0x1234_5678_u32; 96]);
            // SAFETY: both arrays hold 96 words.
            unsafe {
                store_hit_records((&a[0], &a[1], &a[2]), &prim, tag, got.as_mut_ptr());
                hit_records_plain((&a[0], &a[1], &a[2]), &prim, tag, want.as_mut_ptr());
            }
            assert_eq!(got, want, "case {case}");
            assert_eq!(
                want[6 * 5..6 * 6],
                [
                    a[0][5].to_bits(),
                    tag,
                    prim[5],
                    0,
                    a[1][5].to_bits(),
                    a[2][5].to_bits()
                ]
            );
        }
    }

    /// [`UniformRays::write16`] writes the plain loop's sixteen rays bit for bit (the
    /// same special values among directions, origin and time), every byte of the
    /// sixteen (a sentinel-filled array, compared whole).
    #[test]
    fn uniform_rays_write16_equals_the_plain_loop() {
        let mut rng = PixelRng::new(7, 21);
        let mut draw = || component(&mut rng);
        for _ in 0..50 {
            let (store, o, d, time) = uniform_case(&mut draw);
            let mut want = Vec::new();
            append_plain(
                [&o[0][..], &o[1][..], &o[2][..]],
                [&d[0][..], &d[1][..], &d[2][..]],
                &[time; 16],
                16,
                &mut want,
            );
            let sentinel = Ray::new(glam::Vec3::splat(7.0), glam::Vec3::Y);
            let mut got = [std::mem::MaybeUninit::new(sentinel); 16];
            store.write16([&d[0], &d[1], &d[2]], &mut got);
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                // SAFETY: every element was initialised (the sentinel, then the store).
                let g = unsafe { g.assume_init() };
                assert_eq!(g.bits(), w.bits(), "ray {i}");
            }
        }
    }
}
