//! Transmitted shadows (`integrator::shadow`): shadow rays through glass are filtered
//! by its transmission, once per surface crossed; an opaque surface still blocks. Every
//! case runs on both integrators and every acceleration structure.
//!
//! The scene: a diffuse floor lit by a directional light from straight above, ambient
//! zero, and objects stacked above the origin. A camera below the objects (y = 0.45;
//! they start at y = 0.5) looks down at the origin through a 2 degree field of view, so
//! every pixel sees the floor directly within 0.05 of the origin, and every shadow ray
//! goes straight up through the objects' middles.

use glam::Vec3;
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::integrator::{IntegratorKind, RenderOptions, RenderOutput};
use packet_render::scene::load::parse_toml_scene;
use packet_render::scene::{Camera, Light, Material, Scene, SceneBuilder};

const SIZE: u32 = 4;

/// What sits above the floor.
#[derive(Clone, Copy)]
enum Above {
    Nothing,
    /// A glass sphere of this transmission and ior at height 1, radius 0.5.
    GlassSphere(Vec3, f32),
    /// A single glass quad (two triangles) of this transmission at height 1.
    GlassPane(Vec3),
    /// A clear glass sphere at height 1 and an opaque one at 2.2, or (`true`) the other
    /// way round.
    OpaqueAndGlass(bool),
}

fn glass(transmission: Vec3, ior: f32) -> Material {
    Material {
        name: "glass".into(),
        diffuse: Vec3::ZERO,
        transmission,
        ior,
        ..Default::default()
    }
}

fn scene(above: Above, transmitted: bool) -> Scene {
    let mut b = SceneBuilder::new();
    let floor = b.add_material(Material::diffuse("floor", Vec3::splat(0.8)));
    b.add_quad(
        Vec3::new(-8.0, 0.0, -8.0),
        Vec3::new(0.0, 0.0, 16.0),
        Vec3::new(16.0, 0.0, 0.0),
        floor,
    );
    let low = Vec3::new(0.0, 1.0, 0.0);
    let high = Vec3::new(0.0, 2.2, 0.0);
    match above {
        Above::Nothing => {}
        Above::GlassSphere(t, ior) => {
            let m = b.add_material(glass(t, ior));
            b.add_sphere(low, 0.5, m);
        }
        Above::GlassPane(t) => {
            let m = b.add_material(glass(t, 1.5));
            // The shared diagonal (x + z = 1) keeps clear of the shadow rays.
            b.add_quad(
                Vec3::new(-0.3, 1.0, -0.7),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 2.0),
                m,
            );
        }
        Above::OpaqueAndGlass(opaque_below) => {
            let g = b.add_material(glass(Vec3::ONE, 1.0));
            let o = b.add_material(Material::diffuse("opaque", Vec3::splat(0.5)));
            let (og, oo) = if opaque_below {
                (high, low)
            } else {
                (low, high)
            };
            b.add_sphere(og, 0.5, g);
            b.add_sphere(oo, 0.5, o);
        }
    }
    b.add_light(Light::Directional {
        direction: -Vec3::Y,
        irradiance: Vec3::splat(3.0),
    });
    b.ambient = Vec3::ZERO;
    b.background = Vec3::splat(0.3);
    b.camera = Some(Camera {
        eye: Vec3::new(0.0, 0.45, 1.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        vfov_deg: 2.0,
    });
    b.settings.transmitted_shadows = transmitted;
    b.finish().unwrap()
}

fn render(scene: &Scene, integrator: IntegratorKind, accel: AccelKind) -> RenderOutput {
    let mut o = RenderOptions::from_scene(scene);
    o.width = SIZE;
    o.height = SIZE;
    o.spp = 1;
    let accel = SceneAccel::build(scene, accel);
    integrator.render(scene, &accel, &o)
}

fn pixels(out: &RenderOutput) -> Vec<Vec3> {
    (0..SIZE * SIZE)
        .map(|i| out.film.get(i % SIZE, i / SIZE))
        .collect()
}

/// Runs `check(integrator, accel, lit floor, render of the scene)` for every integrator
/// and structure.
fn for_each_render(above: Above, transmitted: bool, check: impl Fn(&str, &[Vec3], &RenderOutput)) {
    let lit = scene(Above::Nothing, transmitted);
    let s = scene(above, transmitted);
    for &integrator in IntegratorKind::ALL {
        for &accel in AccelKind::ALL {
            let base = pixels(&render(&lit, integrator, accel));
            assert!(base.iter().all(|p| p.min_element() > 0.1), "floor is lit");
            let out = render(&s, integrator, accel);
            check(&format!("{integrator}/{accel}"), &base, &out);
        }
    }
}

/// An ior 1.0, transmission 1 sphere is invisible to camera rays and must not shadow.
/// Tolerance zero: the transmission product is exactly 1.0, so each shadow ray adds
/// exactly its unblocked contribution and every other ray is the same as without the
/// sphere. (Before transmitted shadows these pixels were black.)
#[test]
fn clear_glass_at_ior_one_casts_no_shadow() {
    for_each_render(
        Above::GlassSphere(Vec3::ONE, 1.0),
        true,
        |name, base, out| {
            assert_eq!(pixels(out), base, "{name}");
            // One shadow ray per pixel, every one blocked by the plain query, traced again.
            assert_eq!(out.rays.transmitted_shadow, (SIZE * SIZE) as u64, "{name}");
        },
    );
}

/// Coloured glass filters the light once per surface: a sphere crossed through its
/// middle twice (`T²`), a single pane once (`T`). Relative tolerance 1e-5: the pixel is
/// the same sum scaled by `T²`, so only a few f32 roundings (6e-8 each) separate the
/// two.
#[test]
fn coloured_glass_gives_a_coloured_shadow() {
    let t = Vec3::new(0.8, 0.4, 0.2);
    let expect = |name: &str, base: &[Vec3], out: &RenderOutput, factor: Vec3| {
        for (p, b) in pixels(out).iter().zip(base) {
            let want = *b * factor;
            assert!(
                ((*p - want).abs() / want).max_element() < 1e-5,
                "{name}: {p} against {want}"
            );
        }
    };
    for_each_render(Above::GlassSphere(t, 1.5), true, |name, base, out| {
        expect(name, base, out, t * t);
    });
    for_each_render(Above::GlassPane(t), true, |name, base, out| {
        expect(name, base, out, t);
    });
}

/// An opaque object on the same shadow ray as glass, above or below it: black.
#[test]
fn opaque_and_glass_on_one_shadow_ray_is_black() {
    for opaque_below in [false, true] {
        for_each_render(Above::OpaqueAndGlass(opaque_below), true, |name, _, out| {
            assert!(
                pixels(out).iter().all(|p| *p == Vec3::ZERO),
                "{name}, opaque below: {opaque_below}"
            );
        });
    }
}

/// Switched off, glass blocks light like any surface and nothing is traced again.
#[test]
fn switched_off_glass_blocks_light() {
    for_each_render(Above::GlassSphere(Vec3::ONE, 1.0), false, |name, _, out| {
        assert!(pixels(out).iter().all(|p| *p == Vec3::ZERO), "{name}");
        assert_eq!(out.rays.transmitted_shadow, 0, "{name}");
    });
}

#[test]
fn toml_key_sets_it_and_the_default_is_on() {
    let base = "[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\nfov = 40\n\
                [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n";
    let path = std::path::Path::new("inline.toml");
    let on = parse_toml_scene(base, path).unwrap();
    assert!(on.settings.transmitted_shadows);
    let off = parse_toml_scene(
        &format!("[render]\ntransmitted_shadows = false\n{base}"),
        path,
    )
    .unwrap();
    assert!(!off.settings.transmitted_shadows);
    assert!(!RenderOptions::from_scene(&off).transmitted_shadows);
    let bad = parse_toml_scene(&format!("[render]\ntransmitted_shadows = 1\n{base}"), path)
        .unwrap_err()
        .to_string();
    assert!(
        bad.contains("inline.toml:2:") && bad.contains("expected a boolean"),
        "{bad}"
    );
}

/// The CLI flag overrides the scene: the Whitted room's glass sphere shadows the floor,
/// so by default blocked shadow rays are traced again; `--transmitted-shadows false`
/// traces none again and the image changes.
#[test]
fn cli_flag_switches_it() {
    let dir = crate::common::temp::temp_dir("cli");
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/whitted.toml");
    let run = |tag: &str, extra: &[&str]| {
        let (png, json) = (
            dir.join(format!("{tag}.png")),
            dir.join(format!("{tag}.json")),
        );
        let o = crate::common::bin::bin()
            .args([
                "render",
                scene.to_str().unwrap(),
                "-o",
                png.to_str().unwrap(),
            ])
            .args(["--width", "40", "--height", "30", "--quiet", "--stats-json"])
            .arg(&json)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let again = stats["rays"]["transmitted_shadow"].as_u64().unwrap();
        (std::fs::read(&png).unwrap(), again)
    };
    let (on, on_again) = run("on", &[]);
    let (off, off_again) = run("off", &["--transmitted-shadows", "false"]);
    assert!(on_again > 0, "no shadow ray met the glass");
    assert_eq!(off_again, 0);
    assert_ne!(on, off, "the glass shadow should differ");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Shadow segments from the camera-ray hits of `scene` (`w` x `h` pixel centres) to
/// every light (the centre and the corners of a quad light, a point far along a
/// directional light).
fn shadow_segments(
    scene: &Scene,
    accel: &SceneAccel,
    w: u32,
    h: u32,
) -> Vec<packet_render::geometry::Ray> {
    use packet_render::geometry::Ray;
    let frame = scene.camera.frame(w, h);
    let mut rays = Vec::new();
    for i in 0..w * h {
        let ray = frame.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
        let Some(hit) = accel.closest_hit(&ray) else {
            continue;
        };
        // Just in front of the surface, so the segment does not start inside it.
        let p = ray.at(hit.t * (1.0 - 1e-4));
        let mut targets = Vec::new();
        for light in &scene.lights {
            match *light {
                Light::Point { position, .. } | Light::Spot { position, .. } => {
                    targets.push(position)
                }
                Light::Directional { direction, .. } => targets.push(p - 1e3 * direction),
                Light::Quad {
                    corner,
                    edge1,
                    edge2,
                    ..
                } => targets.extend([
                    corner + 0.5 * (edge1 + edge2),
                    corner,
                    corner + edge1,
                    corner + edge2,
                    corner + edge1 + edge2,
                ]),
                _ => {}
            }
        }
        for q in targets {
            let d = q - p;
            let len = d.length();
            rays.push(Ray::segment(p, d / len, 1e-4, len * (1.0 - 1e-4)));
        }
    }
    rays
}

/// The occlusion batch names the primitive set that blocks each shadow ray first (the
/// same answer as the single-ray `occluder`, and blocked exactly where `any_hit_batch`
/// says so), and settling a blocked ray from that set (`ShadowFilter::transmittance`:
/// zero behind an all-opaque set; for a set that mixes opaque primitives and glass,
/// split in two, zero if the opaque part blocks it, else the filtered query over the
/// glass part and the later sets; else the filtered query from the set on) gives the
/// transmittance the filtered query of the whole scene gives, bit for bit (one glass
/// material per set here, so the order of the factors cannot matter): the sets and
/// the parts it skips have no candidate on the ray. The wavefront's batch form gives
/// the same factors and counts. Real shadow segments from camera-ray hits, on
/// every structure, in the Whitted room (opaque floor triangles; mirror and glass
/// spheres, one mixed set) and a scene whose triangles are mixed (a floor and a glass
/// pane) with an opaque sphere above and a moving glass sphere.
#[test]
fn settling_a_blocked_ray_from_its_blocking_set_equals_the_whole_scene_query() {
    use packet_render::accel::{BatchScratch, Occluder};
    use packet_render::integrator::shadow::{ShadowFilter, ShadowScratch, filtered_transmittance};
    use packet_render::stats::RayCounts;
    let whitted = packet_render::scene::load::load_scene(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/whitted.toml"),
    )
    .unwrap();
    let mixed = {
        let mut b = SceneBuilder::new();
        let floor = b.add_material(Material::diffuse("floor", Vec3::splat(0.8)));
        let pane = b.add_material(glass(Vec3::new(0.8, 0.4, 0.2), 1.5));
        let clear = b.add_material(glass(Vec3::splat(0.9), 1.2));
        let opaque = b.add_material(Material::diffuse("opaque", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(-8.0, 0.0, -8.0),
            Vec3::new(0.0, 0.0, 16.0),
            Vec3::new(16.0, 0.0, 0.0),
            floor,
        );
        b.add_quad(
            Vec3::new(-1.5, 1.0, -1.5),
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(3.0, 0.0, 0.0),
            pane,
        );
        b.add_sphere(Vec3::new(0.8, 2.2, 0.0), 0.5, opaque);
        b.add_moving_sphere(
            Vec3::new(-0.8, 2.2, 0.3),
            0.6,
            Vec3::new(0.1, 0.0, 0.0),
            clear,
        );
        b.add_light(Light::Point {
            position: Vec3::new(0.2, 5.0, 0.1),
            intensity: Vec3::splat(20.0),
        });
        b.camera = Some(Camera {
            eye: Vec3::new(0.0, 4.0, 6.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 50.0,
        });
        b.finish().unwrap()
    };
    for (name, scene) in [("whitted", &whitted), ("mixed", &mixed)] {
        let filter = ShadowFilter::new(scene, true, AccelKind::Bvh4).expect("the scene has glass");
        for &kind in AccelKind::ALL {
            let accel = SceneAccel::build(scene, kind);
            let rays = shadow_segments(scene, &accel, 48, 36);
            let mut first = vec![None; rays.len()];
            let (mut blocked, mut plain) = (Vec::new(), vec![false; rays.len()]);
            let mut scratch = BatchScratch::default();
            accel.occluders_batch(&rays, &mut first, &mut blocked, &mut scratch);
            accel.any_hit_batch(&rays, &mut plain, &mut scratch);
            // The wavefront's batch form: the same factors and counts as ray by ray.
            let (mut batch, mut batch_counts) = (Vec::new(), RayCounts::default());
            let mut shadow_scratch = ShadowScratch::default();
            filter.transmittance_batch(
                scene,
                &accel,
                &rays,
                &first,
                &mut batch,
                &mut shadow_scratch,
                &mut batch_counts,
            );
            let mut counts = RayCounts::default();
            let (mut skipped, mut settled, mut lit) = (0, 0, 0);
            let mut sets = [0usize; 4];
            for (i, ray) in rays.iter().enumerate() {
                assert_eq!(
                    first[i],
                    accel.occluder(ray),
                    "{name}/{kind} ray {i}: {ray:?}"
                );
                assert_eq!(first[i].is_some(), plain[i], "{name}/{kind} ray {i}");
                let Some(set) = first[i] else {
                    assert_eq!(batch[i], Vec3::ONE, "{name}/{kind} ray {i}");
                    continue;
                };
                sets[set as usize] += 1;
                let before = counts.transmitted_shadow;
                let t = filter.transmittance(scene, &accel, ray, set, &mut counts);
                let whole = filtered_transmittance(scene, &accel, ray, true);
                assert_eq!(
                    t.to_array().map(f32::to_bits),
                    whole.to_array().map(f32::to_bits),
                    "{name}/{kind} ray {i}: {t} from {set:?} against {whole}"
                );
                assert_eq!(
                    t.to_array().map(f32::to_bits),
                    batch[i].to_array().map(f32::to_bits),
                    "{name}/{kind} ray {i}: batch"
                );
                if counts.transmitted_shadow == before {
                    skipped += 1;
                } else {
                    settled += 1;
                }
                lit += (t != Vec3::ZERO) as usize;
            }
            assert_eq!(counts, batch_counts, "{name}/{kind}");
            eprintln!(
                "{name}/{kind}: {} rays, blocked first by {:?} {sets:?}, {skipped} dark \
                 without a second query, {settled} traced again ({lit} lit through glass)",
                rays.len(),
                Occluder::ALL
            );
            assert!(
                settled > 0 && lit > 0,
                "{name}/{kind}: no ray through glass"
            );
            if name == "whitted" {
                // The floor's triangles are all opaque: what they block needs no query
                // (the lights are above it, so that is nothing here); the spheres are
                // a mirror and glass, traced again.
                assert!(
                    filter.is_opaque(Occluder::Triangles) && filter.is_split(Occluder::Spheres)
                );
                // Some behind the mirror sphere (its part of the split set blocks them).
                assert!(
                    sets[1] > 0 && skipped == sets[0] && settled > lit,
                    "{name}/{kind}"
                );
            } else {
                assert!(
                    filter.is_split(Occluder::Triangles)
                        && filter.is_opaque(Occluder::Spheres)
                        && !filter.is_opaque(Occluder::Moving)
                        && !filter.is_split(Occluder::Moving)
                );
                assert!(
                    sets[1] > 0 && sets[2] > 0 && skipped == sets[1],
                    "{name}/{kind}"
                );
            }
        }
    }
}

/// The one-pass settlement of a tiny scene's shadow rays (`ShadowFilter::tiny_pass`,
/// occlusion and glass crossings in the same lanes) gives the two-step batch's answers
/// (`occluders_batch`, then `ShadowFilter::transmittance_batch`): every factor bit for
/// bit and the same counts. Real shadow segments from camera-ray hits towards the
/// lights and 16 rays through each sphere (runs of one key, partial lane groups at
/// the ends), on every structure: the Whitted room (opaque floor, a mirror and
/// a glass sphere: the glass variant), the same room with its glass made opaque but a
/// glass material defined (a filter whose spheres are all opaque), and at a batch
/// length that leaves partial groups. The scene with moving glass does not take it.
#[test]
fn one_pass_tiny_shadows_equal_the_two_step_batch() {
    use packet_render::accel::BatchScratch;
    use packet_render::integrator::shadow::{ShadowFilter, ShadowScratch};
    use packet_render::stats::RayCounts;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/whitted.toml");
    let whitted = packet_render::scene::load::load_scene(&path).unwrap();
    let mut opaque = whitted.clone();
    for m in &mut opaque.materials {
        if m.is_transmissive() {
            *m = Material::diffuse("was glass", Vec3::splat(0.5));
        }
    }
    opaque.materials.push(glass(Vec3::splat(0.9), 1.5));
    let mut moving = SceneBuilder::new();
    let floor = moving.add_material(Material::diffuse("floor", Vec3::splat(0.8)));
    let clear = moving.add_material(glass(Vec3::splat(0.9), 1.2));
    moving.add_quad(
        Vec3::new(-8.0, 0.0, -8.0),
        Vec3::new(0.0, 0.0, 16.0),
        Vec3::new(16.0, 0.0, 0.0),
        floor,
    );
    moving.add_moving_sphere(Vec3::new(0.0, 1.0, 0.0), 0.6, Vec3::X, clear);
    moving.add_light(Light::Point {
        position: Vec3::new(0.2, 5.0, 0.1),
        intensity: Vec3::splat(20.0),
    });
    moving.camera = Some(Camera {
        eye: Vec3::new(0.0, 4.0, 6.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        vfov_deg: 50.0,
    });
    let moving = moving.finish().unwrap();
    for &kind in AccelKind::ALL {
        let accel = SceneAccel::build(&moving, kind);
        let filter = ShadowFilter::new(&moving, true, kind).expect("glass");
        assert!(filter.tiny_pass(&accel).is_none(), "moving/{kind}");
    }
    for (name, scene) in [("whitted", &whitted), ("opaque", &opaque)] {
        let filter = ShadowFilter::new(scene, true, AccelKind::Bvh4).expect("a glass material");
        for &kind in AccelKind::ALL {
            let accel = SceneAccel::build(scene, kind);
            let pass = filter
                .tiny_pass(&accel)
                .unwrap_or_else(|| panic!("{name}/{kind}: the one-pass settlement applies"));
            let mut rays = shadow_segments(scene, &accel, 48, 36);
            let frame = scene.camera.frame(24, 18);
            for i in 0..24 * 18 {
                let ray = frame.ray((i % 24) as f32 + 0.5, (i / 24) as f32 + 0.5);
                let Some(hit) = accel.closest_hit(&ray) else {
                    continue;
                };
                let p = ray.at(hit.t * (1.0 - 1e-4));
                // Runs of 16 rays from the hit through each sphere (near its centre).
                for k in 0..scene.spheres.len() {
                    let c = scene.spheres.center(k);
                    for s in 0..16 {
                        let off = Vec3::new((s % 4) as f32 - 1.5, 0.0, (s / 4) as f32 - 1.5);
                        let q = c + 0.1 * off + 3.0 * (c - p).normalize();
                        let d = q - p;
                        let len = d.length();
                        let seg = packet_render::geometry::Ray::segment(p, d / len, 1e-4, len);
                        rays.push(seg);
                    }
                }
            }
            let (mut through, mut dark) = (0, 0);
            for len in [rays.len() - 7, rays.len()] {
                let rays = &rays[..len];
                let mut first = vec![None; len];
                let mut scratch = BatchScratch::default();
                accel.occluders_batch(rays, &mut first, &mut Vec::new(), &mut scratch);
                let (mut want, mut want_counts) = (Vec::new(), RayCounts::default());
                filter.transmittance_batch(
                    scene,
                    &accel,
                    rays,
                    &first,
                    &mut want,
                    &mut ShadowScratch::default(),
                    &mut want_counts,
                );
                let (mut got, mut counts) = (Vec::new(), RayCounts::default());
                pass.transmittance_batch(rays, &mut got, scratch.tiny(), &mut counts);
                assert_eq!(got.len(), len, "{name}/{kind}");
                for i in 0..len {
                    assert_eq!(
                        got[i].to_array().map(f32::to_bits),
                        want[i].to_array().map(f32::to_bits),
                        "{name}/{kind} ray {i}: {:?}",
                        rays[i]
                    );
                }
                assert_eq!(counts, want_counts, "{name}/{kind}");
                // Blocked first by the spheres and yet lit: through the glass.
                through = (0..len)
                    .filter(|&i| {
                        first[i] == Some(packet_render::accel::Occluder::Spheres)
                            && got[i] != Vec3::ZERO
                    })
                    .count();
                dark = got.iter().filter(|t| **t == Vec3::ZERO).count();
            }
            eprintln!(
                "{name}/{kind}: {} rays, {dark} dark, {through} through glass",
                rays.len()
            );
            assert!(dark > 100, "{name}/{kind}: {dark} dark rays");
            assert_eq!(
                through > 100,
                name == "whitted",
                "{name}/{kind}: {through} through glass"
            );
        }
    }
}
