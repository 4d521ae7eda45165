//! TOML scene files; the format is documented with a complete example in
//! `scenes/README.md`.
//!
//! Values that can be wrong in meaning, not just in type, are deserialized as
//! `toml::Spanned`, so a semantic error (an unknown material, a negative radius, a
//! `nan` — TOML accepts `nan` and `inf` — or an absurd image size) points at the
//! offending value, like the syntax and type errors `toml` itself reports. Tagged
//! things (`[[light]]`, `[[generator]]`) are flat structs with a `type` field checked
//! here rather than serde enums: serde's internally tagged enums buffer their content
//! and would lose the spans.

use super::{
    add_obj_mesh, line_column, load_mesh_with, obj::utf8_or_located_error, print_warnings,
};
use crate::error::{Error, Result};
use crate::scene::limits::{MAX_DEPTH, MAX_EFFECT_SAMPLES, MAX_IMAGE_SIDE, MAX_SPP};
use crate::scene::procedural::{sphereflake, sphereflake_count, tessellated_mesh, whitted_room};
use crate::scene::{Camera, CameraEffects, Checker, Light, Material, Scene, SceneBuilder};
use crate::texture::{Encoding, Procedural, ProceduralKind, TextureCache, TextureRef, WrapMode};
use glam::{Mat3, Mat4, Vec3};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// Deepest sphereflake accepted (level 6 is 597,871 spheres).
pub const MAX_SPHEREFLAKE_LEVEL: u32 = 6;
/// Largest tessellated mesh accepted.
pub const MAX_GENERATED_TRIANGLES: u64 = 50_000_000;

pub(super) type V3 = Spanned<[f32; 3]>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    render: Option<RenderDef>,
    camera: Option<Spanned<CameraDef>>,
    background: Option<V3>,
    ambient: Option<V3>,
    environment: Option<Spanned<super::toml_environment::EnvironmentDef>>,
    #[serde(default)]
    materials: BTreeMap<String, MaterialDef>,
    #[serde(default)]
    light: Vec<Spanned<LightDef>>,
    #[serde(default)]
    sphere: Vec<SphereDef>,
    #[serde(default)]
    quad: Vec<QuadDef>,
    #[serde(default)]
    plane: Vec<PlaneDef>,
    #[serde(default)]
    mesh: Vec<MeshDef>,
    #[serde(default)]
    instance: Vec<super::toml_instance::InstanceDef>,
    #[serde(default)]
    generator: Vec<Spanned<GeneratorDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderDef {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    spp: Option<Spanned<u32>>,
    max_depth: Option<Spanned<u32>>,
    min_contribution: Option<Spanned<f32>>,
    samples: Option<SamplesDef>,
    transmitted_shadows: Option<bool>,
}

/// `samples = { eye = 1, shadow = 16, glossy = 4, lens = 1, time = 1, environment = 4 }`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SamplesDef {
    eye: Option<Spanned<u32>>,
    shadow: Option<Spanned<u32>>,
    glossy: Option<Spanned<u32>>,
    lens: Option<Spanned<u32>>,
    time: Option<Spanned<u32>>,
    environment: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDef {
    eye: Option<V3>,
    target: Option<V3>,
    up: Option<V3>,
    fov: Option<Spanned<f32>>,
    aperture: Option<Spanned<f32>>,
    focus_distance: Option<Spanned<f32>>,
    aperture_blades: Option<Spanned<u32>>,
    aperture_rotation: Option<Spanned<f32>>,
    shutter: Option<Spanned<[f32; 2]>>,
    eye1: Option<V3>,
    projection: Option<Spanned<String>>,
    height: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialDef {
    preset: Option<Spanned<String>>,
    diffuse: Option<V3>,
    specular: Option<V3>,
    shininess: Option<Spanned<f32>>,
    mirror: Option<V3>,
    transmission: Option<V3>,
    ior: Option<Spanned<f32>>,
    emission: Option<V3>,
    checker: Option<CheckerDef>,
    glossy: Option<V3>,
    gloss_exponent: Option<Spanned<f32>>,
    translucency_exponent: Option<Spanned<f32>>,
    /// A file name or `{ procedural = ..., ... }` (see `texture_ref`).
    texture: Option<Spanned<toml::Value>>,
    specular_texture: Option<Spanned<toml::Value>>,
    alpha_texture: Option<Spanned<toml::Value>>,
    wrap: Option<Spanned<String>>,
    uv_scale: Option<Spanned<[f32; 2]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CheckerDef {
    a: V3,
    b: V3,
    scale: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightDef {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    position: Option<V3>,
    intensity: Option<V3>,
    direction: Option<V3>,
    irradiance: Option<V3>,
    corner: Option<V3>,
    edge1: Option<V3>,
    edge2: Option<V3>,
    center: Option<V3>,
    normal: Option<V3>,
    radius: Option<Spanned<f32>>,
    radiance: Option<V3>,
    cone_angle: Option<Spanned<f32>>,
    falloff: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereDef {
    center: V3,
    radius: Spanned<f32>,
    material: Option<Spanned<String>>,
    velocity: Option<V3>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct QuadDef {
    corner: V3,
    edge1: V3,
    edge2: V3,
    material: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlaneDef {
    point: V3,
    normal: V3,
    /// Half-extent of a finite square; without it the plane is infinite.
    size: Option<Spanned<f32>>,
    material: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshDef {
    pub(super) file: Spanned<String>,
    /// Makes the mesh an object that `[[instance]]` entries can place.
    pub(super) name: Option<Spanned<String>>,
    /// With `name`: the mesh is drawn only through its instances.
    pub(super) instance_only: Option<Spanned<bool>>,
    material: Option<Spanned<String>>,
    translate: Option<V3>,
    scale: Option<Spanned<toml::Value>>,
    rotate_y: Option<Spanned<f32>>,
    rotate: Option<V3>,
    pub(super) velocity: Option<V3>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GeneratorDef {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    level: Option<Spanned<u32>>,
    triangles: Option<Spanned<u64>>,
    center: Option<V3>,
    radius: Option<Spanned<f32>>,
    material: Option<Spanned<String>>,
}

/// Reads and builds a TOML scene file.
pub fn load_toml_scene(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = utf8_or_located_error(path, &bytes)?;
    parse_toml_scene(text, path)
}

/// Builds a scene from TOML `text`; `path` names it in errors and anchors relative
/// mesh paths.
pub fn parse_toml_scene(text: &str, path: &Path) -> Result<Scene> {
    let cx = Ctx { path, text };
    let file: SceneFile = toml::from_str(text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        cx.error(&span, e.message().trim_end().to_string())
    })?;
    Builder::new(cx, &file.materials)?.build(file)
}

/// The file being read, to turn spans into locations.
#[derive(Clone, Copy)]
pub(super) struct Ctx<'a> {
    pub(super) path: &'a Path,
    pub(super) text: &'a str,
}

impl Ctx<'_> {
    pub(super) fn error(&self, span: &Range<usize>, message: impl Into<String>) -> Error {
        let (line, column) = line_column(self.text, span.start);
        Error::input(self.path, line, column, message)
    }

    pub(super) fn at<T>(&self, v: &Spanned<T>, message: impl Into<String>) -> Error {
        self.error(&v.span(), message)
    }

    pub(super) fn vec3(&self, v: &V3, what: &str) -> Result<Vec3> {
        let p = Vec3::from_array(*v.get_ref());
        if !p.is_finite() {
            return Err(self.at(v, format!("`{what}` must be three finite numbers, got {p}")));
        }
        Ok(p)
    }

    fn color(&self, v: &V3, what: &str) -> Result<Vec3> {
        let c = self.vec3(v, what)?;
        if c.min_element() < 0.0 {
            return Err(self.at(v, format!("`{what}` must be non-negative, got {c}")));
        }
        Ok(c)
    }

    fn direction(&self, v: &V3, what: &str) -> Result<Vec3> {
        let d = self.vec3(v, what)?;
        if d.length_squared() < 1e-20 {
            return Err(self.at(v, format!("`{what}` must be a non-zero vector")));
        }
        Ok(d)
    }

    fn positive(&self, v: &Spanned<f32>, what: &str) -> Result<f32> {
        let x = *v.get_ref();
        if !(x.is_finite() && x > 0.0) {
            return Err(self.at(v, format!("`{what}` must be a finite number > 0, got {x}")));
        }
        Ok(x)
    }

    fn range_u32(&self, v: &Spanned<u32>, what: &str, lo: u32, hi: u32) -> Result<u32> {
        let x = *v.get_ref();
        if x < lo || x > hi {
            return Err(self.at(
                v,
                format!("`{what}` must be between {lo} and {hi}, got {x}"),
            ));
        }
        Ok(x)
    }
}

pub(super) struct Builder<'a> {
    pub(super) cx: Ctx<'a>,
    pub(super) b: SceneBuilder,
    /// Every texture of the scene (TOML materials and the meshes' MTL files).
    textures: TextureCache,
    material_ids: BTreeMap<String, u32>,
    default_material: Option<u32>,
}

impl<'a> Builder<'a> {
    fn new(cx: Ctx<'a>, defs: &BTreeMap<String, MaterialDef>) -> Result<Self> {
        let mut b = SceneBuilder::new();
        let mut material_ids = BTreeMap::new();
        let mut textures = TextureCache::new();
        for (name, def) in defs {
            let m = material(cx, name, def, &mut textures)?;
            material_ids.insert(name.clone(), b.add_material(m));
        }
        Ok(Builder {
            cx,
            b,
            textures,
            material_ids,
            default_material: None,
        })
    }

    /// The id of a named material; no name means the default grey diffuse material.
    pub(super) fn material(&mut self, name: &Option<Spanned<String>>) -> Result<u32> {
        let Some(name) = name else {
            let b = &mut self.b;
            return Ok(*self
                .default_material
                .get_or_insert_with(|| b.add_material(Material::default())));
        };
        self.material_ids
            .get(name.get_ref())
            .copied()
            .ok_or_else(|| {
                let defined = if self.material_ids.is_empty() {
                    "no materials are defined (add a [materials.NAME] table)".to_string()
                } else {
                    format!(
                        "defined materials: {}",
                        self.material_ids
                            .keys()
                            .map(String::as_str)
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                self.cx.at(
                    name,
                    format!("unknown material `{}`; {defined}", name.get_ref()),
                )
            })
    }

    fn build(mut self, file: SceneFile) -> Result<Scene> {
        let cx = self.cx;
        // Generators first: `whitted_room` sets a camera, lights and background that
        // the file's own settings then override.
        for g in &file.generator {
            self.generator(g)?;
        }
        for s in &file.sphere {
            let center = cx.vec3(&s.center, "center")?;
            let radius = cx.positive(&s.radius, "radius")?;
            let m = self.material(&s.material)?;
            match &s.velocity {
                Some(v) => {
                    let v = cx.vec3(v, "velocity")?;
                    self.b.add_moving_sphere(center, radius, v, m);
                }
                None => self.b.add_sphere(center, radius, m),
            }
        }
        for q in &file.quad {
            let corner = cx.vec3(&q.corner, "corner")?;
            let e1 = cx.direction(&q.edge1, "edge1")?;
            let e2 = cx.direction(&q.edge2, "edge2")?;
            if e1.cross(e2).length_squared() <= 1e-12 * e1.length_squared() * e2.length_squared() {
                return Err(cx.at(
                    &q.edge2,
                    "`edge2` is parallel to `edge1`: a quad needs two independent edges",
                ));
            }
            let m = self.material(&q.material)?;
            self.b.add_quad(corner, e1, e2, m);
        }
        for p in &file.plane {
            let point = cx.vec3(&p.point, "point")?;
            let n = cx.direction(&p.normal, "normal")?.normalize();
            let m = self.material(&p.material)?;
            let Some(size) = &p.size else {
                self.b.planes.push(crate::scene::Plane {
                    point,
                    normal: n,
                    material: m,
                });
                continue;
            };
            let size = cx.positive(size, "size")?;
            // A square of half-extent `size` around `point`, wound so e1 × e2 = n.
            let (t, bt) = tangent_frame(n);
            self.b
                .add_quad(point - size * (t + bt), 2.0 * size * t, 2.0 * size * bt, m);
        }
        let mut objects = super::toml_instance::Objects::default();
        for mesh in &file.mesh {
            match (&mesh.name, &mesh.instance_only) {
                (Some(_), _) => objects.mesh(&mut self, mesh)?,
                (None, Some(io)) => {
                    return Err(cx.at(io, "`instance_only` needs a `name` on the same [[mesh]]"));
                }
                (None, None) => self.mesh(mesh)?,
            }
        }
        for i in &file.instance {
            objects.instance(&mut self, i)?;
        }
        for l in &file.light {
            let light = light(cx, l)?;
            self.b.add_light(light);
        }
        if let Some(r) = &file.render {
            self.render_settings(r)?;
        }
        if let Some(bg) = &file.background {
            self.b.background = cx.color(bg, "background")?;
        }
        if let Some(a) = &file.ambient {
            self.b.ambient = cx.color(a, "ambient")?;
        }
        if let Some(e) = &file.environment {
            let env =
                super::toml_environment::environment(e.get_ref(), e.span(), cx.path, cx.text)?;
            self.b.environment = Some(std::sync::Arc::new(env));
        }
        if let Some(c) = &file.camera {
            self.b.camera_effects = camera_effects(cx, c.get_ref())?;
            self.b.camera = Some(self.camera(c)?);
        }
        self.b.finish()
    }

    fn render_settings(&mut self, r: &RenderDef) -> Result<()> {
        let cx = self.cx;
        let s = &mut self.b.settings;
        if let Some(w) = &r.width {
            s.width = cx.range_u32(w, "width", 1, MAX_IMAGE_SIDE)?;
        }
        if let Some(h) = &r.height {
            s.height = cx.range_u32(h, "height", 1, MAX_IMAGE_SIDE)?;
        }
        if (s.width as u64) * (s.height as u64) > 1 << 30 {
            let span = r
                .width
                .as_ref()
                .or(r.height.as_ref())
                .map_or(0..0, |v| v.span());
            return Err(cx.error(
                &span,
                format!("{}x{} exceeds 2^30 pixels", s.width, s.height),
            ));
        }
        if let Some(spp) = &r.spp {
            s.spp = cx.range_u32(spp, "spp", 1, MAX_SPP)?;
        }
        if let Some(d) = &r.max_depth {
            s.max_depth = cx.range_u32(d, "max_depth", 0, MAX_DEPTH)?;
        }
        if let Some(mc) = &r.min_contribution {
            let x = *mc.get_ref();
            if !(0.0..=1.0).contains(&x) {
                return Err(cx.at(
                    mc,
                    format!("`min_contribution` must be between 0 and 1, got {x}"),
                ));
            }
            s.min_contribution = x;
        }
        if let Some(on) = r.transmitted_shadows {
            s.transmitted_shadows = on;
        }
        if let Some(n) = &r.samples {
            if let Some(eye) = &n.eye {
                let e = cx.range_u32(eye, "eye", 1, MAX_SPP)?;
                if let Some(spp) = &r.spp
                    && *spp.get_ref() != e
                {
                    return Err(cx.at(
                        eye,
                        format!(
                            "`samples.eye` ({e}) and `spp` ({}) disagree; give one",
                            spp.get_ref()
                        ),
                    ));
                }
                s.spp = e;
            }
            let counts = [
                (&n.shadow, "shadow", &mut s.samples.shadow),
                (&n.glossy, "glossy", &mut s.samples.glossy),
                (&n.lens, "lens", &mut s.samples.lens),
                (&n.time, "time", &mut s.samples.time),
                (&n.environment, "environment", &mut s.samples.environment),
            ];
            for (value, what, slot) in counts {
                if let Some(v) = value {
                    *slot = cx.range_u32(v, what, 1, MAX_EFFECT_SAMPLES)?;
                }
            }
        }
        Ok(())
    }

    /// Missing `eye`/`target` come from the automatic framing of the scene's bounds.
    fn camera(&self, c: &Spanned<CameraDef>) -> Result<Camera> {
        let cx = self.cx;
        let def = c.get_ref();
        let framing = Camera::framing(&self.b.bounds());
        let eye = def
            .eye
            .as_ref()
            .map(|v| cx.vec3(v, "eye"))
            .transpose()?
            .unwrap_or(framing.eye);
        let target = def
            .target
            .as_ref()
            .map(|v| cx.vec3(v, "target"))
            .transpose()?
            .unwrap_or(framing.target);
        let up = def
            .up
            .as_ref()
            .map(|v| cx.direction(v, "up"))
            .transpose()?
            .unwrap_or(Vec3::Y);
        let vfov_deg = match &def.fov {
            Some(f) => {
                let x = *f.get_ref();
                if !(x > 0.0 && x < 180.0) {
                    return Err(cx.at(
                        f,
                        format!("`fov` must be between 0 and 180 degrees (exclusive), got {x}"),
                    ));
                }
                x
            }
            None => 45.0,
        };
        let camera = Camera {
            eye,
            target,
            up,
            vfov_deg,
        };
        let anchor = def
            .eye
            .as_ref()
            .or(def.target.as_ref())
            .map_or(c.span(), |v| v.span());
        camera
            .validate()
            .map_err(|e| cx.error(&anchor, format!("invalid camera: {e}")))?;
        Ok(camera)
    }

    pub(super) fn mesh(&mut self, def: &MeshDef) -> Result<()> {
        let cx = self.cx;
        let dir = cx.path.parent().unwrap_or(Path::new(""));
        let resolved = dir.join(def.file.get_ref());
        if !resolved.is_file() {
            return Err(cx.at(
                &def.file,
                format!(
                    "mesh file `{}` not found (resolved to {})",
                    def.file.get_ref(),
                    resolved.display()
                ),
            ));
        }
        let transform = mesh_transform(cx, &def.placement())?;
        let material = def
            .material
            .as_ref()
            .map(|_| self.material(&def.material))
            .transpose()?;
        let mesh = load_mesh_with(&resolved, &mut self.textures)?;
        print_warnings(&mesh.warnings);
        // Finite vertices can overflow under a large scale or translation; say which
        // mesh entry did it rather than leave it to the scene-wide check.
        if let Some(p) = mesh
            .positions
            .iter()
            .find(|p| !transform.transform_point3(**p).is_finite())
        {
            return Err(cx.at(
                &def.file,
                format!(
                    "mesh `{}`: vertex {p} is not finite after scale, rotate and translate",
                    def.file.get_ref()
                ),
            ));
        }
        match &def.velocity {
            None => {
                add_obj_mesh(&mut self.b, &mesh, transform, material);
            }
            Some(v) => {
                let velocity = cx.vec3(v, "velocity")?;
                // Load into an empty static mesh (materials go to the scene as usual),
                // then move those triangles to the moving set.
                let saved = std::mem::take(&mut self.b.mesh);
                add_obj_mesh(&mut self.b, &mesh, transform, material);
                let moving = std::mem::replace(&mut self.b.mesh, saved);
                self.b.motion.add_mesh(&moving, velocity);
            }
        }
        Ok(())
    }

    fn generator(&mut self, g: &Spanned<GeneratorDef>) -> Result<()> {
        let cx = self.cx;
        let def = g.get_ref();
        let kind = def.kind.get_ref().as_str();
        let fields: &[&str] = match kind {
            "sphereflake" => &["level", "center", "radius", "material"],
            "tessellated" => &["triangles", "center", "radius", "material"],
            "whitted_room" => &[],
            other => {
                return Err(cx.at(
                    &def.kind,
                    format!("unknown generator type `{other}`; expected one of: sphereflake, tessellated, whitted_room"),
                ));
            }
        };
        let present = [
            ("level", def.level.as_ref().map(|v| v.span())),
            ("triangles", def.triangles.as_ref().map(|v| v.span())),
            ("center", def.center.as_ref().map(|v| v.span())),
            ("radius", def.radius.as_ref().map(|v| v.span())),
            ("material", def.material.as_ref().map(|v| v.span())),
        ];
        reject_foreign_fields(cx, &present, fields, &format!("a `{kind}` generator"))?;
        let center = def
            .center
            .as_ref()
            .map(|v| cx.vec3(v, "center"))
            .transpose()?
            .unwrap_or(Vec3::ZERO);
        let radius = def
            .radius
            .as_ref()
            .map(|v| cx.positive(v, "radius"))
            .transpose()?
            .unwrap_or(1.0);
        match kind {
            "sphereflake" => {
                let level = match &def.level {
                    Some(l) => cx.range_u32(l, "level", 0, MAX_SPHEREFLAKE_LEVEL)?,
                    None => return Err(cx.at(g, "a sphereflake generator needs `level` (0..=6)")),
                };
                let m = self.material(&def.material)?;
                let n = sphereflake(&mut self.b, level, center, radius, m);
                debug_assert_eq!(n, sphereflake_count(level));
            }
            "tessellated" => {
                let triangles = match &def.triangles {
                    Some(t) if (1..=MAX_GENERATED_TRIANGLES).contains(t.get_ref()) => {
                        *t.get_ref() as usize
                    }
                    Some(t) => {
                        return Err(cx.at(
                            t,
                            format!("`triangles` must be between 1 and {MAX_GENERATED_TRIANGLES}, got {}", t.get_ref()),
                        ));
                    }
                    None => return Err(cx.at(g, "a tessellated generator needs `triangles`")),
                };
                let m = self.material(&def.material)?;
                tessellated_mesh(&mut self.b, triangles, center, radius, m);
            }
            _ => whitted_room(&mut self.b),
        }
        Ok(())
    }
}

fn material(
    cx: Ctx,
    name: &str,
    def: &MaterialDef,
    textures: &mut TextureCache,
) -> Result<Material> {
    let mut m = match &def.preset {
        None => Material::diffuse(name, Vec3::splat(0.8)),
        Some(p) => {
            match p.get_ref().as_str() {
                "diffuse" => Material::diffuse(name, Vec3::splat(0.8)),
                "mirror" => Material::mirror(name, Vec3::splat(0.9)),
                "glass" => Material::glass(name, 1.5),
                other => {
                    return Err(cx.at(p, format!("unknown material preset `{other}`; expected one of: diffuse, mirror, glass")));
                }
            }
        }
    };
    let colours = [
        (&def.diffuse, "diffuse", &mut m.diffuse),
        (&def.specular, "specular", &mut m.specular),
        (&def.mirror, "mirror", &mut m.mirror),
        (&def.transmission, "transmission", &mut m.transmission),
        (&def.emission, "emission", &mut m.emission),
    ];
    for (value, what, slot) in colours {
        if let Some(v) = value {
            *slot = cx.color(v, what)?;
        }
    }
    if let Some(s) = &def.shininess {
        let x = *s.get_ref();
        if !(x.is_finite() && x >= 0.0) {
            return Err(cx.at(
                s,
                format!("`shininess` must be a finite number >= 0, got {x}"),
            ));
        }
        m.shininess = x;
    }
    if let Some(ior) = &def.ior {
        m.ior = cx.positive(ior, "ior")?;
    }
    if let Some(g) = &def.glossy {
        m.glossy = cx.color(g, "glossy")?;
    }
    if let Some(e) = &def.gloss_exponent {
        m.gloss_exponent = non_negative(cx, e, "gloss_exponent")?;
    }
    if let Some(e) = &def.translucency_exponent {
        m.translucency_exponent = non_negative(cx, e, "translucency_exponent")?;
        if m.translucency_exponent > 0.0 && !m.is_transmissive() {
            return Err(cx.at(
                e,
                "`translucency_exponent` blurs refraction: the material needs `transmission` (or preset = \"glass\")",
            ));
        }
    }
    if let Some(c) = &def.checker {
        m.checker = Some(Checker {
            color_a: cx.color(&c.a, "a")?,
            color_b: cx.color(&c.b, "b")?,
            scale: c
                .scale
                .as_ref()
                .map(|s| cx.positive(s, "scale"))
                .transpose()?
                .unwrap_or(1.0),
        });
    }
    material_textures(cx, def, textures, &mut m)?;
    Ok(m)
}

/// `texture`, `specular_texture`, `alpha_texture`, with `wrap` and `uv_scale` for all
/// three. A colour texture replaces the default colour of its lobe by 1 (white) unless
/// the lobe's colour is given, which it then multiplies.
fn material_textures(
    cx: Ctx,
    def: &MaterialDef,
    cache: &mut TextureCache,
    m: &mut Material,
) -> Result<()> {
    let wrap = match &def.wrap {
        None => WrapMode::Repeat,
        Some(w) => WrapMode::parse(w.get_ref()).ok_or_else(|| {
            cx.at(
                w,
                format!(
                    "unknown wrap `{}`; expected one of: repeat, clamp, mirror",
                    w.get_ref()
                ),
            )
        })?,
    };
    let scale = match &def.uv_scale {
        None => glam::Vec2::ONE,
        Some(s) => {
            let v = glam::Vec2::from_array(*s.get_ref());
            if !(v.is_finite() && v.x != 0.0 && v.y != 0.0) {
                return Err(cx.at(
                    s,
                    format!("`uv_scale` must be two finite non-zero numbers, got {v}"),
                ));
            }
            v
        }
    };
    let mut load =
        |v: &Option<Spanned<toml::Value>>, what: &str, encoding| -> Result<Option<TextureRef>> {
            let Some(v) = v else { return Ok(None) };
            let texture = texture_value(cx, v, what, encoding, cache)?;
            Ok(Some(TextureRef {
                texture,
                wrap,
                scale,
                offset: glam::Vec2::ZERO,
            }))
        };
    m.textures.diffuse = load(&def.texture, "texture", Encoding::Srgb)?;
    m.textures.specular = load(&def.specular_texture, "specular_texture", Encoding::Srgb)?;
    m.textures.alpha = load(&def.alpha_texture, "alpha_texture", Encoding::Linear)?;
    if m.textures.diffuse.is_some() && def.diffuse.is_none() {
        m.diffuse = Vec3::ONE;
    }
    if m.textures.specular.is_some() && def.specular.is_none() {
        m.specular = Vec3::ONE;
    }
    if m.textures.is_empty() && (def.wrap.is_some() || def.uv_scale.is_some()) {
        let at = def
            .wrap
            .as_ref()
            .map(|w| w.span())
            .or(def.uv_scale.as_ref().map(|s| s.span()));
        return Err(cx.error(
            &at.unwrap_or(0..0),
            "`wrap` and `uv_scale` apply to textures: the material has none",
        ));
    }
    Ok(())
}

/// A texture value: a file name (relative to the scene file; PNG, JPEG, TGA, HDR,
/// EXR) or a procedural description
/// `{ procedural = "checker"|"bricks"|"noise", size, cells, a, b, seed }`.
fn texture_value(
    cx: Ctx,
    v: &Spanned<toml::Value>,
    what: &str,
    encoding: Encoding,
    cache: &mut TextureCache,
) -> Result<std::sync::Arc<crate::texture::Texture>> {
    match v.get_ref() {
        toml::Value::String(file) => {
            let dir = cx.path.parent().unwrap_or(Path::new(""));
            let resolved = dir.join(file);
            if !resolved.is_file() {
                return Err(cx.at(
                    v,
                    format!(
                        "`{what}` file `{file}` not found (resolved to {})",
                        resolved.display()
                    ),
                ));
            }
            cache
                .get(&resolved, encoding)
                .map_err(|e| cx.at(v, format!("`{what}`: {e}")))
        }
        toml::Value::Table(t) => {
            let p = procedural(t).map_err(|msg| cx.at(v, format!("`{what}`: {msg}")))?;
            Ok(cache.insert_generated(p.key(), || p.render()))
        }
        other => Err(cx.at(
            v,
            format!(
                "`{what}` must be a file name or a table {{ procedural = \"checker\", ... }}, got a {}",
                other.type_str()
            ),
        )),
    }
}

/// Largest side of a procedural texture.
pub const MAX_PROCEDURAL_SIZE: u32 = 4096;

fn procedural(t: &toml::Table) -> std::result::Result<Procedural, String> {
    const KEYS: [&str; 6] = ["procedural", "size", "cells", "a", "b", "seed"];
    if let Some(k) = t.keys().find(|k| !KEYS.contains(&k.as_str())) {
        return Err(format!("unknown key `{k}`; expected: {}", KEYS.join(", ")));
    }
    let kind = match t.get("procedural") {
        Some(toml::Value::String(s)) => ProceduralKind::parse(s).ok_or_else(|| {
            format!("unknown procedural `{s}`; expected one of: checker, bricks, noise")
        })?,
        _ => return Err("needs `procedural = \"checker\"|\"bricks\"|\"noise\"`".into()),
    };
    let int = |k: &str, default: i64, lo: i64, hi: i64| -> std::result::Result<u32, String> {
        match t.get(k) {
            None => Ok(default as u32),
            Some(toml::Value::Integer(i)) if (lo..=hi).contains(i) => Ok(*i as u32),
            Some(v) => Err(format!("`{k}` must be an integer in {lo}..={hi}, got {v}")),
        }
    };
    let colour = |k: &str, default: Vec3| -> std::result::Result<Vec3, String> {
        let Some(v) = t.get(k) else {
            return Ok(default);
        };
        let nums: Option<Vec<f32>> = v.as_array().and_then(|a| {
            a.iter()
                .map(|x| {
                    x.as_float()
                        .or(x.as_integer().map(|i| i as f64))
                        .map(|f| f as f32)
                })
                .collect()
        });
        match nums.as_deref() {
            Some([r, g, b]) if [r, g, b].iter().all(|x| x.is_finite() && **x >= 0.0) => {
                Ok(Vec3::new(*r, *g, *b))
            }
            _ => Err(format!(
                "`{k}` must be three finite non-negative numbers, got {v}"
            )),
        }
    };
    Ok(Procedural {
        kind,
        size: int("size", 256, 1, MAX_PROCEDURAL_SIZE as i64)?,
        cells: int("cells", 8, 1, MAX_PROCEDURAL_SIZE as i64)?,
        a: colour("a", Vec3::splat(0.8))?,
        b: colour("b", Vec3::splat(0.2))?,
        seed: int("seed", 0, 0, u32::MAX as i64)?,
    })
}

fn light(cx: Ctx, l: &Spanned<LightDef>) -> Result<Light> {
    let def = l.get_ref();
    let kind = def.kind.get_ref().as_str();
    let fields: &[&str] = match kind {
        "point" => &["position", "intensity"],
        "directional" => &["direction", "irradiance"],
        "quad" => &["corner", "edge1", "edge2", "radiance"],
        "disk" => &["center", "normal", "radius", "radiance"],
        "sphere" => &["center", "radius", "radiance"],
        "spot" => &["position", "direction", "intensity"],
        other => {
            return Err(cx.at(
                &def.kind,
                format!(
                    "unknown light type `{other}`; expected one of: point, directional, spot, quad, disk, sphere"
                ),
            ));
        }
    };
    let span = |v: &Option<V3>| v.as_ref().map(|v| v.span());
    let present = [
        ("position", span(&def.position)),
        ("intensity", span(&def.intensity)),
        ("direction", span(&def.direction)),
        ("irradiance", span(&def.irradiance)),
        ("corner", span(&def.corner)),
        ("edge1", span(&def.edge1)),
        ("edge2", span(&def.edge2)),
        ("center", span(&def.center)),
        ("normal", span(&def.normal)),
        ("radius", def.radius.as_ref().map(|v| v.span())),
        ("radiance", span(&def.radiance)),
    ];
    let what = format!("a {kind} light");
    reject_foreign_fields(cx, &present, fields, &what)?;
    if kind != "spot" {
        // the spot's optional keys
        if let Some(f) = def.cone_angle.as_ref().or(def.falloff.as_ref()) {
            return Err(cx.at(
                f,
                format!("`cone_angle` and `falloff` are keys of a spot light, not of {what}"),
            ));
        }
    }
    if let Some((missing, _)) = present
        .iter()
        .find(|(name, span)| fields.contains(name) && span.is_none())
    {
        return Err(cx.at(
            l,
            format!(
                "{what} needs `{}` (missing `{missing}`)",
                fields.join("`, `")
            ),
        ));
    }
    // Every field this type needs is present (checked above).
    fn v(x: &Option<V3>) -> &V3 {
        x.as_ref().expect("checked present")
    }
    Ok(match kind {
        "point" => Light::Point {
            position: cx.vec3(v(&def.position), "position")?,
            intensity: cx.color(v(&def.intensity), "intensity")?,
        },
        "directional" => Light::Directional {
            direction: cx.direction(v(&def.direction), "direction")?.normalize(),
            irradiance: cx.color(v(&def.irradiance), "irradiance")?,
        },
        "quad" => {
            let edge1 = cx.direction(v(&def.edge1), "edge1")?;
            let edge2 = cx.direction(v(&def.edge2), "edge2")?;
            if edge1.cross(edge2).length_squared()
                <= 1e-12 * edge1.length_squared() * edge2.length_squared()
            {
                return Err(cx.at(
                    v(&def.edge2),
                    "`edge2` is parallel to `edge1`: a quad light needs two independent edges",
                ));
            }
            Light::Quad {
                corner: cx.vec3(v(&def.corner), "corner")?,
                edge1,
                edge2,
                radiance: cx.color(v(&def.radiance), "radiance")?,
            }
        }
        "disk" => Light::Disk {
            center: cx.vec3(v(&def.center), "center")?,
            normal: cx.direction(v(&def.normal), "normal")?.normalize(),
            radius: cx.positive(def.radius.as_ref().expect("checked present"), "radius")?,
            radiance: cx.color(v(&def.radiance), "radiance")?,
        },
        "spot" => spot_light(cx, def, v)?,
        _ => Light::Sphere {
            center: cx.vec3(v(&def.center), "center")?,
            radius: cx.positive(def.radius.as_ref().expect("checked present"), "radius")?,
            radiance: cx.color(v(&def.radiance), "radiance")?,
        },
    })
}

/// `type = "spot"`: `cone_angle` (half-angle of the cone in degrees, (0, 90], default
/// 30) and `falloff` (degrees of smooth edge inside it, [0, cone_angle], default 5),
/// as pbrt's `coneangle` and `conedelta`.
fn spot_light(cx: Ctx, def: &LightDef, v: fn(&Option<V3>) -> &V3) -> Result<Light> {
    let cone = match &def.cone_angle {
        Some(c) => {
            let x = *c.get_ref();
            if !(x > 0.0 && x <= 90.0) {
                return Err(cx.at(
                    c,
                    format!("`cone_angle` must be in (0, 90] degrees, got {x}"),
                ));
            }
            x
        }
        None => 30.0,
    };
    let falloff = match &def.falloff {
        Some(f) => {
            let x = *f.get_ref();
            if !(x >= 0.0 && x <= cone) {
                return Err(cx.at(
                    f,
                    format!("`falloff` must be in [0, cone_angle = {cone}] degrees, got {x}"),
                ));
            }
            x
        }
        None => 5f32.min(cone),
    };
    Ok(Light::Spot {
        position: cx.vec3(v(&def.position), "position")?,
        direction: cx.direction(v(&def.direction), "direction")?.normalize(),
        intensity: cx.color(v(&def.intensity), "intensity")?,
        cos_total: cone.to_radians().cos(),
        cos_falloff_start: (cone - falloff).to_radians().cos(),
    })
}

fn non_negative(cx: Ctx, v: &Spanned<f32>, what: &str) -> Result<f32> {
    let x = *v.get_ref();
    if !(x.is_finite() && x >= 0.0) {
        return Err(cx.at(v, format!("`{what}` must be a finite number >= 0, got {x}")));
    }
    Ok(x)
}

/// Lens and shutter keys of `[camera]`.
fn camera_effects(cx: Ctx, def: &CameraDef) -> Result<CameraEffects> {
    let mut e = CameraEffects::default();
    if let Some(a) = &def.aperture {
        e.aperture = non_negative(cx, a, "aperture")?;
    }
    if let Some(f) = &def.focus_distance {
        e.focus_distance = Some(cx.positive(f, "focus_distance")?);
    }
    if let Some(b) = &def.aperture_blades {
        let n = *b.get_ref();
        if n != 0 && !(3..=64).contains(&n) {
            return Err(cx.at(
                b,
                format!("`aperture_blades` must be 0 (round) or between 3 and 64, got {n}"),
            ));
        }
        e.aperture_blades = n;
    }
    if let Some(r) = &def.aperture_rotation {
        let x = *r.get_ref();
        if !x.is_finite() {
            return Err(cx.at(r, "`aperture_rotation` must be a finite number of degrees"));
        }
        e.aperture_rotation_deg = x;
    }
    if let Some(sh) = &def.shutter {
        let [open, close] = *sh.get_ref();
        if !(open.is_finite() && close.is_finite() && open <= close) {
            return Err(cx.at(
                sh,
                format!("`shutter` must be [open, close] with finite open <= close, got [{open}, {close}]"),
            ));
        }
        e.shutter = [open, close];
    }
    if let Some(e1) = &def.eye1 {
        e.eye1 = Some(cx.vec3(e1, "eye1")?);
    }
    e.ortho_height = projection(cx, def, e.aperture)?;
    Ok(e)
}

/// `projection = "perspective" | "orthographic"` and the orthographic `height`: the
/// image height in world units, for `orthographic` only (and then required).
fn projection(cx: Ctx, def: &CameraDef, aperture: f32) -> Result<Option<f32>> {
    let ortho = match &def.projection {
        None => false,
        Some(p) => {
            match p.get_ref().as_str() {
                "perspective" => false,
                "orthographic" => true,
                other => {
                    return Err(cx.at(
                    p,
                    format!("unknown projection `{other}`: expected \"perspective\" or \"orthographic\""),
                ));
                }
            }
        }
    };
    match (&def.height, ortho) {
        (Some(h), false) => Err(cx.at(
            h,
            "`height` is the orthographic image height: it needs `projection = \"orthographic\"`",
        )),
        (None, true) => Err(cx.at(
            def.projection.as_ref().expect("ortho has a projection key"),
            "`projection = \"orthographic\"` needs `height` (image height in world units, > 0)",
        )),
        (None, false) => Ok(None),
        (Some(h), true) => {
            let h = cx.positive(h, "height")?;
            if aperture > 0.0 {
                return Err(cx.at(
                    def.projection.as_ref().expect("ortho has a projection key"),
                    "an orthographic camera has no lens: `aperture` must be 0",
                ));
            }
            Ok(Some(h))
        }
    }
}

/// A field that exists in the struct but not for this `type` is an error at that field.
fn reject_foreign_fields(
    cx: Ctx,
    present: &[(&str, Option<Range<usize>>)],
    allowed: &[&str],
    what: &str,
) -> Result<()> {
    for (name, span) in present {
        if let Some(span) = span
            && !allowed.contains(name)
        {
            let expected = if allowed.is_empty() {
                "it takes no fields besides `type`".to_string()
            } else {
                format!("expected one of: type, {}", allowed.join(", "))
            };
            return Err(cx.error(
                span,
                format!("`{name}` is not a field of {what}; {expected}"),
            ));
        }
    }
    Ok(())
}

/// The transform fields shared by `[[mesh]]` and `[[instance]]`.
pub(super) struct Placement<'a> {
    pub(super) translate: &'a Option<V3>,
    pub(super) scale: &'a Option<Spanned<toml::Value>>,
    pub(super) rotate_y: &'a Option<Spanned<f32>>,
    pub(super) rotate: &'a Option<V3>,
}

impl MeshDef {
    pub(super) fn placement(&self) -> Placement<'_> {
        Placement {
            translate: &self.translate,
            scale: &self.scale,
            rotate_y: &self.rotate_y,
            rotate: &self.rotate,
        }
    }
}

/// `translate * rotate * scale`; rotations in degrees, applied about x, then y, then z.
pub(super) fn mesh_transform(cx: Ctx, def: &Placement) -> Result<Mat4> {
    let translate = def
        .translate
        .as_ref()
        .map(|v| cx.vec3(v, "translate"))
        .transpose()?
        .unwrap_or(Vec3::ZERO);
    let scale = match &def.scale {
        None => Vec3::ONE,
        Some(s) => {
            let bad = || {
                cx.at(
                    s,
                    "`scale` must be a non-zero finite number or an array [x, y, z] of them",
                )
            };
            let num = |v: &toml::Value| match v {
                toml::Value::Float(f) => Some(*f as f32),
                toml::Value::Integer(i) => Some(*i as f32),
                _ => None,
            };
            let v = match s.get_ref() {
                toml::Value::Array(a) if a.len() == 3 => {
                    let c: Option<Vec<f32>> = a.iter().map(num).collect();
                    c.map(|c| Vec3::new(c[0], c[1], c[2])).ok_or_else(bad)?
                }
                other => Vec3::splat(num(other).ok_or_else(bad)?),
            };
            if !v.is_finite() || v.x == 0.0 || v.y == 0.0 || v.z == 0.0 {
                return Err(bad());
            }
            v
        }
    };
    let degrees = match (&def.rotate, &def.rotate_y) {
        (Some(_), Some(ry)) => {
            return Err(cx.at(ry, "give either `rotate` or `rotate_y`, not both"));
        }
        (Some(r), None) => cx.vec3(r, "rotate")?,
        (None, Some(ry)) => {
            let y = *ry.get_ref();
            if !y.is_finite() {
                return Err(cx.at(
                    ry,
                    format!("`rotate_y` must be a finite number of degrees, got {y}"),
                ));
            }
            Vec3::new(0.0, y, 0.0)
        }
        (None, None) => Vec3::ZERO,
    };
    let r = Mat3::from_rotation_z(degrees.z.to_radians())
        * Mat3::from_rotation_y(degrees.y.to_radians())
        * Mat3::from_rotation_x(degrees.x.to_radians());
    Ok(Mat4::from_translation(translate) * Mat4::from_mat3(r) * Mat4::from_scale(scale))
}

/// Unit `(t, b)` with `t × b = n` for unit `n`.
fn tangent_frame(n: Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let b = n.cross(helper).normalize();
    let t = b.cross(n);
    (t, b)
}
