//! The tracing modes under test: one ray, packets, half packets, streams, and the
//! mode names `bench --modes` accepts.

use crate::accel::{
    Accel, AccelKind, Bvh, BvhNode, NodeWidth, Prefetch, QNode, Triangles, WideNode, Width,
    hits_as_lanes,
};
use crate::geometry::{Hit, Ray, RayPacket};

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
    /// One packet's closest hits as lanes (Embree's `RTCRayHit16` form): lane `k`'s
    /// distance and triangle in `t[k]` and `prim[k]`, NaN and `u32::MAX` where it has
    /// none (lanes past `rays.len` included).
    fn closest_packet_lanes(&self, rays: &RayPacket, t: &mut [f32; 16], prim: &mut [u32; 16]) {
        let mut hits = [None; 16];
        self.closest_packet(rays, &mut hits[..rays.len]);
        hits_to_lanes(&hits, t, prim);
    }
    /// One packet's occlusion as bits (bit `k` for lane `k`).
    fn occluded_packet_bits(&self, rays: &RayPacket) -> u32 {
        let mut occ = [false; 16];
        self.occluded_packet(rays, &mut occ[..rays.len]);
        (0..16).fold(0, |m, k| m | u32::from(occ[k]) << k)
    }
    /// [`closest`](Self::closest)'s answers as lanes: ray `k`'s distance and triangle in
    /// `t[k]` and `prim[k]`, NaN and `u32::MAX` where it has none.
    fn closest_lanes(&self, rays: &[Ray], t: &mut [f32], prim: &mut [u32]) {
        let mut hits = vec![None; rays.len()];
        self.closest(rays, &mut hits);
        hits_as_lanes(&hits, t, prim);
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

/// Answers as lanes (see [`TraceMode::closest_packet_lanes`]).
fn hits_to_lanes(hits: &[Option<Hit>; 16], t: &mut [f32; 16], prim: &mut [u32; 16]) {
    for (k, h) in hits.iter().enumerate() {
        (t[k], prim[k]) = h.map_or((f32::NAN, u32::MAX), |h| (h.t, h.prim));
    }
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

/// The packet kernels of an N-wide BVH: tiles as 16-ray SoA packets, answers in lanes.
pub struct Packets<const N: usize, T: WideNode<N>>
where
    Width<N>: NodeWidth,
{
    pub name: &'static str,
    pub bvh: Bvh<Triangles, N, T>,
}

impl<const N: usize, T: WideNode<N>> TraceMode for Packets<N, T>
where
    Width<N>: NodeWidth,
{
    fn name(&self) -> &'static str {
        self.name
    }
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.bvh.closest_hit_batch(rays, out);
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) {
        self.bvh.any_hit_batch(rays, out);
    }
    fn takes_packets(&self) -> bool {
        true
    }
    fn closest_packet(&self, rays: &RayPacket, out: &mut [Option<Hit>]) {
        self.bvh.closest_hit_packet(rays, out);
    }
    fn occluded_packet(&self, rays: &RayPacket, out: &mut [bool]) {
        self.bvh.any_hit_packet(rays, out);
    }
    fn closest_packet_lanes(&self, rays: &RayPacket, t: &mut [f32; 16], prim: &mut [u32; 16]) {
        self.bvh.closest_hit_packet_lanes(rays, t, prim);
    }
    fn occluded_packet_bits(&self, rays: &RayPacket) -> u32 {
        self.bvh.any_hit_packet_bits(rays)
    }
    fn build_ms(&self) -> f64 {
        self.bvh.info().build_ms
    }
    fn memory_bytes(&self) -> usize {
        self.bvh.info().memory_bytes
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
    fn closest_packet_lanes(&self, rays: &RayPacket, t: &mut [f32; 16], prim: &mut [u32; 16]) {
        if self.half {
            let mut hits = [None; 16];
            self.bvh.closest_hit_packet8(rays, &mut hits);
            hits_to_lanes(&hits, t, prim);
        } else {
            self.bvh.closest_hit_packet_lanes(rays, t, prim);
        }
    }
    fn build_ms(&self) -> f64 {
        self.bvh.info().build_ms
    }
    fn memory_bytes(&self) -> usize {
        self.bvh.info().memory_bytes
    }
}

/// A tile's rays regrouped by direction octant and dominant axis into packets
/// (`Bvh::closest_hit_sorted`), as Embree's `rtcIntersect1M` sorts an incoherent
/// stream into packets.
pub struct SortedPackets<const N: usize> {
    pub name: &'static str,
    pub bvh: Bvh<Triangles, N>,
}

impl<const N: usize> TraceMode for SortedPackets<N>
where
    Width<N>: NodeWidth,
{
    fn name(&self) -> &'static str {
        self.name
    }
    fn closest(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.bvh.closest_hit_sorted(rays, out);
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) {
        self.bvh.any_hit_sorted(rays, out);
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
    fn closest_lanes(&self, rays: &[Ray], t: &mut [f32], prim: &mut [u32]) {
        self.accel.closest_hit_stream_lanes(rays, t, prim);
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

/// The single-ray and stream kernels with the FMA node test (`simd/slab_fma.rs`, off by
/// default: see `Bvh::set_fma_slab`) instead of Ize's subtract-multiply test, `+fma`, or
/// with the FMA test and the leaf test called out of line, `+call`; run when asked for
/// by name: A/Bs on one binary.
pub const SLAB_MODES: &[&str] = &[
    "bvh4-single+fma",
    "bvh4-stream+fma",
    "bvh8-single+fma",
    "bvh8-stream+fma",
    "bvh8-single+call",
    "bvh8-stream+call",
];

/// Sorted packets (see [`SortedPackets`]), run when asked for by name: slower than the
/// ray-by-ray path on diffuse rays on AVX2 (numbers in `accel/bvhn/sorted.rs`).
pub const SORTED_MODES: &[&str] = &[
    "bvh4-sorted",
    "bvh8-sorted",
    "bvh8-sorted@8",
    "bvh8-sorted@12",
    "bvh8-sorted@15",
];

/// The name of a mode `bench` knows, as a `'static` string.
pub fn known_mode(name: &str) -> Option<&'static str> {
    MODES
        .iter()
        .chain(COMPRESSED_MODES)
        .chain(PREFETCH_MODES)
        .chain(PACKET_TUNING_MODES)
        .chain(SORTED_MODES)
        .chain(SLAB_MODES)
        .copied()
        .find(|&m| m == name)
}

/// The mode `name`: an N-wide BVH over `tris` with node type `T` traced by `kernel`
/// (`single`, `packet` or `stream`), prefetching in `kernel` forced to `prefetch` where
/// given, the FMA node test on where `fma`, the leaf test out of line where `call`.
fn wide_mode<const N: usize, T: WideNode<N>>(
    name: &'static str,
    tris: Triangles,
    kernel: &str,
    (prefetch, fma, call): (Option<bool>, bool, bool),
) -> Option<Box<dyn TraceMode>>
where
    Width<N>: NodeWidth,
{
    let mut bvh = Bvh::<Triangles, N, T>::build(tris);
    bvh.set_fma_slab(fma);
    bvh.set_leaf_call(call);
    if let Some(on) = prefetch {
        let mut p = Prefetch::default();
        match kernel {
            "single" => p.single = on,
            "packet" => p.packet = on,
            _ => p.stream = on,
        }
        bvh.set_prefetch(p);
    }
    Some(match kernel {
        "single" => Box::new(SingleRay {
            name,
            accel: Box::new(bvh),
        }),
        "packet" => Box::new(Packets { name, bvh }),
        "stream" => Box::new(Streamed {
            name,
            accel: Box::new(bvh),
        }),
        _ => return None,
    })
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
    if let Some(rest) = name.strip_prefix("bvh8-sorted") {
        let mut bvh = Bvh::<Triangles, 8>::build(tris);
        if let Some(k) = rest.strip_prefix('@').and_then(|k| k.parse::<u32>().ok()) {
            bvh.set_packet_min_active([k; 2]);
        }
        return Some(Box::new(SortedPackets { name, bvh }));
    }
    if name == "bvh4-sorted" {
        let bvh = Bvh::<Triangles, 4>::build(tris);
        return Some(Box::new(SortedPackets { name, bvh }));
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
    let (base, prefetch, fma) = match name.split_once('+') {
        None => (name, None, false),
        Some((b, "fma" | "call")) => (b, None, true),
        Some((b, "pf")) => (b, Some(true), false),
        Some((b, _)) => (b, Some(false), false),
    };
    let (structure, kernel) = base.split_once('-')?;
    let opts = (prefetch, fma, name.ends_with("+call"));
    match structure {
        "bvh4" => wide_mode::<4, BvhNode<4>>(name, tris, kernel, opts),
        "bvh8" => wide_mode::<8, BvhNode<8>>(name, tris, kernel, opts),
        "bvh4c" => wide_mode::<4, QNode<4>>(name, tris, kernel, opts),
        "bvh8c" => wide_mode::<8, QNode<8>>(name, tris, kernel, opts),
        _ => None,
    }
}
