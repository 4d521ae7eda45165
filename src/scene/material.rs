use glam::Vec3;

/// A material as a sum of lobes, each weighted by an RGB coefficient; a material uses
/// the lobes whose weight is non-zero, and the scene's [`Features`](super::Features)
/// record which lobes any material uses.
///
/// - diffuse (Lambert), optionally modulated by a checkerboard;
/// - specular highlight (Blinn-Phong, exponent `shininess`) for direct light;
/// - `mirror`: perfect specular reflection without Fresnel (a metal);
/// - `transmission` with `ior`: a dielectric (glass): reflection and refraction weighted
///   by Schlick's Fresnel, total internal reflection past the critical angle.
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
}

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

    pub fn validate(&self) -> Result<(), String> {
        let colours = [
            ("diffuse", self.diffuse),
            ("specular", self.specular),
            ("mirror", self.mirror),
            ("transmission", self.transmission),
            ("emission", self.emission),
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
        if !(self.ior.is_finite() && self.ior > 0.0) {
            return Err(format!("ior must be finite and > 0, got {}", self.ior));
        }
        Ok(())
    }
}
