use crate::texture::MaterialTextures;
use glam::{Vec2, Vec3};

/// A material as a sum of lobes, each weighted by an RGB coefficient; a material uses
/// the lobes whose weight is non-zero, and the scene's [`Features`](super::Features)
/// record which lobes any material uses.
///
/// - diffuse (Lambert), optionally modulated by a checkerboard or an image texture;
/// - specular highlight (Blinn-Phong, exponent `shininess`) for direct light;
/// - `mirror`: perfect specular reflection without Fresnel (a metal);
/// - `transmission` with `ior`: a dielectric (glass): reflection and refraction weighted
///   by Schlick's Fresnel, total internal reflection past the critical angle;
/// - `glossy` with `gloss_exponent`: blurred reflection, directions drawn from the Phong
///   lobe `cos^n` around the mirror direction (distribution ray tracing, Cook 1984);
/// - `translucency_exponent` > 0 blurs the refracted ray of a dielectric the same way
///   (0 keeps it sharp).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub diffuse: Vec3,
    pub checker: Option<Checker>,
    pub specular: Vec3,
    pub shininess: f32,
    pub mirror: Vec3,
    pub transmission: Vec3,
    pub ior: f32,
    pub emission: Vec3,
    pub glossy: Vec3,
    pub gloss_exponent: f32,
    pub translucency_exponent: f32,
    /// Image textures over the surface's `uv` (diffuse, specular, cut-out).
    pub textures: MaterialTextures,
}

/// How far inside the surface, beyond the hit point's own error bound and relative to
/// the magnitude of its coordinates, [`Material::albedo_on_surface`] looks up a solid
/// texture: 64 ulps of 1. The error bound already puts the lookup point on the inside
/// whatever the rounding of the hit point; this margin adds the division by the cell
/// size (1 ulp) and a vertex typed as a decimal ("0.3"), which sits within an ulp of the
/// boundary it was meant for, with a factor of about 8 to spare.
pub const CHECKER_INSET: f32 = 64.0 * f32::EPSILON;

/// A 3D checkerboard: `color_a`/`color_b` alternate in cubes of edge `scale` (solid
/// texture, so it needs no UVs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checker {
    pub color_a: Vec3,
    pub color_b: Vec3,
    pub scale: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            diffuse: Vec3::splat(0.8),
            checker: None,
            specular: Vec3::ZERO,
            shininess: 32.0,
            mirror: Vec3::ZERO,
            transmission: Vec3::ZERO,
            ior: 1.5,
            emission: Vec3::ZERO,
            glossy: Vec3::ZERO,
            gloss_exponent: 100.0,
            translucency_exponent: 0.0,
            textures: MaterialTextures::default(),
        }
    }
}

impl Material {
    pub fn diffuse(name: &str, color: Vec3) -> Self {
        Material {
            name: name.into(),
            diffuse: color,
            ..Default::default()
        }
    }

    pub fn mirror(name: &str, color: Vec3) -> Self {
        Material {
            name: name.into(),
            diffuse: Vec3::ZERO,
            mirror: color,
            ..Default::default()
        }
    }

    pub fn glass(name: &str, ior: f32) -> Self {
        Material {
            name: name.into(),
            diffuse: Vec3::ZERO,
            transmission: Vec3::ONE,
            ior,
            ..Default::default()
        }
    }

    pub fn is_transmissive(&self) -> bool {
        self.transmission != Vec3::ZERO
    }

    pub fn is_glossy(&self) -> bool {
        self.glossy != Vec3::ZERO
    }

    /// A dielectric whose refracted ray is blurred.
    pub fn is_translucent(&self) -> bool {
        self.is_transmissive() && self.translucency_exponent > 0.0
    }

    /// Diffuse albedo at a world-space point (the checkerboard is a solid texture).
    pub fn albedo_at(&self, p: Vec3) -> Vec3 {
        match &self.checker {
            None => self.diffuse,
            Some(c) => {
                let q = (p / c.scale).floor();
                let parity = (q.x as i64 + q.y as i64 + q.z as i64).rem_euclid(2);
                if parity == 0 { c.color_a } else { c.color_b }
            }
        }
    }

    /// Diffuse albedo at a hit point `p` on a surface with outward (winding) normal
    /// `outward`, where `p_error` bounds the rounding error of `p` per component (the
    /// hit point's error box, pbrt-v4's `Point3fi`).
    ///
    /// The solid checkerboard `floor(p / scale)` is discontinuous on every cell
    /// boundary. A surface lying exactly on one (a floor at y = 1 with cells of 0.5)
    /// would flip between the two cells on the rounding noise of each hit point: salt
    /// and pepper. The texture is therefore looked up at a point moved *inside* the
    /// surface by twice its error bound `p_error` along the normal plus [`CHECKER_INSET`]
    /// times its magnitude, well above that noise: a surface on a
    /// boundary takes the cell behind it, the same from either side and for every
    /// pixel, and a surface crossing boundaries moves its checker edges by that inset
    /// (a few 1e-6 of the scene's scale), which no pixel shows.
    pub fn albedo_on_surface(&self, p: Vec3, p_error: Vec3, outward: Vec3) -> Vec3 {
        if self.checker.is_none() {
            return self.diffuse;
        }
        // The extent of the error box along the normal (pbrt-v4's offset distance),
        // twice: the lookup point lies beyond the box on the inside.
        let inset = 2.0 * outward.abs().dot(p_error) + CHECKER_INSET * p.abs().max_element();
        self.albedo_at(p - outward * inset)
    }

    /// Diffuse albedo and specular colour at a hit: [`albedo_on_surface`](Self::albedo_on_surface)
    /// (Self::albedo_on_surface), then each multiplied by its texture at `uv` if the
    /// material has one (the MTL rule: `map_Kd` times `Kd`).
    pub fn colours_on_surface(
        &self,
        p: Vec3,
        p_error: Vec3,
        outward: Vec3,
        uv: Vec2,
    ) -> (Vec3, Vec3) {
        let mut albedo = self.albedo_on_surface(p, p_error, outward);
        let mut specular = self.specular;
        if let Some(t) = &self.textures.diffuse {
            albedo *= t.rgb(uv);
        }
        if let Some(t) = &self.textures.specular {
            specular *= t.rgb(uv);
        }
        (albedo, specular)
    }

    /// Whether the material has a cut-out (alpha) map.
    pub fn has_cutout(&self) -> bool {
        self.textures.alpha.is_some()
    }

    pub fn validate(&self) -> Result<(), String> {
        let colours = [
            ("diffuse", self.diffuse),
            ("specular", self.specular),
            ("mirror", self.mirror),
            ("transmission", self.transmission),
            ("emission", self.emission),
            ("glossy", self.glossy),
        ];
        for (name, c) in colours {
            if !c.is_finite() || c.min_element() < 0.0 {
                return Err(format!("{name} must be finite and non-negative, got {c}"));
            }
        }
        if let Some(c) = &self.checker
            && !(c.scale.is_finite()
                && c.scale > 0.0
                && c.color_a.is_finite()
                && c.color_b.is_finite())
        {
            return Err("checker needs finite colours and a positive scale".into());
        }
        if !(self.shininess.is_finite() && self.shininess >= 0.0) {
            return Err(format!(
                "shininess must be finite and >= 0, got {}",
                self.shininess
            ));
        }
        for (name, x) in [
            ("gloss_exponent", self.gloss_exponent),
            ("translucency_exponent", self.translucency_exponent),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(format!("{name} must be finite and >= 0, got {x}"));
            }
        }
        if !(self.ior.is_finite() && self.ior > 0.0) {
            return Err(format!("ior must be finite and > 0, got {}", self.ior));
        }
        Ok(())
    }
}
