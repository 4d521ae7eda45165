//! Loading scenes: the shipped scenes parse, generators produce what they promise, and
//! every kind of bad input gives an `Error::Input` at the right line (and column).

use crate::common::temp::{temp_dir, write};
use glam::Vec3;
use packet_render::Error;
use packet_render::scene::load::{load_obj, load_obj_scene, load_scene, parse_toml_scene};
use packet_render::scene::procedural::{sphereflake, sphereflake_count, tessellated_mesh};
use packet_render::scene::{Light, Scene, SceneBuilder};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Asserts an `Error::Input` in `file` at `line` (and `column` if given) whose message
/// contains `needle`.
#[track_caller]
fn assert_input_error<T: std::fmt::Debug>(
    r: packet_render::Result<T>,
    file: &Path,
    line: usize,
    column: Option<usize>,
    needle: &str,
) {
    match r {
        Err(Error::Input { location, message }) => {
            assert_eq!(location.file, file, "{location}: {message}");
            assert_eq!(location.line, line, "{location}: {message}");
            if let Some(c) = column {
                assert_eq!(location.column, c, "{location}: {message}");
            }
            assert!(
                message.contains(needle),
                "`{message}` should mention `{needle}`"
            );
        }
        other => panic!("expected an input error at line {line}, got {other:?}"),
    }
}

fn toml(text: &str) -> (PathBuf, packet_render::Result<Scene>) {
    let dir = temp_dir("toml");
    let path = write(&dir, "scene.toml", text);
    let r = load_scene(&path);
    (path, r)
}

// ---------------------------------------------------------------- generators

#[test]
fn sphereflake_counts_for_levels_0_to_5() {
    for (level, n) in [1, 10, 91, 820, 7381, 66430].into_iter().enumerate() {
        assert_eq!(sphereflake_count(level as u32), n);
        let mut b = SceneBuilder::new();
        assert_eq!(sphereflake(&mut b, level as u32, Vec3::ZERO, 1.0, 0), n);
        let scene = b.finish().unwrap();
        assert_eq!(scene.spheres.len(), n);
    }
}

#[test]
fn tessellated_mesh_is_closed_finite_and_close_to_the_requested_size() {
    for requested in [1_000usize, 69_451] {
        let mut b = SceneBuilder::new();
        let n = tessellated_mesh(&mut b, requested, Vec3::new(1.0, 2.0, 3.0), 2.0, 0);
        let scene = b.finish().unwrap();
        let mesh = &scene.mesh;
        assert_eq!(n, mesh.len());
        assert!(
            n >= requested && n <= requested + requested / 20,
            "{requested} -> {n}"
        );
        assert!(mesh.has_normals());
        assert!(mesh.vertex_count() < mesh.len(), "vertices are shared");
        for i in 0..mesh.vertex_count() {
            let n = Vec3::new(mesh.nxs[i], mesh.nys[i], mesh.nzs[i]);
            assert!((n.length() - 1.0).abs() < 1e-3, "normal {i} = {n}");
        }
        // Closed and consistently oriented: every directed edge appears once and its
        // reverse once, so every undirected edge is shared by exactly two triangles.
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for t in 0..mesh.len() {
            let v = [mesh.i0[t], mesh.i1[t], mesh.i2[t]];
            assert!(
                v[0] != v[1] && v[1] != v[2] && v[0] != v[2],
                "degenerate triangle {t}"
            );
            for k in 0..3 {
                *edges.entry((v[k], v[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &count) in &edges {
            assert_eq!(count, 1, "directed edge {a}->{b} used {count} times");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} is a border");
        }
        assert!(scene.bounds.min.is_finite() && scene.bounds.max.is_finite());
    }
}

// ---------------------------------------------------------------- shipped scenes

#[test]
fn every_shipped_scene_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.primitive_count() > 0, "{} is empty", path.display());
        assert!(
            !scene.lights.is_empty() || scene.features.emission || scene.features.environment,
            "{} is unlit",
            path.display()
        );
        count += 1;
    }
    assert!(
        count >= 4,
        "expected at least 4 scenes in {}",
        dir.display()
    );
}

#[test]
fn shipped_scenes_have_what_they_promise() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let flake = load_scene(&dir.join("sphereflake.toml")).unwrap();
    assert_eq!(flake.spheres.len(), 7381);
    let tess = load_scene(&dir.join("tessellated.toml")).unwrap();
    assert!(
        (70_000..72_000).contains(&tess.mesh.len()),
        "{}",
        tess.mesh.len()
    );
    assert!(tess.features.glass && tess.features.mirror);
    let whitted = load_scene(&dir.join("whitted.toml")).unwrap();
    assert!(whitted.features.glass && whitted.features.mirror && whitted.features.textures);
    let cornell = load_scene(&dir.join("cornell.toml")).unwrap();
    assert!(cornell.features.emission && cornell.features.mirror && cornell.features.glass);
}

// ---------------------------------------------------------------- TOML errors

#[test]
fn toml_syntax_error_has_line_and_column() {
    let (p, r) = toml("[render]\nwidth = 64\nheight = = 3\n");
    assert_input_error(r, &p, 3, Some(10), "extra `=`");
}

#[test]
fn toml_wrong_type_points_at_the_value() {
    let (p, r) = toml("[[sphere]]\ncenter = [0, 0, 0]\nradius = \"big\"\n");
    assert_input_error(r, &p, 3, Some(10), "f32");
}

#[test]
fn toml_unknown_key_is_an_error_listing_valid_keys() {
    let (p, r) = toml("[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\ncolour = 3\n");
    assert_input_error(r, &p, 4, Some(1), "radius");
}

#[test]
fn toml_unknown_material_names_it_and_lists_defined_ones() {
    let (p, r) = toml(
        "[materials.red]\ndiffuse = [1, 0, 0]\n[materials.blue]\ndiffuse = [0, 0, 1]\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"green\"\n",
    );
    assert_input_error(
        r,
        &p,
        8,
        Some(12),
        "unknown material `green`; defined materials: blue, red",
    );
}

#[test]
fn toml_negative_radius() {
    let (p, r) = toml("[[sphere]]\ncenter = [0, 0, 0]\nradius = -1.5\n");
    assert_input_error(r, &p, 3, Some(10), "radius");
}

#[test]
fn toml_nan_and_inf_values() {
    let (p, r) = toml("[[sphere]]\ncenter = [0, nan, 0]\nradius = 1\n");
    assert_input_error(r, &p, 2, Some(10), "finite");
    let (p, r) =
        toml("[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [inf, 1, 1]\n");
    assert_input_error(r, &p, 4, Some(13), "finite");
}

#[test]
fn toml_absurd_render_settings() {
    let (p, r) = toml("[render]\nwidth = 0\n");
    assert_input_error(r, &p, 2, Some(9), "width");
    let (p, r) = toml("[render]\nwidth = 64\nspp = 1000000000\n");
    assert_input_error(r, &p, 3, Some(7), "spp");
    let (p, r) = toml("[render]\nheight = -4\n");
    assert_input_error(r, &p, 2, Some(10), "integer `-4`, expected u32");
}

#[test]
fn toml_unknown_types_list_the_valid_ones() {
    let (p, r) = toml("[[light]]\ntype = \"laser\"\n");
    assert_input_error(r, &p, 2, Some(8), "point, directional, spot");
    let (p, r) = toml("[[generator]]\ntype = \"teapot\"\n");
    assert_input_error(r, &p, 2, Some(8), "sphereflake, tessellated, whitted_room");
    let (p, r) = toml("[[light]]\ntype = \"point\"\ndirection = [0, -1, 0]\n");
    assert_input_error(r, &p, 3, Some(13), "not a field of a point light");
}

#[test]
fn toml_generator_limits() {
    let (p, r) = toml("[[generator]]\ntype = \"sphereflake\"\nlevel = 9\n");
    assert_input_error(r, &p, 3, Some(9), "level");
    let (p, r) = toml("[[generator]]\ntype = \"tessellated\"\ntriangles = 100000000\n");
    assert_input_error(r, &p, 3, Some(13), "triangles");
}

#[test]
fn toml_zero_plane_normal() {
    let (p, r) = toml("[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\nsize = 1\n");
    assert_input_error(r, &p, 3, Some(10), "non-zero");
}

#[test]
fn toml_missing_obj_names_the_resolved_path() {
    let (p, r) = toml(
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n\n[[mesh]]\nfile = \"nowhere/missing.obj\"\n",
    );
    let resolved = p.parent().unwrap().join("nowhere/missing.obj");
    assert_input_error(r, &p, 6, Some(8), &resolved.display().to_string());
}

#[test]
fn missing_scene_file_is_an_io_error_with_the_path() {
    let p = temp_dir("missing").join("absent.toml");
    match load_scene(&p) {
        Err(Error::Io { path, .. }) => assert_eq!(path, p),
        other => panic!("expected Error::Io, got {other:?}"),
    }
    let p = p.with_extension("obj");
    assert!(matches!(load_obj(&p), Err(Error::Io { path, .. }) if path == p));
}

#[test]
fn toml_mesh_with_transform_and_mtl_materials() {
    let dir = temp_dir("mesh");
    write(
        &dir,
        "tri.obj",
        "mtllib tri.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n",
    );
    write(&dir, "tri.mtl", "newmtl m\nKd 0.1 0.2 0.3\n");
    let path = write(
        &dir,
        "s.toml",
        "[[mesh]]\nfile = \"tri.obj\"\nscale = 2\ntranslate = [10, 0, 0]\n\
         [[mesh]]\nfile = \"tri.obj\"\nscale = [-1, 1, 1]\nmaterial = \"x\"\n[materials.x]\ndiffuse = [1, 1, 1]\n",
    );
    let s = load_scene(&path).unwrap();
    assert_eq!(s.mesh.len(), 2);
    assert_eq!(
        s.mesh.corners(0),
        [
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(12.0, 0.0, 0.0),
            Vec3::new(10.0, 2.0, 0.0)
        ]
    );
    assert_eq!(
        s.materials[s.mesh.material[0] as usize].diffuse,
        Vec3::new(0.1, 0.2, 0.3)
    );
    assert_eq!(s.materials[s.mesh.material[1] as usize].name, "x");
    // The mirrored copy keeps its outward (+z) normal.
    assert!(s.mesh.geometric_normal(1).z > 0.99);
}

// ---------------------------------------------------------------- OBJ errors

fn obj(
    text: impl AsRef<[u8]>,
) -> (
    PathBuf,
    packet_render::Result<packet_render::scene::load::ObjMesh>,
) {
    let dir = temp_dir("obj");
    let path = write(&dir, "m.obj", text);
    let r = load_obj(&path);
    (path, r)
}

#[test]
fn obj_nan_vertex_reports_its_line() {
    let (p, r) = obj("# x\nv 0 0 0\nv 1 0 0\n\nv 0 nan 0\nf 1 2 3\n");
    assert_input_error(r, &p, 5, Some(1), "not finite");
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n");
    assert_input_error(r, &p, 3, None, "coordinate inf is not finite");
}

#[test]
fn obj_out_of_range_face_index_reports_its_line() {
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n");
    assert_input_error(r, &p, 5, Some(1), "index 4 is out of range");
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
    assert_input_error(r, &p, 4, None, "-4");
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    assert_input_error(r, &p, 4, None, "start at 1");
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n");
    assert_input_error(r, &p, 4, None, "integer vertex index");
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n");
    assert_input_error(r, &p, 5, None, "normal index 2");
    // A face may only use vertices defined above it.
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n");
    assert_input_error(r, &p, 3, None, "index 3");
}

#[test]
fn obj_degenerate_records() {
    let (p, r) = obj("v 0 0 0\nv 1 0 0\nf 1 2\n");
    assert_input_error(r, &p, 3, None, "at least 3");
    let (p, r) = obj("v 0 0\n");
    assert_input_error(r, &p, 1, None, "three numbers");
}

#[test]
fn obj_empty_and_binary_garbage() {
    // No faces (empty, or vertices only) is an empty mesh with a warning (issue 13),
    // and as a scene it is framed and renderable.
    for text in ["", "# only a comment\nv 0 0 0\n"] {
        let (p, r) = obj(text);
        let mesh = r.unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert!(mesh.indices.is_empty());
        assert!(
            mesh.warnings.iter().any(|w| w.contains("no triangles")),
            "{:?}",
            mesh.warnings
        );
        let scene = load_obj_scene(&p).unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_eq!(scene.mesh.len(), 0);
        assert_eq!(scene.lights.len(), 1);
    }
    let mut garbage = b"v 0 0 0\n".to_vec();
    garbage.extend((0..4096u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8 | 0x80));
    let (p, r) = obj(&garbage);
    assert_input_error(r, &p, 2, Some(1), "UTF-8");
    // Garbage that happens to be text must not panic either.
    for text in [
        "f",
        "v",
        "f 1/2/3/4",
        "vt",
        "usemtl",
        "mtllib",
        "o",
        "v 1 2 3 0",
        "f a b c",
    ] {
        // an input error, or (no face at all) an empty mesh with its warning
        match obj(text).1 {
            Err(Error::Input { .. }) => {}
            Ok(m) => assert!(
                m.indices.is_empty() && m.warnings.iter().any(|w| w.contains("no triangles")),
                "{text:?}: {m:?}"
            ),
            Err(e) => panic!("{text:?}: not an input error: {e:?}"),
        }
    }
}

#[test]
fn obj_with_mtl_maps_illumination_models() {
    let dir = temp_dir("mtl");
    write(
        &dir,
        "m.mtl",
        "newmtl chrome\nKd 0 0 0\nKs 0.9 0.8 0.7\nillum 3\n\
         newmtl plainmirror\nillum 3\n\
         newmtl glass4\nKd 0.1 0.1 0.1\nNi 1.33\nd 0.2\nillum 4\n\
         newmtl glass7\nNi 1.7\nillum 7\n\
         newmtl grey\nKd 0.5\nillum 1\n\
         newmtl lamp\nKe 2 2 2\n",
    );
    let mut text = String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for m in ["chrome", "plainmirror", "glass4", "glass7", "grey", "lamp"] {
        text += &format!("usemtl {m}\nf 1 2 3\n");
    }
    let path = write(&dir, "m.obj", &text);
    let mesh = load_obj(&path).unwrap();
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
    let by_name = |n: &str| mesh.materials.iter().find(|m| m.name == n).unwrap().clone();
    assert_eq!(by_name("chrome").mirror, Vec3::new(0.9, 0.8, 0.7));
    assert_eq!(by_name("plainmirror").mirror, Vec3::ONE);
    let g4 = by_name("glass4");
    assert_eq!((g4.ior, g4.transmission), (1.33, Vec3::splat(0.8)));
    let g7 = by_name("glass7");
    assert_eq!(
        (g7.ior, g7.transmission, g7.mirror),
        (1.7, Vec3::ONE, Vec3::ZERO)
    );
    assert_eq!(by_name("grey").diffuse, Vec3::splat(0.5));
    assert_eq!(by_name("lamp").emission, Vec3::splat(2.0));
    // Per-triangle material ids follow `usemtl`.
    let names: Vec<&str> = mesh
        .material_ids
        .iter()
        .map(|&i| mesh.materials[i as usize].name.as_str())
        .collect();
    assert_eq!(
        names,
        ["chrome", "plainmirror", "glass4", "glass7", "grey", "lamp"]
    );
}

#[test]
fn missing_mtl_is_a_warning_but_malformed_mtl_is_an_error() {
    let dir = temp_dir("nomtl");
    let path = write(
        &dir,
        "m.obj",
        "mtllib absent.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n",
    );
    let mesh = load_obj(&path).unwrap();
    assert_eq!(mesh.materials.len(), 1);
    assert!(
        mesh.warnings.iter().any(|w| w.contains("absent.mtl")),
        "{:?}",
        mesh.warnings
    );

    let mtl = write(&dir, "bad.mtl", "newmtl a\nKd 0.5 0.5\n");
    let path = write(
        &dir,
        "b.obj",
        "mtllib bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    assert_input_error(load_obj(&path), &mtl, 2, Some(1), "Kd");
}

#[test]
fn obj_scene_is_framed_and_lit() {
    let dir = temp_dir("objscene");
    let path = write(
        &dir,
        "q.obj",
        "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nf 1 2 3 4\n",
    );
    let s = load_obj_scene(&path).unwrap();
    assert_eq!(s.mesh.len(), 2, "a quad is split as a fan");
    assert_eq!(s.camera.target, Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(s.lights.len(), 1);
    assert!(s.ambient.max_element() > 0.0 && s.background.max_element() > 0.0);
    assert!(load_scene(&path).is_ok());
}

#[test]
fn benchmark_meshes_load_when_present() {
    for (name, triangles) in [("bunny.obj", 69_451), ("teapot.obj", 6_320)] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/models")
            .join(name);
        if !path.is_file() {
            eprintln!("SKIPPED: {} not present", path.display());
            continue;
        }
        let mesh = load_obj(&path).unwrap();
        assert_eq!(mesh.indices.len(), triangles, "{name}");
    }
}

#[test]
fn readme_example_is_a_valid_scene() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let start = readme.find("```toml\n").expect("a ```toml block") + "```toml\n".len();
    let len = readme[start..].find("```").unwrap();
    // Named as if it sat in scenes/, so its mesh path resolves.
    let scene = parse_toml_scene(
        &readme[start..start + len],
        &dir.join("readme-example.toml"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    // Its own sphere, the flake, and the two spheres of the Whitted room.
    assert_eq!(scene.spheres.len(), 1 + sphereflake_count(3) + 2);
    assert_eq!((scene.settings.width, scene.settings.spp), (640, 4));
}

#[test]
fn toml_orthographic_camera() {
    let (_, r) = toml(
        "[camera]\nprojection = \"orthographic\"\nheight = 2.5\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n",
    );
    assert_eq!(r.unwrap().camera_effects.ortho_height, Some(2.5));
    let (_, r) = toml("[camera]\nprojection = \"perspective\"\n");
    assert_eq!(r.unwrap().camera_effects.ortho_height, None);
    let (p, r) = toml("[camera]\nprojection = \"orthographic\"\n");
    assert_input_error(r, &p, 2, Some(14), "needs `height`");
    let (p, r) = toml("[camera]\nheight = 2\n");
    assert_input_error(r, &p, 2, Some(10), "needs `projection");
    let (p, r) = toml("[camera]\nprojection = \"fisheye\"\n");
    assert_input_error(r, &p, 2, Some(14), "unknown projection");
    let (p, r) = toml("[camera]\nprojection = \"orthographic\"\nheight = -1\n");
    assert_input_error(r, &p, 3, Some(10), "height");
    let (p, r) = toml("[camera]\nprojection = \"orthographic\"\nheight = 1\naperture = 0.1\n");
    assert_input_error(r, &p, 2, Some(14), "no lens");
}

#[test]
fn toml_spot_light() {
    let (_, r) = toml(
        "[[light]]\ntype = \"spot\"\nposition = [0, 2, 0]\ndirection = [0, -2, 0]\nintensity = [5, 5, 5]\ncone_angle = 40\nfalloff = 10\n",
    );
    match r.unwrap().lights[0] {
        Light::Spot {
            direction,
            cos_total,
            cos_falloff_start,
            ..
        } => {
            assert_eq!(direction, Vec3::NEG_Y);
            assert_eq!(cos_total, 40f32.to_radians().cos());
            assert_eq!(cos_falloff_start, 30f32.to_radians().cos());
        }
        other => panic!("expected a spot light, got {other:?}"),
    }
    let spot = "[[light]]\ntype = \"spot\"\nposition = [0, 2, 0]\ndirection = [0, -1, 0]\nintensity = [5, 5, 5]\n";
    let (p, r) = toml(&format!("{spot}cone_angle = 91\n"));
    assert_input_error(r, &p, 6, Some(14), "cone_angle");
    let (p, r) = toml(&format!("{spot}cone_angle = 20\nfalloff = 25\n"));
    assert_input_error(r, &p, 7, Some(11), "falloff");
    let (p, r) = toml(
        "[[light]]\ntype = \"point\"\nposition = [0, 2, 0]\nintensity = [5, 5, 5]\ncone_angle = 20\n",
    );
    assert_input_error(r, &p, 5, Some(14), "spot light");
    let (p, r) = toml("[[light]]\ntype = \"spot\"\nposition = [0, 2, 0]\nintensity = [5, 5, 5]\n");
    assert_input_error(r, &p, 1, None, "missing `direction`");
}

/// `--up-axis` / `--look-from-side` re-frame a loaded OBJ around its bounds.
#[test]
fn obj_scene_reframed_from_a_side() {
    use packet_render::scene::{CameraOverrides, Side, UpAxis};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/gem.obj");
    let mut scene = load_obj_scene(&path).unwrap();
    let auto = scene.camera;
    let o = CameraOverrides {
        side: Some(Side::Front),
        up_axis: Some(UpAxis::Z),
        ..Default::default()
    };
    o.apply_to_scene(&mut scene).unwrap();
    let c = scene.camera;
    assert_ne!(c, auto);
    assert_eq!(c.target, scene.bounds.center());
    let d = c.eye - c.target;
    // front with Z up looks from -Y: the offset (0, -1.2 d, 0) adds nothing to x and
    // z, so they are exactly the centre's
    assert!(d.y < 0.0 && d.x == 0.0 && d.z == 0.0, "{d}");
    assert_eq!(c.up, Vec3::Z);
    // no camera flag leaves the scene as loaded
    let mut again = load_obj_scene(&path).unwrap();
    CameraOverrides::default()
        .apply_to_scene(&mut again)
        .unwrap();
    assert_eq!(again.camera, auto);
}
