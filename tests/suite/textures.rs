//! Image textures end to end: MTL maps and `vt` coordinates, TOML texture keys, PLY
//! texture coordinates, one decode per file, located warnings and errors, and renders
//! with known answers (a textured quad against plain quads of the texel colours, a
//! cut-out quad in front of a red one), on both integrators and every structure.

use crate::common::temp::{temp_dir, write};
use glam::{Vec2, Vec3};
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::film::srgb_to_linear;
use packet_render::integrator::{IntegratorKind, RenderOptions};
use packet_render::scene::Scene;
use packet_render::scene::load::{load_obj, load_ply, load_scene, parse_toml_scene};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Writes an RGBA PNG of `w x h` texels from a function of the texel.
fn png(dir: &Path, name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> PathBuf {
    let p = dir.join(name);
    image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)))
        .save(&p)
        .unwrap();
    p
}

fn lin(code: u8) -> f32 {
    srgb_to_linear(code as f32 / 255.0)
}

const QUAD_OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl tex\nf 1/1 2/2 3/3 4/4\n";

#[test]
fn obj_with_map_kd_loads_uvs_and_the_linearised_texture() {
    let dir = temp_dir("objmtl");
    png(&dir, "kd.png", 2, 2, |x, y| {
        [(100 * x + 50 * y) as u8, 7, 200, 255]
    });
    write(
        &dir,
        "m.mtl",
        "newmtl tex\nKd 1 1 1\nmap_Kd -s 2 2 kd.png\n",
    );
    let obj = write(&dir, "q.obj", QUAD_OBJ);
    let mesh = load_obj(&obj).unwrap();
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
    assert_eq!(
        mesh.texcoords,
        [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        "one vt per position, in order"
    );
    let m = mesh.materials.iter().find(|m| m.name == "tex").unwrap();
    let t = m.textures.diffuse.as_ref().expect("map_Kd bound");
    assert_eq!(t.scale, Vec2::splat(2.0));
    let tex = &t.texture;
    assert_eq!((tex.width, tex.height), (2, 2));
    // texel (1, 1): codes (150, 7, 200), linearised on load
    let want = Vec3::new(lin(150), lin(7), lin(200));
    assert_eq!(tex.texel(1, 1).truncate(), want);

    // Through the whole scene: the SoA mesh carries the uvs.
    let scene = load_scene(&obj).unwrap();
    assert_eq!(scene.mesh.us, [0.0, 1.0, 1.0, 0.0]);
    assert_eq!(scene.mesh.vs, [0.0, 0.0, 1.0, 1.0]);
    assert!(scene.features.textures);
    // the middle of triangle 0 (corners 0 1 2) at barycentrics (1/4, 1/2)
    assert_eq!(scene.mesh.uv_at(0, 0.25, 0.5), Vec2::new(0.75, 0.5));
}

#[test]
fn missing_texture_warns_with_the_mtl_file_and_line() {
    let dir = temp_dir("missing");
    write(
        &dir,
        "m.mtl",
        "newmtl tex\nKd 0.5 0.5 0.5\n\nmap_Kd nowhere.png\nmap_Bump bump.png\n",
    );
    let obj = write(&dir, "q.obj", QUAD_OBJ);
    let mesh = load_obj(&obj).unwrap();
    let mtl = dir.join("m.mtl").display().to_string();
    let w = mesh
        .warnings
        .iter()
        .find(|w| w.contains("nowhere.png"))
        .unwrap_or_else(|| panic!("no warning for the missing map: {:?}", mesh.warnings));
    assert!(w.starts_with(&format!("{mtl}:4:")), "{w}");
    assert!(w.contains("renders with its `Kd` colour"), "{w}");
    // the material keeps its colour, no texture
    let m = mesh.materials.iter().find(|m| m.name == "tex").unwrap();
    assert!(m.textures.diffuse.is_none());
    assert_eq!(m.diffuse, Vec3::splat(0.5));
    // an unsupported map is named too, not dropped silently
    assert!(
        mesh.warnings
            .iter()
            .any(|w| w.starts_with(&format!("{mtl}:5:")) && w.contains("map_Bump")),
        "{:?}",
        mesh.warnings
    );
}

#[test]
fn corrupt_texture_is_an_error_naming_the_file_and_the_mtl_line() {
    let dir = temp_dir("corrupt");
    write(&dir, "bad.png", b"\x89PNG\r\n\x1a\n garbage");
    write(&dir, "m.mtl", "newmtl tex\nmap_Kd bad.png\n");
    let obj = write(&dir, "q.obj", QUAD_OBJ);
    let e = load_obj(&obj).unwrap_err().to_string();
    let mtl = dir.join("m.mtl").display().to_string();
    assert!(e.starts_with(&format!("{mtl}:2:")), "{e}");
    assert!(e.contains("bad.png"), "{e}");
}

#[test]
fn windows_separators_in_map_names_resolve() {
    let dir = temp_dir("backslash");
    std::fs::create_dir_all(dir.join("textures")).unwrap();
    png(&dir.join("textures"), "a.png", 1, 1, |_, _| {
        [255, 0, 0, 255]
    });
    write(&dir, "m.mtl", "newmtl tex\nmap_Kd textures\\a.png\n");
    let obj = write(&dir, "q.obj", QUAD_OBJ);
    let mesh = load_obj(&obj).unwrap();
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
    let m = mesh.materials.iter().find(|m| m.name == "tex").unwrap();
    assert!(m.textures.diffuse.is_some());
}

#[test]
fn one_file_named_by_two_materials_is_decoded_once() {
    let dir = temp_dir("shared");
    png(&dir, "a.png", 2, 2, |_, _| [1, 2, 3, 255]);
    let toml = "[materials.x]\ntexture = \"a.png\"\n[materials.y]\ntexture = \"a.png\"\n\
                wrap = \"mirror\"\n\
                [[quad]]\ncorner = [0,0,0]\nedge1 = [1,0,0]\nedge2 = [0,1,0]\nmaterial = \"x\"\n\
                [[quad]]\ncorner = [0,0,1]\nedge1 = [1,0,0]\nedge2 = [0,1,0]\nmaterial = \"y\"\n";
    let path = write(&dir, "s.toml", toml);
    let scene = load_scene(&path).unwrap();
    let tex = |name: &str| {
        let m = scene.materials.iter().find(|m| m.name == name).unwrap();
        m.textures.diffuse.clone().unwrap()
    };
    assert!(Arc::ptr_eq(&tex("x").texture, &tex("y").texture));
    assert_eq!(tex("y").wrap, packet_render::texture::WrapMode::Mirror);
    // a texture without `diffuse` is the colour itself
    let x = scene.materials.iter().find(|m| m.name == "x").unwrap();
    assert_eq!(x.diffuse, Vec3::ONE);
}

#[test]
fn toml_texture_errors_are_located() {
    let dir = temp_dir("tomlerr");
    let cases = [
        ("texture = \"missing.png\"", "not found"),
        ("texture = 3", "must be a file name or a table"),
        (
            "texture = { procedural = \"plaid\" }",
            "unknown procedural `plaid`",
        ),
        (
            "texture = { procedural = \"checker\", size = 0 }",
            "`size` must be an integer",
        ),
        (
            "texture = { procedural = \"checker\", colour = 1 }",
            "unknown key `colour`",
        ),
        (
            "texture = { procedural = \"noise\" }\nwrap = \"tile\"",
            "unknown wrap `tile`",
        ),
        (
            "texture = { procedural = \"noise\" }\nuv_scale = [0, 1]",
            "`uv_scale` must be",
        ),
        ("wrap = \"clamp\"", "the material has none"),
    ];
    for (body, want) in cases {
        let text = format!("[materials.m]\n{body}\n");
        let e = parse_toml_scene(&text, &dir.join("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{body}: {e}");
        assert!(e.contains("s.toml:"), "{body}: located: {e}");
    }
}

#[test]
fn procedural_texture_in_toml() {
    let text = "[materials.m]\ntexture = { procedural = \"checker\", size = 4, cells = 2, a = [1, 0, 0], b = [0, 0, 1] }\n\
                [[quad]]\ncorner = [0,0,0]\nedge1 = [1,0,0]\nedge2 = [0,1,0]\nmaterial = \"m\"\n";
    let scene = parse_toml_scene(text, Path::new("p.toml")).unwrap();
    let m = scene.materials.iter().find(|m| m.name == "m").unwrap();
    let t = &m.textures.diffuse.as_ref().unwrap().texture;
    // procedural colours are linear values, not sRGB codes
    assert_eq!(t.texel(0, 0).truncate(), Vec3::X);
    assert_eq!(t.texel(2, 0).truncate(), Vec3::Z);
    // the quad's corners carry (0,0)..(1,1)
    assert_eq!(scene.mesh.us, [0.0, 1.0, 1.0, 0.0]);
    assert_eq!(scene.mesh.vs, [0.0, 0.0, 1.0, 1.0]);
}

#[test]
fn ply_texture_coordinates_are_read() {
    let dir = temp_dir("ply");
    for (u, v) in [("u", "v"), ("s", "t"), ("texture_u", "texture_v")] {
        let text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nproperty float {u}\nproperty float {v}\nelement face 1\n\
             property list uchar int vertex_indices\nend_header\n\
             0 0 0 0.25 0.5\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n"
        );
        let p = write(&dir, &format!("{u}.ply"), text);
        let m = load_ply(&p).unwrap();
        assert_eq!(
            m.mesh.texcoords,
            [Vec2::new(0.25, 0.5), Vec2::X, Vec2::Y],
            "{u} {v}"
        );
    }
}

// ---- renders -------------------------------------------------------------------

const SIZE: u32 = 9;

/// A camera 3 units in front of the plane z = 0 looking down -Z with a 20° field of
/// view (the image spans x, y in ±0.53), a directional light shining straight down -Z,
/// no ambient light, black background.
const FRAME: &str = "background = [0, 0, 0]\nambient = [0, 0, 0]\n\
    [camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\nfov = 20\n\
    [[light]]\ntype = \"directional\"\ndirection = [0, 0, -1]\nirradiance = [3, 3, 3]\n";

/// A 2 x 2 quad at z = 0 (uv (0,0) at (-1,-1), (1,1) at (1,1)) of material `m`.
const FRONT_QUAD: &str =
    "[[quad]]\ncorner = [-1, -1, 0]\nedge1 = [2, 0, 0]\nedge2 = [0, 2, 0]\nmaterial = \"m\"\n";

fn scene_in(dir: &Path, body: &str) -> Scene {
    parse_toml_scene(&format!("{FRAME}{body}"), &dir.join("s.toml")).unwrap()
}

fn render_all(scene: &Scene, check: impl Fn(&str, &dyn Fn(u32, u32) -> Vec3)) {
    for &integrator in IntegratorKind::ALL {
        for &kind in AccelKind::ALL {
            let mut o = RenderOptions::from_scene(scene);
            o.width = SIZE;
            o.height = SIZE;
            o.spp = 1;
            let accel = SceneAccel::build(scene, kind);
            let out = integrator.render(scene, &accel, &o);
            check(&format!("{integrator}/{kind}"), &|x, y| out.film.get(x, y));
        }
    }
}

fn render_one(scene: &Scene) -> Vec<Vec3> {
    let mut o = RenderOptions::from_scene(scene);
    o.width = SIZE;
    o.height = SIZE;
    o.spp = 1;
    let accel = SceneAccel::build(scene, AccelKind::Bvh4);
    let out = IntegratorKind::Whitted.render(scene, &accel, &o);
    (0..SIZE * SIZE)
        .map(|i| out.film.get(i % SIZE, i / SIZE))
        .collect()
}

fn close(a: Vec3, b: Vec3, rel: f32) -> bool {
    ((a - b).abs().max_element()) <= rel * b.abs().max_element()
}

/// Texture 4 x 4: columns 0-1 colour code A, columns 2-3 code B. On the quad, u < 0.375
/// reads only A texels and u > 0.625 only B (bilinear reaches half a texel, 0.125, to
/// either side of the column boundary at u = 0.5). Pixel columns 0-1 of the 9-wide
/// image see u <= 0.27, columns 7-8 u >= 0.73, column 4 u = 0.5 (midway).
#[test]
fn textured_quad_shades_the_texel_colour_times_the_plain_shading() {
    let dir = temp_dir("render-tex");
    let (a, b) = ([200u8, 40, 90], [30u8, 180, 220]);
    png(&dir, "t.png", 4, 4, |x, _| {
        let c = if x < 2 { a } else { b };
        [c[0], c[1], c[2], 255]
    });
    let la = Vec3::new(lin(a[0]), lin(a[1]), lin(a[2]));
    let lb = Vec3::new(lin(b[0]), lin(b[1]), lin(b[2]));
    let textured = scene_in(
        &dir,
        &format!("[materials.m]\ntexture = \"t.png\"\n{FRONT_QUAD}"),
    );
    let plain = |c: Vec3| {
        render_one(&scene_in(
            &dir,
            &format!(
                "[materials.m]\ndiffuse = [{}, {}, {}]\n{FRONT_QUAD}",
                c.x, c.y, c.z
            ),
        ))
    };
    let (pa, pb, pm) = (plain(la), plain(lb), plain((la + lb) * 0.5));
    assert!(
        pa[0].min_element() > 0.01,
        "the plain quad is lit: {}",
        pa[0]
    );
    render_all(&textured, |name, px| {
        for y in 0..SIZE {
            let i = |x: u32| (y * SIZE + x) as usize;
            // Tolerance 1e-6 relative: between equal texels bilinear weighting
            // `a (1 - f) + a f` rounds up to 2 ulps (6e-8 each) away from `a`, and
            // nothing else differs from the plain render.
            for x in [0, 1] {
                assert!(
                    close(px(x, y), pa[i(x)], 1e-6),
                    "{name} ({x},{y}): {} vs A {}",
                    px(x, y),
                    pa[i(x)]
                );
            }
            for x in [7, 8] {
                assert!(
                    close(px(x, y), pb[i(x)], 1e-6),
                    "{name} ({x},{y}): {} vs B {}",
                    px(x, y),
                    pb[i(x)]
                );
            }
            // Midway between the A and B columns the mean. Tolerance 1e-5 relative:
            // the hit's u carries the intersection's rounding (~1e-7), which moves
            // the blend weight by 4 texels/unit times that, on a colour step of ~0.6.
            assert!(
                close(px(4, y), pm[i(4)], 1e-5),
                "{name} (4,{y}): {} vs mean {}",
                px(4, y),
                pm[i(4)]
            );
        }
    });

    // The AOV albedo is the texel, not the material's plain colour.
    let accel = SceneAccel::build(&textured, AccelKind::Bvh4);
    let aovs = packet_render::integrator::aov::Aovs::render(
        &textured,
        &accel,
        SIZE,
        SIZE,
        packet_render::integrator::PixelBounds::full(SIZE, SIZE),
    );
    assert!(
        close(aovs.albedo[0], la, 1e-6),
        "{} vs {la}",
        aovs.albedo[0]
    );
    assert!(
        close(aovs.albedo[8], lb, 1e-6),
        "{} vs {lb}",
        aovs.albedo[8]
    );
}

/// A blue cut-out quad (mask: columns 0-1 alpha 0, columns 2-3 alpha 1) in front of a
/// red quad, lit from the camera's side. Where the mask is a hole (u < 0.5: pixel
/// columns 0-3) the image is exactly the red quad alone: the camera ray reaches it and
/// so does its shadow ray, which crosses the cut-out plane through the same hole.
/// Where the mask is solid (columns 5-8) it is exactly an opaque blue quad. Exact:
/// the filtered query returns the same hit as the plain one, bit for bit, and a
/// shadow ray through holes only is weighted by exactly 1.
#[test]
fn cutout_quad_lets_camera_and_shadow_rays_through_its_holes() {
    let dir = temp_dir("render-cut");
    png(&dir, "mask.png", 4, 4, |x, _| {
        [255, 255, 255, if x < 2 { 0 } else { 255 }]
    });
    let red = "[materials.red]\ndiffuse = [0.8, 0.05, 0.05]\n\
               [[quad]]\ncorner = [-2, -2, -1]\nedge1 = [4, 0, 0]\nedge2 = [0, 4, 0]\nmaterial = \"red\"\n";
    let blue = "[materials.m]\ndiffuse = [0.05, 0.05, 0.8]\n";
    let cut = scene_in(
        &dir,
        &format!("{red}{blue}alpha_texture = \"mask.png\"\nwrap = \"clamp\"\n{FRONT_QUAD}"),
    );
    let only_red = render_one(&scene_in(&dir, red));
    let opaque = render_one(&scene_in(&dir, &format!("{red}{blue}{FRONT_QUAD}")));
    assert!(
        only_red[0].x > 0.01 && only_red[0].x > 4.0 * only_red[0].z,
        "{}",
        only_red[0]
    );
    render_all(&cut, |name, px| {
        for y in 0..SIZE {
            let i = |x: u32| (y * SIZE + x) as usize;
            for x in 0..4 {
                assert_eq!(
                    px(x, y),
                    only_red[i(x)],
                    "{name} ({x},{y}): through the hole"
                );
            }
            for x in 5..SIZE {
                assert_eq!(px(x, y), opaque[i(x)], "{name} ({x},{y}): solid part");
            }
        }
    });
    // With transmitted shadows off (glass blocks), holes still pass shadow rays.
    let mut off = cut.clone();
    off.settings.transmitted_shadows = false;
    let img = render_one(&off);
    assert_eq!(img[0], only_red[0]);
}
