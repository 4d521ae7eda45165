use crate::geometry::{Aabb, Ray};
use glam::Vec3;

/// Pinhole camera. Pixel `(x, y)` with row 0 at the top maps to the direction
/// `normalize(f + sx r + sy u)`, exactly as in shared/BENCHMARK.md, so that renders and
/// the throughput protocol share one camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub vfov_deg: f32,
}

/// The camera's frame, computed once per render.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    pub eye: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub tan_half: f32,
    pub width: f32,
    pub height: f32,
}

impl Camera {
    /// The framing of BENCHMARK.md: `eye = c + 1.2 d normalize(0.5, 0.3, 1)`, 45° fov.
    pub fn framing(bounds: &Aabb) -> Camera {
        if bounds.is_empty() {
            return Camera {
                eye: Vec3::new(0.0, 0.0, 5.0),
                target: Vec3::ZERO,
                up: Vec3::Y,
                vfov_deg: 45.0,
            };
        }
        let c = bounds.center();
        let d = bounds.diagonal().max(f32::MIN_POSITIVE);
        Camera {
            eye: c + 1.2 * d * Vec3::new(0.5, 0.3, 1.0).normalize(),
            target: c,
            up: Vec3::Y,
            vfov_deg: 45.0,
        }
    }

    pub fn validate(&self) -> Result<(), String> {
        if !self.eye.is_finite() || !self.target.is_finite() || !self.up.is_finite() {
            return Err("eye, target and up must be finite".into());
        }
        if self.eye == self.target {
            return Err("eye and target are the same point".into());
        }
        let f = (self.target - self.eye).normalize();
        if f.cross(self.up).length_squared() < 1e-12 {
            return Err("up is parallel to the viewing direction".into());
        }
        if !(self.vfov_deg > 0.0 && self.vfov_deg < 180.0) {
            return Err(format!(
                "fov must be in (0, 180) degrees, got {}",
                self.vfov_deg
            ));
        }
        Ok(())
    }

    pub fn frame(&self, width: u32, height: u32) -> CameraFrame {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        CameraFrame {
            eye: self.eye,
            forward,
            right,
            up,
            tan_half: (0.5 * self.vfov_deg).to_radians().tan(),
            width: width as f32,
            height: height as f32,
        }
    }
}

impl CameraFrame {
    /// Primary ray through the continuous image point `(px, py)` (pixel centres at +0.5).
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let sx = (2.0 * px / self.width - 1.0) * self.tan_half * self.width / self.height;
        let sy = (1.0 - 2.0 * py / self.height) * self.tan_half;
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.eye, dir)
    }
}
