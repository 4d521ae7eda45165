//! Infinite planes (`[[plane]]` without `size` in TOML): unbounded primitives kept
//! outside the acceleration structures and tested against every ray
//! ([`crate::accel::SceneAccel`]), the way Embree and pbrt handle unbounded geometry.
//! They do not count in the scene's bounds (which frame the default camera and size
//! the spatial structures).

use super::instance::SurfacePoint;
use crate::geometry::{Ray, plane_point};
use glam::Vec3;

/// The plane through `point` with unit normal `normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub point: Vec3,
    /// Unit length (the loader normalises it; [`Plane::validate`] checks it).
    pub normal: Vec3,
    pub material: u32,
}

impl Plane {
    /// The surface where `ray` meets the plane at distance `t` ([`plane_point`]).
    pub fn surface(&self, ray: &Ray, t: f32) -> SurfacePoint {
        let (p, p_error) = plane_point(self.point, self.normal, ray, t);
        SurfacePoint {
            p,
            p_error,
            n_geometric: self.normal,
            n_shading: self.normal,
            material: self.material,
            smooth: None,
        }
    }

    /// Finite point, unit normal (to a few ulps) and a material below `nmat`.
    pub fn validate(&self, nmat: u32) -> Result<(), String> {
        if !self.point.is_finite() || !self.normal.is_finite() {
            return Err(format!(
                "point {} and normal {} must be finite",
                self.point, self.normal
            ));
        }
        if (self.normal.length_squared() - 1.0).abs() > 1e-5 {
            return Err(format!("normal {} is not unit length", self.normal));
        }
        if self.material >= nmat {
            return Err(format!(
                "uses material {}, but there are {nmat}",
                self.material
            ));
        }
        Ok(())
    }
}
