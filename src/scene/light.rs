use glam::Vec3;

/// Lights of the Whitted model. A point light is sampled with exactly one shadow ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity `intensity` (per colour channel); irradiance falls off as 1/r².
    Point { position: Vec3, intensity: Vec3 },
    /// Light arriving along `direction` (pointing from the light into the scene) with
    /// irradiance `irradiance` on a surface facing it.
    Directional { direction: Vec3, irradiance: Vec3 },
}

impl Light {
    pub fn validate(&self) -> Result<(), String> {
        match self {
            Light::Point {
                position,
                intensity,
            } => {
                if !position.is_finite() || !intensity.is_finite() || intensity.min_element() < 0.0
                {
                    return Err(
                        "point light needs a finite position and a finite, non-negative intensity"
                            .into(),
                    );
                }
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                if !direction.is_finite() || direction.length_squared() == 0.0 {
                    return Err("directional light needs a finite, non-zero direction".into());
                }
                if !irradiance.is_finite() || irradiance.min_element() < 0.0 {
                    return Err("directional light needs a finite, non-negative irradiance".into());
                }
            }
        }
        Ok(())
    }
}
