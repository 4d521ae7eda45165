//! Image tests of the Whitted integrator: small scenes built in code whose answer is
//! known from geometry (a projected disc, a shadow, a mirror image, an inverted image
//! through a ball lens, total internal reflection in a prism), plus determinism and ray
//! counts. Brute force keeps the structure out of the question.

use glam::{DVec3, Vec3};
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::film::luminance;
use packet_render::geometry::Ray;
use packet_render::integrator::interaction::SurfaceInteraction;
use packet_render::integrator::optics::dielectric;
use packet_render::integrator::recursive;
use packet_render::integrator::{RenderOptions, RenderOutput};
use packet_render::scene::{Camera, Light, Material, Scene, SceneBuilder};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

fn options(scene: &Scene, width: u32, height: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.width = width;
    o.height = height;
    o.spp = 1;
    o.max_depth = 8;
    o.min_contribution = 1e-4;
    o
}

fn render(scene: &Scene, opts: &RenderOptions) -> RenderOutput {
    let accel = SceneAccel::build(scene, AccelKind::BruteForce);
    let out = recursive::render(scene, &accel, opts);
    assert_eq!(out.nonfinite_samples, 0, "numeric failure in the render");
    out
}

/// The ray through the centre of pixel `(x, y)`: what a 1-spp render traces, from the
/// textbook pinhole model in f64 and not from the renderer's camera code. The image
/// plane at distance 1 along the view direction spans `2 tan(fov / 2)` vertically and
/// `aspect` times that horizontally; +x of the image is `forward x up` (right-handed),
/// row 0 is at the top.
fn pixel_ray(scene: &Scene, opts: &RenderOptions, x: u32, y: u32) -> (DVec3, DVec3) {
    let c = &scene.camera;
    let eye = c.eye.as_dvec3();
    let forward = (c.target.as_dvec3() - eye).normalize();
    let right = forward.cross(c.up.as_dvec3()).normalize();
    let up = right.cross(forward);
    let half_h = (c.vfov_deg as f64 / 2.0).to_radians().tan();
    let half_w = half_h * opts.width as f64 / opts.height as f64;
    let u = (x as f64 + 0.5) / opts.width as f64; // 0 at the left edge, 1 at the right
    let v = (y as f64 + 0.5) / opts.height as f64; // 0 at the top edge, 1 at the bottom
    let d = forward + (2.0 * u - 1.0) * half_w * right + (1.0 - 2.0 * v) * half_h * up;
    (eye, d.normalize())
}

/// Nearest positive root of a ray/sphere test in f64: the analytic answer.
fn sphere_t(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<f64> {
    let f = o - c;
    let b = f.dot(d);
    let disc = b * b - (f.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    [-b - s, -b + s].into_iter().find(|&t| t > 0.0)
}

/// Distance along `d` to the plane `p[axis] = value`, if in front.
fn plane_t(o: DVec3, d: DVec3, axis: usize, value: f64) -> Option<f64> {
    let t = (value - o[axis]) / d[axis];
    (t > 0.0 && t.is_finite()).then_some(t)
}

fn emissive(name: &str, c: Vec3) -> Material {
    Material {
        name: name.into(),
        diffuse: Vec3::ZERO,
        emission: c,
        ..Default::default()
    }
}

fn camera(eye: Vec3, target: Vec3, vfov_deg: f32) -> Camera {
    Camera {
        eye,
        target,
        up: Vec3::Y,
        vfov_deg,
    }
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

// ---------------------------------------------------------------------------------
// Lit sphere: coverage and shadow
// ---------------------------------------------------------------------------------

#[test]
fn lit_sphere_covers_exactly_its_projected_disc() {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::diffuse("clay", Vec3::new(0.8, 0.3, 0.2)));
    b.add_sphere(Vec3::new(0.3, -0.2, 0.0), 1.0, m);
    b.add_light(Light::Directional {
        direction: Vec3::new(-0.3, -0.4, -1.0),
        irradiance: Vec3::splat(3.0),
    });
    b.ambient = Vec3::splat(0.05);
    b.camera = Some(camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 40.0));
    let scene = b.finish().unwrap();
    let opts = options(&scene, 48, 40);
    let film = render(&scene, &opts).film;

    let c = DVec3::new(0.3, -0.2, 0.0);
    let (mut inside, mut outside, mut boundary) = (0, 0, 0);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let (o, d) = pixel_ray(&scene, &opts, x, y);
            // A hair of margin either side: only pixels whose centre ray grazes the
            // silhouette within float noise are allowed to go either way.
            let surely_in = sphere_t(o, d, c, 1.0 - 1e-4).is_some();
            let surely_out = sphere_t(o, d, c, 1.0 + 1e-4).is_none();
            let covered = luminance(film.get(x, y)) > 1e-6;
            if surely_in {
                inside += 1;
                assert!(covered, "pixel ({x},{y}) should show the sphere");
            } else if surely_out {
                outside += 1;
                assert_eq!(
                    film.get(x, y),
                    Vec3::ZERO,
                    "pixel ({x},{y}) should be background"
                );
            } else {
                boundary += 1;
            }
        }
    }
    // The disc is about 11 px in radius: ~400 pixels, with at most a handful undecided.
    assert!(
        inside > 300 && outside > 1000,
        "inside {inside}, outside {outside}"
    );
    assert!(boundary <= 4, "{boundary} undecided pixels");
}

fn sphere_on_floor(light: Vec3) -> Scene {
    let mut b = SceneBuilder::new();
    let floor = b.add_material(Material::diffuse("floor", Vec3::splat(0.8)));
    let ball = b.add_material(Material::diffuse("ball", Vec3::new(0.2, 0.4, 0.8)));
    b.add_quad(
        Vec3::new(-8.0, 0.0, -8.0),
        Vec3::new(0.0, 0.0, 16.0),
        Vec3::new(16.0, 0.0, 0.0),
        floor,
    );
    b.add_sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, ball);
    b.add_light(Light::Point {
        position: light,
        intensity: Vec3::splat(200.0),
    });
    b.ambient = Vec3::splat(0.05);
    b.camera = Some(camera(
        Vec3::new(0.0, 4.0, 7.0),
        Vec3::new(-0.5, 0.3, 0.0),
        50.0,
    ));
    b.finish().unwrap()
}

#[test]
fn sphere_shadow_falls_where_geometry_says() {
    let light = Vec3::new(3.0, 4.0, 1.0);
    let scene = sphere_on_floor(light);
    let opts = options(&scene, 64, 48);
    let film = render(&scene, &opts).film;

    let c = DVec3::new(0.0, 1.0, 0.0);
    let l = light.as_dvec3();
    let ambient_only = Vec3::splat(0.05 * 0.8);
    let (mut dark, mut lit, mut near_lit) = (0, 0, 0);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let (o, d) = pixel_ray(&scene, &opts, x, y);
            let Some(t) = plane_t(o, d, 1, 0.0) else {
                continue;
            };
            let p = o + t * d;
            if p.x.abs() > 8.0
                || p.z.abs() > 8.0
                || sphere_t(o, d, c, 1.0 + 1e-4).is_some_and(|ts| ts < t)
            {
                continue; // off the floor, or the sphere is in front
            }
            let to_light = l - p;
            let dist = to_light.length();
            let w = to_light / dist;
            let blocked = |r: f64| sphere_t(p, w, c, r).is_some_and(|ts| ts < dist);
            let pixel = film.get(x, y);
            if blocked(1.0 - 1e-3) {
                dark += 1;
                assert!(
                    close(pixel, ambient_only, 1e-6),
                    "({x},{y}) in shadow: {pixel}"
                );
            } else if !blocked(1.0 + 1e-3) {
                lit += 1;
                // Lambert: ambient + albedo/π · I cosθ / r².
                let cos = w.y;
                let expect = 0.05 * 0.8 + 0.8 / std::f64::consts::PI * 200.0 * cos / (dist * dist);
                assert!(
                    (pixel.x as f64 - expect).abs() < 1e-4 * expect,
                    "({x},{y}) lit: {pixel}, expected {expect}"
                );
                if p.length() < 3.0 {
                    near_lit += 1;
                    assert!(
                        pixel.x > 5.0 * ambient_only.x,
                        "({x},{y}) lit floor near the ball is not bright"
                    );
                }
            }
        }
    }
    assert!(
        dark > 40 && lit > 800 && near_lit > 100,
        "dark {dark}, lit {lit} ({near_lit} near)"
    );
}

// ---------------------------------------------------------------------------------
// Mirror
// ---------------------------------------------------------------------------------

fn mirror_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let mirror = b.add_material(Material::mirror("mirror", Vec3::splat(0.9)));
    let red = b.add_material(emissive("red", Vec3::new(1.0, 0.0, 0.0)));
    b.add_quad(
        Vec3::new(-3.0, -3.0, -1.0),
        Vec3::new(6.0, 0.0, 0.0),
        Vec3::new(0.0, 6.0, 0.0),
        mirror,
    );
    // Behind the camera: visible only in the mirror.
    b.add_sphere(Vec3::new(0.8, 0.3, 9.0), 1.5, red);
    b.background = Vec3::new(0.0, 0.0, 0.3);
    b.camera = Some(camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 40.0));
    b.finish().unwrap()
}

#[test]
fn mirror_shows_the_sphere_behind_the_camera() {
    let scene = mirror_scene();
    let opts = options(&scene, 48, 48);
    let film = render(&scene, &opts).film;
    let c = DVec3::new(0.8, 0.3, 9.0);
    let (mut red, mut blue) = (0, 0);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let (o, d) = pixel_ray(&scene, &opts, x, y);
            let t = plane_t(o, d, 2, -1.0).unwrap();
            let p = o + t * d;
            assert!(
                p.x.abs() < 3.0 && p.y.abs() < 3.0,
                "the mirror fills the view"
            );
            let r = DVec3::new(d.x, d.y, -d.z);
            let pixel = film.get(x, y);
            if sphere_t(p, r, c, 1.5 - 1e-3).is_some() {
                red += 1;
                assert!(
                    close(pixel, Vec3::new(0.9, 0.0, 0.0), 1e-6),
                    "({x},{y}): {pixel}"
                );
            } else if sphere_t(p, r, c, 1.5 + 1e-3).is_none() {
                blue += 1;
                assert!(
                    close(pixel, Vec3::new(0.0, 0.0, 0.27), 1e-6),
                    "({x},{y}): {pixel}"
                );
            }
        }
    }
    // Angular radius asin(1.5/16) ≈ 5.4° in a 40° view: a disc of ~6.5 px radius.
    assert!(red > 80 && blue > 1500, "red {red}, blue {blue}");
}

// ---------------------------------------------------------------------------------
// Glass
// ---------------------------------------------------------------------------------

fn glass_ball_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let glass = b.add_material(Material::glass("glass", 1.5));
    let green = b.add_material(emissive("green", Vec3::new(0.0, 1.0, 0.0)));
    let blue = b.add_material(emissive("blue", Vec3::new(0.0, 0.0, 1.0)));
    b.add_sphere(Vec3::ZERO, 1.0, glass);
    // Backdrop: green above y = 0, blue below.
    b.add_quad(
        Vec3::new(-20.0, 0.0, -4.0),
        Vec3::new(40.0, 0.0, 0.0),
        Vec3::new(0.0, 20.0, 0.0),
        green,
    );
    b.add_quad(
        Vec3::new(-20.0, -20.0, -4.0),
        Vec3::new(40.0, 0.0, 0.0),
        Vec3::new(0.0, 20.0, 0.0),
        blue,
    );
    b.camera = Some(camera(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 30.0));
    b.finish().unwrap()
}

#[test]
fn glass_ball_inverts_the_backdrop() {
    // A ball lens (f = nR / 2(n-1) = 1.5 from its centre) images the camera 2.1 units
    // behind itself, in front of the backdrop: rays cross the axis before they land, so
    // the top of the ball shows the bottom colour.
    let scene = glass_ball_scene();
    let opts = options(&scene, 48, 48);
    let film = render(&scene, &opts).film;
    let (mut flipped, mut direct) = (0, 0);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let (o, d) = pixel_ray(&scene, &opts, x, y);
            // Distance of the ray line from the ball's centre: away from the rim, and off
            // the horizon row, the answer does not hang on rounding.
            let impact = o.cross(d).length();
            let pixel = film.get(x, y);
            if d.y.abs() < 0.01 {
                continue;
            }
            // The colour of the half the ray points at, and of the other half.
            let (same, opposite) = if d.y > 0.0 {
                (pixel.y, pixel.z)
            } else {
                (pixel.z, pixel.y)
            };
            if impact < 0.6 {
                flipped += 1;
                assert!(
                    opposite > 0.7 && same < 0.1 * opposite,
                    "({x},{y}) through the ball: {pixel}"
                );
            } else if impact > 1.001 {
                direct += 1;
                assert!(
                    same == 1.0 && opposite == 0.0 && pixel.x == 0.0,
                    "({x},{y}) beside the ball: {pixel}"
                );
            }
        }
    }
    assert!(
        flipped > 150 && direct > 1000,
        "flipped {flipped}, direct {direct}"
    );
}

#[test]
fn dielectric_obeys_snell_fresnel_and_tir() {
    let n = Vec3::Z;
    // Incident direction at angle θ from the normal, coming down onto the surface.
    let incident = |deg: f32| {
        let t = deg.to_radians();
        Vec3::new(t.sin(), 0.0, -t.cos())
    };
    let sin_of = |v: Vec3| v.cross(n).length();
    let ior = 1.5f32;
    let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);

    // Normal incidence: F0 either way, no bending.
    for (ei, et) in [(1.0, ior), (ior, 1.0)] {
        let s = dielectric(-n, n, ei, et);
        assert!((s.reflectance - f0).abs() < 1e-6, "{s:?}");
        assert!(close(s.refracted.unwrap(), -n, 1e-6));
    }
    // Grazing from outside: everything reflects.
    assert!(dielectric(incident(89.9), n, 1.0, ior).reflectance > 0.99);

    // From inside: refraction below the critical angle, TIR above it.
    let critical = (1.0 / ior).asin().to_degrees();
    for deg in [0.0, 10.0, 30.0, critical - 0.5] {
        let d = incident(deg);
        let s = dielectric(d, n, ior, 1.0);
        let t = s
            .refracted
            .unwrap_or_else(|| panic!("{deg}°: no refraction below the critical angle"));
        assert!((sin_of(t) - ior * sin_of(d)).abs() < 1e-4, "{deg}°: Snell");
        assert!(t.z < 0.0 && (t.length() - 1.0).abs() < 1e-6);
        assert!((0.0..1.0).contains(&s.reflectance), "{deg}°: {s:?}");
    }
    for deg in [critical + 0.5, 45.0, 60.0, 89.0] {
        let s = dielectric(incident(deg), n, ior, 1.0);
        assert_eq!(
            (s.reflectance, s.refracted),
            (1.0, None),
            "{deg}°: expected TIR"
        );
    }
    // Schlick fed the transmitted cosine goes smoothly to 1 at the critical angle,
    // instead of jumping from ~0.1 to 1.
    assert!(dielectric(incident(critical - 0.05), n, ior, 1.0).reflectance > 0.7);

    // From outside, Snell the other way, and Fresnel never leaves [0, 1].
    for step in 0..=90 {
        let d = incident(step as f32 * 0.999);
        for (ei, et) in [(1.0, ior), (ior, 1.0), (1.0, 2.4)] {
            let s = dielectric(d, n, ei, et);
            assert!((0.0..=1.0).contains(&s.reflectance));
            if let Some(t) = s.refracted {
                assert!((et * sin_of(t) - ei * sin_of(d)).abs() < 1e-4);
            }
        }
    }

    // Index-matched: no interface at all.
    for deg in [0.0, 40.0, 80.0] {
        let d = incident(deg);
        let s = dielectric(d, n, 1.0, 1.0);
        assert_eq!((s.reflectance, s.refracted), (0.0, Some(d)));
    }
}

/// A right-angle glass prism (legs on z = 0 and x = 1, hypotenuse x + z = -1, extruded
/// over y in [-1, 1]) seen head-on, a red wall to its right and a green wall behind.
/// A camera ray enters the front leg at normal incidence and meets the hypotenuse at
/// 45°: past the critical angle for ior 1.5 (41.8°), so it turns 90° towards the red
/// wall; for ior 1.2 (56.4°) it passes on to the green one.
fn prism_scene(ior: f32) -> Scene {
    let mut b = SceneBuilder::new();
    let glass = b.add_material(Material::glass("prism", ior));
    let red = b.add_material(emissive("red", Vec3::new(1.0, 0.0, 0.0)));
    let green = b.add_material(emissive("green", Vec3::new(0.0, 1.0, 0.0)));
    let corners = [(-1.0, 0.0), (1.0, 0.0), (1.0, -2.0)];
    let v = |i: usize, y: f32| Vec3::new(corners[i].0, y, corners[i].1);
    let interior = Vec3::new(1.0 / 3.0, 0.0, -2.0 / 3.0);
    // Outward winding matters: it tells the integrator whether a ray enters or leaves.
    let mut tri = |a: Vec3, bb: Vec3, c: Vec3| {
        let outward = (bb - a).cross(c - a).dot(a - interior) > 0.0;
        if outward {
            b.add_triangle(a, bb, c, glass);
        } else {
            b.add_triangle(a, c, bb, glass);
        }
    };
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        tri(v(i, -1.0), v(j, -1.0), v(j, 1.0));
        tri(v(i, -1.0), v(j, 1.0), v(i, 1.0));
    }
    tri(v(0, 1.0), v(1, 1.0), v(2, 1.0));
    tri(v(0, -1.0), v(1, -1.0), v(2, -1.0));
    b.add_quad(
        Vec3::new(3.0, -5.0, -8.0),
        Vec3::new(0.0, 10.0, 0.0),
        Vec3::new(0.0, 0.0, 12.0),
        red,
    );
    b.add_quad(
        Vec3::new(-30.0, -30.0, -8.0),
        Vec3::new(60.0, 0.0, 0.0),
        Vec3::new(0.0, 60.0, 0.0),
        green,
    );
    b.camera = Some(camera(Vec3::new(0.0, 0.0, 20.0), Vec3::ZERO, 8.0));
    b.finish().unwrap()
}

#[test]
fn prism_totally_reflects_past_the_critical_angle() {
    for (ior, tir) in [(1.5, true), (1.2, false)] {
        let scene = prism_scene(ior);
        let opts = options(&scene, 32, 32);
        let out = render(&scene, &opts);
        let mut through = 0;
        for y in 0..opts.height {
            for x in 0..opts.width {
                let (o, d) = pixel_ray(&scene, &opts, x, y);
                let p = o + plane_t(o, d, 2, 0.0).unwrap() * d;
                if p.x.abs() > 0.9 || p.y.abs() > 0.9 {
                    continue;
                }
                through += 1;
                let pixel = out.film.get(x, y);
                let (seen, other) = if tir {
                    (pixel.x, pixel.y)
                } else {
                    (pixel.y, pixel.x)
                };
                // Two interfaces at ~4% loss each (ior 1.5) leave ~0.92.
                assert!(seen > 0.85 && other < 0.05, "ior {ior}, ({x},{y}): {pixel}");
            }
        }
        assert!(through > 300, "{through} pixels through the prism");
        assert!(out.rays.refraction > 0);
    }
}

// ---------------------------------------------------------------------------------
// Determinism, progress, robustness
// ---------------------------------------------------------------------------------

/// Glass, mirror, diffuse and shadows together, at a size that leaves partial tiles.
fn busy_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let glass = b.add_material(Material::glass("glass", 1.5));
    let mirror = b.add_material(Material::mirror("mirror", Vec3::splat(0.8)));
    let floor = b.add_material(Material {
        checker: Some(packet_render::scene::Checker {
            color_a: Vec3::splat(0.9),
            color_b: Vec3::new(0.2, 0.3, 0.6),
            scale: 0.5,
        }),
        specular: Vec3::splat(0.3),
        ..Material::diffuse("floor", Vec3::ONE)
    });
    b.add_quad(
        Vec3::new(-5.0, 0.0, -5.0),
        Vec3::new(0.0, 0.0, 10.0),
        Vec3::new(10.0, 0.0, 0.0),
        floor,
    );
    b.add_quad(
        Vec3::new(-3.0, 0.0, -2.0),
        Vec3::new(6.0, 0.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
        mirror,
    );
    b.add_sphere(Vec3::new(-0.6, 0.7, 0.5), 0.7, glass);
    b.add_sphere(Vec3::new(0.9, 0.5, 0.0), 0.5, floor);
    b.add_light(Light::Point {
        position: Vec3::new(2.0, 4.0, 3.0),
        intensity: Vec3::splat(60.0),
    });
    b.add_light(Light::Directional {
        direction: Vec3::new(0.2, -1.0, -0.3),
        irradiance: Vec3::splat(0.5),
    });
    b.ambient = Vec3::splat(0.05);
    b.background = Vec3::new(0.3, 0.4, 0.5);
    b.camera = Some(camera(
        Vec3::new(0.0, 1.5, 5.0),
        Vec3::new(0.0, 0.6, 0.0),
        45.0,
    ));
    b.finish().unwrap()
}

fn bits(out: &RenderOutput) -> Vec<[u32; 3]> {
    out.film
        .pixels
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn images_are_bit_identical_across_thread_counts_and_runs() {
    let scene = busy_scene();
    let mut opts = options(&scene, 40, 36);
    opts.seed = 7;
    for spp in [1, 4, 3] {
        opts.spp = spp;
        let in_pool = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| render(&scene, &opts))
        };
        let one = in_pool(1);
        let three = in_pool(3);
        assert_eq!(bits(&one), bits(&three), "spp {spp}: 1 vs 3 threads");
        assert_eq!(one.rays, three.rays);
        assert_eq!(bits(&one), bits(&render(&scene, &opts)), "spp {spp}: rerun");
        if spp > 1 {
            // The seed is actually used: another one jitters differently.
            let mut other = opts.clone();
            other.seed = 8;
            assert_ne!(
                bits(&one),
                bits(&render(&scene, &other)),
                "spp {spp}: seed ignored"
            );
        }
    }
}

#[test]
fn progress_reports_every_tile_once() {
    let scene = busy_scene();
    let mut opts = options(&scene, 72, 66);
    let calls = Arc::new(AtomicU64::new(0));
    let last_total = Arc::new(AtomicU64::new(0));
    let max_done = Arc::new(AtomicU64::new(0));
    let (c, t, m) = (calls.clone(), last_total.clone(), max_done.clone());
    opts.progress = Some(Arc::new(move |done, total| {
        c.fetch_add(1, Ordering::Relaxed);
        t.store(total, Ordering::Relaxed);
        m.fetch_max(done, Ordering::Relaxed);
    }));
    render(&scene, &opts);
    // 72x66 in 32x32 tiles: 3 x 3.
    assert_eq!(calls.load(Ordering::Relaxed), 9);
    assert_eq!(last_total.load(Ordering::Relaxed), 9);
    assert_eq!(max_done.load(Ordering::Relaxed), 9);
}

#[test]
fn nonfinite_samples_are_counted_and_black() {
    // Two lights of f32::MAX intensity a unit away overflow the sum to infinity.
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::diffuse("white", Vec3::ONE));
    b.add_sphere(Vec3::ZERO, 1.0, m);
    for x in [-0.5, 0.5] {
        b.add_light(Light::Point {
            position: Vec3::new(x, 0.0, 1.5),
            intensity: Vec3::splat(f32::MAX),
        });
    }
    b.background = Vec3::splat(0.1);
    b.ambient = Vec3::splat(0.1);
    b.camera = Some(camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 40.0));
    let scene = b.finish().unwrap();
    let opts = options(&scene, 24, 24);
    let accel = SceneAccel::build(&scene, AccelKind::BruteForce);
    let out = recursive::render(&scene, &accel, &opts);
    assert!(out.nonfinite_samples > 0);
    assert!(out.film.pixels.iter().all(|p| p.is_finite()));
    // At 1 spp each non-finite sample is one black pixel; nothing else here is black.
    let black = out.film.pixels.iter().filter(|p| **p == Vec3::ZERO).count() as u64;
    assert_eq!(black, out.nonfinite_samples);
}

// ---------------------------------------------------------------------------------
// Ray counts
// ---------------------------------------------------------------------------------

#[test]
fn ray_counts_match_what_the_scene_contains() {
    // One point light, no mirror, no glass.
    let scene = sphere_on_floor(Vec3::new(3.0, 4.0, 1.0));
    let opts = options(&scene, 32, 24);
    let out = render(&scene, &opts);
    let accel = SceneAccel::build(&scene, AccelKind::BruteForce);
    let frame = scene.camera.frame(opts.width, opts.height);
    let camera_hits = (0..opts.height)
        .flat_map(|y| (0..opts.width).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            accel
                .closest_hit(&frame.ray(x as f32 + 0.5, y as f32 + 0.5))
                .is_some()
        })
        .count() as u64;
    assert_eq!(out.rays.camera, 32 * 24);
    assert!(camera_hits > 0 && out.rays.shadow > 0);
    assert!(
        out.rays.shadow <= camera_hits,
        "{:?}, {camera_hits} hits",
        out.rays
    );
    assert_eq!((out.rays.reflection, out.rays.refraction), (0, 0));

    // A mirror but no glass: reflections, no refraction.
    let scene = mirror_scene();
    let out = render(&scene, &options(&scene, 16, 16));
    assert!(out.rays.reflection > 0);
    assert_eq!(out.rays.refraction, 0);

    // Depth 0 traces camera and shadow rays only, whatever the materials.
    let scene = busy_scene();
    let mut opts = options(&scene, 20, 20);
    opts.spp = 4;
    let deep = render(&scene, &opts).rays;
    assert!(
        deep.reflection > 0 && deep.refraction > 0 && deep.shadow > 0,
        "{deep:?}"
    );
    opts.max_depth = 0;
    let flat = render(&scene, &opts).rays;
    assert_eq!(flat.camera, 20 * 20 * 4);
    assert_eq!((flat.reflection, flat.refraction), (0, 0), "{flat:?}");
    assert!(flat.shadow > 0);
}

#[test]
fn contribution_cutoff_prunes_weak_branches() {
    let scene = busy_scene();
    let mut opts = options(&scene, 20, 20);
    opts.min_contribution = 0.0;
    let all = render(&scene, &opts).rays;
    // Fresnel reflection off glass weighs ~4-10%: a cutoff above that drops it.
    opts.min_contribution = 0.5;
    let pruned = render(&scene, &opts).rays;
    assert_eq!(pruned.camera, all.camera);
    assert!(
        pruned.reflection + pruned.refraction < all.reflection + all.refraction,
        "{pruned:?} vs {all:?}"
    );
}

/// Keeps the helper honest: the f64 pinhole model of `pixel_ray` and the renderer's f32
/// camera give the same ray for every pixel of a non-square image with a tilted view
/// (the mirror scene's camera), so the analytic answers of the other tests are about
/// the rays the renderer traces. Tolerance 1e-6 on unit directions: the f32 camera
/// rounds each of its few operations to 6e-8, and a wrong aspect, flipped axis or
/// half-pixel offset moves a direction by 1e-2 or more.
#[test]
fn pixel_ray_helper_matches_the_camera() {
    let scene = mirror_scene();
    let opts = options(&scene, 12, 7);
    let frame = scene.camera.frame(opts.width, opts.height);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let (o, d) = pixel_ray(&scene, &opts, x, y);
            let r: Ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
            assert_eq!(o, r.origin.as_dvec3());
            assert!(
                (d - r.dir.as_dvec3()).length() < 1e-6,
                "pixel ({x}, {y}): model {d}, camera {}",
                r.dir
            );
        }
    }
}

/// The camera against facts that need no formula: the centre ray looks at the target;
/// the rays through the middles of the top and bottom edges are `fov` apart and those
/// through the left and right edges `2 atan(aspect tan(fov / 2))` apart; the top edge
/// leans towards `up` and the right edge towards `forward x up`. And in a render, a
/// small emissive sphere up and to the right of the target (as seen from the eye)
/// lands in the top-right quadrant of a wide image.
#[test]
fn camera_orientation_fov_and_aspect() {
    let cam = camera(Vec3::new(1.0, 2.0, 6.0), Vec3::new(0.0, 1.0, 0.0), 50.0);
    let (w, h) = (160u32, 90u32);
    let f = cam.frame(w, h);
    let dir = |px: f32, py: f32| f.ray(px, py).dir.as_dvec3();
    let forward = (cam.target - cam.eye).as_dvec3().normalize();
    let right = forward.cross(DVec3::Y).normalize();
    let angle = |a: DVec3, b: DVec3| a.dot(b).clamp(-1.0, 1.0).acos().to_degrees();
    // Angles to 1e-3 degrees: f32 directions are good to ~1e-7 rad = 6e-6 degrees.
    assert!(angle(dir(80.0, 45.0), forward) < 1e-3);
    let vfov = angle(dir(80.0, 0.0), dir(80.0, 90.0));
    assert!((vfov - 50.0).abs() < 1e-3, "vertical fov {vfov}");
    let hfov = angle(dir(0.0, 45.0), dir(160.0, 45.0));
    let expect = 2.0
        * (16.0f64 / 9.0 * 25f64.to_radians().tan())
            .atan()
            .to_degrees();
    assert!(
        (hfov - expect).abs() < 1e-3,
        "horizontal fov {hfov} vs {expect}"
    );
    assert!(
        dir(80.0, 0.0).y > forward.y,
        "top of the image must look up"
    );
    assert!(
        dir(160.0, 45.0).dot(right) > 0.0,
        "right of the image must look right"
    );
    assert!(dir(0.0, 45.0).dot(right) < 0.0);

    let mut b = SceneBuilder::new();
    let m = b.add_material(emissive("lamp", Vec3::ONE));
    let up = right.cross(forward);
    let p = cam.target.as_dvec3() + 0.8 * right + 0.5 * up;
    b.add_sphere(p.as_vec3(), 0.15, m);
    b.camera = Some(cam);
    let scene = b.finish().unwrap();
    let opts = options(&scene, w, h);
    let film = render(&scene, &opts).film;
    let lit: Vec<(u32, u32)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| film.get(x, y) != Vec3::ZERO)
        .collect();
    assert!(!lit.is_empty(), "the sphere is not in the image");
    assert!(
        lit.iter().all(|&(x, y)| x > w / 2 && y < h / 2),
        "sphere outside the top-right quadrant: {:?}",
        &lit[..lit.len().min(5)]
    );
}

// ---------------------------------------------------------------------------------
// Solid checkerboard on a cell boundary
// ---------------------------------------------------------------------------------

/// A quad lying exactly on a checker cell boundary (a floor at y = 1 and a wall at
/// z = -1 with cells of 0.5) must show one cell per checker square, not the
/// salt-and-pepper of `floor(p / scale)` flipping on the rounding of the hit point.
/// The expected colour of every pixel is computed in f64 from the analytic hit point,
/// taking the cell just inside the surface (against its winding normal); pixels whose
/// hit point lies within 1e-3 of a boundary *across* the surface (a checker edge seen
/// in the image) are skipped, which is well above the f32 error of the hit point (a few
/// 1e-7 at this scale) and still leaves thousands of pixels decided.
#[test]
fn checker_on_a_cell_boundary_has_no_speckle() {
    let (a, b) = (Vec3::new(0.9, 0.9, 0.9), Vec3::new(0.1, 0.1, 0.5));
    let checker = Material {
        name: "checker".into(),
        checker: Some(packet_render::scene::Checker {
            color_a: a,
            color_b: b,
            scale: 0.5,
        }),
        ..Default::default()
    };
    // (axis of the normal, plane value, corner, e1, e2, camera eye, target); e1 x e2 is
    // the winding normal, +y for the floor and +z for the wall.
    let cases = [
        (
            1usize,
            1.0f32,
            Vec3::new(-6.0, 1.0, -6.0),
            Vec3::new(0.0, 0.0, 12.0),
            Vec3::new(12.0, 0.0, 0.0),
            Vec3::new(0.3, 4.0, 3.0),
            Vec3::new(0.1, 1.0, -0.5),
        ),
        (
            2,
            -1.0,
            Vec3::new(-6.0, -6.0, -1.0),
            Vec3::new(12.0, 0.0, 0.0),
            Vec3::new(0.0, 12.0, 0.0),
            Vec3::new(0.4, 0.7, 3.0),
            Vec3::new(0.2, 0.3, -1.0),
        ),
    ];
    for (axis, value, corner, e1, e2, eye, target) in cases {
        let mut sb = SceneBuilder::new();
        let m = sb.add_material(checker.clone());
        sb.add_quad(corner, e1, e2, m);
        // Ambient light only: every pixel is exactly its albedo.
        sb.ambient = Vec3::ONE;
        sb.camera = Some(camera(eye, target, 60.0));
        let scene = sb.finish().unwrap();
        let opts = options(&scene, 64, 48);
        let film = render(&scene, &opts).film;
        let (mut checked, mut wrong) = (0, 0);
        for y in 0..opts.height {
            for x in 0..opts.width {
                let (o, d) = pixel_ray(&scene, &opts, x, y);
                let Some(t) = plane_t(o, d, axis, value as f64) else {
                    continue;
                };
                let p = (o + t * d) / 0.5;
                let near_edge = (0..3)
                    .filter(|&k| k != axis)
                    .any(|k| (p[k] - p[k].round()).abs() < 2e-3);
                if near_edge || p.abs().max_element() > 11.0 {
                    continue;
                }
                // Inside the surface: just below the plane along its normal.
                let mut q = p.floor();
                q[axis] = p[axis].round() - 1.0;
                let parity = (q.x + q.y + q.z).rem_euclid(2.0);
                let expected = if parity == 0.0 { a } else { b };
                checked += 1;
                if film.get(x, y) != expected {
                    wrong += 1;
                }
            }
        }
        assert!(checked > 2000, "axis {axis}: only {checked} pixels decided");
        assert_eq!(
            wrong, 0,
            "axis {axis}: {wrong} of {checked} pixels show the other cell's colour"
        );
    }
}

// ---------------------------------------------------------------------------------
// Shadow terminator on a coarse mesh with vertex normals
// ---------------------------------------------------------------------------------

/// Fraction of the lit-side pixels of a smooth-shaded 8 x 6 UV sphere (exact sphere
/// normals at the vertices) that come out shadowed, lit from the side by a directional
/// light. Lit side: the shading normal faces the light (`n_s · l > 0.1`), whichever
/// way the flat facet under it faces. Shadowed: the pixel is below half the unoccluded
/// Lambert value `albedo / π · (n_s · l) · E` the shader would give it — nothing else
/// is in the scene, so only the sphere's own facets can block the light.
fn terminator_shadowed_fraction() -> (usize, usize) {
    let mut b = SceneBuilder::new();
    let albedo = Vec3::splat(0.8);
    let m = b.add_material(Material::diffuse("clay", albedo));
    packet_render::scene::procedural::low_poly_sphere(&mut b, 8, 6, Vec3::ZERO, 1.0, m);
    let dir = Vec3::new(-1.0, -0.25, -0.35);
    let e = 3.0;
    b.add_light(Light::Directional {
        direction: dir,
        irradiance: Vec3::splat(e),
    });
    b.camera = Some(camera(Vec3::new(0.6, 0.3, 4.0), Vec3::ZERO, 40.0));
    let scene = b.finish().unwrap();
    let opts = options(&scene, 96, 96);
    let film = render(&scene, &opts).film;
    let accel = SceneAccel::build(&scene, AccelKind::BruteForce);
    let l = -dir.normalize();
    let (mut lit, mut shadowed) = (0, 0);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let ray = scene
                .camera
                .frame(opts.width, opts.height)
                .ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(hit) = accel.closest_hit(&ray) else {
                continue;
            };
            let si = SurfaceInteraction::new(&scene, &ray, &hit);
            let cos = si.n_shading.dot(l);
            if cos <= 0.1 {
                continue;
            }
            lit += 1;
            let unoccluded = albedo.x * std::f32::consts::FRAC_1_PI * cos * e;
            if film.get(x, y).x < 0.5 * unoccluded {
                shadowed += 1;
            }
        }
    }
    (lit, shadowed)
}

/// Hanika's shadow-ray origin (RTG II ch. 4) removes the faceted self-shadowing of a
/// low-polygon mesh with vertex normals: none of the lit-side pixels is shadowed (with
/// shadow rays from the flat facets and lights below a facet dropped, 107 of 2400 were).
#[test]
fn low_poly_smooth_sphere_does_not_shadow_its_lit_side() {
    let (lit, shadowed) = terminator_shadowed_fraction();
    assert!(lit > 1500, "only {lit} lit-side pixels");
    assert_eq!(
        shadowed, 0,
        "{shadowed} of {lit} lit-side pixels are shadowed by the mesh's own facets"
    );
}

// ---------------------------------------------------------------------------------
// Orthographic camera
// ---------------------------------------------------------------------------------

/// An orthographic camera (`CameraEffects::ortho_height`) images a sphere of radius r
/// as a disc of radius `r / height * image_height` pixels wherever it is, with no
/// perspective shrinking or stretching: here an off-axis sphere twice as far as a
/// centred one, both radius 0.5, image height 4 world units over 64 pixels: 8 px.
#[test]
fn orthographic_sphere_is_a_disc_of_the_right_pixel_radius() {
    let mut b = SceneBuilder::new();
    let m = b.add_material(emissive("white", Vec3::ONE));
    // centred sphere and an off-axis one further back
    let spheres = [
        (Vec3::ZERO, (32.0, 32.0)),
        (Vec3::new(-0.75, 0.5, -5.0), (20.0, 24.0)),
    ];
    for (c, _) in spheres {
        b.add_sphere(c, 0.5, m);
    }
    b.camera = Some(camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 45.0));
    b.camera_effects.ortho_height = Some(4.0);
    let scene = b.finish().unwrap();
    let opts = options(&scene, 64, 64);
    let film = render(&scene, &opts).film;
    // radius 0.5 / height 4 * 64 px = 8 px; centres: (0,0) -> (32,32) and
    // (-0.75, 0.5) -> (32 - 12, 32 - 8)
    let radius = 8.0f64;
    let (mut inside, mut outside) = ([0; 2], 0);
    for y in 0..64 {
        for x in 0..64 {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let dist = |k: usize| {
                let (cx, cy) = spheres[k].1;
                ((px - cx).powi(2) + (py - cy).powi(2)).sqrt()
            };
            let covered = film.get(x, y) != Vec3::ZERO;
            // 0.01 px margin: the f32 ray origins are within ~1e-6 world units
            // (2.5e-4 px at 16 px per unit) of the exact ones
            for (k, n) in inside.iter_mut().enumerate() {
                if dist(k) < radius - 0.01 {
                    *n += 1;
                    assert!(covered, "pixel ({x},{y}) should show sphere {k}");
                }
            }
            if dist(0) > radius + 0.01 && dist(1) > radius + 0.01 {
                outside += 1;
                assert!(!covered, "pixel ({x},{y}) should be background");
            }
        }
    }
    // pi 8^2 = 201 pixel centres per disc (the two overlap in part); a perspective
    // camera would shrink the far one
    assert!(inside[0] > 190 && inside[1] > 190, "{inside:?}");
    assert!(outside > 3500, "{outside}");
}

// ---------------------------------------------------------------------------------
// Spot light
// ---------------------------------------------------------------------------------

/// A spot light 2 above a floor, pointing straight down, seen from above by an
/// orthographic camera (64 px over 4 units: 16 px per unit). The lit pool has the
/// radius 2 tan(cone) exactly (hard edge), and with a smooth edge every pixel is the
/// hard-edged one scaled by pbrt-v4's smoothstep of its cos θ.
#[test]
fn spot_light_lights_a_disc_with_pbrt_falloff() {
    let cone = 30f32;
    let render_spot = |falloff: f32| {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::diffuse("floor", Vec3::splat(0.8)));
        b.add_quad(
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(0.0, 0.0, 8.0),
            Vec3::new(8.0, 0.0, 0.0),
            m,
        );
        b.add_light(Light::Spot {
            position: Vec3::new(0.0, 2.0, 0.0),
            direction: Vec3::NEG_Y,
            intensity: Vec3::splat(10.0),
            cos_total: cone.to_radians().cos(),
            cos_falloff_start: (cone - falloff).to_radians().cos(),
        });
        let mut c = camera(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, 45.0);
        c.up = Vec3::NEG_Z;
        b.camera = Some(c);
        b.camera_effects.ortho_height = Some(4.0);
        let scene = b.finish().unwrap();
        let opts = options(&scene, 64, 64);
        render(&scene, &opts).film
    };
    let hard = render_spot(0.0);
    let smooth = render_spot(10.0);
    let radius_px = 2.0 * (cone as f64).to_radians().tan() * 16.0; // 18.48 px
    let (mut lit, mut dark, mut partial) = (0, 0, 0);
    for y in 0..64 {
        for x in 0..64 {
            let (dx, dy) = (x as f64 + 0.5 - 32.0, y as f64 + 0.5 - 32.0);
            let r = (dx * dx + dy * dy).sqrt();
            let h = hard.get(x, y);
            // 0.01 px margin at 16 px per unit: float noise in the hit point only
            if r < radius_px - 0.01 {
                lit += 1;
                assert!(h.x > 0.0, "({x},{y}) inside the cone is dark");
            } else if r > radius_px + 0.01 {
                dark += 1;
                assert_eq!(h, Vec3::ZERO, "({x},{y}) outside the cone is lit");
                assert_eq!(smooth.get(x, y), Vec3::ZERO);
            }
            if r < radius_px - 0.01 {
                // cos θ of the floor point seen from the light, in f64
                let cos = 2.0 / (4.0 + (r / 16.0).powi(2)).sqrt();
                let (ct, cs) = (
                    (cone as f64).to_radians().cos(),
                    ((cone - 10.0) as f64).to_radians().cos(),
                );
                let t = ((cos - ct) / (cs - ct)).clamp(0.0, 1.0);
                let want = if cos >= cs {
                    1.0
                } else {
                    t * t * (3.0 - 2.0 * t)
                };
                let got = (smooth.get(x, y).x / h.x) as f64;
                if want < 1.0 && want > 0.0 {
                    partial += 1;
                }
                // 1e-3: f32 cos θ near the edge (t's denominator is ~0.07) against f64
                assert!((got - want).abs() < 1e-3, "({x},{y}): {got} vs {want}");
            }
        }
    }
    // pi 18.48^2 = 1073 lit pixel centres; the 20..30 degree ring holds ~600 of them
    assert!(
        lit > 1000 && dark > 2900 && partial > 400,
        "{lit} {dark} {partial}"
    );
}
