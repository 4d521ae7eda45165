//! Image textures end to end: MTL maps and `vt` coordinates, TOML texture keys, PLY
//! texture coordinates, one decode per file, located warnings and errors, and renders
//! with known answers (a textured quad against plain quads of the texel colours, a
//! cut-out quad in front of a red one), on both integrators and every structure.

use glam::{Vec2, Vec3};
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::film::srgb_to_linear;
use packet_render::integrator::{IntegratorKind, RenderOptions};
use packet_render::scene::Scene;
use packet_render::scene::load::{load_obj, load_ply, load_scene, parse_toml_scene};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

fn temp_dir(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "packet-render-textures-{}-{}-{tag}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p
}

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
    png(&dir, "kd.png", 2, 2, |x, y| [(100 * x + 50 * y) as u8, 7, 200, 255]);
    write(&dir, "m.mtl", "newmtl tex\nKd 1 1 1\nmap_Kd -s 2 2 kd.png\n");
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
    png(&dir.join("textures"), "a.png", 1, 1, |_, _| [255, 0, 0, 255]);
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
        ("texture = { procedural = \"plaid\" }", "unknown procedural `plaid`"),
        ("texture = { procedural = \"checker\", size = 0 }", "`size` must be an integer"),
        ("texture = { procedural = \"checker\", colour = 1 }", "unknown key `colour`"),
        ("texture = { procedural = \"noise\" }\nwrap = \"tile\"", "unknown wrap `tile`"),
        ("texture = { procedural = \"noise\" }\nuv_scale = [0, 1]", "`uv_scale` must be"),
        ("wrap = \"clamp\"", "the material has none"),
    ];
    for (body, want) in cases {
        let text = format!("[materials.m]\n{body}\n");
        let e = parse_toml_scene(&text, &dir.join("s.toml")).unwrap_err().to_string();
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
