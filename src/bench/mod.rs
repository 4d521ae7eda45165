//! The throughput protocol of `shared/BENCHMARK.md`, shared by `packet-render bench` and
//! the criterion benches: one fixed set of primary, shadow and diffuse rays over a
//! mesh, timed per tracing mode, with the checksums other tracers must reproduce.
//!
//! Reading of the protocol, matching `shared/anchors/embree/src/protocol.h`: framing
//! and camera basis in f64 rounded to f32, ray directions normalised in f32 as
//! `v * (1/|v|)`; shadow and diffuse rays start from the primary hits of the mode under
//! test's own structure, computed once untimed; rays are generated and traced in 8x8
//! tiles (ordered as 4x4 blocks, so 16 consecutive rays are a 4x4 pixel block and 8 a
//! 4x2 block), and bands of 8 rows are handed to threads dynamically. Stream modes
//! (`bvh4-stream`, `bvh8-stream`) get a band's valid rays, in that tile order, as one
//! batch (Embree's harness hands `rtcIntersect1M` one tile of 64 rays).

pub mod compare;
pub mod converge;
pub mod cpu_time;
pub mod lecture;
pub mod precision;
pub mod sweep;

use crate::accel::{
    Accel, AccelKind, Bvh, BvhNode, NodeWidth, Prefetch, QNode, Triangles, WideNode, Width,
};
use crate::geometry::{Hit, Ray, RayPacket, orthonormal_basis};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

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
        let s = F16::splat;
        let (x, y) = (F16::from_array(xs), F16::from_array(ys));
        let sx = (s(2.0) * (x + s(0.5)) / s(self.width as f32) - s(1.0))
            * s(self.tan_half)
            * s(self.aspect);
        let sy = (s(1.0) - s(2.0) * (y + s(0.5)) / s(self.height as f32)) * s(self.tan_half);
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
        packet.len = pixels.len();
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
fn normalize(v: Vec3) -> Vec3 {
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

/// A tracing mode under test: how a batch of rays (one 8x8 tile, 4x4-block ordered,
/// compacted to valid rays) is traced.
pub trait TraceMode: Send + Sync {
    fn name(&self) -> &'static str;
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]);
    fn occluded(&self, rays: &[Ray], out: &mut [bool]);
    /// Whether the mode traces SoA packets ([`closest_packet`](Self::closest_packet)),
    /// so the harness generates rays straight into lanes, as Embree's does for
    /// `rtcIntersect16`; otherwise it generates a slice of rays.
    fn takes_packets(&self) -> bool {
        false
    }
    /// One packet of rays in SoA form.
    fn closest_packet(&self, rays: &RayPacket, out: &mut [Option<Hit>]) {
        let aos: [Ray; 16] = std::array::from_fn(|k| rays.ray(k));
        self.closest(&aos[..rays.len], out);
    }
    fn occluded_packet(&self, rays: &RayPacket, out: &mut [bool]) {
        let aos: [Ray; 16] = std::array::from_fn(|k| rays.ray(k));
        self.occluded(&aos[..rays.len], out);
    }
    /// Whether the mode takes a whole band's rays as one batch (stream modes, as
    /// Embree's `rtcIntersect1M`), instead of one tile's at a time.
    fn takes_band(&self) -> bool {
        false
    }
    fn build_ms(&self) -> f64;
    /// Bytes of the structure traced (nodes and leaves).
    fn memory_bytes(&self) -> usize;
}

/// One ray at a time through [`Accel::closest_hit`] / [`Accel::any_hit`].
pub struct SingleRay {
    pub name: &'static str,
    pub accel: Box<dyn Accel>,
}

impl TraceMode for SingleRay {
    fn name(&self) -> &'static str {
        self.name
    }
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.accel.closest_hit(r);
        }
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.accel.any_hit(r);
        }
    }

    fn build_ms(&self) -> f64 {
        self.accel.info().build_ms
    }
    fn memory_bytes(&self) -> usize {
        self.accel.info().memory_bytes
    }
}

/// The batch entry points of [`Accel`] (packet kernels where the structure has them).
pub struct Batched {
    pub name: &'static str,
    pub accel: Box<dyn Accel>,
}

impl TraceMode for Batched {
    fn name(&self) -> &'static str {
        self.name
    }
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.accel.closest_hit_batch(rays, out);
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) {
        self.accel.any_hit_batch(rays, out);
    }
    fn takes_packets(&self) -> bool {
        true
    }
    fn closest_packet(&self, rays: &RayPacket, out: &mut [Option<Hit>]) {
        self.accel.closest_hit_packet(rays, out);
    }
    fn occluded_packet(&self, rays: &RayPacket, out: &mut [bool]) {
        self.accel.any_hit_packet(rays, out);
    }
    fn build_ms(&self) -> f64 {
        self.accel.info().build_ms
    }
    fn memory_bytes(&self) -> usize {
        self.accel.info().memory_bytes
    }
}

/// The BVH8's packet kernels with a tuning (see [`PACKET_TUNING_MODES`]).
pub struct HalfPackets {
    pub name: &'static str,
    /// Trace 8-ray halves.
    pub half: bool,
    pub bvh: Bvh<Triangles, 8>,
}

impl TraceMode for HalfPackets {
    fn name(&self) -> &'static str {
        self.name
    }
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        if self.half {
            self.bvh.closest_hit_batch8(rays, out);
        } else {
            self.bvh.closest_hit_batch(rays, out);
        }
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) {
        if self.half {
            self.bvh.any_hit_batch8(rays, out);
        } else {
            self.bvh.any_hit_batch(rays, out);
        }
    }
    fn takes_packets(&self) -> bool {
        true
    }
    fn closest_packet(&self, rays: &RayPacket, out: &mut [Option<Hit>]) {
        if self.half {
            self.bvh.closest_hit_packet8(rays, out);
        } else {
            self.bvh.closest_hit_packet(rays, out);
        }
    }
    fn occluded_packet(&self, rays: &RayPacket, out: &mut [bool]) {
        if self.half {
            self.bvh.any_hit_packet8(rays, out);
        } else {
            self.bvh.any_hit_packet(rays, out);
        }
    }
    fn build_ms(&self) -> f64 {
        self.bvh.info().build_ms
    }
    fn memory_bytes(&self) -> usize {
        self.bvh.info().memory_bytes
    }
}

/// The stream entry points of [`Accel`]: a band's valid rays as one batch.
pub struct Streamed {
    pub name: &'static str,
    pub accel: Box<dyn Accel>,
}

impl TraceMode for Streamed {
    fn name(&self) -> &'static str {
        self.name
    }
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.accel.closest_hit_stream(rays, out);
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) {
        self.accel.any_hit_stream(rays, out);
    }
    fn takes_band(&self) -> bool {
        true
    }
    fn build_ms(&self) -> f64 {
        self.accel.info().build_ms
    }
    fn memory_bytes(&self) -> usize {
        self.accel.info().memory_bytes
    }
}

/// The modes `packet-render bench` runs by default, by name.
pub const MODES: &[&str] = &[
    "scalar-bvh2",
    "bvh4-single",
    "bvh4-packet",
    "bvh4-stream",
    "bvh8-single",
    "bvh8-packet",
    "bvh8-stream",
];

/// The same kernels on compressed nodes (`bvh4c`, `bvh8c`: child boxes quantised to 8
/// bits per plane), run when asked for by name.
pub const COMPRESSED_MODES: &[&str] = &[
    "bvh4c-single",
    "bvh4c-packet",
    "bvh4c-stream",
    "bvh8c-single",
    "bvh8c-packet",
    "bvh8c-stream",
];

/// Every N-wide mode with node prefetching forced on (`+pf`) or off (`+nopf`) for its
/// kernel, whatever [`Prefetch::default`] says: the A/B of the prefetch.
pub const PREFETCH_MODES: &[&str] = &[
    "bvh4-single+pf",
    "bvh4-single+nopf",
    "bvh4-packet+pf",
    "bvh4-packet+nopf",
    "bvh4-stream+pf",
    "bvh4-stream+nopf",
    "bvh8-single+pf",
    "bvh8-single+nopf",
    "bvh8-packet+pf",
    "bvh8-packet+nopf",
    "bvh8-stream+pf",
    "bvh8-stream+nopf",
    "bvh4c-single+pf",
    "bvh4c-single+nopf",
    "bvh4c-packet+pf",
    "bvh4c-packet+nopf",
    "bvh4c-stream+pf",
    "bvh4c-stream+nopf",
    "bvh8c-single+pf",
    "bvh8c-single+nopf",
    "bvh8c-packet+pf",
    "bvh8c-packet+nopf",
    "bvh8c-stream+pf",
    "bvh8c-stream+nopf",
];

/// Tuning variants of the BVH8's packet kernels: `packet8` traces each 16-ray packet
/// as two 8-ray halves (`F8` lanes, AVX2's width, Embree's `rtcOccluded8` shape); `@K`
/// sets the ray-by-ray threshold (a packet part with fewer than K active lanes finishes
/// its subtree ray by ray; Embree's hybrid kernels switch at 7 of 8 lanes).
///
/// Not shown to win, so the defaults stay (16 lanes, threshold 3). Bunny, 1 thread, 5
/// passes, two runs on the loaded AVX2 machine (cpu 0.62-0.69), shadow medians Mrays/s:
/// `bvh8-packet` 4.06 and 7.26 (first and last mode of one run: the noise), 4.27 and
/// 3.87; `packet8` 4.06, 5.24; `@5` 4.02, 4.37; `@8` 3.93, 5.61; `packet8@5` 4.03,
/// 4.59; `packet8@7` 5.03, 4.05. Instructions (callgrind, `examples/stream_profile
/// bunny.obj MODE shadow 1`) of the occlusion kernel: 16 lanes 328.0 M, `@8` 329.8 M,
/// `packet8` 346.3 M (+5.6 %), `packet8@5` 350.2 M. Kept for a quiet-machine A/B.
pub const PACKET_TUNING_MODES: &[&str] = &[
    "bvh8-packet8",
    "bvh8-packet@2",
    "bvh8-packet@5",
    "bvh8-packet@8",
    "bvh8-packet@12",
    "bvh8-packet8@2",
    "bvh8-packet8@5",
    "bvh8-packet8@7",
];

/// The name of a mode `bench` knows, as a `'static` string.
pub fn known_mode(name: &str) -> Option<&'static str> {
    MODES
        .iter()
        .chain(COMPRESSED_MODES)
        .chain(PREFETCH_MODES)
        .chain(PACKET_TUNING_MODES)
        .copied()
        .find(|&m| m == name)
}

/// An N-wide BVH over `tris` with node type `T`, prefetching in `kernel` forced to
/// `prefetch` where given.
fn wide_accel<const N: usize, T: WideNode<N>>(
    tris: Triangles,
    kernel: &str,
    prefetch: Option<bool>,
) -> Box<dyn Accel>
where
    Width<N>: NodeWidth,
{
    let mut bvh = Bvh::<Triangles, N, T>::build(tris);
    if let Some(on) = prefetch {
        let mut p = Prefetch::default();
        match kernel {
            "single" => p.single = on,
            "packet" => p.packet = on,
            _ => p.stream = on,
        }
        bvh.set_prefetch(p);
    }
    Box::new(bvh)
}

/// Builds a mode over `tris` (the mesh in file order): `scalar-bvh2`, or
/// `<structure>-<kernel>[+pf|+nopf]` with structure `bvh4`, `bvh8`, `bvh4c` or `bvh8c`
/// and kernel `single`, `packet` or `stream`.
pub fn build_mode(name: &str, tris: &Triangles) -> Option<Box<dyn TraceMode>> {
    let name = known_mode(name)?;
    let tris = tris.clone();
    if name == "scalar-bvh2" {
        return Some(Box::new(SingleRay {
            name,
            accel: AccelKind::Bvh2.build(tris),
        }));
    }
    let (name_base, min_active) = match name.split_once('@') {
        Some((b, k)) => (b, k.parse::<u32>().ok()),
        None => (name, None),
    };
    if let Some(("bvh8", kernel @ ("packet" | "packet8"))) = name_base.split_once('-')
        && (kernel == "packet8" || min_active.is_some())
    {
        let mut bvh = Bvh::<Triangles, 8>::build(tris);
        if let Some(k) = min_active {
            bvh.set_packet_min_active([k; 2]);
        }
        return Some(Box::new(HalfPackets {
            name,
            half: kernel == "packet8",
            bvh,
        }));
    }
    let (base, prefetch) = match name.split_once('+') {
        None => (name, None),
        Some((b, "pf")) => (b, Some(true)),
        Some((b, _)) => (b, Some(false)),
    };
    let (structure, kernel) = base.split_once('-')?;
    let accel = match structure {
        "bvh4" => wide_accel::<4, BvhNode<4>>(tris, kernel, prefetch),
        "bvh8" => wide_accel::<8, BvhNode<8>>(tris, kernel, prefetch),
        "bvh4c" => wide_accel::<4, QNode<4>>(tris, kernel, prefetch),
        "bvh8c" => wide_accel::<8, QNode<8>>(tris, kernel, prefetch),
        _ => return None,
    };
    Some(match kernel {
        "single" => Box::new(SingleRay { name, accel }),
        "packet" => Box::new(Batched { name, accel }),
        "stream" => Box::new(Streamed { name, accel }),
        _ => return None,
    })
}

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

/// The fixed ray set over one mesh.
pub struct Protocol {
    pub tris: Triangles,
    pub framing: Framing,
    pub camera: BenchCamera,
    /// Geometric normals per triangle (file order), the protocol's `n`.
    pub normals: Vec<Vec3>,
}

/// Pixel coordinates of an 8x8 tile at (tx, ty) in 4x4-block order, clipped to the image.
fn tile_pixels(tx: u32, ty: u32, w: u32, h: u32, out: &mut Vec<(u32, u32)>) {
    out.clear();
    for by in (0..TILE).step_by(4) {
        for bx in (0..TILE).step_by(4) {
            for y in 0..4 {
                for x in 0..4 {
                    let (px, py) = (tx + bx + x, ty + by + y);
                    if px < w && py < h {
                        out.push((px, py));
                    }
                }
            }
        }
    }
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

    /// The secondary ray of pixel `i` for `workload`, from its primary hit.
    #[inline]
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
                let (u1, u2) = pixel_uniforms(y * cam.width + x);
                Ray::new(o, cosine_dir(n, u1, u2))
            }
        }
    }

    /// One pass of `workload` with `mode`; writes per-pixel results into `t_out` (hit
    /// distance or NaN for a miss; for shadow rays 1.0 occluded / 0.0 free) and
    /// `prim_out`. Returns the number of rays traced.
    pub fn pass(
        &self,
        mode: &dyn TraceMode,
        workload: Workload,
        primary: Option<&PrimaryHits>,
        t_out: &mut [f32],
        prim_out: &mut [u32],
    ) -> u64 {
        let (w, h) = (self.camera.width, self.camera.height);
        let band_len = (BAND * w) as usize;
        t_out
            .par_chunks_mut(band_len)
            .zip(prim_out.par_chunks_mut(band_len))
            .enumerate()
            .with_max_len(1)
            .map(|(band, (t_band, prim_band))| {
                let y0 = band as u32 * BAND;
                let mut pixels = Vec::with_capacity(64);
                // A tile's valid rays in order, as four SoA packets of sixteen for packet
                // modes or as a slice for the others; `slots[k]` is the band pixel of ray k.
                let soa = mode.takes_packets();
                // Stream modes: the band's valid rays and their pixels, traced at the end.
                let band_mode = mode.takes_band();
                let mut band_rays = Vec::new();
                let mut band_slots = Vec::new();
                let mut packets = [RayPacket::default(); 4];
                let mut rays = Vec::with_capacity(64);
                let mut camera = RayPacket::default();
                let mut slots = [0usize; 64];
                let mut hits = [None; 16];
                let mut occ = [false; 16];
                let mut count = 0u64;
                for ty in (y0..(y0 + BAND).min(h)).step_by(TILE as usize) {
                    for tx in (0..w).step_by(TILE as usize) {
                        tile_pixels(tx, ty, w, h, &mut pixels);
                        rays.clear();
                        let mut n = 0;
                        for (b, block) in pixels.chunks(16).enumerate() {
                            let local = |(x, y): (u32, u32)| ((y - y0) * w + x) as usize;
                            if workload == Workload::Primary {
                                self.camera.packet_into(block, &mut packets[b]);
                                if !soa {
                                    rays.extend((0..block.len()).map(|k| packets[b].ray(k)));
                                }
                                for &px in block {
                                    slots[n] = local(px);
                                    n += 1;
                                }
                                continue;
                            }
                            let Some(p) = primary else {
                                unreachable!("secondary workloads need primary hits")
                            };
                            // Secondary rays start from the camera rays' hits.
                            self.camera.packet_into(block, &mut camera);
                            for (k, &(x, y)) in block.iter().enumerate() {
                                let i = (y * w + x) as usize;
                                if p.prim[i] == u32::MAX {
                                    t_band[local((x, y))] = f32::NAN;
                                    prim_band[local((x, y))] = u32::MAX;
                                    continue;
                                }
                                let dir =
                                    Vec3::new(camera.dir[0][k], camera.dir[1][k], camera.dir[2][k]);
                                let r = self.secondary_ray(workload, x, y, dir, p.t[i], p.prim[i]);
                                if soa {
                                    packets[n / 16].set(n % 16, &r);
                                } else {
                                    rays.push(r);
                                }
                                slots[n] = local((x, y));
                                n += 1;
                            }
                        }
                        count += n as u64;
                        if band_mode {
                            band_rays.extend_from_slice(&rays[..n]);
                            band_slots.extend_from_slice(&slots[..n]);
                            continue;
                        }
                        for b in 0..n.div_ceil(16) {
                            let len = (n - 16 * b).min(16);
                            packets[b].len = len;
                            let slots = &slots[16 * b..16 * b + len];
                            let rays = if soa {
                                &[][..]
                            } else {
                                &rays[16 * b..16 * b + len]
                            };
                            if workload == Workload::Shadow {
                                if soa {
                                    mode.occluded_packet(&packets[b], &mut occ);
                                } else {
                                    mode.occluded(rays, &mut occ[..len]);
                                }
                                for (k, &s) in slots.iter().enumerate() {
                                    t_band[s] = if occ[k] { 1.0 } else { 0.0 };
                                    prim_band[s] = 0;
                                }
                            } else {
                                if soa {
                                    mode.closest_packet(&packets[b], &mut hits);
                                } else {
                                    mode.closest(rays, &mut hits[..len]);
                                }
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
                    self.trace_band(mode, workload, &band_rays, &band_slots, t_band, prim_band);
                }
                count
            })
            .sum()
    }

    /// A stream mode's band: `rays` traced as one batch, the answer of ray `k` written
    /// to band pixel `slots[k]`.
    fn trace_band(
        &self,
        mode: &dyn TraceMode,
        workload: Workload,
        rays: &[Ray],
        slots: &[usize],
        t_band: &mut [f32],
        prim_band: &mut [u32],
    ) {
        if workload == Workload::Shadow {
            let mut occ = vec![false; rays.len()];
            mode.occluded(rays, &mut occ);
            for (&o, &s) in occ.iter().zip(slots) {
                t_band[s] = if o { 1.0 } else { 0.0 };
                prim_band[s] = 0;
            }
        } else {
            let mut hits = vec![None; rays.len()];
            mode.closest(rays, &mut hits);
            for (h, &s) in hits.iter().zip(slots) {
                (t_band[s], prim_band[s]) = match h {
                    Some(hh) => (hh.t, hh.prim),
                    None => (f32::NAN, u32::MAX),
                };
            }
        }
    }

    /// The untimed primary pass that shadow and diffuse rays start from.
    pub fn primary_hits(&self, mode: &dyn TraceMode) -> PrimaryHits {
        let mut t = vec![0.0; self.pixels()];
        let mut prim = vec![0; self.pixels()];
        self.pass(mode, Workload::Primary, None, &mut t, &mut prim);
        PrimaryHits { t, prim }
    }

    /// Checksums of a pass's results, summed in f64 in pixel order.
    pub fn checksums(workload: Workload, rays: u64, t: &[f32], prim: &[u32]) -> Checksums {
        let mut c = Checksums {
            rays,
            hits_or_occluded: 0,
            sum_t: 0.0,
        };
        for (tt, pp) in t.iter().zip(prim) {
            match workload {
                Workload::Shadow => {
                    if *pp != u32::MAX && *tt == 1.0 {
                        c.hits_or_occluded += 1;
                    }
                }
                _ => {
                    if *pp != u32::MAX {
                        c.hits_or_occluded += 1;
                        c.sum_t += *tt as f64;
                    }
                }
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
        let mut best: Option<(Vec<f64>, f64)> = None;
        let mut rays = 0;
        let mut attempts = 0;
        for _ in 0..=timing.retry_busy {
            attempts += 1;
            // Warm-up: caches, page faults, the clock ramping up; at least one pass.
            let warm = Instant::now();
            loop {
                rays = self.pass(mode, workload, primary, &mut t, &mut prim);
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
                rays = self.pass(mode, workload, primary, &mut t, &mut prim);
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
            checksums: Self::checksums(workload, rays, &t, &prim),
            rates: secs.iter().map(|s| rays as f64 / s / 1e6).collect(),
            cpu_util,
            attempts,
        }
    }
}

/// CPU share below which a measurement is repeated with `--retry-busy` (Embree's
/// harness uses the same).
pub const BUSY_SHARE: f64 = 0.98;

/// How each figure is timed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Timed passes per figure.
    pub reps: usize,
    /// Untimed passes run first until this many seconds have gone by (at least one).
    pub warmup_s: f64,
    /// Repeat a figure's warm-up and timed passes up to this many more times while the
    /// process got less than [`BUSY_SHARE`] of its cores, keeping the attempt with the
    /// highest share (Embree's harness: `--retry-busy`).
    pub retry_busy: usize,
}

impl Timing {
    /// `reps` timed passes after one warm-up pass, no retries.
    pub fn passes(reps: usize) -> Self {
        Timing {
            reps,
            warmup_s: 0.0,
            retry_busy: 0,
        }
    }
}

/// One timed figure.
#[derive(Clone, Debug)]
pub struct Measured {
    pub checksums: Checksums,
    /// Mrays/s of each timed pass.
    pub rates: Vec<f64>,
    /// Process CPU time over the timed passes / (their wall time x threads); NaN where
    /// there is no CPU clock.
    pub cpu_util: f64,
    /// Measurements made (more than one with `retry_busy`).
    pub attempts: usize,
}

/// One row of the report: the JSON fields of the issue, plus the instruction set.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub tracer: &'static str,
    pub mode: String,
    pub workload: &'static str,
    pub threads: usize,
    pub rays: u64,
    pub hits_or_occluded: u64,
    pub sum_t: f64,
    pub mrays_median: f64,
    pub mrays_min: f64,
    pub mrays_max: f64,
    pub build_ms: f64,
    pub isa: &'static str,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Process CPU time over the timed passes / (their wall time x threads): near 1.00
    /// when the figure had its cores to itself (null without a CPU clock).
    pub cpu_util: f64,
    /// Measurements made for the figure (more than one with `--retry-busy`).
    pub attempts: usize,
    pub build_ms_min: f64,
    pub build_ms_max: f64,
    /// Bytes of the traced structure (nodes and leaves) per triangle.
    pub bytes_per_triangle: f64,
}

/// Median of a non-empty list.
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

pub use crate::simd::instruction_set;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simd_camera_rays_are_bit_identical_to_scalar_ones() {
        let positions = [Vec3::new(-1.0, 0.2, -0.5), Vec3::new(0.7, 1.9, 0.3)];
        let cam = BenchCamera::new(&Framing::new(&positions), 1024, 768);
        let pixels: Vec<(u32, u32)> = (0..37).map(|i| (i * 27 % 1024, i * 19 % 768)).collect();
        let mut rays = Vec::new();
        cam.rays_into(&pixels, &mut rays);
        for (r, &(x, y)) in rays.iter().zip(&pixels) {
            assert_eq!(r.dir, cam.dir(x, y), "pixel ({x}, {y})");
            assert_eq!(r.origin, cam.eye);
        }
    }
}

/// Runs every workload for one mode at one thread count (inside the caller's pool):
/// `reps` timed passes after one warm-up pass, the build time as given.
pub fn run_mode(
    protocol: &Protocol,
    mode: &dyn TraceMode,
    threads: usize,
    reps: usize,
    build_ms: f64,
) -> Vec<BenchRow> {
    run_mode_timed(protocol, mode, threads, &Timing::passes(reps), &[build_ms])
}

/// Runs every workload for one mode at one thread count (inside the caller's pool),
/// timed as `timing` says; `builds` are the build times measured (ms, at least one).
pub fn run_mode_timed(
    protocol: &Protocol,
    mode: &dyn TraceMode,
    threads: usize,
    timing: &Timing,
    builds: &[f64],
) -> Vec<BenchRow> {
    let primary = protocol.primary_hits(mode);
    let triangles = protocol.tris.v0.len();
    Workload::ALL
        .iter()
        .map(|&w| {
            let p = (w != Workload::Primary).then_some(&primary);
            let m = protocol.measure(mode, w, p, timing);
            let c = m.checksums;
            BenchRow {
                tracer: "packet-render",
                mode: mode.name().to_string(),
                workload: w.name(),
                threads,
                rays: c.rays,
                hits_or_occluded: c.hits_or_occluded,
                sum_t: c.sum_t,
                mrays_median: median(&m.rates),
                mrays_min: m.rates.iter().copied().fold(f64::INFINITY, f64::min),
                mrays_max: m.rates.iter().copied().fold(0.0, f64::max),
                build_ms: median(builds),
                isa: instruction_set(),
                triangles,
                cpu_util: m.cpu_util,
                attempts: m.attempts,
                build_ms_min: builds.iter().copied().fold(f64::INFINITY, f64::min),
                build_ms_max: builds.iter().copied().fold(0.0, f64::max),
                bytes_per_triangle: mode.memory_bytes() as f64 / triangles.max(1) as f64,
            }
        })
        .collect()
}

/// The mesh a benchmark runs on: its name, every vertex (for the framing) and its
/// triangles in file order.
pub struct BenchMesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub triangles: Triangles,
}

/// Triangles of the default procedural mesh: Bunny-scale (the Stanford Bunny has 69,451).
pub const DEFAULT_MESH_TRIANGLES: usize = 69_451;

impl BenchMesh {
    /// An OBJ file (polygons split as fans, as the protocol says).
    pub fn from_obj(path: &std::path::Path) -> crate::Result<Self> {
        let obj = crate::scene::load::load_obj(path)?;
        let corners: Vec<[Vec3; 3]> = obj
            .indices
            .iter()
            .map(|t| {
                [
                    obj.positions[t[0] as usize],
                    obj.positions[t[1] as usize],
                    obj.positions[t[2] as usize],
                ]
            })
            .collect();
        Ok(BenchMesh {
            name: path.display().to_string(),
            positions: obj.positions,
            triangles: Triangles::from_corners(&corners),
        })
    }

    /// The procedural Bunny-scale mesh (`scene::procedural::tessellated_mesh`).
    pub fn procedural(triangles: usize) -> Self {
        let mut b = crate::scene::SceneBuilder::new();
        let m = b.add_material(crate::scene::Material::default());
        crate::scene::procedural::tessellated_mesh(&mut b, triangles, Vec3::ZERO, 1.0, m);
        let mesh = &b.mesh;
        let positions = (0..mesh.vertex_count() as u32)
            .map(|i| mesh.vertex(i))
            .collect();
        let corners: Vec<[Vec3; 3]> = (0..mesh.len()).map(|t| mesh.corners(t)).collect();
        BenchMesh {
            name: format!("procedural tessellated mesh ({} triangles)", corners.len()),
            positions,
            triangles: Triangles::from_corners(&corners),
        }
    }
}

/// Settings of a benchmark run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub modes: Vec<String>,
    /// Thread counts; 0 means all cores.
    pub threads: Vec<usize>,
    pub reps: usize,
    pub width: u32,
    pub height: u32,
    /// Warm-up seconds per figure (see [`Timing`]).
    pub warmup_s: f64,
    /// Retries of a figure measured while other load took cores (see [`Timing`]).
    pub retry_busy: usize,
}

/// Runs every mode at every thread count. `report` receives each row as it is measured.
pub fn run(
    mesh: &BenchMesh,
    opts: &BenchOptions,
    mut report: impl FnMut(&BenchRow),
) -> crate::Result<Vec<BenchRow>> {
    if opts.reps < 1 {
        return Err(crate::Error::parameter("reps", "at least 1 timed pass"));
    }
    if !(0.0..=600.0).contains(&opts.warmup_s) {
        return Err(crate::Error::parameter(
            "warmup-ms",
            format!("between 0 and 600000 ms, got {}", opts.warmup_s * 1e3),
        ));
    }
    crate::scene::limits::validate_dimensions(opts.width, opts.height, 1, 0)?;
    for m in &opts.modes {
        if known_mode(m).is_none() {
            return Err(crate::Error::parameter(
                "mode",
                format!(
                    "unknown mode '{m}', expected one of {}, {}, {} or a prefetch variant \
                     (<mode>+pf, <mode>+nopf)",
                    MODES.join(", "),
                    COMPRESSED_MODES.join(", "),
                    PACKET_TUNING_MODES.join(", ")
                ),
            ));
        }
    }
    let protocol = Protocol::new(
        &mesh.positions,
        mesh.triangles.clone(),
        opts.width,
        opts.height,
    );
    let mut rows = Vec::new();
    for &t in &opts.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .map_err(|e| crate::Error::parameter("threads", e.to_string()))?;
        let threads = pool.current_num_threads();
        for m in &opts.modes {
            // Build time: median of 5 builds after a warm-up, in this pool.
            let mut times = Vec::new();
            let mut mode = None;
            for _ in 0..6 {
                let start = Instant::now();
                let built = pool
                    .install(|| build_mode(m, &mesh.triangles))
                    .expect("mode names were checked");
                times.push(start.elapsed().as_secs_f64() * 1e3);
                mode = Some(built);
            }
            let mode = mode.expect("built at least once");
            let timing = Timing {
                reps: opts.reps,
                warmup_s: opts.warmup_s,
                retry_busy: opts.retry_busy,
            };
            for row in pool
                .install(|| run_mode_timed(&protocol, mode.as_ref(), threads, &timing, &times[1..]))
            {
                report(&row);
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

/// A fixed-width table row for humans.
pub fn table_header() -> String {
    format!(
        "{:<12} {:<8} {:>7} {:>9} {:>9} {:>16} {:>9} {:>9} {:>9} {:>9} {:>5} {:>9}",
        "mode",
        "workload",
        "threads",
        "rays",
        "hits/occ",
        "sum_t",
        "Mrays/s",
        "min",
        "max",
        "build ms",
        "cpu",
        "bytes/tri"
    )
}

pub fn table_row(r: &BenchRow) -> String {
    format!(
        "{:<12} {:<8} {:>7} {:>9} {:>9} {:>16.6} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>5.2} {:>9.1}",
        r.mode,
        r.workload,
        r.threads,
        r.rays,
        r.hits_or_occluded,
        r.sum_t,
        r.mrays_median,
        r.mrays_min,
        r.mrays_max,
        r.build_ms,
        r.cpu_util,
        r.bytes_per_triangle
    )
}

/// The sweep's table (`bench --sweep`): per size and figure, Mrays/s (median, min,
/// max), the CPU share of the timed passes, build time (median, min, max) and bytes
/// per triangle.
pub fn sweep_table_header() -> String {
    format!(
        "{:>10} {:<12} {:<8} {:>7} {:>9} {:>9} {:>9} {:>5} {:>10} {:>10} {:>10} {:>9}",
        "triangles",
        "mode",
        "workload",
        "threads",
        "Mrays/s",
        "min",
        "max",
        "cpu",
        "build ms",
        "min",
        "max",
        "bytes/tri"
    )
}

pub fn sweep_table_row(r: &BenchRow) -> String {
    format!(
        "{:>10} {:<12} {:<8} {:>7} {:>9.2} {:>9.2} {:>9.2} {:>5.2} {:>10.2} {:>10.2} {:>10.2} {:>9.1}",
        r.triangles,
        r.mode,
        r.workload,
        r.threads,
        r.mrays_median,
        r.mrays_min,
        r.mrays_max,
        r.cpu_util,
        r.build_ms,
        r.build_ms_min,
        r.build_ms_max,
        r.bytes_per_triangle
    )
}
