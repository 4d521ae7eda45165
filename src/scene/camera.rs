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
    /// Half the image height in world units for an orthographic camera (`None`:
    /// perspective). Set by [`CameraFrame::with_effects`].
    pub ortho_half_height: Option<f32>,
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
            ortho_half_height: None,
        }
    }
}

impl CameraFrame {
    /// The frame with the projection of `effects` (orthographic or perspective).
    pub fn with_effects(mut self, effects: &CameraEffects) -> Self {
        self.ortho_half_height = effects.ortho_height.map(|h| 0.5 * h);
        self
    }

    /// Primary ray through the continuous image point `(px, py)` (pixel centres at +0.5).
    /// Orthographic: every ray has the direction `forward` and starts on the plane
    /// through the eye, `ortho_height` tall and `width / height` times that wide.
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        if let Some(h) = self.ortho_half_height {
            let sx = (2.0 * px / self.width - 1.0) * h * self.width / self.height;
            let sy = (1.0 - 2.0 * py / self.height) * h;
            return Ray::new(self.eye + sx * self.right + sy * self.up, self.forward);
        }
        let sx = (2.0 * px / self.width - 1.0) * self.tan_half * self.width / self.height;
        let sy = (1.0 - 2.0 * py / self.height) * self.tan_half;
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.eye, dir)
    }
}

/// What a real camera adds to the pinhole [`Camera`]: a thin lens (depth of field) and
/// a shutter interval with a moving eye (motion blur). The default is the pinhole with
/// an instantaneous shutter, which samples neither lens nor time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraEffects {
    /// Lens radius in world units; 0 is a pinhole.
    pub aperture: f32,
    /// Distance along the viewing direction of the plane in focus; `None` focuses at
    /// the target.
    pub focus_distance: Option<f32>,
    /// Corners of a polygonal aperture (bokeh shape); 0 is a round one.
    pub aperture_blades: u32,
    /// Rotation of the polygonal aperture, in degrees.
    pub aperture_rotation_deg: f32,
    /// Shutter open and close times; motion blur needs `open < close`.
    pub shutter: [f32; 2],
    /// Eye position at shutter close: the camera translates (eye and target together)
    /// from `eye` at open to `eye1` at close. `None` is a fixed camera.
    pub eye1: Option<Vec3>,
    /// Orthographic projection: the image height in world units (`None`, the default,
    /// is the perspective pinhole of [`Camera`], whose `vfov_deg` is then unused).
    pub ortho_height: Option<f32>,
}

impl Default for CameraEffects {
    fn default() -> Self {
        CameraEffects {
            aperture: 0.0,
            focus_distance: None,
            aperture_blades: 0,
            aperture_rotation_deg: 0.0,
            shutter: [0.0, 0.0],
            eye1: None,
            ortho_height: None,
        }
    }
}

impl CameraEffects {
    pub fn has_depth_of_field(&self) -> bool {
        self.aperture > 0.0
    }

    pub fn shutter_open(&self) -> bool {
        self.shutter[0] < self.shutter[1]
    }

    pub fn validate(&self) -> Result<(), String> {
        if !(self.aperture.is_finite() && self.aperture >= 0.0) {
            return Err(format!(
                "aperture must be finite and >= 0, got {}",
                self.aperture
            ));
        }
        if let Some(f) = self.focus_distance
            && !(f.is_finite() && f > 0.0)
        {
            return Err(format!("focus distance must be finite and > 0, got {f}"));
        }
        if self.aperture_blades > 0 && !(3..=64).contains(&self.aperture_blades) {
            return Err(format!(
                "aperture blades must be 0 (round) or 3..=64, got {}",
                self.aperture_blades
            ));
        }
        if !self.aperture_rotation_deg.is_finite() {
            return Err("aperture rotation must be finite".into());
        }
        let [open, close] = self.shutter;
        if !(open.is_finite() && close.is_finite() && open <= close) {
            return Err(format!(
                "shutter must be [open, close] with finite open <= close, got [{open}, {close}]"
            ));
        }
        if self.eye1.is_some_and(|e| !e.is_finite()) {
            return Err("eye1 must be finite".into());
        }
        if let Some(h) = self.ortho_height {
            if !(h.is_finite() && h > 0.0) {
                return Err(format!(
                    "orthographic height must be finite and > 0, got {h}"
                ));
            }
            if self.aperture > 0.0 {
                return Err("an orthographic camera has no lens: aperture must be 0".into());
            }
        }
        Ok(())
    }
}

/// The lens and shutter of one render, resolved against the camera.
#[derive(Clone, Copy, Debug)]
pub struct LensFrame {
    /// Lens radius (0: pinhole).
    pub aperture: f32,
    pub focus_distance: f32,
    pub blades: u32,
    pub rotation: f32,
    pub shutter: [f32; 2],
    /// Eye displacement over the whole shutter interval.
    pub eye_motion: Vec3,
}

impl LensFrame {
    pub fn new(camera: &Camera, effects: &CameraEffects) -> Self {
        LensFrame {
            aperture: effects.aperture,
            focus_distance: effects
                .focus_distance
                .unwrap_or_else(|| (camera.target - camera.eye).length()),
            blades: effects.aperture_blades,
            rotation: effects.aperture_rotation_deg.to_radians(),
            shutter: effects.shutter,
            eye_motion: effects.eye1.map_or(Vec3::ZERO, |e1| e1 - camera.eye),
        }
    }

    /// Shutter time for a uniform number `u` in `[0, 1)`.
    pub fn time(&self, u: f32) -> f32 {
        self.shutter[0] + u * (self.shutter[1] - self.shutter[0])
    }

    /// The thin-lens ray (Cook et al. 1984; Potmesil and Chakravarty 1981) for the
    /// pinhole ray `ray`, the point `lens` on the unit aperture and shutter time
    /// `time`: it leaves the lens at `eye + aperture * lens` and passes through the
    /// point where the pinhole ray meets the plane of focus, so that plane stays sharp
    /// and a point at depth `z` blurs into a disc of radius
    /// `aperture * |z - focus| / z` on the plane of focus.
    pub fn ray(&self, frame: &CameraFrame, ray: Ray, lens: Option<glam::Vec2>, time: f32) -> Ray {
        let mut r = ray;
        if let Some(l) = lens {
            let focus = r.origin + r.dir * (self.focus_distance / r.dir.dot(frame.forward));
            r.origin += self.aperture * (l.x * frame.right + l.y * frame.up);
            r.dir = (focus - r.origin).normalize();
        }
        if self.eye_motion != Vec3::ZERO && self.shutter[1] > self.shutter[0] {
            let s = (time - self.shutter[0]) / (self.shutter[1] - self.shutter[0]);
            r.origin += s * self.eye_motion;
        }
        r.time = time;
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orthographic_rays_are_parallel_and_span_the_height() {
        let cam = Camera {
            eye: Vec3::new(0.3, 1.0, 5.0),
            target: Vec3::new(-0.2, 0.4, 0.0),
            up: Vec3::Y,
            vfov_deg: 45.0,
        };
        let effects = CameraEffects {
            ortho_height: Some(2.0),
            ..Default::default()
        };
        let frame = cam.frame(64, 32).with_effects(&effects);
        for (px, py) in [(0.5, 0.5), (63.5, 31.5), (10.25, 20.75), (32.0, 16.0)] {
            // exact: the direction is the frame's forward, never recomputed
            assert_eq!(frame.ray(px, py).dir, frame.forward);
        }
        // image corners: half height 1, half width 2 (aspect 2); 2e-6 covers the f32
        // rounding of eye + sx r + sy u at |eye| ~ 5 (about four ulps of 5, 4.8e-7 each)
        let top_left = frame.ray(0.0, 0.0).origin - cam.eye;
        let want = -2.0 * frame.right + frame.up;
        assert!(
            (top_left - want).abs().max_element() < 2e-6,
            "{top_left} vs {want}"
        );
        let centre = frame.ray(32.0, 16.0).origin;
        assert_eq!(centre, cam.eye);
        // the perspective frame is unchanged by default effects
        let p = cam.frame(64, 32).with_effects(&CameraEffects::default());
        assert_ne!(p.ray(0.5, 0.5).dir, p.ray(63.5, 31.5).dir);
        assert!(
            CameraEffects {
                ortho_height: Some(0.0),
                ..Default::default()
            }
            .validate()
            .is_err()
        );
        assert!(
            CameraEffects {
                ortho_height: Some(1.0),
                aperture: 0.1,
                ..Default::default()
            }
            .validate()
            .is_err()
        );
    }
}
