//! Scalar-vs-SIMD equivalence: the scalar BVH2 traversal (the oracle), and the
//! single-ray SIMD kernel, the packet kernel, the sorted packets and the stream kernel of both the BVH4 and
//! the BVH8, with exact and with compressed (quantised) nodes, get the same rays and must
//! return bit-identical hits (primitive, `t`, `u`, `v`: the kernels are twins of the
//! scalar test, the same operations in the same order, and a compressed node's boxes
//! only ever grow) and the same occlusion answer. Compressed trees run with every
//! kernel's prefetch on, exact ones with the defaults, so both paths are exercised.

mod common;
#[path = "simd_equivalence/tiny_lanes.rs"]
mod tiny_lanes;

use common::*;
use glam::Vec3;
use packet_render::accel::{
    Accel, Bvh, Bvh2, BvhNode, NodeWidth, Prefetch, Primitives, QNode, Triangles, WideNode, Width,
};
use packet_render::geometry::{Aabb, Hit, Ray};
use packet_render::scene::Camera;

fn bounds_of(p: &Triangles) -> Aabb {
    (0..p.count()).fold(Aabb::EMPTY, |b, i| b.union(&p.bounds(i)))
}

/// Bit-identical hits. The one freedom: an exact tie in `t` between two primitives
/// (a shared edge, duplicated triangles) may go to either, as traversal orders differ;
/// then each side's `u`, `v` belong to its own primitive and are not compared.
fn same_hit(a: Option<Hit>, b: Option<Hit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.t.to_bits() == b.t.to_bits()
                && (a.prim != b.prim
                    || (a.u.to_bits() == b.u.to_bits() && a.v.to_bits() == b.v.to_bits()))
        }
        _ => false,
    }
}

/// Runs the scalar path and both widths' single-ray, packet and stream paths, on exact
/// and compressed nodes, on `rays` (closest hit and occlusion) and compares.
fn check(name: &str, tris: &Triangles, rays: &[Ray]) {
    check_width::<4, BvhNode<4>>(name, tris, rays);
    check_width::<8, BvhNode<8>>(name, tris, rays);
    check_width::<4, QNode<4>>(name, tris, rays);
    check_width::<8, QNode<8>>(name, tris, rays);
}

/// An N-wide tree with node type `T`, validated; compressed trees prefetch everywhere.
fn build<P: Primitives, const N: usize, T: WideNode<N>>(prims: P) -> Bvh<P, N, T>
where
    Width<N>: NodeWidth,
{
    let mut bvh = Bvh::<P, N, T>::build(prims);
    if let Err(e) = bvh.validate() {
        panic!("bvh{N} (compressed: {}): {e}", T::COMPRESSED);
    }
    if T::COMPRESSED {
        bvh.set_prefetch(Prefetch {
            single: true,
            packet: true,
            stream: true,
        });
    }
    bvh
}

fn check_width<const N: usize, T: WideNode<N>>(name: &str, tris: &Triangles, rays: &[Ray])
where
    Width<N>: NodeWidth,
{
    let name = &format!("{name} (bvh{N}, compressed nodes: {})", T::COMPRESSED);
    let scalar = Bvh2::build(tris.clone());
    let bvhn = build::<_, N, T>(tris.clone());
    let mut packet = vec![None; rays.len()];
    bvhn.closest_hit_batch(rays, &mut packet);
    let mut packet_occ = vec![false; rays.len()];
    bvhn.any_hit_batch(rays, &mut packet_occ);
    // The stream kernel: the whole set as one batch, and in batches of 1, 7 and 300.
    let mut stream = vec![None; rays.len()];
    bvhn.closest_stream(rays, &mut stream);
    let mut stream_occ = vec![false; rays.len()];
    bvhn.any_stream(rays, &mut stream_occ);
    // Sorted packets: the set regrouped by octant and dominant axis, whole and in
    // tiles of 64 (the bench's shape).
    let mut sorted = vec![None; rays.len()];
    bvhn.closest_hit_sorted(rays, &mut sorted);
    let mut sorted_occ = vec![false; rays.len()];
    bvhn.any_hit_sorted(rays, &mut sorted_occ);
    let mut tiled = vec![None; rays.len()];
    let mut tiled_occ = vec![false; rays.len()];
    for (k, r) in rays.chunks(64).enumerate() {
        let at = 64 * k;
        bvhn.closest_hit_sorted(r, &mut tiled[at..at + r.len()]);
        bvhn.any_hit_sorted(r, &mut tiled_occ[at..at + r.len()]);
    }
    let mut chunked = vec![None; rays.len()];
    let mut chunked_occ = vec![false; rays.len()];
    let mut at = 0;
    for (k, size) in [1usize, 7, 300].into_iter().cycle().enumerate() {
        if at >= rays.len() {
            break;
        }
        let end = (at + size + k % 3).min(rays.len());
        bvhn.closest_stream(&rays[at..end], &mut chunked[at..end]);
        bvhn.any_stream(&rays[at..end], &mut chunked_occ[at..end]);
        at = end;
    }
    // The same tree with the FMA node test in the single-ray and stream kernels (where
    // the build has FMA; off by default, Ize's subtract-multiply test is the default).
    let mut fma = build::<_, N, T>(tris.clone());
    fma.set_fma_slab(true);
    let mut fma_stream = vec![None; rays.len()];
    fma.closest_stream(rays, &mut fma_stream);
    let mut fma_stream_occ = vec![false; rays.len()];
    fma.any_stream(rays, &mut fma_stream_occ);
    let mut bad = Vec::new();
    for (i, r) in rays.iter().enumerate() {
        let want = scalar.closest_hit(r);
        for (kind, got) in [
            ("single (FMA node test)", fma.closest_single(r)),
            ("stream (FMA node test)", fma_stream[i]),
        ] {
            if !same_hit(want, got) {
                bad.push(format!("ray {i}: scalar {want:?} vs bvh{N}-{kind} {got:?}"));
            }
        }
        if scalar.any_hit(r) != fma.any_single(r) || scalar.any_hit(r) != fma_stream_occ[i] {
            bad.push(format!(
                "ray {i}: bvh{N} occlusion with the FMA node test differs"
            ));
        }
        let single = bvhn.closest_single(r);
        if !same_hit(want, single) {
            bad.push(format!(
                "ray {i}: scalar {want:?} vs bvh{N}-single {single:?}"
            ));
        }
        if !same_hit(want, packet[i]) {
            bad.push(format!(
                "ray {i}: scalar {want:?} vs bvh{N}-packet {:?}",
                packet[i]
            ));
        }
        for (kind, got) in [
            ("stream", stream[i]),
            ("stream-chunked", chunked[i]),
            ("sorted", sorted[i]),
            ("sorted-tiles", tiled[i]),
        ] {
            if !same_hit(want, got) {
                bad.push(format!("ray {i}: scalar {want:?} vs bvh{N}-{kind} {got:?}"));
            }
        }
        let occ = scalar.any_hit(r);
        if occ != bvhn.any_single(r)
            || occ != packet_occ[i]
            || occ != stream_occ[i]
            || occ != chunked_occ[i]
            || occ != sorted_occ[i]
            || occ != tiled_occ[i]
        {
            bad.push(format!(
                "ray {i}: bvh{N} occlusion scalar {occ}, single {}, packet {}, stream {}, \
                 stream-chunked {}, sorted {}, sorted-tiles {}",
                bvhn.any_single(r),
                packet_occ[i],
                stream_occ[i],
                chunked_occ[i],
                sorted_occ[i],
                tiled_occ[i]
            ));
        }
    }
    assert!(
        bad.is_empty(),
        "{name}: {} mismatches of {}; first: {}",
        bad.len(),
        rays.len(),
        bad[0]
    );
}

/// Camera rays over the mesh in 4x4 pixel blocks (the packet order of the bench).
fn camera_rays(b: &Aabb, w: u32, h: u32) -> Vec<Ray> {
    let frame = Camera::framing(b).frame(w, h);
    let mut rays = Vec::new();
    for by in (0..h).step_by(4) {
        for bx in (0..w).step_by(4) {
            for y in by..by + 4 {
                for x in bx..bx + 4 {
                    rays.push(frame.ray(x as f32 + 0.5, y as f32 + 0.5));
                }
            }
        }
    }
    rays
}

fn mesh() -> Triangles {
    let (pos, tris) = bumpy_sphere(48, 96, 1.0);
    triangles_of(&pos, &tris)
}

#[test]
fn camera_rays_agree() {
    let tris = mesh();
    let rays = camera_rays(&bounds_of(&tris), 96, 96);
    check("camera", &tris, &rays);
}

/// Shadow and cosine-diffuse rays from the camera hits, from origins offset along the
/// normal and from origins exactly on the surface.
#[test]
fn secondary_rays_agree_and_shadow_rays_stop_short() {
    let tris = mesh();
    let b = bounds_of(&tris);
    let cam = camera_rays(&b, 64, 64);
    let oracle = Bvh2::build(tris.clone());
    let light = b.center() + b.diagonal() * Vec3::new(0.8, 1.2, 0.6);
    let mut shadow = Vec::new();
    let mut diffuse = Vec::new();
    let mut on_surface = Vec::new();
    let mut rng = Rng(5);
    for r in &cam {
        let Some(h) = oracle.closest_hit(r) else {
            continue;
        };
        let i = h.prim as usize;
        let mut n = (tris.v1[i] - tris.v0[i])
            .cross(tris.v2[i] - tris.v0[i])
            .normalize();
        if n.dot(r.dir) > 0.0 {
            n = -n;
        }
        let (p, err) =
            packet_render::geometry::triangle_point([tris.v0[i], tris.v1[i], tris.v2[i]], h.u, h.v);
        let o = packet_render::geometry::offset_ray_origin(p, err, n, n);
        let to = light - o;
        shadow.push(Ray::segment(o, to.normalize(), 0.0, to.length()));
        let (t1, t2) = packet_render::geometry::orthonormal_basis(n);
        let (u1, u2) = (rng.f32(), rng.f32());
        let (rr, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
        diffuse.push(Ray::new(
            o,
            (t1 * rr * phi.cos() + t2 * rr * phi.sin() + n * (1.0 - u1).sqrt()).normalize(),
        ));
        on_surface.push(Ray::new(p, rng.unit_vector()));
    }
    check("shadow", &tris, &shadow);
    check("diffuse", &tris, &diffuse);
    check("on-surface", &tris, &on_surface);

    // A ray stopped at 0.99 of its hit distance is unoccluded on every path.
    stops_short::<4, BvhNode<4>>(&tris, &oracle, &cam);
    stops_short::<8, BvhNode<8>>(&tris, &oracle, &cam);
    stops_short::<4, QNode<4>>(&tris, &oracle, &cam);
    stops_short::<8, QNode<8>>(&tris, &oracle, &cam);
}

fn stops_short<const N: usize, T: WideNode<N>>(
    tris: &Triangles,
    oracle: &Bvh2<Triangles>,
    cam: &[Ray],
) where
    Width<N>: NodeWidth,
{
    let bvhn = build::<_, N, T>(tris.clone());
    let short: Vec<Ray> = cam
        .iter()
        .filter_map(|r| {
            oracle.closest_hit(r).map(|h| Ray {
                tmax: 0.99 * h.t,
                ..*r
            })
        })
        .collect();
    let mut occ = vec![true; short.len()];
    bvhn.any_hit_batch(&short, &mut occ);
    for (r, o) in short.iter().zip(&occ) {
        assert!(
            !o && !bvhn.any_single(r) && !oracle.any_hit(r),
            "ray ending at 0.99 t reported occluded"
        );
    }
}

/// The procedural tessellated mesh (the bench's Bunny-scale stand-in, smaller) under
/// incoherent rays: random origins inside and around it, random directions.
#[test]
fn procedural_mesh_under_incoherent_rays_agrees() {
    let tris = procedural_mesh(20_000);
    let rays = random_rays(&bounds_of(&tris), 12_000, 31);
    check("procedural mesh, random rays", &tris, &rays);
}

#[test]
fn random_and_axis_parallel_rays_agree() {
    let tris = triangle_soup(4000, 11);
    let rays = random_rays(&bounds_of(&tris), 30_000, 12);
    check("random + axis-parallel", &tris, &rays);
}

/// Rays that stress the node tests' rounding: origins far outside the mesh (10^4 and
/// 10^6 diagonals back along the ray), origins exactly on the planes of the mesh's
/// bounding box with the direction in that plane (zero and subnormal components),
/// intervals starting after 0 and before it (`tmin < 0`: the FMA test does not apply and
/// Ize's is used), and huge coordinates (the mesh moved 10^6 diagonals away).
#[test]
fn far_grazing_and_negative_tmin_rays_agree() {
    let tris = triangle_soup(3000, 17);
    let b = bounds_of(&tris);
    let base = random_rays(&b, 9000, 23);
    let mut rays = Vec::new();
    let mut rng = Rng(29);
    for (i, r) in base.iter().enumerate() {
        let len = b.diagonal();
        rays.push(match i % 6 {
            0 => Ray::new(r.origin - r.dir * (1e4 * len), r.dir),
            1 => Ray::new(r.origin - r.dir * (1e6 * len), r.dir),
            2 => {
                // On a face plane of the bounds, moving within it.
                let a = (rng.next_u64() % 3) as usize;
                let mut o = r.origin;
                o[a] = if rng.next_u64().is_multiple_of(2) {
                    b.min[a]
                } else {
                    b.max[a]
                };
                let mut d = r.dir;
                d[a] = [0.0, -0.0, 1e-40, -1e-39][(rng.next_u64() % 4) as usize];
                Ray::new(o, d)
            }
            3 => Ray::segment(r.origin, r.dir, -0.5 * len, f32::INFINITY),
            4 => Ray::segment(r.origin, r.dir, 0.25 * len * rng.f32(), f32::INFINITY),
            _ => *r,
        });
    }
    check("far, grazing, tmin != 0", &tris, &rays);
    // The same rays against the mesh moved 10^6 diagonals away (and the rays with it).
    let shift = b.extent() * 1e6;
    let moved = Triangles {
        v0: tris.v0.iter().map(|v| *v + shift).collect(),
        v1: tris.v1.iter().map(|v| *v + shift).collect(),
        v2: tris.v2.iter().map(|v| *v + shift).collect(),
    };
    let moved_rays: Vec<Ray> = rays
        .iter()
        .map(|r| Ray {
            origin: r.origin + shift,
            ..*r
        })
        .collect();
    check("huge coordinates", &moved, &moved_rays);
}

/// Invalid lanes (NaN, inf, zero direction, NaN interval) miss and leave the other lanes
/// of their packet untouched.
#[test]
fn invalid_lanes_never_hit_or_poison_neighbours() {
    invalid_lanes::<4, BvhNode<4>>();
    invalid_lanes::<8, BvhNode<8>>();
    invalid_lanes::<4, QNode<4>>();
    invalid_lanes::<8, QNode<8>>();
}

fn invalid_lanes<const N: usize, T: WideNode<N>>()
where
    Width<N>: NodeWidth,
{
    let tris = mesh();
    let b = bounds_of(&tris);
    let rays = camera_rays(&b, 32, 32);
    let bvhn = build::<_, N, T>(tris.clone());
    let mut clean = vec![None; rays.len()];
    bvhn.closest_hit_batch(&rays, &mut clean);
    let mut poisoned = rays.clone();
    let bad = [
        Ray::new(Vec3::NAN, Vec3::Z),
        Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0)),
        Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0)),
        Ray::new(b.center() + Vec3::Z * 5.0, Vec3::ZERO),
        Ray {
            tmin: f32::NAN,
            ..rays[0]
        },
        Ray {
            tmax: f32::NAN,
            ..rays[0]
        },
        Ray {
            tmin: 2.0,
            tmax: 1.0,
            ..rays[0]
        },
    ];
    for (k, i) in (0..poisoned.len()).step_by(5).enumerate() {
        poisoned[i] = bad[k % bad.len()];
    }
    let mut got = vec![None; rays.len()];
    bvhn.closest_hit_batch(&poisoned, &mut got);
    let mut occ = vec![true; rays.len()];
    bvhn.any_hit_batch(&poisoned, &mut occ);
    // The stream kernel, over answers pre-filled with a hit, so a ray it skipped shows.
    let filler = Some(Hit {
        t: -1.0,
        prim: 7,
        u: 0.0,
        v: 0.0,
    });
    let mut streamed = vec![filler; rays.len()];
    bvhn.closest_stream(&poisoned, &mut streamed);
    let mut stream_occ = vec![true; rays.len()];
    bvhn.any_stream(&poisoned, &mut stream_occ);
    let mut clean_occ = vec![false; rays.len()];
    bvhn.any_hit_batch(&rays, &mut clean_occ);
    assert!(clean.iter().filter(|h| h.is_some()).count() > rays.len() / 4);
    for i in 0..rays.len() {
        if i % 5 == 0 {
            assert!(
                got[i].is_none() && !occ[i] && streamed[i].is_none() && !stream_occ[i],
                "invalid ray {i} reported a hit"
            );
        } else {
            assert_eq!(got[i], clean[i], "lane {i} changed by an invalid neighbour");
            assert_eq!(
                streamed[i], clean[i],
                "stream: ray {i} changed by an invalid one"
            );
            assert_eq!(stream_occ[i], clean_occ[i], "stream: ray {i} occlusion");
        }
    }
    // A batch of invalid rays only, and an empty batch.
    let mut only_bad = vec![filler; bad.len()];
    bvhn.closest_stream(&bad, &mut only_bad);
    assert!(only_bad.iter().all(|h| h.is_none()));
    let mut only_bad_occ = vec![true; bad.len()];
    bvhn.any_stream(&bad, &mut only_bad_occ);
    assert!(only_bad_occ.iter().all(|o| !o));
    bvhn.closest_stream(&[], &mut []);
    bvhn.any_stream(&[], &mut []);
    // A whole packet of invalid rays (no lane group to trace): every answer `None`, over
    // answers pre-filled with a hit.
    let packet: Vec<Ray> = (0..16).map(|k| bad[k % bad.len()]).collect();
    let mut packet_hits = vec![filler; packet.len()];
    bvhn.closest_hit_batch(&packet, &mut packet_hits);
    assert!(packet_hits.iter().all(|h| h.is_none()), "{packet_hits:?}");
    let mut packet_occ = vec![true; packet.len()];
    bvhn.any_hit_batch(&packet, &mut packet_occ);
    assert!(packet_occ.iter().all(|o| !o));
}

/// Spheres through packets: the lane-parallel sphere test (the SIMD twin of
/// `intersect_sphere`) against the scalar BVH2, on coherent camera rays and random rays;
/// hits must match exactly (same sphere, bit-identical t) and so must occlusion.
#[test]
fn sphere_packets_match_the_scalar_test() {
    sphere_packets::<4, BvhNode<4>>();
    sphere_packets::<8, BvhNode<8>>();
    sphere_packets::<4, QNode<4>>();
    sphere_packets::<8, QNode<8>>();
}

fn sphere_packets<const N: usize, T: WideNode<N>>()
where
    Width<N>: NodeWidth,
{
    use packet_render::accel::Spheres;
    use packet_render::scene::{Material, SceneBuilder, procedural};
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::default());
    procedural::sphereflake(&mut b, 3, Vec3::ZERO, 1.0, m);
    let spheres = Spheres::from_set(&b.spheres);
    let bounds = (0..spheres.count()).fold(Aabb::EMPTY, |acc, i| acc.union(&spheres.bounds(i)));
    let mut rays = camera_rays(&bounds, 64, 64);
    rays.extend(random_rays(&bounds, 4096, 21));
    let scalar = Bvh2::build(spheres.clone());
    let bvhn = build::<_, N, T>(spheres);
    let mut packet = vec![None; rays.len()];
    bvhn.closest_hit_batch(&rays, &mut packet);
    let mut occ = vec![false; rays.len()];
    bvhn.any_hit_batch(&rays, &mut occ);
    let mut stream = vec![None; rays.len()];
    bvhn.closest_stream(&rays, &mut stream);
    let mut stream_occ = vec![false; rays.len()];
    bvhn.any_stream(&rays, &mut stream_occ);
    let mut hits = 0;
    for (i, r) in rays.iter().enumerate() {
        let want = scalar.closest_hit(r);
        assert_eq!(stream[i], want, "ray {i}: stream");
        assert_eq!(stream_occ[i], want.is_some(), "ray {i}: stream occlusion");
        assert_eq!(
            packet[i].map(|h| (h.prim, h.t)),
            want.map(|h| (h.prim, h.t)),
            "ray {i}"
        );
        assert_eq!(
            bvhn.closest_single(r).map(|h| (h.prim, h.t)),
            want.map(|h| (h.prim, h.t)),
            "ray {i}"
        );
        assert_eq!(occ[i], want.is_some(), "ray {i}: occlusion");
        hits += usize::from(want.is_some());
    }
    assert!(
        hits > rays.len() / 10,
        "the rays must actually hit spheres ({hits})"
    );
}

/// The SoA packet entry points give the single-ray answers, for full and partial
/// packets; lanes past `len` hold rays that would hit and are ignored.
#[test]
fn soa_packets_match_single_rays_and_ignore_lanes_past_len() {
    soa_packets::<4, BvhNode<4>>();
    soa_packets::<8, BvhNode<8>>();
    soa_packets::<4, QNode<4>>();
    soa_packets::<8, QNode<8>>();
}

fn soa_packets<const N: usize, T: WideNode<N>>()
where
    Width<N>: NodeWidth,
{
    use packet_render::geometry::RayPacket;
    let tris = mesh();
    let rays = camera_rays(&bounds_of(&tris), 32, 32);
    let bvh = build::<_, N, T>(tris.clone());
    let mut checked = 0;
    for (k, chunk) in rays.chunks(16).enumerate() {
        let len = 16 - k % 5; // full packets and partial ones
        let mut packet = RayPacket::from_rays(chunk);
        packet.len = len;
        let mut hits = [Some(Hit {
            t: -1.0,
            prim: 7,
            u: 0.0,
            v: 0.0,
        }); 16];
        let mut occ = [true; 16];
        bvh.closest_hit_packet(&packet, &mut hits);
        bvh.any_hit_packet(&packet, &mut occ);
        for i in 0..16 {
            if i < len {
                let want = bvh.closest_single(&chunk[i]);
                assert_eq!(hits[i], want, "bvh{N} packet {k} lane {i}");
                assert_eq!(
                    occ[i],
                    bvh.any_single(&chunk[i]),
                    "bvh{N} packet {k} lane {i}"
                );
                checked += usize::from(want.is_some());
            } else {
                // untouched past len
                assert_eq!(hits[i].map(|h| h.t), Some(-1.0), "bvh{N} lane {i} past len");
                assert!(occ[i]);
            }
        }
    }
    assert!(checked > 100, "too few hits to compare: {checked}");
}

/// The stream kernel's ray-id compaction (`select_ids`: AVX-512 compress, AVX2
/// left-pack or the scalar loop, whichever this build has) against its scalar twin and
/// a filter: the 8-id window `j` (the vector paths step by 8 or 16 ids from the start)
/// holds selection pattern `j`, so all 256 occur, in each of the 8 bit positions, other
/// bits set at random; then a tail of 0 to 15 random masks.
#[test]
fn stream_compaction_matches_scalar_on_all_256_masks() {
    use packet_render::simd::compact::{COMPACT_SLACK, select_ids, select_ids_scalar};
    let mut rng = Rng(99);
    for bit in 0..8u32 {
        for tail in 0..16usize {
            let len = 256 * 8 + tail;
            let masks: Vec<u32> = (0..len)
                .map(|k| {
                    let noise = rng.next_u64() as u32 & 0xff;
                    if k < 256 * 8 {
                        let (j, i) = (k as u32 / 8, k as u32 % 8);
                        noise & !(1 << bit) | (j >> i & 1) << bit
                    } else {
                        noise
                    }
                })
                .collect();
            let ids: Vec<u32> = (0..len as u32).map(|k| k * 3 + 1).collect();
            let want: Vec<u32> = ids
                .iter()
                .zip(&masks)
                .filter(|(_, m)| *m >> bit & 1 == 1)
                .map(|(i, _)| *i)
                .collect();
            let mut a = vec![u32::MAX; len + COMPACT_SLACK];
            let mut b = vec![u32::MAX; len + COMPACT_SLACK];
            let na = select_ids(&ids, &masks, bit, &mut a);
            let nb = select_ids_scalar(&ids, &masks, bit, &mut b);
            assert_eq!(&a[..na], &want[..], "bit {bit} tail {tail}");
            assert_eq!(&b[..nb], &want[..], "bit {bit} tail {tail}");
        }
    }
}

/// The packet kernels' tunings (`bench`'s `bvh8-packet8` and `bvh8-packet@K` modes): the
/// ray-by-ray threshold from 1 (a part never leaves packet traversal) to 17 (always ray
/// by ray), and 16-ray packets traced as two 8-ray halves (`*_packet8`) or slices cut in
/// eights (`*_batch8`), and the sorted packets (`*_sorted`), on camera rays, shadow
/// segments and random rays, against the scalar BVH2: bit-identical hits and the same occlusion; partial packets (down to 5
/// lanes, so the second half is sometimes absent) leave the lanes past `len` untouched.
#[test]
fn packet_tunings_match_the_scalar_oracle() {
    let tris = mesh();
    let b = bounds_of(&tris);
    let oracle = Bvh2::build(tris.clone());
    let cam = camera_rays(&b, 48, 48);
    let light = b.center() + b.diagonal() * Vec3::new(0.8, 1.2, 0.6);
    let shadow: Vec<Ray> = cam
        .iter()
        .filter_map(|r| oracle.closest_hit(r).map(|h| (r, h)))
        .map(|(r, h)| {
            let o = r.origin + r.dir * (h.t * 0.999);
            let to = light - o;
            Ray::segment(o, to.normalize(), 0.0, to.length())
        })
        .collect();
    let random = random_rays(&b, 2_000, 77);
    for (name, rays) in [("camera", &cam), ("shadow", &shadow), ("random", &random)] {
        packet_tunings::<8, BvhNode<8>>(name, &tris, &oracle, rays);
        packet_tunings::<8, QNode<8>>(name, &tris, &oracle, rays);
        packet_tunings::<4, BvhNode<4>>(name, &tris, &oracle, rays);
    }
}

fn packet_tunings<const N: usize, T: WideNode<N>>(
    name: &str,
    tris: &Triangles,
    oracle: &Bvh2<Triangles>,
    rays: &[Ray],
) where
    Width<N>: NodeWidth,
{
    use packet_render::geometry::RayPacket;
    let want: Vec<(Option<Hit>, bool)> = rays
        .iter()
        .map(|r| (oracle.closest_hit(r), oracle.any_hit(r)))
        .collect();
    let (hits, occluded) = (
        want.iter().filter(|w| w.0.is_some()).count(),
        want.iter().filter(|w| w.1).count(),
    );
    assert!(
        hits > 20 && occluded > 20,
        "{name}: too few hits to compare ({hits}, {occluded} occluded)"
    );
    let mut bvh = build::<_, N, T>(tris.clone());
    for k in [1u32, 3, 8, 17] {
        bvh.set_packet_min_active([k; 2]);
        let what = format!(
            "{name}, bvh{N} (compressed: {}), threshold {k}",
            T::COMPRESSED
        );
        // Slices in packets of eight.
        let mut b8 = vec![None; rays.len()];
        let mut o8 = vec![false; rays.len()];
        bvh.closest_hit_batch8(rays, &mut b8);
        bvh.any_hit_batch8(rays, &mut o8);
        // Sorted packets (`bvh8-sorted@K`): regrouped by octant at this threshold.
        let mut bs = vec![None; rays.len()];
        let mut os = vec![false; rays.len()];
        bvh.closest_hit_sorted(rays, &mut bs);
        bvh.any_hit_sorted(rays, &mut os);
        for (i, (&(wh, wo), (h, o))) in want.iter().zip(bs.iter().zip(&os)).enumerate() {
            assert!(
                same_hit(wh, *h) && wo == *o,
                "{what}: ray {i} sorted: {h:?} occluded {o}, scalar {wh:?} {wo}"
            );
        }
        // SoA packets, whole and as halves.
        let mut at = 0;
        for (j, chunk) in rays.chunks(16).enumerate() {
            let len = (16 - j % 12).min(chunk.len()); // 5..=16 lanes
            let mut packet = RayPacket::from_rays(chunk);
            packet.len = len;
            let marker = Some(Hit {
                t: -1.0,
                prim: 7,
                u: 0.0,
                v: 0.0,
            });
            let (mut h16, mut h8) = ([marker; 16], [marker; 16]);
            let (mut a16, mut a8) = ([true; 16], [true; 16]);
            bvh.closest_hit_packet(&packet, &mut h16);
            bvh.any_hit_packet(&packet, &mut a16);
            bvh.closest_hit_packet8(&packet, &mut h8);
            bvh.any_hit_packet8(&packet, &mut a8);
            for i in 0..16 {
                if i < len {
                    let (wh, wo) = want[at + i];
                    for (kind, h, o) in [("packet", h16[i], a16[i]), ("packet8", h8[i], a8[i])] {
                        assert!(
                            same_hit(wh, h) && wo == o,
                            "{what}: ray {} {kind}: {h:?} occluded {o}, scalar {wh:?} {wo}",
                            at + i
                        );
                    }
                } else {
                    assert_eq!(h16[i], marker, "{what}: lane {i} past len");
                    assert_eq!(h8[i], marker, "{what}: lane {i} past len (halves)");
                    assert!(a16[i] && a8[i], "{what}: lane {i} past len");
                }
            }
            for i in 0..chunk.len() {
                let (wh, wo) = want[at + i];
                assert!(
                    same_hit(wh, b8[at + i]) && wo == o8[at + i],
                    "{what}: ray {} batch8: {:?} occluded {}, scalar {wh:?} {wo}",
                    at + i,
                    b8[at + i],
                    o8[at + i]
                );
            }
            at += chunk.len();
        }
    }
}
