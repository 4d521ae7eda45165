//! The triangle mesh of a scene, structure-of-arrays.

use crate::geometry::Aabb;
use glam::{Vec2, Vec3};

/// Triangle mesh, structure-of-arrays. All meshes of a scene are merged into one.
#[derive(Clone, Debug, Default)]
pub struct TriangleMesh {
    pub xs: Vec<f32>,
    pub ys: Vec<f32>,
    pub zs: Vec<f32>,
    /// Optional per-vertex shading normals (all three empty, or as long as `xs`).
    pub nxs: Vec<f32>,
    pub nys: Vec<f32>,
    pub nzs: Vec<f32>,
    /// Optional per-vertex texture coordinates (both empty, or as long as `xs`; OBJ
    /// `vt`, PLY `u v`/`s t`; quads and planes get their corners' `(0, 0)..(1, 1)`).
    pub us: Vec<f32>,
    pub vs: Vec<f32>,
    /// Vertex indices of each triangle's corners.
    pub i0: Vec<u32>,
    pub i1: Vec<u32>,
    pub i2: Vec<u32>,
    /// Material id per triangle.
    pub material: Vec<u32>,
}

impl TriangleMesh {
    pub fn len(&self) -> usize {
        self.i0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.i0.is_empty()
    }

    pub fn vertex_count(&self) -> usize {
        self.xs.len()
    }

    #[inline]
    pub fn vertex(&self, i: u32) -> Vec3 {
        let i = i as usize;
        Vec3::new(self.xs[i], self.ys[i], self.zs[i])
    }

    /// The three corners of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        [
            self.vertex(self.i0[t]),
            self.vertex(self.i1[t]),
            self.vertex(self.i2[t]),
        ]
    }

    pub fn has_normals(&self) -> bool {
        !self.nxs.is_empty()
    }

    pub fn has_uvs(&self) -> bool {
        !self.us.is_empty()
    }

    /// Texture coordinates at barycentrics `(u, v)` of triangle `t`, interpolated as
    /// positions are (`(1 - u - v) uv0 + u uv1 + v uv2`); zero for a mesh without them.
    #[inline]
    pub fn uv_at(&self, t: usize, u: f32, v: f32) -> Vec2 {
        if !self.has_uvs() {
            return Vec2::ZERO;
        }
        let c = |i: u32| Vec2::new(self.us[i as usize], self.vs[i as usize]);
        (1.0 - u - v) * c(self.i0[t]) + u * c(self.i1[t]) + v * c(self.i2[t])
    }

    /// Unit geometric normal `normalize((v1 - v0) × (v2 - v0))`; zero for a degenerate triangle.
    pub fn geometric_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// The unit vertex normals of triangle `t`'s corners, if the mesh has normals and
    /// none of the three is zero (zero means "use the geometric normal").
    pub fn vertex_normals(&self, t: usize) -> Option<[Vec3; 3]> {
        if !self.has_normals() {
            return None;
        }
        let n = |i: u32| {
            let i = i as usize;
            Vec3::new(self.nxs[i], self.nys[i], self.nzs[i]).normalize_or_zero()
        };
        let ns = [n(self.i0[t]), n(self.i1[t]), n(self.i2[t])];
        ns.iter().all(|n| *n != Vec3::ZERO).then_some(ns)
    }

    /// Interpolated shading normal at barycentrics `(u, v)`, or the geometric normal.
    pub fn shading_normal(&self, t: usize, u: f32, v: f32) -> Vec3 {
        if !self.has_normals() {
            return self.geometric_normal(t);
        }
        let n = |i: u32| {
            let i = i as usize;
            Vec3::new(self.nxs[i], self.nys[i], self.nzs[i])
        };
        let s = (1.0 - u - v) * n(self.i0[t]) + u * n(self.i1[t]) + v * n(self.i2[t]);
        let s = s.normalize_or_zero();
        if s == Vec3::ZERO {
            self.geometric_normal(t)
        } else {
            s
        }
    }

    pub fn triangle_bounds(&self, t: usize) -> Aabb {
        let [a, b, c] = self.corners(t);
        let mut bb = Aabb::from_point(a);
        bb.grow(b);
        bb.grow(c);
        bb
    }
}
