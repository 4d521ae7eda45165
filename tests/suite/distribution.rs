//! Distribution ray tracing (Cook, Porter, Carpenter 1984): estimators are unbiased,
//! error falls as it should, and each effect has the geometry the optics predict —
//! depth of field (thin-lens circle of confusion), motion blur (smear = velocity x
//! shutter), area lights (penumbra by similar triangles). A scene without the effects
//! traces exactly the rays of the plain Whitted renderer.

use glam::Vec3;
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::film::{Film, luminance};
use packet_render::integrator::{RenderOptions, RenderOutput, SamplerKind, recursive};
use packet_render::scene::load::parse_toml_scene;
use packet_render::scene::{Camera, CameraEffects, Light, Material, Scene, SceneBuilder};
use std::path::Path;

fn render(scene: &Scene, opts: &RenderOptions) -> RenderOutput {
    let accel = SceneAccel::build(scene, AccelKind::Bvh4);
    let out = recursive::render(scene, &accel, opts);
    assert_eq!(out.nonfinite_samples, 0, "numeric failure in the render");
    out
}

fn options(scene: &Scene, size: u32, spp: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.width = size;
    o.height = size;
    o.spp = spp;
    o.max_depth = 4;
    o
}

fn emissive(c: Vec3) -> Material {
    Material {
        name: "lamp".into(),
        diffuse: Vec3::ZERO,
        emission: c,
        ..Default::default()
    }
}

/// Mean luminance of a film.
fn mean(f: &Film) -> f64 {
    f.pixels.iter().map(|p| luminance(*p) as f64).sum::<f64>() / f.pixels.len() as f64
}

fn mean_and_var(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let v = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, v)
}

/// A scene with every effect: an area light, a glossy sphere, a frosted pane, a lens
/// and a moving sphere.
fn everything() -> Scene {
    let text = r#"
background = [0.1, 0.1, 0.15]
[camera]
eye = [0, 1, 4]
target = [0, 0.5, 0]
fov = 45
aperture = 0.1
focus_distance = 4
shutter = [0, 1]
[materials.floor]
checker = { a = [0.8, 0.8, 0.8], b = [0.2, 0.2, 0.2], scale = 0.5 }
[materials.gloss]
diffuse = [0.1, 0.1, 0.1]
glossy = [0.7, 0.7, 0.7]
gloss_exponent = 30
[materials.frost]
preset = "glass"
translucency_exponent = 40
[[plane]]
point = [0, 0, 0]
normal = [0, 1, 0]
size = 5
material = "floor"
[[sphere]]
center = [-0.7, 0.5, 0]
radius = 0.5
material = "gloss"
[[sphere]]
center = [0.8, 0.4, 0.5]
radius = 0.4
velocity = [0, 0.5, 0]
[[quad]]
corner = [-0.2, 0.1, 1.2]
edge1 = [0.6, 0, 0]
edge2 = [0, 0.7, 0]
material = "frost"
[[light]]
type = "quad"
corner = [-0.5, 2.5, -0.5]
edge1 = [1, 0, 0]
edge2 = [0, 0, 1]
radiance = [5, 5, 5]
"#;
    parse_toml_scene(text, Path::new("everything.toml")).unwrap()
}

#[test]
fn estimators_are_unbiased() {
    let scene = everything();
    let f = scene.features;
    assert!(f.area_lights && f.glossy && f.translucency && f.depth_of_field && f.motion);
    // Many 1-sample renders (uniform random: every sample set is one uniform draw)
    // against a few high-sample stratified ones; the image mean of each render is one
    // draw of its estimator. Equal expectations within 5 standard errors.
    let mut low = options(&scene, 12, 1);
    low.sampler = SamplerKind::Random;
    let lows: Vec<f64> = (0..48)
        .map(|s| {
            low.seed = s;
            mean(&render(&scene, &low).film)
        })
        .collect();
    let mut high = options(&scene, 12, 64);
    high.samples.shadow = 4;
    high.samples.glossy = 4;
    for sampler in [
        SamplerKind::Jittered,
        SamplerKind::Halton,
        SamplerKind::Sobol,
    ] {
        high.sampler = sampler;
        let highs: Vec<f64> = (0..4)
            .map(|s| {
                high.seed = 1000 + s;
                mean(&render(&scene, &high).film)
            })
            .collect();
        let (ml, vl) = mean_and_var(&lows);
        let (mh, vh) = mean_and_var(&highs);
        let se = (vl / lows.len() as f64 + vh / highs.len() as f64).sqrt();
        let z = (ml - mh) / se;
        assert!(
            z.abs() < 5.0,
            "{sampler}: 1-sample mean {ml:.5} vs {mh:.5}, se {se:.5}, z {z:.2}"
        );
    }
}

/// A lit sphere on a floor against the sky: edges and a hard shadow.
fn edges() -> Scene {
    let mut b = SceneBuilder::new();
    let floor = b.add_material(Material::diffuse("floor", Vec3::splat(0.7)));
    let ball = b.add_material(Material::diffuse("ball", Vec3::new(0.9, 0.3, 0.2)));
    b.add_quad(
        Vec3::new(-3.0, 0.0, -3.0),
        Vec3::new(0.0, 0.0, 6.0),
        Vec3::new(6.0, 0.0, 0.0),
        floor,
    );
    b.add_sphere(Vec3::new(0.0, 0.6, 0.0), 0.6, ball);
    b.add_light(Light::Point {
        position: Vec3::new(2.0, 4.0, 2.0),
        intensity: Vec3::splat(20.0),
    });
    b.background = Vec3::new(0.3, 0.4, 0.8);
    b.camera = Some(Camera {
        eye: Vec3::new(0.0, 1.0, 3.0),
        target: Vec3::new(0.0, 0.5, 0.0),
        up: Vec3::Y,
        vfov_deg: 40.0,
    });
    b.finish().unwrap()
}

#[test]
fn random_error_falls_as_inverse_square_root_and_jitter_beats_it() {
    let scene = edges();
    let mut reference = options(&scene, 24, 1024);
    reference.seed = 99;
    let reference = render(&scene, &reference).film;
    let error = |sampler: SamplerKind, n: u32| {
        let mut o = options(&scene, 24, n);
        o.sampler = sampler;
        o.seed = 5;
        render(&scene, &o).film.rmse(&reference).unwrap()
    };
    let ns = [1u32, 4, 16, 64];
    let pts: Vec<(f64, f64)> = ns
        .iter()
        .map(|&n| (n as f64, error(SamplerKind::Random, n)))
        .collect();
    let slope = packet_render::bench::converge::loglog_slope(&pts);
    assert!(
        (-0.65..=-0.35).contains(&slope),
        "random sampling error slope {slope:.3}: {pts:?}"
    );
    for n in [4, 16] {
        let (j, r) = (
            error(SamplerKind::Jittered, n),
            error(SamplerKind::Random, n),
        );
        assert!(j < r, "{n} spp: jittered {j:.5} should beat random {r:.5}");
    }
}

/// A small emissive sphere in front of a pinhole or thin-lens camera looking down -z.
fn bright_point(depth: f32, radius: f32, effects: CameraEffects, velocity: Vec3) -> Scene {
    let mut b = SceneBuilder::new();
    let lamp = b.add_material(emissive(Vec3::ONE));
    let c = Vec3::new(0.0, 0.0, -depth);
    if velocity == Vec3::ZERO {
        b.add_sphere(c, radius, lamp);
    } else {
        b.add_moving_sphere(c, radius, velocity, lamp);
    }
    b.camera = Some(Camera {
        eye: Vec3::ZERO,
        target: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        vfov_deg: 30.0,
    });
    b.camera_effects = effects;
    b.finish().unwrap()
}

/// Intensity-weighted centroid and second central moments `(var_x, var_y)` in pixels.
fn moments(f: &Film) -> (f64, f64, f64, f64) {
    let (mut w, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for y in 0..f.height {
        for x in 0..f.width {
            let i = f.get(x, y).x as f64;
            w += i;
            sx += i * (x as f64 + 0.5);
            sy += i * (y as f64 + 0.5);
        }
    }
    let (cx, cy) = (sx / w, sy / w);
    let (mut vx, mut vy) = (0.0, 0.0);
    for y in 0..f.height {
        for x in 0..f.width {
            let i = f.get(x, y).x as f64;
            vx += i * (x as f64 + 0.5 - cx).powi(2);
            vy += i * (y as f64 + 0.5 - cy).powi(2);
        }
    }
    (cx, cy, vx / w, vy / w)
}

/// Pixels per unit of `tan` on the image plane.
fn pixels_per_tan(size: u32, vfov_deg: f32) -> f64 {
    size as f64 / (2.0 * (0.5 * vfov_deg as f64).to_radians().tan())
}

#[test]
fn depth_of_field_keeps_focus_sharp_and_blurs_by_the_circle_of_confusion() {
    let size = 64;
    let (focus, aperture) = (5.0f32, 0.25f32);
    let lens = CameraEffects {
        aperture,
        focus_distance: Some(focus),
        ..Default::default()
    };
    let spread = |depth: f32, effects: CameraEffects| {
        let scene = bright_point(depth, 0.02, effects, Vec3::ZERO);
        assert_eq!(scene.features.depth_of_field, effects.aperture > 0.0);
        let mut o = options(&scene, size, 256);
        o.sampler = SamplerKind::Jittered;
        let out = render(&scene, &o);
        if effects.aperture > 0.0 {
            assert_eq!(out.samples_drawn.lens, (size * size * 256) as u64);
        } else {
            assert_eq!(out.samples_drawn.total(), 0);
        }
        let (_, _, vx, vy) = moments(&out.film);
        vx + vy
    };
    // In focus: the lens changes nothing measurable.
    let pin = spread(focus, CameraEffects::default());
    let thin = spread(focus, lens);
    assert!(
        (thin - pin).abs() < 0.1,
        "in focus: {thin:.3} vs pinhole {pin:.3} px²"
    );
    // Off focus: a uniform disc of radius R adds R²/2 to the second moment; thin-lens
    // optics give R = aperture |1/z - 1/focus| on the tan-plane.
    let depth = 2.5;
    let pin = spread(depth, CameraEffects::default());
    let thin = spread(depth, lens);
    let measured = (2.0 * (thin - pin)).sqrt();
    let expected = aperture as f64
        * (1.0 / depth as f64 - 1.0 / focus as f64).abs()
        * pixels_per_tan(size, 30.0);
    assert!(
        (measured / expected - 1.0).abs() < 0.08,
        "blur radius {measured:.3} px, thin lens says {expected:.3} px"
    );
}

#[test]
fn motion_blur_smears_by_velocity_times_shutter() {
    let size = 64;
    let depth = 5.0;
    let shutter = CameraEffects {
        shutter: [0.0, 1.0],
        ..Default::default()
    };
    let measure = |velocity: Vec3, effects: CameraEffects| {
        let scene = bright_point(depth, 0.05, effects, velocity);
        let mut o = options(&scene, size, 64);
        o.sampler = SamplerKind::Jittered;
        let out = render(&scene, &o);
        (moments(&out.film), out)
    };
    let ((cx0, _, vx0, vy0), _) = measure(Vec3::ZERO, CameraEffects::default());
    let v = Vec3::new(1.0, 0.0, 0.0);
    let ((cx1, _, vx1, vy1), out) = measure(v, shutter);
    assert_eq!(out.samples_drawn.time, (size * size * 64) as u64);
    // A uniform smear of length L adds L²/12 to the variance along the motion only.
    let ppt = pixels_per_tan(size, 30.0);
    let expected = v.x as f64 / depth as f64 * ppt;
    let measured = (12.0 * (vx1 - vx0)).sqrt();
    assert!(
        (measured / expected - 1.0).abs() < 0.05,
        "smear {measured:.3} px, velocity x shutter says {expected:.3} px"
    );
    assert!((vy1 - vy0).abs() < 0.05, "no smear across the motion");
    // The smear is centred on the mid-shutter position (within a pixel: off axis the
    // sphere's image grows slightly, which pulls the centroid outwards).
    assert!(
        (cx1 - cx0 - 0.5 * expected).abs() < 1.0,
        "{cx1} vs {cx0} + {}",
        0.5 * expected
    );
    // The same moving sphere with a closed shutter (time 0 only) is not smeared.
    let ((_, _, vx2, _), out) = measure(v, CameraEffects::default());
    assert_eq!(out.samples_drawn.total(), 0);
    assert!((vx2 - vx0).abs() < 0.05);
}

#[test]
fn a_static_scene_is_identical_with_and_without_a_shutter() {
    let scene = edges();
    let mut with_shutter = scene.clone();
    with_shutter.camera_effects.shutter = [0.0, 1.0];
    // Finish again so that features are recomputed as a loader would.
    let rebuilt = |s: &Scene, effects: CameraEffects| {
        let mut b = SceneBuilder::new();
        b.mesh = s.mesh.clone();
        b.spheres = s.spheres.clone();
        b.materials = s.materials.clone();
        b.lights = s.lights.clone();
        b.camera = Some(s.camera);
        b.background = s.background;
        b.camera_effects = effects;
        b.finish().unwrap()
    };
    let a = rebuilt(&scene, CameraEffects::default());
    let b = rebuilt(
        &scene,
        CameraEffects {
            shutter: [0.0, 1.0],
            ..Default::default()
        },
    );
    assert!(!b.features.motion);
    let mut o = options(&a, 20, 4);
    o.samples.time = 8;
    let (ra, rb) = (render(&a, &o), render(&b, &o));
    assert_eq!(ra.film, rb.film);
    assert_eq!(ra.rays, rb.rays);
    assert_eq!(rb.samples_drawn.total(), 0);
}

#[test]
fn penumbra_width_follows_similar_triangles() {
    // Light: a 2 x 2 panel at height 4; occluder: the half-plane x < 0 at height 1.
    // A floor point sees all of the light for x > w h_o / (2 (h_l - h_o)) and none
    // below minus that: penumbra width w h_o / (h_l - h_o) = 2/3.
    let (w, h_l, h_o) = (2.0f32, 4.0f32, 1.0f32);
    let build = |occluded: bool| {
        let mut b = SceneBuilder::new();
        let floor = b.add_material(Material::diffuse("floor", Vec3::splat(0.8)));
        let wall = b.add_material(Material::diffuse("wall", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, 0.0),
            floor,
        );
        if occluded {
            b.add_quad(
                Vec3::new(-10.0, h_o, -10.0),
                Vec3::new(10.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 20.0),
                wall,
            );
        }
        b.add_light(Light::Quad {
            corner: Vec3::new(-0.5 * w, h_l, -0.5 * w),
            edge1: Vec3::new(w, 0.0, 0.0),
            edge2: Vec3::new(0.0, 0.0, w),
            radiance: Vec3::splat(4.0),
        });
        // Below the occluder, looking straight down at the floor.
        b.camera = Some(Camera {
            eye: Vec3::new(0.0, 0.9, 0.0),
            target: Vec3::ZERO,
            up: Vec3::new(0.0, 0.0, -1.0),
            vfov_deg: 90.0,
        });
        b.finish().unwrap()
    };
    let size = 64;
    let row = size / 2;
    let profile = |scene: &Scene| {
        let mut o = options(scene, size, 1);
        o.samples.shadow = 1024;
        let out = render(scene, &o);
        (0..size)
            .map(|x| out.film.get(x, row).x as f64)
            .collect::<Vec<_>>()
    };
    let lit = profile(&build(false));
    let shadowed = profile(&build(true));
    // Floor x under each pixel centre of the row (pinhole, 1 spp = the centre).
    let frame = build(false).camera.frame(size, size);
    let floor_x: Vec<f64> = (0..size)
        .map(|x| {
            let r = frame.ray(x as f32 + 0.5, row as f32 + 0.5);
            (r.origin.x - r.dir.x * r.origin.y / r.dir.y) as f64
        })
        .collect();
    let visible: Vec<f64> = lit.iter().zip(&shadowed).map(|(l, s)| s / l).collect();
    // Crossings of 10% and 90% visibility, linearly interpolated.
    let crossing = |level: f64| {
        for i in 1..visible.len() {
            let (a, b) = (visible[i - 1], visible[i]);
            if (a - level) * (b - level) <= 0.0 && a != b {
                let t = (level - a) / (b - a);
                return floor_x[i - 1] + t * (floor_x[i] - floor_x[i - 1]);
            }
        }
        panic!("visibility never crosses {level}: {visible:?}");
    };
    // Visibility rises (nearly) linearly across the penumbra: 10%-90% is 0.8 of it.
    let measured = (crossing(0.9) - crossing(0.1)).abs() / 0.8;
    let expected = (w * h_o / (h_l - h_o)) as f64;
    assert!(
        (measured / expected - 1.0).abs() < 0.1,
        "penumbra {measured:.4}, similar triangles say {expected:.4}"
    );
    assert!(visible[2] < 0.01 && visible[size as usize - 3] > 0.99);
}

#[test]
fn a_scene_without_effects_pays_nothing_for_them() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene = packet_render::scene::load::load_scene(&dir.join("whitted.toml")).unwrap();
    let f = scene.features;
    assert!(!(f.area_lights || f.glossy || f.translucency || f.depth_of_field || f.motion));
    let mut plain = options(&scene, 24, 2);
    plain.max_depth = 8;
    let base = render(&scene, &plain);
    // Golden counts from the scene: one camera ray per pixel sample, at most one
    // shadow ray per light per primary or secondary hit, and no distributed rays.
    let r = base.rays;
    assert_eq!(r.camera, 24 * 24 * 2);
    assert!(r.shadow <= (r.camera + r.reflection + r.refraction) * scene.lights.len() as u64);
    assert_eq!((r.glossy, r.translucency), (0, 0));
    assert_eq!(base.samples_drawn.total(), 0);
    // Asking for many samples of effects the scene lacks changes nothing at all.
    let mut greedy = plain.clone();
    greedy.samples.shadow = 16;
    greedy.samples.glossy = 8;
    greedy.samples.lens = 4;
    greedy.samples.time = 4;
    let out = render(&scene, &greedy);
    assert_eq!(out.rays, base.rays);
    assert_eq!(out.film, base.film);
    assert_eq!(out.samples_drawn.total(), 0);
}

#[test]
fn sample_counts_multiply_as_documented() {
    let scene = everything();
    let mut o = options(&scene, 8, 3);
    o.samples.lens = 2;
    o.samples.time = 2;
    o.samples.shadow = 5;
    let out = render(&scene, &o);
    // camera rays = eye x lens x time per pixel
    assert_eq!(out.rays.camera, 64 * 3 * 2 * 2);
    assert_eq!(out.samples_drawn.lens, 64 * 3 * 2);
    assert_eq!(out.samples_drawn.time, 64 * 3 * 2 * 2);
    // light points come in sets of `shadow`
    assert_eq!(out.samples_drawn.light % 5, 0);
    assert!(out.rays.shadow <= out.samples_drawn.light);
}

#[test]
fn renders_are_identical_across_thread_counts() {
    let scene = everything();
    for sampler in SamplerKind::ALL {
        let mut o = options(&scene, 20, 2);
        o.sampler = *sampler;
        o.samples.glossy = 2;
        o.samples.shadow = 3;
        o.filter = packet_render::integrator::FilterKind::Gaussian;
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| render(&scene, &o))
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.film, b.film, "{sampler}");
        assert_eq!(a.rays, b.rays);
    }
}

#[test]
fn converge_report_has_every_strategy() {
    let scene = everything();
    let opts = packet_render::bench::converge::ConvergeOptions {
        width: 8,
        height: 8,
        reference_eye: 16,
        reference_shadow: 4,
        budgets: vec![1, 4],
        ..Default::default()
    };
    let report = packet_render::bench::converge::run(&scene, &opts, |_| {}).unwrap();
    // 5 patterns + 1xB + adaptive at 2 budgets, √Bx√B at both (1 and 4 are squares).
    assert_eq!(report.rows.len(), 8 * 2);
    assert!(
        report
            .rows
            .iter()
            .all(|r| r.rmse > 0.0 && r.eye * r.shadow == r.budget)
    );
    assert_eq!(report.slopes.len(), 8);
    assert!(report.table().contains("halton Bx1"));
    assert!(report.table().contains("sobol Bx1"));
    assert!(report.table().contains("adaptive sobol"));
}

#[test]
fn distribution_keys_have_located_errors() {
    let check =
        |text: &str, line: usize, needle: &str| match parse_toml_scene(text, Path::new("bad.toml"))
        {
            Err(packet_render::Error::Input { location, message }) => {
                assert_eq!(location.line, line, "{message}");
                assert!(message.contains(needle), "`{message}` lacks `{needle}`");
            }
            other => panic!("expected an error for {text:?}, got {other:?}"),
        };
    check("[camera]\naperture = -1\n", 2, "aperture");
    check("[camera]\nshutter = [1, 0]\n", 2, "shutter");
    check("[camera]\naperture_blades = 2\n", 2, "aperture_blades");
    check("[render]\nsamples = { eye = 2, shadow = 0 }\n", 2, "shadow");
    check("[render]\nspp = 4\nsamples = { eye = 2 }\n", 3, "disagree");
    check("[render]\nsamples = { eyes = 2 }\n", 2, "eyes");
    check("[[light]]\ntype = \"area\"\n", 2, "quad, disk, sphere");
    check(
        "[[light]]\ntype = \"disk\"\ncenter = [0, 1, 0]\nradius = 1\n",
        1,
        "radiance",
    );
    check(
        "[[light]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\nradiance = [1, 1, 1]\nnormal = [0, 1, 0]\n",
        6,
        "normal",
    );
    check("[materials.m]\ngloss_exponent = -3\n", 2, "gloss_exponent");
    check(
        "[materials.m]\ntranslucency_exponent = 10\n",
        2,
        "transmission",
    );
    check(
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nvelocity = [1, nan, 0]\n",
        4,
        "velocity",
    );
}
