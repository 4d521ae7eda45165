//! The scene-level batch queries' stream path: `SceneAccel::closest_hit_batch` and
//! `any_hit_batch` send large incoherent batches through the BVH4/BVH8 stream kernel
//! (`prefers_stream`); their answers must equal the per-ray queries, hit for hit, also
//! where a later primitive kind (spheres) is searched in front of the triangles' hits.

use crate::common;

use common::*;
use glam::Vec3;
use packet_render::accel::{
    AccelKind, BatchScratch, STREAM_WINS, SceneAccel, incoherent_batch, prefers_stream,
};
use packet_render::geometry::{Aabb, Ray};
use packet_render::scene::{Material, Scene, SceneBuilder, procedural};

fn scene() -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::default());
    procedural::tessellated_mesh(&mut b, 20_000, Vec3::ZERO, 1.0, m);
    for k in 0..6 {
        let a = k as f32 * 1.05;
        b.add_sphere(
            Vec3::new(a.cos() * 1.2, 0.3 * k as f32 - 0.8, a.sin() * 1.2),
            0.3,
            m,
        );
    }
    b.finish().expect("a valid scene")
}

/// Rays from random points around the mesh in random directions, with a few invalid ones.
fn incoherent_rays(n: usize) -> Vec<Ray> {
    let mut rng = Rng(17);
    let b = Aabb::new(Vec3::splat(-1.6), Vec3::splat(1.6));
    let mut rays: Vec<Ray> = (0..n)
        .map(|_| Ray::new(rng.point_in(&b), rng.unit_vector()))
        .collect();
    for i in (0..n).step_by(97) {
        rays[i].dir = Vec3::ZERO;
    }
    rays
}

#[test]
fn incoherent_batches_stream_and_agree_with_single_rays() {
    let scene = scene();
    let rays = incoherent_rays(3000);
    assert!(
        incoherent_batch(&rays),
        "random directions make incoherent packets"
    );
    // The stream kernel is chosen only in builds where it measures faster (AVX2 or
    // AVX-512); elsewhere the same batches must stay in packets.
    assert_eq!(prefers_stream(&rays), STREAM_WINS);
    if !STREAM_WINS {
        println!("this build has neither AVX2 nor AVX-512: the batches below run as packets");
    }
    assert!(!incoherent_batch(&rays[..100]), "below the batch threshold");
    let toward_origin: Vec<Ray> = (0..512)
        .map(|i| {
            let o = Vec3::new(0.001 * i as f32, 0.5, 4.0);
            Ray::new(o, (Vec3::ZERO - o).normalize())
        })
        .collect();
    assert!(
        !incoherent_batch(&toward_origin),
        "coherent rays stay in packets"
    );
    for kind in [AccelKind::Bvh4, AccelKind::Bvh8] {
        let accel = SceneAccel::build(&scene, kind);
        let mut scratch = BatchScratch::default();
        let mut hits = vec![None; rays.len()];
        accel.closest_hit_batch(&rays, &mut hits, &mut scratch);
        let mut blocked = vec![false; rays.len()];
        accel.any_hit_batch(&rays, &mut blocked, &mut scratch);
        let (mut tri, mut sph) = (0, 0);
        for (i, r) in rays.iter().enumerate() {
            let want = accel.closest_hit(r);
            assert_eq!(hits[i], want, "{kind} ray {i}");
            assert_eq!(blocked[i], accel.any_hit(r), "{kind} ray {i}: occlusion");
            match want.map(|h| h.prim) {
                Some(packet_render::accel::PrimRef::Triangle(_)) => tri += 1,
                Some(packet_render::accel::PrimRef::Sphere(_)) => sph += 1,
                _ => {}
            }
        }
        assert!(
            tri > 300 && sph > 30,
            "{kind}: too few hits to compare ({tri}, {sph})"
        );
    }
}
