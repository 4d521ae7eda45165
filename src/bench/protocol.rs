//! One fixed set of primary, shadow and diffuse rays over a mesh, traced in 8x8 tiles
//! and bands of 8 rows, with the checksums other tracers must reproduce.

use super::cpu_time;
use super::modes::TraceMode;
use super::timing::{BUSY_SHARE, Measured, Timing};
use super::workload::normalize;
use super::workload::{BenchCamera, Framing, Workload, pixel_uniforms_block};
use crate::accel::Triangles;
use crate::geometry::{Ray, RayPacket};
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// Per-pixel primary results: `t` and triangle (`u32::MAX` for a miss).
#[derive(Clone, Debug)]
pub struct PrimaryHits {
    pub t: Vec<f32>,
    pub prim: Vec<u32>,
}

/// Checksums of one workload pass.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Checksums {
    pub rays: u64,
    pub hits_or_occluded: u64,
    pub sum_t: f64,
}

const TILE: u32 = 8;
const BAND: u32 = 8;

/// Sixteen secondary rays as lanes (see [`Protocol::secondary_lanes`]); diffuse rays
/// end at infinity.
struct SecondaryLanes {
    o: [[f32; 16]; 3],
    d: [[f32; 16]; 3],
    tmax: [f32; 16],
}

impl SecondaryLanes {
    #[inline(always)]
    fn ray(&self, k: usize) -> Ray {
        let v = |a: &[[f32; 16]; 3]| Vec3::new(a[0][k], a[1][k], a[2][k]);
        Ray::segment(v(&self.o), v(&self.d), 0.0, self.tmax[k])
    }

    /// Lane `k` written into lane `i` of `packet`: the fields of [`ray`](Self::ray),
    /// copied array to array (through a `Ray`, each field was read back by glam's
    /// `Index`, a `match` per component).
    #[inline(always)]
    fn write(&self, k: usize, packet: &mut RayPacket, i: usize) {
        for a in 0..3 {
            packet.origin[a][i] = self.o[a][k];
            packet.dir[a][i] = self.d[a][k];
        }
        packet.tmin[i] = 0.0;
        packet.tmax[i] = self.tmax[k];
        packet.time[i] = 0.0;
    }

    /// Every lane written into the same lane of `packet` (a block whose sixteen
    /// pixels all have a ray): [`write`](Self::write) for each lane, as whole-array
    /// copies.
    #[inline(always)]
    fn write_block(&self, packet: &mut RayPacket) {
        (packet.origin, packet.dir) = (self.o, self.d);
        (packet.tmin, packet.tmax, packet.time) = ([0.0; 16], self.tmax, [0.0; 16]);
    }
}

/// Bits `c` of the ids of `row` that are a hit (not `u32::MAX`); a row of four (a
/// whole block's) is compared as one fixed-length array.
#[inline(always)]
fn hit_bits(row: &[u32]) -> u32 {
    let bits = |ids: &[u32]| {
        ids.iter()
            .enumerate()
            .fold(0, |m, (c, &id)| m | u32::from(id != u32::MAX) << c)
    };
    match <&[u32; 4]>::try_from(row) {
        Ok(four) => bits(four),
        Err(_) => bits(row),
    }
}

/// A stream mode's band (see [`Protocol::trace_band`]): its rays, the band pixel of
/// each, and the answers; one set per thread, reused.
#[derive(Default)]
struct BandBuffers {
    rays: Vec<Ray>,
    slots: Vec<u32>,
    t: Vec<f32>,
    prim: Vec<u32>,
    occ: Vec<bool>,
}

thread_local! {
    static BAND_BUFFERS: std::cell::Cell<BandBuffers> = std::cell::Cell::new(BandBuffers::default());
}

/// The fixed ray set over one mesh.
pub struct Protocol {
    pub tris: Triangles,
    pub framing: Framing,
    pub camera: BenchCamera,
    /// Geometric normals per triangle (file order), the protocol's `n`.
    pub normals: Vec<Vec3>,
}

/// `band[l..l + cols]` set to `x`: one 16-byte store for a row of a whole 4x4 block
/// (a fill of a length known only at run time was a call to `memset` per row: 2.2 % of
/// a bunny shadow pass, issue 12, pk21).
#[inline(always)]
fn fill_row<T: Copy>(band: &mut [T], l: usize, cols: usize, x: T) {
    if cols == 4 {
        band[l..l + 4].copy_from_slice(&[x; 4]);
    } else {
        band[l..l + cols].fill(x);
    }
}

/// Pixel `k` (row order) of the 4x4 block whose top left pixel is `(x0, y0)`.
#[inline(always)]
fn block_pixel(x0: u32, y0: u32, k: usize) -> (u32, u32) {
    (x0 + k as u32 % 4, y0 + k as u32 / 4)
}

impl Protocol {
    pub fn new(positions: &[Vec3], tris: Triangles, width: u32, height: u32) -> Self {
        let framing = Framing::new(positions);
        let camera = BenchCamera::new(&framing, width, height);
        let normals = (0..tris.v0.len())
            .map(|i| normalize((tris.v1[i] - tris.v0[i]).cross(tris.v2[i] - tris.v0[i])))
            .collect();
        Protocol {
            tris,
            framing,
            camera,
            normals,
        }
    }

    fn pixels(&self) -> usize {
        (self.camera.width * self.camera.height) as usize
    }

    /// The secondary ray of pixel `i` for `workload`, from its primary hit: the
    /// protocol's definition, one ray at a time (the pass computes sixteen at a time in
    /// lanes, `secondary_lanes`, tested against this).
    #[cfg(test)]
    fn secondary_ray(
        &self,
        workload: Workload,
        x: u32,
        y: u32,
        dir: Vec3,
        t: f32,
        prim: u32,
    ) -> Ray {
        let cam = &self.camera;
        let p = cam.eye + dir * t;
        let mut n = self.normals[prim as usize];
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let eps = (1e-4 * self.framing.diagonal) as f32;
        let o = p + n * eps;
        match workload {
            Workload::Shadow => {
                let to = self.framing.light.as_vec3() - o;
                let tmax = to.length();
                Ray::segment(o, to * (1.0 / tmax), 0.0, tmax)
            }
            _ => {
                let (u1, u2) = super::workload::pixel_uniforms(y * cam.width + x);
                Ray::new(o, super::workload::cosine_dir(n, u1, u2))
            }
        }
    }

    /// The secondary rays (`workload` shadow or diffuse) of the lanes `hit` of the 4x4
    /// block at `(x0, y0)` (lane `k` is pixel `(x0 + k % 4, y0 + k / 4)`; its camera
    /// rays are in `camera`, as `BenchCamera::block_into` makes them), computed sixteen
    /// at a time:
    /// the arithmetic of `secondary_ray` (the test's oracle) lane by lane (the same
    /// operations in the same order, no fused multiply-add; IEEE division and square
    /// root round the same in lanes; the diffuse rays' random numbers per lane by the
    /// scalar function, their sine and cosine by libm's algorithm in lanes,
    /// `simd::kernels::sin_cos_libm16`), so the rays are bit-identical to the scalar
    /// ones (test `secondary_lanes_are_the_scalar_rays`).
    ///
    /// Why: the scalar generation of a shadow ray per pixel, with the camera rays of
    /// every block (blocks without a hit included), was a third of a bunny shadow pass
    /// (`perf record` of `examples/stream_profile bunny.obj bvh8-packet shadow 30`,
    /// AVX-512: `packet_any` 50 %, the pass's closure 23 %, `packet_into` 12 %).
    fn secondary_lanes(
        &self,
        workload: Workload,
        (x0, y0): (u32, u32),
        camera: &RayPacket,
        hit: u32,
        p: &PrimaryHits,
    ) -> SecondaryLanes {
        use crate::simd::{F16, Lanes};
        let w = self.camera.width;
        let mut t = [0.0f32; 16];
        let mut n = [[0.0f32; 16]; 3];
        let diffuse = workload != Workload::Shadow;
        let mut m = hit;
        while m != 0 {
            let k = m.trailing_zeros() as usize;
            m &= m - 1;
            let (x, y) = block_pixel(x0, y0, k);
            let i = (y * w + x) as usize;
            t[k] = p.t[i];
            let nk = self.normals[p.prim[i] as usize];
            (n[0][k], n[1][k], n[2][k]) = (nk.x, nk.y, nk.z);
        }
        // Diffuse: each pixel's `u1` and `u2`, sixteen at a time (every lane's, in the
        // image or not, with a ray or not: unused lanes are never read back).
        let (u1, u2) = if diffuse {
            pixel_uniforms_block(x0, y0, w)
        } else {
            ([0.0; 16], [0.0; 16])
        };
        let s = F16::splat;
        let t = F16::from_array(t);
        let d = camera.dir.map(F16::from_array);
        let eye = self.camera.eye;
        // p = eye + dir * t
        let pt = [0, 1, 2].map(|a| s(eye[a]) + d[a] * t);
        let n = n.map(F16::from_array);
        // n flipped to face the camera ray: `n.dot(dir) > 0` (glam's order).
        let facing = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]).gt(s(0.0));
        let n = n.map(|c| F16::select(facing, -c, c));
        let eps = s((1e-4 * self.framing.diagonal) as f32);
        let light = self.framing.light.as_vec3();
        // o = p + n * eps; to = light - o; tmax = |to| (glam's order); dir = to * (1 / tmax)
        let o = [0, 1, 2].map(|a| pt[a] + n[a] * eps);
        if diffuse {
            // `cosine_dir`: local direction, Duff et al.'s basis, `normalize`. The
            // cosine and sine of `phi = 2 pi u2` are libm's bit for bit, computed in
            // lanes (`sin_cos_libm16`; libm's call per lane was 6 % of a bunny diffuse
            // pass).
            let phi = s((2.0 * std::f64::consts::PI) as f32) * F16::from_array(u2);
            let (sin, cos) = crate::simd::kernels::sin_cos_libm16(&phi.to_array());
            let u1 = F16::from_array(u1);
            let r = u1.sqrt();
            let (lx, ly) = (r * F16::from_array(cos), r * F16::from_array(sin));
            let lz = (s(1.0) - u1).maxps(s(0.0)).sqrt();
            let sign = F16::select(F16::mask_from_bits(n[2].sign_bits()), s(-1.0), s(1.0));
            let a = s(-1.0) / (sign + n[2]);
            let b = n[0] * n[1] * a;
            let t1 = [s(1.0) + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
            let t2 = [b, sign + n[1] * n[1] * a, -n[1]];
            let v = [0, 1, 2].map(|k| t1[k] * lx + t2[k] * ly + n[k] * lz);
            let inv = s(1.0) / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            return SecondaryLanes {
                o: o.map(F16::to_array),
                d: v.map(|c| (c * inv).to_array()),
                tmax: [f32::INFINITY; 16],
            };
        }
        let to = [0, 1, 2].map(|a| s(light[a]) - o[a]);
        let tmax = (to[0] * to[0] + to[1] * to[1] + to[2] * to[2]).sqrt();
        let inv = s(1.0) / tmax;
        SecondaryLanes {
            o: o.map(F16::to_array),
            d: to.map(|c| (c * inv).to_array()),
            tmax: tmax.to_array(),
        }
    }

    /// One pass of `workload` with `mode`; writes per-pixel results: primary and
    /// diffuse rays into `t_out` (hit distance or NaN for a miss) and `prim_out` (the
    /// triangle, `u32::MAX` for a miss), shadow rays into `occ_out` alone (1 occluded,
    /// 0 free or no ray: one byte per pixel, as Embree's harness writes). All three
    /// have one entry per pixel. Returns the number of rays traced.
    ///
    /// Issue 12, pk26: a shadow pass wrote a 4-byte `t` per pixel (1.0 / 0.0 / NaN),
    /// 4 MB per pass at 1024 x 1024 against the 1 MB of Embree's harness.
    ///
    /// Packet modes answer in lanes (`TraceMode::closest_packet_lanes`,
    /// `occluded_packet_bits`, as Embree's `rtcIntersect16` answers in `RTCRayHit16`),
    /// and a packet that is one whole camera block is written back row by row. Issue 12,
    /// pk21: before, each lane's `Option<Hit>` was built by the kernel and read back
    /// here with a branch per lane (2.9 % and 4 % of a bunny primary pass), a slot
    /// was listed per pixel (1.5 %), and a shadow pass also wrote `prim_out` (0 for a
    /// ray, `u32::MAX` for none, by `memset` per block row: 2.2 %); Embree's harness
    /// writes one byte per shadow pixel. Same rays, same timed region (ray generation,
    /// tracing, one write per pixel's result), same checksums.
    pub fn pass(
        &self,
        mode: &dyn TraceMode,
        workload: Workload,
        primary: Option<&PrimaryHits>,
        t_out: &mut [f32],
        prim_out: &mut [u32],
        occ_out: &mut [u8],
    ) -> u64 {
        let (w, h) = (self.camera.width, self.camera.height);
        let band_len = (BAND * w) as usize;
        let pixels = self.pixels();
        assert!(
            t_out.len() == pixels && prim_out.len() == pixels && occ_out.len() == pixels,
            "one result per pixel"
        );
        t_out
            .par_chunks_mut(band_len)
            .zip(prim_out.par_chunks_mut(band_len))
            .zip(occ_out.par_chunks_mut(band_len))
            .enumerate()
            .with_max_len(1)
            .map(|(band, ((t_band, prim_band), occ_band))| {
                let y0 = band as u32 * BAND;
                // A tile's valid rays in order, as four SoA packets of sixteen for packet
                // modes or as a slice for the others; `slots[k]` is the band pixel of ray k.
                let soa = mode.takes_packets();
                // Stream modes: the band's valid rays (in `rays`, not cleared per tile)
                // and their pixels, traced at the end, in this thread's band buffers.
                let band_mode = mode.takes_band();
                let mut band = if band_mode {
                    BAND_BUFFERS.take()
                } else {
                    BandBuffers::default()
                };
                band.slots.clear();
                let mut packets = [RayPacket::default(); 4];
                let mut rays = std::mem::take(&mut band.rays);
                rays.clear();
                rays.reserve(64);
                let mut camera = RayPacket::default();
                let mut slots = [0usize; 64];
                let mut hits = [None; 16];
                let mut occ = [false; 16];
                let (mut lane_t, mut lane_prim) = ([0.0f32; 16], [0u32; 16]);
                let mut count = 0u64;
                for ty in (y0..(y0 + BAND).min(h)).step_by(TILE as usize) {
                    for tx in (0..w).step_by(TILE as usize) {
                        if !band_mode {
                            rays.clear();
                        }
                        let mut n = 0;
                        // Packet `b` is the whole 4x4 block whose top left band pixel
                        // is `blocks[b]` (its answers are written row by row from the
                        // lanes, without `slots`).
                        let mut blocks = [None::<usize>; 4];
                        let local = |(x, y): (u32, u32)| ((y - y0) * w + x) as usize;
                        // By 4x4 block (row order), by row in a block; lane `k` of a
                        // block is its pixel `(k % 4, k / 4)` whether or not the image
                        // clips it, and a tile's rays are the blocks' rays in order,
                        // sixteen to a packet.
                        //
                        // Why (issue 12, pk20): the tile's pixels were listed one by one
                        // (`tile_pixels`, a `Vec` push per pixel), a secondary pass
                        // branched per pixel on its primary hit (mispredicted along the
                        // silhouette), made camera rays through the pixel list
                        // (`packet_into`) and copied each ray into its packet through a
                        // `Ray`: in `perf record` of `examples/stream_profile bunny.obj
                        // bvh8-packet shadow 80` (AVX-512) the pass's closure was 31 % of
                        // a shadow pass and `packet_into` 4.2 %, the branch alone 8.7 %.
                        // The timed region is unchanged (the protocol's: ray generation
                        // from the stored primary hits, tracing, the per-pixel writes).
                        // The load of a row's primary ids still stalls (20 % of the
                        // closure's samples); tried, no win: the ids and distances of the
                        // tile two tiles ahead prefetched at each tile's start (eight rows,
                        // `simd::prefetch`), two interleaved pairs of `perf record` of
                        // `stream_profile bunny.obj bvh8-packet shadow 60` (cpu 1.00):
                        // closure 28.97 / 29.51 % of the pass, medians 12.01 / 11.85
                        // Mrays/s, with it 34.73 / 32.26 %, 11.78 / 11.82.
                        // Tried, no win (issue 12, pk26): tiles of 16 x 4 (four blocks side
                        // by side), so a band is walked four rows at a time, as Embree's
                        // packet16 harness walks it (half as many rows, so pages, of the
                        // primary ids and distances and of the outputs in use at once: 32
                        // 4 KB pages with 8 rows, the L2 streamer's limit). Same checksums.
                        // `stream_profile bunny.obj MODE WORKLOAD REPS`, 4 interleaved
                        // rounds, load 3.3, Mrays per CPU-second, 8 x 8 against 16 x 4:
                        // bvh8-packet primary 52.2/55.8/54.0/56.0 against
                        // 54.3/56.2/55.9/62.2, shadow 18.3/18.9/19.8/19.4 against
                        // 18.8/18.4/19.5/18.6, bvh8-stream diffuse 6.95/6.64/6.59/6.91
                        // against 6.77/6.86/6.88/6.58: within the noise.
                        for (bx, by) in [(0, 0), (4, 0), (0, 4), (4, 4)] {
                            let (x0, yb) = (tx + bx, ty + by);
                            if x0 >= w || yb >= h {
                                continue;
                            }
                            let (cols, rows) = ((w - x0).min(4) as usize, (h - yb).min(4));
                            if workload == Workload::Primary {
                                // the lanes inside the image
                                let inside =
                                    (0..rows).fold(0u32, |m, r| m | ((1 << cols) - 1) << (4 * r));
                                // A whole block starting a packet is made in place.
                                let whole = inside == 0xffff && n % 16 == 0;
                                let made = if whole {
                                    &mut packets[n / 16]
                                } else {
                                    &mut camera
                                };
                                self.camera.block_into(x0, yb, made);
                                if whole && soa {
                                    blocks[n / 16] = Some(local((x0, yb)));
                                    n += 16;
                                    continue;
                                }
                                if whole {
                                    rays.extend((0..16).map(|k| packets[n / 16].ray(k)));
                                }
                                let mut m = inside;
                                while m != 0 {
                                    let k = m.trailing_zeros() as usize;
                                    m &= m - 1;
                                    if !whole {
                                        let r = camera.ray(k);
                                        if soa {
                                            packets[n / 16].set(n % 16, &r);
                                        } else {
                                            rays.push(r);
                                        }
                                    }
                                    slots[n] = local(block_pixel(x0, yb, k));
                                    n += 1;
                                }
                                continue;
                            }
                            let Some(p) = primary else {
                                unreachable!("secondary workloads need primary hits")
                            };
                            // Secondary rays start from the camera rays' hits: the pixels
                            // with a primary hit. Every pixel is first written as a miss
                            // (a hit's result overwrites it after tracing), row by row,
                            // and the hit bits taken from a row's ids: no branch per pixel.
                            // A shadow pass writes `t` alone (see `checksums`).
                            let mut hit = 0u32;
                            for r in 0..rows {
                                let (i, l) = (((yb + r) * w + x0) as usize, local((x0, yb + r)));
                                hit |= hit_bits(&p.prim[i..i + cols]) << (4 * r);
                                if workload == Workload::Shadow {
                                    fill_row(occ_band, l, cols, 0u8);
                                } else {
                                    fill_row(t_band, l, cols, f32::NAN);
                                    fill_row(prim_band, l, cols, u32::MAX);
                                }
                            }
                            // No camera rays for a block the mesh misses (Embree's
                            // harness computes a pixel's camera ray only where it hit).
                            if hit == 0 {
                                continue;
                            }
                            self.camera.block_into(x0, yb, &mut camera);
                            let lanes = self.secondary_lanes(workload, (x0, yb), &camera, hit, p);
                            // A block with sixteen rays starting a packet is copied in
                            // whole and its answers written back by rows, as a primary
                            // pass's whole blocks are (issue 12, pk22: the lane-by-lane
                            // copy, its slots and the shadow answers written through
                            // them were ~1/4 of the pass's closure, which was 28 % of a
                            // bunny shadow pass, `perf record` of `examples/stream_profile
                            // bunny.obj bvh8-packet shadow 100`).
                            if hit == 0xffff && n % 16 == 0 && soa {
                                lanes.write_block(&mut packets[n / 16]);
                                blocks[n / 16] = Some(local((x0, yb)));
                                n += 16;
                                continue;
                            }
                            let mut m = hit;
                            while m != 0 {
                                let k = m.trailing_zeros() as usize;
                                m &= m - 1;
                                if soa {
                                    lanes.write(k, &mut packets[n / 16], n % 16);
                                } else {
                                    rays.push(lanes.ray(k));
                                }
                                slots[n] = local(block_pixel(x0, yb, k));
                                n += 1;
                            }
                        }
                        count += n as u64;
                        if band_mode {
                            band.slots.extend(slots[..n].iter().map(|&s| s as u32));
                            continue;
                        }
                        for b in 0..n.div_ceil(16) {
                            let len = (n - 16 * b).min(16);
                            packets[b].len = len;
                            let slots = &slots[16 * b..16 * b + len];
                            if workload == Workload::Shadow {
                                if soa {
                                    let bits = mode.occluded_packet_bits(&packets[b]);
                                    let occ = |k: usize| u8::from(bits >> k & 1 == 1);
                                    if let Some(l) = blocks[b] {
                                        for r in 0..4 {
                                            let (row, k) = (l + r * w as usize, 4 * r);
                                            occ_band[row..row + 4].copy_from_slice(&[
                                                occ(k),
                                                occ(k + 1),
                                                occ(k + 2),
                                                occ(k + 3),
                                            ]);
                                        }
                                    } else {
                                        for (k, &s) in slots.iter().enumerate() {
                                            occ_band[s] = occ(k);
                                        }
                                    }
                                } else {
                                    mode.occluded(&rays[16 * b..16 * b + len], &mut occ[..len]);
                                    for (k, &s) in slots.iter().enumerate() {
                                        occ_band[s] = u8::from(occ[k]);
                                    }
                                }
                            } else if soa {
                                mode.closest_packet_lanes(&packets[b], &mut lane_t, &mut lane_prim);
                                if let Some(l) = blocks[b] {
                                    for r in 0..4 {
                                        let (row, k) = (l + r * w as usize, 4 * r);
                                        t_band[row..row + 4].copy_from_slice(&lane_t[k..k + 4]);
                                        prim_band[row..row + 4]
                                            .copy_from_slice(&lane_prim[k..k + 4]);
                                    }
                                } else {
                                    for (k, &s) in slots.iter().enumerate() {
                                        (t_band[s], prim_band[s]) = (lane_t[k], lane_prim[k]);
                                    }
                                }
                            } else {
                                mode.closest(&rays[16 * b..16 * b + len], &mut hits[..len]);
                                for (k, &s) in slots.iter().enumerate() {
                                    (t_band[s], prim_band[s]) = match hits[k] {
                                        Some(hh) => (hh.t, hh.prim),
                                        None => (f32::NAN, u32::MAX),
                                    };
                                }
                            }
                        }
                    }
                }
                if band_mode {
                    band.rays = rays;
                    self.trace_band(mode, workload, &mut band, (t_band, prim_band, occ_band));
                    BAND_BUFFERS.set(band);
                }
                count
            })
            .sum()
    }

    /// A stream mode's band: `band.rays` traced as one batch, the answer of ray `k`
    /// written to band pixel `band.slots[k]`; closest hits come back as lanes
    /// (`TraceMode::closest_lanes`: distance and triangle per ray, no `Option<Hit>`).
    ///
    /// Why (issue 12, pk26): the band's rays, pixels and answers were fresh `Vec`s per
    /// band (the rays grown by doubling, each copied in from the tile's), and the
    /// answers `Option<Hit>`s filled with `None`, scattered and read back with a branch
    /// per ray: `memset`, `memmove` and this function's loop were ~4 % of a bunny
    /// diffuse pass (`perf record` of `examples/stream_profile bunny.obj bvh8-stream
    /// diffuse 40`). Now one set of buffers per thread, reused by every band and pass.
    fn trace_band(
        &self,
        mode: &dyn TraceMode,
        workload: Workload,
        band: &mut BandBuffers,
        (t_band, prim_band, occ_band): (&mut [f32], &mut [u32], &mut [u8]),
    ) {
        let n = band.rays.len();
        if workload == Workload::Shadow {
            band.occ.clear();
            band.occ.resize(n, false);
            mode.occluded(&band.rays, &mut band.occ);
            for (&o, &s) in band.occ.iter().zip(&band.slots) {
                occ_band[s as usize] = u8::from(o);
            }
        } else {
            band.t.resize(n, 0.0);
            band.prim.resize(n, 0);
            mode.closest_lanes(&band.rays, &mut band.t[..n], &mut band.prim[..n]);
            for ((&t, &p), &s) in band.t[..n].iter().zip(&band.prim[..n]).zip(&band.slots) {
                (t_band[s as usize], prim_band[s as usize]) = (t, p);
            }
        }
    }

    /// The untimed primary pass that shadow and diffuse rays start from.
    pub fn primary_hits(&self, mode: &dyn TraceMode) -> PrimaryHits {
        let mut t = vec![0.0; self.pixels()];
        let mut prim = vec![0; self.pixels()];
        let mut occ = vec![0; self.pixels()];
        self.pass(mode, Workload::Primary, None, &mut t, &mut prim, &mut occ);
        PrimaryHits { t, prim }
    }

    /// Checksums of a pass's results, summed in f64 in pixel order.
    /// A shadow pass's results are `occ` alone (see [`pass`](Self::pass)).
    pub fn checksums(
        workload: Workload,
        rays: u64,
        t: &[f32],
        prim: &[u32],
        occ: &[u8],
    ) -> Checksums {
        let mut c = Checksums {
            rays,
            hits_or_occluded: 0,
            sum_t: 0.0,
        };
        if workload == Workload::Shadow {
            c.hits_or_occluded = occ.iter().filter(|&&o| o == 1).count() as u64;
            return c;
        }
        for (tt, pp) in t.iter().zip(prim) {
            if *pp != u32::MAX {
                c.hits_or_occluded += 1;
                c.sum_t += *tt as f64;
            }
        }
        c
    }

    /// Times `timing.reps` passes after a warm-up (see [`Timing`]); returns the
    /// checksums, the Mrays/s of each pass and the CPU share of the timed passes.
    pub fn measure(
        &self,
        mode: &dyn TraceMode,
        workload: Workload,
        primary: Option<&PrimaryHits>,
        timing: &Timing,
    ) -> Measured {
        let threads = rayon::current_num_threads();
        let mut t = vec![0.0; self.pixels()];
        let mut prim = vec![0; self.pixels()];
        let mut occ = vec![0; self.pixels()];
        let mut best: Option<(Vec<f64>, f64)> = None;
        let mut rays = 0;
        let mut attempts = 0;
        for _ in 0..=timing.retry_busy {
            attempts += 1;
            // Warm-up: caches, page faults, the clock ramping up; at least one pass.
            let warm = Instant::now();
            loop {
                rays = self.pass(mode, workload, primary, &mut t, &mut prim, &mut occ);
                if warm.elapsed().as_secs_f64() >= timing.warmup_s {
                    break;
                }
            }
            let mut secs = Vec::with_capacity(timing.reps);
            // The wall span encloses both CPU-clock reads, so for one thread the share
            // cannot exceed 1 by the passes' bookkeeping between the timed intervals
            // (with passes of microseconds, comparing against the sum of the passes
            // alone gave 1.06 once under load).
            let span = Instant::now();
            let c0 = cpu_time::process_cpu_seconds();
            for _ in 0..timing.reps {
                let start = Instant::now();
                rays = self.pass(mode, workload, primary, &mut t, &mut prim, &mut occ);
                secs.push(start.elapsed().as_secs_f64());
            }
            let cpu = cpu_time::process_cpu_seconds()
                .zip(c0)
                .map(|(c1, c0)| c1 - c0);
            let util = cpu_time::utilisation(cpu, span.elapsed().as_secs_f64(), threads);
            // NaN (no clock) never retries and never replaces a measured share.
            if best.as_ref().is_none_or(|b| util > b.1) {
                best = Some((secs, util));
            }
            if best
                .as_ref()
                .is_none_or(|b| b.1.is_nan() || b.1 >= BUSY_SHARE)
            {
                break;
            }
        }
        let (secs, cpu_util) = best.expect("at least one attempt");
        Measured {
            checksums: Self::checksums(workload, rays, &t, &prim, &occ),
            rates: secs.iter().map(|s| rays as f64 / s / 1e6).collect(),
            cpu_util,
            attempts,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::{BenchMesh, build_mode};

    /// Every shadow and diffuse ray computed in lanes (`secondary_lanes`) is the scalar
    /// `secondary_ray` of its pixel, bit for bit (origin, direction, interval), over
    /// every block of an image whose width and height cut tiles and blocks short; and
    /// the packet, stream and single-ray modes answer passes of them, and the primary
    /// pass (whole camera blocks written back by rows, clipped ones by slots), as the
    /// scalar reference does.
    #[test]
    fn secondary_lanes_are_the_scalar_rays() {
        let mesh = BenchMesh::procedural(3000);
        let (w, h) = (70, 54);
        let protocol = Protocol::new(&mesh.positions, mesh.triangles.clone(), w, h);
        let scalar = build_mode("scalar-bvh2", &protocol.tris).expect("mode");
        let primary = protocol.primary_hits(scalar.as_ref());
        let bits = |r: &Ray| {
            let (o, d) = (r.origin.to_array(), r.dir.to_array());
            [o[0], o[1], o[2], d[0], d[1], d[2], r.tmin, r.tmax, r.time].map(f32::to_bits)
        };
        let t_bits = |t: &[f32]| t.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let modes = ["bvh8-packet", "bvh4-packet", "bvh8-stream", "bvh8-single"];
        let hits = primary.prim.iter().filter(|&&p| p != u32::MAX).count();
        assert!(
            hits > 500 && hits < (w * h) as usize - 500,
            "{hits} primary hits"
        );
        for mode in modes {
            let m = build_mode(mode, &protocol.tris).expect("mode");
            let p = protocol.primary_hits(m.as_ref());
            assert_eq!(t_bits(&p.t), t_bits(&primary.t), "primary {mode}");
            assert_eq!(p.prim, primary.prim, "primary {mode}");
        }
        let mut camera = RayPacket::default();
        for workload in [Workload::Shadow, Workload::Diffuse] {
            let mut checked = 0u64;
            let mut want_occ = vec![0u8; (w * h) as usize];
            // every 4x4 block, those the image clips included
            for y0 in (0..h).step_by(4) {
                for x0 in (0..w).step_by(4) {
                    let in_image = |(x, y): (u32, u32)| x < w && y < h;
                    let hit = (0..16).fold(0u32, |m, k| {
                        let (x, y) = block_pixel(x0, y0, k);
                        let hit =
                            in_image((x, y)) && primary.prim[(y * w + x) as usize] != u32::MAX;
                        m | u32::from(hit) << k
                    });
                    protocol.camera.block_into(x0, y0, &mut camera);
                    let lanes =
                        protocol.secondary_lanes(workload, (x0, y0), &camera, hit, &primary);
                    for k in (0..16).filter(|k| hit >> k & 1 == 1) {
                        let (x, y) = block_pixel(x0, y0, k);
                        let i = (y * w + x) as usize;
                        let dir = protocol.camera.dir(x, y);
                        let (t, prim) = (primary.t[i], primary.prim[i]);
                        let want = protocol.secondary_ray(workload, x, y, dir, t, prim);
                        let mut occ = [false];
                        scalar.occluded(&[want], &mut occ);
                        want_occ[i] = u8::from(occ[0]);
                        let got = lanes.ray(k);
                        assert_eq!(bits(&got), bits(&want), "{workload:?} ({x}, {y})");
                        // and written straight into a packet's lane, the same ray
                        let mut packet = RayPacket::default();
                        (packet.tmin, packet.time) = ([f32::NAN; 16], [f32::NAN; 16]);
                        lanes.write(k, &mut packet, 15 - k);
                        assert_eq!(bits(&packet.ray(15 - k)), bits(&want));
                        // and with the whole block, in its own lane
                        let mut block = RayPacket::default();
                        (block.tmin, block.time) = ([f32::NAN; 16], [f32::NAN; 16]);
                        lanes.write_block(&mut block);
                        assert_eq!(bits(&block.ray(k)), bits(&want));
                        checked += 1;
                    }
                }
            }
            assert!(checked > 500, "too few hits to check: {checked}");
            // The pass: every mode's answers equal the scalar reference's.
            let n = (w * h) as usize;
            let (mut t0, mut p0, mut o0) = (vec![0.0; n], vec![0; n], vec![7; n]);
            let rays = protocol.pass(
                scalar.as_ref(),
                workload,
                Some(&primary),
                &mut t0,
                &mut p0,
                &mut o0,
            );
            assert_eq!(rays, checked);
            if workload == Workload::Shadow {
                // One byte per pixel: each ray's scalar occlusion, 0 without a ray.
                assert_eq!(o0, want_occ, "shadow answers");
                let occluded = o0.iter().filter(|&&o| o == 1).count();
                assert!(
                    occluded > 50 && occluded + 50 < checked as usize,
                    "{occluded}"
                );
            }
            for mode in modes {
                let m = build_mode(mode, &protocol.tris).expect("mode");
                let (mut t1, mut p1, mut o1) = (vec![0.0; n], vec![0; n], vec![7; n]);
                protocol.pass(
                    m.as_ref(),
                    workload,
                    Some(&primary),
                    &mut t1,
                    &mut p1,
                    &mut o1,
                );
                assert_eq!(t_bits(&t1), t_bits(&t0), "{workload:?} {mode}");
                assert_eq!(p1, p0, "{workload:?} {mode}");
                assert_eq!(o1, o0, "{workload:?} {mode}");
            }
        }
    }
}
