//! Collects a scene and validates all of it in [`SceneBuilder::finish`], the one way
//! every loader and generator makes a [`Scene`].

use super::{
    Camera, CameraEffects, Environment, Features, InstanceSet, Light, Material, MotionSet, Plane,
    RenderSettings, Scene, SphereSet, TriangleMesh, limits,
};
use crate::error::{Error, Result};
use crate::geometry::Aabb;
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// Collects geometry, materials and lights, and validates everything in [`finish`](Self::finish).
#[derive(Clone, Debug, Default)]
pub struct SceneBuilder {
    pub mesh: TriangleMesh,
    pub spheres: SphereSet,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    pub camera: Option<Camera>,
    pub camera_effects: CameraEffects,
    pub motion: MotionSet,
    pub instances: InstanceSet,
    pub planes: Vec<Plane>,
    pub background: Vec3,
    pub environment: Option<Arc<Environment>>,
    pub ambient: Vec3,
    pub settings: RenderSettings,
}

impl SceneBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn add_material(&mut self, m: Material) -> u32 {
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }

    /// Adds a light; an area light also gets emissive geometry of its shape (a quad,
    /// a 64-gon for a disk, a sphere) with a material emitting its radiance, so that
    /// camera, reflection and refraction rays see it.
    pub fn add_light(&mut self, l: Light) {
        self.lights.push(l);
        let emitter = |name: String, radiance: Vec3| Material {
            name,
            diffuse: Vec3::ZERO,
            emission: radiance,
            ..Material::default()
        };
        let name = format!("light{}", self.lights.len() - 1);
        match l {
            Light::Point { .. } | Light::Directional { .. } | Light::Spot { .. } => {}
            Light::Quad {
                corner,
                edge1,
                edge2,
                radiance,
            } => {
                let m = self.add_material(emitter(name, radiance));
                self.add_quad(corner, edge1, edge2, m);
            }
            Light::Disk {
                center,
                normal,
                radius,
                radiance,
            } => {
                let m = self.add_material(emitter(name, radiance));
                let (t, b) = crate::geometry::orthonormal_basis(normal.normalize());
                let c = self.add_vertex(center);
                const SIDES: u32 = 64;
                let first = self.mesh.xs.len() as u32;
                for i in 0..SIDES {
                    let a = std::f32::consts::TAU * i as f32 / SIDES as f32;
                    self.add_vertex(center + radius * (a.cos() * t + a.sin() * b));
                }
                for i in 0..SIDES {
                    self.add_triangle_indices(c, first + i, first + (i + 1) % SIDES, m);
                }
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let m = self.add_material(emitter(name, radiance));
                self.add_sphere(center, radius, m);
            }
        }
    }

    /// A sphere whose centre at time `t` is `center + t * velocity`.
    pub fn add_moving_sphere(&mut self, center: Vec3, radius: f32, velocity: Vec3, material: u32) {
        let s = &mut self.motion.spheres;
        s.cx.push(center.x);
        s.cy.push(center.y);
        s.cz.push(center.z);
        s.radius.push(radius);
        s.material.push(material);
        self.motion.sphere_velocity.push(velocity);
    }

    pub fn add_vertex(&mut self, p: Vec3) -> u32 {
        self.mesh.xs.push(p.x);
        self.mesh.ys.push(p.y);
        self.mesh.zs.push(p.z);
        (self.mesh.xs.len() - 1) as u32
    }

    pub fn add_triangle_indices(&mut self, a: u32, b: u32, c: u32, material: u32) {
        self.mesh.i0.push(a);
        self.mesh.i1.push(b);
        self.mesh.i2.push(c);
        self.mesh.material.push(material);
    }

    pub fn add_triangle(&mut self, v0: Vec3, v1: Vec3, v2: Vec3, material: u32) {
        let a = self.add_vertex(v0);
        let b = self.add_vertex(v1);
        let c = self.add_vertex(v2);
        self.add_triangle_indices(a, b, c, material);
    }

    /// A parallelogram `corner, corner + e1, corner + e1 + e2, corner + e2` as two triangles.
    pub fn add_quad(&mut self, corner: Vec3, e1: Vec3, e2: Vec3, material: u32) {
        let a = self.add_vertex(corner);
        let b = self.add_vertex(corner + e1);
        let c = self.add_vertex(corner + e1 + e2);
        let d = self.add_vertex(corner + e2);
        self.set_uvs(a, &[Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]);
        self.add_triangle_indices(a, b, c, material);
        self.add_triangle_indices(a, c, d, material);
    }

    /// Gives vertices `first..first + uvs.len()` (just added) texture coordinates;
    /// vertices before them without any get `(0, 0)`.
    pub fn set_uvs(&mut self, first: u32, uvs: &[Vec2]) {
        let m = &mut self.mesh;
        m.us.resize(first as usize, 0.0);
        m.vs.resize(first as usize, 0.0);
        m.us.extend(uvs.iter().map(|t| t.x));
        m.vs.extend(uvs.iter().map(|t| t.y));
    }

    /// Appends an indexed mesh. `normals` is either empty or one per position; a mesh
    /// without normals gets none, and if the scene mixes meshes with and without normals
    /// the missing ones are filled with zero (meaning "use the geometric normal").
    pub fn add_mesh(
        &mut self,
        positions: &[Vec3],
        normals: &[Vec3],
        indices: &[[u32; 3]],
        material: u32,
    ) {
        self.add_mesh_with_uvs(positions, normals, &[], indices, material);
    }

    /// [`add_mesh`](Self::add_mesh) with texture coordinates: `uvs` is empty or one
    /// per position.
    pub fn add_mesh_with_uvs(
        &mut self,
        positions: &[Vec3],
        normals: &[Vec3],
        uvs: &[Vec2],
        indices: &[[u32; 3]],
        material: u32,
    ) {
        let base = self.mesh.xs.len();
        if !uvs.is_empty() {
            self.set_uvs(base as u32, uvs);
        }
        let had = self.mesh.has_normals();
        let want = !normals.is_empty();
        if want && !had {
            self.mesh.nxs.resize(base, 0.0);
            self.mesh.nys.resize(base, 0.0);
            self.mesh.nzs.resize(base, 0.0);
        }
        for p in positions {
            self.add_vertex(*p);
        }
        if want {
            for n in normals {
                self.mesh.nxs.push(n.x);
                self.mesh.nys.push(n.y);
                self.mesh.nzs.push(n.z);
            }
        } else if had {
            let len = self.mesh.xs.len();
            self.mesh.nxs.resize(len, 0.0);
            self.mesh.nys.resize(len, 0.0);
            self.mesh.nzs.resize(len, 0.0);
        }
        let base = base as u32;
        for t in indices {
            self.add_triangle_indices(base + t[0], base + t[1], base + t[2], material);
        }
    }

    pub fn add_sphere(&mut self, center: Vec3, radius: f32, material: u32) {
        self.spheres.cx.push(center.x);
        self.spheres.cy.push(center.y);
        self.spheres.cz.push(center.z);
        self.spheres.radius.push(radius);
        self.spheres.material.push(material);
    }

    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for i in 0..self.mesh.xs.len() {
            b.grow(Vec3::new(self.mesh.xs[i], self.mesh.ys[i], self.mesh.zs[i]));
        }
        for i in 0..self.spheres.len() {
            b = b.union(&self.spheres.sphere_bounds(i));
        }
        if !self.motion.is_empty() {
            b = b.union(&self.motion.bounds(self.camera_effects.shutter));
        }
        for ib in self.instances.world_bounds() {
            b = b.union(&ib);
        }
        b
    }

    /// Validates and freezes the scene. Loaders check their input with locations first;
    /// this is the final guarantee for every path into a [`Scene`].
    pub fn finish(mut self) -> Result<Scene> {
        let bad = |msg: String| Err(Error::parameter("scene", msg));
        if self.materials.is_empty() {
            self.materials.push(Material::default());
        }
        let nmat = self.materials.len() as u32;
        let nv = self.mesh.xs.len() as u32;
        for i in 0..self.mesh.xs.len() {
            let p = Vec3::new(self.mesh.xs[i], self.mesh.ys[i], self.mesh.zs[i]);
            if !p.is_finite() {
                return bad(format!("vertex {i} is not finite: {p}"));
            }
        }
        // Vertices added one by one (quads, triangles) after a mesh with normals have
        // none: give them zero normals, meaning "use the geometric normal".
        if self.mesh.has_normals() && self.mesh.nxs.len() < self.mesh.xs.len() {
            let len = self.mesh.xs.len();
            self.mesh.nxs.resize(len, 0.0);
            self.mesh.nys.resize(len, 0.0);
            self.mesh.nzs.resize(len, 0.0);
        }
        if self.mesh.has_normals() && self.mesh.nxs.len() != self.mesh.xs.len() {
            return bad("normal count differs from vertex count".into());
        }
        // Likewise texture coordinates: vertices added after the last ones with
        // coordinates read (0, 0).
        if self.mesh.has_uvs() {
            let len = self.mesh.xs.len();
            if self.mesh.us.len() > len || self.mesh.vs.len() != self.mesh.us.len() {
                return bad("texture coordinate count differs from vertex count".into());
            }
            self.mesh.us.resize(len, 0.0);
            self.mesh.vs.resize(len, 0.0);
        }
        if let Some(i) = (0..self.mesh.us.len())
            .find(|&i| !(self.mesh.us[i].is_finite() && self.mesh.vs[i].is_finite()))
        {
            return bad(format!("texture coordinate {i} is not finite"));
        }
        for t in 0..self.mesh.len() {
            for idx in [self.mesh.i0[t], self.mesh.i1[t], self.mesh.i2[t]] {
                if idx >= nv {
                    return bad(format!(
                        "triangle {t} uses vertex {idx}, but there are {nv} vertices"
                    ));
                }
            }
            if self.mesh.material[t] >= nmat {
                return bad(format!(
                    "triangle {t} uses material {}, but there are {nmat}",
                    self.mesh.material[t]
                ));
            }
        }
        for i in 0..self.spheres.len() {
            let c = self.spheres.center(i);
            let r = self.spheres.radius[i];
            if !c.is_finite() || !r.is_finite() || r <= 0.0 {
                return bad(format!(
                    "sphere {i} has centre {c} and radius {r}: need finite values and radius > 0"
                ));
            }
            if self.spheres.material[i] >= nmat {
                return bad(format!(
                    "sphere {i} uses material {}, but there are {nmat}",
                    self.spheres.material[i]
                ));
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            m.validate().map_err(|e| {
                Error::parameter("material", format!("material {i} ({}): {e}", m.name))
            })?;
        }
        for (i, l) in self.lights.iter().enumerate() {
            l.validate()
                .map_err(|e| Error::parameter("light", format!("light {i}: {e}")))?;
        }
        self.validate_motion(nmat)?;
        self.instances
            .validate(nmat)
            .map_err(|e| Error::parameter("instance", e))?;
        for (i, p) in self.planes.iter().enumerate() {
            p.validate(nmat)
                .map_err(|e| Error::parameter("plane", format!("plane {i}: {e}")))?;
        }
        self.camera_effects
            .validate()
            .map_err(|e| Error::parameter("camera", e))?;
        let s = &self.settings;
        limits::validate_dimensions(s.width, s.height, s.spp, s.max_depth)?;
        limits::validate_sample_counts(&s.samples)?;

        let bounds = self.bounds();
        let camera = match self.camera {
            Some(c) => {
                c.validate().map_err(|e| Error::parameter("camera", e))?;
                c
            }
            None => Camera::framing(&bounds),
        };

        let used = |id: u32| {
            self.mesh.material.contains(&id)
                || self.spheres.material.contains(&id)
                || self.motion.mesh.material.contains(&id)
                || self.motion.spheres.material.contains(&id)
                || self.instances.uses_material(id)
                || self.planes.iter().any(|p| p.material == id)
        };
        let mut features = Features {
            triangles: !self.mesh.is_empty(),
            spheres: !self.spheres.is_empty(),
            shading_normals: self.mesh.has_normals() && !self.mesh.is_empty(),
            // a spot light is a point light with a cone: same shadow ray
            point_lights: self
                .lights
                .iter()
                .any(|l| matches!(l, Light::Point { .. } | Light::Spot { .. })),
            directional_lights: self
                .lights
                .iter()
                .any(|l| matches!(l, Light::Directional { .. })),
            area_lights: self.lights.iter().any(Light::is_area),
            depth_of_field: self.camera_effects.has_depth_of_field(),
            environment: self.environment.as_ref().is_some_and(|e| !e.is_black()),
            motion: self.camera_effects.shutter_open()
                && (self.camera_effects.eye1.is_some_and(|e| e != camera.eye)
                    || self.motion.sphere_velocity.iter().any(|v| *v != Vec3::ZERO)
                    || self
                        .motion
                        .triangle_velocity
                        .iter()
                        .any(|v| *v != Vec3::ZERO)),
            ..Features::default()
        };
        features.triangles |= !self.motion.mesh.is_empty();
        features.spheres |= !self.motion.spheres.is_empty();
        features.triangles |= !self.instances.is_empty();
        features.shading_normals |= self.instances.has_shading_normals();
        for (i, m) in self.materials.iter().enumerate() {
            if !used(i as u32) {
                continue;
            }
            features.diffuse |= m.diffuse != Vec3::ZERO || m.checker.is_some();
            features.specular |= m.specular != Vec3::ZERO;
            features.mirror |= m.mirror != Vec3::ZERO;
            features.glass |= m.is_transmissive();
            features.textures |= m.checker.is_some() || !m.textures.is_empty();
            features.emission |= m.emission != Vec3::ZERO;
            features.glossy |= m.is_glossy();
            features.translucency |= m.is_translucent();
        }

        Ok(Scene {
            mesh: self.mesh,
            spheres: self.spheres,
            materials: self.materials,
            lights: self.lights,
            camera,
            camera_effects: self.camera_effects,
            motion: self.motion,
            instances: self.instances,
            planes: self.planes,
            background: self.background,
            environment: self.environment,
            ambient: self.ambient,
            settings: self.settings,
            bounds,
            features,
        })
    }
}

impl SceneBuilder {
    fn validate_motion(&self, nmat: u32) -> Result<()> {
        let bad = |msg: String| Err(Error::parameter("moving geometry", msg));
        let m = &self.motion;
        if m.sphere_velocity.len() != m.spheres.len() || m.triangle_velocity.len() != m.mesh.len() {
            return bad("one velocity per moving sphere and triangle is needed".into());
        }
        for i in 0..m.spheres.len() {
            let (c, r, v) = (
                m.spheres.center(i),
                m.spheres.radius[i],
                m.sphere_velocity[i],
            );
            if !(c.is_finite() && v.is_finite() && r.is_finite() && r > 0.0) {
                return bad(format!(
                    "moving sphere {i}: centre {c}, radius {r}, velocity {v}: need finite values and radius > 0"
                ));
            }
            if m.spheres.material[i] >= nmat {
                return bad(format!(
                    "moving sphere {i} uses material {}, but there are {nmat}",
                    m.spheres.material[i]
                ));
            }
        }
        let nv = m.mesh.xs.len() as u32;
        for i in 0..m.mesh.xs.len() {
            let p = m.mesh.vertex(i as u32);
            if !p.is_finite() {
                return bad(format!("moving vertex {i} is not finite: {p}"));
            }
        }
        if m.mesh.has_normals() && m.mesh.nxs.len() != m.mesh.xs.len() {
            return bad("moving mesh: normal count differs from vertex count".into());
        }
        for t in 0..m.mesh.len() {
            if [m.mesh.i0[t], m.mesh.i1[t], m.mesh.i2[t]]
                .iter()
                .any(|&i| i >= nv)
            {
                return bad(format!("moving triangle {t} uses a vertex beyond {nv}"));
            }
            if m.mesh.material[t] >= nmat || !m.triangle_velocity[t].is_finite() {
                return bad(format!("moving triangle {t}: bad material or velocity"));
            }
        }
        Ok(())
    }
}
