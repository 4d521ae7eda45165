//! Sixteen [`Ray`]s from an array of structs into lanes ([`RayLanes`] and the interval
//! ends): the tiny scene's lane groups (`accel::tiny`) and the hit batch's surface
//! lanes (`integrator::hit_batch`) start from rays held as structs in a queue.
//!
//! With AVX2 each ray's first 32 bytes (origin, direction, `tmin`, `tmax`) are one
//! unaligned load, and two 8x8 transposes (`ray_store`'s, the other way round) turn
//! sixteen such rows into the eight component rows: 16 loads and 48 shuffles where
//! the plain loop ([`RayLanes::gather`]) does 128 scalar loads and as many stores.
//! Measured before (`perf annotate`, whitted_base `--spp 9 --sampler grid`, 1 thread):
//! the plain gather was about a fifth of `TinyScene::closest_batch`'s own time.

use super::kernels::RayLanes;
use super::{PACKET_WIDTH, Packet};
use crate::geometry::{Ray, RayPacket};

// The layout the loads rely on: origin, direction, tmin, tmax as the first eight f32s.
const _: () = {
    assert!(std::mem::size_of::<Ray>() == 36);
    assert!(std::mem::offset_of!(Ray, origin) == 0);
    assert!(std::mem::offset_of!(Ray, dir) == 12);
    assert!(std::mem::offset_of!(Ray, tmin) == 24);
    assert!(std::mem::offset_of!(Ray, tmax) == 28);
};

/// The rays `rays[idx[l]]` as lanes `l` (origins, directions, `tmin`) and their
/// interval ends: what [`RayLanes::gather`] gives for those sixteen rays. Every index
/// must be in bounds (checked: a ray past the end panics, as indexing does).
#[inline(always)]
pub fn gather_rays(rays: &[Ray], idx: &[u32; 16]) -> (RayLanes<Packet>, Packet) {
    let max = idx.iter().copied().max().unwrap_or(0) as usize;
    assert!(max < rays.len(), "ray {max} of {}", rays.len());
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        // SAFETY: every index is below `rays.len()` (checked above), and each load
        // reads the first 32 of a ray's 36 bytes (layout asserted above).
        unsafe { avx2::gather(rays.as_ptr(), idx) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        RayLanes::gather(idx.iter().map(|&i| &rays[i as usize]))
    }
}

/// [`gather_rays`] of sixteen consecutive rays (`window` holds at least sixteen).
#[inline(always)]
pub fn load_rays(window: &[Ray]) -> (RayLanes<Packet>, Packet) {
    const IDX: [u32; 16] = {
        let mut a = [0u32; 16];
        let mut i = 0;
        while i < 16 {
            a[i] = i as u32;
            i += 1;
        }
        a
    };
    gather_rays(window, &IDX)
}

/// Up to sixteen consecutive rays as a [`RayPacket`] (lanes past `window.len()` zero,
/// as [`RayPacket::from_rays`] leaves them): the same lanes as `from_rays`, a full
/// packet through the transposed loads of [`load_rays`] rather than lane by lane.
#[inline(always)]
pub fn packet_of_rays(window: &[Ray]) -> RayPacket {
    if window.len() < PACKET_WIDTH {
        return RayPacket::from_rays(window);
    }
    let (r, tmax) = load_rays(window);
    let mut time = [0.0; PACKET_WIDTH];
    for (t, ray) in time.iter_mut().zip(window) {
        *t = ray.time;
    }
    RayPacket {
        origin: r.o.map(Packet::to_array),
        dir: r.d.map(Packet::to_array),
        tmin: r.tmin.to_array(),
        tmax: tmax.to_array(),
        time,
        len: PACKET_WIDTH,
    }
}

/// `table[idx[l]]` in lane `l` for the lanes of `mask` (bits 0-15), zero in the others:
/// with AVX-512 one masked hardware gather, all sixteen loads in flight at once. Every
/// index under `mask` must be in bounds (checked: one out of bounds panics, as indexing
/// does).
#[inline(always)]
pub fn gather_u32(table: &[u32], idx: &[u32; 16], mask: u32) -> [u32; 16] {
    check_lanes(table.len(), idx, mask);
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        // SAFETY: every index under `mask` is below `table.len()` and below 2^31
        // (checked above), and the other lanes load nothing.
        unsafe { avx512::gather_u32(table.as_ptr(), idx, mask) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    {
        let mut out = [0; 16];
        for (l, o) in out.iter_mut().enumerate() {
            if mask >> l & 1 == 1 {
                *o = table[idx[l] as usize];
            }
        }
        out
    }
}

/// [`gather_u32`] of an `f32` table, as lanes.
#[inline(always)]
pub fn gather_f32(table: &[f32], idx: &[u32; 16], mask: u32) -> Packet {
    check_lanes(table.len(), idx, mask);
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        // SAFETY: as in `gather_u32`.
        unsafe { avx512::gather_f32(table.as_ptr(), idx, mask) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    {
        let mut out = [0.0; 16];
        for (l, o) in out.iter_mut().enumerate() {
            if mask >> l & 1 == 1 {
                *o = table[idx[l] as usize];
            }
        }
        Packet::new(out)
    }
}

/// [`gather_f32`] of three tables at the same indices (a point's coordinates, a
/// vertex normal's), the indices checked once against the shortest table.
///
/// Before (`integrator::hit_batch`, the corners and vertex normals of a lane group's
/// triangles): a closure doing three `gather_f32`s that the compiler kept out of line,
/// six calls per lane group, each checking the indices three times with a scalar and
/// 256-bit mix: 1.9 % of the bunny frame's render phase (perf record -e cpu-clock,
/// 1024x1024, 1 thread, AVX-512), its compare and reduction most of it.
#[inline(always)]
pub fn gather_f32x3(tables: [&[f32]; 3], idx: &[u32; 16], mask: u32) -> [Packet; 3] {
    let len = tables[0].len().min(tables[1].len()).min(tables[2].len());
    check_lanes(len, idx, mask);
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        // SAFETY: every index under `mask` is below each table's length and below
        // 2^31 (checked above), and the other lanes load nothing.
        unsafe { tables.map(|t| avx512::gather_f32(t.as_ptr(), idx, mask)) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    {
        tables.map(|t| gather_f32(t, idx, mask))
    }
}

/// Panics unless every `idx[l]` under `mask` is below `len` and below 2^31 (the
/// hardware gathers' indices are signed). With AVX-512 one unsigned compare of the
/// sixteen lanes under the mask.
#[inline(always)]
fn check_lanes(len: usize, idx: &[u32; 16], mask: u32) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        let limit = lane_limit(len);
        use std::arch::x86_64::*;
        // SAFETY: an unaligned load of sixteen `u32`s; compares only.
        let bad = unsafe {
            let vi = _mm512_loadu_si512(idx.as_ptr().cast());
            _mm512_mask_cmpge_epu32_mask(mask as __mmask16, vi, _mm512_set1_epi32(limit as i32))
        };
        assert!(bad == 0, "gather index out of bounds ({len})");
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    check_lanes_plain(len, idx, mask);
}

/// The bound every gathered index must stay below: the table's length, at most 2^31 - 1.
#[inline(always)]
fn lane_limit(len: usize) -> u32 {
    len.min(i32::MAX as usize) as u32
}

/// The plain loop of [`check_lanes`] (its reference, and the path without AVX-512).
#[inline(always)]
#[cfg_attr(
    all(target_arch = "x86_64", target_feature = "avx512f"),
    allow(dead_code)
)]
fn check_lanes_plain(len: usize, idx: &[u32; 16], mask: u32) {
    let limit = lane_limit(len);
    let mut bad = 0u32;
    for (l, &i) in idx.iter().enumerate() {
        bad |= ((i >= limit) as u32) << l;
    }
    assert!(
        bad & mask & 0xffff == 0,
        "gather index out of bounds ({len})"
    );
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
mod avx512 {
    use super::Packet;
    use std::arch::x86_64::*;

    /// # Safety
    /// Every `idx[l]` under `mask` must index `table`'s array and be below 2^31.
    #[inline(always)]
    pub unsafe fn gather_u32(table: *const u32, idx: &[u32; 16], mask: u32) -> [u32; 16] {
        unsafe {
            let vi = _mm512_loadu_si512(idx.as_ptr() as *const _);
            let g = _mm512_mask_i32gather_epi32::<4>(
                _mm512_setzero_si512(),
                mask as __mmask16,
                vi,
                table as *const i32,
            );
            std::mem::transmute::<__m512i, [u32; 16]>(g)
        }
    }

    /// # Safety
    /// As [`gather_u32`].
    #[inline(always)]
    pub unsafe fn gather_f32(table: *const f32, idx: &[u32; 16], mask: u32) -> Packet {
        unsafe {
            let vi = _mm512_loadu_si512(idx.as_ptr() as *const _);
            let g =
                _mm512_mask_i32gather_ps::<4>(_mm512_setzero_ps(), mask as __mmask16, vi, table);
            // SAFETY: `Packet` (`wide::f32x16`) is one `__m512` with AVX-512 (as in
            // `simd::aperture`).
            std::mem::transmute::<__m512, Packet>(g)
        }
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod avx2 {
    use super::super::ray_store::avx2::transpose;
    use super::{Packet, Ray, RayLanes};
    use std::arch::x86_64::*;

    /// # Safety
    /// Every `idx[l]` must index a ray of the array at `rays`.
    ///
    /// Tried, no clear win, reverted (issue 11, bf24, 2026-11-29): with AVX-512 each
    /// component's two 8-lane halves joined into one register (`_mm512_insertf64x4`)
    /// before `packet_of_rays` stores it, so that the packet kernel's 64-byte loads of
    /// the `RayPacket` read one store each instead of spanning two 32-byte stores (no
    /// store forwarding: the first such load held 14-20 % of the bunny frame's
    /// `closest_hit_packet_lanes` samples). The stall went away there, but the samples
    /// of `SceneAccel::closest_hit_batch` and `closest_hit_packet_lanes` together
    /// (perf record -e cpu-clock -F 10000, 5 bunny frames 1024x1024, 1 thread, load
    /// 6-8, 4 interleaved rounds) were 227/236/276/238 joined against 242/245/251/264
    /// as halves: 2-3 % of the wrappers, 0.2 % of the frame, inside the noise.
    #[inline(always)]
    pub unsafe fn gather(rays: *const Ray, idx: &[u32; 16]) -> (RayLanes<Packet>, Packet) {
        unsafe {
            let mut c = [[0.0f32; 16]; 8];
            for half in 0..2 {
                let row =
                    |l: usize| _mm256_loadu_ps(rays.add(idx[8 * half + l] as usize) as *const f32);
                let cols = transpose([
                    row(0),
                    row(1),
                    row(2),
                    row(3),
                    row(4),
                    row(5),
                    row(6),
                    row(7),
                ]);
                for (k, col) in cols.iter().enumerate() {
                    _mm256_storeu_ps(c[k].as_mut_ptr().add(8 * half), *col);
                }
            }
            let [ox, oy, oz, dx, dy, dz, tmin, tmax] = c.map(Packet::new);
            (
                RayLanes {
                    o: [ox, oy, oz],
                    d: [dx, dy, dz],
                    tmin,
                },
                tmax,
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::xorshift64;

    /// `n` rays of values drawn from `seed`, a tenth of them NaN, signed zeros,
    /// infinities or a subnormal.
    fn random_rays(seed: u64, n: usize) -> Vec<Ray> {
        let mut next = xorshift64(seed);
        let specials = [
            f32::NAN,
            -0.0,
            0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -1e-40,
        ];
        let mut draw = move || {
            let r = next();
            if r.is_multiple_of(10) {
                specials[(r >> 8) as usize % specials.len()]
            } else {
                ((r >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 1e3
            }
        };
        (0..n)
            .map(|_| Ray {
                origin: glam::Vec3::new(draw(), draw(), draw()),
                dir: glam::Vec3::new(draw(), draw(), draw()),
                tmin: draw(),
                tmax: draw(),
                time: draw(),
            })
            .collect()
    }

    /// The transposed loads give the plain gather's lanes bit for bit (NaN, signed
    /// zeros, infinities among the components), for consecutive windows and for
    /// scattered, repeated indices.
    #[test]
    fn transposed_loads_equal_the_plain_gather() {
        let rays = random_rays(0x2545_f491_4f6c_dd1d, 200);
        let bits = |l: &RayLanes<Packet>, t: Packet| {
            let mut v = Vec::new();
            for p in l.o.iter().chain(&l.d).chain([&l.tmin, &t]) {
                v.extend(p.to_array().map(f32::to_bits));
            }
            v
        };
        for start in 0..rays.len() - 16 {
            let (got, gt) = load_rays(&rays[start..]);
            let (want, wt) = RayLanes::gather(&rays[start..start + 16]);
            assert_eq!(bits(&got, gt), bits(&want, wt), "window at {start}");
            let idx: [u32; 16] = std::array::from_fn(|l| ((start * 7 + l * l * 13) % 200) as u32);
            let (got, gt) = gather_rays(&rays, &idx);
            let (want, wt) = RayLanes::gather(idx.iter().map(|&i| &rays[i as usize]));
            assert_eq!(bits(&got, gt), bits(&want, wt), "indices {idx:?}");
        }
        // The component order of the lanes.
        let (l, t) = load_rays(&rays);
        assert_eq!(l.d[1].to_array()[3].to_bits(), rays[3].dir.y.to_bits());
        assert_eq!(t.to_array()[15].to_bits(), rays[15].tmax.to_bits());
    }

    /// `packet_of_rays` is `RayPacket::from_rays` bit for bit (every lane of every
    /// component, the time and the length), for full windows at every offset and for
    /// every shorter window, with NaN, signed zeros and infinities among the values.
    #[test]
    fn packet_of_rays_is_from_rays() {
        let rays = random_rays(0x9e37_79b9_7f4a_7c15, 64);
        let bits = |p: &RayPacket| {
            let mut v: Vec<u32> = Vec::new();
            for a in p
                .origin
                .iter()
                .chain(&p.dir)
                .chain([&p.tmin, &p.tmax, &p.time])
            {
                v.extend(a.map(f32::to_bits));
            }
            (v, p.len)
        };
        for start in 0..rays.len() {
            let end = (start + 16).min(rays.len());
            let window = &rays[start..end];
            assert_eq!(
                bits(&packet_of_rays(window)),
                bits(&RayPacket::from_rays(window)),
                "window {start}..{end}"
            );
        }
    }

    /// The masked gathers give `table[idx[l]]` in every lane of the mask, bit for bit
    /// (NaN and signed zeros among the values), and zero elsewhere, whatever the other
    /// lanes' indices hold (out of bounds included), over many masks.
    #[test]
    fn masked_gathers_are_table_lookups() {
        let mut next = xorshift64(0x1234_5678_9abc_def1);
        let n = 1000;
        let ints: Vec<u32> = (0..n).map(|_| next() as u32).collect();
        let mut floats: Vec<f32> = (0..n).map(|_| f32::from_bits(next() as u32)).collect();
        floats[3] = -0.0;
        floats[4] = f32::NAN;
        for round in 0..500 {
            let mask = (next() as u32) & 0xffff | if round % 7 == 0 { 0xffff } else { 0 };
            let idx: [u32; 16] = std::array::from_fn(|l| {
                let i = (next() % n as u64) as u32;
                // Lanes off the mask may index anything.
                if mask >> l & 1 == 0 && l % 3 == 0 {
                    u32::MAX - l as u32
                } else {
                    i
                }
            });
            let got_u = gather_u32(&ints, &idx, mask);
            let got_f = gather_f32(&floats, &idx, mask).to_array();
            for l in 0..16 {
                let on = mask >> l & 1 == 1;
                let want_u = if on { ints[idx[l] as usize] } else { 0 };
                let want_f = if on {
                    floats[idx[l] as usize].to_bits()
                } else {
                    0
                };
                assert_eq!(got_u[l], want_u, "round {round} lane {l}");
                assert_eq!(got_f[l].to_bits(), want_f, "round {round} lane {l}");
            }
        }
    }

    /// `gather_f32x3` is three `gather_f32`s bit for bit (tables of different
    /// lengths, indices off the mask anywhere), and `check_lanes` (one vector compare
    /// with AVX-512) panics exactly where the plain loop does: indices at, just below
    /// and past the length and past 2^31, under and off the mask, lengths up to past
    /// 2^31.
    #[test]
    fn three_gathers_and_the_lane_check_are_the_plain_ones() {
        let mut next = xorshift64(0x0dd_ba11_5eed);
        let tables: [Vec<f32>; 3] = std::array::from_fn(|k| {
            (0..300 + 7 * k)
                .map(|_| f32::from_bits(next() as u32))
                .collect()
        });
        let t = [&tables[0][..], &tables[1][..], &tables[2][..]];
        for round in 0..300 {
            let mask = (next() as u32) & 0xffff;
            let idx: [u32; 16] = std::array::from_fn(|l| match (mask >> l & 1, next() % 5) {
                (0, 0) => u32::MAX - l as u32,
                _ => (next() % 300) as u32,
            });
            let got = gather_f32x3(t, &idx, mask).map(|p| p.to_array().map(f32::to_bits));
            let want = t.map(|t| gather_f32(t, &idx, mask).to_array().map(f32::to_bits));
            assert_eq!(got, want, "round {round}");
        }
        let lens = [
            0usize,
            1,
            16,
            299,
            300,
            i32::MAX as usize,
            u32::MAX as usize + 5,
        ];
        for round in 0..300 {
            let len = lens[round % lens.len()];
            let mask = (next() as u32) & 0xffff | if round % 3 == 0 { 0xffff } else { 0 };
            let near = [
                0,
                1,
                15,
                298,
                299,
                300,
                301,
                i32::MAX as u32,
                1 << 31,
                u32::MAX,
            ];
            let idx: [u32; 16] = std::array::from_fn(|_| match next() % 4 {
                0 => near[(next() % near.len() as u64) as usize],
                _ => (next() % 8) as u32,
            });
            let run = |f: fn(usize, &[u32; 16], u32)| {
                std::panic::catch_unwind(|| f(len, &idx, mask)).is_err()
            };
            let vector = run(check_lanes);
            let plain = run(check_lanes_plain);
            assert_eq!(vector, plain, "len {len} mask {mask:#x} idx {idx:?}");
        }
    }

    /// An index out of bounds under the mask panics (the gathers do not read past the
    /// table).
    #[test]
    #[should_panic(expected = "out of bounds")]
    fn masked_gather_checks_its_bounds() {
        let table = [1.0f32; 10];
        let mut idx = [0u32; 16];
        idx[9] = 10;
        gather_f32(&table, &idx, 1 << 9);
    }
}
