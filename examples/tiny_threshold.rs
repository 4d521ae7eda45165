//! Measures the scene-level batch queries of small scenes with and without the tiny
//! brute-force lane path (`accel::TinyScene`), to choose `TINY_MAX_PRIMITIVES`:
//! `cargo run --release --example tiny_threshold` (1 thread). Scenes: a floor quad and
//! `n - 2` spheres of the Whitted room's size; rays: camera rays (coherent) and shadow
//! segments from their hits towards a point light, batches of 4096, as the wavefront
//! integrator issues them.

use glam::Vec3;
use packet_render::accel::{AccelKind, BatchScratch, SceneAccel};
use packet_render::geometry::Ray;
use packet_render::scene::{Camera, Material, Scene, SceneBuilder};
use std::time::Instant;

fn scene(n: usize) -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    b.add_quad(
        Vec3::new(-500.0, 0.0, -500.0),
        Vec3::new(0.0, 0.0, 1000.0),
        Vec3::new(1000.0, 0.0, 0.0),
        m,
    );
    for i in 0..n - 2 {
        let a = i as f32 * 2.4;
        let r = 0.3 + 0.7 * ((i * 7 % 5) as f32 / 4.0);
        let c = Vec3::new(2.5 * a.cos(), r + 0.2 * (i % 3) as f32, 2.5 * a.sin() - 1.0);
        b.add_sphere(c, r, m);
    }
    b.camera = Some(Camera {
        eye: Vec3::new(0.0, 1.8, 7.0),
        target: Vec3::new(0.0, 1.0, 0.0),
        up: Vec3::Y,
        vfov_deg: 40.1,
    });
    b.finish().unwrap()
}

fn time(f: &mut dyn FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..7 {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    println!("prims  closest tree/tiny ns/ray   occlusion tree/tiny ns/ray");
    for n in [4, 6, 8, 12, 16, 24, 32] {
        let scene = scene(n);
        let mut accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        let (w, h) = (512, 384);
        let frame = scene.camera.frame(w, h);
        let camera: Vec<Ray> = (0..w * h)
            .map(|i| frame.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5))
            .collect();
        let light = Vec3::new(-5.0, 9.0, 7.0);
        let shadow: Vec<Ray> = camera
            .iter()
            .filter_map(|r| {
                let hit = accel.closest_hit(r)?;
                let p = r.at(hit.t * (1.0 - 1e-4));
                Some(Ray::segment(p, light - p, 0.0, 1.0 - 1e-4))
            })
            .collect();
        let mut scratch = BatchScratch::default();
        let mut hits = vec![None; 4096];
        let mut blocked = vec![false; 4096];
        let mut run = |accel: &SceneAccel| {
            let c = time(&mut || {
                for b in camera.chunks(4096) {
                    accel.closest_hit_batch(b, &mut hits[..b.len()], &mut scratch);
                }
            });
            let s = time(&mut || {
                for b in shadow.chunks(4096) {
                    accel.any_hit_batch(b, &mut blocked[..b.len()], &mut scratch);
                }
            });
            (c * 1e9 / camera.len() as f64, s * 1e9 / shadow.len() as f64)
        };
        let tiny = packet_render::accel::TinyScene::build_up_to(&scene, usize::MAX);
        accel.tiny = None;
        let (ct, st) = run(&accel);
        accel.tiny = tiny;
        let (cb, sb) = run(&accel);
        println!(
            "{n:5}  {ct:8.1} {cb:8.1} ({:.2}x)   {st:8.1} {sb:8.1} ({:.2}x)",
            ct / cb,
            st / sb
        );
    }
}
