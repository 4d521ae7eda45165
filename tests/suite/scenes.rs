//! Every scene shipped in `scenes/` loads and renders to a plausible image through the
//! default structure (BVH4) and matches the reference structure (BVH2) pixel for pixel.

use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::integrator::camera_rays::SamplePlan;
use packet_render::integrator::{RenderOptions, recursive};
use packet_render::scene::load::load_scene;
use std::path::Path;

#[test]
fn every_shipped_scene_renders() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut rendered = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut opts = RenderOptions::from_scene(&scene);
        opts.width = 32;
        opts.height = 24;
        opts.spp = 1;
        let (bvh4, bvh2) = (
            SceneAccel::build(&scene, AccelKind::Bvh4),
            SceneAccel::build(&scene, AccelKind::Bvh2),
        );
        let fast = recursive::render(&scene, &bvh4, &opts);
        let reference = recursive::render(&scene, &bvh2, &opts);
        let name = path.display();
        // Pixels may differ only where the camera ray hits two primitives at exactly the
        // same distance (a ray through an edge shared by two walls): either is right.
        let frame = scene.camera.frame(opts.width, opts.height);
        for i in 0..fast.film.pixels.len() {
            if fast.film.pixels[i] == reference.film.pixels[i] {
                continue;
            }
            let (x, y) = (i as u32 % opts.width, i as u32 / opts.width);
            let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
            let (a, b) = (
                bvh4.closest_hit(&ray).unwrap(),
                bvh2.closest_hit(&ray).unwrap(),
            );
            assert!(
                a.t == b.t && a.prim != b.prim,
                "{name}: pixel ({x}, {y}) differs without a tie: bvh4 {a:?}, bvh2 {b:?}"
            );
        }
        assert_eq!(fast.nonfinite_samples, 0, "{name}");
        let per_pixel = SamplePlan::new(&scene, &opts).camera_rays_per_pixel() as u64;
        assert_eq!(fast.rays.camera, 32 * 24 * per_pixel, "{name}");
        let px = &fast.film.pixels;
        assert!(
            px.iter().all(|p| p.is_finite() && p.min_element() >= 0.0),
            "{name}: bad pixel values"
        );
        // something in view: not every pixel is the background
        let background = scene.background;
        let covered = px
            .iter()
            .filter(|p| (**p - background).abs().max_element() > 1e-4)
            .count();
        assert!(
            covered > px.len() / 10,
            "{name}: only {covered} of {} pixels show geometry",
            px.len()
        );
        rendered += 1;
    }
    assert!(
        rendered >= 4,
        "expected the shipped scenes, found {rendered}"
    );
}
