//! The protocol's workloads and its camera: framing, ray directions, the random
//! numbers of the diffuse workload.

use crate::geometry::{Ray, RayPacket, orthonormal_basis};
use glam::{DVec3, Vec3};
use serde::Serialize;

/// The three workloads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Workload {
    Primary,
    Shadow,
    Diffuse,
}

impl Workload {
    pub const ALL: [Workload; 3] = [Workload::Primary, Workload::Shadow, Workload::Diffuse];
    pub fn name(self) -> &'static str {
        match self {
            Workload::Primary => "primary",
            Workload::Shadow => "shadow",
            Workload::Diffuse => "diffuse",
        }
    }
}

/// Scene framing of the protocol, in f64.
#[derive(Clone, Copy, Debug)]
pub struct Framing {
    pub lo: DVec3,
    pub hi: DVec3,
    pub center: DVec3,
    pub diagonal: f64,
    pub eye: DVec3,
    pub light: DVec3,
}

impl Framing {
    /// `lo`, `hi` over all vertices of the file (used or not).
    pub fn new(positions: &[Vec3]) -> Framing {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in positions {
            lo = lo.min(p.as_dvec3());
            hi = hi.max(p.as_dvec3());
        }
        let center = (lo + hi) * 0.5;
        let diagonal = (hi - lo).length();
        Framing {
            lo,
            hi,
            center,
            diagonal,
            eye: center + DVec3::new(0.5, 0.3, 1.0).normalize() * (1.2 * diagonal),
            light: center + DVec3::new(0.8, 1.2, 0.6) * diagonal,
        }
    }
}

/// The protocol's pinhole camera: basis in f64, rounded to f32.
#[derive(Clone, Copy, Debug)]
pub struct BenchCamera {
    pub eye: Vec3,
    pub f: Vec3,
    pub r: Vec3,
    pub u: Vec3,
    pub tan_half: f32,
    pub aspect: f32,
    pub width: u32,
    pub height: u32,
}

impl BenchCamera {
    pub fn new(fr: &Framing, width: u32, height: u32) -> Self {
        let up = DVec3::Y;
        let f = (fr.center - fr.eye).normalize();
        let r = f.cross(up).normalize();
        let u = r.cross(f);
        BenchCamera {
            eye: fr.eye.as_vec3(),
            f: f.as_vec3(),
            r: r.as_vec3(),
            u: u.as_vec3(),
            tan_half: (22.5f64.to_radians()).tan() as f32,
            aspect: (width as f64 / height as f64) as f32,
            width,
            height,
        }
    }

    /// Camera rays of up to sixteen `pixels` written into `packet` (lanes
    /// `0..pixels.len()`, which becomes its `len`): the arithmetic of [`dir`](Self::dir)
    /// lane by lane (IEEE division and square root round the same in SIMD lanes), so
    /// the rays are bit-identical to the scalar ones.
    pub fn packet_into(&self, pixels: &[(u32, u32)], packet: &mut RayPacket) {
        use crate::simd::{F16, Lanes};
        assert!(pixels.len() <= 16, "a packet holds sixteen rays");
        let mut xs = [0.0f32; 16];
        let mut ys = [0.0f32; 16];
        for (k, &(x, y)) in pixels.iter().enumerate() {
            xs[k] = x as f32;
            ys[k] = y as f32;
        }
        self.lanes_into(F16::from_array(xs), F16::from_array(ys), packet);
        packet.len = pixels.len();
    }

    /// The camera rays of the 4x4 pixel block whose top left pixel is `(x0, y0)`, in
    /// row order (the order of [`packet_into`](Self::packet_into)'s pixels in the
    /// bench's tiles), written into `packet` (all sixteen lanes): the same rays.
    ///
    /// Why: the pixel coordinates are made in lanes (`x0 + column`, exact for integers
    /// below 2^24) instead of being stored lane by lane and read back whole, a load that
    /// cannot be forwarded from the sixteen stores and waits for them; and, inlined,
    /// a tile's four blocks form independent chains of divisions and square roots that
    /// overlap (`packet_into`, called per block, was 7 % of a bunny primary pass,
    /// mostly waiting at the end of that chain; `perf annotate` of
    /// `examples/stream_profile bunny.obj bvh8-packet primary 30`, AVX-512).
    #[inline(always)]
    pub fn block_into(&self, x0: u32, y0: u32, packet: &mut RayPacket) {
        use crate::simd::{F16, Lanes};
        const COLUMN: [f32; 16] = [
            0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0,
        ];
        const ROW: [f32; 16] = [
            0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0,
        ];
        let s = F16::splat;
        let x = s(x0 as f32) + F16::from_array(COLUMN);
        let y = s(y0 as f32) + F16::from_array(ROW);
        self.lanes_into(x, y, packet);
        packet.len = 16;
    }

    /// The rays through pixel coordinates `x`, `y` (integers as `f32`) into `packet`'s
    /// sixteen lanes (`len` left to the caller).
    #[inline(always)]
    fn lanes_into(&self, x: crate::simd::F16, y: crate::simd::F16, packet: &mut RayPacket) {
        use crate::simd::F16;
        let s = F16::splat;
        // `v / n` as `v * (1 / n)` where `n` is a power of two: both scale `v >= 1` by a
        // power of two exactly, so they are equal bit for bit (no overflow, no
        // underflow), and the multiplication spares a 16-lane division on the chain
        // to the packet's directions (two per packet at 1024 x 1024).
        let over = |v: F16, n: u32| {
            if n.is_power_of_two() {
                v * s(1.0 / n as f32)
            } else {
                v / s(n as f32)
            }
        };
        let sx =
            (over(s(2.0) * (x + s(0.5)), self.width) - s(1.0)) * s(self.tan_half) * s(self.aspect);
        let sy = (s(1.0) - over(s(2.0) * (y + s(0.5)), self.height)) * s(self.tan_half);
        let v = [0, 1, 2].map(|a| s(self.f[a]) + s(self.r[a]) * sx + s(self.u[a]) * sy);
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let inv = s(1.0) / len;
        for (a, &va) in v.iter().enumerate() {
            packet.dir[a] = (va * inv).to_array();
            packet.origin[a] = [self.eye[a]; 16];
        }
        packet.tmin = [0.0; 16];
        packet.tmax = [f32::INFINITY; 16];
        packet.time = [0.0; 16];
    }

    /// Camera rays of `pixels` appended to `out` (see [`packet_into`](Self::packet_into)).
    pub fn rays_into(&self, pixels: &[(u32, u32)], out: &mut Vec<Ray>) {
        let mut p = RayPacket::default();
        for chunk in pixels.chunks(16) {
            self.packet_into(chunk, &mut p);
            out.extend((0..p.len).map(|k| p.ray(k)));
        }
    }

    #[inline]
    pub fn dir(&self, x: u32, y: u32) -> Vec3 {
        let sx = (2.0 * (x as f32 + 0.5) / self.width as f32 - 1.0) * self.tan_half * self.aspect;
        let sy = (1.0 - 2.0 * (y as f32 + 0.5) / self.height as f32) * self.tan_half;
        normalize(self.f + self.r * sx + self.u * sy)
    }
}

/// `v * (1/|v|)`, the protocol's normalisation (not `v / |v|`).
#[inline]
pub(super) fn normalize(v: Vec3) -> Vec3 {
    v * (1.0 / v.length())
}

/// splitmix64 step, the protocol's per-pixel generator.
#[inline]
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The two uniforms of pixel `index`.
#[inline]
pub fn pixel_uniforms(index: u32) -> (f32, f32) {
    let mut s = index as u64;
    let u1 = (splitmix64(&mut s) >> 40) as f32 * (1.0 / 16_777_216.0);
    let u2 = (splitmix64(&mut s) >> 40) as f32 * (1.0 / 16_777_216.0);
    (u1, u2)
}

/// [`pixel_uniforms`] of the sixteen pixels of the 4x4 block whose top left pixel is
/// `(x0, y0)` in an image `width` wide (lane `k` is pixel `(x0 + k % 4, y0 + k / 4)`,
/// index `y width + x`, wrapping): the same draws, bit for bit, computed lane by lane
/// in a loop the compiler vectorises (AVX-512DQ's 64-bit `vpmullq`).
///
/// Why (issue 12, pk26): the two draws per diffuse ray were scalar 64-bit multiplies
/// and shifts, per lane of a block, inside the loop that gathers each lane's primary hit.
#[inline(always)]
pub fn pixel_uniforms_block(x0: u32, y0: u32, width: u32) -> ([f32; 16], [f32; 16]) {
    let (mut u1, mut u2) = ([0.0f32; 16], [0.0f32; 16]);
    for k in 0..16u32 {
        let index = (y0 + k / 4).wrapping_mul(width).wrapping_add(x0 + k % 4);
        (u1[k as usize], u2[k as usize]) = pixel_uniforms(index);
    }
    (u1, u2)
}

/// Cosine-weighted direction around unit `n` (Duff et al. basis).
#[inline]
pub fn cosine_dir(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = (2.0 * std::f64::consts::PI) as f32 * u2;
    let (lx, ly) = (r * phi.cos(), r * phi.sin());
    let lz = (1.0 - u1).max(0.0).sqrt();
    let (t1, t2) = orthonormal_basis(n);
    normalize(t1 * lx + t2 * ly + n * lz)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera rays made in lanes are the scalar `dir`'s, bit for bit, for image sides
    /// that are powers of two (divided by multiplying with the exact reciprocal) and
    /// sides that are not, the image's corners and edges included.
    #[test]
    fn simd_camera_rays_are_bit_identical_to_scalar_ones() {
        let positions = [Vec3::new(-1.0, 0.2, -0.5), Vec3::new(0.7, 1.9, 0.3)];
        for (w, h) in [(1024, 768), (1024, 1024), (640, 2048), (70, 54), (1, 1)] {
            let cam = BenchCamera::new(&Framing::new(&positions), w, h);
            let mut pixels: Vec<(u32, u32)> = (0..37).map(|i| (i * 27 % w, i * 19 % h)).collect();
            pixels.extend([
                (0, 0),
                (w - 1, 0),
                (0, h - 1),
                (w - 1, h - 1),
                (w / 2, h / 2),
            ]);
            let mut rays = Vec::new();
            cam.rays_into(&pixels, &mut rays);
            for (r, &(x, y)) in rays.iter().zip(&pixels) {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(r.dir), bits(cam.dir(x, y)), "{w}x{h} pixel ({x}, {y})");
                assert_eq!(r.origin, cam.eye);
            }
        }
    }

    /// A block's draws in lanes are `pixel_uniforms` of each of its pixels, bit for
    /// bit, for blocks inside the image, on its edges and past them.
    #[test]
    fn block_draws_are_the_pixels_draws() {
        for (x0, y0, w) in [
            (0, 0, 1024),
            (1020, 1020, 1024),
            (68, 52, 70),
            (4, 8, 7),
            (0, 0, 1),
        ] {
            let (u1, u2) = pixel_uniforms_block(x0, y0, w);
            for k in 0..16u32 {
                let (a, b) = pixel_uniforms((y0 + k / 4) * w + x0 + k % 4);
                let i = k as usize;
                assert_eq!(
                    (u1[i].to_bits(), u2[i].to_bits()),
                    (a.to_bits(), b.to_bits())
                );
                assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
            }
        }
    }

    /// A full 4x4 block's rays made from its corner (`block_into`) are those of its
    /// sixteen pixels (`packet_into`), bit for bit, every field of every lane.
    #[test]
    fn block_rays_are_the_pixels_rays() {
        let positions = [Vec3::new(-1.0, 0.2, -0.5), Vec3::new(0.7, 1.9, 0.3)];
        let cam = BenchCamera::new(&Framing::new(&positions), 1024, 768);
        let bits = |p: &RayPacket| {
            let mut v = vec![p.len as u32];
            for a in 0..3 {
                v.extend(p.origin[a].map(f32::to_bits));
                v.extend(p.dir[a].map(f32::to_bits));
            }
            for lanes in [&p.tmin, &p.tmax, &p.time] {
                v.extend(lanes.map(f32::to_bits));
            }
            v
        };
        for (x0, y0) in [(0, 0), (4, 0), (508, 380), (1020, 764), (16, 200), (800, 8)] {
            let pixels: Vec<(u32, u32)> = (0..16).map(|k| (x0 + k % 4, y0 + k / 4)).collect();
            let (mut a, mut b) = (RayPacket::default(), RayPacket::default());
            cam.packet_into(&pixels, &mut a);
            cam.block_into(x0, y0, &mut b);
            assert_eq!(bits(&b), bits(&a), "block at ({x0}, {y0})");
        }
    }
}
