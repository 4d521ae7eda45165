//! The spheres of a scene, structure-of-arrays.

use crate::geometry::Aabb;
use glam::Vec3;

/// Spheres, structure-of-arrays.
#[derive(Clone, Debug, Default)]
pub struct SphereSet {
    pub cx: Vec<f32>,
    pub cy: Vec<f32>,
    pub cz: Vec<f32>,
    pub radius: Vec<f32>,
    pub material: Vec<u32>,
}

impl SphereSet {
    pub fn len(&self) -> usize {
        self.radius.len()
    }

    pub fn is_empty(&self) -> bool {
        self.radius.is_empty()
    }

    #[inline]
    pub fn center(&self, i: usize) -> Vec3 {
        Vec3::new(self.cx[i], self.cy[i], self.cz[i])
    }

    pub fn sphere_bounds(&self, i: usize) -> Aabb {
        let c = self.center(i);
        let r = Vec3::splat(self.radius[i]);
        Aabb::new(c - r, c + r)
    }
}
