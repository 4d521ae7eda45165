//! Camera settings from the command line (`--eye`, `--target`, `--up`, `--fov`,
//! `--up-axis`, `--look-from-side`): applied to a loaded scene's camera.

use super::{Camera, Scene};
use crate::error::{Error, Result};
use crate::geometry::Aabb;
use glam::Vec3;
use std::str::FromStr;

/// Which world axis points up in the model (`--up-axis`). Scans often use Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum UpAxis {
    #[default]
    Y,
    Z,
}

/// The side a framed camera looks from (`--look-from-side`), relative to the up axis:
/// with Y up, `front` looks from +Z, `back` from -Z, `right` from +X, `left` from -X
/// and `top` from +Y (screen-up towards -Z, so the front is at the bottom). With Z up
/// the same directions are rotated by +90° about X (Y to Z): `front` looks from -Y,
/// `back` from +Y, `top` from +Z with screen-up +Y (Blender's front and top views).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Front,
    Back,
    Left,
    Right,
    Top,
}

impl FromStr for UpAxis {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "y" | "Y" => Ok(UpAxis::Y),
            "z" | "Z" => Ok(UpAxis::Z),
            _ => Err(format!("unknown up axis `{s}`: expected `y` or `z`")),
        }
    }
}

impl FromStr for Side {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "front" => Ok(Side::Front),
            "back" => Ok(Side::Back),
            "left" => Ok(Side::Left),
            "right" => Ok(Side::Right),
            "top" => Ok(Side::Top),
            _ => Err(format!(
                "unknown side `{s}`: expected front, back, left, right or top"
            )),
        }
    }
}

impl UpAxis {
    /// A Y-up direction expressed in this axis convention (+90° about X for Z up:
    /// `(x, y, z) -> (x, -z, y)`, exact, no rounding).
    pub fn from_y_up(self, v: Vec3) -> Vec3 {
        match self {
            UpAxis::Y => v,
            UpAxis::Z => Vec3::new(v.x, -v.z, v.y),
        }
    }
}

impl Side {
    /// Direction from the target to the eye and the camera's up vector, Y up.
    fn y_up_view(self) -> (Vec3, Vec3) {
        match self {
            Side::Front => (Vec3::Z, Vec3::Y),
            Side::Back => (Vec3::NEG_Z, Vec3::Y),
            Side::Right => (Vec3::X, Vec3::Y),
            Side::Left => (Vec3::NEG_X, Vec3::Y),
            Side::Top => (Vec3::Y, Vec3::NEG_Z),
        }
    }
}

impl Camera {
    /// [`Camera::framing`] generalised: the eye at `c + 1.2 d dir` with 45° fov, where
    /// `dir` is the side's axis or, with no side, BENCHMARK.md's `normalize(0.5, 0.3, 1)`,
    /// both rotated into the `up` axis convention. `framing_from(b, None, UpAxis::Y)`
    /// equals `framing(b)` bit for bit.
    pub fn framing_from(bounds: &Aabb, side: Option<Side>, up: UpAxis) -> Camera {
        let base = Camera::framing(bounds);
        let (dir, cam_up) = match side {
            Some(s) => s.y_up_view(),
            None => (Vec3::new(0.5, 0.3, 1.0).normalize(), Vec3::Y),
        };
        let (dir, cam_up) = (up.from_y_up(dir), up.from_y_up(cam_up));
        let d = if bounds.is_empty() {
            (base.eye - base.target).length()
        } else {
            1.2 * bounds.diagonal().max(f32::MIN_POSITIVE)
        };
        Camera {
            eye: base.target + d * dir,
            target: base.target,
            up: cam_up,
            vfov_deg: base.vfov_deg,
        }
    }
}

/// Camera settings given on the command line. `ortho` makes the camera orthographic.
/// Framing (`side`, `up_axis`) replaces the
/// scene's camera by [`Camera::framing_from`] of the scene bounds; `eye`, `target`,
/// `up` and `fov` then replace single fields. All-`None` leaves the scene untouched.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraOverrides {
    pub eye: Option<Vec3>,
    pub target: Option<Vec3>,
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees.
    pub fov: Option<f32>,
    pub up_axis: Option<UpAxis>,
    pub side: Option<Side>,
    /// `--ortho HEIGHT`: orthographic projection with this image height (world units).
    pub ortho: Option<f32>,
}

impl CameraOverrides {
    /// True when no camera flag was given.
    pub fn is_empty(&self) -> bool {
        *self == CameraOverrides::default()
    }

    /// The camera with the overrides applied, validated as a TOML camera is (finite
    /// vectors, `eye != target`, `up` not parallel to the view, `0 < fov < 180`).
    pub fn apply(&self, camera: Camera, bounds: &Aabb) -> Result<Camera> {
        let bad = |m: String| Error::parameter("camera flags", m);
        let mut c = camera;
        if self.side.is_some() || self.up_axis.is_some() {
            c = Camera::framing_from(bounds, self.side, self.up_axis.unwrap_or_default());
        }
        for (name, v) in [("--eye", self.eye), ("--target", self.target)] {
            if v.is_some_and(|v| !v.is_finite()) {
                return Err(bad(format!("{name} must be three finite numbers")));
            }
        }
        if let Some(up) = self.up
            && !(up.is_finite() && up.length_squared() >= 1e-20)
        {
            return Err(bad(format!(
                "--up must be a finite non-zero vector, got {up}"
            )));
        }
        if let Some(f) = self.fov
            && !(f > 0.0 && f < 180.0)
        {
            return Err(bad(format!(
                "--fov must be between 0 and 180 degrees (exclusive), got {f}"
            )));
        }
        c.eye = self.eye.unwrap_or(c.eye);
        c.target = self.target.unwrap_or(c.target);
        c.up = self.up.unwrap_or(c.up);
        c.vfov_deg = self.fov.unwrap_or(c.vfov_deg);
        c.validate().map_err(bad)?;
        Ok(c)
    }

    /// Applies the overrides to a loaded scene. A moving camera (`eye1`) keeps its
    /// absolute close position, so moving `eye` with it set is refused rather than
    /// silently changing the motion.
    pub fn apply_to_scene(&self, scene: &mut Scene) -> Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        let c = self.apply(scene.camera, &scene.bounds)?;
        if let Some(h) = self.ortho {
            let mut e = scene.camera_effects;
            e.ortho_height = Some(h);
            e.validate()
                .map_err(|m| Error::parameter("camera flags", format!("--ortho: {m}")))?;
            scene.camera_effects = e;
        }
        if c.eye != scene.camera.eye && scene.camera_effects.eye1.is_some() {
            return Err(Error::parameter(
                "camera flags",
                "the scene's camera moves (`eye1`); moving its eye from the command line is not supported",
            ));
        }
        scene.camera = c;
        Ok(())
    }
}

/// Parses `x,y,z` as three numbers. Each is read as `f64` and rounded to `f32`, as the
/// TOML loader does, so a flag and a TOML key with the same text give the same bits.
pub fn parse_vec3(s: &str) -> std::result::Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z (three numbers), got `{s}`"));
    }
    let mut v = [0.0f32; 3];
    for (o, p) in v.iter_mut().zip(&parts) {
        let x: f64 = p.parse().map_err(|_| format!("`{p}` is not a number"))?;
        *o = x as f32;
    }
    Ok(Vec3::from_array(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0))
    }

    fn view_dir(c: &Camera) -> Vec3 {
        (c.eye - c.target).normalize()
    }

    #[test]
    fn default_framing_is_the_benchmark_framing() {
        let b = unit_box();
        assert_eq!(
            Camera::framing_from(&b, None, UpAxis::Y),
            Camera::framing(&b)
        );
    }

    #[test]
    fn sides_look_from_the_named_axis() {
        let b = unit_box();
        let cases = [
            (Side::Front, UpAxis::Y, Vec3::Z),
            (Side::Back, UpAxis::Y, Vec3::NEG_Z),
            (Side::Right, UpAxis::Y, Vec3::X),
            (Side::Left, UpAxis::Y, Vec3::NEG_X),
            (Side::Top, UpAxis::Y, Vec3::Y),
            (Side::Front, UpAxis::Z, Vec3::NEG_Y),
            (Side::Back, UpAxis::Z, Vec3::Y),
            (Side::Right, UpAxis::Z, Vec3::X),
            (Side::Left, UpAxis::Z, Vec3::NEG_X),
            (Side::Top, UpAxis::Z, Vec3::Z),
        ];
        for (side, axis, want) in cases {
            let c = Camera::framing_from(&b, Some(side), axis);
            // exact: axis-aligned offsets from the centre, one non-zero component
            assert_eq!(view_dir(&c), want, "{side:?} {axis:?}");
            assert_eq!(c.target, b.center());
            c.validate().unwrap();
            // the camera's up is the world up axis except for the top view
            if side != Side::Top {
                let up = if axis == UpAxis::Y { Vec3::Y } else { Vec3::Z };
                assert_eq!(c.up, up);
            }
        }
    }

    #[test]
    fn z_up_default_view_is_the_y_up_view_rotated() {
        // centred at the origin, so `eye - target` is the offset exactly (no rounding)
        let b = Aabb::new(Vec3::new(-1.0, -2.0, -3.0), Vec3::new(1.0, 2.0, 3.0));
        let y = Camera::framing_from(&b, None, UpAxis::Y);
        let z = Camera::framing_from(&b, None, UpAxis::Z);
        let (dy, dz) = (y.eye - y.target, z.eye - z.target);
        assert_eq!(dz, Vec3::new(dy.x, -dy.z, dy.y));
        assert_eq!(z.up, Vec3::Z);
    }

    #[test]
    fn overrides_replace_fields_and_are_validated() {
        let b = unit_box();
        let base = Camera::framing(&b);
        let o = CameraOverrides {
            fov: Some(30.0),
            eye: Some(Vec3::new(0.0, 1.0, 9.0)),
            ..Default::default()
        };
        let c = o.apply(base, &b).unwrap();
        assert_eq!(
            (c.eye, c.target, c.vfov_deg),
            (Vec3::new(0.0, 1.0, 9.0), base.target, 30.0)
        );
        let bad = [
            CameraOverrides {
                fov: Some(180.0),
                ..Default::default()
            },
            CameraOverrides {
                fov: Some(f32::NAN),
                ..Default::default()
            },
            CameraOverrides {
                eye: Some(base.target),
                ..Default::default()
            },
            CameraOverrides {
                up: Some(Vec3::ZERO),
                ..Default::default()
            },
            CameraOverrides {
                eye: Some(Vec3::new(f32::INFINITY, 0.0, 0.0)),
                ..Default::default()
            },
            CameraOverrides {
                eye: Some(Vec3::new(0.0, 5.0, 0.0)),
                target: Some(Vec3::ZERO),
                ..Default::default()
            },
        ];
        for o in bad {
            assert!(o.apply(base, &b).is_err(), "{o:?} accepted");
        }
    }

    #[test]
    fn vec3_flags_parse_like_toml() {
        assert_eq!(
            parse_vec3("1, -2.5,3e1").unwrap(),
            Vec3::new(1.0, -2.5, 30.0)
        );
        // 0.1 via f64 then f32, as toml does
        assert_eq!(parse_vec3("0.1,0,0").unwrap().x, 0.1f64 as f32);
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,x").is_err());
    }
}
