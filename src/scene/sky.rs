//! A procedural sky, generated as an equirectangular map at load time (TOML
//! `[environment] map = { procedural = "sky", ... }`): a gradient from a horizon colour
//! to a zenith colour over the upper hemisphere, a constant ground below, and a sun
//! disk of given angular diameter and radiance. Not a physical sky model (no
//! scattering); it gives a scene a bright, small light and a dim, large one, which is
//! what the importance sampling of the map is for.

use super::environment::uv_to_direction;
use glam::Vec3;

/// Parameters of [`generate`]; directions are in the map's frame (+Y up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyParams {
    /// Map width in texels; the height is half of it (rounded up).
    pub width: usize,
    /// Unit direction towards the sun's centre.
    pub sun_direction: Vec3,
    /// Angular diameter of the sun disk, degrees.
    pub sun_angle_deg: f32,
    /// Radiance of a texel inside the sun disk (added to the sky).
    pub sun_radiance: Vec3,
    pub zenith: Vec3,
    pub horizon: Vec3,
    pub ground: Vec3,
}

impl Default for SkyParams {
    fn default() -> Self {
        SkyParams {
            width: 512,
            sun_direction: Vec3::new(0.5, 0.55, 0.35).normalize(),
            sun_angle_deg: 4.0,
            sun_radiance: Vec3::new(200.0, 180.0, 150.0),
            zenith: Vec3::new(0.12, 0.25, 0.7),
            horizon: Vec3::new(0.75, 0.8, 0.9),
            ground: Vec3::new(0.25, 0.22, 0.2),
        }
    }
}

/// The sky map, `(width, height, texels)` row-major from the zenith row: every texel
/// takes the sky's value at its centre direction.
pub fn generate(p: &SkyParams) -> (usize, usize, Vec<Vec3>) {
    let (w, h) = (p.width, p.width.div_ceil(2));
    let cos_sun = (0.5 * p.sun_angle_deg).to_radians().cos();
    let sun = p.sun_direction.normalize();
    let mut texels = Vec::with_capacity(w * h);
    for r in 0..h {
        for c in 0..w {
            let d = uv_to_direction((c as f32 + 0.5) / w as f32, (r as f32 + 0.5) / h as f32);
            let mut l = if d.y >= 0.0 {
                p.horizon.lerp(p.zenith, d.y.sqrt())
            } else {
                p.ground
            };
            if d.dot(sun) >= cos_sun {
                l += p.sun_radiance;
            }
            texels.push(l);
        }
    }
    (w, h, texels)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sun covers the texels within its radius of the sun direction and no others;
    /// the ground is constant.
    #[test]
    fn sun_disk_and_ground_are_where_asked() {
        let p = SkyParams {
            width: 64,
            sun_direction: Vec3::Y,
            sun_angle_deg: 30.0,
            ..SkyParams::default()
        };
        let (w, h, t) = generate(&p);
        assert_eq!((w, h), (64, 32));
        // Row centres at polar angles 2.8125°, 8.4375°, 14.0625°, 19.6875°: the first
        // three are inside the 15° radius, the fourth outside.
        for r in 0..4 {
            let lit = t[r * w].x > 100.0;
            assert_eq!(lit, r < 3, "row {r}");
        }
        assert_eq!(t[(h - 1) * w + 5], p.ground);
    }
}
