//! Instancing (two-level structure) and infinite planes: memory, equality with the
//! flattened scene, self-intersection under large transforms, analytic plane hits,
//! shadows blocked by a plane, TOML errors with locations.

use glam::{EulerRot, Mat4, Quat, Vec3};
use packet_render::accel::{AccelKind, BatchScratch, PrimRef, SceneAccel};
use packet_render::geometry::{Ray, offset_ray_origin};
use packet_render::integrator::interaction::SurfaceInteraction;
use packet_render::integrator::{RenderOptions, recursive};
use packet_render::scene::load::parse_toml_scene;
use packet_render::scene::procedural::tessellated_mesh;
use packet_render::scene::{Affine, Camera, Material, Plane, SceneBuilder, TriangleMesh};
use std::path::Path;

/// A mesh built by a generator, taken out of a builder to serve as an object.
fn object(triangles: usize) -> (TriangleMesh, Vec<Material>) {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material {
        diffuse: Vec3::new(0.7, 0.6, 0.5),
        ..Material::default()
    });
    tessellated_mesh(&mut b, triangles, Vec3::ZERO, 1.0, m);
    (b.mesh, b.materials)
}

/// Placements: rotations, non-uniform scales, translations, one mirror.
fn placements() -> Vec<Mat4> {
    (0..8)
        .map(|i| {
            let f = i as f32;
            let scale = if i == 3 {
                Vec3::new(-0.8, 0.8, 0.8)
            } else {
                Vec3::new(0.6 + 0.1 * f, 0.8, 0.7 + 0.05 * f)
            };
            Mat4::from_scale_rotation_translation(
                scale,
                Quat::from_euler(EulerRot::XYZ, 0.3 * f, 0.7 * f, -0.2 * f),
                Vec3::new((i % 4) as f32 * 2.2 - 3.3, (i / 4) as f32 * 2.2 - 1.1, 0.0),
            )
        })
        .collect()
}

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 0.0, 9.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        vfov_deg: 60.0,
    }
}

fn instanced_scene(mesh: &TriangleMesh, mats: &[Material], xf: &[Mat4]) -> SceneBuilder {
    let mut b = SceneBuilder::new();
    b.materials = mats.to_vec();
    let red = b.add_material(Material {
        diffuse: Vec3::new(0.8, 0.1, 0.1),
        ..Material::default()
    });
    let o = b.instances.add_object("blob", mesh.clone());
    for (i, m) in xf.iter().enumerate() {
        let material = (i == 5).then_some(red);
        b.instances.add_instance(o, *m, material).unwrap();
    }
    b
}

#[test]
fn eight_instances_cost_one_mesh_of_memory() {
    // A 200k-triangle object, placed once and eight times.
    let (mesh, mats) = object(200_000);
    assert!(mesh.len() >= 200_000, "{} triangles", mesh.len());
    let xf = placements();
    let mut mem = Vec::new();
    for n in [1usize, 8] {
        let mut b = instanced_scene(&mesh, &mats, &xf[..n]);
        b.camera = Some(camera());
        let scene = b.finish().unwrap();
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        let info = accel.info();
        let inst = info.iter().find(|i| i.name == "instances").unwrap();
        assert_eq!(inst.primitives, n);
        let two_level = accel.instances.as_ref().unwrap();
        mem.push((inst.memory_bytes, two_level.blas_memory_bytes()));
        eprintln!(
            "{n} instance(s) of {} triangles: accel memory {} bytes (BLAS {}, top level {})",
            mesh.len(),
            inst.memory_bytes,
            two_level.blas_memory_bytes(),
            two_level.top_memory_bytes()
        );
    }
    let (one, eight) = (mem[0].0, mem[1].0);
    // The bottom level is the same structure, built once, whatever the instance count.
    assert_eq!(mem[0].1, mem[1].1);
    // Bound: 1.1 x one instance plus 256 bytes per extra instance for the top level
    // (two 48-byte matrices are stored in the scene; the structure keeps one inverse,
    // an object index, a leaf reference and about one 32-byte node per instance).
    let bound = one as f64 * 1.1 + 7.0 * 256.0;
    assert!(
        (eight as f64) < bound,
        "8 instances: {eight} bytes, 1 instance: {one} bytes, bound {bound}"
    );
    // And the scene stores the object's triangles once.
    assert!(
        one > 200_000 * 16,
        "a 200k-triangle BLAS cannot be {one} bytes"
    );
}

#[test]
fn instanced_scene_matches_the_flattened_one() {
    let (mesh, mats) = object(3_000);
    let xf = placements();
    let mut inst = instanced_scene(&mesh, &mats, &xf);
    // Flattened: the same object baked into world space with the same f32 map and the
    // same winding rule (a mirror swaps two corners), one mesh per instance.
    let mut flat = SceneBuilder::new();
    flat.materials = inst.materials.clone();
    for (i, m) in xf.iter().enumerate() {
        let a = Affine::from_mat4(*m);
        let positions: Vec<Vec3> = (0..mesh.vertex_count() as u32)
            .map(|v| a.point(mesh.vertex(v)))
            .collect();
        let inv = a.inverse().unwrap();
        let normals: Vec<Vec3> = (0..mesh.vertex_count())
            .map(|v| {
                inv.transpose_vector(Vec3::new(mesh.nxs[v], mesh.nys[v], mesh.nzs[v]))
                    .normalize_or_zero()
            })
            .collect();
        let flip = a.determinant() < 0.0;
        let indices: Vec<[u32; 3]> = (0..mesh.len())
            .map(|t| {
                let [x, y, z] = [mesh.i0[t], mesh.i1[t], mesh.i2[t]];
                if flip { [x, z, y] } else { [x, y, z] }
            })
            .collect();
        let material = if i == 5 { 1 } else { 0 };
        flat.add_mesh(&positions, &normals, &indices, material);
    }
    for b in [&mut inst, &mut flat] {
        b.camera = Some(camera());
        b.add_light(packet_render::scene::Light::Point {
            position: Vec3::new(4.0, 6.0, 8.0),
            intensity: Vec3::splat(60.0),
        });
        b.background = Vec3::new(0.1, 0.2, 0.3);
    }
    let (inst, flat) = (inst.finish().unwrap(), flat.finish().unwrap());
    // The instances' padded world boxes contain the baked vertices.
    assert!(inst.bounds.min.cmple(flat.bounds.min).all());
    assert!(inst.bounds.max.cmpge(flat.bounds.max).all());
    let n = mesh.len() as u32;
    let (w, h) = (96u32, 64u32);
    for kind in [AccelKind::Bvh4, AccelKind::Bvh8, AccelKind::Bvh2] {
        let (ai, af) = (
            SceneAccel::build(&inst, kind),
            SceneAccel::build(&flat, kind),
        );
        // Hit ids on pixel-centre rays: exactly equal, except where the two hits lie
        // within 1e-4 (barycentric) of an edge on both sides: there the baked corners
        // and the object-space ray round differently and either neighbour is right.
        let frame = inst.camera_frame(w, h);
        let (mut same, mut edge) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
                let (a, b) = (ai.closest_hit(&ray), af.closest_hit(&ray));
                let ids = |h: Option<packet_render::accel::SceneHit>| {
                    h.map(|h| match h.prim {
                        PrimRef::Instance { instance, prim } => instance * n + prim,
                        PrimRef::Triangle(t) => t,
                        p => panic!("unexpected {p:?}"),
                    })
                };
                if ids(a) == ids(b) {
                    same += 1;
                    if let (Some(a), Some(b)) = (a, b) {
                        // Same triangle: same distance to 1e-5 relative (the ray is
                        // mapped into object space, the corners into world space).
                        assert!(
                            (a.t - b.t).abs() <= 1e-5 * b.t,
                            "{kind} {x},{y}: {a:?} {b:?}"
                        );
                    }
                    continue;
                }
                let near_edge = |h: Option<packet_render::accel::SceneHit>| {
                    h.is_some_and(|h| h.u.min(h.v).min(1.0 - h.u - h.v) < 1e-4)
                };
                assert!(
                    near_edge(a) && near_edge(b),
                    "{kind} pixel {x},{y}: instanced {a:?} vs flattened {b:?}"
                );
                edge += 1;
            }
        }
        eprintln!("{kind}: {same} pixel-centre rays hit the same triangle, {edge} edge ties");
        assert!(edge * 200 <= (w * h) as usize, "{edge} edge ties on {kind}");

        // Images: per channel within 1e-5 absolute (values are O(1); the differences
        // come from world points, normals and shadow origins computed through the
        // transform instead of baked corners, a few ulps each: measured 1.1e-6 on
        // BVH2/4/8), outside the pixels whose centre ray was an edge tie.
        let mut opts = RenderOptions::from_scene(&inst);
        opts.width = w;
        opts.height = h;
        let (ri, rf) = (
            recursive::render(&inst, &ai, &opts),
            recursive::render(&flat, &af, &opts),
        );
        // The wavefront integrator (ray queues, batch queries) renders the same bits
        // as the recursive one through instances, as it does for flat meshes.
        let wave = packet_render::integrator::wavefront::render(&inst, &ai, &opts);
        assert!(
            wave.film.pixels == ri.film.pixels,
            "{kind}: wavefront differs"
        );
        let mut worst = 0.0f32;
        let mut differing = 0;
        for (i, (p, q)) in ri.film.pixels.iter().zip(&rf.film.pixels).enumerate() {
            let d = (*p - *q).abs().max_element();
            worst = worst.max(d);
            if d > 1e-5 {
                differing += 1;
                eprintln!("{kind}: pixel {i} differs by {d}: {p} vs {q}");
            }
        }
        eprintln!("{kind}: largest pixel difference {worst}");
        assert!(
            differing <= edge,
            "{differing} pixels differ, {edge} edge ties"
        );
    }
}

/// An axis-aligned cube `[-1, 1]^3`, 12 outward-wound triangles.
fn cube() -> TriangleMesh {
    let mut b = SceneBuilder::new();
    let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let faces = [
        (c(-1.0, -1.0, 1.0), c(2.0, 0.0, 0.0), c(0.0, 2.0, 0.0)),
        (c(1.0, -1.0, -1.0), c(-2.0, 0.0, 0.0), c(0.0, 2.0, 0.0)),
        (c(1.0, -1.0, 1.0), c(0.0, 0.0, -2.0), c(0.0, 2.0, 0.0)),
        (c(-1.0, -1.0, -1.0), c(0.0, 0.0, 2.0), c(0.0, 2.0, 0.0)),
        (c(-1.0, 1.0, 1.0), c(2.0, 0.0, 0.0), c(0.0, 0.0, -2.0)),
        (c(-1.0, -1.0, -1.0), c(2.0, 0.0, 0.0), c(0.0, 0.0, 2.0)),
    ];
    for (corner, e1, e2) in faces {
        b.add_quad(corner, e1, e2, 0);
    }
    b.mesh
}

/// xorshift in [-1, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 23) as f32 - 1.0
    }
    fn dir(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.next(), self.next(), self.next());
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

#[test]
fn rays_leaving_instanced_surfaces_never_rehit_them() {
    // A closed convex cube under large translations (up to 1e4 times its size) and
    // scales: a ray leaving a hit outwards must hit nothing, a ray leaving inwards must
    // reach another face. Precondition for the inward rays (as in
    // tests/suite/robustness_watertight.rs): the hit lies more than 8 offset distances from
    // the face's edges, all of them sharp (90°); closer, f32 cannot place an origin
    // inside the wedge and the ray leaves through the neighbouring face. At scale 1e-3
    // and offset 1e4 the cube is about one f32 ulp wide and no inward origin exists:
    // such placements are outside what the renderer can resolve and are not tested.
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut checked, mut self_hits, mut skipped, mut tested) = (0u32, 0u32, 0u32, 0u32);
    for (scale, offset) in [
        (1.0, 0.0),
        (1e3, 1e6),
        (1e-3, 1.0),
        (50.0, -3e5),
        (0.2, 2e3),
    ] {
        let xf = Mat4::from_scale_rotation_translation(
            Vec3::new(scale, scale * 0.7, scale * 1.3),
            Quat::from_euler(EulerRot::XYZ, 0.4, 1.1, -0.8),
            Vec3::new(offset, -0.5 * offset, 0.25 * offset),
        );
        let mut b = SceneBuilder::new();
        let o = b.instances.add_object("cube", cube());
        b.instances.add_instance(o, xf, None).unwrap();
        b.camera = Some(camera());
        let scene = b.finish().unwrap();
        let centre = xf.transform_point3(Vec3::ZERO);
        for kind in [AccelKind::Bvh4, AccelKind::Bvh2, AccelKind::KdTree] {
            let accel = SceneAccel::build(&scene, kind);
            for _ in 0..400 {
                // From outside towards a random point near the centre.
                let from = centre + rng.dir() * (scale * 10.0);
                let to = centre + rng.dir() * (scale * 0.5 * rng.next().abs());
                let ray = Ray::new(from, to - from);
                let Some(hit) = accel.closest_hit(&ray) else {
                    panic!("{kind} scale {scale}: a ray aimed at the cube missed it");
                };
                let si = SurfaceInteraction::new(&scene, &ray, &hit);
                let face = match hit.prim {
                    PrimRef::Instance { prim, .. } => prim / 2,
                    p => panic!("{p:?}"),
                };
                let n = si.n_geometric; // faces the incoming ray: outward here
                // Clearance from the face's edges in world units, from the exact
                // (f64) object-space point.
                let inv = xf.as_dmat4().inverse();
                let q = inv.transform_point3(si.p.as_dvec3());
                let axis = [2, 2, 0, 0, 1, 1][face as usize]; // cube(): z, x, y pairs
                let clearance = (0..3)
                    .filter(|&a| a != axis)
                    .map(|a| 1.0 - q[a].abs())
                    .fold(f64::INFINITY, f64::min)
                    * (scale * 0.7) as f64;
                let offset = n.abs().dot(si.p_error) as f64;
                let inward_ok = clearance > 8.0 * offset;
                skipped += !inward_ok as u32;
                tested += 1;
                for _ in 0..4 {
                    let mut w = rng.dir();
                    if w.dot(n) < 0.0 {
                        w = -w;
                    }
                    let out = Ray::new(offset_ray_origin(si.p, si.p_error, n, w), w);
                    checked += 1;
                    if accel.any_hit(&out) {
                        self_hits += 1;
                    }
                    if !inward_ok {
                        continue;
                    }
                    let inward = Ray::new(offset_ray_origin(si.p, si.p_error, n, -w), -w);
                    match accel.closest_hit(&inward) {
                        Some(h) => match h.prim {
                            PrimRef::Instance { prim, .. } if prim / 2 != face => {}
                            _ => self_hits += 1,
                        },
                        None => self_hits += 1, // escaped through the surface
                    }
                    checked += 1;
                }
            }
        }
    }
    eprintln!(
        "{checked} rays from instanced hits, {self_hits} self-hits or escapes; \
         inward rays skipped near edges at {skipped} of {tested} hits"
    );
    assert_eq!(self_hits, 0);
    assert!(
        skipped * 20 < tested,
        "the edge precondition skipped {skipped} of {tested}"
    );
}

fn plane_scene() -> packet_render::scene::Scene {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::default());
    b.planes.push(Plane {
        point: Vec3::new(3.0, 0.0, -7.0),
        normal: Vec3::Y,
        material: m,
    });
    // Bounded geometry too, so every structure has something to build.
    b.add_sphere(Vec3::new(0.0, 5.0, 0.0), 1.0, m);
    b.add_triangle(
        Vec3::new(-1.0, 8.0, -1.0),
        Vec3::new(1.0, 8.0, -1.0),
        Vec3::new(0.0, 8.0, 1.0),
        m,
    );
    b.camera = Some(camera());
    b.finish().unwrap()
}

#[test]
fn infinite_plane_analytic_hit_and_shadow_on_every_structure() {
    let scene = plane_scene();
    // The plane leaves the bounds alone.
    assert!(scene.bounds.min.y > 3.0, "{:?}", scene.bounds);
    // From (10, 2, 10) along (0, -1, 1): meets y = 0 at t = 2 exactly, far outside
    // the bounded geometry.
    let down = Ray::new(Vec3::new(10.0, 2.0, 10.0), Vec3::new(0.0, -1.0, 1.0));
    // A shadow segment from above the plane to a light below it, and one that stays
    // above.
    let below = Ray::segment(
        Vec3::new(50.0, 1.0, 0.0),
        Vec3::new(0.0, -2.0, 0.0),
        0.0,
        1.0,
    );
    let above = Ray::segment(
        Vec3::new(50.0, 1.0, 0.0),
        Vec3::new(0.0, 0.5, 0.0),
        0.0,
        1.0,
    );
    let short = Ray::segment(
        Vec3::new(50.0, 1.0, 0.0),
        Vec3::new(0.0, -2.0, 0.0),
        0.0,
        0.4,
    );
    for &kind in AccelKind::ALL {
        let accel = SceneAccel::build(&scene, kind);
        let h = accel.closest_hit(&down).unwrap();
        assert_eq!((h.t, h.prim), (2.0, PrimRef::Plane(0)), "{kind}");
        assert!(accel.any_hit(&below), "{kind}");
        assert!(!accel.any_hit(&above), "{kind}");
        assert!(
            !accel.any_hit(&short),
            "{kind}: the segment ends above the plane"
        );
        let rays = [down, below, above, short];
        let mut hits = [None; 4];
        let mut blocked = [false; 4];
        let mut scratch = BatchScratch::default();
        accel.closest_hit_batch(&rays, &mut hits, &mut scratch);
        accel.any_hit_batch(&rays, &mut blocked, &mut scratch);
        assert_eq!(
            hits[0].map(|h| (h.t, h.prim)),
            Some((2.0, PrimRef::Plane(0)))
        );
        assert_eq!(blocked, [true, true, false, false], "{kind}");
        // The surface: on the plane, normal up, and a ray leaving it upwards is free.
        let si = SurfaceInteraction::new(&scene, &down, &h);
        assert_eq!(si.p, Vec3::new(10.0, 0.0, 12.0));
        assert_eq!(si.n_geometric, Vec3::Y);
        // The sphere above (0, 5, 0) blocks the way up from the plane under it.
        let up = Ray::new(Vec3::new(0.0, 0.0, 0.0), Vec3::Y);
        assert_eq!(
            accel.closest_hit(&up).map(|h| h.prim),
            Some(PrimRef::Sphere(0))
        );
        let all = accel.all_hits(&Ray::new(Vec3::new(0.0, 20.0, 0.0), -Vec3::Y), false);
        let prims: Vec<PrimRef> = all.iter().map(|c| c.hit.prim).collect();
        assert_eq!(
            prims,
            [
                PrimRef::Triangle(0),
                PrimRef::Sphere(0),
                PrimRef::Sphere(0),
                PrimRef::Plane(0)
            ],
            "{kind}"
        );
    }
}

#[test]
fn toml_instances_planes_and_their_errors() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene_path = dir.join("inline.toml");
    let obj = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models/teapot.obj");
    if !obj.is_file() {
        eprintln!("SKIPPED: {} not found", obj.display());
        return;
    }
    let file = obj.display().to_string();
    let text = format!(
        r#"
[materials.red]
diffuse = [0.8, 0.1, 0.1]

[[mesh]]
name = "pot"
file = "{file}"
instance_only = true

[[instance]]
object = "pot"
translate = [3, 0, 0]

[[instance]]
object = "pot"
matrix = [[0, 0, 1, -3], [0, 1, 0, 0], [-1, 0, 0, 0]]
material = "red"

[[plane]]
point = [0, -1, 0]
normal = [0, 1, 0]
"#
    );
    let scene = parse_toml_scene(&text, &scene_path).unwrap();
    assert_eq!(scene.instances.objects.len(), 1);
    assert_eq!(scene.instances.instances.len(), 2);
    assert_eq!(scene.mesh.len(), 0, "instance_only: nothing drawn in place");
    assert_eq!(scene.planes.len(), 1);
    assert_eq!(scene.instances.instances[1].material, Some(0));
    assert_eq!(
        scene.instances.instances[1].to_world.m[0],
        [0.0, 0.0, 1.0, -3.0]
    );

    // An unknown object: an error at its line (line 4 of this text).
    let bad = "[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n[[instance]]\nobject = \"nope\"\n";
    let e = parse_toml_scene(bad, &scene_path).unwrap_err().to_string();
    assert!(
        e.contains("inline.toml:5:") && e.contains("unknown object `nope`"),
        "{e}"
    );
    // matrix and translate together, a singular matrix, a non-affine last row.
    let with = |body: &str| {
        format!(
            "[[mesh]]\nname = \"pot\"\nfile = \"{file}\"\n[[instance]]\nobject = \"pot\"\n{body}\n"
        )
    };
    for (body, msg) in [
        (
            "translate = [1, 0, 0]\nmatrix = [[1,0,0,0],[0,1,0,0],[0,0,1,0]]",
            "not both",
        ),
        ("matrix = [[1,0,0,0],[0,0,0,0],[0,0,1,0]]", "singular"),
        (
            "matrix = [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]",
            "affine",
        ),
    ] {
        let e = parse_toml_scene(&with(body), &scene_path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("inline.toml:") && e.contains(msg), "{body}: {e}");
    }
    let e = parse_toml_scene(
        &format!("[[mesh]]\nfile = \"{file}\"\ninstance_only = true\n"),
        &scene_path,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("inline.toml:3:") && e.contains("needs a `name`"),
        "{e}"
    );
}
