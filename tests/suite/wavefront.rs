//! The wavefront integrator renders the recursive renderer's images (every shipped
//! scene, distribution effects included, at 1 and 2 threads), and a scene pays only for
//! the queues and stages it needs, as `--stats-json` of the real binary shows.

use crate::common::bin::bin;
use crate::common::temp::temp_dir;
use packet_render::accel::{AccelKind, Primitives, SceneAccel, Triangles};
use packet_render::geometry::RayQuery;
use packet_render::integrator::{RenderOptions, recursive, wavefront};
use packet_render::scene::Scene;
use packet_render::scene::load::load_scene;
use std::path::{Path, PathBuf};

fn scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    paths
}

/// Float summation order differs (the recursive renderer sums each node's children
/// before weighting them, the wavefront adds weighted contributions to the camera
/// sample as they arrive): a relative tolerance per channel, absolute near zero.
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-4 * a.abs().max(1.0)
}

/// Whether the camera ray of pixel `(x, y)` hits two triangles at exactly its closest
/// t, by brute force. Only decidable where a pixel has one camera ray through its
/// centre (1 spp, no lens, no motion); elsewhere `false`, so a difference fails.
fn camera_ray_ties(scene: &Scene, opts: &RenderOptions, x: u32, y: u32) -> bool {
    if opts.spp != 1 || scene.features.depth_of_field || scene.features.motion {
        return false;
    }
    let ray = scene
        .camera
        .frame(opts.width, opts.height)
        .ray(x as f32 + 0.5, y as f32 + 0.5);
    let (Some(best), Some(q)) = (
        SceneAccel::build(scene, AccelKind::BruteForce).closest_hit(&ray),
        RayQuery::new(&ray),
    ) else {
        return false;
    };
    let tris = Triangles::from_mesh(&scene.mesh);
    (0..tris.count())
        .filter(|&i| {
            tris.intersect(i, &q, f32::INFINITY)
                .is_some_and(|h| h.t == best.t)
        })
        .count()
        >= 2
}

#[test]
fn wavefront_images_equal_recursive_images_on_every_shipped_scene() {
    let mut compared = 0;
    for path in scenes() {
        let name = path.display().to_string();
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut opts = RenderOptions::from_scene(&scene);
        opts.width = 48;
        opts.height = 36;
        opts.seed = 3;
        // The scene's own sample settings, capped small.
        opts.spp = opts.spp.min(4);
        opts.samples.shadow = opts.samples.shadow.min(4);
        opts.samples.glossy = opts.samples.glossy.min(4);
        opts.samples.lens = opts.samples.lens.min(2);
        opts.samples.time = opts.samples.time.min(2);
        // BVH2 traces batches ray by ray; the BVH4 (the default) traces the wavefront's
        // batches as 16-ray packets and the recursive renderer's rays one by one. The
        // two traversals visit leaves in different orders, so a ray that hits two
        // primitives at exactly the same t (a camera ray through the edge the Cornell
        // floor shares with a wall) may get the other primitive: measured, 10 of the
        // 262,144 pixel-centre rays of cornell.toml at 512 x 512 (17 with the BVH8), all
        // exact ties, none in the other shipped scenes; here 1 of 1728 Cornell pixels
        // on the BVH4 (floor against green wall, bottom row), 5 of 19,200 at 160 x 120,
        // none on the BVH2. A deterministic tie rule (smallest (t, primitive id), with
        // ties admitted by the triangle tests and the node culling) would remove the
        // cause but touches every closest-hit comparison of the traversals and SIMD
        // kernels; not done. Until then a differing BVH4 pixel passes only if its
        // camera ray is shown, by brute force, to hit two primitives at one t, and
        // the test prints how many it let through.
        for (kind, threads) in [
            (AccelKind::Bvh2, 1),
            (AccelKind::Bvh2, 2),
            (AccelKind::Bvh4, 1),
            (AccelKind::Bvh4, 2),
        ] {
            let accel = SceneAccel::build(&scene, kind);
            let name = format!("{name} ({kind})");
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (reference, wave) = pool.install(|| {
                (
                    recursive::render(&scene, &accel, &opts),
                    wavefront::render(&scene, &accel, &opts),
                )
            });
            // Same rays, same samples: the ray trees are the same trees.
            assert_eq!(wave.rays, reference.rays, "{name}, {threads} threads");
            assert_eq!(
                wave.samples_drawn, reference.samples_drawn,
                "{name}, {threads} threads"
            );
            assert_eq!(
                wave.nonfinite_samples, reference.nonfinite_samples,
                "{name}"
            );
            let mut ties = 0;
            let differ: Vec<String> = reference
                .film
                .pixels
                .iter()
                .zip(&wave.film.pixels)
                .enumerate()
                .filter(|(_, (a, b))| !(0..3).all(|c| close(a[c], b[c])))
                .filter(|(i, _)| {
                    let (x, y) = (*i as u32 % opts.width, *i as u32 / opts.width);
                    let tie = kind != AccelKind::Bvh2 && camera_ray_ties(&scene, &opts, x, y);
                    ties += tie as usize;
                    !tie
                })
                .map(|(i, (a, b))| {
                    format!(
                        "({}, {}) recursive {a} wavefront {b}",
                        i as u32 % opts.width,
                        i as u32 / opts.width
                    )
                })
                .collect();
            assert!(
                differ.is_empty(),
                "{name}, {threads} threads: {} pixels differ, first {:?}",
                differ.len(),
                &differ[..differ.len().min(3)]
            );
            if ties > 0 {
                eprintln!(
                    "NOTE: {name}, {threads} threads: {ties} pixels differ on an exact tie of \
                     their camera ray (two primitives at one t), let through"
                );
            }
            assert!(wave.stages_ms.is_some() && reference.stages_ms.is_none());
        }
        compared += 1;
    }
    assert!(
        compared >= 9,
        "expected the shipped scenes, found {compared}"
    );
}

#[test]
fn wavefront_is_deterministic_across_thread_counts() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/glossy.toml");
    let scene = load_scene(&path).unwrap();
    let mut opts = RenderOptions::from_scene(&scene);
    (opts.width, opts.height, opts.spp, opts.seed) = (40, 24, 2, 11);
    let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
    let render = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let out = pool.install(|| wavefront::render(&scene, &accel, &opts));
        out.film
            .pixels
            .iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    let one = render(1);
    assert_eq!(one, render(2));
    assert_eq!(one, render(3));
}

fn stats(scene: &str) -> serde_json::Value {
    stats_with(scene, &[])
}

/// `--stats-json` of a 32x24, 1 spp wavefront render of `scene`, with `extra` flags.
fn stats_with(scene: &str, extra: &[&str]) -> serde_json::Value {
    let dir = temp_dir(&scene.replace('.', "_"));
    let json = dir.join("stats.json");
    let o = bin()
        .args([
            "render",
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scenes")
                .join(scene)
                .to_str()
                .unwrap(),
            "-o",
            dir.join("out.png").to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "1",
            "--shadow-samples",
            "2",
            "--integrator",
            "wavefront",
            "--quiet",
            "--stats-json",
            json.to_str().unwrap(),
        ])
        .args(extra)
        .output()
        .expect("binary runs");
    assert!(
        o.status.success(),
        "{scene}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let s = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    s
}

#[test]
fn the_scene_decides_the_pipeline() {
    // The Whitted room has glass and a mirror: refraction and reflection queues exist
    // and carry rays; two point lights, no area light.
    let s = stats("whitted.toml");
    assert_eq!(s["integrator"], "wavefront");
    let (rays, stages) = (&s["rays"], &s["stages_ms"]);
    assert_eq!(rays["camera"], 32 * 24);
    for kind in ["shadow", "reflection", "refraction"] {
        assert!(rays[kind].as_u64().unwrap() > 0, "whitted: {kind} rays");
        assert!(
            stages[kind].as_f64().unwrap() >= 0.0,
            "whitted: {kind} stage"
        );
    }
    for absent in ["area_shadow", "glossy", "translucency"] {
        assert!(stages.get(absent).is_none(), "whitted: {absent} stage");
    }
    for stage in ["camera", "trace", "shade"] {
        assert!(stages[stage].as_f64().unwrap() >= 0.0, "whitted: {stage}");
    }
    // The queue high-water mark is reported: 768 camera rays in batches of at most
    // `MAX_WAVE_PATHS` paths, so at least one camera ray and at most the bound.
    let peak = s["peak_queue_paths"].as_u64().expect("peak_queue_paths");
    assert!(
        peak >= 1 && peak <= wavefront::MAX_WAVE_PATHS as u64,
        "{peak}"
    );

    // The sphereflake is mirror metal without glass: no refraction at all.
    let s = stats("sphereflake.toml");
    let (rays, stages) = (&s["rays"], &s["stages_ms"]);
    assert_eq!(rays["refraction"], 0);
    assert!(stages.get("refraction").is_none(), "sphereflake: {stages}");
    assert!(rays["reflection"].as_u64().unwrap() > 0);
    assert!(stages["reflection"].as_f64().is_some());

    // Diffuse surfaces under area lights only: no reflection, refraction, glossy or
    // translucency queue, no point-light shadow queue; area-light shadow rays only.
    let s = stats("area_lights.toml");
    let (rays, stages) = (&s["rays"], &s["stages_ms"]);
    for kind in ["reflection", "refraction", "glossy", "translucency"] {
        assert_eq!(rays[kind], 0, "area_lights: {kind} rays");
        assert!(stages.get(kind).is_none(), "area_lights: {kind} stage");
    }
    assert!(stages.get("shadow").is_none(), "area_lights: {stages}");
    assert!(stages["area_shadow"].as_f64().is_some());
    assert!(rays["shadow"].as_u64().unwrap() > 0);
}

/// The wavefront's queues hold a bounded number of paths whatever the samples per
/// pixel: at 1 and at 4096 camera rays per pixel (dof_area.toml, 4x4 pixels; 256 eye
/// samples x 16 lens points) the peak stays within `MAX_WAVE_PATHS`. dof_area has no
/// mirror or glass, so every path ends at its first hit and the bound is exact: a batch
/// of `b` camera rays holds at most `b (1 + fan-out)` paths, and `b` is chosen so that
/// this is at most `MAX_WAVE_PATHS`. Before the queues were bounded, a tile held all of
/// its camera rays and their shadow rays at once (here 65536 camera rays and 4 shadow
/// rays each), which is what the second assertion would have seen.
#[test]
fn wavefront_queues_are_bounded_whatever_the_sample_counts() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/dof_area.toml");
    let scene = load_scene(&path).unwrap();
    let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
    let mut peaks = Vec::new();
    for (spp, lens) in [(1u32, 1u32), (256, 16)] {
        let mut o = RenderOptions::from_scene(&scene);
        o.width = 4;
        o.height = 4;
        o.spp = spp;
        o.samples.lens = lens;
        o.samples.shadow = 4;
        let out = wavefront::render(&scene, &accel, &o);
        assert_eq!(out.rays.camera, 16 * (spp * lens) as u64);
        assert!(
            out.peak_queue_paths >= 1 && out.peak_queue_paths <= wavefront::MAX_WAVE_PATHS as u64,
            "{spp} spp x {lens} lens: peak {} paths",
            out.peak_queue_paths
        );
        peaks.push(out.peak_queue_paths);
    }
    // One ray per pixel: all 16 camera rays fit one batch, with at most 4 shadow rays
    // each (one area light, 4 samples), all queued before any is traced.
    assert!(peaks[0] <= 16 * 5, "{peaks:?}");
}

/// Time by stage: at one thread the stages are disjoint intervals of the render phase,
/// so each is non-negative and together they take no more than it. The Whitted room
/// (mirror, glass, point lights) has the camera, trace, shade, shadow, reflection and
/// refraction stages, and every frame has the tile scheduler's serial `setup` and
/// `assemble` and the pixel filter's `resolve`.
#[test]
fn stage_times_are_part_of_the_render_phase() {
    let s = stats_with("whitted.toml", &["--threads", "1"]);
    let stages = s["stages_ms"].as_object().expect("stages_ms");
    for key in [
        "camera",
        "trace",
        "shade",
        "shadow",
        "reflection",
        "refraction",
        "setup",
        "resolve",
        "film",
        "assemble",
    ] {
        assert!(stages.contains_key(key), "missing stage {key}: {stages:?}");
    }
    let mut sum = 0.0;
    for (key, v) in stages {
        let ms = v.as_f64().unwrap();
        assert!(ms >= 0.0, "{key}: {ms}");
        sum += ms;
    }
    let render = s["time_ms"]["render"].as_f64().unwrap();
    assert!(
        sum > 0.0 && sum <= render,
        "stages {sum} ms, render {render} ms"
    );
}
