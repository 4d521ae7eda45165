//! Linearly moving geometry for motion blur: kept apart from the static arrays so that
//! static primitives, their structures and their kernels do not change at all.

use super::{SphereSet, TriangleMesh};
use crate::geometry::Aabb;
use glam::Vec3;

/// Moving spheres and triangles. A primitive's position at time `t` is its stored
/// position plus `t * velocity`; the shutter interval picks which times are seen.
#[derive(Clone, Debug, Default)]
pub struct MotionSet {
    pub spheres: SphereSet,
    /// One per sphere.
    pub sphere_velocity: Vec<Vec3>,
    pub mesh: TriangleMesh,
    /// One per triangle (meshes move rigidly).
    pub triangle_velocity: Vec<Vec3>,
}

impl MotionSet {
    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty() && self.mesh.is_empty()
    }

    pub fn len(&self) -> usize {
        self.spheres.len() + self.mesh.len()
    }

    pub fn sphere_center(&self, i: usize, time: f32) -> Vec3 {
        self.spheres.center(i) + time * self.sphere_velocity[i]
    }

    pub fn triangle_corners(&self, t: usize, time: f32) -> [Vec3; 3] {
        let d = time * self.triangle_velocity[t];
        self.mesh.corners(t).map(|c| c + d)
    }

    /// Bounds over the time interval `[t0, t1]` (linear motion: the union of both ends).
    pub fn bounds(&self, [t0, t1]: [f32; 2]) -> Aabb {
        let mut b = Aabb::EMPTY;
        for i in 0..self.spheres.len() {
            let r = Vec3::splat(self.spheres.radius[i]);
            for t in [t0, t1] {
                let c = self.sphere_center(i, t);
                b = b.union(&Aabb::new(c - r, c + r));
            }
        }
        for i in 0..self.mesh.len() {
            for t in [t0, t1] {
                for c in self.triangle_corners(i, t) {
                    b.grow(c);
                }
            }
        }
        b
    }

    /// Appends a mesh (vertices, normals, triangles and materials ids already valid for
    /// the scene) moving with `velocity`.
    pub fn add_mesh(&mut self, mesh: &TriangleMesh, velocity: Vec3) {
        let m = &mut self.mesh;
        let base = m.xs.len() as u32;
        let had = m.has_normals();
        let want = mesh.has_normals();
        if want && !had {
            m.nxs.resize(base as usize, 0.0);
            m.nys.resize(base as usize, 0.0);
            m.nzs.resize(base as usize, 0.0);
        }
        m.xs.extend_from_slice(&mesh.xs);
        m.ys.extend_from_slice(&mesh.ys);
        m.zs.extend_from_slice(&mesh.zs);
        if want {
            m.nxs.extend_from_slice(&mesh.nxs);
            m.nys.extend_from_slice(&mesh.nys);
            m.nzs.extend_from_slice(&mesh.nzs);
        } else if had {
            let len = m.xs.len();
            m.nxs.resize(len, 0.0);
            m.nys.resize(len, 0.0);
            m.nzs.resize(len, 0.0);
        }
        // Texture coordinates: kept when either side has them, (0, 0) where missing.
        if m.has_uvs() || mesh.has_uvs() {
            m.us.resize(base as usize, 0.0);
            m.vs.resize(base as usize, 0.0);
            m.us.extend_from_slice(&mesh.us);
            m.vs.extend_from_slice(&mesh.vs);
            m.us.resize(m.xs.len(), 0.0);
            m.vs.resize(m.xs.len(), 0.0);
        }
        m.i0.extend(mesh.i0.iter().map(|i| i + base));
        m.i1.extend(mesh.i1.iter().map(|i| i + base));
        m.i2.extend(mesh.i2.iter().map(|i| i + base));
        m.material.extend_from_slice(&mesh.material);
        self.triangle_velocity
            .extend(std::iter::repeat_n(velocity, mesh.len()));
    }
}
