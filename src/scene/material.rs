use glam::Vec3;

/// A material as a sum of lobes, each weighted by an RGB coefficient; a material uses
/// the lobes whose weight is non-zero, and the scene's [`Features`](super::Features)
/// record which lobes any material uses.
///
/// - diffuse (Lambert), optionally modulated by a checkerboard;
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
}

/// How far inside the surface, relative to the magnitude of the hit point's coordinates,
/// [`Material::albedo_on_surface`] looks up a solid texture: 64 ulps of 1. The
/// barycentric hit point is within about 4 ulps of the true surface, the division by
/// the cell size adds 1, and a vertex typed as a decimal ("0.3") sits within an ulp of
/// the boundary it was meant for; 64 leaves a factor of about 8 over their sum.
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
    /// `outward`, where `scale` bounds the magnitude of the coordinates `p` was computed
    /// from (the hit point's rounding error is a few ulps of it).
    ///
    /// The solid checkerboard `floor(p / scale)` is discontinuous on every cell
    /// boundary. A surface lying exactly on one (a floor at y = 1 with cells of 0.5)
    /// would flip between the two cells on the rounding noise of each hit point: salt
    /// and pepper. The texture is therefore looked up at a point moved *inside* the
    /// surface by [`CHECKER_INSET`] times `scale`, well above that noise: a surface on a
    /// boundary takes the cell behind it, the same from either side and for every
    /// pixel, and a surface crossing boundaries moves its checker edges by that inset
    /// (a few 1e-6 of the scene's scale), which no pixel shows.
    pub fn albedo_on_surface(&self, p: Vec3, outward: Vec3, scale: f32) -> Vec3 {
        if self.checker.is_none() {
            return self.diffuse;
        }
        let scale = scale.max(p.abs().max_element());
        self.albedo_at(p - outward * (CHECKER_INSET * scale))
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
